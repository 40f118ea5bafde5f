"""
Fit a silhouette image
======================

A binary image is read as the outline of its largest shape (subpixel contour, y up) with the
outline's normals, so a drawing or a segmentation mask can be fitted directly. Here the image
is drawn with Pillow: a rounded body with two ears.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from PIL import Image, ImageDraw

import ipfit

folder = Path(tempfile.mkdtemp())
image = Image.new("L", (240, 200), 0)
draw = ImageDraw.Draw(image)
draw.ellipse((40, 60, 200, 180), fill=255)  # the body
draw.ellipse((50, 20, 110, 90), fill=255)  # two ears
draw.ellipse((130, 20, 190, 90), fill=255)
image.save(folder / "silhouette.png")

cloud = ipfit.load(folder / "silhouette.png")
print(cloud.points.shape, "outline points; normals from:", cloud.normals_source)

result = ipfit.fit_adaptive(cloud, max_degree=8, rng=0)
print(result.message)

# %%
# The zero set of the selected polynomial over the image (the reader puts y up, so the image
# is drawn with its origin at the bottom).
fig, ax = plt.subplots(figsize=(5, 4.2))
ax.imshow(image, cmap="gray_r", origin="upper", extent=(0, 240, 0, 200), alpha=0.35)
ipfit.plot_curve(result.polynomial, cloud.points, ax=ax, label=f"degree {result.selected_degree}")
ax.legend(loc="lower right")
ax.set_title("silhouette.png and its fit")
plt.show()

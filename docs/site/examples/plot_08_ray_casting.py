"""
Ray casting a surface
=====================

A 3D fit needs no mesh to be drawn: ``intersect_rays`` finds every intersection of a ray with
the zero set as the real roots of f restricted to the ray (a univariate polynomial of the
fit's degree), and ``render`` ray-casts an image from them (``ipfit render`` on the command
line). Here: a quartic surface fitted to the small bunny (``refine`` at one degree: DE and the
L-BFGS polish from the linear fits, with the far-field term that keeps the zero set closed).
"""

import matplotlib.pyplot as plt
import numpy as np

import ipfit

cloud = ipfit.load("bunny_res4")
poly = ipfit.refine(cloud, None, 4, rng=0).polynomial  # None: the cloud's own normals
print(cloud.points.shape, "points; a degree-4 surface with", len(poly.coefficients), "coefficients")

# %%
# Three rays from outside the data through its centre: each hits the closed surface an even
# number of times; ``t`` is the distance along the unit direction.
centre = cloud.points.mean(axis=0)
directions = np.eye(3)
origins = centre - 0.3 * directions
hits = ipfit.intersect_rays(origins, directions, poly)
for axis, t, count in zip("xyz", hits.t, hits.count, strict=True):
    print(f"along {axis}: {count} hits at t = {np.round(t[:count], 4).tolist()}")

# %%
# A ray-cast image of the exact zero set, shaded by its normal, beside the data.
lo, hi = cloud.points.min(axis=0), cloud.points.max(axis=0)
pad = 0.15 * (hi - lo)
bounds = np.column_stack([lo - pad, hi + pad])  # (3, 2): min and max per axis
image = ipfit.render(poly, bounds, size=320, up="y", view=(20, 30))
fig, (left, right) = plt.subplots(1, 2, figsize=(8, 4))
left.scatter(cloud.points[:, 0], cloud.points[:, 1], s=2, color="0.3")
left.set_aspect("equal")
left.set_title(f"{len(cloud.points)} points (x, y)")
right.imshow(image)
right.set_axis_off()
right.set_title("render(poly, bounds)")
plt.show()

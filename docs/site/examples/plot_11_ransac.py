"""
RANSAC with scikit-image
========================

``ipfit.ImplicitPolynomialModel`` is a model for ``skimage.measure.ransac``: each random
sample is fitted by Taubin's linear fit, and a point's residual is its first-order distance
|f|/‖∇f‖ to the zero set in the data's units. Consensus suits conics and quadrics: here a
circle with 30% outliers.
"""

import matplotlib.pyplot as plt
import numpy as np
from skimage.measure import ransac

import ipfit
from ipfit import ImplicitPolynomialModel

rng = np.random.default_rng(0)
t = rng.uniform(0, 2 * np.pi, 300)
circle = np.column_stack([3 + 2 * np.cos(t), -1 + 2 * np.sin(t)]) + rng.normal(scale=0.004, size=(300, 2))
outliers = rng.uniform([0.0, -4.0], [6.0, 2.0], (130, 2))
points = np.vstack([circle, outliers])

model, inliers = ransac(points, ImplicitPolynomialModel, ImplicitPolynomialModel.min_samples(2),
                        residual_threshold=0.02, max_trials=200, rng=0)
poly = model.polynomial  # an ipfit.ImplicitPolynomial
print(f"{inliers[:300].mean():.0%} of the circle kept, {1 - inliers[300:].mean():.0%} of the outliers flagged")
print(f"largest residual of the circle's points: {poly.residuals(circle).max():.3f}")

# %%
fig, ax = plt.subplots(figsize=(5, 5))
ax.plot(*points[~inliers].T, ".", color="#ffb000", ms=4, label="outliers")
ipfit.plot_curve(poly, points[inliers], ax=ax, label="ransac's conic")
ax.legend(loc="upper right")
plt.show()

"""
Fit a contour
=============

The bundled ``boot`` is a contour traced from an MPEG-7 silhouette, with normals. ``fit_adaptive``
raises the degree 2, 4, 6, ... while the fit still improves, refines each degree's linear fits
with differential evolution and an L-BFGS polish, and selects a degree; ``plot_result`` draws
the fit of every degree tried, the selected one framed.
"""

import ipfit

cloud = ipfit.load("boot")
print(cloud.points.shape, "points; normals from:", cloud.normals_source)

# max_degree keeps the example quick: the defaults go up to degree 14 in 2D.
result = ipfit.fit_adaptive(cloud, max_degree=6, rng=0)
print(result.message)
for degree in result.degrees:
    print(f"degree {degree.degree}: {degree.reason}")

# %%
# The selected polynomial is an immutable :class:`ipfit.ImplicitPolynomial`: it evaluates f and
# its gradient, and is inside (f < 0) or outside the shape.
poly = result.polynomial
print(poly.degree, len(poly.coefficients), "coefficients")
print("inside at the centre of the data:", poly.contains(cloud.points.mean(axis=0, keepdims=True)))

fig = ipfit.plot_result(result, cloud.points)  # a matplotlib Figure: fig.savefig("boot.png") saves it

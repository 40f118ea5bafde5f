"""Second derivatives and curvature of an implicit polynomial's zero set, at any points.

Derivatives are exact: the coefficients of ∂²p/∂u_k∂u_l come from chaining the sparse
derivative maps of :mod:`ipfit.basis` (degree g → g−1 → g−2), then one design matrix of
degree g−2 evaluates all of them. The chain rule through the normalisation
u = (x − center) / scale divides the Hessian by scale².

Curvature convention: with n = ∇f / |∇f| (outward for a canonical fit, f > 0 outside), the
shape operator is S = P H P / |∇f| with P = I − n nᵀ, so convex shapes have positive
curvature (a circle or sphere of radius r: 1/r). The formulas are Goldman (2005),
"Curvature formulas for implicit curves and surfaces", CAGD 22.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.numeric import unit_rows_mask
from .._utils.validation import as_points

__all__ = ["Curvature", "curvature", "hessian", "derivatives_normalized"]


@lru_cache(maxsize=64)
def _second_maps(dim: int, degree: int) -> NDArray[np.float64]:
    # (dim, dim, d_{g-2}, d_g): coefficients of ∂²p/∂u_k∂u_l from those of p.
    first = basis.derivative_maps(dim, degree)
    second = basis.derivative_maps(dim, max(degree - 1, 0))
    d_low = basis.n_coefficients(dim, max(degree - 2, 0))
    out = np.zeros((dim, dim, d_low, basis.n_coefficients(dim, degree)))
    if degree >= 2:
        for k in range(dim):
            for m in range(dim):
                out[k, m] = (second[m] @ first[k]).toarray()
    out.setflags(write=False)
    return out


def derivatives_normalized(poly, u: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
    """p, ∇p (N, dim) and the Hessian of p (N, dim, dim) at normalised points ``u``."""
    values, grads = poly.evaluate_normalized(u, gradient=True)
    dim, degree = poly.dim, poly.degree
    low = basis.monomials(u, basis.exponents(dim, max(degree - 2, 0)))
    hess_coef = _second_maps(dim, degree) @ poly.coefficients  # (dim, dim, d_{g-2})
    hess = np.einsum("nc,klc->nkl", low, hess_coef)
    return values, grads, hess


def hessian(poly, points: ArrayLike) -> NDArray[np.float64]:
    """Hessian matrix of f at ``points`` in user coordinates, shape (N, dim, dim).

    >>> from ipfit import ImplicitPolynomial
    >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    >>> hessian(circle, [[0.5, 0.5]]).tolist()
    [[[2.0, 0.0], [0.0, 2.0]]]
    """
    pts = as_points(points, "points", dims=(poly.dim,))
    return derivatives_normalized(poly, poly.normalization.apply(pts))[2] / poly.scale ** 2


class Curvature(NamedTuple):
    """Curvature of the level set of f through each point (normally its zero set).

    Attributes
    ----------
    principal : (N, 1) in 2D (the curve's curvature), (N, 2) in 3D with k1 <= k2.
    directions : (N, dim−1, dim) unit principal directions (2D: the tangent).
    normals : (N, dim) unit normals ∇f / |∇f|.

    Rows where ∇f = 0 (singular points) are NaN.
    """

    principal: NDArray[np.float64]
    directions: NDArray[np.float64]
    normals: NDArray[np.float64]

    @property
    def mean(self) -> NDArray[np.float64]:
        """Mean curvature (k1 + k2) / 2; in 2D the curve's curvature."""
        return self.principal.mean(axis=1)

    @property
    def gaussian(self) -> NDArray[np.float64] | None:
        """Gaussian curvature k1·k2 (3D); None for a 2D curve."""
        return self.principal.prod(axis=1) if self.principal.shape[1] == 2 else None


def curvature(poly, points: ArrayLike) -> Curvature:
    """Principal curvatures and directions of the level set of f through ``points``.

    Parameters
    ----------
    poly : ImplicitPolynomial
    points : (N, dim) array in user coordinates (points on the zero set, usually, e.g. from
        :func:`ipfit.analysis.projection.project`).

    Returns
    -------
    Curvature
        ``.principal``, ``.directions``, ``.normals`` and the ``.mean`` and ``.gaussian``
        properties; positive for convex shapes with f > 0 outside.

    Examples
    --------
    A sphere of radius 2:

    >>> from ipfit.datasets.synthetic import sphere
    >>> c = curvature(sphere(radius=2.0).polynomial, [[2.0, 0.0, 0.0]])
    >>> c.mean.tolist(), c.gaussian.tolist()
    ([0.5], [0.25])
    """
    pts = as_points(points, "points", dims=(poly.dim,))
    dim = poly.dim
    _, grad_u, hess_u = derivatives_normalized(poly, poly.normalization.apply(pts))
    grad, hess = grad_u / poly.scale, hess_u / poly.scale ** 2
    normal, ok = unit_rows_mask(grad)
    length = np.linalg.norm(grad, axis=1)
    eye = np.eye(dim)
    proj = eye - normal[:, :, None] * normal[:, None, :]
    shape_op = proj @ hess @ proj / np.where(ok, length, 1.0)[:, None, None]
    # Lift the normal's eigenvalue (0) far above the tangent ones so that eigh's ascending
    # order puts the dim−1 principal curvatures first, even when one of them is 0 (cylinder).
    lift = 1.0 + 2.0 * np.abs(shape_op).sum(axis=(1, 2))
    values, vectors = np.linalg.eigh(shape_op + lift[:, None, None] * normal[:, :, None] * normal[:, None, :])
    principal = values[:, : dim - 1]
    directions = np.swapaxes(vectors[:, :, : dim - 1], 1, 2)
    principal[~ok] = np.nan
    directions[~ok] = np.nan
    normal[~ok] = np.nan
    return Curvature(principal, directions, normal)

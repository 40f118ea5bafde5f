"""Closest points on the zero set, and the true geometric distance to it.

For each query point q, starting points on the zero set come from exact ray intersections
(:mod:`ipfit.analysis.rays`) along the line through q in the direction of ∇f(q) — where Newton's
method on f along ∇f heads — and, as fallbacks when that line misses or ∇f(q) = 0, along
the line to the data's centre, the coordinate axes and the diagonals. The nearest of them is
then polished by Newton's method on the Lagrange conditions of the closest point,
u − q + λ∇f(u) = 0 and f(u) = 0, with the exact Hessian (:mod:`ipfit.analysis.curvature`); the
polished point is kept only if it lies on the zero set and is not farther than the starting
point, so the answer is never worse than an exact point of the zero set. All work is done in
normalised coordinates, where distances are of order one, and scaled back.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.numeric import unit_rows_mask
from .._utils.validation import as_points
from .curvature import derivatives_normalized
from .rays import intersect_rays

__all__ = ["Projection", "project", "distance_summary"]

_NEWTON_STEPS = 12


class Projection(NamedTuple):
    """Closest points on the zero set.

    Attributes
    ----------
    points : (N, dim) nearest points found on f = 0 (NaN where none was found).
    distances : (N,) distances to them in user units (inf where none was found).
    converged : (N,) True where the Lagrange-Newton polish met the closest-point conditions;
        False rows keep an exact point of the zero set, possibly not the nearest.
    """

    points: NDArray[np.float64]
    distances: NDArray[np.float64]
    converged: NDArray[np.bool_]


@lru_cache(maxsize=2)
def _fixed_directions(dim: int) -> tuple[NDArray, ...]:
    # Lines every 22.5° in 2D; axes, face and body diagonals (13 lines) in 3D. A closest point
    # that the ∇f line misses is usually near one of their hits, which Newton then polishes.
    if dim == 2:
        angles = np.pi * np.arange(8) / 8
        return tuple(np.column_stack([np.cos(angles), np.sin(angles)]))
    grid = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T
    keep = [v for v in grid if np.any(v) and v[np.flatnonzero(v)[0]] > 0]
    return tuple(v / np.linalg.norm(v) for v in keep)


def _nearest_line_hits(poly, pts: NDArray) -> NDArray[np.float64]:
    """Nearest intersection of lines through ``pts``: along ∇f, towards the data's centre, fixed ones."""
    unit, ok = unit_rows_mask(poly.gradient(pts))
    inward, ok_in = unit_rows_mask(poly.center - pts)
    fallback = np.eye(poly.dim)[0]
    directions = [np.where(ok[:, None], unit, fallback), np.where(ok_in[:, None], inward, fallback)]
    directions += list(_fixed_directions(poly.dim))
    best = np.full(pts.shape, np.nan)
    best_d = np.full(len(pts), np.inf)
    for d in directions:
        # Unit directions: |t| is the distance, so each line is searched only as far as the
        # nearest hit so far (roots farther out cannot be nearer; the search costs by the interval).
        hits = intersect_rays(pts, np.broadcast_to(d, pts.shape), poly, tmin=-best_d, tmax=best_d)
        t = np.where(np.isfinite(hits.t), np.abs(hits.t), np.inf)
        k = np.argmin(t, axis=1)
        dist = t[np.arange(len(pts)), k]
        closer = dist < best_d
        best[closer] = hits.points[np.flatnonzero(closer), k[closer]]
        best_d[closer] = dist[closer]
    return best


def _lagrange_newton(poly, q: NDArray, u: NDArray) -> tuple[NDArray, NDArray]:
    """Polish u towards the closest point to q on p = 0; returns u and a success mask."""
    dim = poly.dim
    _, grad, _ = derivatives_normalized(poly, u)
    g2 = np.einsum("nd,nd->n", grad, grad)
    lam = -np.einsum("nd,nd->n", u - q, grad) / np.where(g2 > 0, g2, 1.0)
    for _ in range(_NEWTON_STEPS):
        value, grad, hess = derivatives_normalized(poly, u)
        resid = np.concatenate([u - q + lam[:, None] * grad, value[:, None]], axis=1)
        jac = np.zeros((len(u), dim + 1, dim + 1))
        jac[:, :dim, :dim] = np.eye(dim) + lam[:, None, None] * hess
        jac[:, :dim, dim] = grad
        jac[:, dim, :dim] = grad
        solvable = np.abs(np.linalg.det(jac)) > 1e-200
        step = np.zeros_like(resid)
        if solvable.any():
            step[solvable] = np.linalg.solve(jac[solvable], resid[solvable][:, :, None])[:, :, 0]
        # A long step means Newton is not in its basin: stop moving that point.
        size = np.linalg.norm(step[:, :dim], axis=1)
        step[~(size <= 0.5)] = 0.0  # also drops NaN steps from a nearly singular system
        u = u - step[:, :dim]
        lam = lam - step[:, dim]
    value, grad, _ = derivatives_normalized(poly, u)
    terms = np.abs(basis.monomials(u, poly.exponents)) @ np.abs(poly.coefficients)
    on_set = np.abs(value) <= 1e-10 * np.maximum(terms, 1e-300)
    # Closest-point condition: q − u parallel to ∇f (or u = q).
    offset = q - u
    cross = np.linalg.norm(offset, axis=1) * np.linalg.norm(grad, axis=1) - np.abs(np.einsum("nd,nd->n", offset, grad))
    parallel = cross <= 1e-8 * (1.0 + np.linalg.norm(offset, axis=1) * np.linalg.norm(grad, axis=1))
    return u, on_set & parallel & np.all(np.isfinite(u), axis=1)


def project(poly, points: ArrayLike) -> Projection:
    """Nearest points on the zero set of ``poly`` and the distances to them.

    Parameters
    ----------
    poly : ImplicitPolynomial
    points : (N, dim) query points in user coordinates.

    Returns
    -------
    Projection
        ``points`` (on f = 0), ``distances`` (true geometric distance, user units) and
        ``converged``.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import circle
    >>> proj = project(circle(radius=2.0).polynomial, [[3.0, 4.0], [0.0, 0.5]])
    >>> proj.points.round(12).tolist(), proj.distances.round(12).tolist()
    ([[1.2, 1.6], [0.0, 2.0]], [3.0, 1.5])
    """
    pts = as_points(points, "points", dims=(poly.dim,))
    start = _nearest_line_hits(poly, pts)
    found = np.all(np.isfinite(start), axis=1)
    norm = poly.normalization
    q, u0 = norm.apply(pts), norm.apply(start)
    polished = np.full(pts.shape, np.nan)
    converged = np.zeros(len(pts), dtype=bool)
    if found.any():
        u, ok = _lagrange_newton(poly, q[found], u0[found])
        before = np.linalg.norm(u0[found] - q[found], axis=1)
        after = np.linalg.norm(u - q[found], axis=1)
        keep = ok & (after <= before * (1 + 1e-9) + 1e-12)
        u = np.where(keep[:, None], u, u0[found])
        polished[found] = norm.invert(u)
        converged[found] = keep
    distances = np.where(found, np.linalg.norm(polished - pts, axis=1), np.inf)
    return Projection(polished, distances, converged)


def distance_summary(poly, points: ArrayLike, max_points: int = 4000) -> dict[str, float]:
    """Mean and max of the true (projected) and the Taubin distances of ``points`` to f = 0.

    At most ``max_points`` evenly strided points are used (the summary is a statistic).

    >>> from ipfit.datasets.synthetic import circle
    >>> s = distance_summary(circle().polynomial, [[2.0, 0.0], [0.0, 3.0]])
    >>> round(s["projected_mean"], 12), round(s["taubin_mean"], 6)   # true (1 + 2) / 2; Taubin (3/4 + 8/6) / 2
    (1.5, 1.041667)
    """
    pts = as_points(points, "points", dims=(poly.dim,))
    pts = pts[:: max(1, -(-len(pts) // max_points))]
    true = project(poly, pts).distances
    taubin = poly.taubin_distance(pts)
    return {"projected_mean": float(np.mean(true)), "projected_max": float(np.max(true)),
            "taubin_mean": float(np.mean(taubin)), "taubin_max": float(np.max(taubin)), "n_points": len(pts)}

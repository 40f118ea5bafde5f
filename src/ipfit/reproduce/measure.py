"""What a run records about one fit: the paper's measures, geometric quality, time and coefficients.

Every entry is a plain dict (the experiments store them in ``results.json``); a quality that
cannot be measured (e.g. values overflowing over the box) is recorded as ``None`` with the
reason, never as an exception that stops the run.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .. import basis
from .._utils.numeric import unit_rows
from ..exceptions import IpfitError
from ..fitting.linear import DEFAULT_OFFSET, ridge_penalty
from ..fitting.objective import measures
from ..polynomial import Normalization
from ..zeroset.extract import extract_zero_set
from ..zeroset.quality import quality
from .config import Config
from .data import Data

__all__ = ["fit_entry", "quality_entry", "refine_summary", "history_entry", "zero_set_geometry", "ridge_scale",
           "area_perimeter", "contour_roundness"]

_NO_QUALITY = ("f_score", "recall", "precision", "chamfer_rel", "n_components", "n_spurious", "closed")


def quality_entry(poly, data: Data, cfg: Config) -> dict:
    """F-score, spurious components and closedness of ``poly``'s zero set against the whole shape."""
    try:
        q = quality(poly, data.ref_points, faces=data.ref_faces, ordered_contour=data.ordered,
                    resolution=cfg.quality_resolution_3d if data.dim == 3 else None,
                    max_samples=cfg.quality_max_samples)
    except IpfitError as exc:  # e.g. values overflowing over the box
        return dict.fromkeys(_NO_QUALITY) | {"error": str(exc)}
    return {"f_score": q.f_score, "recall": q.recall, "precision": q.precision,
            "chamfer_rel": q.chamfer / data.diagonal, "n_components": q.n_components,
            "n_spurious": q.n_spurious, "closed": q.closed}


def fit_entry(poly, data: Data, cfg: Config, seconds: float, *, delta: float | None = None, **extra) -> dict:
    """Measures (at ``delta``, default the run's δ), geometric quality, time and coefficients of a fit."""
    m = measures(poly, data.points, data.normals, delta=cfg.delta if delta is None else delta)
    out = {"degree": poly.degree, "method": poly.method, "distance": float(m.distance),
           "dissimilarity": float(m.dissimilarity), "smoothness": float(m.smoothness), "seconds": float(seconds)}
    out.update(quality_entry(poly, data, cfg))
    out.update(extra)
    out["coefficients"] = [float(c) for c in poly.coefficients]
    return out


def _improvement(start: float, final: float) -> float | None:
    """How much lower ``final`` is than the best start fit's distance, as a share of it."""
    return (start - final) / start if start > 0 else None


def refine_summary(result) -> dict:
    """Iterations, evaluations, best start fit and improvement of a :class:`~ipfit.fitting.refine.RefineResult`."""
    seed = float(result.best_start_value)
    return {"nit": int(result.nit), "nfev": int(result.nfev), "best_seed": result.best_start,
            "best_seed_distance": seed, "refine_seconds": float(result.seconds),
            "improvement": _improvement(seed, float(result.distance))}


def history_entry(res, history: Iterable[float], *, nfev: int | None = None, seconds: float | None = None,
                  best_seed_distance: float | None = None, switch: int | None = None) -> dict:
    """A convergence curve (best distance per iteration) and how the refinement ``res`` ended.

    ``switch`` is the iteration where the polish took over from the metaheuristic.
    """
    seed = float(res.best_start_value if best_seed_distance is None else best_seed_distance)
    final = float(res.distance)
    return {"history": [float(f"{h:.6g}") for h in history], "final": final, "nit": int(res.nit),
            "nfev": int(res.nfev if nfev is None else nfev),
            "seconds": float(res.seconds if seconds is None else seconds), "best_seed_distance": seed,
            "improvement": _improvement(seed, final), "polish_from": switch}


def area_perimeter(closed: NDArray) -> tuple[float, float]:
    """Area and perimeter of a closed polyline (last point equal to the first).

    >>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    >>> area, perimeter = area_perimeter(square)
    >>> area, perimeter, round(4 * math.pi * area / perimeter ** 2, 4)
    (1.0, 4.0, 0.7854)
    """
    x, y = closed[:, 0], closed[:, 1]
    area = 0.5 * abs(float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1])))
    perimeter = float(np.linalg.norm(np.diff(closed, axis=0), axis=1).sum())
    return area, perimeter


def contour_roundness(points: NDArray) -> float:
    """4πA/P² of an ordered contour (1 for a circle)."""
    area, perimeter = area_perimeter(np.vstack([points, points[:1]]))
    return 4 * math.pi * area / perimeter ** 2


def zero_set_geometry(poly, data: Data) -> dict:
    """2D: roundness 4πA/P² of the largest closed curve; data-to-curve distances / box diagonal."""
    try:
        zs = extract_zero_set(poly, points=data.ref_points, resolution=600)
    except IpfitError:
        return {"roundness": None, "p95_error": None, "max_error": None}
    best = None
    for curve, closed in zip(zs.curves, zs.curve_closed, strict=True):
        if closed:
            area, perimeter = area_perimeter(curve)
            if perimeter > 0 and (best is None or area > best[0]):
                best = (area, perimeter)
    out: dict[str, Any] = {"roundness": None if best is None else 4 * math.pi * best[0] / best[1] ** 2,
                           "p95_error": None, "max_error": None}
    if not zs.is_empty:
        dist, _ = cKDTree(zs.sample(zs.step / 2).points).query(data.ref_points)
        out["p95_error"] = float(np.quantile(dist, 0.95)) / data.diagonal
        out["max_error"] = float(dist.max()) / data.diagonal
    return out


def ridge_scale(data: Data, degree: int) -> dict:
    """How heavy κ·D is against the 3L system: the ratios D_αα / (AᵀA)_αα over the coefficients α.

    A is the 3L design matrix (points and their ±c offsets along the normals, normalised
    coordinates, c = ipfit's default offset) and D :func:`~ipfit.fitting.linear.ridge_penalty`.
    κ times these ratios is the ridge weight relative to the data, per coefficient.
    """
    u = Normalization.from_points(data.points).apply(data.points)
    n = unit_rows(data.normals)
    exps = basis.exponents(data.dim, degree)
    rows = basis.monomials(np.concatenate([u, u + DEFAULT_OFFSET * n, u - DEFAULT_OFFSET * n]), exps)
    ratio = ridge_penalty(u, exps) / np.einsum("ij,ij->j", rows, rows)
    return {"median": float(np.median(ratio)), "min": float(ratio.min()), "max": float(ratio.max())}

"""Geometric quality of a fit, measured on its extracted zero set, not on the objective.

With a tolerance τ (default 2 % of the data's bounding-box diagonal):

* **recall**: the fraction of data points within τ of the zero set;
* **precision**: the fraction of the zero set (by length or area) within τ of the data's
  shape. The shape is the data's faces (densely sampled) for a mesh, its polyline for an
  ordered contour, and the points themselves for a bare cloud: measured against the sparse
  vertices of a mesh alone, even a perfect fit would score low;
* **f_score**: their harmonic mean;
* **chamfer**: the symmetric Chamfer distance, the mean of the two mean nearest distances
  (data → zero set and zero set → shape);
* **n_components** / **n_spurious**: pieces of the zero set inside the box, and those with
  no part within τ of the shape;
* **closed**: whether the zero set closes inside the box.

Distances are nearest-sample distances to dense samples (spacing τ/6 by default), so they
overestimate the true distances by at most about τ/9.

>>> from ipfit.datasets import synthetic
>>> shape = synthetic.circle()
>>> q = quality(shape.polynomial, shape.points)
>>> q.f_score, q.n_spurious, q.closed
(1.0, 0, True)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validation import as_points, check_int, check_positive, error
from .polynomial import ImplicitPolynomial
from .zeroset import Samples, ZeroSet, extract_zero_set, sample_segments, sample_triangles

__all__ = ["Quality", "quality", "looks_like_contour", "DEFAULT_TAU_FRACTION"]

DEFAULT_TAU_FRACTION = 0.02
DEFAULT_MAX_SAMPLES = 2_000_000


@dataclass(frozen=True)
class Quality:
    """Geometric quality measures of one fit; see :mod:`ipfit.quality`.

    Attributes
    ----------
    recall, precision, f_score : fractions in [0, 1].
    chamfer : symmetric Chamfer distance in user units (inf when the zero set is empty).
    n_components, n_spurious : pieces of the zero set in the box, and those far from the data.
    closed : the zero set is non-empty and closes inside the box.
    tau : the tolerance used, in user units.
    data_to_zero_set, zero_set_to_data : the two one-sided mean distances.
    grid_step : the extraction grid's step (the zero set's own accuracy).
    reference : what precision was measured against: "faces", "contour" or "points".
    """

    recall: float
    precision: float
    f_score: float
    chamfer: float
    n_components: int
    n_spurious: int
    closed: bool
    tau: float
    data_to_zero_set: float
    zero_set_to_data: float
    grid_step: float
    reference: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (infinite distances become None)."""
        out = asdict(self)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        return out

    def __str__(self) -> str:
        return "\n".join(f"{k:<17} {_fmt(v)}" for k, v in asdict(self).items())


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def looks_like_contour(points: ArrayLike) -> bool:
    """Heuristic: are 2D ``points`` listed in order along a contour?

    True when consecutive points are about as close as nearest neighbours (95th
    percentiles within a factor 4); a shuffled cloud has consecutive gaps of the order of
    its diameter.
    """
    pts = as_points(points)
    if pts.shape[1] != 2 or len(pts) < 4:
        return False
    from scipy.spatial import cKDTree

    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    nearest = cKDTree(pts).query(pts, k=2)[0][:, 1]
    scale = float(np.quantile(nearest, 0.95))
    if scale == 0:
        return False
    return bool(np.quantile(gaps, 0.95) <= 4 * scale)


def _check_faces(faces: ArrayLike, n_points: int, dim: int) -> NDArray[np.int64]:
    if dim != 3:
        raise error("faces", "None for 2D data", "faces", "Faces describe 3D meshes; pass ordered_contour for 2D.")
    try:
        arr = np.asarray(faces)
    except (TypeError, ValueError):
        raise error("faces", "an (F, 3) integer array", type(faces).__name__) from None
    if arr.ndim != 2 or arr.shape[1] != 3 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        raise error("faces", "an (F, 3) integer array of point indices", f"shape {arr.shape}, dtype {arr.dtype}",
                    "Pass triangles; split polygons first.")
    if arr.size and (arr.min() < 0 or arr.max() >= n_points):
        raise error("faces", f"indices in [0, {n_points})", f"indices in [{arr.min()}, {arr.max()}]",
                    "Faces must index the rows of points.")
    return arr.astype(np.int64)


def _contour_samples(points: NDArray, spacing: float, max_samples: int) -> Samples:
    starts, ends = points[:-1], points[1:]
    gaps = np.linalg.norm(ends - starts, axis=1)
    closing = float(np.linalg.norm(points[0] - points[-1]))
    # Close the loop unless its last gap is far longer than the typical one (an open curve).
    if closing > 0 and closing <= 10 * float(np.median(gaps)):
        starts = np.vstack([starts, points[-1:]])
        ends = np.vstack([ends, points[:1]])
    return sample_segments(starts, ends, spacing, max_samples=max_samples)


def quality(model: ImplicitPolynomial | ZeroSet, points: ArrayLike, *, faces: ArrayLike | None = None,
            ordered_contour: bool = False, tau: float | None = None,
            tau_fraction: float = DEFAULT_TAU_FRACTION, bounds: ArrayLike | None = None, margin: float = 0.25,
            resolution: int | Sequence[int] | None = None, spacing: float | None = None,
            max_samples: int = DEFAULT_MAX_SAMPLES) -> Quality:
    """Measure how well the zero set of ``model`` matches the data, geometrically.

    Parameters
    ----------
    model : ImplicitPolynomial or ZeroSet
        A polynomial (its zero set is extracted over the data's box grown by ``margin``,
        or over ``bounds``) or an already extracted :class:`~ipfit.zeroset.ZeroSet`.
    points : (N, dim) data points.
    faces : (F, 3) int array, optional
        Triangles over ``points`` when the data is a mesh: precision is then measured
        against dense samples of the faces.
    ordered_contour : bool
        2D: the points are in order along a contour (closed unless the last gap is far
        longer than the others); precision is measured against the polyline.
    tau : tolerance in user units; default ``tau_fraction`` × the data's box diagonal.
    bounds, margin, resolution : passed to :func:`ipfit.zeroset.extract_zero_set`.
    spacing : sample spacing of the zero set and of the data's shape; default τ/6.
    max_samples : cap on each sample set (the spacing grows beyond it).

    Returns
    -------
    Quality
    """
    pts = as_points(points, min_points=2)
    dim = pts.shape[1]
    if isinstance(model, ImplicitPolynomial):
        if model.dim != dim:
            raise error("points", f"{model.dim}D points to match the polynomial", f"{dim}D points")
        zs = extract_zero_set(model, bounds=bounds, points=pts, margin=margin, resolution=resolution)
    elif isinstance(model, ZeroSet):
        if model.dim != dim:
            raise error("points", f"{model.dim}D points to match the zero set", f"{dim}D points")
        zs = model
    else:
        raise error("model", "an ImplicitPolynomial or a ZeroSet", type(model).__name__)
    diagonal = float(np.linalg.norm(np.ptp(pts, axis=0)))
    if tau is None:
        if diagonal == 0:
            raise error("points", "points with some extent", "identical points", "Pass tau explicitly.")
        tau = check_positive(tau_fraction, "tau_fraction") * diagonal
    tau = check_positive(tau, "tau")
    spacing = tau / 6 if spacing is None else check_positive(spacing, "spacing")
    max_samples = check_int(max_samples, "max_samples", minimum=1000)

    if faces is not None:
        ref = sample_triangles(pts, _check_faces(faces, len(pts), dim), spacing, max_samples=max_samples)
        reference = "faces"
        if ref.points.shape[0] == 0:
            ref, reference = Samples(pts, np.ones(len(pts)), np.full(len(pts), -1)), "points"
    elif ordered_contour:
        ref, reference = _contour_samples(pts, spacing, max_samples), "contour"
    else:
        ref, reference = Samples(pts, np.ones(len(pts)), np.full(len(pts), -1)), "points"

    n_components = zs.n_components
    if zs.is_empty:
        return Quality(0.0, 0.0, 0.0, math.inf, 0, 0, False, tau, math.inf, math.inf, zs.step, reference)

    from scipy.spatial import cKDTree

    samples = zs.sample(spacing, max_samples=max_samples)
    d_data, _ = cKDTree(samples.points).query(pts, workers=-1)
    d_zero, _ = cKDTree(ref.points).query(samples.points, workers=-1)
    recall = float(np.mean(d_data <= tau))
    w = samples.weights
    total = float(w.sum())
    if total > 0:
        precision = float(w[d_zero <= tau].sum() / total)
        zero_to_data = float(np.dot(w, d_zero) / total)
    else:  # a zero set of degenerate (zero-length) pieces: weigh the samples alike
        precision = float(np.mean(d_zero <= tau))
        zero_to_data = float(d_zero.mean())
    data_to_zero = float(d_data.mean())
    f_score = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    nearest = np.full(n_components, np.inf)
    np.minimum.at(nearest, samples.labels, d_zero)
    n_spurious = int(np.sum(nearest > tau))
    return Quality(recall=recall, precision=precision, f_score=float(f_score),
                   chamfer=0.5 * (data_to_zero + zero_to_data), n_components=n_components,
                   n_spurious=n_spurious, closed=zs.closed, tau=tau, data_to_zero_set=data_to_zero,
                   zero_set_to_data=zero_to_data, grid_step=zs.step, reference=reference)

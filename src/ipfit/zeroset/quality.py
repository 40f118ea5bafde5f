"""Geometric quality of a fit, measured on its extracted zero set, not on the objective.

With a tolerance τ (default 2 % of the data's bounding-box diagonal):

* **recall**: the fraction of data points within τ of the zero set;
* **precision**: the fraction of the zero set (by length or area) within τ of the data's
  shape. The shape is the data's faces for a mesh, its polyline for an
  ordered contour, and the points themselves for a bare cloud: measured against the sparse
  vertices of a mesh alone, even a perfect fit would score low. For a bare cloud the surface
  between the points is unknown, and the exact zero set passes up to half a gap from every
  point, so a zero-set sample counts as within τ of the shape when its nearest data point is
  at most √(τ² + s²) away, s being that point's local spacing (the distance to its
  ``dim``-th nearest neighbour): τ where the cloud is dense, more only where its gaps are
  wider than τ (a 600-point sphere's exact polynomial scored F = 0.84 with τ alone);
* **f_score**: their harmonic mean;
* **chamfer**: the symmetric Chamfer distance, the mean of the two mean nearest distances
  (data → zero set and zero set → shape);
* **n_components** / **n_spurious**: pieces of the zero set inside the box, and those with
  no part within τ of the shape;
* **closed**: whether the zero set closes inside the box;
* **topology**, **data_topology**, **topology_matches**: the zero set's loops and their nesting
  (2D) or components and genus (3D), specks left out, against the data's, with its confidence
  (:mod:`ipfit.zeroset.topology`); ``topology_matches`` is None when the data's is not known
  well enough to say.

Distances are exact distances to the zero set's segments or triangles (and to the data's
contour segments or faces), found among the elements of the nearest samples of that shape.
Every "within τ" decision (recall, precision, spurious components) is exact: a point with
no candidate within τ gets more candidates until none within τ can have been missed.
Distances within 2τ are exact whenever the nearest element is among the candidates (and
never exceed the nearest sample's); farther ones, which only enter the Chamfer distance,
are estimates. Precision weighs the zero set by one sample per piece of it at most τ long
(one per segment or triangle of the extraction at the default resolutions, whose elements
are shorter than τ). The extracted zero set itself is accurate to about one grid step.

>>> from ipfit.datasets import synthetic
>>> shape = synthetic.circle()
>>> q = quality(shape.polynomial, shape.points)
>>> q.f_score, q.n_spurious, q.closed
(1.0, 0, True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import check_int, check_positive, error
from ..cloud import Cloud, as_cloud
from ..geometry.distance import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_TAU_FRACTION,
    Samples,
    Target,
    data_target,
    mesh_target,
    query_workers,
)
from ..polynomial import ImplicitPolynomial
from .extract import ZeroSet, extract_zero_set
from .topology import Topology, data_topology, zero_set_topology

__all__ = ["Quality", "quality", "spurious_components", "stray_samples", "missed_points", "looks_like_contour",
           "DEFAULT_TAU_FRACTION"]


@dataclass(frozen=True)
class Quality:
    """Geometric quality measures of one fit; see :mod:`ipfit.zeroset.quality`.

    Attributes
    ----------
    recall, precision, f_score : fractions in [0, 1].
    chamfer : symmetric Chamfer distance in user units (inf when the zero set is empty).
    n_components, n_spurious : pieces of the zero set in the box, and those far from the data.
    closed : the zero set is non-empty and closes inside the box.
    n_open : pieces near the data (not spurious) that leave the box: an open sheet or curve
        where the data is closed, as opposed to a stray piece far away reaching the box's edge.
    tau : the tolerance used, in user units.
    data_to_zero_set, zero_set_to_data : the two one-sided mean distances.
    grid_step : the extraction grid's step (the zero set's own accuracy).
    reference : what precision was measured against: "faces", "contour" or "points".
    spurious : one record per spurious component: its ``size`` (length in 2D, area in 3D,
        user units), ``share`` of the zero set's total size, ``center`` (mean position) and
        ``distance`` (nearest approach to the data).
    topology, data_topology : the zero set's :class:`~ipfit.zeroset.topology.Topology` (specks
        left out) and the data's (with its confidence); None when not measured.
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
    spurious: tuple[dict, ...] = ()
    n_open: int = 0
    topology: Topology | None = None
    data_topology: Topology | None = None

    @property
    def topology_matches(self) -> bool | None:
        """Whether the zero set has the data's topology; None when either is unknown (the data's
        confidence "low" or "unknown", or not measured)."""
        if self.topology is None or self.data_topology is None:
            return None
        return self.data_topology.matches(self.topology)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Quality:
        """The quality :meth:`to_dict` wrote (a result file's ``quality``): None distances become
        infinite again, the topologies :class:`~ipfit.zeroset.topology.Topology` objects; keys it
        does not know (``topology_matches``, which is derived) are left out."""
        values = {name: data[name] for name in cls.__dataclass_fields__ if name in data}
        for name in ("chamfer", "data_to_zero_set", "zero_set_to_data"):
            if name in values and values[name] is None:
                values[name] = math.inf
        values["spurious"] = tuple(dict(c) for c in data.get("spurious") or ())
        for name in ("topology", "data_topology"):
            values[name] = Topology.from_dict(data[name]) if data.get(name) else None
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (infinite distances become None)."""
        out = asdict(self)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        out["spurious"] = [dict(c) for c in self.spurious]
        for key in ("topology", "data_topology"):
            value = getattr(self, key)
            out[key] = None if value is None else value.to_dict()
        out["topology_matches"] = self.topology_matches
        return out

    def __str__(self) -> str:
        rows = {**asdict(self), "topology": self.topology and self.topology.describe(),
                "data_topology": self.data_topology and self.data_topology.describe(),
                "topology_matches": self.topology_matches}
        return "\n".join(f"{k:<17} {_fmt(v)}" for k, v in rows.items())


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


#: Zero-set samples of a bare cloud farther than this many τ from every point are judged within
#: a sampling gap (:func:`_within_gaps`) only after every point's spacing is known.
_NEAR_GAPS = 4.0


def looks_like_contour(points: ArrayLike | Cloud) -> bool:
    """Heuristic: are 2D ``points`` listed in order along a contour?

    True when consecutive points are about as close as nearest neighbours (95th
    percentiles within a factor 4); a shuffled cloud has consecutive gaps of the order of
    its diameter.
    """
    pts = as_cloud(points).points
    if pts.shape[1] != 2 or len(pts) < 4:
        return False
    from scipy.spatial import cKDTree

    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    nearest = cKDTree(pts).query(pts, k=2)[0][:, 1]
    scale = float(np.quantile(nearest, 0.95))
    if scale == 0:
        return False
    return bool(np.quantile(gaps, 0.95) <= 4 * scale)


def _within_gaps(cloud: Cloud, ref: Target, query: NDArray, d_zero: NDArray, tau: float) -> NDArray[np.bool_]:
    """Zero-set samples within τ of the surface a bare cloud samples: within √(τ² + s²) of
    their nearest data point (``ref`` holds the cloud's points), s its local spacing (see the
    module notes)."""
    within = d_zero <= tau
    maybe = np.flatnonzero(~within)
    if not maybe.size:
        return within
    # Samples near the data need the spacing of their nearest points only; every point's (whose
    # largest bounds the reach) only for samples farther out: a 10⁶-point cloud's spacings took
    # 1.8 s of the 4.4 s its one measurement took, for a few hundred samples beyond τ.
    def judge(rows: NDArray[np.intp], reach: float, spacing_at) -> NDArray[np.intp]:
        """Decide the samples ``rows`` whose nearest point lies within ``reach``; return the others."""
        d, nearest = ref.tree.query(query[rows], distance_upper_bound=reach, workers=query_workers(rows.size))
        found = np.isfinite(d)
        within[rows[found]] = d[found] <= np.sqrt(tau**2 + spacing_at(nearest[found]) ** 2)
        return rows[~found]

    near = _NEAR_GAPS * tau
    far = judge(maybe, near, lambda at: cloud.point_spacing_at(at, cloud.dim))
    if far.size:
        spacing = cloud.point_spacing(cloud.dim)
        reach = math.sqrt(tau**2 + float(spacing.max(initial=0.0)) ** 2)
        if reach > near:
            judge(far, reach, lambda at: spacing[at])
    return within


def quality(model: ImplicitPolynomial | ZeroSet, points: ArrayLike | Cloud, *, faces: ArrayLike | None = None,
            ordered_contour: bool = False, tau: float | None = None,
            tau_fraction: float = DEFAULT_TAU_FRACTION, bounds: ArrayLike | None = None, margin: float = 0.25,
            resolution: int | Sequence[int] | None = None, spacing: float | None = None,
            max_samples: int = DEFAULT_MAX_SAMPLES) -> Quality:
    """Measure how well the zero set of ``model`` matches the data, geometrically.

    Parameters
    ----------
    model : ImplicitPolynomial or ZeroSet
        A polynomial (its zero set is extracted over the data's box grown by ``margin``,
        or over ``bounds``) or an already extracted :class:`~ipfit.zeroset.extract.ZeroSet`.
    points : (N, dim) data points, or a :class:`~ipfit.Cloud`: then its faces are used, and
        it keeps the data's side of the measurement and the last few measurements (measuring
        the same polynomial on it again computes nothing).
    faces : (F, 3) int array, optional
        Triangles over ``points`` when the data is a mesh: precision is then measured
        against the faces. None with a cloud.
    ordered_contour : bool
        2D: the points are in order along a contour (closed unless the last gap is far
        longer than the others); precision is measured against the polyline.
    tau : tolerance in user units; default ``tau_fraction`` × the data's box diagonal.
    bounds, margin, resolution : passed to :func:`ipfit.zeroset.extract.extract_zero_set`.
    spacing : sample spacing of the zero set and of the data's shape; default τ. The
        samples weigh the zero set for precision (every element keeps at least one) and
        find the candidate segments or faces for the distances, which are then computed
        exactly; a finer spacing refines only the precision's quadrature.
    max_samples : cap on each sample set (the spacing grows beyond it).

    Returns
    -------
    Quality
    """
    return _measure(model, points, faces=faces, ordered_contour=ordered_contour, tau=tau, tau_fraction=tau_fraction,
                    bounds=bounds, margin=margin, resolution=resolution, spacing=spacing,
                    max_samples=max_samples)[0]


def spurious_components(zero_set: ZeroSet, points: ArrayLike | Cloud, **options) -> NDArray[np.bool_]:
    """Which pieces of ``zero_set`` are spurious: no part within τ of the data's shape.

    One flag per component, numbered as ``zero_set.component_labels`` (2D: per curve);
    their count is :attr:`Quality.n_spurious`. ``options`` are those of :func:`quality`.

    Two ovals, (x² − 1)² + y² = 1/4, and data along the right one only:

    >>> from ipfit.datasets import synthetic
    >>> two = synthetic.from_terms(2, 4, {(4, 0): 1, (2, 0): -2, (0, 2): 1, (0, 0): 0.75})
    >>> zs = extract_zero_set(two, bounds=[[-2, 2], [-1, 1]])
    >>> right = np.concatenate([c for c in zs.curves if c[:, 0].mean() > 0])
    >>> flags = spurious_components(zs, right)
    >>> [("right" if c[:, 0].mean() > 0 else "left", bool(f)) for c, f in zip(zs.curves, flags)]
    [('left', True), ('right', False)]
    """
    if not isinstance(zero_set, ZeroSet):
        raise error("zero_set", "a ZeroSet (ipfit.extract_zero_set)", type(zero_set).__name__)
    options, cloud = _options(points, options)
    if zero_set.dim != cloud.dim:
        raise error("points", f"{zero_set.dim}D points to match the zero set", f"{cloud.dim}D points")
    # Only the zero set's side of a measurement: the data's distances to it do not flag a piece.
    tau, spacing, max_samples, ref, _ = _data_side(cloud, **options)
    if zero_set.is_empty:
        return np.zeros(0, dtype=bool)
    samples = zero_set.sample(spacing, max_samples=max_samples)
    return _nearest_per_component(zero_set, samples, ref.distance(samples.points)) > tau


def stray_samples(model: ImplicitPolynomial | ZeroSet, points: ArrayLike | Cloud, *, most: int = 400,
                  distance: float | None = None, spurious_only: bool = False, **options) -> NDArray[np.float64]:
    """Up to ``most`` samples (evenly taken) of the zero set farther than ``distance`` (default τ)
    from the data's shape: the part that costs precision (spurious components, bulges, sheets).
    With ``spurious_only``, only samples of the spurious components (no part within τ of the
    data). ``options`` are those of :func:`quality`.

    >>> from ipfit.datasets import synthetic
    >>> two = synthetic.from_terms(2, 4, {(4, 0): 1, (2, 0): -2, (0, 2): 1, (0, 0): 0.75})
    >>> zs = extract_zero_set(two, bounds=[[-2, 2], [-1, 1]])
    >>> right = np.concatenate([c for c in zs.curves if c[:, 0].mean() > 0])
    >>> bool(np.all(stray_samples(zs, right)[:, 0] < 0))
    True
    """
    _, flags, samples, d_zero, tau, _ = _measure(model, points, **options, details=True)
    far = d_zero > (tau if distance is None else check_positive(distance, "distance"))
    if spurious_only:
        far &= flags[samples.labels] if len(flags) else False
    far = samples.points[far]
    return far[:: max(1, -(-len(far) // check_int(most, "most", minimum=1)))]


def missed_points(model: ImplicitPolynomial | ZeroSet, points: ArrayLike | Cloud, *, distance: float | None = None,
                  **options) -> NDArray[np.bool_]:
    """Which data points have no zero set within ``distance`` (default τ): the part of the data
    that costs recall (a thin part the zero set cuts short, a hole in it). One flag per point;
    ``options`` are those of :func:`quality` (a cloud's measurement of the same polynomial is
    reused).

    >>> from ipfit.datasets import synthetic
    >>> circle = synthetic.from_terms(2, 2, {(2, 0): 1, (0, 2): 1, (0, 0): -1})
    >>> points = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, 0.0]])
    >>> missed_points(circle, points, tau=0.1).tolist()
    [False, False, True]
    """
    _, _, _, _, tau, d_data = _measure(model, points, **options, details=True)
    return d_data > (tau if distance is None else check_positive(distance, "distance"))


def _measure(model, points, *, details: bool = False, **options):
    """(Quality, spurious flags) or, with ``details``, (None, flags, zero-set samples, their
    distances to the shape, τ, the data points' distances to the zero set). A cloud keeps the
    last few measurements of polynomials, so that a repair's stray samples reuse the measurement
    that judged its degree."""
    options, cloud = _options(points, options)
    if not isinstance(model, ImplicitPolynomial):
        found = _measure_now(model, cloud, **options)
    else:
        # The polynomial (its coefficients in its normalisation) and the settings name a measurement.
        key = (model.coefficients.tobytes(), model.normalization.center.tobytes(), model.normalization.scale,
               repr(sorted(options.items())))
        found = cloud.derived("measurement", key, lambda: _measure_now(model, cloud, **options),
                              keep=_MEASUREMENTS_KEPT)
    q, flags, samples, d_zero, tau, d_data = found
    return (None, flags, samples, d_zero, tau, d_data) if details else (q, flags)


def _options(points, options: dict) -> tuple[dict, Cloud]:
    """The measurement's options with their defaults (faces taken out), and the data as a cloud."""
    unknown = set(options) - set(_MEASURE_DEFAULTS)
    if unknown:
        raise TypeError(f"unexpected keyword argument {sorted(unknown)[0]!r}")
    options = {**_MEASURE_DEFAULTS, **options, "ordered_contour": bool(options.get("ordered_contour"))}
    return options, as_cloud(points, faces=options.pop("faces"), min_points=2)


def _data_side(cloud: Cloud, *, ordered_contour, tau, tau_fraction, spacing, max_samples, **_extraction):
    """τ, the sample spacing and cap, and the data's shape as a distance target with its name
    (kept on ``cloud``: the same for every degree and repair round)."""
    diagonal = float(np.linalg.norm(np.ptp(cloud.points, axis=0)))
    if tau is None:
        if not 0 < diagonal < np.inf:  # tau defaults to a fraction of the diagonal: none to take
            raise error("points", "points whose box has a diagonal > 0 and finite in float64",
                        f"a diagonal of {diagonal:.3g}",
                        "Pass the tolerance tau= (ipfit score --tau), or other points.")
        tau = check_positive(tau_fraction, "tau_fraction") * diagonal
    tau = check_positive(tau, "tau")
    # Samples only find candidate elements (distances are exact to those) and weigh the zero
    # set for precision. At τ the zero set keeps one sample per element of the extraction
    # (shorter than τ at the default resolutions). Sampling at τ/3, as before, made about 4x
    # as many samples of the zero set in 3D and 8x as many of the data's faces, for F, P and R
    # within 0.002 and identical spurious counts on the bundled datasets (bench_quality.py).
    spacing = tau if spacing is None else check_positive(spacing, "spacing")
    max_samples = check_int(max_samples, "max_samples", minimum=1000)
    ref, reference = cloud.derived("data_target", (bool(ordered_contour), spacing, max_samples, tau),
                                   lambda: data_target(cloud.points, cloud.faces, ordered_contour, spacing,
                                                       max_samples, tau, lambda: cloud.kdtree))
    return tau, spacing, max_samples, ref, reference


def _nearest_per_component(zs: ZeroSet, samples, d_zero: NDArray) -> NDArray[np.float64]:
    """Each component's smallest sample distance to the data's shape (inf for a piece without samples)."""
    nearest = np.full(zs.n_components, np.inf)
    np.minimum.at(nearest, samples.labels, d_zero)
    return nearest


# A degree and its repair rounds measure a few polynomials, each kept with its zero set's samples.
_MEASUREMENTS_KEPT = 4
_MEASURE_DEFAULTS = dict(faces=None, ordered_contour=False, tau=None, tau_fraction=DEFAULT_TAU_FRACTION, bounds=None,
                         margin=0.25, resolution=None, spacing=None, max_samples=DEFAULT_MAX_SAMPLES)


def _measure_now(model, cloud: Cloud, *, ordered_contour, tau, tau_fraction, bounds, margin, resolution, spacing,
                 max_samples):
    """(Quality, spurious flags, zero-set samples, their distances to the shape, τ, the data
    points' distances to the zero set)."""
    pts, dim = cloud.points, cloud.dim
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
    tau, spacing, max_samples, ref, reference = _data_side(cloud, ordered_contour=ordered_contour, tau=tau,
                                                           tau_fraction=tau_fraction, spacing=spacing,
                                                           max_samples=max_samples)

    n_components = zs.n_components
    shape = data_topology(cloud, bool(ordered_contour))
    if zs.is_empty:
        return (Quality(recall=0.0, precision=0.0, f_score=0.0, chamfer=math.inf, n_components=0, n_spurious=0,
                        closed=False, tau=tau, data_to_zero_set=math.inf, zero_set_to_data=math.inf,
                        grid_step=zs.step, reference=reference, topology=zero_set_topology(zs),
                        data_topology=shape), np.zeros(0, dtype=bool),
                Samples(np.empty((0, dim)), np.empty(0), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)),
                np.empty(0), tau, np.full(len(pts), math.inf))

    samples = zs.sample(spacing, max_samples=max_samples)
    if dim == 2:
        starts, ends, _ = zs.segments()
        target = Target(samples, "segments", (starts, ends), tau=tau)
    else:
        # a 3D zero set that is not empty has its mesh
        target = mesh_target(cast(NDArray[np.float64], zs.vertices), cast(NDArray[np.int64], zs.faces), samples, tau)
    d_data = target.distance(pts)
    d_zero = ref.distance(samples.points)
    recall = float(np.mean(d_data <= tau))
    within = _within_gaps(cloud, ref, samples.points, d_zero, tau) if reference == "points" else d_zero <= tau
    w = samples.weights
    total = float(w.sum())
    if total > 0:
        precision = float(w[within].sum() / total)
        zero_to_data = float(np.dot(w, d_zero) / total)
    else:  # a zero set of degenerate (zero-length) pieces: weigh the samples alike
        precision = float(np.mean(within))
        zero_to_data = float(d_zero.mean())
    data_to_zero = float(d_data.mean())
    f_score = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    nearest = _nearest_per_component(zs, samples, d_zero)
    flags = nearest > tau
    spurious = _spurious_components(samples, nearest, tau)
    return (Quality(recall=recall, precision=precision, f_score=float(f_score),
                    chamfer=0.5 * (data_to_zero + zero_to_data), n_components=n_components,
                    n_spurious=int(flags.sum()), closed=zs.closed, tau=tau, data_to_zero_set=data_to_zero,
                    zero_set_to_data=zero_to_data, grid_step=zs.step, reference=reference, spurious=spurious,
                    n_open=int((zs.component_open & ~flags).sum()),
                    topology=zero_set_topology(zs, spurious, flags, tau), data_topology=shape),
            flags, samples, d_zero, tau, d_data)


def _spurious_components(samples, nearest: NDArray, tau: float) -> tuple[dict, ...]:
    """Size, share, position and distance of every component that never comes within τ of the data."""
    n = len(nearest)
    size = np.bincount(samples.labels, weights=samples.weights, minlength=n)
    count = np.maximum(np.bincount(samples.labels, minlength=n), 1)
    center = np.stack([np.bincount(samples.labels, weights=samples.points[:, j], minlength=n) / count
                       for j in range(samples.points.shape[1])], axis=1)
    total = float(size.sum()) or 1.0
    return tuple({"size": float(size[i]), "share": float(size[i] / total), "center": center[i].tolist(),
                  "distance": float(nearest[i])} for i in np.flatnonzero(nearest > tau))

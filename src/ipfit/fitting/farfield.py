"""Far-field information: what the zero set must *not* do away from the data.

The paper's objective only looks at the data points, so nothing stops a fit from growing
extra sheets or loops elsewhere in the box. Grid samples of the box away from the data
carry their signed distance to the data (sign from the nearest point's normal):

* the linear fits add them as weighted rows with target f ≈ signed distance
  (``far_weight`` of :func:`ipfit.fit_3l`, :func:`ipfit.fit_ridge`,
  :func:`ipfit.fit_gradient_one`);
* the metaheuristics and the polish add :class:`FarFieldTerm` to the objective: a penalty
  where f has the wrong sign, or where the zero set comes close to a sample (its Taubin
  distance is a small fraction of the sample's distance to the data). The term uses at most
  a few hundred samples chosen once per fit (:func:`term_samples`), and
  :class:`~ipfit.fitting.objective.Objective` evaluates them in the same compiled pass as the data,
  so the term costs about as much as that many extra data points. In a DE search it is
  evaluated only for the trials whose data distance does not already lose to their parent
  (``Objective(population, bound)``): 15-40 % of them, so the term takes 8-25 % of the
  search time on the bundled datasets (``benchmarks/bench_farfield.py``,
  ``docs/farfield-cost.md``).

On a cloud with weights (strays left in, see :func:`ipfit.refine`) the far field is judged from
the points of weight at least :data:`CONFIDENT_WEIGHT` only (:func:`confident_mask`), and a
sample's side is the majority of its :data:`VOTERS` nearest points' (``voters``): a stray
left in would otherwise clear the space around it of samples and, worse, give the samples
nearest to it its own random side of the shape, which the term then holds the zero set to.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .. import basis
from .._utils.validation import as_matching, as_points, check_nonnegative, check_positive, error
from ..cloud import Cloud, as_cloud

__all__ = ["far_field_samples", "term_samples", "term_sample_count", "fused_rows", "FarFieldTerm", "DEFAULT_MARGIN",
           "DEFAULT_CLEARANCE", "DEFAULT_RATIO", "DEFAULT_TERM_WEIGHT", "CONFIDENT_WEIGHT", "confident_mask",
           "confident_cloud", "FAR_FIELD_POINTS", "FAR_FIELD_SUBSAMPLE"]

#: The sampled box is the data's box grown by this × its longest side: a little more than the
#: box in which zero sets are extracted and judged (0.25), so every part of that box is seen.
DEFAULT_MARGIN = 0.3
#: Samples nearer to the data than this × the 3L offset are dropped: there the data rows speak.
DEFAULT_CLEARANCE = 3.0
#: The zero set counts as "close" to a sample when its Taubin distance there is below this
#: fraction of the sample's true distance to the data. Far from a shape, a degree-g polynomial's
#: Taubin distance is about r/g while the true distance is about r, so the fraction must stay
#: below 1/g for a clean fit not to be penalised: 1/8 was chosen when degrees went up to 8, and
#: still sees small loops between grid nodes (1/16 missed one inside the boot at degree 8). The
#: capture rule now goes to 20 in 2D and 12 in 3D, where a clean fit's far samples may pay a
#: little; not re-measured there.
DEFAULT_RATIO = 1.0 / 8.0
#: Candidate grid nodes along the longest side for the objective term's samples: fine enough
#: that the chosen samples sit close to where they are wanted (the grid only proposes places;
#: :func:`term_samples` keeps a few hundred of them).
TERM_GRID = {2: 96, 3: 28}
#: A cloud of more points than this (the most a degree loop fits, SearchOptions.fit_points) gets
#: its far-field samples' distances and sides from an even subsample of FAR_FIELD_SUBSAMPLE of
#: its points (see :func:`far_field_samples`).
FAR_FIELD_POINTS = 50_000
FAR_FIELD_SUBSAMPLE = 20_000
#: Term samples per data point, and their bounds (see :func:`term_sample_count`).
TERM_SAMPLES_PER_POINT = {2: 2.0, 3: 1.0}
TERM_SAMPLES_MIN = {2: 48, 3: 96}
TERM_SAMPLES_MAX = {2: 512, 3: 2400}
#: Spacing of the term samples grows like (distance to the data + this × the data's mean
#: radius): denser near the data, where the spurious loops of real fits sit.
SPREAD_OFFSET = 0.3
# Squared-gradient floor, as in the data objective: below it ∇f counts as zero.
_TINY = float(np.finfo(np.float64).tiny)
#: Recommended weight of the term in the objective (its values lie in [0, 2]; the paper's
#: distance of good fits is 0.005-0.2): 0.1 removed every spurious component of DE + polish
#: on the bundled contours at degrees 4-8, where 0.01 left some.
DEFAULT_TERM_WEIGHT = 0.1
#: The far field of a weighted cloud is judged from its points of at least this weight: an
#: outlier score below 0.72 of the threshold (:func:`ipfit.robust.score_outliers`' weights
#: 1/(1 + score⁴)), well inside it, where the shape's samples lie; the strays a score misses sit
#: near its threshold (weights 0.5-0.9).
CONFIDENT_WEIGHT = 0.9
# ... unless fewer than this share of the points reach it: then the weights say little, all count.
_CONFIDENT_SHARE = 0.5
#: Nearest points whose normals vote on a sample's side on a weighted cloud: a stray among them
#: is outvoted by the shape's samples around it (an odd number: no ties).
VOTERS = 7


def confident_mask(weights: NDArray[np.float64] | None, n_points: int) -> NDArray[np.bool_] | slice:
    """The points the far field is judged from: every point (``slice(None)``) without weights,
    else those of weight >= :data:`CONFIDENT_WEIGHT` (every point when under half of them are)."""
    if weights is None:
        return slice(None)
    mask = weights >= CONFIDENT_WEIGHT
    return mask if mask.sum() >= _CONFIDENT_SHARE * n_points else slice(None)


def confident_cloud(cloud: Cloud) -> Cloud:
    """``cloud`` itself without weights, else the cloud of its :func:`confident_mask` points (kept
    by ``cloud``, so that the far-field samples it keeps are computed once)."""
    if cloud.weights is None:
        return cloud

    def compute() -> Cloud:
        keep = confident_mask(cloud.weights, len(cloud))
        return Cloud._checked(cloud.points[keep], cloud.oriented[keep])

    return cloud.derived("confident_cloud", None, compute)


def far_field_samples(u: NDArray[np.float64] | Cloud, normals: NDArray[np.float64] | None = None, *, c: float = 0.05,
                      margin: float = DEFAULT_MARGIN, per_axis: int | None = None,
                      clearance: float = DEFAULT_CLEARANCE,
                      voters: int = 1) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Grid samples of the data's box (plus ``margin``) away from the data, with signed distances.

    The grid is regular with the same step on every axis (``per_axis`` nodes along the
    longest side; 40 in 2D, 16 in 3D), so fits stay deterministic.

    Parameters
    ----------
    u : (N, dim) points (normalised coordinates in the fits), or a :class:`~ipfit.Cloud` (its
        points and unit normals).
    normals : (N, dim) unit normals at ``u``; None with a cloud.
    c : the 3L offset; samples within ``clearance · c`` of the data are dropped.
    voters : a sample's side is the majority of the sides of its ``voters`` nearest points
        (the side of a point: the sign of (sample − point) · its normal); 1: the nearest's.

    Returns
    -------
    samples : (M, dim) array in the coordinates of ``u``.
    targets : (M,) distances to the nearest data point, negative where that point's normal
        says the sample is inside.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(100)
    >>> samples, targets = far_field_samples(shape.points, shape.normals)
    >>> inside = np.linalg.norm(samples, axis=1) < 1
    >>> bool(np.all(targets[inside] < 0) and np.all(targets[~inside] > 0))
    True
    """
    u, normals = _points_and_normals(u, normals, "far_field_samples")
    dim = u.shape[1]
    lo, hi = u.min(axis=0), u.max(axis=0)
    pad = margin * float((hi - lo).max())
    lo, hi = lo - pad, hi + pad
    if len(u) > FAR_FIELD_POINTS:
        # A node far from a dense surface has nearly every point of it almost as near as the
        # nearest, and its k-d tree query visits most of the tree: 5 s of a 10⁶-point fit's 45.
        # The nodes kept lie beyond the clearance, far more than an even subsample's spacing,
        # so the subsample gives them the same distances (to within that spacing) and sides.
        from ..geometry.sampling import spread_subsample

        pick = spread_subsample(u, FAR_FIELD_SUBSAMPLE)
        u, normals = u[pick], normals[pick]
    step = float((hi - lo).max()) / ((per_axis or (40 if dim == 2 else 16)) - 1)
    axes = [np.arange(a, b + 0.5 * step, step) for a, b in zip(lo, hi, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
    if voters == 1:
        dist, nearest = cKDTree(u).query(grid, workers=-1)
        keep = dist > clearance * c
        grid, dist, nearest = grid[keep], dist[keep], nearest[keep]
        side = np.einsum("ij,ij->i", grid - u[nearest], normals[nearest])
        return grid, np.where(side < 0, -dist, dist)
    dists, near = cKDTree(u).query(grid, k=min(int(voters), len(u)), workers=-1)
    dists, near = dists.reshape(len(grid), -1), near.reshape(len(grid), -1)
    keep = dists[:, 0] > clearance * c
    grid, dist, near = grid[keep], dists[keep, 0], near[keep]
    votes = np.sign(np.einsum("ikj,ikj->ik", grid[:, None, :] - u[near], normals[near])).sum(axis=1)
    return grid, np.where(votes < 0, -dist, dist)


def _points_and_normals(u, normals, required_by: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if isinstance(u, Cloud):
        cloud = as_cloud(u, normals, name="u", required_by=required_by)
        return cloud.points, cloud.oriented
    u = as_points(u, "u")
    return u, as_matching(normals, u)  # arrays: the normals as given (the fits pass unit normals)


def term_sample_count(n_points: int, dim: int) -> int:
    """Number of samples of the objective's far-field term for ``n_points`` data points.

    :data:`TERM_SAMPLES_PER_POINT` per data point (2 in 2D, 1 in 3D), within
    [:data:`TERM_SAMPLES_MIN`, :data:`TERM_SAMPLES_MAX`] (48-512 in 2D, 96-2,400 in 3D).

    Why: a sample costs what a data point costs in the fused pass, so the term's share of
    one full evaluation is M/(N + M); in 2D the cap keeps it at or under 30 % from 1,200 points
    on, and a DE search evaluates the samples for its contending trials only (see the module
    notes). In 3D the cap is higher: with 768 samples the bunny (3,000 points, the size of the
    recommended search subsample) grew spurious blobs at degrees 6 and 8 and the rule fell back
    to degree 4 (F = 0.756); with 2,400 every degree was clean and degree 8 was selected
    (F = 0.987), as with the old 2,211-node grid. Fewer samples per point were measured to let the search grow
    loops in the gaps between them (DE + polish, weight 0.1): on the airplane contour (200
    points) at degree 10, N/3, N/2 and N samples left 1-4 spurious loops where 2N left none;
    on the apple (867 points) at degree 8, N/3 samples left 2 spurious sheets where N left
    none, as the old grids (3,064 and 2,160 nodes) did. So on small clouds the term costs
    more than the data, but the whole search is then cheap.

    >>> term_sample_count(200, 2), term_sample_count(1354, 2), term_sample_count(867, 3), term_sample_count(3000, 3)
    (400, 512, 867, 2400)
    """
    count = np.ceil(TERM_SAMPLES_PER_POINT[dim] * int(n_points))
    return int(min(max(count, TERM_SAMPLES_MIN[dim]), TERM_SAMPLES_MAX[dim]))


def _spread(candidates: NDArray[np.float64], reach: NDArray[np.float64], count: int) -> NDArray[np.int64]:
    # Farthest-point selection with gaps measured relative to ``reach``: every candidate ends
    # up within (final ratio) × its reach of a chosen sample, no two samples crowd while a
    # region is empty, and nothing is random. With reach = distance to the data + an offset,
    # the samples are denser near the data but never absent far from it (reach = distance
    # alone put nearly all of them in the band just outside the clearance).
    if count >= len(candidates):
        return np.arange(len(candidates))
    from ..geometry._distance_kernels import farthest_points

    chosen = np.empty(count, dtype=np.int64)
    farthest_points(np.ascontiguousarray(candidates, dtype=np.float64), np.ascontiguousarray(reach, dtype=np.float64),
                    int(np.argmin(reach)), chosen)
    return np.sort(chosen)


def term_samples(u: NDArray[np.float64] | Cloud, normals: NDArray[np.float64] | None = None, *,
                 count: int | None = None, per_axis: int | None = None,
                 **kwargs) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The far-field term's samples: ``count`` nodes of a fine grid, evenly spread away from the data.

    Candidates are the nodes of :func:`far_field_samples` (``per_axis`` along the longest side,
    default :data:`TERM_GRID`) in the data's box plus its margin, where the zero set is judged;
    those within the clearance of the data (a kd-tree distance) are already gone: there the
    data speak. Of these, ``count`` (default :func:`term_sample_count`) are kept by a
    farthest-point selection whose spacing grows with the distance to the data plus
    :data:`SPREAD_OFFSET` × the data's mean radius: a deterministic stratification of the free
    space, densest where spurious loops were seen. Other keywords go to :func:`far_field_samples`.

    Given a :class:`~ipfit.Cloud` (its points and unit normals), the cloud keeps the samples for
    the next call with the same keywords: the farthest-point selection is the costly part.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(100)
    >>> samples, targets = term_samples(shape.points, shape.normals)
    >>> len(samples), bool(np.all(np.abs(targets) > 0.15))
    (200, True)
    """
    if isinstance(u, Cloud):
        cloud = as_cloud(u, normals, name="u", required_by="term_samples")
        key = (count, per_axis, tuple(sorted(kwargs.items())))
        samples, targets = cloud.derived("term_samples", key, lambda: _term_samples(
            cloud.points, cloud.unit_normals, count, per_axis, kwargs))
        return samples.copy(), targets.copy()  # copies: the cloud's stay as computed
    u = np.ascontiguousarray(u, dtype=np.float64)
    normals = np.ascontiguousarray(normals, dtype=np.float64)
    return _term_samples(u, normals, count, per_axis, kwargs)


def _term_samples(u, normals, count, per_axis, kwargs) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    dim = u.shape[1]
    candidates, targets = far_field_samples(u, normals, per_axis=per_axis or TERM_GRID[dim], **kwargs)
    radius = float(np.linalg.norm(u - u.mean(axis=0), axis=1).mean())
    keep = _spread(candidates, np.abs(targets) + SPREAD_OFFSET * radius,
                   term_sample_count(len(u), dim) if count is None else int(count))
    return candidates[keep], targets[keep]


class FarFieldTerm:
    r"""Objective term penalising zero-set pieces away from the data.

    For sample s_i with signed distance t_i and signed Taubin distance τ_i = f/||∇f||:

    .. math::

        \text{term} = \frac{w}{M} \sum_i
        \min\left(2, \max\left(0, 1 - \frac{\operatorname{sign}(t_i)\,τ_i}{ρ |t_i|}\right)\right)

    It is 0 where f has the right sign and the zero set is not within ρ|t_i| of the sample,
    grows to 1 as the zero set reaches the sample, and up to 2 on the wrong side. It is
    invariant to positive scaling of the coefficients, like the paper's distance, and
    ``weight = 0`` leaves the paper's objective exactly.

    Passed in ``terms`` to :class:`~ipfit.fitting.objective.Objective`, the samples join the data
    rows of the objective's compiled pass (:meth:`rows`); on its own, :meth:`__call__` runs
    the same kernel over the samples alone.

    Parameters
    ----------
    samples, targets : from :func:`term_samples` (or :func:`far_field_samples`), in the
        objective's coordinates.
    degree : polynomial degree of the coefficient vectors.
    weight : w.
    ratio : ρ (:data:`DEFAULT_RATIO`).
    """

    def __init__(self, samples: NDArray[np.float64], targets: NDArray[np.float64], degree: int, weight: float,
                 ratio: float = DEFAULT_RATIO) -> None:
        self.samples = np.asarray(samples, dtype=np.float64)
        self.targets = np.asarray(targets, dtype=np.float64)
        self.weight = check_nonnegative(weight, "far_weight")
        self.ratio = check_positive(ratio, "ratio")
        self.degree = degree
        self.dim = self.samples.shape[1]
        self.n_lower = basis.n_coefficients(self.dim, degree - 1)
        self._m = basis.monomials(self.samples, basis.exponents(self.dim, degree))
        # k_i = sign(t_i)/(ρ|t_i|): the term is clip(1 − k_i f/||∇f||, 0, 2) per sample.
        self._scale = np.sign(self.targets) / (self.ratio * np.abs(self.targets))

    @classmethod
    def from_data(cls, u: NDArray | Cloud, normals: NDArray | None, degree: int, weight: float, *,
                  ratio: float = DEFAULT_RATIO, **kwargs) -> FarFieldTerm:
        """Build the term from the data (samples from :func:`term_samples`, which a
        :class:`~ipfit.Cloud` keeps; keywords go there)."""
        samples, targets = term_samples(u, normals, **kwargs)
        return cls(samples, targets, degree, weight, ratio=ratio)

    @property
    def active(self) -> bool:
        """Whether the term can be non-zero (a positive weight and at least one sample)."""
        return self.weight > 0 and len(self.samples) > 0

    def rows(self, dtype=np.float64) -> tuple[NDArray, NDArray[np.float64], NDArray[np.float64]]:
        """Design matrix (M, d) in ``dtype``, k_i (M,) and per-sample weights w/M (M,): what
        the compiled pass needs to add the term's samples to the data rows."""
        weights = np.full(len(self.samples), self.weight / max(len(self.samples), 1))
        return self._m.astype(dtype, copy=False), self._scale, weights

    def __call__(self, population: NDArray[np.float64]) -> NDArray[np.float64]:
        """(P, d) coefficients → (P,) values of the term."""
        a = np.atleast_2d(np.asarray(population, dtype=np.float64))
        total = np.zeros(a.shape[0])
        if not self.active:
            return total
        from ._objective_kernels import reduce_far_field

        at = np.ascontiguousarray(a.T)
        grads = self._m[:, : self.n_lower] @ basis.gradient_coefficients(at, self.dim, self.degree)
        m, scale, weights = self.rows()
        reduce_far_field(m @ at, grads, scale, weights, _TINY, total)
        return total

    def value_and_grad(self, coefficients: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        """Value and analytic gradient (d,) for one coefficient vector (for the polish)."""
        a = np.asarray(coefficients, dtype=np.float64)
        if not self.active:
            return 0.0, np.zeros_like(a)
        low = self._m[:, : self.n_lower]
        f = self._m @ a
        g = low @ basis.gradient_coefficients(a[:, None], self.dim, self.degree)  # (M, dim)
        norm = np.sqrt(np.maximum(np.einsum("ij,ij->i", g, g), _TINY))
        k = self._scale
        shortfall = 1.0 - k * f / norm
        active = (shortfall > 0) & (shortfall < 2)
        value = self.weight * np.clip(shortfall, 0.0, 2.0).mean()
        # d(f/||g||) = dm/||g|| − f gᵀ dg / ||g||³, and the term is −w/M Σ_active k_i d(f/||g||)
        coef_f = np.where(active, -k / norm, 0.0)
        coef_g = np.where(active, k * f / norm**3, 0.0)[:, None] * g  # (M, dim)
        grad = self._m.T @ coef_f
        basis.add_gradient_adjoint(grad, low.T @ coef_g, self.degree)
        return float(value), self.weight * grad / len(f)


def fused_rows(terms, dim: int, degree: int, dtype) -> tuple[NDArray, NDArray, NDArray] | None:
    """The rows that the far-field terms among ``terms`` add to an objective's compiled pass.

    Stacks :meth:`FarFieldTerm.rows` of every active term (design matrix in ``dtype``, k_i,
    per-sample weights); ``None`` when there is none, so that weight 0 changes nothing.
    """
    far = [t for t in terms if isinstance(t, FarFieldTerm) and t.active]
    for term in far:
        if term.dim != dim or term.degree != degree:
            raise error("terms", f"far-field terms of degree {degree} in {dim}D",
                        f"degree {term.degree} in {term.dim}D", "Build the term for this objective.")
    if not far:
        return None
    parts = [t.rows(dtype) for t in far]
    m, k, w = (np.ascontiguousarray(np.concatenate(column)) for column in zip(*parts, strict=True))
    return m, k, w

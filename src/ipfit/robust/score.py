"""Per-point outlier scores, inlier weights, noise scale and spacing, from the points alone.

:func:`score_outliers` finds the points that do not lie on the curve or surface the others
sample. Three steps, each measured on the development data (``experiments/outlier_scores.py``):

1. **A dense seed.** Samples of a curve or surface are much denser than points strewn in its
   box: their distance to the 8th neighbour is several times shorter. The seed is the points
   whose distance is at most twice the typical one (the mode of its logarithm, found as the
   shortest half of the values, which holds samples only even among 40 % strays), or within
   one width of that half where the sampling is irregular.
2. **Local surfaces, a few rounds.** Each point's offset from a quadric fitted to the reference
   points around it (the seed at first; the point itself left out; in a frame of the k nearest
   at first, then of the points within 4 noise scales, see :mod:`.local`) is
   compared with the noise scale, the Gaussian σ of the reference points' offsets (the
   half-normal part of a half-normal + uniform mixture, so that strays left in the reference
   do not inflate it), or, where the shape is rougher than the noise (corners, creases, a
   coarse mesh), with the offsets of its reference neighbours. Points off their surface or
   beyond its end leave the reference; sparse points well on it (the far side of a hole) join.
3. **Weights.** The score is the larger of the offset over 3.5 of those scales and the
   distance beyond the neighbours over 4 of their spreads: 1 is the threshold. The weight
   1 / (1 + score⁴) (a Cauchy-type weight) is near 1 for samples, 0.5 at the threshold and
   falls off past it, so that a fit can weight points instead of deleting them.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from scipy.special import ndtri  # scipy.stats costs every command ~1 s of import for two constants

from .._utils.numeric import unique_rows
from .._utils.validation import as_points, check_int, error
from ..normals.local import check_workers, standardise
from .local import fit_local, n_terms

__all__ = ["OutlierScore", "score_outliers", "check_outliers", "DEFAULT_K"]

# Points in each local quadric fit (the point itself not among them): about ±5 samples along a
# curve, two rings round a point of a surface. Its noise estimate is within 0.8-1.3 of the true
# σ on the development contours and meshes at noise 0.5-1 % of the box diagonal; wider
# neighbourhoods take in the shape's detail (beetle legs, the bottle's neck) and overestimate it.
DEFAULT_K = {2: 10, 3: 12}
# The seed: log d_8 of samples spreads about 1/(D·√8), narrow enough for strays to stand out.
_DENSITY_K = 8
_SEED_WIDTHS = 1.0
_SEED_RATIO = 2.0
# Points outside the reference join it when their score is below _READMIT and their 8th
# neighbour at most 4 times farther than the typical one: the far side of a hole in a random
# sampling, whose points the seed leaves out. Joining at the threshold instead lets strays in
# that pull the reference off noisy shapes; a lower bar leaves holes' edges flagged.
_SPARSE_RATIO = 4.0
_READMIT = 0.5
# The frame of a local fit reaches this many noise scales (see local.py): enough for its PCA to
# see the shape through the noise, and no more, so that thin parts stay apart on clean data.
_FRAME_REACH = 4.0
_ROUNDS = 3
# Thresholds, in scales: an offset beyond 3.5 σ (0.05 % of Gaussian samples); a position beyond
# 4 RMS spreads of the neighbours along the tangent (a point amid them is below 1, at the end of
# a run of samples about 2).
_OFFSET_CUT = 3.5
_BEYOND_CUT = 4.0
# Roughness: the 90th percentile of the reference neighbours' offsets, as a Gaussian σ; a point
# at a corner, a crease or on a coarse mesh is judged against it. Capped at 2 spacings or 2
# noise scales, and at a quarter of the neighbours' spread along the tangent: a point among
# strays that stayed in the reference sees offsets a third of that spread, and must not pass.
_ROUGH_QUANTILE = 0.9
_ROUGH_CAP_SPACINGS = 2.0
_ROUGH_CAP_SCALES = 2.0
_ROUGH_CAP_EXTENT = 0.25
_ROUGH_ROWS = 1 << 16
# ... and no scale is below 5 % of the spacing: clean synthetic data has a noise scale of 1e-6.
_FLOOR_SPACINGS = 0.05
_MODES = ("auto", "none")
_SQRT_2PI = np.sqrt(2.0 * np.pi)
# 'auto' acts only on evidence of strays: at least this share of the points scores beyond
# _EVIDENCE_SCORE. Clean shapes' sharp or sparse parts score just past 1; planted strays put
# far more of the points beyond 3 (experiments/outlier_flags.py). Below the evidence nothing is
# left out, so a clean cloud is fitted exactly as with 'none'.
_EVIDENCE_SCORE = 3.0
_EVIDENCE_SHARE = 0.02
# Above this many distinct points the reference surfaces are found on a random sample of this
# many (see _big), then every point is scored once against them: the rounds on all of a
# 10⁶-point scan took 34 s, a third of its fit. 65,536 find the same strays as 131,072 in half
# the time (benchmarks/bench_score_sample.py, docs/performance.md).
_REFERENCE_POINTS = 1 << 16


def _frozen(a: NDArray) -> NDArray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class OutlierScore:
    """What :func:`score_outliers` found; arrays are read-only, one entry per input point.

    Attributes
    ----------
    weights : (N,) array in [0, 1]
        1 / (1 + score⁴) (``outliers='auto'``): near 1 for samples of the shape, 0.5 at the
        threshold, small far from it. All 1 for ``outliers='none'``, and for 'auto' when
        under 2 % of the points score beyond 3 (no evidence of strays: a clean shape's sharp
        or sparse parts score just past the threshold, and are kept); see
        :func:`score_outliers` for a forced fraction.
    inliers : (N,) bool array
        ``weights >= 0.5``.
    score : (N,) array >= 0
        The outlier score: 1 at the threshold (see the module notes). A big cloud whose weights
        did not need it (see :func:`score_outliers`) computes it when first asked for.
    noise_scale : float
        The Gaussian σ of the inliers' offsets from the shape, in the points' units. On clean
        data, the shape's own roughness at the scale of k samples (pixel steps, facets).
    spacing : float
        The median distance from an inlier to its nearest other inlier (distinct positions;
        the inliers the data say, score <= 1, whatever ``outliers`` forces); computed with
        ``score``.
    outlier_share : float
        The share of points that are not inliers.
    mode : 'auto', 'none' or float
        The ``outliers`` setting that made it.
    count : int
        The number of points that are not inliers.
    """

    weights: NDArray[np.float64]
    inliers: NDArray[np.bool_]
    noise_scale: float
    mode: str | float
    # () -> (score, spacing): the scores of every point and the inliers' spacing, when asked for
    _measure: Callable[[], tuple[NDArray[np.float64], float]] = field(repr=False)
    outlier_share: float = field(init=False)

    def __post_init__(self):
        for name in ("weights", "inliers"):
            _frozen(getattr(self, name))
        object.__setattr__(self, "outlier_share", float(1.0 - self.inliers.mean()))

    @cached_property
    def _measured(self) -> tuple[NDArray[np.float64], float]:
        score, spacing = self._measure()
        return _frozen(score), spacing

    @property
    def score(self) -> NDArray[np.float64]:
        return self._measured[0]

    @property
    def spacing(self) -> float:
        return self._measured[1]

    @property
    def count(self) -> int:
        return int(len(self.inliers) - np.count_nonzero(self.inliers))

    def to_dict(self) -> dict:
        """The result JSON's ``outliers`` section (docs/result-format.md): the mask as the
        outliers' indices, which are few."""
        return {"mode": self.mode, "count": self.count, "share": self.outlier_share,
                "noise_scale": float(self.noise_scale), "indices": np.flatnonzero(~self.inliers).tolist()}


def check_outliers(outliers) -> str | float:
    """The ``outliers`` setting of a fit or a score, checked: 'auto', 'none' or a float share."""
    expected = "'auto', 'none' or a fraction in [0, 0.9)"
    if isinstance(outliers, str):
        if outliers.lower() not in _MODES:
            raise error("outliers", expected, repr(outliers)[:60], "Pass outliers='auto' to decide from the data.")
        return outliers.lower()
    if isinstance(outliers, bool) or not isinstance(outliers, numbers.Real) or not 0.0 <= float(outliers) < 0.9:
        raise error("outliers", expected, f"{type(outliers).__name__} {outliers!r}"[:80],
                    "Pass e.g. outliers=0.1 to mark the 10 % highest-scored points.")
    return float(outliers)


def _shorth(values: NDArray) -> tuple[float, float]:
    """Midpoint of the shortest interval holding half the values, and its half-width as a Gaussian σ.

    Half the points are samples even with 40 % strays among them, so the shortest half lies on
    the samples' mode (Rousseeuw's LMS location).
    """
    x = np.sort(values)
    half = len(x) // 2
    widths = x[half:] - x[: len(x) - half]
    j = int(np.argmin(widths))
    return 0.5 * (x[j] + x[j + half]), widths[j] / 2.0 / ndtri(0.75)


def _seed(tree: cKDTree, counts: NDArray, workers: int) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """The dense points, and those whose density is at most _SPARSE_RATIO times below the typical.

    A position given more than once is a sample whatever its density, and its copies count in
    its neighbours' density: uniform strays never coincide, a mesh's vertices repeated along its
    seams do (the bundled duck: 30,083 rows, 5,482 positions). Counted once, 25 % of strays
    outnumbered the duck's positions and the seed took them in (34 % of them found, 95 % now).
    """
    k = min(_DENSITY_K, int(counts.sum()) - 1)
    # the k-th nearest other point, copies included: the first column whose cumulative count
    # (the point's own copies beyond itself, then each neighbour's) reaches k
    dist, idx = tree.query(tree.data, k=min(k + 1, tree.n), workers=workers)
    dist, idx = dist.reshape(tree.n, -1), idx.reshape(tree.n, -1)
    within = counts[idx].cumsum(axis=1) - 1
    column = np.argmax(within >= k, axis=1)
    kth = np.where(within[:, -1] >= k, np.take_along_axis(dist, column[:, None], 1)[:, 0], dist[:, -1])
    log = np.log(np.maximum(kth, np.finfo(float).tiny))
    mode, width = _shorth(np.repeat(log, counts))  # every input point counts, duplicates too
    repeated = counts > 1
    return (repeated | (log <= mode + max(_SEED_WIDTHS * width, np.log(_SEED_RATIO))),
            repeated | (log <= mode + np.log(_SPARSE_RATIO)))


def _rounds(points: NDArray, counts: NDArray, k: int, workers: int):
    """Score every point against the reference surfaces, refined over a few rounds. Returns the
    scores, the noise scale, and the reference and frame reach a further round would use."""
    tree = cKDTree(points)
    ref, sparse = _seed(tree, counts, workers)
    reach = 0.0  # the first round knows no noise scale: fits on the k nearest (see local.py)
    for _ in range(_ROUNDS):
        score, sigma, widest = _score(points, counts, ref, k, reach, workers)
        # Points leave the reference past the threshold. Points outside it come back in only if
        # well inside the threshold and not much sparser than the samples (the far side of a
        # hole in a random sampling): strays let back in pull the reference off noisy shapes.
        kept = (ref & (score < 1.0)) | (sparse & (score < _READMIT))
        if kept.sum() <= k:
            kept = ref
        # the same reference and frames of the k nearest again: the same fits (clean data)
        if np.array_equal(kept, ref) and max(reach, _FRAME_REACH * sigma) < widest:
            break
        ref, reach = kept, _FRAME_REACH * sigma
    return score, sigma, kept, _FRAME_REACH * sigma


def _score(points: NDArray, counts: NDArray, ref: NDArray[np.bool_], k: int, reach: float, workers: int):
    """Every point's score against the local surfaces of the ``ref`` points, the noise scale, and
    the least reach that widens a frame (:class:`~ipfit.robust.local.LocalFit`'s ``widest``)."""
    at = np.flatnonzero(ref)
    own = np.full(len(points), -1)
    own[at] = np.arange(len(at))
    fit = fit_local(points[at], points, own, k, reach, workers)
    weights = counts[at]
    sigma = _gaussian_scale(fit.residual[at], weights)
    nearest = cKDTree(points[at]).query(points[at], k=2, workers=workers)[0][:, 1]
    spacing = float(np.median(np.repeat(nearest, weights)))
    # a slice of points at a time: the neighbours' offsets of every point at once, and the
    # quantile's sorted copy of them, were most of a 10⁶-point score's peak memory (+350 MB)
    reference, rough = fit.residual[at], np.empty(len(points))
    for start in range(0, len(points), _ROUGH_ROWS):
        rows = slice(start, start + _ROUGH_ROWS)
        rough[rows] = np.quantile(reference[fit.neighbours[rows]], _ROUGH_QUANTILE, axis=1)
    rough /= ndtri(0.5 + _ROUGH_QUANTILE / 2)
    cap = np.minimum(max(_ROUGH_CAP_SCALES * sigma, _ROUGH_CAP_SPACINGS * spacing), _ROUGH_CAP_EXTENT * fit.extent)
    scale = np.maximum(np.minimum(rough, cap), max(sigma, _FLOOR_SPACINGS * spacing))
    return np.maximum(fit.residual / scale / _OFFSET_CUT, fit.offset / _BEYOND_CUT), sigma, fit.widest


def _big(points: NDArray, counts: NDArray, k: int, workers: int, mode: str | float):
    """Scores and noise scale of more than :data:`_REFERENCE_POINTS` distinct points.

    The rounds run on a random sample of that many (fixed seed; a random one keeps the density
    contrast between samples and strays that the seed needs); every point is then scored once
    against the reference they settled on. The scores of every point are needed now only for a
    forced fraction, or for 'auto' when strays may be evidence: the sample, and every repeated
    position (which may weigh heavily), are scored first, and under half the evidence share
    among them says 'auto' keeps every point. A point's score does not depend on the other
    queries, so the sample's are those of the whole pass. Returns every point's scores or
    ``None``, the noise scale, and a function giving every point's scores.
    """
    pick = np.sort(np.random.default_rng(0).choice(len(points), _REFERENCE_POINTS, replace=False))
    _, _, kept, reach = _rounds(points[pick], counts[pick], k, workers)
    ref = np.zeros(len(points), dtype=bool)
    ref[pick[kept]] = True

    def every() -> NDArray[np.float64]:
        return _score(points, counts, ref, k, reach, workers)[0]

    if isinstance(mode, str):
        single = counts == 1
        probe = np.union1d(pick, np.flatnonzero(~single))
        probe_score, sigma, _ = _score(points[probe], counts[probe], ref[probe], k, reach, workers)
        beyond = probe_score > _EVIDENCE_SCORE
        sampled = single[probe]
        # the singletons' share estimated from the sample's, the repeated positions' counted
        singles = beyond[sampled].mean() if sampled.any() else 1.0
        mass = singles * np.count_nonzero(single) + (counts[probe] * (beyond & ~sampled)).sum()
        if mode == "none" or mass < 0.5 * _EVIDENCE_SHARE * counts.sum():
            return None, sigma, every
    # the noise scale of the whole pass is the probe's: the same reference points' own fits
    score, sigma, _ = _score(points, counts, ref, k, reach, workers)
    return score, sigma, every


def _gaussian_scale(residuals: NDArray, counts: NDArray) -> float:
    """Gaussian σ of absolute residuals (each counted ``counts`` times): the half-normal part of a
    half-normal + uniform mixture, fitted by EM from the median over 0.6745."""
    r = np.repeat(residuals, counts)
    sigma = float(np.median(r) / ndtri(0.75))
    top = float(r.max())
    if not (sigma > 0.0 and top > 0.0):
        return sigma
    share = 0.9
    for _ in range(30):
        normal = share * 2.0 * np.exp(-((r / sigma) ** 2) / 2.0) / _SQRT_2PI / sigma  # the normal density
        member = normal / (normal + (1.0 - share) / top)
        share = float(member.mean())
        refined = float(np.sqrt((member * r * r).sum() / member.sum())) if member.sum() > 0 else 0.0
        if not refined > 0.0:  # the samples lie exactly on their quadrics (a polygon): keep the median's
            break
        sigma = refined
    return sigma


def score_outliers(points: ArrayLike, *, outliers="auto", k: int | None = None,
                   workers: int = -1) -> OutlierScore:
    """Outlier score, inlier weight and mask of every point, with the noise scale and spacing.

    Every point's offset from a local quadric fitted to the samples around it (itself left
    out) is compared with the noise scale, estimated from the same offsets; density picks the
    first samples. See the module notes for the steps and :class:`OutlierScore` for the result.
    Nothing but the points is used: no normals, no order. The result does not depend on the
    points' order, position, orientation or units. Above 65,536 distinct points the reference
    surfaces are found on a random 65,536 of them (fixed seed) and every point is scored once
    against them: the result still does not depend on the order, but which points that sample
    holds, and so a score near the threshold, can change with the position, orientation or units.
    There 'auto' decides on the sample whether strays are evidence when the sample is clear
    (under 1 % of it beyond 3, half the evidence share: a random sample of 65,536 that shows
    under 1 % where the cloud has 2 % is practically impossible, 18 standard deviations off), and
    ``score`` and ``spacing``, which the weights then do not need, are computed when first asked
    for (seconds of a 10⁶-point scan's fit).

    Parameters
    ----------
    points : (N, D) array, D = 2 or 3, with at least k + 2 distinct points
    outliers : 'auto', 'none' or float
        'auto' decides from the data: outliers are the points scored above 1, when at least
        2 % of the points score beyond 3 (otherwise there are none). 'none' makes
        every point an inlier of weight 1. A fraction F in [0, 0.9) marks exactly round(F·N)
        highest-scored points as outliers (ties broken by coordinates), the weights
        1 / (1 + (score / cut)⁴) with the cut between them and the rest, so that those and only
        those are below 0.5. The score, noise scale and spacing do not depend on ``outliers``.
    k : int, optional
        Points in each local fit; default 10 in 2D, 12 in 3D (:data:`DEFAULT_K`), at least 5
        in 2D and 8 in 3D.
    workers : int
        Threads for the neighbour search: -1 for all cores, or a positive number.

    Returns
    -------
    OutlierScore

    >>> from ipfit.datasets.synthetic import circle
    >>> pts = np.vstack([circle(200).points, [[0.0, 0.0], [1.9, 1.9]]])
    >>> found = score_outliers(pts)  # two strays: scored past the threshold, too few to act on
    >>> (found.score[-2:] > 1).tolist(), found.count
    ([True, True], 0)
    >>> score_outliers(pts, outliers=0.01).inliers[-2:].tolist()  # 1% of 202 points: those two
    [False, False]
    """
    pts = as_points(points, min_points=1)
    mode = check_outliers(outliers)
    dim = pts.shape[1]
    k = DEFAULT_K[dim] if k is None else check_int(k, "k", minimum=n_terms(dim) + 2)
    workers = check_workers(workers)
    standard, unit = _standardised(pts)
    unique, _, inverse, counts = unique_rows(standard)
    if len(unique) < k + 2:
        raise error("points", f"at least k + 2 = {k + 2} distinct points", f"{len(unique)}",
                    "Pass more points or a smaller k.")
    if len(unique) <= _REFERENCE_POINTS:
        score_u, sigma = _rounds(unique, counts, k, workers)[:2]
        every = None
    else:
        score_u, sigma, every = _big(unique, counts, k, workers, mode)

    def measure(score_u: NDArray | None = score_u) -> tuple[NDArray[np.float64], float]:
        if score_u is None:
            assert every is not None
            score_u = every()
        # the spacing of the points the data say are inliers, whatever `outliers` forces
        inner = unique[score_u <= 1.0]
        spacing = float(np.median(cKDTree(inner).query(inner, k=2, workers=workers)[0][:, 1])) if len(inner) > 1 \
            else 0.0
        return score_u[inverse], spacing * unit

    if score_u is None or mode == "none":
        weights = np.ones(len(pts))
    else:
        weights = _weights(score_u[inverse], standard, mode)
    return OutlierScore(weights, weights >= 0.5, sigma * unit, mode, measure)


def _weights(score: NDArray, standard: NDArray, mode: str | float) -> NDArray[np.float64]:
    """1 / (1 + (score / cut)⁴), the cut at 1 ('auto') or between the forced outliers and the rest."""
    if mode == "auto":
        if np.mean(score > _EVIDENCE_SCORE) < _EVIDENCE_SHARE:
            return np.ones(len(score))
        return 1.0 / (1.0 + score ** 4)
    n = len(score)
    m = round(float(mode) * n)
    # highest score first, ties by coordinates: the same points whatever the input order
    order = np.lexsort((*standard.T[::-1], -score))
    if m == 0:
        cut = max(1.0, float(score.max()))
    else:
        low, high = float(score[order[m - 1]]), float(score[order[m]]) if m < n else 0.0
        cut = np.sqrt(low * high) if high > 0 else low / 2.0
    cut = max(cut, np.finfo(float).tiny)
    weights = 1.0 / (1.0 + (score / cut) ** 4)
    marked = order[:m]
    weights[marked] = np.minimum(weights[marked], np.nextafter(0.5, 0.0))  # ties at the cut
    unmarked = order[m:]
    weights[unmarked] = np.maximum(weights[unmarked], 0.5)
    return weights


def _standardised(points: NDArray) -> tuple[NDArray[np.float64], float]:
    """The points centred and scaled (:func:`~ipfit.normals.local.standardise`), and the unit:
    a length in standardised coordinates times the unit is a length in the points' own."""
    standard = standardise(points)
    axis = int(np.argmax(np.ptp(standard, axis=0)))
    extent = float(np.ptp(standard[:, axis]))
    if extent == 0.0:
        return standard, 1.0
    big = 2.0 ** np.frexp(float(np.max(np.abs(points[:, axis]))))[1]
    return standard, float(np.ptp(points[:, axis] / big)) * big / extent

"""Normal estimation: k-nearest-neighbour PCA with the refits where those neighbours mislead.

:func:`estimate_normals` is the public entry (it also handles noisy data through
:mod:`.scale` and orients through :mod:`.orient`); :func:`contour_normals` gives the normals
of an ordered 2D contour from its order alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import row_norms, unit_rows_mask
from .._utils.validation import as_points, check_int, check_nonnegative, error
from .local import (
    blocks,
    check_flag,
    check_workers,
    covariances,
    default_k,
    flatness_of,
    neighbours,
    normal_confidence,
    pca,
    pca_normals,
    spread,
    standardise,
)
from .orient import orient_graph
from .poles import doubtful_points, is_uneven, pole_lines
from .scale import SIGMAS_WIDE, noise_scale, orient_coarse, roughness

__all__ = ["estimate_normals", "contour_normals", "looks_noisy"]

# A 3D point is on a "sampled curve" when its nearest _CURVE_K points (the point and ±3 samples
# along a curve) are nearly collinear: second singular value below _CURVE_RATIO of the first. A
# 24-gon ring gives 0.23 there; random samples of a surface rarely go below 0.3 (~2 % of a
# uniform sphere's points, where the refit below is harmless: it still finds the surface).
_CURVE_K = 7
_CURVE_RATIO = 0.3
_CURVE_LINK_SLOPE = np.sin(np.radians(20.0))  # links across the curve: this close to the tangent plane
# The refit's neighbourhood, in multiples of k (72 points for k = 12): it must reach past the
# point's own curve, so rings of up to ~60 points are handled. Too wide and it takes in other
# surfaces: on the apple, whose stem stands 4-6 mm from the dimple's wall, 4k and 8k both leave
# the stem's lowest ring (24 points) flipped; 6k gets it right.
_CURVE_REACH = 6
# Noisy clouds of more than _NOISY_SAMPLE points are estimated on an even sample of that many
# (normals.local.spread): the neighbourhoods that see past the noise hold up to 400 points, and
# on a million points their search took minutes. Under noise wider than the spacing, a sample
# loses nothing a neighbourhood wide enough to average the noise would have kept (a torus of 10⁶
# points at σ = 0.5 % of its size: median error 1.9° either way, benchmarks/bench_normals.py).
# The test for noise looks at the k nearest neighbours of _NOISY_PROBE points of the whole cloud.
_NOISY_SAMPLE = 40_000
_NOISY_PROBE = 10_000
# A noisy 3D cloud of known σ, denser than that, is estimated on an even sample whose k nearest
# points reach SIGMAS_WIDE σ (see _noise_sample), by the plain fit with its refinements, instead
# of growing each point's neighbourhood to where it looks flattest: on dense scans the grown
# neighbourhoods reach 10 σ and more, round a thin body's tight bends and tilt the normals of a
# whole rim (a flattened body's edge, a fin's) towards the flat sides' — an error the fits cannot
# average out, where the sample's plain normals err at random. docs/robust-dense.md: the Turk
# shapes at 50,000 points, median F 0.74 → 0.92 at σ = 0.5 %, 0.79 → 0.89 at 1 %.
_SAMPLE_FEWEST = 400  # below this the sample would lose the shape's details to the noise anyway


def _refit_sampled_curves(points: NDArray, tree: cKDTree, idx: NDArray[np.intp], normals: NDArray,
                          workers: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Normals across the curves of anisotropically sampled surfaces (3D), in place.

    A lathe or scan-line model samples its surface densely along curves (rings of a stem,
    scan lines) that lie farther apart than the samples on them. Then the k nearest
    neighbours all lie on one curve, and their direction of least spread is the normal of the
    curve's plane (the stem's axis), not the surface's: on the bundled apple's stem, ~80° off.
    The surface contains the curve, so its normal is perpendicular to the curve's tangent t
    (reliable from the nearest few points); within the plane perpendicular to t, it is the
    direction of least spread of a neighbourhood wide enough to reach the neighbouring curves.

    Returns the refitted points, and links for the orientation graph (whose k-nearest edges
    stay on the curve): from each refitted point to its nearest point on either side across
    the curve, near its tangent plane (within 20°): the orientation then follows the surface
    the normal was measured on.
    """
    n, k = idx.shape
    ks = min(_CURVE_K, k)
    none = np.empty(0, np.intp)
    if ks < 3 or n <= k:
        return none, none, none
    values = np.empty((n, 3))
    for rows in blocks(n, ks):
        values[rows] = np.linalg.eigvalsh(covariances(points, idx[rows, :ks]))
    values = np.clip(values, 0.0, None)
    curve = np.flatnonzero(values[:, 1] < _CURVE_RATIO ** 2 * values[:, 2])
    if len(curve) == 0:
        return none, none, none
    link_lo, link_hi = [], []
    kb = min(_CURVE_REACH * k, n)
    for rows in blocks(len(curve), kb):
        at = curve[rows]
        t = np.linalg.eigh(covariances(points, idx[at, :ks]))[1][:, :, 2]
        wide = neighbours(tree, kb, workers, points[at])
        cov = covariances(points, wide)
        tt = t[:, :, None] * t[:, None, :]
        proj = np.eye(3) - tt
        # Spread across t only, and t itself made the direction of most spread: the least
        # is then the normal, perpendicular to the curve.
        _, vectors_w = np.linalg.eigh(proj @ cov @ proj + 2.0 * tt)
        nrm = vectors_w[:, :, 0]
        normals[at] = nrm
        step = points[wide] - points[at][:, None, :]
        across = np.einsum("ikj,ij->ik", step, np.cross(nrm, t))
        along = np.abs(np.einsum("ikj,ij->ik", step, t))
        off = np.abs(np.einsum("ikj,ij->ik", step, nrm))
        fit = (np.abs(across) > along) & (off < _CURVE_LINK_SLOPE * row_norms(step))
        for side in (across > 0, across < 0):
            cand = fit & side  # the wide neighbours come nearest first: take the first candidate
            has = cand.any(axis=1)
            first = np.argmax(cand, axis=1)
            link_lo.append(at[has])
            link_hi.append(wide[has, first[has]])
    return curve, np.concatenate(link_lo), np.concatenate(link_hi)


def _refit_along_curve(points: NDArray, idx: NDArray[np.intp], normals: NDArray, flatness: NDArray) -> None:
    """Refit 2D normals on the neighbours along the curve instead of the nearest ones, in place.

    On a coarse contour the k nearest points of a sharp tip or of one side of a thin part
    include points of the other side, and the fitted line mixes both (the airplane's tips:
    75° off). The curve through the points is reconstructed locally by the NN-crust of
    Dey & Kumar (1999): each point joins its nearest neighbour and its nearest neighbour on
    the other side (in the half-plane away from the first). Where those links are mutual for
    (k-1)//2 hops each way, the point is refitted on that chain of k-1 or k points (the same
    reach along the curve as k nearest points on a smooth part); elsewhere (branchings,
    ambiguous links of noisy or pixel-traced data) the k-nearest fit is kept.
    """
    n, k = idx.shape
    hops = (k - 1) // 2
    if hops < 1:
        return
    at = np.arange(n)
    step = points[idx[:, 1:]] - points[:, None, :]
    behind = np.einsum("ikj,ij->ik", step, step[:, 0]) < 0  # away from the nearest neighbour
    ok = behind.any(axis=1)
    second = np.where(ok, idx[:, 1:][at, np.argmax(behind, axis=1)], n)
    links = np.vstack([np.column_stack([idx[:, 1], second]), [n, n]])  # row n: "no point"
    columns = [at]
    for side in (0, 1):
        prev, cur = at, links[at, side]
        for _ in range(hops):
            # the link prev → cur must be mutual; then go on to cur's other link
            mutual = (links[cur, 0] == prev) | (links[cur, 1] == prev)
            ok &= mutual & (cur < n)
            columns.append(np.where(ok, cur, at))
            prev, cur = cur, np.where(links[cur, 0] == prev, links[cur, 1], links[cur, 0])
    chain = np.column_stack(columns)
    ordered = np.sort(chain, axis=1)
    ok &= (np.diff(ordered, axis=1) > 0).all(axis=1)  # a chain round a tiny loop repeats points
    use = np.flatnonzero(ok)
    if len(use):
        normals[use], flatness[use] = pca_normals(points, chain[use])


def estimate_normals(points: ArrayLike, k: int | None = None, *, orient: bool = True,
                     workers: int = -1, inliers: ArrayLike | None = None, noise: float | None = None,
                     return_confidence: bool = False, progress: Callable[[dict], None] | None = None):
    """Unit normals of a 2D or 3D point cloud by k-nearest-neighbour PCA.

    Refinements of the plain fit where the k nearest neighbours are the wrong sample of the
    shape: in 2D each point is refitted on its neighbours *along* the curve (see
    :func:`_refit_along_curve`), so that the two sides of a thin part or of a sharp tip do not
    mix; in 3D, points whose nearest neighbours all lie on one sampled curve (rings, scan lines
    farther apart than the samples along them) get a normal across that curve (see
    :func:`_refit_sampled_curves`), and points whose neighbours are a poor sample of a plane
    (one or two rows of points, creases, thin parts: the vertices of CAD meshes, few on flat
    panels and many at details) get, among several candidate lines, the one that leaves the
    largest empty ball touching the point, a local Voronoi pole (see
    :func:`~ipfit.normals.poles.pole_lines`). Coincident points are estimated once.

    On such sparse or uneven 3D clouds (a quarter of the points or more with a poor plane) the
    orientation also starts from the points a large empty ball touches from one side only
    (:func:`~ipfit.normals.poles.exterior_anchors`) and flips the pieces that the generalized
    winding number of the rest says are inside out: a thin part's two sides sampled more
    coarsely than it is thick defeat the neighbour links alone.

    Noisy data (noise wider than the k nearest neighbours) are detected and handled apart:
    each point's neighbourhood is grown to the scale where it looks flattest (up to 32k
    points; in 3D at most 8 % of the cloud's box diagonal wide, beyond which a neighbourhood
    sees the object's overall shape rather than averaged noise; see :func:`noise_scale`), and
    the signs are propagated on a denoised, coarser sample of the shape, from which each point
    takes its own (see :func:`orient_coarse`). When the noise's σ is known (``noise``, 3D), the
    normals are instead those of the plain fit above on an even sample of the points whose k
    nearest reach about 4 σ, each point taking its nearest sample point's: grown neighbourhoods
    reach 10 σ and more on a dense cloud and tilt a thin body's rim as a whole, where the
    sample's normals err at random (more widely on smooth parts: the fit, not each normal, is
    what they are for; docs/robust-dense.md). On a cloud too sparse for such a sample, where no
    size looks flatter (noise about as wide as the shape's bends), every neighbourhood is grown
    to a radius of about 4 σ.
    Parts thinner than a few times the noise (a butterfly's antennae under noise wider than
    they are) cannot be told apart and come out with one side flipped. A noisy cloud of more
    than 40,000 points is estimated on an even sample of 40,000 of them, and each point takes
    the normal of its nearest sample point: the neighbourhoods that average the noise are
    wider than the sample's spacing, so nothing they would see is lost, and a million noisy
    points take seconds instead of minutes.

    Parameters
    ----------
    points : (N, D) array, D = 2 or 3, N >= 3
    k : int, optional
        Neighbours per point, the point itself included; default 6 in 2D, 12 in 3D
        (:data:`DEFAULT_K`). Lower it for thin parts; on noisy data it is the smallest
        neighbourhood tried (see above).
    orient : bool
        Make the signs consistent, outward for closed shapes (see :func:`orient_normals`).
        If False the signs are arbitrary.
    workers : int
        Threads for the neighbour search: -1 for all cores, or a positive number.
    inliers : (N,) bool array, optional
        Which points are samples of the shape (e.g. ``ipfit.robust.score_outliers(points).inliers``).
        The normals are estimated and oriented on those alone, so that a stray point can neither
        tilt nor flip a neighbourhood; every other point takes the normal of its nearest inlier.
        At least 3 inliers. None (the default): every point is one.
    noise : float, optional
        The Gaussian σ of the points' offsets from the shape, in their units, if known (e.g.
        ``ipfit.robust.score_outliers(points).noise_scale``, which :func:`ipfit.fit_adaptive`
        passes): noisy points get neighbourhoods about 4 σ wide, on a sample of them when they are
        denser than that (see above). It is used only where 3D points look noisy; None: sizes
        from the points alone.
    return_confidence : bool
        Also return how well each point's neighbourhood supports its normal line (see below).
    progress : callable, optional
        Called with a dict per stage, ``{'event': 'normals', 'message': str, 'seconds': float}``
        (seconds since the call began), the last one's message ``'done'``: a big cloud takes a
        while. ``ipfit fit`` and ``ipfit normals`` print them.

    Returns
    -------
    normals : (N, D) array of unit normals.
    confidence : (N,) array in [0, 1], only with ``return_confidence=True``
        1 − (spread of the neighbours along the normal) / (their least spread across it), on
        the k nearest points (on noisy data, on the neighbourhood the normal was fitted on):
        near 1 where the neighbours lie on a plane (a line in 2D) through the normal's foot;
        near 0 where they spread as much along the normal as across it (noise, a crease, both
        sides of a thin part) or lie on one row (3D: no plane is determined), so the line may
        be off; 0 for the points outside ``inliers``. A fit can downweight the normals of
        points with low confidence. It says nothing of the sign.

    Notes
    -----
    The points are centred and divided by a robust size first, so the normals do not depend
    on the data's position or units: coordinates of 1e-200 or 1e200 give the same normals.
    Memory stays bounded (blocks of points): a million points take seconds on a few cores.

    >>> from ipfit.datasets.synthetic import circle
    >>> pts, true, _ = circle(100)
    >>> bool((estimate_normals(pts) * true).sum(axis=1).min() > 0.99)
    True
    >>> normals, confidence = estimate_normals(pts, return_confidence=True)
    >>> bool(confidence.min() > 0.99)
    True
    """
    pts = as_points(points, min_points=3)
    return_confidence = check_flag(return_confidence, "return_confidence")
    if noise is not None:
        noise = check_nonnegative(noise, "noise")
    if progress is not None and not callable(progress):
        raise error("progress", "a callable taking one event dict, or None", type(progress).__name__)
    if inliers is not None:
        mask = _check_inliers(inliers, len(pts))
        if not mask.all():
            return _normals_of_inliers(pts, mask, k, orient, workers, noise, return_confidence, progress)
    orient = check_flag(orient, "orient")
    workers = check_workers(workers)
    return _estimate_checked(pts, k, orient, workers, noise, return_confidence, progress)


def layered_normals(points: ArrayLike, noise: float | None = None) -> NDArray[np.float64]:
    """:func:`estimate_normals` (every point, default k) with the close-layer vote added to the
    orientation of a sparse or unevenly sampled 3D cloud (``orient_graph``'s ``layers``); elsewhere
    the same normals. The variant :func:`~ipfit.fit_adaptive` looks at when its first fit of a bare
    3D cloud measures poorly."""
    return _estimate_checked(as_points(points, min_points=3), None, True, -1, noise, False, None, layers=True)


def _estimate_checked(pts: NDArray, k, orient: bool, workers: int, noise: float | None, return_confidence: bool,
                      progress: Callable[[dict], None] | None, layers: bool = False):
    """:func:`estimate_normals` on its checked arguments (``layers``: see :func:`layered_normals`)."""
    given = pts
    pts = standardise(pts)
    sigma = None if noise is None else _standard_sigma(given, pts, noise)
    if k is not None:
        default_k(k, pts.shape[1], len(pts))  # checked on the caller's points
    # Coincident points (a mesh's vertices split per face) add nothing but fill the k nearest:
    # the normals are estimated on the distinct points.
    started = time.perf_counter()

    def say(message: str) -> None:
        if progress is not None:
            progress({"event": "normals", "message": message, "seconds": time.perf_counter() - started})

    distinct, inverse = _distinct(pts)
    if len(distinct) < len(pts) and len(distinct) > pts.shape[1]:
        normals, confidence = _estimate(distinct, k, orient, workers, return_confidence, say, sigma, layers=layers)
        normals, confidence = normals[inverse], confidence[inverse]
    else:
        normals, confidence = _estimate(pts, k, orient, workers, return_confidence, say, sigma, layers=layers)
    say("done")
    return (normals, confidence) if return_confidence else normals


def _distinct(points: NDArray) -> tuple[NDArray, NDArray[np.intp]]:
    """The distinct rows (in coordinate order if any repeat) and each row's index among them."""
    order = np.lexsort(points.T[::-1])
    repeat = (points[order][1:] == points[order][:-1]).all(axis=1)
    if not repeat.any():
        return points, np.arange(len(points))
    group = np.concatenate([[0], np.cumsum(~repeat)])
    inverse = np.empty(len(points), dtype=np.intp)
    inverse[order] = group
    return points[order][np.concatenate([[True], ~repeat])], inverse


def _standard_sigma(points: NDArray, standard: NDArray, noise: float) -> float | None:
    """``noise`` (in the units of ``points``) in those of their :func:`standardise` copy ``standard``."""
    axis = int(np.argmax(np.ptp(standard, axis=0)))
    span = float(np.ptp(points[:, axis]))
    return noise * float(np.ptp(standard[:, axis])) / span if 0 < span < np.inf else None


def _noise_sample(pts: NDArray, tree: cKDTree, k: int, sigma: float, workers: int) -> NDArray[np.intp] | None:
    """An even sample (:func:`~ipfit.normals.local.spread`) of the 3D ``pts`` (their k-d tree
    ``tree``) whose k nearest points reach about SIGMAS_WIDE ``sigma`` (median radius over a
    probe), or None when ``pts`` themselves reach that already. A sample of m of n points reaches
    about √(n/m) times as far; two corrections of that first guess land within a few per cent."""
    n = len(pts)
    target = SIGMAS_WIDE * sigma

    def reach(points: NDArray, points_tree: cKDTree) -> float:
        probe = points[spread(points, _NOISY_PROBE)]
        return float(np.median(points_tree.query(probe, k, workers=workers)[0][:, -1]))

    m, now = n, reach(pts, tree)
    for correction in range(3):
        m = int(max(_SAMPLE_FEWEST, k + 1, m * (now / target) ** 2))
        if m >= n:
            return None
        sample = spread(pts, m)
        if correction < 2:
            now = reach(pts[sample], cKDTree(pts[sample]))
    return sample


def _on_sample(pts: NDArray, sample: NDArray[np.intp], estimate: Callable[[NDArray], tuple[NDArray, NDArray]],
               say: Callable[[str], None], workers: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``estimate`` on ``pts[sample]``; every point takes its nearest sample point's normal and confidence."""
    normals, confidence = estimate(pts[sample])
    say(f"giving each of the {len(pts):,} points its nearest sample point's normal")
    _, nearest = cKDTree(pts[sample]).query(pts, workers=workers)
    return normals[nearest], confidence[nearest]


def _estimate(pts: NDArray, k, orient: bool, workers: int, want_confidence: bool, say: Callable[[str], None],
              sigma: float | None = None, plain: bool = False,
              layers: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normals and (if wanted, else NaN) their confidence on standardised points (see estimate_normals);
    ``plain``: the k nearest points' fit and its refinements, even where the points look noisy."""
    k = default_k(k, pts.shape[1], len(pts))
    tree = cKDTree(pts)
    known = sigma is not None and pts.shape[1] == 3
    if not plain and (known or len(pts) > _NOISY_SAMPLE) and _probe_is_rough(pts, tree, k, workers):
        # Noisy: estimated on an even sample, each point taking its nearest sample point's normal;
        # with the noise's σ known (3D), the plain fit on a sample sparse enough for its k
        # nearest to see past the noise (see _noise_sample), else a big cloud's sample of
        # _NOISY_SAMPLE (see estimate_normals).
        sample = _noise_sample(pts, tree, k, sigma, workers) if known and sigma is not None else None
        if sample is not None:
            say(f"noisy: estimating on an even sample of {len(sample):,} of the {len(pts):,} points, "
                f"its {k} nearest {SIGMAS_WIDE:g} σ of the noise wide")
            return _on_sample(pts, sample, lambda at: _estimate(at, k, orient, workers, want_confidence, say,
                                                                plain=True), say, workers)
        if len(pts) > _NOISY_SAMPLE:
            sample = spread(pts, _NOISY_SAMPLE)
            say(f"noisy: estimating on an even sample of {len(sample):,} of the {len(pts):,} points")
            return _on_sample(pts, sample, lambda at: _estimate(at, k, orient, workers, want_confidence, say,
                                                                sigma), say, workers)
    idx = neighbours(tree, k, workers)
    normals, values = pca(pts, idx)
    flatness = flatness_of(values)
    say(f"{len(pts):,} neighbourhoods of {k} points fitted")
    scaled = None if plain else noise_scale(pts, tree, idx, flatness, workers, sigma)
    if scaled is not None:
        # Noise-dominated: the normals of wider neighbourhoods, oriented on a denoised,
        # coarser sample of the shape (see orient_coarse).
        say(f"noisy: neighbourhoods grown to {SIGMAS_WIDE:g} σ of the noise" if scaled.by_sigma else
            "noisy: neighbourhoods grown past the noise")
        out = orient_coarse(pts, tree, scaled, workers) if orient else scaled.normals
        return out, scaled.confidence
    links: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None
    doubtful: NDArray[np.intp] | None = None
    if pts.shape[1] == 2:
        _refit_along_curve(pts, idx, normals, flatness)
    else:
        curve, link_lo, link_hi = _refit_sampled_curves(pts, tree, idx, normals, workers)
        links = (link_lo, link_hi)
        # Where the k nearest points are a poor sample of a plane (on one or two rows, or not
        # flat: sparse or uneven sampling, thin parts), the line with the largest empty ball.
        doubtful = doubtful_points(values)
        refitted = np.zeros(len(pts), dtype=bool)
        refitted[curve] = True
        pole_lines(pts, tree, doubtful, normals, workers, keep=refitted)
    confidence = normal_confidence(pts, idx, normals) if want_confidence else np.full(len(pts), np.nan)
    if orient:
        say("orienting")
        # Sparse or unevenly sampled clouds: the doubtful points' outside is also tested with
        # large empty balls (poles.exterior_anchors), and the winding number votes.
        uneven = doubtful is not None and is_uneven(doubtful, len(pts))
        normals = orient_graph(pts, normals, idx, flatness, links, tree=tree,
                               exterior=doubtful if uneven else None, winding=uneven, layers=layers and uneven)
    return normals, confidence


def looks_noisy(points: NDArray, workers: int = -1) -> bool:
    """Whether :func:`estimate_normals` takes ``points`` (checked, (N, D)) for noisy data: their
    k nearest neighbours (of an even probe of a big cloud) spread along the normal as only noise
    wider than them does (:func:`~ipfit.normals.scale.roughness`). Clean clouds, sparse CAD
    vertices included, are not."""
    pts = standardise(points)
    if len(pts) <= pts.shape[1] + 1:
        return False
    return _probe_is_rough(pts, cKDTree(pts), default_k(None, pts.shape[1], len(pts)), check_workers(workers))


def _probe_is_rough(pts: NDArray, tree: cKDTree, k: int, workers: int) -> bool:
    """The test for noise on the k nearest neighbours of _NOISY_PROBE points spread over ``pts``
    (of every point of a smaller cloud)."""
    at = spread(pts, _NOISY_PROBE) if len(pts) > _NOISY_PROBE else slice(None)
    probe = neighbours(tree, k, workers, pts[at])
    return roughness(pts, probe, pca_normals(pts, probe)[1]) is not None


def _check_inliers(inliers: ArrayLike, n: int) -> NDArray[np.bool_]:
    mask = np.asarray(inliers)
    if mask.dtype != np.bool_ or mask.shape != (n,):
        got = f"an array of shape {mask.shape} and dtype {mask.dtype}"
        raise error("inliers", f"a boolean mask of shape ({n},), one entry per point", got,
                    "Pass e.g. ipfit.robust.score_outliers(points).inliers.")
    if mask.sum() < 3:
        raise error("inliers", "at least 3 inliers", str(int(mask.sum())), "Mark more points as inliers.")
    return mask


def _normals_of_inliers(points: NDArray, mask: NDArray[np.bool_], k, orient, workers, noise, return_confidence,
                        progress):
    """Normals estimated on the inliers alone; each other point takes its nearest inlier's (confidence 0)."""
    normals = np.empty(points.shape)
    confidence = np.zeros(len(points))
    normals[mask], confidence[mask] = estimate_normals(points[mask], k, orient=orient, workers=workers, noise=noise,
                                                       return_confidence=True, progress=progress)
    std = standardise(points)  # a far stray's squared distance must not overflow
    _, nearest = cKDTree(std[mask]).query(std[~mask], workers=check_workers(workers))
    normals[~mask] = normals[mask][nearest]
    return (normals, confidence) if return_confidence else normals


def contour_normals(points: ArrayLike, *, closed: bool = True, span: int = 1) -> NDArray[np.float64]:
    """Outward unit normals of an ordered 2D contour: perpendiculars of central differences.

    The outward side comes from the sign of the enclosed area (for an open contour, of the
    area closed by the chord between its ends), so either direction of travel works.

    Parameters
    ----------
    points : (N, 2) array, in order along the contour, N >= 3
    closed : bool
        Whether the last point connects back to the first.
    span : int
        Difference between the points ``span`` places ahead and behind. On pixel-traced
        contours span=1 only sees the 45° staircase; 2 or 3 averages it.

    >>> square = [[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]]
    >>> contour_normals(square)[1].tolist()
    [0.0, -1.0]
    """
    pts = standardise(as_points(points, dims=(2,), min_points=3))  # the area below squares coordinates
    span = check_int(span, "span", minimum=1, maximum=max(1, (len(pts) - 1) // 2))
    if closed:
        nxt, prv = np.roll(pts, -span, axis=0), np.roll(pts, span, axis=0)
    else:
        at = np.arange(len(pts))
        nxt = pts[np.minimum(at + span, len(pts) - 1)]
        prv = pts[np.maximum(at - span, 0)]
    tangent = nxt - prv
    # A spike that goes out and back has a zero central difference: use a one-sided one.
    for fallback in (nxt - pts, pts - prv):
        zero = ~(np.abs(tangent).sum(axis=1) > 0)
        tangent[zero] = fallback[zero]
    x, y = pts[:, 0] - pts[:, 0].mean(), pts[:, 1] - pts[:, 1].mean()
    twice_area = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # right of travel: outward if counter-clockwise
    if twice_area < 0:
        normal = -normal
    normal, ok = unit_rows_mask(normal)
    if not ok.all():
        raise error("points", "a contour without repeated consecutive points",
                    f"{int((~ok).sum())} points with no direction", "Remove repeated points first.")
    return normal

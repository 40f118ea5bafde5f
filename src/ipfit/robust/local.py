"""Local surfaces: each point's offset from a quadric fitted to reference points around it.

A sample of a curve or surface lies on the smooth piece its neighbours trace; a stray point
does not. :func:`fit_local` fits, for each query point, a quadric height function over the
tangent line or plane (``h = a + b u + c u²`` in 2D, a full quadratic in ``(u, v)`` in 3D) to
k reference points around it, by iteratively reweighted least squares (Tukey weights), and
returns how far the query lies from it. The query is never one of its own k points, so an
outlier cannot pull its own fit towards itself.

The k points are the nearest *along the tangent* of a wider neighbourhood, not the k nearest:
the k nearest of a noisy point lie mostly on its own side of the noise band, so a fit to them
passes near it and the noise looks smaller than it is (measured on the development contours
with noise 1 % of the box diagonal: about 0.5 of the true σ at k = 10, against 0.8-1.2 chosen
along the tangent of 4k points).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._utils.threads import default_threads, in_parts

# The frame's neighbourhood: up to this many times k reference points, those within the
# caller's reach (and always the k nearest).
WIDE = 4
# Tukey's biweight constant in units of the fit's MAD scale (4.685 is the 95 %-efficient
# choice for Gaussian residuals; 4 rejects a second layer, across a thin part, a little sooner).
_TUKEY = 4.0
_IRLS_STEPS = 2
# The residual is divided by sqrt(1 + leverage), the spread of a prediction at the query. A
# query beyond its k points (leverage > 1) is extrapolated, and dividing by its full leverage
# would let a far outlier on the extension of a patch pass as a sample of it.
_LEVERAGE_CAP = 1.0
# Queries whose frames are held at once (see fit_local): 4k = 48 neighbours of 2^16 queries
# are 50 MB of distances and indices.
_QUERIES = 1 << 16
# The fits of fewer queries than this are not worth a thread of their own.
_MIN_PART = 4096


class LocalFit(NamedTuple):
    """One quadric per query point (arrays of length n, one row per query)."""

    residual: NDArray[np.float64]
    """The query's offset from its quadric, divided by sqrt(1 + leverage) (leverage capped)."""
    offset: NDArray[np.float64]
    """Distance from the query to the centroid of its k points along the tangent, in units of
    their RMS spread about it: about 0-1 among them, large when the query lies beyond them."""
    neighbours: NDArray[np.intp]
    """(n, k) indices into the reference points of each query's k points."""
    extent: NDArray[np.float64]
    """The RMS spread of the k points along the tangent, about their centroid."""
    widest: float
    """The smallest reach that widens a frame beyond the k nearest (the least k-th distance)."""


def n_terms(dim: int) -> int:
    """Coefficients of the local quadric: 3 in 2D, 6 in 3D."""
    return 3 if dim == 2 else 6


def _neighbourhoods(tree: cKDTree, query: NDArray, own: NDArray[np.intp], width: int,
                    workers: int) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Distances and indices of each query's ``width`` nearest reference points, itself left out."""
    count = min(width + 1, tree.n)
    dist, idx = tree.query(query, k=count, workers=workers)
    dist, idx = dist.reshape(len(query), count), idx.reshape(len(query), count)
    keep = idx != own[:, None]
    # the first `width` kept columns, in order (the query itself is at most one column)
    order = np.argsort(~keep, axis=1, kind="stable")[:, :count - 1]
    return np.take_along_axis(dist, order, 1), np.take_along_axis(idx, order, 1)


def _frames(tree: cKDTree, query: NDArray, own: NDArray[np.intp], k: int, reach: float | None,
            workers: int) -> tuple[NDArray[np.float64], NDArray[np.intp], float]:
    """Each query's frame neighbourhood: distances (inf = not in it) and indices, nearest first.

    Only the queries whose k-th neighbour lies within ``reach`` need more than k points, so
    the wider search is run for those alone (on clean data, none). Also returns the least k-th
    distance: a reach below it keeps every frame to the k nearest.
    """
    width = min(WIDE * k, tree.n - 1)
    dist, idx = _neighbourhoods(tree, query, own, k, workers)
    least = float(dist[:, -1].min())
    need = np.arange(len(query)) if reach is None else np.flatnonzero(dist[:, -1] < reach)
    if width == k or len(need) == 0:
        return dist, idx, least
    wide_dist = np.full((len(query), width), np.inf)
    wide_idx = np.zeros((len(query), width), dtype=np.intp)
    wide_dist[:, :k], wide_idx[:, :k] = dist, idx
    wide_dist[need], wide_idx[need] = _neighbourhoods(tree, query[need], own[need], width, workers)
    if reach is not None:
        wide_dist[wide_dist > np.maximum(reach, wide_dist[:, k - 1:k])] = np.inf
    return wide_dist, wide_idx, least


def fit_local(ref: NDArray, query: NDArray, own: NDArray[np.intp], k: int, reach: float | None,
              workers: int) -> LocalFit:
    """Fit a quadric to k reference points around each query point; see the module notes.

    Parameters
    ----------
    ref : (M, D) reference points, M > k
    query : (n, D) points to measure
    own : (n,) index of each query point in ``ref``, or -1: left out of its own fit
    k : points per fit
    reach : radius of the frame's neighbourhood, or None for the widest (``WIDE * k`` points).
        The k nearest are always in it, so a radius below their distance (0) keeps only them:
        on clean data that keeps the two sides of a thin part apart.
    workers : threads for the neighbour search and the fits: -1 for all cores (at most
        ``OMP_NUM_THREADS`` when set), or a positive number
    """
    n = len(query)
    tree = cKDTree(ref)
    residual, offset, extent = np.empty(n), np.empty(n), np.empty(n)
    chosen = np.empty((n, k), dtype=np.intp)
    least = np.inf
    threads = default_threads() if workers == -1 else workers
    # The frames are found a slice of queries at a time: at 4k neighbours each, a million
    # queries' distances and indices at once are 768 MB (it was a fit's peak memory).
    for part in range(0, n, _QUERIES):
        at = slice(part, min(part + _QUERIES, n))
        dist, wide, nearest = _frames(tree, query[at], own[at], k, reach, workers)
        least = min(least, nearest)
        _fit_frames(ref, query[at], dist, wide, k, residual[at], offset[at], extent[at], chosen[at], threads)
    return LocalFit(residual, offset, chosen, extent, least)


def _fit_frames(ref: NDArray, query: NDArray, dist: NDArray, wide: NDArray[np.intp], k: int,
                residual: NDArray, offset: NDArray, extent: NDArray, chosen: NDArray[np.intp], threads: int) -> None:
    """The quadric fits of ``query``'s frames (``dist``, ``wide`` from :func:`_frames`), written
    into the views ``residual``, ``offset``, ``extent`` and ``chosen``: the compiled kernel over
    ``threads`` even parts of the queries (it releases the GIL)."""
    from ._local_kernels import quadric_frames  # here: reading a file loads no numba

    def run(at: slice) -> None:
        quadric_frames(ref, query[at], dist[at], wide[at], k, _TUKEY, _IRLS_STEPS, _LEVERAGE_CAP,
                       residual[at], offset[at], extent[at], chosen[at])

    in_parts(run, len(query), threads, _MIN_PART)

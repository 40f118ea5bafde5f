"""Distances from query points to a shape: bare points, polyline segments or mesh triangles.

The engine of :mod:`ipfit.zeroset.quality` (distances between the data and a zero set) and of
:mod:`ipfit.zeroset.trim` (which parts of a zero set lie near the data): a :class:`Target` holds
samples of the shape in a k-d tree, finds candidate elements among the nearest samples and
computes the distance to them exactly (:mod:`ipfit.geometry._distance_kernels`). Both modules import it;
neither imports the other. The samples themselves (:class:`Samples`, :func:`sample_segments`,
:func:`sample_triangles`) are also the quadrature of a zero set's measures
(:meth:`ipfit.zeroset.extract.ZeroSet.sample`), which is why :mod:`ipfit.zeroset.extract` imports them from
here and this module imports nothing of the package at import time.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from .._utils.threads import default_threads, in_parts

__all__ = ["Samples", "sample_segments", "sample_triangles", "Target", "points_target", "contour_target",
           "contour_pieces", "mesh_target", "data_target", "query_workers", "DEFAULT_TAU_FRACTION",
           "DEFAULT_MAX_SAMPLES", "BREAK_RATIO"]

#: The tolerance τ within which a point counts as on the data's shape, as a fraction of the
#: data's bounding-box diagonal: the default of :func:`ipfit.zeroset.quality.quality` and the least
#: default distance of :func:`ipfit.zeroset.trim.trim_zero_set`.
DEFAULT_TAU_FRACTION = 0.02
#: Cap on the samples of one shape (the spacing grows beyond it).
DEFAULT_MAX_SAMPLES = 2_000_000


# -- samples of a shape: candidates for the distances, quadrature for the zero set's measures --

class Samples(NamedTuple):
    """Points spread over a curve or surface with quadrature weights.

    ``weights`` are the lengths (2D) or areas (3D) each sample stands for, so weighted means
    are means over the shape, not over however it happened to be triangulated.
    ``labels`` are the component index of each sample (-1 when unknown), ``elements``
    the segment or face it was drawn from.
    """

    points: NDArray[np.float64]
    weights: NDArray[np.float64]
    labels: NDArray[np.int64]
    elements: NDArray[np.int64] | None = None  # index of the segment / face each sample lies on


def _pieces(lengths: NDArray, spacing: float, max_samples: int | None, power: int) -> NDArray[np.int64]:
    # Pieces per element (segment: k, triangle: k²); coarsen the spacing when over budget.
    for _ in range(8):
        ks = np.maximum(1, np.ceil(lengths / spacing)).astype(np.int64)
        total = int(np.sum(ks ** power))
        if max_samples is None or total <= max_samples or ks.max() == 1:
            return ks
        spacing *= 1.05 * (total / max_samples) ** (1 / power)
    return ks


def sample_segments(starts: NDArray, ends: NDArray, spacing: float,
                    labels: NDArray | None = None, max_samples: int | None = None) -> Samples:
    """Midpoints of equal pieces of each segment, at most ``spacing`` long, with their lengths.

    Every point of a segment is within ``spacing / 2`` of a sample. With ``max_samples``,
    the spacing grows as needed to stay near that count (every segment keeps one sample).
    """
    starts = np.asarray(starts, dtype=np.float64)
    ends = np.asarray(ends, dtype=np.float64)
    dim = starts.shape[1] if starts.ndim == 2 else 2
    lengths = np.linalg.norm(ends - starts, axis=1)
    pieces = _pieces(lengths, spacing, max_samples, 1)
    owner = np.repeat(np.arange(len(lengths)), pieces)
    # position of each piece within its segment: 0..pieces-1, without a Python loop
    first = np.cumsum(pieces) - pieces
    rank = np.arange(owner.size) - first[owner]
    t = (rank + 0.5) / pieces[owner]
    pts = starts[owner] + t[:, None] * (ends[owner] - starts[owner]) if owner.size else np.empty((0, dim))
    weights = lengths[owner] / pieces[owner]
    lab = np.full(owner.size, -1, dtype=np.int64) if labels is None else np.asarray(labels)[owner]
    return Samples(pts, weights, lab, owner)


def _subtriangle_centroids(k: int) -> NDArray[np.float64]:
    # Barycentric (s, t) of the centroids of the k² congruent triangles of a k-subdivision.
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    up = (i + j) <= k - 1
    down = (i + j) <= k - 2
    s = np.concatenate([i[up] + 1 / 3, i[down] + 2 / 3]) / k
    t = np.concatenate([j[up] + 1 / 3, j[down] + 2 / 3]) / k
    return np.column_stack([s, t])


def sample_triangles(vertices: NDArray, faces: NDArray, spacing: float,
                     labels: NDArray | None = None, max_samples: int | None = None) -> Samples:
    """Centroids of a regular subdivision of every face, with the area each stands for.

    A face whose longest edge is L is cut into k² congruent triangles, k = ceil(L / spacing),
    so every point of the surface is within about ``2/3 · spacing`` of a sample, and the
    weights are exact areas (a midpoint quadrature of the surface). With ``max_samples``,
    the spacing grows as needed to stay near that count (every face keeps one sample).
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return Samples(np.empty((0, 3)), np.empty(0), np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64))
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    longest = np.maximum.reduce([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                                 np.linalg.norm(a - c, axis=1)])
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    ks = _pieces(longest, spacing, max_samples, 2)
    lab = np.full(len(f), -1, dtype=np.int64) if labels is None else np.asarray(labels, dtype=np.int64)
    pts, wts, labs, elems = [], [], [], []
    for k in np.unique(ks):  # few distinct subdivision levels: vectorised within each
        sel = np.flatnonzero(ks == k)
        bary = _subtriangle_centroids(int(k))
        e1, e2 = b[sel] - a[sel], c[sel] - a[sel]
        p = a[sel, None, :] + bary[None, :, 0, None] * e1[:, None, :] + bary[None, :, 1, None] * e2[:, None, :]
        pts.append(p.reshape(-1, 3))
        wts.append(np.repeat(areas[sel] / (k * k), len(bary)))
        labs.append(np.repeat(lab[sel], len(bary)))
        elems.append(np.repeat(sel, len(bary)))
    return Samples(np.concatenate(pts), np.concatenate(wts), np.concatenate(labs), np.concatenate(elems))


# -- distances to a sampled shape ---------------------------------------------------------------

# scipy's k-d tree starts its worker threads on every call: a loss on small calls (2D contours,
# the data's few hundred points), a gain on the tens of thousands of samples of a 3D zero set
# (benchmarks/bench_quality.py times the measurement).
_THREADED_QUERIES = 20_000
# Leaves of 64 samples: a query far from a surface has many near-equidistant samples, which
# larger leaves visit with less tree overhead; the answers are the same.
_LEAF_SIZE = 64


def query_workers(n_queries: int) -> int:
    """k-d tree worker threads for a call of ``n_queries`` queries."""
    return default_threads() if n_queries >= _THREADED_QUERIES else 1


class Target:
    """A shape to measure distances to: bare points, segments or triangles, with its tolerance τ.

    Samples of the shape find candidates (the elements of the k nearest samples) and the
    distance is then exact to those elements. Every "within τ" decision is exact: a query
    whose candidates are all farther than τ is asked again with more neighbours until every
    sample within τ + r is among them, r being the largest distance from a sample to a point
    of the piece it stands for (so the piece holding the nearest point within τ, if any, has
    been seen). Within the band 2τ + r the distance is exact whenever the nearest element is
    among the candidates, and never exceeds the nearest-sample distance. Farther away, where
    the distance only enters the Chamfer mean, it is computed the same way for up to
    ``far_budget`` evenly spread queries and, for the others, is that of their nearest such
    query: a k-d tree answers far queries against a dense surface slowly, and the answer
    there needs no sub-τ precision.
    """

    _ENTRIES = 1 << 22  # neighbours per k-d tree call when completing candidates

    def __init__(self, samples: Samples, kind: str, corners: tuple[NDArray, ...] = (), *, tau: float = np.inf,
                 far_budget: int = 5000, k: int = 6, tree=None) -> None:
        from scipy.spatial import cKDTree

        self.samples, self.kind, self.corners = samples, kind, corners
        self.tau, self.far_budget = tau, far_budget
        self.k = 1 if kind == "points" else min(k, len(samples.points))
        self.reach = _piece_radius(samples, kind, corners)
        self.band = 2 * tau + self.reach
        # a tree of the samples given (a cloud's own) answers the same: the searches are exact
        self.tree = cKDTree(samples.points, leafsize=_LEAF_SIZE) if tree is None else tree
        self._cells: NDArray[np.int64] | None = None

    def _build_cells(self) -> None:
        # Cells of side `band` holding samples, grown by one cell: a query outside them is
        # farther than `band` from every sample, and needs no k-d tree search to say so.
        points = self.samples.points
        dim = points.shape[1]
        keys = np.floor(points / self.band).astype(np.int64)
        self._lo = keys.min(axis=0) - 1
        self._extent = keys.max(axis=0) - self._lo + 2
        codes = np.unique(self._encode(keys))  # 1D codes: far cheaper to sort than rows
        offsets = np.stack(np.meshgrid(*[[-1, 0, 1]] * dim, indexing="ij"), axis=-1).reshape(-1, dim)
        self._cells = np.unique((codes[:, None] + self._encode(offsets - self._lo)[None, :]
                                 - self._encode(np.zeros((1, dim), dtype=np.int64) - self._lo)).ravel())

    def _encode(self, keys: NDArray) -> NDArray:
        code = np.zeros(len(keys), dtype=np.int64)
        for j in range(keys.shape[1]):
            code = code * self._extent[j] + (keys[:, j] - self._lo[j])
        return code

    def _maybe_near(self, query: NDArray) -> NDArray[np.bool_]:
        # The cells only pay for themselves over many queries: a few data points against a
        # dense zero set go straight to the (bounded) k-d tree search.
        if not np.isfinite(self.band) or len(query) < len(self.samples.points) // 4:
            return np.ones(len(query), dtype=bool)
        if self._cells is None:
            self._build_cells()
        cells = cast(NDArray[np.int64], self._cells)  # built just above
        keys = np.floor(query / self.band).astype(np.int64)
        inside = np.all((keys >= self._lo) & (keys < self._lo + self._extent), axis=1)
        out = np.zeros(len(query), dtype=bool)
        out[inside] = np.isin(self._encode(keys[inside]), cells)
        return out

    def _nearest(self, query: NDArray, k: int, bound: float = np.inf) -> tuple[NDArray, NDArray]:
        """Distances to the k nearest samples (within ``bound``) and the nearest candidate element."""
        d, idx = self.tree.query(query, k=[1] if k == 1 else k, distance_upper_bound=bound,
                                 workers=query_workers(len(query)))
        d, idx = d.reshape(len(query), k), idx.reshape(len(query), k)
        if self.kind == "points":
            return d, d[:, 0]
        from ._distance_kernels import nearest_candidates

        a, b, *c = self.corners
        out = np.empty(len(query))

        def run(rows: slice) -> None:
            out[rows] = nearest_candidates(query[rows], idx[rows], len(self.samples.points), self.samples.elements,
                                           a, b, c[0] if c else a, d[rows, 0], self.kind == "triangles")

        in_parts(run, len(query), query_workers(len(query)), _THREADED_QUERIES)
        return d, out

    def distance(self, query: NDArray) -> NDArray:
        from scipy.spatial import cKDTree

        query = np.ascontiguousarray(query, dtype=np.float64)
        out = np.full(len(query), np.inf)
        rows = np.flatnonzero(self._maybe_near(query))
        d, out[rows] = self._nearest(query[rows], self.k, self.band)
        # Complete the candidates of queries still beyond τ while a sample within τ + reach was
        # left out: only then could a piece within τ have been missed.
        bound = self.tau + self.reach
        k, n = self.k, len(self.samples.points)
        todo = rows[(out[rows] > self.tau) & (d[:, -1] <= bound)] if self.kind != "points" else rows[:0]
        while todo.size and k < n:
            k = min(4 * k, n)
            still = []
            for block in np.array_split(todo, -(-todo.size * k // self._ENTRIES)):  # bounded memory
                d, nearest = self._nearest(query[block], k, bound * (1 + 1e-12))
                out[block] = np.minimum(out[block], nearest)
                still.append(block[(out[block] > self.tau) & (d[:, -1] <= bound)])
            todo = np.concatenate(still)
        far = np.flatnonzero(~np.isfinite(out))
        if far.size:
            probe = far[:: -(-far.size // self.far_budget)]
            out[probe] = self._nearest(query[probe], self.k)[1]
            rest = far[np.isin(far, probe, assume_unique=True, invert=True)]
            if rest.size:
                # distance is 1-Lipschitz: a near probe's value is off by at most the gap to it
                nearest = cKDTree(query[probe]).query(query[rest], workers=query_workers(rest.size))[1]
                out[rest] = out[probe][nearest]
        return out


def _piece_radius(samples: Samples, kind: str, corners: tuple[NDArray, ...]) -> float:
    """Largest distance from a sample to a point of the piece of its element it stands for."""
    if kind == "points" or not len(samples.points):
        return 0.0
    # samples of segments or faces record their element
    count = np.bincount(cast(NDArray[np.int64], samples.elements), minlength=len(corners[0]))
    used = count > 0
    ends = [c[used] for c in corners]
    if kind == "segments":  # midpoints of `count` equal pieces
        return float(np.max(np.linalg.norm(ends[1] - ends[0], axis=1) / count[used]) / 2)
    # centroids of k² similar triangles: a point of one is within 2/3 of its longest median
    sq = [np.einsum("ij,ij->i", e, e) for e in (ends[1] - ends[0], ends[2] - ends[1], ends[0] - ends[2])]
    median2 = np.max([2 * (sq[0] + sq[1] + sq[2]) - 3 * x for x in sq], axis=0) / 4
    return float(np.max(np.sqrt(median2 / count[used])) * 2 / 3)


def points_target(pts: NDArray, tau: float, tree=None) -> Target:
    """The points themselves, each its own sample (``tree``: a k-d tree of them, if one is at hand)."""
    n = len(pts)
    return Target(Samples(pts, np.ones(n), np.full(n, -1), np.arange(n)), "points", tau=tau, tree=tree)


#: A jump between consecutive points of an ordered contour longer than this many times their
#: median gap ends a piece (a loop, or an open arc); the same ratio closes a piece.
BREAK_RATIO = 10.0


def contour_pieces(points: NDArray) -> list[tuple[int, int, bool]]:
    """The pieces of an ordered 2D contour: ``(start, stop, closed)`` row ranges, split where
    consecutive points jump more than :data:`BREAK_RATIO` median gaps (the readers put one
    loop after another, outline then holes); a piece is closed unless its own closing gap is
    that long too.

    >>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> circle = np.c_[np.cos(t), np.sin(t)]
    >>> contour_pieces(np.vstack([circle, circle / 2 + 3, circle[:20]]))  # two loops, then an arc
    [(0, 40, True), (40, 80, True), (80, 100, False)]
    """
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return [(0, len(pts), False)]
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    limit = BREAK_RATIO * float(np.median(gaps))
    cuts = [0, *(np.flatnonzero(gaps > limit) + 1).tolist(), len(pts)] if limit > 0 else [0, len(pts)]
    out = []
    for start, stop in itertools.pairwise(cuts):
        closing = float(np.linalg.norm(pts[start] - pts[stop - 1]))
        out.append((start, stop, stop - start > 2 and 0 < closing <= limit))
    return out


def contour_target(points: NDArray, spacing: float, max_samples: int, tau: float) -> Target:
    """The polylines through 2D ``points`` in order, piece by piece (:func:`contour_pieces`: a
    contour file or silhouette of several loops lists one after another), each closed unless
    its closing gap is far longer than the typical one (an open curve), sampled every
    ``spacing`` at most."""
    pieces = [np.vstack([points[a:b], points[a:a + 1]]) if closed else points[a:b]
              for a, b, closed in contour_pieces(points)]
    starts = np.concatenate([piece[:-1] for piece in pieces])
    ends = np.concatenate([piece[1:] for piece in pieces])
    return Target(sample_segments(starts, ends, spacing, max_samples=max_samples), "segments", (starts, ends),
                  tau=tau)


def mesh_target(vertices: NDArray, faces: NDArray, samples: Samples, tau: float) -> Target:
    """The triangles ``faces`` over ``vertices``, found through ``samples`` of them."""
    return Target(samples, "triangles", (vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]),
                  tau=tau)


def data_target(pts: NDArray, faces: NDArray | None, ordered_contour: bool, spacing: float, max_samples: int,
                tau: float, get_tree=None) -> tuple[Target, str]:
    """The shape the data stands for, and its name: the mesh's faces ("faces"), the 2D
    contour through the points in order ("contour") or the points themselves ("points").
    ``pts`` and ``faces`` are checked; ``spacing`` and ``max_samples`` sample the faces or
    the contour, ``tau`` is the target's tolerance; ``get_tree``, a callable giving a k-d tree
    of ``pts``, is asked for only when the points are the target."""
    if faces is not None and len(faces):
        return mesh_target(pts, faces, sample_triangles(pts, faces, spacing, max_samples=max_samples), tau), "faces"
    if faces is None and ordered_contour:
        return contour_target(pts, spacing, max_samples, tau), "contour"
    return points_target(pts, tau, None if get_tree is None else get_tree()), "points"

"""Empty balls: the normal line of sparse, uneven samples, and the outside of a closed shape.

A sample of a surface lies on the boundary of empty balls that reach far along its normal and
only a little along the surface: its Voronoi cell is long and thin, and the cell's farthest
vertex, the *pole*, gives the normal line even where the sampling is too uneven for a plane fit
(Amenta & Bern 1999). That is the case of the vertices of CAD meshes, few on flat panels and many
at details: a point's k nearest neighbours can lie on one row, or on two rows of a rounded edge,
and the plane through them is then the wrong one (up to 90° off). :func:`pole_lines` keeps, per
point, the candidate line (plane fits at several sizes, the offset from the neighbourhood's
centroid, planes through the point and two neighbours) that leaves the largest empty ball touching
the point, on either side, among its nearest points; where several reach past those points, the
one deepest inside the cone of empty directions (Mitra & Nguyen 2003 choose among neighbourhood
sizes by flatness instead: on these clouds the flattest plane is often the wrong one).

:func:`exterior_anchors` finds points whose outward side is plain: a large empty ball touches them
from one side, and no small one fits on the other. They seed the orientation (:mod:`.orient`) far
beyond the convex hull's vertices.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import row_norms, unit_rows_mask
from .local import blocks, covariances, neighbours, spread

# 3D points whose k nearest neighbours are a poor sample of a plane get the line of the largest
# empty ball (pole_lines): neighbours spread mostly along one direction (second spread below
# _ROWS of the first: one or two rows of points), or not flat (least spread above _CURVED of the
# second). A finely sampled scan has few: 2 % of the bunny, 8 % of bunny_res2, 14 % of the duck,
# 21 % of the apple (its stem's rings); the vertices of the development CAD meshes 47-100 %.
_ROWS = 0.3
_CURVED = 0.1
# Where at least this share is doubtful (CAD meshes: 47-100 %; the apple 21 %, the duck 14 %), the
# neighbour graph's links are unreliable too (they cross thin parts): the orientation also takes
# anchors from large empty balls and the winding number's vote (orient._winding_votes).
_UNEVEN = 0.25


def doubtful_points(values: NDArray) -> NDArray[np.intp]:
    """The points whose k-nearest spreads (``values``, (N, 3) ascending) are a poor sample of a plane."""
    return np.flatnonzero((values[:, 1] < _ROWS * values[:, 2]) | (values[:, 0] > _CURVED * values[:, 1]))


def is_uneven(doubtful: NDArray[np.intp], n: int) -> bool:
    """Whether a cloud with these doubtful points is sparse or uneven enough for empty-ball anchors."""
    return len(doubtful) >= _UNEVEN * n


# The nearest points that bound the empty balls (the point itself included). On the development
# meshes 48 gets most of the full Voronoi poles' gain (24: half; 96: no more), at 48 dot products
# per candidate and point.
_REACH = 48
# Plane fits of these sizes are candidates, with the offset from the centroid of these:
_SIZES = (6, 8, 16, 24, 32, 48)
_CENTROID_SIZES = (8, 16)
_CROSS = 4  # and the planes through the point and two of its _CROSS nearest other points

# A ball touching the point reaches past its nearest points when its radius is above half the
# farthest one's distance: it is then "full", and fulls are compared by their angular margin.
_FULL = 10.0
_KEEP = 0.5  # a refitted line stays if its ball reaches half the way (see pole_lines)

# Exterior anchors (see exterior_anchors): an empty ball of radius _OUTSIDE × the bounding box's
# diagonal on one side, none of _CROWDED × it on the other.
_OUTSIDE = 1.0 / 6.0
_CROWDED = 1.0 / 24.0
_TILT = np.radians(30.0)  # the ball may touch along the line or tilted this far from it, ...
_AZIMUTHS = 4  # ... in these many directions
# Points tested at most (spread over them): enough anchors in bounded time. A query this far from
# the data costs ~8 times one at a point.
_EXTERIOR_MOST = 4000


def _candidates(points: NDArray, wide: NDArray[np.intp], current: NDArray) -> NDArray[np.float64]:
    """Candidate normal lines of each point (rows of ``wide``, nearest first): (C, n, 3)."""
    reach = wide.shape[1]
    out = [current]
    at = points[wide[:, 0]]
    plane_sizes = {min(size, reach) for size in _SIZES}
    centroid_sizes = {min(size, reach) for size in _CENTROID_SIZES}
    for size in sorted(plane_sizes | centroid_sizes):
        _, vectors = np.linalg.eigh(covariances(points, wide[:, :size]))
        if size in plane_sizes:
            out.append(vectors[:, :, 0])
        if size in centroid_sizes:
            # On a curved part (a thin tube's ring, a rounded edge) the point stands off the
            # centroid of its neighbours along the normal, across the direction of most spread.
            axis = vectors[:, :, 2]
            off = at - points[wide[:, :size]].mean(axis=1)
            off -= np.einsum("ij,ij->i", off, axis)[:, None] * axis
            out.append(unit_rows_mask(off)[0])
    step = points[wide[:, 1:1 + _CROSS]] - at[:, None, :]
    for i in range(step.shape[1]):
        for j in range(i + 1, step.shape[1]):
            out.append(unit_rows_mask(np.cross(step[:, i], step[:, j]))[0])
    return np.stack(out)


def _ball_scores(step: NDArray, sq: NDArray, line: NDArray) -> NDArray[np.float64]:
    """Score of each candidate line: the larger empty ball on its two sides, as a share of the
    reach (below 1), or _FULL + the angular margin on the open side where a ball reaches past
    the neighbours. Lines without a direction (zero rows) score -inf."""
    s = np.einsum("ikj,ij->ik", step, line)
    s = np.where(sq > 0, s, 0.0)  # a coincident point bounds nothing
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(s > 0, sq / (2.0 * s), np.inf).min(axis=1)
        down = np.where(s < 0, sq / (-2.0 * s), np.inf).min(axis=1)
        cos = s / np.sqrt(np.where(sq > 0, sq, 1.0))
    cap = np.sqrt(sq.max(axis=1)) / 2.0
    radius = np.minimum(np.maximum(up, down), cap)
    margin = np.maximum(np.where(up >= cap, -cos.max(axis=1), -1.0), np.where(down >= cap, cos.min(axis=1), -1.0))
    score = np.where(radius >= cap, _FULL + margin, radius / np.where(cap > 0, cap, 1.0))
    return np.where(np.abs(line).sum(axis=1) > 0, score, -np.inf)


def pole_lines(points: NDArray, tree: cKDTree, rows: NDArray[np.intp], normals: NDArray, workers: int,
               keep: NDArray[np.bool_] | None = None) -> None:
    """Replace the normals of ``rows`` by the candidate line with the largest empty ball, in place.

    3D points only. The current normal is one of the candidates, so a point keeps it unless
    another line leaves a larger empty ball (see the module notes). Points marked in ``keep``
    (a mask over all points) keep it also where its ball only nearly reaches past their
    neighbours (half the way: _KEEP).
    """
    n = len(points)
    reach = min(_REACH, n)
    if len(rows) == 0 or reach < 4:
        return
    for part in blocks(len(rows), reach * 4):
        at = rows[part]
        wide = neighbours(tree, reach, workers, points[at])
        wide[:, 0] = at  # the point itself first, even among coincident points
        cands = _candidates(points, wide, normals[at])
        step = points[wide[:, 1:]] - points[at][:, None, :]
        # each neighbourhood at its own scale (the scores do not depend on it): a far outlier's
        # squared offsets must not overflow
        big = np.abs(step).max(axis=(1, 2))
        step /= np.where(big > 0, big, 1.0)[:, None, None]
        sq = np.einsum("ikj,ikj->ik", step, step)
        scores = np.stack([_ball_scores(step, sq, c) for c in cands])
        # A kept line whose ball nearly reaches past the neighbours stays: the margin prefers
        # lines pointing away from one-sided neighbourhoods (the end of a sampled tube, whose
        # surface goes on beyond the neighbours), which only farther points could refute.
        stays = scores[0] >= _FULL
        if keep is not None:
            stays |= keep[at] & (scores[0] >= _KEEP)
        scores[0] = np.where(stays, 2.0 * _FULL, scores[0])
        best = np.argmax(scores, axis=0)
        normals[at] = cands[best, np.arange(len(at))]


def _frame(line: NDArray) -> tuple[NDArray, NDArray]:
    helper = np.where(np.abs(line[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = unit_rows_mask(np.cross(line, helper))[0]
    return t1, np.cross(line, t1)


def exterior_anchors(points: NDArray, tree: cKDTree, normals: NDArray, rows: NDArray[np.intp],
                     workers: int) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Points whose outside is plain: a large empty ball on one side, a crowd on the other (3D).

    A point is an anchor where an empty ball of radius D/6 (D: the bounding box's diagonal)
    touches it from one side of its normal line while no ball of radius D/24 fits on the other:
    the large ball is outside, the other side is inside a thin or crowded part. Each side is
    tried along the line and tilted 30° from it in four directions, so that a normal a few
    degrees off still finds its ball; the direction returned is the mean of the empty ones.
    Open surfaces, empty on both sides, give no anchor. Only ``rows`` are tested, at most
    _EXTERIOR_MOST of them, spread over them.

    No ball of radius D/3 fits inside a solid the cloud bounds (the largest ball inside a box
    has radius at most D/(2√3) = 0.289 D); D/6 against D/24 is an empirical rule: on the 14
    development meshes, with their own normals and the exact largest empty balls, it marks
    7-55 % of the vertices (D/3 on both sides: 4-52 %) and never the wrong side.
    """
    none = (np.empty(0, np.intp), np.empty((0, 3)))
    diagonal = float(row_norms(np.ptp(points, axis=0)[None, :])[0])
    if len(points) < 4 or len(rows) == 0 or not diagonal > 0:
        return none
    test = np.asarray(rows, dtype=np.intp)
    test = test[spread(points[test], _EXTERIOR_MOST)]
    p, line = points[test], normals[test]
    t1, t2 = _frame(line)
    directions = [line] + [np.cos(_TILT) * line + np.sin(_TILT) * (np.cos(a) * t1 + np.sin(a) * t2)
                           for a in 2.0 * np.pi * np.arange(_AZIMUTHS) / _AZIMUTHS]

    def empty_side(radius: float, sign: float, gap: float) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """Whether a ball of ``radius``, ``gap`` off the point along some direction, is empty."""
        total = np.zeros_like(p)
        found = np.zeros(len(p), dtype=bool)
        for d in directions:
            dist, _ = tree.query(p + sign * (radius + gap) * d, k=1, workers=workers)
            empty = dist >= radius * (1.0 - 1e-9)  # with no gap, the point itself lies on the ball
            total[empty] += sign * d[empty]
            found |= empty
        return found, total

    # The large ball touches the point; the small one may stand a sixteenth of its radius off, so
    # that a neighbour standing a little proud of the point does not make a side look crowded.
    outside, crowded = _OUTSIDE * diagonal, _CROWDED * diagonal
    (up, up_dir), (down, down_dir) = (empty_side(outside, sign, 0.0) for sign in (1.0, -1.0))
    up &= ~empty_side(crowded, -1.0, crowded / 16.0)[0]
    down &= ~empty_side(crowded, 1.0, crowded / 16.0)[0]
    one = up ^ down
    direction, ok = unit_rows_mask(np.where(up[:, None], up_dir, down_dir)[one])
    return test[one][ok].astype(np.intp), direction[ok]

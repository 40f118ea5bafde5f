"""Normals rounded over thin rims and sharp creases, as a mesh's vertex normals are.

A dense scan's normals as :func:`~ipfit.estimate_normals` finds them are those of its faces: on a
thin part (a fin, a wing, a blade) they point to either side right up to its rim. A polynomial's
zero set is smooth, and normals that say nothing about where a thin part ends leave it free to run
on past the rim. On 5,000 points drawn on the Turk dolphins' surface, their face normals give F
0.58; the same normals rounded here 0.91, interpolated from the mesh's vertex normals (which turn
outward over the rim within one edge of it) 0.94 (docs/rims.md).

:func:`round_rims` turns the normals near a rim outward over it without a mesh: a point whose
neighbours, seen on its tangent plane, leave a wide empty angle (at a rim, all of them lie on one
side: the other face of a thin part too) turns its normal towards the middle of that angle, the
more the wider it is. A wide angle by the sampling's chance, or at a point alone, is no rim; the
cloud must be dense and evenly spread (uneven spacing leaves empty angles too, as on a mesh's
vertices), else the normals are kept.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import row_norms, tangent_frames, unit_rows
from .._utils.validation import as_matching, as_points, as_weights, check_positive, error
from .local import check_workers, spread

__all__ = ["round_rims", "RIM_RADIUS"]

#: The rounding radius, in the units of :class:`~ipfit.Normalization` (the data's mean distance
#: to their centre is 1): twice the 3L offset (``ipfit.fitting.linear.DEFAULT_OFFSET``),
#: so that the offsets on the two sides of a thin part do not meet past its rim; about 2.5 % of a
#: compact shape's box diagonal, about a coarse mesh's edge.
RIM_RADIUS = 0.1
# A point at a rim sees its neighbours, projected on its tangent plane, on one side of it: the
# largest angle between two consecutive ones is 180° at the rim (the other side of a thin part
# lies on the same side) and 2·acos(d / radius) at a distance d inside it. The turn grows from 0
# at a gap of _START to full at 180°, where the gap is not the sampling's chance: among n uniform
# directions a gap of a share g of the circle or more has probability about n·(1 - g)^(n-1),
# which must be below _CHANCE (180° among 12 neighbours: 0.6 %; 120° among 24: 0.2 %).
_START = np.radians(120.0)
_CHANCE = 0.01
_FEWEST = 8
# A point turns only when at least _RIM_NEIGHBOURS of its _ALONG_RIM nearest points turn too.
_ALONG_RIM = 8
_RIM_NEIGHBOURS = 2
# Neighbours nearly along the normal (the other face of a thin part, right behind the point) have
# no direction on the tangent plane: left out below this share of their distance.
_ALONG = 0.3
# The neighbours counted (the nearest within the radius).
_MOST_NEIGHBOURS = 48
# A mesh's vertices are spread unevenly (small triangles where the shape bends, long ones where
# it is flat): they leave wide empty angles without a rim. The spacing's spread (p90 / p10 of the
# distance to the 8th nearest) is 1.6-1.8 on the 5,000-point scans of the 21 meshes of
# docs/rims.md, 2.0-8.7 on the vertices of 19 of them (the regular remeshes fandisk and
# cheburashka: 1.3 and 1.8).
_SPACING_K = 8
_UNEVEN = 2.0
# The angles are taken on an even sample of at most this many points, each point taking its
# nearest sample point's turn: a rim is a property of the surface at the radius' scale.
_SAMPLE = 20_000


def _widest_gaps(sample, normals, idx, dist, within):
    """Per point, the turn (0-1) from the widest angle between its neighbours on its tangent
    plane, and the unit direction bisecting that angle (outward, where the points end)."""
    e1, e2 = tangent_frames(normals)
    offset = sample[idx] - sample[:, None, :]
    a, b = np.einsum("ijk,ik->ij", offset, e1), np.einsum("ijk,ik->ij", offset, e2)
    valid = within & (np.hypot(a, b) > _ALONG * np.where(within, dist, 0.0))
    angle = np.sort(np.where(valid, np.arctan2(b, a), np.inf), axis=1)
    count = valid.sum(axis=1)
    rows = np.arange(len(sample))
    last = angle[rows, np.maximum(count - 1, 0)]
    with np.errstate(invalid="ignore"):  # inf - inf past each row's last neighbour, masked below
        steps = np.diff(angle, axis=1)
        wrap = np.where(count > 0, angle[:, 0] - last, 0.0) + 2 * np.pi
    steps[np.arange(steps.shape[1])[None, :] >= (count - 1)[:, None]] = -np.inf
    gaps = np.column_stack([steps, wrap])
    widest = np.argmax(gaps, axis=1)
    gap = gaps[rows, widest]
    inner = widest < steps.shape[1]
    start = np.where(inner, angle[rows, np.minimum(widest, steps.shape[1] - 1)], last)
    bisector = np.where(count > 0, start + gap / 2, 0.0)
    turn = np.clip((gap - _START) / (np.pi - _START), 0.0, 1.0)
    chance = count * (1.0 - gap / (2 * np.pi)) ** np.maximum(count - 1, 0)
    turn[(count < _FEWEST) | (chance > _CHANCE)] = 0.0
    direction = np.cos(bisector)[:, None] * e1 + np.sin(bisector)[:, None] * e2
    return turn, direction


def _even(tree: cKDTree, workers: int) -> bool:
    """Whether the points are spread evenly enough for an empty angle to mean a rim:
    the spacing (the distance to the :data:`_SPACING_K`-th nearest) of the widest-spaced tenth at
    most :data:`_UNEVEN` times that of the closest-spaced tenth."""
    if tree.n <= _SPACING_K:
        return False
    spacing = tree.query(tree.data, k=[_SPACING_K + 1], workers=workers)[0][:, 0]
    low, high = np.percentile(spacing, [10, 90])
    return bool(high <= _UNEVEN * low)


def round_rims(points: ArrayLike, normals: ArrayLike, radius: float = RIM_RADIUS, *,
               weights: ArrayLike | None = None, workers: int = -1,
               return_turn: bool = False) -> NDArray[np.float64] | tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The unit ``normals`` of a 3D cloud turned outward over its thin rims and sharp creases.

    Parameters
    ----------
    points : (N, 3) array
    normals : (N, 3) array
        Oriented normals (their signs are kept: a rim turns each towards the side where the
        points end, within its own half-space).
    radius : float
        The rounding radius in normalised units (:class:`~ipfit.Normalization`).
    weights : (N,) array, optional
        Per-point weights in [0, 1]: points weighing less than 1/2 are left out of the rims'
        statistics (a stray the outlier score found does not fill a rim's empty side) and take
        their nearest other point's turn.
    workers : int
        Threads for the neighbour search: -1 for all cores, or a positive number.
    return_turn : bool
        Also return each point's turn in [0, 1] (0: its normal kept; 1: turned fully along the
        tangent plane).

    Returns
    -------
    (N, 3) array of unit normals, and with ``return_turn`` the (N,) turns.

    Examples
    --------
    A thin plate's two faces, 0.01 apart: the points near its border turn outward over it, the
    middle keeps its normals.

    >>> import numpy as np
    >>> g = np.linspace(-1, 1, 61)
    >>> x, y = [a.ravel() for a in np.meshgrid(g, g)]
    >>> top = np.column_stack([x, y, np.full(x.size, 0.005)])
    >>> pts = np.vstack([top, top * [1, 1, -1]])
    >>> nrm = np.repeat([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], x.size, axis=0)
    >>> out, turn = round_rims(pts, nrm, return_turn=True)
    >>> middle = np.tile(np.maximum(abs(x), abs(y)) < 0.8, 2)
    >>> bool(np.all(out[middle] == nrm[middle]))
    True
    >>> edge = np.tile((x == 1) & (abs(y) < 0.5), 2)  # the middle of the border at x = 1
    >>> bool(turn[edge].min() > 0.5), bool(out[edge, 0].min() > 0.7)
    (True, True)
    """
    pts = as_points(points)
    if pts.shape[1] != 3:
        raise error("points", "3D points (rims are a surface's)", f"{pts.shape[1]}D points")
    nrm = unit_rows(as_matching(normals, pts, "normals"))
    radius = check_positive(radius, "radius")
    workers = check_workers(workers)
    w = None if weights is None else as_weights(weights, len(pts))
    # in the fit's normalised units (ipfit.Normalization: centred, the mean distance to the centre 1)
    u = pts - pts.mean(axis=0)
    scale = float(row_norms(u).mean())
    trusted = np.arange(len(u)) if w is None else np.flatnonzero(w >= 0.5)
    pick = trusted[spread(u[trusted], _SAMPLE)]
    if not scale > 0 or len(pick) <= _SPACING_K:
        return (nrm, np.zeros(len(nrm))) if return_turn else nrm
    u /= scale
    sample, sample_normals = u[pick], nrm[pick]
    tree = cKDTree(sample)
    if not _even(tree, workers):
        return (nrm, np.zeros(len(nrm))) if return_turn else nrm
    dist, idx = tree.query(sample, k=min(_MOST_NEIGHBOURS, len(sample)), distance_upper_bound=radius,
                           workers=workers)
    within = np.isfinite(dist) & (dist > 0)
    idx = np.where(within, idx, 0)
    turn, tangent = _widest_gaps(sample, sample_normals, idx, dist, within)
    # a rim is a line of such points; one alone is the sampling's chance (1 in 1/_CHANCE)
    nearest_turned = np.sum(within[:, :_ALONG_RIM + 1] & (turn[idx[:, :_ALONG_RIM + 1]] > 0), axis=1)
    turn[nearest_turned < _RIM_NEIGHBOURS] = 0.0
    # every point takes its nearest sample point's turn and direction, in its own tangent plane
    nearest = np.arange(len(u)) if len(pick) == len(u) else tree.query(u, workers=workers)[1]
    direction = tangent[nearest]
    direction -= np.einsum("ij,ij->i", direction, nrm)[:, None] * nrm
    length = np.linalg.norm(direction, axis=1)
    turn_all = np.where(length > 0, turn[nearest], 0.0)
    direction /= np.maximum(length, 1e-300)[:, None]
    out = unit_rows((1.0 - turn_all)[:, None] * nrm + turn_all[:, None] * direction)
    return (out, turn_all) if return_turn else out

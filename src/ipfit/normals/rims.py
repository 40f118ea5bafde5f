"""Normals rounded over thin rims and sharp creases, as a mesh's vertex normals are.

A dense scan's normals (a scanner's, or :func:`~ipfit.normals.estimate_normals`') are those of
its faces: on a thin part (a fin, a wing, a blade) they point to either side right up to its
rim. A polynomial's zero set is smooth, and normals that say nothing about where a thin part
ends leave it free to run on past the rim: fitted with its face normals, a dense sample of the
Turk dolphins' surface gives F 0.58, with the normals interpolated from its mesh's vertex normals
(which turn outward over the rim, within one edge of it) 0.93; the 5 % of the points where the
two differ by more than 60° decide it (docs/rims.md).

:func:`round_rims` turns the normals near a rim outward over it without a mesh: a point whose
neighbours within the rounding radius lie to one side of it along its tangent plane (their
centroid displaced from it, as at the edge of a half-disc) is at a rim or crease, and its normal
turns towards the side where the points end, the more the farther the centroid is displaced. The
radius is about a coarse mesh's edge: the points within it must be many (the displacement of a
few scattered points is noise) and spread evenly (uneven spacing moves the centroid too, as on a
mesh's vertices), so sparse and unevenly sampled clouds keep their normals.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import unit_rows
from .._utils.validation import as_matching, as_points, as_weights, check_positive, error
from .local import check_workers

__all__ = ["round_rims", "RIM_RADIUS"]

#: The rounding radius, in the units of :class:`~ipfit.Normalization` (the data's mean distance
#: to their centre is 1): twice the 3L offset (:data:`~ipfit.fitting.linear.DEFAULT_OFFSET`),
#: so that the offsets on the two sides of a thin part do not meet past its rim; about 2.5 % of a
#: compact shape's box diagonal, a coarse mesh's edge (the Turk dolphins' is 0.10).
RIM_RADIUS = 0.1
# The centroid's displacement along the tangent plane, as a share of the radius: at the edge of
# a uniformly sampled half-disc it is 4/(3π) ≈ 0.42, inside a full disc 0 up to the sampling's
# noise, about 0.6/√(points within the radius). The normal starts turning at _START above that
# noise and has turned fully _RAMP further.
_START = 0.05
_RAMP = 0.25
_NOISE = 0.6
# Fewer points within the radius than _FEWEST: no turn (their centroid is noise); full turns from
# twice as many.
_FEWEST = 8
# The neighbours counted (the nearest within the radius): enough for the centroid's noise to be
# small next to a rim's displacement.
_MOST_NEIGHBOURS = 96
# A mesh's vertices are spread unevenly (small triangles where the shape bends, long ones where
# it is flat): their centroid moves without a rim, and their normals are a mesh's, rounded. The
# spacing's spread (p90 / p10 of the distance to the 8th nearest) is 1.6-1.8 on the surface
# samples of the 23 development and external meshes, 2.0-8.7 on the vertices of 21 of them
# (regular remeshes, fandisk and cheburashka, 1.3 and 1.8): docs/rims.md.
_SPACING_K = 8
_UNEVEN = 2.0
# The statistics are taken on an even sample of at most this many points, each point taking its
# nearest sample point's: the displacement is a property of the surface at the radius' scale.
_SAMPLE = 20_000


def _even(tree: cKDTree, workers: int) -> bool:
    """Whether the points are spread evenly enough for the centroid's displacement to mean a rim:
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
        Per-point weights in [0, 1]: the neighbours' centroid is weighted by them (a stray the
        outlier score found does not displace it).
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
    from ..geometry.sampling import spread_subsample
    from ..polynomial import Normalization

    pts = as_points(points)
    if pts.shape[1] != 3:
        raise error("points", "3D points (rims are a surface's)", f"{pts.shape[1]}D points")
    nrm = unit_rows(as_matching(normals, pts, "normals"))
    radius = check_positive(radius, "radius")
    workers = check_workers(workers)
    w = None if weights is None else as_weights(weights, len(pts))
    u = Normalization.from_points(pts).apply(pts)
    pick = spread_subsample(u, _SAMPLE) if len(u) > _SAMPLE else np.arange(len(u))
    sample, sample_normals = u[pick], nrm[pick]
    tree = cKDTree(sample)
    if not _even(tree, workers):
        return (nrm, np.zeros(len(nrm))) if return_turn else nrm
    dist, idx = tree.query(sample, k=min(_MOST_NEIGHBOURS, len(sample)), distance_upper_bound=radius,
                           workers=workers)
    within = np.isfinite(dist)
    idx = np.where(within, idx, 0)
    mass = within.astype(float) if w is None else np.where(within, w[pick][idx], 0.0)
    total = mass.sum(axis=1)
    count = within.sum(axis=1)
    centroid = np.einsum("ij,ijk->ik", mass, sample[idx]) / np.maximum(total, 1e-300)[:, None]
    offset = sample - centroid
    tangent = offset - np.einsum("ij,ij->i", offset, sample_normals)[:, None] * sample_normals
    shift = np.linalg.norm(tangent, axis=1) / radius
    turn = np.clip((shift - _NOISE / np.sqrt(np.maximum(count, 1)) - _START) / _RAMP, 0.0, 1.0)
    turn *= np.clip((count - _FEWEST) / _FEWEST, 0.0, 1.0)
    turn[total <= 0] = 0.0
    # every point takes its nearest sample point's turn and direction, in its own tangent plane
    nearest = np.arange(len(u)) if len(pick) == len(u) else tree.query(u, workers=workers)[1]
    direction = tangent[nearest]
    direction -= np.einsum("ij,ij->i", direction, nrm)[:, None] * nrm
    length = np.linalg.norm(direction, axis=1)
    turn_all = np.where(length > 0, turn[nearest], 0.0)
    direction /= np.maximum(length, 1e-300)[:, None]
    out = unit_rows((1.0 - turn_all)[:, None] * nrm + turn_all[:, None] * direction)
    return (out, turn_all) if return_turn else out

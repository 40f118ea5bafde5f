"""Trim an extracted zero set to the data: drop the parts farther than a distance from it.

An implicit polynomial's zero set cannot be open: fitted to an open scan (a cup without a
lid, a vase without a base) it closes the openings with surface no data supports. The
polynomial stays as it is; what a user exports or draws can be trimmed to the data, as
screened-Poisson users do with density trimming.

A 3D face is kept when all three of its vertices lie within the distance of the data's
shape: its points (the data's faces, densely sampled, when the data is a mesh; the points
themselves otherwise). Vertices no kept face uses are dropped. A 2D curve is cut into the
runs of consecutive vertices within the distance.

A gap in the sampling is not an opening, and the two are told apart by how far the surface
beyond the distance gets from the data: a connected region of the zero set farther than the
distance that nowhere gets farther than the *gap* distance is a hole between samples,
enclosed by data, and is kept; the surface over an opening (a missing lid) runs on far from
every point and goes. So the default distance can hug the data at an opening (2 median
point spacings, at least half the quality tolerance τ) while the default gap (5 spacings, at
least τ: the widest empty patch of random samples, see :func:`default_gap_distance`) keeps a
closed shape whole. An explicit distance of at least the gap is the plain rule above.

A sphere's zero set trimmed to data on its lower half: the upper half goes, but for a
collar as wide as the trim distance along the data's rim.

>>> import ipfit
>>> from ipfit.datasets import synthetic
>>> sphere = synthetic.sphere(2000)
>>> bowl = sphere.points[sphere.points[:, 2] < 0]
>>> zs = ipfit.extract_zero_set(sphere.polynomial, points=sphere.points, resolution=64)
>>> cup = zs.trimmed(bowl)
>>> print(cup.trim.describe())
trimmed 45.0% of the surface area farther than 0.1507 from the data (holes in the data kept up to 0.3768)
>>> bool(cup.vertices[:, 2].max() <= cup.trim.distance), cup.closed, zs.trimmed(sphere.points).trim.removed_share
(True, False, 0.0)
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import as_faces, as_points, check_positive, error
from ..geometry.distance import DEFAULT_MAX_SAMPLES, DEFAULT_TAU_FRACTION, data_target
from .extract import ZeroSet

__all__ = ["Trim", "trim_zero_set", "trim_mask", "default_trim_distance", "default_gap_distance",
           "DEFAULT_TRIM_SPACINGS", "DEFAULT_GAP_SPACINGS"]

#: The default trim distance in median point spacings: the surface between neighbouring samples
#: along a rim stays, and little more.
DEFAULT_TRIM_SPACINGS = 2.0
#: The default gap distance in median point spacings: holes between samples up to this far from
#: every sample are kept (see :func:`default_gap_distance`).
DEFAULT_GAP_SPACINGS = 5.0


@dataclass(frozen=True)
class Trim:
    """What :func:`trim_zero_set` removed.

    Attributes
    ----------
    distance : the distance used, in the data's units.
    removed_share : share of the zero set's area (3D) or length (2D) removed, in [0, 1].
    removed_size, kept_size : area (3D) or length (2D) removed and kept.
    removed_faces : 3D: faces removed; 2D: polyline segments removed.
    reference : what distances were measured to: "faces" (the data's surface) or "points".
    measure : "area" (3D) or "length" (2D).
    gap : regions farther than ``distance`` that nowhere get farther than this from the data
        (holes between samples) were kept; equal to ``distance`` when none could be.
    """

    distance: float
    removed_share: float
    removed_size: float
    kept_size: float
    removed_faces: int
    reference: str
    measure: str = "area"
    gap: float = 0.0

    def describe(self) -> str:
        """One line, e.g. ``trimmed 23.4% of the surface area farther than 0.012 from the data``
        (and, when holes could be kept, ``(holes in the data kept up to 0.03)``)."""
        what = "surface area" if self.measure == "area" else "curve length"
        holes = f" (holes in the data kept up to {self.gap:.4g})" if self.gap > self.distance else ""
        return (f"trimmed {100 * self.removed_share:.1f}% of the {what} farther than {self.distance:.4g} from the "
                f"data{holes}")


def _spacing(pts: NDArray) -> float:
    from ..geometry.sampling import point_spacing

    nearest = point_spacing(pts)
    nearest = nearest[nearest > 0]  # repeated points say nothing about the sampling density
    if nearest.size == 0:
        raise error("points", "points with some extent", "identical points", "Pass the trim distance explicitly.")
    return float(np.median(nearest))


def _tolerance(pts: NDArray) -> float:
    return DEFAULT_TAU_FRACTION * float(np.linalg.norm(np.ptp(pts, axis=0)))


def default_trim_distance(points: ArrayLike) -> float:
    """The default trim distance: the larger of 2 point spacings and half the quality tolerance τ.

    The spacing is the median distance from each point to its nearest neighbour; τ is
    :data:`ipfit.zeroset.quality.DEFAULT_TAU_FRACTION` (2 %) of the data's box diagonal. Two
    spacings keep the surface between neighbouring samples along an opening's rim, so the
    trimmed surface ends about that far beyond the last data; half of τ keeps a fit that is
    precise by the quality measures' standard from fraying there. Holes between samples
    farther than this from the data are not cut: they are kept up to
    :func:`default_gap_distance`.

    Four points 0.5, 1 and 1.5 apart (median spacing 0.75, diagonal 3):

    >>> default_trim_distance([[0.0, 0.0], [0.5, 0.0], [1.5, 0.0], [3.0, 0.0]])
    1.5
    """
    pts = as_points(points, min_points=2)
    return max(DEFAULT_TRIM_SPACINGS * _spacing(pts), 0.5 * _tolerance(pts))


def default_gap_distance(points: ArrayLike) -> float:
    """The default gap distance: the larger of 5 point spacings and the quality tolerance τ.

    A region of the zero set farther than the trim distance from the data but nowhere
    farther than this is a hole between samples and is kept. Among n points spread at random
    over a surface the widest empty patch has a radius of about sqrt(ln n / ln 2) median
    spacings (3.3 for 2 000 points, 4.1 for 100 000), and scanned data is more regular than
    that, so ``DEFAULT_GAP_SPACINGS`` (5) spacings keep every such hole; on dense data a good
    fit deviates from it by up to τ. Surface over a real opening (a missing lid, a cut base)
    gets farther than this from every point.

    >>> default_gap_distance([[0.0, 0.0], [0.5, 0.0], [1.5, 0.0], [3.0, 0.0]])
    3.75
    """
    pts = as_points(points, min_points=2)
    return max(DEFAULT_GAP_SPACINGS * _spacing(pts), _tolerance(pts))


def trim_zero_set(zero_set: ZeroSet, points: ArrayLike, distance: float | None = None, *,
                  faces: ArrayLike | None = None) -> ZeroSet:
    """The parts of ``zero_set`` near the data, as a new zero set.

    Parameters
    ----------
    zero_set : ZeroSet
        An extracted zero set (:func:`ipfit.extract_zero_set`), 2D or 3D.
    points : (N, dim) data points.
    distance : float, optional
        Keep what lies within this distance of the data, in the data's units, and the holes
        between samples: the connected regions beyond it that nowhere get farther from the
        data than :func:`default_gap_distance` (when that is larger). Default
        :func:`default_trim_distance`: 2 × the median nearest-neighbour spacing of the
        points, or half of 2 % of their box diagonal (the quality tolerance τ) when that is
        larger.
    faces : (F, 3) int array, optional
        Triangles over ``points`` when the data is a mesh: distances are then measured to
        its surface, not only to its vertices (a sparse mesh's faces are data too).

    Returns
    -------
    ZeroSet
        3D: the faces whose three vertices are all within ``distance`` of the data or in a
        hole, with the vertices they use. 2D: the runs of polyline vertices within
        ``distance`` or in a hole; a closed curve stays closed only when nothing of it is
        removed. Its ``trim`` attribute is a :class:`Trim` record (the distances used, the
        share removed); ``closed`` is False once anything was removed. The polynomial is the
        same object, untouched.

    Examples
    --------
    A circle's zero set, with data on its right half only: the left half goes, but for
    the arcs within the trim distance (2 spacings, 0.13) of the data's ends.

    >>> import ipfit
    >>> from ipfit.datasets import synthetic
    >>> zs = ipfit.extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    >>> t = np.linspace(-np.pi / 2, np.pi / 2, 50)
    >>> half = trim_zero_set(zs, np.column_stack([np.cos(t), np.sin(t)]))
    >>> round(half.trim.removed_share, 2), half.closed, len(half.curves)
    (0.46, False, 1)
    """
    keep, record = _keep(zero_set, points, distance, faces)
    if zero_set.is_empty:
        return replace(zero_set, trim=record)
    if zero_set.dim == 3:
        return _trim_mesh(zero_set, keep, record)
    return _trim_curves(zero_set, keep, record)


def trim_mask(zero_set: ZeroSet, points: ArrayLike, distance: float | None = None, *,
              faces: ArrayLike | None = None) -> NDArray[np.bool_] | list[NDArray[np.bool_]]:
    """What :func:`trim_zero_set` keeps, marked on ``zero_set`` itself (for drawing the rest apart).

    3D: one flag per face of ``zero_set``; 2D: per curve, one flag per segment. Arguments as
    in :func:`trim_zero_set`.
    """
    keep, _ = _keep(zero_set, points, distance, faces)
    if zero_set.is_empty:
        return np.empty(0, dtype=bool) if zero_set.dim == 3 else []
    if zero_set.dim == 3:
        return keep[zero_set._mesh()[1]].all(axis=1)
    return [ok[:-1] & ok[1:] for ok in keep]


def _keep(zero_set: ZeroSet, points: ArrayLike, distance: float | None, faces: ArrayLike | None):
    """Which vertices (3D) or, per curve, which polyline vertices (2D) are kept, and the record
    of the distances (its sizes still zero)."""
    if not isinstance(zero_set, ZeroSet):
        raise error("zero_set", "a ZeroSet (ipfit.extract_zero_set)", type(zero_set).__name__)
    pts = as_points(points, dims=(zero_set.dim,), min_points=2)
    distance = default_trim_distance(pts) if distance is None else check_positive(distance, "distance")
    gap = max(distance, default_gap_distance(pts))
    face_array = None
    if faces is not None:
        if zero_set.dim != 3:
            raise error("faces", "no faces for 2D data", "faces", "Drop faces; 2D data is trimmed to its points.")
        face_array = as_faces(faces, len(pts), 3)
        face_array = face_array if len(face_array) else None
    # The target decides "within the gap distance" exactly (its tolerance); samples only find
    # candidates. Distances below it are exact unless the nearest element is not among them,
    # and then overstated: a vertex near the data taken as farther lies in a hole, and is kept.
    target, reference = data_target(pts, face_array, False, distance, DEFAULT_MAX_SAMPLES, gap)
    record = Trim(distance=float(distance), removed_share=0.0, removed_size=0.0, kept_size=0.0, removed_faces=0,
                  reference=reference, measure="area" if zero_set.dim == 3 else "length", gap=float(gap))
    if zero_set.is_empty:
        return None, record
    if zero_set.dim == 3:
        vertices, mesh_faces = zero_set._mesh()
        d = target.distance(vertices)
        return _with_holes(d, distance, gap, mesh_faces), record
    return [_with_holes_along(target.distance(c), distance, gap, closed)
            for c, closed in zip(zero_set.curves, zero_set.curve_closed, strict=True)], record


def _with_holes(d: NDArray, distance: float, gap: float, faces: NDArray) -> NDArray[np.bool_]:
    """Vertices within ``distance``, and those of the connected regions beyond it (joined by
    the faces' edges) that nowhere get farther than ``gap``."""
    near = d <= distance
    far = np.flatnonzero(~near)
    if gap <= distance or far.size == 0:
        return near
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    index = np.full(len(d), -1)
    index[far] = np.arange(far.size)
    a = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2]])
    b = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
    both = (index[a] >= 0) & (index[b] >= 0)
    graph = coo_matrix((np.ones(both.sum()), (index[a[both]], index[b[both]])), shape=(far.size, far.size))
    _, labels = connected_components(graph, directed=False)
    farthest = np.zeros(labels.max() + 1)
    np.maximum.at(farthest, labels, d[far])
    out = near.copy()
    out[far] = farthest[labels] <= gap
    return out


def _with_holes_along(d: NDArray, distance: float, gap: float, closed: bool) -> NDArray[np.bool_]:
    """A polyline's vertices within ``distance``, and its runs beyond it that nowhere get
    farther than ``gap`` (a closed curve's runs wrap around its seam)."""
    near = d <= distance
    if gap <= distance or near.all():
        return near
    out = near.copy()
    if closed and near.any():
        # roll so that the polyline starts at a near vertex: no far run then crosses the seam
        # (a closed curve repeats its first vertex last)
        shift = int(np.flatnonzero(near[:-1])[0])
        order = np.concatenate([np.arange(shift, len(d) - 1), np.arange(shift + 1)])
    else:
        order = np.arange(len(d))
    for a, b in _runs(~near[order]):
        run = order[a:b]
        if d[run].max() <= gap:
            out[run] = True
    if closed:
        out[-1] = out[0]
    return out


def _face_areas(vertices: NDArray, faces: NDArray) -> NDArray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def _trim_mesh(zs: ZeroSet, near: NDArray[np.bool_], record: Trim) -> ZeroSet:
    vertices, old_faces = zs._mesh()
    keep = near[old_faces].all(axis=1)
    areas = _face_areas(vertices, old_faces)
    used = np.zeros(len(vertices), dtype=bool)
    used[old_faces[keep].ravel()] = True
    index = np.cumsum(used) - 1  # old vertex -> new vertex, for the vertices kept faces use
    faces = index[old_faces[keep]].astype(np.int64)
    record = _sized(record, float(areas[~keep].sum()), float(areas[keep].sum()), int((~keep).sum()))
    return replace(zs, vertices=vertices[used], faces=faces, trim=record)


def _runs(keep: NDArray[np.bool_]) -> list[tuple[int, int]]:
    # [start, stop) of each run of True in keep
    edges = np.diff(np.concatenate([[0], keep.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _trim_curves(zs: ZeroSet, near: list[NDArray[np.bool_]], record: Trim) -> ZeroSet:
    pieces, removed, kept, n_removed = [], 0.0, 0.0, 0
    for curve, ok, closed in zip(zs.curves, near, zs.curve_closed, strict=True):
        lengths = np.linalg.norm(np.diff(curve, axis=0), axis=1)
        segment_ok = ok[:-1] & ok[1:]
        removed += float(lengths[~segment_ok].sum())
        kept += float(lengths[segment_ok].sum())
        n_removed += int((~segment_ok).sum())
        if segment_ok.all():
            pieces.append(curve)
            continue
        if closed:
            # Start the loop at a removed segment so that no kept run is split at the seam.
            shift = int(np.flatnonzero(~segment_ok)[0]) + 1
            curve = np.vstack([curve[shift:-1], curve[:shift + 1]])
            segment_ok = np.roll(segment_ok, -shift)
        # a run of kept segments [a, b) spans vertices a..b
        pieces.extend(curve[a:b + 1] for a, b in _runs(segment_ok))
    return replace(zs, curves=tuple(pieces), trim=_sized(record, removed, kept, n_removed))


def _sized(record: Trim, removed: float, kept: float, n_removed: int) -> Trim:
    total = removed + kept
    return replace(record, removed_share=removed / total if total > 0 else 0.0, removed_size=removed,
                   kept_size=kept, removed_faces=n_removed)

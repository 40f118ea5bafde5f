"""Trim an extracted zero set to the data: drop the parts farther than a distance from it.

An implicit polynomial's zero set cannot be open: fitted to an open scan (a cup without a
lid, a vase without a base) it closes the openings with surface no data supports. The
polynomial stays as it is; what a user exports or draws can be trimmed to the data, as
screened-Poisson users do with density trimming.

A 3D face is kept when all three of its vertices lie within the distance of the data's
shape: its points (the data's faces, densely sampled, when the data is a mesh; the points
themselves otherwise). Vertices no kept face uses are dropped. A 2D curve is cut into the
runs of consecutive vertices within the distance.

A sphere's zero set trimmed to data on its lower half: the upper half goes, but for a
collar as wide as the trim distance along the data's rim.

>>> import ipfit
>>> from ipfit.datasets import synthetic
>>> sphere = synthetic.sphere(2000)
>>> bowl = sphere.points[sphere.points[:, 2] < 0]
>>> zs = ipfit.extract_zero_set(sphere.polynomial, points=sphere.points, resolution=64)
>>> cup = zs.trimmed(bowl)
>>> print(cup.trim.describe())
trimmed 33.8% of the surface area farther than 0.3768 from the data
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

__all__ = ["Trim", "trim_zero_set", "default_trim_distance", "DEFAULT_TRIM_SPACINGS"]

DEFAULT_TRIM_SPACINGS = 5.0


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
    """

    distance: float
    removed_share: float
    removed_size: float
    kept_size: float
    removed_faces: int
    reference: str
    measure: str = "area"

    def describe(self) -> str:
        """One line, e.g. ``trimmed 23.4% of the surface area farther than 0.012 from the data``."""
        what = "surface area" if self.measure == "area" else "curve length"
        return f"trimmed {100 * self.removed_share:.1f}% of the {what} farther than {self.distance:.4g} from the data"


def _spacing(pts: NDArray) -> float:
    from ..geometry.sampling import point_spacing

    nearest = point_spacing(pts)
    nearest = nearest[nearest > 0]  # repeated points say nothing about the sampling density
    if nearest.size == 0:
        raise error("points", "points with some extent", "identical points", "Pass the trim distance explicitly.")
    return float(np.median(nearest))


def default_trim_distance(points: ArrayLike) -> float:
    """The default trim distance: the larger of 5 point spacings and the quality tolerance τ.

    The spacing is the median distance from each point to its nearest neighbour. A gap in
    the sampling is not a hole in the shape: among n points spread at random over a surface
    the widest empty patch has a radius of about sqrt(ln n / ln 2) median spacings (3.3 for
    2 000 points, 4.1 for 100 000), and scanned data is more regular than that, so
    ``DEFAULT_TRIM_SPACINGS`` (5) spacings keep the surface between samples. τ is
    :data:`ipfit.zeroset.quality.DEFAULT_TAU_FRACTION` (2 %) of the data's box diagonal, the
    tolerance within which :func:`ipfit.zeroset.quality.quality` counts the zero set as on the data:
    on dense data a good fit deviates by more than a few spacings, and a default that cut
    what the quality measures call precise would punch holes in it. Surface over a real
    opening (a missing lid, a cut base) is farther than this from every point except for a
    collar of that width along the opening's rim.

    Four points 0.5, 1 and 1.5 apart (median spacing 0.75, diagonal 3):

    >>> default_trim_distance([[0.0, 0.0], [0.5, 0.0], [1.5, 0.0], [3.0, 0.0]])
    3.75
    """
    pts = as_points(points, min_points=2)
    diagonal = float(np.linalg.norm(np.ptp(pts, axis=0)))
    return max(DEFAULT_TRIM_SPACINGS * _spacing(pts), DEFAULT_TAU_FRACTION * diagonal)


def trim_zero_set(zero_set: ZeroSet, points: ArrayLike, distance: float | None = None, *,
                  faces: ArrayLike | None = None) -> ZeroSet:
    """The parts of ``zero_set`` within ``distance`` of the data, as a new zero set.

    Parameters
    ----------
    zero_set : ZeroSet
        An extracted zero set (:func:`ipfit.extract_zero_set`), 2D or 3D.
    points : (N, dim) data points.
    distance : float, optional
        Keep what lies within this distance of the data, in the data's units. Default
        :func:`default_trim_distance`: 5 × the median nearest-neighbour spacing of the
        points, or 2 % of their box diagonal (the quality tolerance τ) when that is larger.
    faces : (F, 3) int array, optional
        Triangles over ``points`` when the data is a mesh: distances are then measured to
        its surface, not only to its vertices (a sparse mesh's faces are data too).

    Returns
    -------
    ZeroSet
        3D: the faces whose three vertices are all within ``distance`` of the data, with the
        vertices they use (every point of a kept face is within ``distance`` plus one grid
        step of the data). 2D: the runs of polyline vertices within ``distance``; a closed
        curve stays closed only when nothing of it is removed. Its ``trim`` attribute is a
        :class:`Trim` record (the distance used, the share removed); ``closed`` is False once
        anything was removed. The polynomial is the same object, untouched.

    Examples
    --------
    A circle's zero set, with data on its right half only: the left half goes, but for
    the arcs within the trim distance (5 spacings, 0.32) of the data's ends.

    >>> import ipfit
    >>> from ipfit.datasets import synthetic
    >>> zs = ipfit.extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    >>> t = np.linspace(-np.pi / 2, np.pi / 2, 50)
    >>> half = trim_zero_set(zs, np.column_stack([np.cos(t), np.sin(t)]))
    >>> round(half.trim.removed_share, 2), half.closed, len(half.curves)
    (0.4, False, 1)
    """
    if not isinstance(zero_set, ZeroSet):
        raise error("zero_set", "a ZeroSet (ipfit.extract_zero_set)", type(zero_set).__name__)
    pts = as_points(points, dims=(zero_set.dim,), min_points=2)
    distance = default_trim_distance(pts) if distance is None else check_positive(distance, "distance")
    face_array = None
    if faces is not None:
        if zero_set.dim != 3:
            raise error("faces", "no faces for 2D data", "faces", "Drop faces; 2D data is trimmed to its points.")
        face_array = as_faces(faces, len(pts), 3)
        face_array = face_array if len(face_array) else None
    # The target decides "within distance" exactly (its tolerance); samples only find candidates.
    target, reference = data_target(pts, face_array, False, distance, DEFAULT_MAX_SAMPLES, distance)
    if zero_set.is_empty:
        return replace(zero_set, trim=_record(distance, 0.0, 0.0, 0, reference, zero_set.dim))
    if zero_set.dim == 3:
        return _trim_mesh(zero_set, target.distance(zero_set._mesh()[0]) <= distance, distance, reference)
    return _trim_curves(zero_set, [target.distance(c) <= distance for c in zero_set.curves], distance, reference)


def _face_areas(vertices: NDArray, faces: NDArray) -> NDArray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def _trim_mesh(zs: ZeroSet, near: NDArray[np.bool_], distance: float, reference: str) -> ZeroSet:
    vertices, old_faces = zs._mesh()
    keep = near[old_faces].all(axis=1)
    areas = _face_areas(vertices, old_faces)
    used = np.zeros(len(vertices), dtype=bool)
    used[old_faces[keep].ravel()] = True
    index = np.cumsum(used) - 1  # old vertex -> new vertex, for the vertices kept faces use
    faces = index[old_faces[keep]].astype(np.int64)
    record = _record(distance, float(areas[~keep].sum()), float(areas[keep].sum()), int((~keep).sum()), reference, 3)
    return replace(zs, vertices=vertices[used], faces=faces, trim=record)


def _runs(keep: NDArray[np.bool_]) -> list[tuple[int, int]]:
    # [start, stop) of each run of True in keep
    edges = np.diff(np.concatenate([[0], keep.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _trim_curves(zs: ZeroSet, near: list[NDArray[np.bool_]], distance: float, reference: str) -> ZeroSet:
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
    return replace(zs, curves=tuple(pieces), trim=_record(distance, removed, kept, n_removed, reference, 2))


def _record(distance: float, removed: float, kept: float, n_removed: int, reference: str, dim: int) -> Trim:
    total = removed + kept
    return Trim(distance=float(distance), removed_share=removed / total if total > 0 else 0.0, removed_size=removed,
                kept_size=kept, removed_faces=n_removed, reference=reference, measure="area" if dim == 3 else "length")

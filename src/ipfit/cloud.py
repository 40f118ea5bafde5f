"""The data of one fit: a point cloud, its normals and faces, and where they came from.

:func:`ipfit.load` returns a :class:`Cloud` for a file or a bundled dataset; a cloud built in
code holds copies of whatever arrays are given. It is immutable: its arrays are read-only, so
a cloud can be shared by every step of a fit without one step changing another's data, and
what it keeps derived from them stays true.

Because its data cannot change, a cloud also owns what is derived from it (trimesh's and
Open3D's way): its unit normals, k-d tree and point spacing as cached properties, and a store
(:meth:`Cloud.derived`) where the steps of a fit keep what depends on their parameters too (the
far-field term's samples, the start fits' big R factors, the data's side of a quality
measurement, the last measurements). :func:`ipfit.fit_adaptive` builds one cloud per fit and
passes it down, so each of these is computed once per fit; a public function given arrays
builds a transient cloud (:func:`as_cloud`), and nothing is kept across calls.

>>> import numpy as np
>>> cloud = Cloud(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), name="triangle")
>>> cloud.dim, len(cloud), cloud.n_file, cloud.normals_source, cloud.points.flags.writeable
(2, 3, 3, None, False)
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from ._utils.foreign import foreign_parts
from ._utils.validation import as_faces, as_matching, as_normals, as_points, as_weights, check_int, error

__all__ = ["Cloud", "as_cloud"]


#: point_spacing_at computes the spacings it is asked for alone while they are fewer than this
#: share (1 in _FEW_SPACINGS) of the cloud's points; more, and every point's is computed and kept.
_FEW_SPACINGS = 8


def _read_only(arr: NDArray) -> NDArray:
    # A view, so that the caller's own array stays writable and nothing is copied: for arrays
    # the cloud owns, or that live no longer than a transient cloud (as_cloud).
    view = arr.view()
    view.setflags(write=False)
    return view


def _frozen_copy(arr: NDArray) -> NDArray:
    # The caller may change its array later; the cloud's derived data must stay true to its own.
    return _read_only(np.array(arr, copy=True))


@dataclass(frozen=True, eq=False)
class Cloud:
    """A point cloud with its normals and faces, as read (or given).

    Parameters
    ----------
    points : (N, dim) array, dim 2 or 3
        Finite coordinates; held as a read-only float64 copy.
    normals : (N, dim) array, optional
        One normal per point, held as given (a read-only copy): :func:`ipfit.load` gives unit
        normals; None when there are none (estimate them, :func:`ipfit.estimate_normals`).
    faces : (F, 3) int array, optional
        Triangles as indices into ``points`` when the data is a mesh; None otherwise (and
        after a subsample, whose points the faces no longer index).
    name : str
        How the data is named in messages and output file names: a file's stem, a
        dataset's name.
    source : path or str, optional
        Where the data was read from: the file's path (a :class:`~pathlib.Path`) or the
        bundled dataset's name (a str); None for data built in code.
    n_file : int, optional
        Points in the source before subsampling (a file's rows, before duplicates are
        merged; a dataset's points); default ``len(points)``. ``n_file > len(cloud)`` says
        that points were dropped.
    normals_source : {"file", "faces", "contour", None}
        Where the normals come from: the file (or, for data built in code, the caller), the
        mesh's faces (area-weighted), the order of a contour; None when there are none.
        Default "file" when there are normals.
    weights : (N,) array in [0, 1], optional
        How much each point counts in a fit (a read-only float64 copy): the linear fits scale
        a point's rows by its square root, the objective weights its terms (a weighted mean),
        and a cloud with weights is fitted robustly (:func:`ipfit.refine`). None (default):
        every point counts fully, and the fits are exactly those of a cloud without weights.
        :func:`ipfit.fit_adaptive` gives the inliers' weights of
        :func:`ipfit.robust.score_outliers` when it found outliers.

    Attributes
    ----------
    dim : int
        2 or 3.
    unit_normals : (N, dim) array or None
        The normals scaled to unit length (what the fits use); computed once.
    kdtree : scipy.spatial.cKDTree
        Of the points; built once.
    spacing : (N,) array
        Each point's distance to its nearest other point (:meth:`point_spacing`).
    """

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None = None
    faces: NDArray[np.int64] | None = None
    name: str = "points"
    source: os.PathLike | str | None = None
    n_file: int | None = None
    normals_source: str | None = None
    weights: NDArray[np.float64] | None = None
    if TYPE_CHECKING:
        # The store (_start_store) is set with object.__setattr__, outside the dataclass fields;
        # declared for the type checker only.
        _derived: dict[tuple[str, Hashable], Any] = field(init=False, repr=False, compare=False)
        _lock: threading.Lock = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        points = as_points(self.points)
        normals = None if self.normals is None else as_matching(self.normals, points)
        faces = None if self.faces is None else as_faces(self.faces, len(points))
        n_file = len(points) if self.n_file is None else check_int(self.n_file, "n_file", minimum=len(points))
        source = None if normals is None else (self.normals_source or "file")
        weights = None if self.weights is None else as_weights(self.weights, len(points))
        # frozen: the checked values replace the given ones once, here
        for key, value in (("points", _frozen_copy(points)),
                           ("normals", None if normals is None else _frozen_copy(normals)),
                           ("faces", None if faces is None else _frozen_copy(faces)), ("name", str(self.name)),
                           ("n_file", n_file), ("normals_source", source),
                           ("weights", None if weights is None else _frozen_copy(weights))):
            object.__setattr__(self, key, value)
        self._start_store()

    def _start_store(self) -> None:
        # Outside the dataclass fields (not compared, not repr'd); fits may measure from several
        # threads, so the store is read and written under a lock.
        object.__setattr__(self, "_derived", {})
        object.__setattr__(self, "_lock", threading.Lock())

    def __getstate__(self) -> dict:
        # What a cloud derived stays behind (a lock cannot travel): a copy in another process
        # derives again what it needs.
        return {k: v for k, v in self.__dict__.items() if k not in ("_derived", "_lock")}

    def __setstate__(self, state: dict) -> None:
        for key, value in state.items():
            # unpickled arrays come back writable: the cloud's own copies, made read-only again
            object.__setattr__(self, key, _read_only(value) if isinstance(value, np.ndarray) else value)
        self._start_store()

    @classmethod
    def _checked(cls, points: NDArray[np.float64], unit_normals: NDArray[np.float64] | None,
                 faces: NDArray[np.int64] | None = None, weights: NDArray[np.float64] | None = None) -> Cloud:
        """A cloud of arrays the caller has already checked (:func:`as_cloud`), whose normals are
        the unit normals computed there, and whose weights (float64 in [0, 1], or None) are
        checked too: nothing is checked or normalised again."""
        cloud = cls.__new__(cls)
        normals = None if unit_normals is None else _read_only(unit_normals)
        for key, value in (("points", _read_only(points)), ("normals", normals),
                           ("faces", None if faces is None else _read_only(faces)), ("name", "points"),
                           ("source", None), ("n_file", len(points)),
                           ("normals_source", None if normals is None else "file"),
                           ("weights", None if weights is None else _read_only(weights))):
            object.__setattr__(cloud, key, value)
        cloud._start_store()
        # Normalising unit normals again could change their last bits: they are kept as they are.
        cloud._derived[("unit_normals", None)] = normals
        return cloud

    def derived(self, kind: str, key: Hashable, compute: Callable[[], Any], keep: int | None = None) -> Any:
        """What ``compute()`` derives from this cloud, computed the first time ``(kind, key)`` is
        asked for and kept; ``key`` must name every parameter the result depends on.

        With ``keep``, only the last ``keep`` results of that kind are kept (measurements hold
        whole zero sets). ``compute`` runs outside the lock: two threads asking at once may both
        compute, and both get the first result stored.

        >>> import numpy as np
        >>> cloud = Cloud(np.eye(3)[:, :2])
        >>> calls = []
        >>> [cloud.derived("double", 2, lambda: calls.append(1) or 4) for _ in range(3)], len(calls)
        ([4, 4, 4], 1)
        """
        full = (kind, key)
        with self._lock:
            if full in self._derived:
                return self._derived[full]
        value = compute()
        with self._lock:
            value = self._derived.setdefault(full, value)
            if keep is not None:
                same = [k for k in self._derived if k[0] == kind]
                for old in same[: max(0, len(same) - keep)]:
                    del self._derived[old]
        return value

    @property
    def unit_normals(self) -> NDArray[np.float64] | None:
        return self.derived("unit_normals", None, lambda: None if self.normals is None
                            else _read_only(as_normals(self.normals, self.points)))

    @property
    def oriented(self) -> NDArray[np.float64]:
        """``unit_normals`` of a cloud checked to have them (``as_cloud(..., required_by=...)``)."""
        normals = self.unit_normals
        if normals is None:
            raise error("normals", "one normal per point", "none", "Pass normals or ipfit.estimate_normals(points).")
        return normals

    @property
    def kdtree(self):
        from scipy.spatial import cKDTree

        return self.derived("kdtree", None, lambda: cKDTree(self.points))

    @property
    def spacing(self) -> NDArray[np.float64]:
        return self.point_spacing(1)

    def point_spacing(self, k: int = 1) -> NDArray[np.float64]:
        """Each point's distance to its ``k``-th nearest other point (read-only; 0 for a
        repeated point when ``k`` = 1, and for every point of a cloud of at most ``k`` points)."""
        return self.derived("point_spacing", k, lambda: _read_only(self._spacing_of(self.points, k)))

    def point_spacing_at(self, index: NDArray[np.intp], k: int = 1) -> NDArray[np.float64]:
        """``point_spacing(k)[index]``, computed for those points alone while they are a small
        share of the cloud and it does not hold every point's yet (a big cloud measured once needs
        a few of them); otherwise every point's, kept for the next call."""
        index = np.asarray(index, dtype=np.intp)
        with self._lock:
            every = self._derived.get(("point_spacing", k))
        at, back = np.unique(index, return_inverse=True)
        if every is None and len(at) * _FEW_SPACINGS < len(self):
            return self._spacing_of(self.points[at], k)[back.ravel()]
        return self.point_spacing(k)[index]

    def _spacing_of(self, query: NDArray[np.float64], k: int) -> NDArray[np.float64]:
        """The distance of each of ``query`` (points of this cloud) to its ``k``-th nearest other point."""
        if len(self) <= k:
            return np.zeros(len(query))
        return self.kdtree.query(query, k=[k + 1], workers=-1)[0][:, 0]

    @property
    def dim(self) -> int:
        return int(self.points.shape[1])

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        extras = [f"normals from {self.normals_source}" if self.normals is not None else "no normals"]
        if self.faces is not None:
            extras.append(f"{len(self.faces):,} faces")
        if cast(int, self.n_file) > len(self):  # __post_init__ replaced None with len(points)
            extras.append(f"{len(self):,} of {self.n_file:,} kept")
        if self.weights is not None:
            extras.append("weighted")
        return f"Cloud({self.name!r}: {len(self):,} {self.dim}D points, {', '.join(extras)})"


def as_cloud(points, normals=None, *, faces=None, weights=None, name: str = "points", dims=(2, 3),
             min_points: int = 1, required_by: str | None = None) -> Cloud:
    """``points`` (and ``normals``, ``faces``, ``weights``) as a :class:`Cloud`: a given cloud as
    it is (its own normals, faces and weights, and its store of derived data), arrays checked
    once (as :func:`~ipfit._utils.validation.as_points`, :func:`~ipfit._utils.validation.as_normals`
    with ``required_by``, :func:`~ipfit._utils.validation.as_faces`,
    :func:`~ipfit._utils.validation.as_weights`) into a transient cloud.

    The public functions that take points call this once at their entry and pass the cloud
    down; below it nothing is checked again. A trimesh, Open3D or PyVista object, or a
    DataFrame, gives its points, and its normals and faces when it has them
    (:mod:`ipfit._utils.foreign`); ``normals`` or ``faces`` given as well take their place.
    """
    parts = foreign_parts(points, name)
    if parts is not None:
        points = parts.points
        normals = parts.normals if normals is None else normals
        faces = parts.faces if faces is None else faces
    if isinstance(points, Cloud):
        for given, what in ((normals, "normals"), (faces, "faces"), (weights, "weights")):
            if given is not None:
                raise error(what, f"None when the points are a Cloud (its {what} are used)", type(given).__name__,
                            f"Build the Cloud with these {what}, or pass arrays.")
        if points.dim not in dims:
            raise error(name, " or ".join(f"{d}D points" for d in dims), f"a {points.dim}D Cloud")
        if len(points) < min_points:
            raise error(name, f"at least {min_points} points", f"a Cloud of {len(points)}", "Pass more points.")
        if required_by is not None and points.normals is None:
            as_normals(None, points.points, required_by=required_by)  # raises: one message for every caller
        return points
    pts = as_points(points, name, dims=dims, min_points=min_points)
    unit = as_normals(normals, pts, required_by=required_by)
    return Cloud._checked(pts, unit, None if faces is None else as_faces(faces, len(pts), pts.shape[1]),
                          None if weights is None else as_weights(weights, len(pts)))

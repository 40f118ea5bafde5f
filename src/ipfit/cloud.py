"""The data of one fit: a point cloud, its normals and faces, and where they came from.

:func:`ipfit.load` returns a :class:`Cloud` for a file or a bundled dataset; a cloud built in
code holds whatever arrays are given. It is immutable: its arrays are read-only views, so a
cloud can be shared by every step of a fit without one step changing another's data.

>>> import numpy as np
>>> cloud = Cloud(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), name="triangle")
>>> cloud.dim, len(cloud), cloud.n_file, cloud.normals_source, cloud.points.flags.writeable
(2, 3, 3, None, False)
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._validation import as_faces, as_matching, as_points, check_int

__all__ = ["Cloud"]


def _read_only(arr: NDArray) -> NDArray:
    # A view, so that the caller's own array stays writable and nothing is copied.
    view = arr.view()
    view.setflags(write=False)
    return view


@dataclass(frozen=True, eq=False)
class Cloud:
    """A point cloud with its normals and faces, as read (or given).

    Parameters
    ----------
    points : (N, dim) array, dim 2 or 3
        Finite coordinates; held as a read-only float64 array.
    normals : (N, dim) array, optional
        One normal per point, held as given (read-only): :func:`ipfit.load` gives unit
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

    Attributes
    ----------
    dim : int
        2 or 3.
    """

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None = None
    faces: NDArray[np.int64] | None = None
    name: str = "points"
    source: os.PathLike | str | None = None
    n_file: int | None = None
    normals_source: str | None = None

    def __post_init__(self) -> None:
        points = as_points(self.points)
        normals = None if self.normals is None else as_matching(self.normals, points)
        faces = None if self.faces is None else as_faces(self.faces, len(points))
        n_file = len(points) if self.n_file is None else check_int(self.n_file, "n_file", minimum=len(points))
        source = None if normals is None else (self.normals_source or "file")
        # frozen: the checked values replace the given ones once, here
        for key, value in (("points", _read_only(points)),
                           ("normals", None if normals is None else _read_only(normals)),
                           ("faces", None if faces is None else _read_only(faces)), ("name", str(self.name)),
                           ("n_file", n_file), ("normals_source", source)):
            object.__setattr__(self, key, value)

    @property
    def dim(self) -> int:
        return int(self.points.shape[1])

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        extras = [f"normals from {self.normals_source}" if self.normals is not None else "no normals"]
        if self.faces is not None:
            extras.append(f"{len(self.faces):,} faces")
        if self.n_file > len(self):
            extras.append(f"{len(self):,} of {self.n_file:,} kept")
        return f"Cloud({self.name!r}: {len(self):,} {self.dim}D points, {', '.join(extras)})"

"""Reading point clouds: one registry from file suffix to reader, and the checks every file gets.

:func:`read_points` and :func:`read_mesh` look the suffix up in :data:`FORMATS` (name, the
library that reads it, the reader function), read the bytes, let the format's reader parse
them into a :class:`~ipfit.io._base.Raw`, then apply the same checks to every format:
finite coordinates, one normal per point, face indices in range, duplicates merged, normals
of unit length. Every failure is one :class:`~ipfit.exceptions.ReadError` line that starts
with the file's path; no library's exception or numpy warning reaches the caller.

To add a format: write ``read_x(path, raw) -> Raw`` in the module of its kind (mesh files,
tables, scanners) and add a line to :data:`FORMATS`.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._utils.atomic import special_kind
from .._utils.numeric import unit_rows_mask
from .._utils.validation import check_int, check_rng
from ..exceptions import NormalsDroppedWarning, ReadError
from ..geometry.mesh import fill_missing_normals, merge_duplicates, vertex_normals_from_faces
from ._base import MIN_POINTS, Raw, as_path, short
from .meshfiles import read_obj, read_off, read_ply, read_scene, read_stl
from .scanners import read_e57, read_las, read_pcd
from .silhouettes import IMAGE_SUFFIXES, read_image
from .tables import read_npy, read_npz, read_text

__all__ = ["PointCloud", "Mesh", "Format", "FORMATS", "READ_FORMATS", "read_points", "read_points_faces", "read_mesh"]


class _Pair(NamedTuple):
    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None


class PointCloud(_Pair):
    """What :func:`read_points` returns: unpacks as ``points, normals = read_points(path)``.

    Attributes
    ----------
    points : (N, D) float64 array
    normals : (N, D) unit vectors, or None
    normals_source : {"file", "faces", "contour", None}
        Where the normals come from: the file itself, the mesh's faces (area-weighted), the
        traced contour of an image; None when there are none (estimate them).
    n_file : int
        How many points (rows) the file holds, before merging duplicates and subsampling.
    n_kept : int
        How many points were kept (``len(points)``).
    """

    normals_source: str | None = None  # class defaults for copies made by _replace / _make
    n_file: int  # set by __new__; a copy made by _replace / _make reads it through __getattr__

    def __new__(cls, points, normals, normals_source: str | None = None, n_file: int | None = None):
        self = super().__new__(cls, points, normals)
        self.normals_source = None if normals is None else (normals_source or "file")
        self.n_file = len(points) if n_file is None else int(n_file)
        return self

    @property
    def n_kept(self) -> int:
        return len(self.points)

    def __getattr__(self, name: str):
        if name == "n_file":  # a copy made by _replace / _make: no count recorded
            return len(self.points)
        raise AttributeError(name)


class Mesh(NamedTuple):
    """What :func:`read_mesh` returns: merged points, the file's own vertex normals (or None)
    and triangles as (M, 3) indices into ``points`` (or None when the file has no faces)."""

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None
    faces: NDArray[np.int64] | None


class Format(NamedTuple):
    """A readable format: its name, the library that reads it, the reader, and the pip extra
    that installs the library when it is not a dependency of ipfit."""

    name: str
    library: str
    reader: Callable[[Path, bytes], Raw]
    extra: str | None = None

    @property
    def short_name(self) -> str:
        """The name without its notes, for messages: "PLY", "LAS / LAZ", "text table"."""
        return re.split(r"[,:(]", self.name)[0].strip()


_GLTF = Format("glTF 2.0 / GLB (every mesh of the scene, node transforms applied)", "trimesh", read_scene)
_TABLE = Format("text table: x y [z] [nx ny [nz]], optional header", "numpy", read_text)
_NUMPY = Format("NumPy array (N, 2|3|4|6) or archive (points, normals)", "numpy", read_npy)
_LAS = Format("LAS / LAZ (LiDAR; scales and offsets applied)", "laspy + lazrs", read_las, "scanners")
FORMATS: dict[str, Format] = {
    ".ply": Format("PLY, ASCII or binary", "plyfile", read_ply),
    ".obj": Format("Wavefront OBJ", "trimesh", read_obj),
    ".off": Format("OFF / NOFF", "trimesh", read_off),
    ".stl": Format("STL, ASCII or binary", "trimesh", read_stl),
    ".glb": _GLTF,
    ".gltf": _GLTF,
    ".3mf": Format("3MF (3D printing; every mesh of the build, transforms applied)", "trimesh + lxml", read_scene,
                   "scanners"),
    ".dae": Format("COLLADA (every mesh of the scene, node transforms applied)", "trimesh + pycollada", read_scene,
                   "scanners"),
    ".xyz": _TABLE,
    ".txt": _TABLE,
    ".csv": _TABLE,
    ".npy": _NUMPY,
    ".npz": _NUMPY._replace(reader=read_npz),
    ".las": _LAS,
    ".laz": _LAS,
    ".pcd": Format("PCD, ASCII or binary (PCL, ROS)", "pypcd4", read_pcd, "scanners"),
    ".e57": Format("E57 (terrestrial scanners; scan poses applied)", "pye57", read_e57, "scanners"),
    **{suffix: Format("silhouette image (outline and holes of the largest shape)", "Pillow + scikit-image", read_image)
       for suffix in IMAGE_SUFFIXES},
}
#: Extensions :func:`read_points` understands.
READ_FORMATS = tuple(FORMATS)


def read_points(path: str | os.PathLike, *, merge: bool = True, face_normals: bool = True,
                max_points: int | None = None, rng=0, largest_outline: bool = False) -> PointCloud:
    """Read a point cloud and its normals from a file, the format chosen by extension.

    Parameters
    ----------
    path : str or path
        Any suffix of :data:`READ_FORMATS`: ``.ply``, ``.obj``, ``.off``, ``.stl``, ``.glb``,
        ``.gltf``, ``.3mf``, ``.dae``, ``.xyz``, ``.txt``, ``.csv``, ``.npy``, ``.npz``, ``.las``, ``.laz``,
        ``.pcd``, ``.e57`` or a silhouette image (``.png``, ``.gif``, ``.bmp``, ``.tif``,
        ``.jpg``...; the boundaries of the largest shape, its outline then its holes, traced
        at subpixel precision, x right and y up in pixel units, with outward normals).
    merge : bool
        Merge points at exactly the same position, averaging their normals.
    face_normals : bool
        For meshes without vertex normals, give area-weighted normals from the faces
        (:func:`~ipfit.geometry.mesh.vertex_normals_from_faces`); vertices in no face take their nearest
        neighbour's. If False such files give ``normals=None``.
    max_points : int, optional
        Keep at most this many points, drawn at random without replacement (file order kept).
    rng : int, Generator or None
        Seed of that draw; the default 0 gives the same subset on every run.
    largest_outline : bool
        A silhouette image: the outline of the largest shape alone, its holes dropped.

    Returns
    -------
    PointCloud
        ``points`` (N, D) float array, D = 2 or 3; ``normals`` (N, D) unit vectors or None;
        ``normals_source``, ``n_file`` and ``n_kept`` say where the normals come from and
        how many points the file had and how many were kept.

    Raises
    ------
    InvalidInputError
        ``path`` is not a path, or ``max_points`` is not an integer >= 3.
    ReadError
        Missing, empty, truncated or malformed file, unknown format, fewer than 3 points.

    Warns
    -----
    NormalsDroppedWarning
        The file's normals are all zero, or not one per point: they are dropped.

    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "square.csv"
    >>> _ = path.write_text("x,y\\n0,0\\n1,0\\n1,1\\n0,1\\n")
    >>> cloud = read_points(path, max_points=3)
    >>> cloud.points.shape, cloud.n_file, cloud.n_kept, cloud.normals_source
    ((3, 2), 4, 3, None)
    """
    return read_points_faces(path, merge=merge, face_normals=face_normals, max_points=max_points, rng=rng,
                             largest_outline=largest_outline)[0]


def read_points_faces(path: str | os.PathLike, *, merge: bool = True, face_normals: bool = True,
                      max_points: int | None = None, rng=0,
                      largest_outline: bool = False) -> tuple[PointCloud, NDArray[np.int64] | None]:
    """:func:`read_points` and the file's faces (as :func:`read_mesh` gives them), from one read.

    The faces index the returned points; they are None when the file has none and when
    ``max_points`` dropped points (the faces index the points before the draw).
    """
    path = as_path(path)
    if max_points is not None:
        max_points = check_int(max_points, "max_points", minimum=MIN_POINTS)
    generator = check_rng(rng)
    data, n_file = _parse(path, largest_outline=bool(largest_outline))
    if max_points is not None and data.faces is None and len(data.points) > max_points:
        # before merging: a scanner's 100 million rows need not all be sorted
        data = _subsample(data, max_points, generator)
    mesh = _finish(path, data, merge)
    normals, source = mesh.normals, data.normals_source
    if normals is None and face_normals and mesh.faces is not None and mesh.points.shape[1] == 3:
        normals, source = fill_missing_normals(mesh.points, vertex_normals_from_faces(mesh.points, mesh.faces)), "faces"
    points, faces = mesh.points, mesh.faces
    if max_points is not None and len(points) > max_points:
        keep = np.sort(generator.choice(len(points), max_points, replace=False))
        points, normals, faces = points[keep], None if normals is None else normals[keep], None
    return PointCloud(points, normals, source, n_file), faces


def read_mesh(path: str | os.PathLike, *, merge: bool = True) -> Mesh:
    """Read points, the file's own vertex normals and its faces (triangulated).

    Like :func:`read_points`, but the normals are only those stored in the file (or traced,
    for images) and the faces come along, re-indexed after merging. Faces with a repeated
    vertex after merging are dropped.
    """
    path = as_path(path)
    return _finish(path, _parse(path)[0], merge)


def _subsample(data: Raw, max_points: int, generator: np.random.Generator) -> Raw:
    keep = np.sort(generator.choice(len(data.points), max_points, replace=False))
    normals = data.normals
    if normals is not None and len(normals) == len(data.points):
        normals = np.asarray(normals)[keep]
    return data._replace(points=np.asarray(data.points)[keep], normals=normals)


def _format_for(path: Path) -> Format:
    suffix = path.suffix.lower()
    fmt = FORMATS.get(suffix)
    if fmt is None:
        what = f"unknown format '{suffix}'" if suffix else "no extension, so the format is unknown"
        raise ReadError(f"{path}: {what}. Supported: {', '.join(READ_FORMATS)}.")
    return fmt


def _refuse_special(path: Path, kind: str | None = None) -> None:
    """A FIFO, socket or device (``/dev/stdin``) is refused before anything reads it: reading
    would wait for a writer forever, or never end."""
    kind = kind or special_kind(path)
    if kind is not None:
        raise ReadError(f"{path}: is a {kind}, not a regular file; ipfit reads only regular files. "
                        "Save the data to a file first and give its path.")


def _open_regular(path: Path):
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    # O_NONBLOCK: a path swapped for a FIFO after the check does not make open() wait for a writer
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        _refuse_special(path, special_kind(path) or "special file")
    return os.fdopen(fd, "rb")


def _read_bytes(path: Path) -> bytes:
    try:
        with _open_regular(path) as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file. Check the path.") from None
    except IsADirectoryError:
        raise ReadError(f"{path}: is a folder, not a file. Give the path of a point file.") from None
    except PermissionError:
        raise ReadError(f"{path}: permission denied. Check the file's permissions.") from None
    except OSError as exc:
        raise ReadError(f"{path}: cannot be read ({short(exc)}).") from None
    if not raw:
        raise ReadError(f"{path}: the file is empty. Check that it was written completely.")
    return raw


def _parse(path: Path, largest_outline: bool = False) -> tuple[Raw, int]:
    """The format's reader on the file's bytes, every failure turned into one ReadError line;
    also the number of rows the file holds. ``largest_outline`` goes to the image reader."""
    _refuse_special(path)
    fmt = _format_for(path)
    raw = _read_bytes(path)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            # parsers warn about what they then fail on (or repair): the ReadError is the message
            warnings.simplefilter("ignore")
            data = read_image(path, raw, largest_outline=True) if largest_outline and fmt.reader is read_image \
                else fmt.reader(path, raw)
    except ReadError:
        raise
    except MemoryError:
        raise ReadError(f"{path}: the file announces more data than fits in memory. "
                        "Check that it is not corrupted.") from None
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:  # noqa: BLE001 - parsers raise anything on malformed input (Rust panics are BaseExceptions)
        raise ReadError(f"{path}: not a valid {fmt.short_name} file ({short(exc)}). "
                        "Check that the file is complete and of the format its extension says.") from None
    return data, len(data.points)


def _finish(path: Path, data: Raw, merge: bool) -> Mesh:
    pts = np.asarray(data.points)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ReadError(f"{path}: expected 2 or 3 coordinates per point, got an array of shape {pts.shape}.")
    if pts.dtype.kind not in "biuf":
        raise ReadError(f"{path}: the coordinates are {pts.dtype} values, not real numbers.")
    pts = pts.astype(np.float64)
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise ReadError(f"{path}: {int(bad.sum())} points with NaN or infinite coordinates "
                        f"(first: point {int(np.flatnonzero(bad)[0])}). Remove or repair them.")
    if len(pts) < MIN_POINTS:
        raise ReadError(f"{path}: only {len(pts)} point{'s' if len(pts) != 1 else ''}; at least {MIN_POINTS} "
                        "are needed.")
    normals = _file_normals(path, data, pts)
    faces = _faces(path, data.faces, len(pts))
    if merge:
        merged = merge_duplicates(pts, normals)
        pts, normals = merged.points, merged.normals
        if faces is not None:
            faces = merged.index[faces]
    elif normals is not None:
        normals = unit_rows_mask(normals)[0]
    if faces is not None:
        faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
        faces = faces if len(faces) else None
    if normals is not None:
        normals = _repair_normals(path, pts, normals)
    if len(pts) < MIN_POINTS:
        raise ReadError(f"{path}: only {len(pts)} distinct points; at least {MIN_POINTS} are needed.")
    return Mesh(np.ascontiguousarray(pts), normals, faces)


def _file_normals(path: Path, data: Raw, pts: NDArray) -> NDArray[np.float64] | None:
    if data.dropped_normals is not None:
        _warn(path, f"{data.dropped_normals}; the file's normals were dropped")
    if data.normals is None:
        return None
    normals = np.asarray(data.normals)
    if normals.dtype.kind not in "biuf":
        raise ReadError(f"{path}: the normals are {normals.dtype} values, not real numbers.")
    normals = normals.astype(np.float64)
    if normals.shape != pts.shape:
        raise ReadError(f"{path}: {normals.shape[0] if normals.ndim else 0} normals of shape {normals.shape[1:]} "
                        f"for {len(pts)} points of {pts.shape[1]} coordinates. Give one normal per point.")
    finite = np.isfinite(normals).all(axis=1)
    if not finite.all():
        raise ReadError(f"{path}: {int((~finite).sum())} normals with NaN or infinite values "
                        f"(first: point {int(np.flatnonzero(~finite)[0])}). Remove or repair them.")
    return normals


def _faces(path: Path, faces, n_points: int) -> NDArray[np.int64] | None:
    if faces is None or len(faces) == 0:
        return None
    arr = np.asarray(faces)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.dtype.kind not in "iu":
        raise ReadError(f"{path}: the faces are not triangles of vertex indices. The file is corrupted.")
    if arr.min() < 0 or arr.max() >= n_points:
        wrong = int(arr.max() if arr.max() >= n_points else arr.min())
        raise ReadError(f"{path}: a face refers to vertex {wrong} but there are {n_points} vertices. "
                        "The file is corrupted.")
    return arr.astype(np.int64)


def _repair_normals(path: Path, pts: NDArray, normals: NDArray) -> NDArray[np.float64] | None:
    """Zero normals (in the file, or cancelled by merging) take their nearest neighbour's; if
    all are zero they are dropped. Either way, with a warning."""
    missing = int(np.count_nonzero(~np.any(normals != 0, axis=1)))
    if missing == 0:
        return normals
    if missing == len(normals):
        _warn(path, "all the file's normals are zero; they were dropped")
        return None
    _warn(path, f"{missing} of {len(normals)} normals are zero (or cancel out where duplicate points were "
                "merged); they take their nearest neighbour's normal", estimated=False)
    return fill_missing_normals(pts, normals)


def _warn(path: Path, what: str, *, estimated: bool = True) -> None:
    tail = " and will be taken from the faces or estimated" if estimated else ""
    warnings.warn(f"{path}: {what}{tail}.", NormalsDroppedWarning, stacklevel=4)

"""Reading and writing point clouds: points, normals and (for meshes) faces.

:func:`read_points` returns ``(points, normals)`` from PLY (ASCII or binary), OBJ, OFF, STL,
XYZ/TXT/CSV, NPY/NPZ and silhouette images (PNG, GIF, BMP, TIFF, JPEG...). Repeated
positions (meshes split per face) are merged and their normals averaged; meshes without
vertex normals get area-weighted normals from their faces. :func:`write_points` writes
PLY, XYZ/TXT/CSV, NPY and NPZ. Every failure to read is a :class:`~ipfit.exceptions.ReadError`
whose one-line message starts with the file's path.
"""

from __future__ import annotations

import io as _io
import logging
import os
import warnings
import re
import zipfile
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ._atomic import atomic_path, write_text_atomic
from ._validation import as_points, error
from .exceptions import InvalidInputError, ReadError

__all__ = [
    "PointCloud",
    "Mesh",
    "Merged",
    "read_points",
    "read_mesh",
    "write_points",
    "merge_duplicates",
    "face_normals",
    "vertex_normals_from_faces",
    "trace_silhouette",
    "READ_FORMATS",
    "WRITE_FORMATS",
    "CONTOUR_SPAN",
]

MIN_POINTS = 3
#: Central-difference span for the normals of traced contours (see ``contour_normals``):
#: ±1 pixel only sees the 45° staircase of a traced boundary, ±2 averages it.
CONTOUR_SPAN = 2


class PointCloud(NamedTuple):
    """What :func:`read_points` returns: unpacks as ``points, normals = read_points(path)``."""

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None


class Mesh(NamedTuple):
    """What :func:`read_mesh` returns: merged points, the file's own vertex normals (or None)
    and triangles as (M, 3) indices into ``points`` (or None when the file has no faces)."""

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None
    faces: NDArray[np.int64] | None


class Merged(NamedTuple):
    """What :func:`merge_duplicates` returns; ``index[i]`` is the new row of old row ``i``."""

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None
    index: NDArray[np.intp]


class _Raw(NamedTuple):  # what a format reader returns, before merging and checks
    points: NDArray
    normals: NDArray | None = None
    faces: NDArray | None = None


# -- public API ------------------------------------------------------------------------------------

def read_points(path: str | os.PathLike, *, merge: bool = True, face_normals: bool = True) -> PointCloud:
    """Read a point cloud and its normals from a file, the format chosen by extension.

    Parameters
    ----------
    path : str or path
        A ``.ply``, ``.obj``, ``.off``, ``.stl``, ``.xyz``, ``.txt``, ``.csv``, ``.npy``,
        ``.npz`` file or a silhouette image (``.png``, ``.gif``, ``.bmp``, ``.tif``, ``.jpg``...;
        the outer boundary of the largest shape, traced at subpixel precision, x right and
        y up in pixel units, with outward normals).
    merge : bool
        Merge points at exactly the same position, averaging their normals.
    face_normals : bool
        For meshes without vertex normals, give area-weighted normals from the faces
        (:func:`vertex_normals_from_faces`); vertices in no face take their nearest
        neighbour's. If False such files give ``normals=None``.

    Returns
    -------
    PointCloud
        ``points`` (N, D) float array, D = 2 or 3; ``normals`` (N, D) unit vectors or None.

    Raises
    ------
    ReadError
        Missing, empty, truncated or malformed file, unknown format, fewer than 3 points.
    """
    mesh = read_mesh(path, merge=merge)
    normals = mesh.normals
    if normals is None and face_normals and mesh.faces is not None and mesh.points.shape[1] == 3:
        normals = _complete(mesh.points, vertex_normals_from_faces(mesh.points, mesh.faces))
    return PointCloud(mesh.points, normals)


def read_mesh(path: str | os.PathLike, *, merge: bool = True) -> Mesh:
    """Read points, the file's own vertex normals and its faces (triangulated).

    Like :func:`read_points`, but the normals are only those stored in the file (or traced,
    for images) and the faces come along, re-indexed after merging. Faces with a repeated
    vertex after merging are dropped.
    """
    path = Path(path)
    raw = _read_bytes(path)
    reader = _reader_for(path)
    try:
        with warnings.catch_warnings():
            # parsers warn about what they then fail on (or repair): the ReadError is the message
            warnings.simplefilter("ignore")
            data = reader(path, raw)
    except ReadError:
        raise
    except MemoryError:
        raise ReadError(f"{path}: the file announces more data than fits in memory. "
                        "Check that it is not corrupted.") from None
    except Exception as exc:  # third-party parsers raise anything on malformed input
        raise ReadError(f"{path}: not a valid {_format_name(path)} file ({_short(exc)}). "
                        "Check that the file is complete and of the format its extension says.") from None
    return _finish(path, data, merge)


def write_points(path: str | os.PathLike, points: ArrayLike, normals: ArrayLike | None = None, *,
                 binary: bool = True) -> Path:
    """Write points (and normals) atomically; the format is chosen by extension.

    Parameters
    ----------
    path : str or path
        ``.ply`` (x, y, z [, nx, ny, nz] as doubles), ``.obj`` (``v`` and ``vn`` lines),
        ``.off`` (OFF, or NOFF with normals); in these three 2D points get z = 0 and a
        comment so that ipfit reads them back as 2D. ``.csv`` (header ``x,y[,z][,nx,ny[,nz]]``),
        ``.xyz``/``.txt`` (space separated), ``.npy`` (one array, normals as extra
        columns) or ``.npz`` (arrays ``points`` and ``normals``).
    points : (N, D) array
    normals : (N, D) array, optional
    binary : bool
        PLY only: binary little-endian (default) or ASCII.

    Returns
    -------
    Path of the written file.
    """
    path = Path(path)
    pts = as_points(points)
    nrm = None
    if normals is not None:
        nrm = as_points(normals, "normals", dims=(pts.shape[1],))
        if nrm.shape != pts.shape:
            raise error("normals", f"shape {pts.shape} to match the points", f"shape {nrm.shape}",
                        "Pass one normal per point.")
    suffix = path.suffix.lower()
    writer = _WRITERS.get(suffix)
    if writer is None:
        raise InvalidInputError(f"{path}: cannot write '{suffix or path.name}' files. "
                                f"Use one of: {', '.join(WRITE_FORMATS)}.")
    writer(path, pts, nrm, binary)
    return path


def merge_duplicates(points: ArrayLike, normals: ArrayLike | None = None) -> Merged:
    """Merge rows with exactly equal coordinates, keeping the order of first appearance.

    Normals of merged rows are summed and renormalised (NaN where they cancel out).

    >>> m = merge_duplicates([[0, 0], [1, 0], [0, 0]], [[1, 0], [0, 1], [0, 1]])
    >>> m.points.tolist(), m.index.tolist()
    ([[0.0, 0.0], [1.0, 0.0]], [0, 1, 0])
    """
    pts = np.asarray(points, dtype=np.float64)
    key = pts + 0.0  # −0.0 → 0.0: the same position must give the same key
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    if len(first) == len(pts):
        nrm = None if normals is None else _unit_rows(np.asarray(normals, dtype=np.float64))
        return Merged(pts, nrm, np.arange(len(pts)))
    order = np.argsort(first, kind="stable")  # unique rows in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    index = rank[inverse]
    merged = pts[first[order]]
    nrm = None
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float64)
        total = np.stack([np.bincount(index, normals[:, j], len(merged)) for j in range(normals.shape[1])], axis=1)
        nrm = _unit_rows(total)
    return Merged(merged, nrm, index)


def face_normals(points: ArrayLike, faces: ArrayLike) -> NDArray[np.float64]:
    """Unit normals of triangles (right-hand rule: counter-clockwise seen from outside).

    Degenerate (zero-area) triangles get NaN rows.
    """
    pts, tri = np.asarray(points, dtype=np.float64), np.asarray(faces, dtype=np.intp)
    return _unit_rows(_cross(pts, tri))


def vertex_normals_from_faces(points: ArrayLike, faces: ArrayLike) -> NDArray[np.float64]:
    """Area-weighted vertex normals: the sum of the adjacent triangles' area vectors, normalised.

    Vertices in no (non-degenerate) triangle get NaN rows.
    """
    pts, tri = np.asarray(points, dtype=np.float64), np.asarray(faces, dtype=np.intp)
    area_vectors = _cross(pts, tri)  # |cross| = twice the area: the weighting comes for free
    corners = tri.ravel()
    total = np.stack([np.bincount(corners, np.repeat(area_vectors[:, j], 3), len(pts)) for j in range(3)], axis=1)
    return _unit_rows(total)


def trace_silhouette(image: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Outer boundary of the largest shape in an image, with outward normals.

    The foreground is the class (Otsu threshold; midway for two-level images) that is rarer
    on the image border; alpha is used instead of brightness when it varies. The image is
    padded with background so shapes touching the border close. Points are in pixel units,
    x to the right, y up (y = −row), at subpixel precision (marching squares).

    Raises
    ------
    InvalidInputError
        If no shape is found.
    """
    from skimage import measure

    from .normals import contour_normals

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < 1:
        raise error("image", "a 2D array of grey levels", f"shape {img.shape}")
    lo, hi = float(img.min()), float(img.max())
    if not hi > lo:
        raise InvalidInputError("image: the image is uniform, no shape to trace. Use a silhouette "
                                "(a shape on a plain background).")
    img = (img - lo) / (hi - lo)
    levels = np.unique(img)
    if len(levels) == 2:
        level = 0.5
    else:
        from skimage.filters import threshold_otsu

        level = float(threshold_otsu(img))
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    if (border > level).mean() > 0.5:  # bright background: the shape is the dark part
        img, level = 1.0 - img, 1.0 - level
    padded = np.pad(img, 1, constant_values=0.0)
    contours = measure.find_contours(padded, level)
    best, best_area = None, 0.0
    for c in contours:
        if len(c) < MIN_POINTS + 1:
            continue
        r, q = c[:, 0], c[:, 1]
        area = 0.5 * abs(float(np.sum(q * np.roll(r, -1) - np.roll(q, -1) * r)))
        if area > best_area:
            best, best_area = c, area
    if best is None or best_area <= 0:
        raise InvalidInputError("image: no closed shape found. Use a silhouette (a shape on a plain background).")
    if np.array_equal(best[0], best[-1]):
        best = best[:-1]
    points = np.column_stack([best[:, 1] - 1.0, -(best[:, 0] - 1.0)])
    keep = np.ones(len(points), dtype=bool)  # marching squares can repeat a vertex at saddles
    keep[1:] = np.any(np.diff(points, axis=0) != 0, axis=1)
    points = points[keep]
    if len(points) < MIN_POINTS:
        raise InvalidInputError("image: the shape is too small to trace (fewer than 3 boundary points).")
    return points, contour_normals(points, span=min(CONTOUR_SPAN, (len(points) - 1) // 2))


# -- plumbing ------------------------------------------------------------------------------------

def _short(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def _format_name(path: Path) -> str:
    suffix = path.suffix.lower()
    return _FORMAT_NAMES.get(suffix, suffix.lstrip(".").upper())


def _reader_for(path: Path) -> Callable[[Path, bytes], _Raw]:
    suffix = path.suffix.lower()
    reader = _READERS.get(suffix)
    if reader is None:
        what = f"unknown format '{suffix}'" if suffix else "no extension, so the format is unknown"
        raise ReadError(f"{path}: {what}. Supported: {', '.join(READ_FORMATS)}.")
    return reader


def _read_bytes(path: Path) -> bytes:
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file. Check the path.") from None
    except IsADirectoryError:
        raise ReadError(f"{path}: is a folder, not a file. Give the path of a point file.") from None
    except PermissionError:
        raise ReadError(f"{path}: permission denied. Check the file's permissions.") from None
    except OSError as exc:
        raise ReadError(f"{path}: cannot be read ({_short(exc)}).") from None
    if not raw:
        raise ReadError(f"{path}: the file is empty. Check that it was written completely.")
    return raw


def _unit_rows(v: NDArray) -> NDArray[np.float64]:
    length = np.linalg.norm(v, axis=1)
    ok = length > 0
    out = np.full(v.shape, np.nan)
    out[ok] = v[ok] / length[ok, None]
    return out


def _cross(pts: NDArray, tri: NDArray) -> NDArray[np.float64]:
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    return np.cross(b - a, c - a)


def _complete(points: NDArray, normals: NDArray) -> NDArray | None:
    """Fill NaN/zero rows with the normal of the nearest point that has one (None if none has)."""
    ok = np.isfinite(normals).all(axis=1)
    if ok.all():
        return normals
    if not ok.any():
        return None
    _, nearest = cKDTree(points[ok]).query(points[~ok])
    normals = normals.copy()
    normals[~ok] = normals[ok][nearest]
    return normals


def _finish(path: Path, data: _Raw, merge: bool) -> Mesh:
    pts = np.asarray(data.points)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ReadError(f"{path}: expected 2 or 3 coordinates per point, got an array of shape {pts.shape}.")
    try:
        pts = pts.astype(np.float64)
    except (TypeError, ValueError):
        raise ReadError(f"{path}: the coordinates are not numbers.") from None
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise ReadError(f"{path}: {int(bad.sum())} points with NaN or infinite coordinates "
                        f"(first: point {int(np.flatnonzero(bad)[0])}). Remove or repair them.")
    if len(pts) < MIN_POINTS:
        raise ReadError(f"{path}: only {len(pts)} point{'s' if len(pts) != 1 else ''}; at least {MIN_POINTS} "
                        "are needed.")
    normals = None if data.normals is None else np.asarray(data.normals, dtype=np.float64)
    if normals is not None:
        if normals.shape != pts.shape:
            raise ReadError(f"{path}: {len(normals)} normals of {normals.shape[-1]} components for "
                            f"{len(pts)} points of {pts.shape[1]}.")
        finite = np.isfinite(normals).all(axis=1)
        if not finite.all():
            raise ReadError(f"{path}: {int((~finite).sum())} normals with NaN or infinite values "
                            f"(first: point {int(np.flatnonzero(~finite)[0])}). Remove or repair them.")
    faces = None
    if data.faces is not None and len(data.faces):
        faces = np.asarray(data.faces, dtype=np.int64)
        if faces.min() < 0 or faces.max() >= len(pts):
            wrong = int(faces.max() if faces.max() >= len(pts) else faces.min())
            raise ReadError(f"{path}: a face refers to vertex {wrong} but there are {len(pts)} vertices. "
                            "The file is corrupted.")
    if merge:
        merged = merge_duplicates(pts, normals)
        pts, normals = merged.points, merged.normals
        if faces is not None:
            faces = merged.index[faces]
    elif normals is not None:
        normals = _unit_rows(normals)
    if faces is not None:
        faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
        faces = faces if len(faces) else None
    if normals is not None:
        normals = _complete(pts, normals)  # zero normals in the file, or ones that cancelled in merging
    if len(pts) < MIN_POINTS:
        raise ReadError(f"{path}: only {len(pts)} distinct points; at least {MIN_POINTS} are needed.")
    return Mesh(np.ascontiguousarray(pts), normals, faces)


# -- PLY -----------------------------------------------------------------------------------------

_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
              "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
_IPFIT_2D = "ipfit 2D points (z = 0)"


def _ply_check_size(path: Path, raw: bytes) -> None:
    """Refuse files whose header announces more rows than the body can hold (truncated files),
    before plyfile allocates arrays of the announced size."""
    end = raw.find(b"end_header")
    if end < 0:
        return  # plyfile reports the broken header
    body_start = raw.find(b"\n", end)
    body = raw[body_start + 1:] if body_start >= 0 else b""
    header = raw[:end].decode("ascii", "replace").splitlines()
    text = any(line.split()[:2] == ["format", "ascii"] for line in header)
    needed, elements = 0, []
    for line in header:
        words = line.split()
        if not words:
            continue
        if words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append([words[1], int(words[2]), 0])
        elif words[0] == "property" and elements:
            if len(words) == 3 and words[1] in _PLY_SIZES:
                elements[-1][2] += _PLY_SIZES[words[1]]
            elif len(words) == 5 and words[1] == "list" and words[2] in _PLY_SIZES:
                elements[-1][2] += _PLY_SIZES[words[2]]  # at least the length field
    if text:
        needed = sum(count for _, count, _ in elements)
        available = body.count(b"\n") + (0 if body.endswith(b"\n") or not body else 1)
        unit = "lines"
    else:
        needed = sum(count * size for _, count, size in elements)
        available = len(body)
        unit = "bytes"
    if needed > available:
        summary = ", ".join(f"{count} {name}" for name, count, _ in elements)
        raise ReadError(f"{path}: truncated: the header announces {summary} (at least {needed} {unit}) "
                        f"but only {available} {unit} follow. Re-export or re-download the file.")


def _read_ply(path: Path, raw: bytes) -> _Raw:
    from plyfile import PlyData, PlyParseError

    _ply_check_size(path, raw)
    try:
        ply = PlyData.read(_io.BytesIO(raw), mmap=False)
    except PlyParseError as exc:
        if "end-of-file" in str(exc):
            raise ReadError(f"{path}: truncated ({_short(exc)}). Re-export or re-download the file.") from None
        raise
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise ReadError(f"{path}: no 'vertex' element in the PLY header (elements: {', '.join(names) or 'none'}).")
    vertex = ply["vertex"].data
    fields = set(vertex.dtype.names or ())
    if not {"x", "y"} <= fields:
        raise ReadError(f"{path}: the vertices have no x and y properties "
                        f"(they have: {', '.join(sorted(fields)) or 'none'}).")
    two_d = "z" not in fields or (any(_IPFIT_2D in c for c in ply.comments) and not np.any(vertex["z"]))
    axes = "xy" if two_d else "xyz"
    points = np.column_stack([np.asarray(vertex[a], dtype=np.float64) for a in axes])
    normals = None
    for names_ in (["nx", "ny", "nz"], ["normal_x", "normal_y", "normal_z"]):
        wanted = names_[:len(axes)]
        if set(wanted) <= fields:
            normals = np.column_stack([np.asarray(vertex[a], dtype=np.float64) for a in wanted])
            break
    faces = None
    if "face" in names and len(ply["face"].data):
        face = ply["face"].data
        key = next((k for k in ("vertex_indices", "vertex_index") if k in (face.dtype.names or ())), None)
        if key is not None:
            faces = _triangulate(list(face[key]))
    return _Raw(points, normals, faces)


def _triangulate(polygons: list) -> NDArray[np.int64] | None:
    """Fan-triangulate polygons given as a list of index arrays (vectorised per polygon size)."""
    if not polygons:
        return None
    sizes = np.fromiter(map(len, polygons), dtype=np.intp, count=len(polygons))
    flat = np.concatenate(polygons).astype(np.int64) if sizes.sum() else np.empty(0, np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    out = []
    for size in np.unique(sizes):
        if size < 3:
            continue
        rows = flat[starts[sizes == size][:, None] + np.arange(size)]
        for j in range(1, size - 1):
            out.append(rows[:, [0, j, j + 1]])
    return np.concatenate(out) if out else None


# -- OBJ / OFF / STL (trimesh) -------------------------------------------------------------------

def _trimesh_dicts(result) -> list[dict]:
    if isinstance(result, dict) and "geometry" in result:
        return [g for g in result["geometry"].values() if isinstance(g, dict)]
    return [result] if isinstance(result, dict) else []


def _read_trimesh(path: Path, raw: bytes, kind: str) -> _Raw:
    from trimesh.exchange.load import mesh_loaders

    loader = mesh_loaders[kind]
    kwargs = {"skip_materials": True} if kind == "obj" else {}
    logger = logging.getLogger("trimesh")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)  # trimesh logs tracebacks of its fallbacks; our error says it all
    try:
        parts = _trimesh_dicts(loader(_io.BytesIO(raw), file_type=kind, **kwargs))
    finally:
        logger.setLevel(level)
    points, normals, faces = [], [], []
    offset = 0
    for part in parts:
        v = part.get("vertices")
        if v is None or len(v) == 0:
            continue
        v = np.asarray(v, dtype=np.float64).reshape(len(v), -1)
        points.append(v)
        vn = part.get("vertex_normals")
        normals.append(None if vn is None or np.shape(vn) != v.shape else np.asarray(vn, dtype=np.float64))
        f = part.get("faces")
        if f is not None and len(f):
            faces.append(np.asarray(f, dtype=np.int64).reshape(len(f), -1)[:, :3] + offset)
        offset += len(v)
    if not points:
        raise ReadError(f"{path}: no vertices found. Check that it is a {_format_name(path)} file with vertices.")
    nrm = np.concatenate(normals) if all(n is not None for n in normals) else None
    return _Raw(np.concatenate(points), nrm, np.concatenate(faces) if faces else None)


_OFF_KEYWORD = re.compile(r"^(ST)?(C)?(N)?(4)?(n)?OFF(?=\s|$)")


def _off_layout(path: Path, raw: bytes) -> tuple[bool, list[str]]:
    """Check an OFF file's header and counts (trimesh reads a truncated face list silently).

    Returns whether the vertex lines carry normals (NOFF: x y z nx ny nz ...) and the vertex lines.
    """
    text = raw.decode("utf-8", "replace")
    lines = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    match = _OFF_KEYWORD.match(lines[0]) if lines else None
    if match is None:
        raise ReadError(f"{path}: not an OFF file (the first line should be 'OFF', or 'NOFF' with normals).")
    if match.group(4) or match.group(5):
        raise ReadError(f"{path}: {match.group(0)} files (homogeneous or n-dimensional vertices) are not supported. "
                        "Convert it to a plain 3D OFF or PLY.")
    rest = lines[0][match.end():].split()
    body = lines[1:]
    if not rest:
        if not body:
            raise ReadError(f"{path}: truncated: no vertex/face counts after '{match.group(0)}'.")
        rest, body = body[0].split(), body[1:]
    try:
        nv, nf = int(rest[0]), int(rest[1])
    except (IndexError, ValueError):
        raise ReadError(f"{path}: the counts line should hold the numbers of vertices and faces.") from None
    if len(body) < nv + nf:
        raise ReadError(f"{path}: truncated: the header announces {nv} vertices and {nf} faces "
                        f"but only {len(body)} data lines follow.")
    return bool(match.group(3)), body[:nv]


def _written_2d(raw: bytes, data: _Raw) -> _Raw:
    """2D points written by ipfit to a 3D-only format (z = 0 and a comment) come back as 2D."""
    if _IPFIT_2D.encode() not in raw[:200] or np.any(data.points[:, 2]):
        return data
    return data._replace(points=data.points[:, :2], normals=None if data.normals is None else data.normals[:, :2])


def _read_obj(path: Path, raw: bytes) -> _Raw:
    return _written_2d(raw, _read_trimesh(path, raw, "obj"))


def _read_off(path: Path, raw: bytes) -> _Raw:
    with_normals, vertex_lines = _off_layout(path, raw)
    data = _read_trimesh(path, raw, "off")
    if not with_normals:
        return _written_2d(raw, data)
    try:
        normals = np.array([ln.split()[3:6] for ln in vertex_lines], dtype=np.float64)
    except ValueError:
        raise ReadError(f"{path}: NOFF vertex lines need x y z nx ny nz numbers; some are missing or "
                        "not numbers.") from None
    return _written_2d(raw, data._replace(normals=normals))


# -- text tables ---------------------------------------------------------------------------------

_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"), ("n_x", "n_y", "n_z"))


def _split(line: str, delimiter: str | None) -> list[str]:
    return [w.strip() for w in line.split(delimiter)] if delimiter else line.split()


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _read_text(path: Path, raw: bytes) -> _Raw:
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ReadError(f"{path}: not a text file (byte {exc.start} is not UTF-8 text). "
                        "Check the format of the file.") from None
    if "\x00" in text:
        raise ReadError(f"{path}: not a text file (it contains NUL bytes). Check the format of the file.")
    lines = [(number, line.split("#", 1)[0].strip()) for number, line in enumerate(text.splitlines(), start=1)]
    lines = [(number, line) for number, line in lines if line]
    if not lines:
        raise ReadError(f"{path}: no data rows (only blank or comment lines). Add one point per row.")
    first = lines[0][1]
    delimiter = "," if "," in first else (";" if ";" in first else None)
    names = None
    if not all(_is_number(w) for w in _split(first, delimiter)):
        names = [w.strip().strip('"').strip("'").lower() for w in _split(first, delimiter)]
        lines = lines[1:]
        if not lines:
            raise ReadError(f"{path}: a header line but no data rows. Add one point per row.")
    numbers = [number for number, _ in lines]
    body = [line for _, line in lines]
    ncols = len(_split(body[0], delimiter))
    try:
        table = np.loadtxt(body, delimiter=delimiter, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        _diagnose_table(path, body, numbers, delimiter, ncols if names is None else len(names))
        raise  # _diagnose_table always raises; this keeps type checkers content
    if names is not None and len(names) != table.shape[1]:
        raise ReadError(f"{path}: the header names {len(names)} columns but line {numbers[0]} has "
                        f"{table.shape[1]} values. Make them match.")
    bad = ~np.isfinite(table).all(axis=1)
    if bad.any():
        first_bad = numbers[int(np.flatnonzero(bad)[0])]
        raise ReadError(f"{path}: {int(bad.sum())} rows with NaN or infinite values (first at line {first_bad}). "
                        "Remove or repair them.")
    return _columns(path, table, names)


def _diagnose_table(path: Path, body: list[str], numbers: list[int], delimiter: str | None, ncols: int) -> None:
    """Find the first bad line (only on failure: a Python loop is fine here) and raise."""
    for number, line in zip(numbers, body):
        words = _split(line, delimiter)
        if len(words) != ncols:
            raise ReadError(f"{path}: line {number} has {len(words)} values, expected {ncols} like the first row. "
                            "Every row needs the same columns.")
        for word in words:
            if not _is_number(word):
                shown = word if len(word) <= 20 else word[:17] + "..."
                raise ReadError(f"{path}: line {number}: '{shown}' is not a number. "
                                "Use plain decimal numbers (a '#' starts a comment).")
    raise ReadError(f"{path}: the rows could not be read as numbers. Check the delimiter and the values.")


def _columns(path: Path, table: NDArray, names: list[str] | None) -> _Raw:
    if names is not None and {"x", "y"} <= set(names):
        axes = ["x", "y", "z"] if "z" in names else ["x", "y"]
        points = table[:, [names.index(a) for a in axes]]
        for candidate in _NORMAL_NAMES:
            wanted = list(candidate[:len(axes)])
            if set(wanted) <= set(names):
                return _Raw(points, table[:, [names.index(a) for a in wanted]])
        return _Raw(points)
    return _positional(path, table)


def _positional(path: Path, table: NDArray) -> _Raw:
    ncols = table.shape[1]
    if ncols in (2, 3):
        return _Raw(table)
    if ncols in (4, 6):
        half = ncols // 2
        return _Raw(table[:, :half], table[:, half:])
    raise ReadError(f"{path}: {ncols} columns; expected 2 or 3 coordinates, optionally followed by as many "
                    "normal components (2, 3, 4 or 6 columns), or a header naming x, y[, z][, nx, ny[, nz]].")


# -- NumPy ---------------------------------------------------------------------------------------

def _check_npy_header(path: Path, stream) -> None:
    """Refuse arrays whose header announces more data than the file holds."""
    start = stream.tell()
    version = np.lib.format.read_magic(stream)
    reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, _, dtype = reader(stream)
    if dtype.hasobject:
        raise ReadError(f"{path}: the array holds Python objects, not numbers. Save a numeric array.")
    needed = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    here = stream.tell()
    stream.seek(0, 2)
    available = stream.tell() - here
    stream.seek(start)
    if needed > available:
        raise ReadError(f"{path}: truncated: the header announces an array of shape {shape} "
                        f"({needed} bytes) but {available} bytes follow.")


def _read_npy(path: Path, raw: bytes) -> _Raw:
    stream = _io.BytesIO(raw)
    _check_npy_header(path, stream)
    arr = np.load(stream, allow_pickle=False)
    return _array_columns(path, arr, "the array")


def _array_columns(path: Path, arr: NDArray, what: str) -> _Raw:
    if arr.dtype.kind not in "biuf":
        raise ReadError(f"{path}: {what} holds {arr.dtype} values, not numbers.")
    if arr.ndim != 2:
        raise ReadError(f"{path}: {what} has shape {arr.shape}; expected (N, 2), (N, 3), or with normals "
                        "as extra columns (N, 4) or (N, 6).")
    return _positional(path, arr.astype(np.float64))


def _read_npz(path: Path, raw: bytes) -> _Raw:
    try:
        archive = np.load(_io.BytesIO(raw), allow_pickle=False)
    except zipfile.BadZipFile as exc:
        raise ReadError(f"{path}: not a valid NPZ archive ({_short(exc)}).") from None
    with archive:
        keys = list(archive.files)
        if "points" in keys:
            key = "points"
        elif len(keys) == 1:
            key = keys[0]
        else:
            raise ReadError(f"{path}: no array named 'points' (arrays: {', '.join(keys) or 'none'}). "
                            "Save with np.savez(path, points=..., normals=...).")
        data = _array_columns(path, archive[key], f"array '{key}'")
        if "normals" in keys:
            normals = archive["normals"]
            if normals.dtype.kind not in "biuf":
                raise ReadError(f"{path}: array 'normals' holds {normals.dtype} values, not numbers.")
            data = _Raw(data.points, normals.astype(np.float64))
        if "faces" in keys and archive["faces"].dtype.kind in "iu" and archive["faces"].ndim == 2 \
                and archive["faces"].shape[1] == 3:
            data = _Raw(data.points, data.normals, archive["faces"].astype(np.int64))
    return data


# -- images --------------------------------------------------------------------------------------

def _read_image(path: Path, raw: bytes) -> _Raw:
    from PIL import Image

    with Image.open(_io.BytesIO(raw)) as im:
        im.load()
        if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
            alpha = np.asarray(im.convert("RGBA"))[:, :, 3]
            grey = alpha if alpha.min() != alpha.max() else np.asarray(im.convert("L"))
        else:
            grey = np.asarray(im.convert("L"))
    try:
        points, normals = trace_silhouette(grey)
    except InvalidInputError as exc:
        raise ReadError(f"{path}: {str(exc).removeprefix('image: ')}") from None
    return _Raw(points, normals)


# -- writers -------------------------------------------------------------------------------------

def _write_ply(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    from plyfile import PlyData, PlyElement

    n, dim = pts.shape
    cols = [pts[:, 0], pts[:, 1], pts[:, 2] if dim == 3 else np.zeros(n)]
    names = ["x", "y", "z"]
    if nrm is not None:
        cols += [nrm[:, 0], nrm[:, 1], nrm[:, 2] if dim == 3 else np.zeros(n)]
        names += ["nx", "ny", "nz"]
    table = np.empty(n, dtype=[(name, "f8") for name in names])
    for name, col in zip(names, cols):
        table[name] = col
    comments = ["written by ipfit"] + ([_IPFIT_2D] if dim == 2 else [])
    ply = PlyData([PlyElement.describe(table, "vertex")], text=not binary, comments=comments)
    with atomic_path(path) as tmp:
        ply.write(str(tmp))


def _table_text(pts: NDArray, nrm: NDArray | None, delimiter: str, header: str) -> str:
    table = pts if nrm is None else np.hstack([pts, nrm])
    buffer = _io.StringIO()
    np.savetxt(buffer, table, fmt="%.17g", delimiter=delimiter, header=header, comments="")
    return buffer.getvalue()


def _column_names(dim: int, normals: bool) -> list[str]:
    axes = ["x", "y", "z"][:dim]
    return axes + ([f"n{a}" for a in axes] if normals else [])


def _write_csv(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    write_text_atomic(path, _table_text(pts, nrm, ",", ",".join(_column_names(pts.shape[1], nrm is not None))))


def _write_xyz(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    header = "# " + " ".join(_column_names(pts.shape[1], nrm is not None))
    write_text_atomic(path, _table_text(pts, nrm, " ", header))


def _write_npy(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.save(fh, pts if nrm is None else np.hstack([pts, nrm]))


def _write_npz(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    arrays = {"points": pts} if nrm is None else {"points": pts, "normals": nrm}
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _as_3d(pts: NDArray) -> NDArray:
    return pts if pts.shape[1] == 3 else np.column_stack([pts, np.zeros(len(pts))])


def _comments(dim: int) -> list[str]:
    return ["# written by ipfit"] + ([f"# {_IPFIT_2D}"] if dim == 2 else [])


def _write_obj(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    buffer = _io.StringIO()
    buffer.write("".join(line + "\n" for line in _comments(pts.shape[1])))
    for prefix, table in [("v", pts)] + ([("vn", nrm)] if nrm is not None else []):
        np.savetxt(buffer, _as_3d(table), fmt=prefix + " %.17g %.17g %.17g")
    write_text_atomic(path, buffer.getvalue())


def _write_off(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    header = ["OFF" if nrm is None else "NOFF"] + _comments(pts.shape[1]) + [f"{len(pts)} 0 0"]
    write_text_atomic(path, _table_text(_as_3d(pts), None if nrm is None else _as_3d(nrm), " ", "\n".join(header)))


_IMAGE_SUFFIXES = (".png", ".gif", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".webp", ".pgm", ".pbm", ".ppm")

_READERS: dict[str, Callable[[Path, bytes], _Raw]] = {
    ".ply": _read_ply,
    ".obj": _read_obj,
    ".off": _read_off,
    ".stl": lambda path, raw: _read_trimesh(path, raw, "stl"),
    ".xyz": _read_text,
    ".txt": _read_text,
    ".csv": _read_text,
    ".npy": _read_npy,
    ".npz": _read_npz,
    **{suffix: _read_image for suffix in _IMAGE_SUFFIXES},
}
_WRITERS = {".ply": _write_ply, ".obj": _write_obj, ".off": _write_off, ".csv": _write_csv, ".xyz": _write_xyz, ".txt": _write_xyz,
            ".npy": _write_npy, ".npz": _write_npz}
_FORMAT_NAMES = {".ply": "PLY", ".obj": "OBJ", ".off": "OFF", ".stl": "STL", ".xyz": "XYZ text", ".txt": "text",
                 ".csv": "CSV", ".npy": "NPY", ".npz": "NPZ", **{s: "image" for s in _IMAGE_SUFFIXES}}

#: Extensions :func:`read_points` understands.
READ_FORMATS = tuple(_READERS)
#: Extensions :func:`write_points` can write.
WRITE_FORMATS = tuple(_WRITERS)

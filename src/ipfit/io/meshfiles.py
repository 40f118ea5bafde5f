"""Readers of mesh files: PLY (plyfile), OBJ, OFF, STL and glTF/GLB/3MF scenes (trimesh).

Each reader takes the path and the file's bytes and returns a :class:`~ipfit.io._base.Raw`
(points, the file's vertex normals, triangles). The structure the libraries trust blindly
(PLY element counts, OFF counts, STL triangle counts, text encodings) is checked here first,
so that a corrupted file gives one line saying what is wrong rather than the library's
stumble. Scenes with several meshes are merged with each node's transform applied.
"""

from __future__ import annotations

import io as _io
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ReadError
from ._base import IPFIT_2D, Raw, optional_module, quiet_logger, short

__all__ = ["read_ply", "read_obj", "read_off", "read_stl", "read_scene"]

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_SIZES = {name: np.dtype(kind).itemsize for name, kind in _PLY_TYPES.items()}
_NORMAL_FIELDS = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))


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
    elements: list[list[Any]] = []  # [name, rows, bytes per row at least]
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


def read_ply(path: Path, raw: bytes) -> Raw:
    _ply_check_size(path, raw)
    names, vertex, comments, polygons = _ascii_ply(raw) or _plyfile_elements(path, raw)
    if "vertex" not in names:
        raise ReadError(f"{path}: no 'vertex' element in the PLY header (elements: {', '.join(names) or 'none'}).")
    fields = set(vertex.dtype.names or ())
    if not {"x", "y"} <= fields:
        raise ReadError(f"{path}: the vertices have no x and y properties "
                        f"(they have: {', '.join(sorted(fields)) or 'none'}).")
    two_d = "z" not in fields or (any(IPFIT_2D in c for c in comments) and not np.any(vertex["z"]))
    axes = "xy" if two_d else "xyz"
    points = np.column_stack([np.asarray(vertex[a], dtype=np.float64) for a in axes])
    normals = None
    for candidate in _NORMAL_FIELDS:
        wanted = candidate[:len(axes)]
        if set(wanted) <= fields:
            normals = np.column_stack([np.asarray(vertex[a], dtype=np.float64) for a in wanted])
            break
    faces = None if polygons is None else _triangulate(path, *polygons)
    return Raw(points, normals, faces, "file" if normals is not None else None)


_Elements = tuple[list[str], Any, list[str], "tuple[NDArray[np.intp], NDArray] | None"]


def _plyfile_elements(path: Path, raw: bytes) -> _Elements:
    """The element names, the vertices (a structured array, None without them), the comments and
    the faces' polygons (sizes, flat indices; None without them), read by plyfile."""
    from plyfile import PlyData, PlyParseError

    try:
        ply = PlyData.read(_io.BytesIO(raw), mmap=False)
    except PlyParseError as exc:
        if "end-of-file" in str(exc):
            raise ReadError(f"{path}: truncated ({short(exc)}). Re-export or re-download the file.") from None
        raise
    names = [e.name for e in ply.elements]
    vertex = ply["vertex"].data if "vertex" in names else None
    polygons = None
    if "face" in names and len(ply["face"].data):
        face = ply["face"].data
        key = next((k for k in ("vertex_indices", "vertex_index") if k in (face.dtype.names or ())), None)
        if key is not None:
            lists = list(face[key])
            sizes = np.fromiter(map(len, lists), dtype=np.intp, count=len(lists))
            polygons = sizes, (np.concatenate(lists) if sizes.sum() else np.empty(0, np.int64))
    return names, vertex, list(ply.comments), polygons


def _ascii_ply(raw: bytes) -> _Elements | None:
    """What :func:`_plyfile_elements` gives, parsed by numpy for the common ASCII layout: elements of
    scalar properties, and faces whose polygons all have the same number of corners.

    plyfile reads an ASCII file a value at a time (about 15 µs a line: 15 s for a million
    vertices); numpy's text reader parses the same values into the same types, a dozen times
    faster. Anything else (a binary file, other list properties, mixed polygons, a malformed or
    short line) returns None and is left to plyfile, which reads it, or says what is wrong, as
    before.
    """
    end = raw.find(b"end_header")
    body = raw.find(b"\n", end)
    if not raw.startswith(b"ply") or end < 0 or body < 0:
        return None
    try:
        header = raw[:end].decode("ascii").splitlines()[1:]
    except UnicodeDecodeError:
        return None
    ascii_format, comments = False, []
    # name, rows, [(property, numpy type, the list length type or None)]
    elements: list[tuple[str, int, list[tuple[str, str, str | None]]]] = []
    for line in header:
        words = line.split()
        if not words or words[0] == "obj_info":
            continue
        if words[0] == "comment":
            comments.append(line.split(None, 1)[1] if len(words) > 1 else "")
        elif words == ["format", "ascii", "1.0"]:
            ascii_format = True
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in _PLY_TYPES:
            elements[-1][2].append((words[2], _PLY_TYPES[words[1]], None))
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and _PLY_TYPES.get(words[2], "f")[0] in "iu" and _PLY_TYPES.get(words[3], "f")[0] in "iu"):
            elements[-1][2].append((words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]]))
        else:
            return None
    if not ascii_format:
        return None
    lines = raw[body + 1:].split(b"\n")
    names, vertex, polygons, at = [], None, None, 0
    for name, count, props in elements:
        rows = lines[at:at + count]
        at += count
        if not props or len(rows) < count or not all(row.strip() for row in rows):  # numpy skips blank lines
            return None
        text = _io.BytesIO(b"\n".join(rows))
        scalar = all(length is None for _, _, length in props)
        if not scalar and len(props) > 1:
            return None
        try:
            if scalar:
                dtype = np.dtype([(p, t) for p, t, _ in props])
                data = np.loadtxt(text, dtype=dtype, ndmin=1, comments=None) if count else np.empty(0, dtype)
            else:
                table = (np.loadtxt(text, dtype=np.int64, ndmin=2, comments=None) if count
                         else np.empty((0, 1), np.int64))
        except (ValueError, TypeError):  # a malformed value or a repeated property name: plyfile says which
            return None
        if not scalar:
            prop, value_type, length_type = props[0]
            corners = table.shape[1] - 1
            value_info, length_info = np.iinfo(value_type), np.iinfo(cast(str, length_type))
            indices = table[:, 1:]
            if count and (np.any(table[:, 0] != corners) or not length_info.min <= corners <= length_info.max
                          or indices.min(initial=0) < value_info.min or indices.max(initial=0) > value_info.max):
                return None
            if name == "face" and prop in ("vertex_indices", "vertex_index") and count and polygons is None:
                polygons = np.full(count, corners, dtype=np.intp), indices.ravel()
        elif name == "vertex":
            vertex = data
        names.append(name)
    return names, vertex, comments, polygons


def _triangulate(path: Path, sizes: NDArray[np.intp], flat: NDArray) -> NDArray[np.int64] | None:
    """Fan-triangulate polygons given by their sizes and their corners one after another
    (vectorised per polygon size)."""
    if not len(sizes):
        return None
    if flat.dtype.kind not in "iu":
        raise ReadError(f"{path}: the face indices are not integers ({flat.dtype}). The file is corrupted.")
    flat = flat.astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    out = []
    for size in np.unique(sizes):
        if size < 3:
            continue
        rows = flat[starts[sizes == size][:, None] + np.arange(size)]
        for j in range(1, size - 1):
            out.append(rows[:, [0, j, j + 1]])
    return np.concatenate(out) if out else None


def _as_text(path: Path, raw: bytes, what: str) -> bytes:
    """UTF-8 bytes of a text format, or a ReadError saying it is not text (trimesh would try to
    guess the encoding with a library that may not be installed)."""
    try:
        raw.decode("utf-8")
        return raw
    except UnicodeDecodeError as exc:
        if b"\x00" in raw:
            raise ReadError(f"{path}: not a text {what} file (it contains binary data, first non-text byte at "
                            f"{exc.start}). Check that the file is complete and really is {what}.") from None
        return raw.decode("latin-1").encode("utf-8")  # older exporters write Latin-1 names


def _trimesh_parts(result) -> list[dict]:
    if isinstance(result, dict) and "geometry" in result:
        return [g for g in result["geometry"].values() if isinstance(g, dict)]
    return [result] if isinstance(result, dict) else []


def _merge_parts(path: Path, parts: Sequence[tuple[dict, np.ndarray | None]], empty: str) -> Raw:
    """One cloud from trimesh's per-mesh dicts, each moved by its 4x4 transform (or None)."""
    points: list[NDArray[np.float64]] = []
    normals: list[NDArray[np.float64] | None] = []
    faces: list[NDArray[np.int64]] = []
    offset = 0
    dropped = None
    for part, transform in parts:
        v = part.get("vertices")
        if v is None or len(v) == 0:
            continue  # point-less geometry: paths, cameras...
        v = np.asarray(v, dtype=np.float64).reshape(len(v), -1)
        vn = part.get("vertex_normals")
        if vn is not None and np.shape(vn) != v.shape:
            dropped = f"{len(vn)} normals for {len(v)} vertices"
            vn = None
        vn = None if vn is None else np.asarray(vn, dtype=np.float64)
        if transform is not None:
            linear = transform[:3, :3]
            v = v @ linear.T + transform[:3, 3]
            # normals move with the inverse transpose of the linear part (non-uniform scales)
            vn = None if vn is None else vn @ np.linalg.inv(linear)
        points.append(v)
        normals.append(vn)
        f = part.get("faces")
        if f is not None and len(f):
            faces.append(np.asarray(f, dtype=np.int64).reshape(len(f), -1)[:, :3] + offset)
        offset += len(v)
    if not points:
        raise ReadError(f"{path}: {empty}")
    given = [n for n in normals if n is not None]
    nrm = np.concatenate(given) if len(given) == len(normals) else None
    return Raw(np.concatenate(points), nrm, np.concatenate(faces) if faces else None,
               "file" if nrm is not None else None, dropped)


def _read_trimesh(path: Path, raw: bytes, kind: str) -> Raw:
    from trimesh.exchange.load import mesh_loaders

    kwargs = {"skip_materials": True} if kind == "obj" else {}
    with quiet_logger("trimesh"):
        parts = _trimesh_parts(mesh_loaders[kind](_io.BytesIO(raw), file_type=kind, **kwargs))
    return _merge_parts(path, [(part, None) for part in parts],
                        f"no vertices found. Check that it is a valid {kind.upper()} file with vertices.")


def _written_2d(raw: bytes, data: Raw) -> Raw:
    """2D points written by ipfit to a 3D-only format (z = 0 and a comment) come back as 2D."""
    if IPFIT_2D.encode() not in raw[:200] or np.any(data.points[:, 2]):
        return data
    return data._replace(points=data.points[:, :2], normals=None if data.normals is None else data.normals[:, :2])


def read_obj(path: Path, raw: bytes) -> Raw:
    raw = _as_text(path, raw, "OBJ")
    data = _read_trimesh(path, raw, "obj")
    if data.normals is None and data.dropped_normals is None:
        # trimesh ignores 'vn' lines it cannot pair with vertices: say so rather than drop them silently
        n_vn = len(re.findall(rb"^\s*vn\s", raw, flags=re.MULTILINE))
        if n_vn:
            data = data._replace(dropped_normals=f"{n_vn} 'vn' lines for {len(data.points)} vertices")
    return _written_2d(raw, data)


_OFF_KEYWORD = re.compile(r"^(ST)?(C)?(N)?(4)?(n)?OFF(?=\s|$)")


def _off_layout(path: Path, text: str) -> tuple[bool, list[str], int]:
    """Check an OFF file's header and counts (trimesh reads a truncated face list silently).

    Returns whether the vertex lines carry normals (NOFF: x y z nx ny nz ...), the vertex
    lines and the number of faces announced.
    """
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
    if nv < 0 or nf < 0:
        raise ReadError(f"{path}: negative vertex or face count ({nv}, {nf}). The file is corrupted.")
    if len(body) < nv + nf:
        raise ReadError(f"{path}: truncated: the header announces {nv} vertices and {nf} faces "
                        f"but only {len(body)} data lines follow.")
    return bool(match.group(3)), body[:nv], nf


def read_off(path: Path, raw: bytes) -> Raw:
    raw = _as_text(path, raw, "OFF")
    with_normals, vertex_lines, n_faces = _off_layout(path, raw.decode("utf-8"))
    data = _read_trimesh(path, raw, "off")
    if len(data.points) != len(vertex_lines):
        raise ReadError(f"{path}: the header announces {len(vertex_lines)} vertices but {len(data.points)} "
                        "could be read. Every vertex line needs x y z numbers.")
    n_read = 0 if data.faces is None else len(data.faces)
    if n_faces and n_read < n_faces:
        raise ReadError(f"{path}: the header announces {n_faces} faces but only {n_read} triangles could be "
                        "read. Check the face lines (a count, then that many vertex indices).")
    if not with_normals:
        return _written_2d(raw, data)
    try:
        normals = np.array([ln.split()[3:6] for ln in vertex_lines], dtype=np.float64)
    except ValueError:
        raise ReadError(f"{path}: NOFF vertex lines need x y z nx ny nz numbers; some are missing or "
                        "not numbers.") from None
    return _written_2d(raw, data._replace(normals=normals, normals_source="file"))


def read_stl(path: Path, raw: bytes) -> Raw:
    n_announced = int.from_bytes(raw[80:84], "little") if len(raw) >= 84 else -1
    if n_announced >= 0 and len(raw) == 84 + 50 * n_announced:
        return _read_trimesh(path, raw, "stl")  # binary
    try:
        is_text = raw.decode("ascii").lstrip().lower().startswith("solid")
    except UnicodeDecodeError:
        is_text = False
    if not is_text:
        expected = (f"{84 + 50 * n_announced} bytes for the {n_announced} triangles its header announces"
                    if n_announced >= 0 else "at least 84 bytes")
        raise ReadError(f"{path}: not a valid STL file: as binary STL it should have {expected} but it has "
                        f"{len(raw)}, and it is not a text STL either (those start with 'solid'). "
                        "Check that the file is complete.")
    return _read_trimesh(path, raw, "stl")


def _checked_resolver(path: Path):
    """trimesh's resolver of the files a scene refers to (glTF buffers, COLLADA images), refusing
    a name outside the scene's folder and one that is not a regular file (a FIFO would hang)."""
    import os

    from trimesh.resolvers import FilePathResolver

    from .._utils.atomic import special_kind

    class Resolver(FilePathResolver):
        def get(self, name: str):
            folder = Path(self.parent).resolve()
            literal = (folder / name.strip()).resolve()
            if not literal.is_relative_to(folder):
                raise ReadError(f"{path}: it refers to '{name}', outside its folder; ipfit reads only files beside "
                                "the scene. Move that file next to it.")
            # every name trimesh may try for it (as given, without a leading '/', its base name)
            for candidate in (name.strip(), name.strip().lstrip("/"), os.path.basename(name)):
                kind = special_kind(folder / candidate)
                if kind is not None:
                    raise ReadError(f"{path}: it refers to '{name}', a {kind}, not a regular file. "
                                    "Point it to the data file itself.")
            return super().get(name)

    return Resolver(str(path))


def read_scene(path: Path, raw: bytes) -> Raw:
    """glTF 2.0 (.gltf with its buffers beside it, or .glb), 3MF and COLLADA (.dae): every mesh
    of the scene, each moved by its node's transform, merged into one cloud."""
    import trimesh

    load: Callable[..., Any]  # trimesh's loader of the format
    kwargs: dict[str, Any]
    if path.suffix.lower() == ".3mf":
        optional_module("lxml", path, "3MF")
        from trimesh.exchange.threemf import load_3MF

        kind, load, kwargs = "3mf", load_3MF, {}
    elif path.suffix.lower() == ".dae":
        optional_module("collada", path, "COLLADA")
        from trimesh.exchange.dae import load_collada

        kind, load, kwargs = "dae", load_collada, {"resolver": _checked_resolver(path)}
    else:
        from trimesh.exchange import gltf

        binary = raw[:4] == b"glTF"
        kind, load = ("glb", gltf.load_glb) if binary else ("gltf", gltf.load_gltf)
        kwargs = {"resolver": None if binary else _checked_resolver(path), "merge_primitives": True,
                  "skip_materials": True}
    with quiet_logger("trimesh"):
        parsed = load(_io.BytesIO(raw), **kwargs)
        scene = trimesh.load_scene(_io.BytesIO(raw), file_type=kind, resolver=kwargs.get("resolver"), process=False)
    geometry = parsed.get("geometry", {})
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        if isinstance(geometry.get(name), dict):
            parts.append((geometry[name], np.asarray(transform, dtype=np.float64)))
    return _merge_parts(path, parts, "no meshes with vertices in the scene. Export the model's geometry.")

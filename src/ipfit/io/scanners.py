"""Readers of scanner point clouds: LAS/LAZ (laspy + lazrs), PCD (pypcd4), E57 (pye57).

These libraries are optional (``pip install 'ipfit[scanners]'``); a missing one gives a
one-line error naming the extra. Coordinates stay float64 with the files' scales, offsets
and scan poses applied. Normals are read where the file stores them: LAS extra dimensions
(nx/ny/nz or normal_x/...), PCD fields normal_x/normal_y/normal_z, and the E57 surface
normals extension (``nor:normalX``...).
"""

from __future__ import annotations

import io as _io
import struct
from pathlib import Path

import numpy as np

from ..exceptions import ReadError
from ._base import Raw, optional_module

__all__ = ["read_las", "read_pcd", "read_e57"]

_NORMAL_TRIPLES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"), ("normalx", "normaly", "normalz"))


def _normal_columns(names, get) -> np.ndarray | None:
    """The first triple of normal fields present (case-insensitive), as an (N, 3) array."""
    by_lower = {name.lower(): name for name in names}
    for triple in _NORMAL_TRIPLES:
        if all(t in by_lower for t in triple):
            return np.column_stack([np.asarray(get(by_lower[t]), dtype=np.float64) for t in triple])
    return None


# LAZ compresses point records about 5-15 times; a header announcing more than this many times
# the file's size cannot be right, and the decompressor would abort the process allocating it.
_LAZ_MAX_RATIO = 1000
_LAZ_MAX_CHUNK = 10_000_000
_LAZ_VARIABLE_CHUNKS = 0xFFFFFFFF


def _check_las_structure(path: Path, raw: bytes) -> None:
    """Check the counts a LAS/LAZ header announces against the file, before decompressing.

    lazrs (Rust) aborts the whole process, uncatchably, when a corrupted chunk table or count
    makes it allocate terabytes; these are the fields it trusts.
    """
    if len(raw) < 227 or raw[:4] != b"LASF":
        raise ReadError(f"{path}: not a LAS/LAZ file (it should start with 'LASF' and a 227-byte header).")
    header_size, to_points, n_vlrs = struct.unpack_from("<HII", raw, 94)
    point_format, record_length, legacy_count = struct.unpack_from("<BHI", raw, 104)
    count = legacy_count
    if raw[25] >= 4 and header_size >= 255 and len(raw) >= 255:
        count = max(count, struct.unpack_from("<Q", raw, 247)[0])
    if not header_size <= to_points <= len(raw):
        raise ReadError(f"{path}: the header puts the points at byte {to_points} of a {len(raw)}-byte file. "
                        "The file is truncated or corrupted.")
    if n_vlrs * 54 > to_points - header_size:
        raise ReadError(f"{path}: the header announces {n_vlrs} variable-length records before byte {to_points}, "
                        "more than fit. The file is corrupted.")
    if raw[25] >= 4 and header_size >= 375 and len(raw) >= 375:
        evlr_start, n_evlrs = struct.unpack_from("<QI", raw, 235)
        if n_evlrs and (evlr_start > len(raw) or n_evlrs * 60 > len(raw) - evlr_start):
            raise ReadError(f"{path}: the header announces {n_evlrs} extended records at byte {evlr_start} of a "
                            f"{len(raw)}-byte file. The file is truncated or corrupted.")
    compressed = bool(point_format & 0xC0)
    needed = count * record_length
    available = len(raw) - to_points
    if needed > (available * _LAZ_MAX_RATIO if compressed else available):
        raise ReadError(f"{path}: the header announces {count} points of {record_length} bytes but the file holds "
                        f"only {available} bytes of point data. The file is truncated or corrupted.")
    if not compressed:
        return
    chunk_size = _laszip_chunk_size(path, raw, header_size, n_vlrs)
    if chunk_size != _LAZ_VARIABLE_CHUNKS and chunk_size > _LAZ_MAX_CHUNK:
        raise ReadError(f"{path}: the LAZ header announces chunks of {chunk_size} points. The file is corrupted.")
    table = struct.unpack_from("<q", raw, to_points)[0] if available >= 8 else -1
    if table == -1:
        return
    if not to_points + 8 <= table <= len(raw) - 8:
        raise ReadError(f"{path}: the LAZ chunk table is announced at byte {table} of a {len(raw)}-byte file. "
                        "The file is truncated or corrupted.")
    version, n_chunks = struct.unpack_from("<II", raw, table)
    if version != 0 or n_chunks > max(count, 1):
        raise ReadError(f"{path}: the LAZ chunk table announces {n_chunks} chunks for {count} points. "
                        "The file is corrupted.")


def _laszip_chunk_size(path: Path, raw: bytes, header_size: int, n_vlrs: int) -> int:
    at = header_size
    for _ in range(min(n_vlrs, 10_000)):
        if at + 54 > len(raw):
            break
        user_id = raw[at + 2:at + 18].rstrip(b"\0")
        record_id, length = struct.unpack_from("<HH", raw, at + 18)
        if user_id == b"laszip encoded" and record_id == 22204 and length >= 16 and at + 54 + 16 <= len(raw):
            return struct.unpack_from("<I", raw, at + 54 + 12)[0]
        at += 54 + length
    raise ReadError(f"{path}: compressed points but no LASzip description in the header. The file is corrupted.")


def read_las(path: Path, raw: bytes) -> Raw:
    laspy = optional_module("laspy", path, "LAS/LAZ")
    _check_las_structure(path, raw)
    if raw[104] & 0xC0:
        optional_module("lazrs", path, "LAZ")
    las = laspy.read(_io.BytesIO(raw))
    # x, y, z are the stored integers times the header's scales plus its offsets, in float64
    points = np.column_stack([np.asarray(las.x, dtype=np.float64), np.asarray(las.y, dtype=np.float64),
                              np.asarray(las.z, dtype=np.float64)])
    normals = _normal_columns(list(las.point_format.extra_dimension_names), lambda name: las[name])
    return Raw(points, normals)


def read_pcd(path: Path, raw: bytes) -> Raw:
    pypcd4 = optional_module("pypcd4", path, "PCD")
    cloud = pypcd4.PointCloud.from_fileobj(_io.BytesIO(raw))
    fields = list(cloud.fields)
    if not {"x", "y", "z"} <= set(fields):
        raise ReadError(f"{path}: the PCD fields are {', '.join(fields) or 'none'}; x, y and z are needed.")
    data = cloud.pc_data
    expected = int(cloud.metadata.points)
    if len(data) != expected:
        raise ReadError(f"{path}: the header announces {expected} points but {len(data)} could be read. "
                        "The file is truncated or corrupted.")
    points = np.column_stack([np.asarray(data[a], dtype=np.float64) for a in "xyz"])
    return Raw(points, _normal_columns(fields, lambda name: data[name]))


#: Fields of the E57 surface-normals extension (http://www.libe57.org/E57_NOR_surface_normals.txt).
E57_NORMAL_FIELDS = ("nor:normalX", "nor:normalY", "nor:normalZ")


def read_e57(path: Path, raw: bytes) -> Raw:
    """Every scan of the file, moved to the file's frame by its pose, merged."""
    pye57 = optional_module("pye57", path, "E57")
    from pye57 import libe57

    points, normals = [], []
    with pye57.E57(str(path)) as e57:
        for index in range(e57.scan_count):
            header = e57.get_header(index)
            scan = e57.read_scan(index, ignore_missing_fields=True, transform=True)
            xyz = np.column_stack([scan["cartesianX"], scan["cartesianY"], scan["cartesianZ"]])
            points.append(xyz.astype(np.float64))
            normals.append(None)
            if all(f in header.point_fields for f in E57_NORMAL_FIELDS):
                n = header.point_count
                arrays = [np.empty(n, np.float64) for _ in E57_NORMAL_FIELDS]
                buffers = libe57.VectorSourceDestBuffer()
                for name, array in zip(E57_NORMAL_FIELDS, arrays):
                    buffers.append(libe57.SourceDestBuffer(e57.image_file, name, array, n, True, True))
                header.points.reader(buffers).read()
                nrm = np.column_stack(arrays)
                if "cartesianInvalidState" in header.point_fields:
                    state = e57.read_scan_raw(index, ignore_unsupported_fields=True)["cartesianInvalidState"]
                    nrm = nrm[state == 0]
                if header.has_pose():
                    nrm = nrm @ header.rotation_matrix.T  # a rotation: normals turn like points
                normals[-1] = nrm if nrm.shape == xyz.shape else None
    if not points:
        raise ReadError(f"{path}: the E57 file holds no scans. Export the point cloud into it.")
    nrm = np.concatenate(normals) if all(n is not None for n in normals) else None
    return Raw(np.concatenate(points), nrm)

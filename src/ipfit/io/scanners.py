"""Readers of scanner point clouds: LAS/LAZ (laspy + lazrs), PCD (pypcd4), E57 (pye57).

These libraries are optional (``pip install 'ipfit[scanners]'``); a missing one gives a
one-line error naming the extra. Coordinates stay float64 with the files' scales, offsets
and scan poses applied. Normals are read where the file stores them: LAS extra dimensions
(nx/ny/nz or normal_x/...), PCD fields normal_x/normal_y/normal_z, and the E57 surface
normals extension (``nor:normalX``...).
"""

from __future__ import annotations

import io as _io
import re
import struct
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

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


# pypcd4 trusts its header: COUNT 2147483648 makes it build a list of 2**31 field names (tens of
# GB), POINTS sizes a zeroed array and the compressed-size fields an LZF buffer. The header is
# read here first, the way pypcd4 reads it, and checked against the file.
_PCD_HEADER_LINE = re.compile(r"(\w+)\s+([\w\s\.\-?\d+\.?\d*]+)")  # pypcd4's HEADER_PATTERN
_PCD_MAX_HEADER_LINES = 10  # pypcd4 stops reading the header after 10 lines
_PCD_TYPES = {"F": (4, 8), "U": (1, 2, 4, 8), "I": (1, 2, 4, 8)}
#: Values per point (the sum of COUNT) accepted; PCL's widest descriptors hold about 2,000.
_PCD_MAX_COLUMNS = 100_000
#: LZF turns 3 bytes into at most 264: a larger announced ratio is a corrupted size field.
_LZF_MAX_RATIO = 100
_PCD_ENCODINGS = ("ascii", "binary", "binary_compressed", "binaryscompressed")


def _pcd_number(text: str) -> str:
    return text if len(text) <= 20 else f"{text[:8]}... ({len(text)} digits)"


def _pcd_header(path: Path, raw: bytes) -> tuple[dict[str, list[str]], int]:
    """The PCD header's entries {key (lower case): values} as pypcd4 reads them, and the offset
    of the data after the DATA line."""
    lines: list[str] = []
    at = 0
    while at < len(raw) and len(lines) < _PCD_MAX_HEADER_LINES:
        end = raw.find(b"\n", at)
        end = len(raw) if end < 0 else end + 1
        try:
            line = raw[at:end].decode("utf-8").strip()
        except UnicodeDecodeError:
            raise ReadError(f"{path}: the PCD header is not text (line {len(lines) + 1} is binary). "
                            "The file is corrupted or not a PCD file.") from None
        at = end
        if line.startswith("#") or not line:
            continue
        lines.append(line)
        if line.startswith("DATA"):
            break
    if not lines or not lines[-1].startswith("DATA"):
        raise ReadError(f"{path}: no DATA line ends the PCD header (within its first {_PCD_MAX_HEADER_LINES} "
                        "lines). The file is corrupted or not a PCD file.")
    header: dict[str, list[str]] = {}
    for line in lines:
        match = _PCD_HEADER_LINE.match(line)
        if match is not None:
            header[match.group(1).lower()] = match.group(2).split()
    last = _PCD_HEADER_LINE.match(lines[-1])
    if last is None or last.group(1).lower() != "data" or not header.get("data"):
        raise ReadError(f"{path}: the PCD header ends with {lines[-1][:40]!r}, not 'DATA ascii', 'DATA binary' "
                        "or 'DATA binary_compressed'. The file is corrupted.")
    return header, at


def _pcd_integers(path: Path, header: dict[str, list[str]], key: str) -> list[int]:
    if not header.get(key):
        raise ReadError(f"{path}: the PCD header has no {key.upper()} line. The file is corrupted or not a PCD file.")
    values = []
    for text in header[key]:
        if not (text.isascii() and text.isdigit() and len(text) <= 30):
            raise ReadError(f"{path}: {key.upper()} {_pcd_number(text)!r} in the PCD header is not a whole number "
                            "of 0 or more. The file is corrupted.")
        values.append(int(text))
    return values


def _check_pcd_structure(path: Path, raw: bytes) -> None:
    """Check the sizes a PCD header announces against the file, before pypcd4 allocates them."""
    header, start = _pcd_header(path, raw)
    fields = header.get("fields") or []
    sizes, counts = _pcd_integers(path, header, "size"), _pcd_integers(path, header, "count")
    types = header.get("type") or []
    if not fields or not len(fields) == len(sizes) == len(types) == len(counts):
        raise ReadError(f"{path}: the PCD header lists {len(fields)} FIELDS, {len(sizes)} SIZE, {len(types)} TYPE "
                        f"and {len(counts)} COUNT values; they must be as many, one per field. "
                        "The file is corrupted.")
    for name, size, kind in zip(fields, sizes, types, strict=True):
        if size not in _PCD_TYPES.get(kind, ()):
            raise ReadError(f"{path}: field {name[:40]!r} of the PCD header has TYPE {kind[:10]!r} and SIZE "
                            f"{_pcd_number(str(size))}; PCD fields are F of 4 or 8 bytes, or U and I of 1, 2, 4 "
                            "or 8. The file is corrupted.")
    if min(counts) < 1 or sum(counts) > _PCD_MAX_COLUMNS:
        raise ReadError(f"{path}: the PCD header gives COUNT {' '.join(_pcd_number(str(c)) for c in counts[:8])}"
                        f"{' ...' if len(counts) > 8 else ''}; each field needs a COUNT of at least 1 and at most "
                        f"{_PCD_MAX_COLUMNS} values per point in all. The file is corrupted.")
    width, points = _pcd_integers(path, header, "width")[0], _pcd_integers(path, header, "points")[0]
    height = _pcd_integers(path, header, "height")[0] if "height" in header else 1
    if width * height != points:
        raise ReadError(f"{path}: the PCD header announces WIDTH {_pcd_number(str(width))} x HEIGHT "
                        f"{_pcd_number(str(height))} but POINTS {_pcd_number(str(points))}; they must agree. "
                        "The file is corrupted.")
    encoding = header["data"][0]
    if encoding not in _PCD_ENCODINGS:
        raise ReadError(f"{path}: 'DATA {encoding[:40]}' in the PCD header; the data must be ascii, binary or "
                        "binary_compressed. The file is corrupted.")
    if points == 0:
        return
    record = sum(size * count for size, count in zip(sizes, counts, strict=True))
    needed, available = points * record, len(raw) - start
    shown = _pcd_number(str(points))
    if encoding == "ascii":
        lines = raw.count(b"\n", start) + (1 if available and not raw.endswith(b"\n") else 0)
        if points > lines:
            raise ReadError(f"{path}: the PCD header announces {shown} points but only {lines} lines of data "
                            "follow. The file is truncated or corrupted.")
        values = points * sum(counts)
        if 2 * values > available + 1:  # every value takes a digit and a separator: else the table
            raise ReadError(f"{path}: the PCD header announces {shown} points of {sum(counts)} values each, but "
                            f"{available} bytes of text cannot hold {values} values. The file is corrupted.")
    elif encoding == "binary":
        if needed > available:
            raise ReadError(f"{path}: the PCD header announces {shown} points of {record} bytes but the file holds "
                            f"only {available} bytes of point data. The file is truncated or corrupted.")
    else:
        if available < 8:
            raise ReadError(f"{path}: the compressed PCD data has no size fields. The file is truncated.")
        compressed, uncompressed = struct.unpack_from("II", raw, start)
        if compressed > available - 8:
            raise ReadError(f"{path}: the PCD header announces {compressed} bytes of compressed data but the file "
                            f"holds only {available - 8}. The file is truncated or corrupted.")
        if uncompressed != needed or uncompressed > compressed * _LZF_MAX_RATIO:
            raise ReadError(f"{path}: the compressed PCD data announces {uncompressed} bytes from {compressed} "
                            f"compressed bytes, but {shown} points of {record} bytes are {needed}. "
                            "The file is corrupted.")


def read_pcd(path: Path, raw: bytes) -> Raw:
    pypcd4 = optional_module("pypcd4", path, "PCD")
    _check_pcd_structure(path, raw)
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

    points: list[NDArray[np.float64]] = []
    normals: list[NDArray[np.float64] | None] = []
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
                for name, array in zip(E57_NORMAL_FIELDS, arrays, strict=True):
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
    given = [n for n in normals if n is not None]
    return Raw(np.concatenate(points), np.concatenate(given) if len(given) == len(normals) else None)

"""Readers of scanner point clouds: LAS/LAZ (laspy + lazrs), PCD (pypcd4), E57 (pye57).

These libraries are optional (``pip install 'ipfit[scanners]'``); a missing one gives a
one-line error naming the extra. Coordinates stay float64 with the files' scales, offsets
and scan poses applied. Normals are read where the file stores them: LAS extra dimensions
(nx/ny/nz or normal_x/...), PCD fields normal_x/normal_y/normal_z, and the E57 surface
normals extension (``nor:normalX``...).
"""

from __future__ import annotations

import io as _io
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


def read_las(path: Path, raw: bytes) -> Raw:
    laspy = optional_module("laspy", path, "LAS/LAZ")
    if path.suffix.lower() == ".laz" or raw[:4] == b"LASF" and b"laszip" in raw[:4096].lower():
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

"""Geometry of point clouds and meshes, below any polynomial: well-spread subsamples and point
spacing (:mod:`~ipfit.geometry.sampling`), the distance engine from query points to bare points,
a contour's segments or a mesh's triangles (:mod:`~ipfit.geometry.distance`, compiled in
:mod:`~ipfit.geometry._distance_kernels`), and mesh geometry: merging split vertices, face and vertex
normals, winding numbers (:mod:`~ipfit.geometry.mesh`).
"""

from .distance import DEFAULT_TAU_FRACTION, Samples, Target, data_target
from .mesh import (
    Merged,
    face_normals,
    fill_missing_normals,
    merge_duplicates,
    outward_vertices,
    vertex_normals_from_faces,
    winding_number,
)
from .sampling import point_spacing, spread_subsample

__all__ = [
    "spread_subsample",
    "point_spacing",
    "Samples",
    "Target",
    "data_target",
    "DEFAULT_TAU_FRACTION",
    "Merged",
    "merge_duplicates",
    "face_normals",
    "vertex_normals_from_faces",
    "fill_missing_normals",
    "winding_number",
    "outward_vertices",
]

"""Reading and writing point clouds: points, normals and (for meshes) faces.

The package, one concern per module:

- :mod:`~ipfit.io.readers`: :func:`read_points`, :func:`read_mesh`, the registry of formats
  (:data:`FORMATS`: suffix -> name, library, reader) and the checks every file gets;
- :mod:`~ipfit.io.meshfiles`, :mod:`~ipfit.io.tables`, :mod:`~ipfit.io.scanners`: the format
  readers (PLY/OBJ/OFF/STL/glTF; text and NumPy tables; LAS/LAZ, PCD, E57);
- :mod:`~ipfit.io.silhouettes`: tracing the outline of a shape in an image;
- :mod:`~ipfit.io.writers`: :func:`write_points`.

File formats only: the geometry of the meshes read (merging split vertices, face and vertex
normals, winding numbers) is :mod:`ipfit.geometry.mesh`.

Every failure to read is a :class:`~ipfit.exceptions.ReadError` whose one-line message starts
with the file's path.
"""

from .readers import FORMATS, READ_FORMATS, Format, Mesh, PointCloud, read_mesh, read_points
from .silhouettes import CONTOUR_SPAN, IMAGE_SUFFIXES, trace_silhouette
from .writers import WRITE_FORMATS, write_points

__all__ = [
    "PointCloud",
    "Mesh",
    "Format",
    "read_points",
    "read_mesh",
    "write_points",
    "trace_silhouette",
    "FORMATS",
    "READ_FORMATS",
    "WRITE_FORMATS",
    "CONTOUR_SPAN",
    "IMAGE_SUFFIXES",
]

"""Geometry objects of other libraries as arrays: trimesh, Open3D, PyVista, pandas.

Recognised by duck typing on the object's class and module, so none of those packages is a
dependency and none is imported here: a user who holds one has it installed already.
:func:`foreign_parts` returns the points, normals and faces an object carries (normals and
faces only when present), as plain arrays; the public functions check them as they check
arrays (:func:`ipfit.cloud.as_cloud`), so an object and the same arrays give the same fit.

==============================================  ============================================
object                                          points, normals, faces
==============================================  ============================================
``trimesh.Trimesh``                             ``vertices``, ``vertex_normals``, ``faces``
``trimesh.PointCloud``                          ``vertices``
``open3d.geometry.PointCloud``                  ``points``, ``normals`` if ``has_normals()``
``open3d.geometry.TriangleMesh``                ``vertices``, ``vertex_normals`` if
                                                ``has_vertex_normals()``, ``triangles``
``pyvista.PolyData`` (and other PyVista sets)   ``points``, ``point_data["Normals"]`` if
                                                present, triangles of ``faces`` if all are
``pandas.DataFrame``                            columns x, y[, z]; nx, ny[, nz] if present
==============================================  ============================================

A trimesh mesh's ``vertex_normals`` are the file's when it had them, otherwise trimesh's
(area- and angle-weighted from the faces), so they are always present.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..exceptions import error

__all__ = ["ForeignParts", "foreign_parts", "is_foreign", "KINDS"]

#: What is understood, for messages.
KINDS = ("trimesh.Trimesh", "trimesh.PointCloud", "open3d.geometry.PointCloud", "open3d.geometry.TriangleMesh",
         "pyvista.PolyData", "pandas.DataFrame")


class ForeignParts(NamedTuple):
    """The arrays of a foreign object; ``kind`` names it in messages ("trimesh.Trimesh")."""

    points: Any
    normals: Any
    faces: Any
    kind: str


def _package(obj: Any) -> str:
    return type(obj).__module__.split(".")[0]


def is_foreign(obj: Any) -> bool:
    """Whether ``obj`` comes from one of the libraries :func:`foreign_parts` reads (arrays,
    trimesh's ``TrackedArray`` among them, are not foreign)."""
    return not isinstance(obj, np.ndarray) and _package(obj) in ("trimesh", "open3d", "pyvista", "pandas")


def foreign_parts(obj: Any, name: str = "points") -> ForeignParts | None:
    """The points, normals and faces of a foreign geometry object, or None for anything else.

    Parameters
    ----------
    obj : object
        See the module notes for what is read from each kind.
    name : str
        The argument's name in the error raised for an object of a known library that is not
        understood (a trimesh ``Path3D``, an Open3D voxel grid...).

    Returns
    -------
    ForeignParts or None
        Arrays as the object holds them (checked by the caller), None when ``obj`` is not from
        trimesh, Open3D, PyVista or pandas.
    """
    if isinstance(obj, np.ndarray):  # trimesh's TrackedArray and other array subclasses are arrays
        return None
    package = _package(obj)
    kind = f"{package}.{type(obj).__name__}"
    if package == "pandas":
        if type(obj).__name__ != "DataFrame":
            return None  # a Series etc.: as_points explains what it expects
        lowered = {str(c).strip().lower() for c in obj.columns}
        has_normals = {"nx", "ny"} <= lowered
        return ForeignParts(obj, obj if has_normals else None, None, kind)
    if package == "trimesh":
        if hasattr(obj, "vertices") and hasattr(obj, "faces") and hasattr(obj, "vertex_normals"):
            faces = np.asarray(obj.faces)
            return ForeignParts(np.asarray(obj.vertices), np.asarray(obj.vertex_normals) if len(faces) else None,
                                faces if len(faces) else None, kind)
        if hasattr(obj, "vertices") and not hasattr(obj, "entities"):  # PointCloud (a Path has entities)
            return ForeignParts(np.asarray(obj.vertices), None, None, kind)
    elif package == "open3d":
        if hasattr(obj, "triangles") and hasattr(obj, "vertices"):
            faces = np.asarray(obj.triangles)
            normals = np.asarray(obj.vertex_normals) if obj.has_vertex_normals() else None
            return ForeignParts(np.asarray(obj.vertices), normals, faces if len(faces) else None, kind)
        if hasattr(obj, "points") and hasattr(obj, "has_normals"):
            return ForeignParts(np.asarray(obj.points), np.asarray(obj.normals) if obj.has_normals() else None,
                                None, kind)
    elif package == "pyvista":
        if hasattr(obj, "points") and hasattr(obj, "point_data"):
            normals = obj.point_data["Normals"] if "Normals" in obj.point_data else None
            return ForeignParts(np.asarray(obj.points), None if normals is None else np.asarray(normals),
                                _pyvista_triangles(obj), kind)
    else:
        return None
    raise error(name, "points as an array, a Cloud or one of " + ", ".join(KINDS), f"a {kind}",
                "Pass its points as an array, e.g. np.asarray(...).")


def _pyvista_triangles(data: Any) -> NDArray[np.int64] | None:
    """The triangles of a PolyData (None when it has no faces: points or lines only)."""
    faces = getattr(data, "faces", None)
    if faces is None or len(faces) == 0:
        return None
    flat = np.asarray(faces, dtype=np.int64)
    if len(flat) % 4 or not np.all(flat[::4] == 3):
        raise error("faces", "triangles", "a PyVista mesh with other polygons",
                    "Triangulate it first: mesh.triangulate().")
    return flat.reshape(-1, 4)[:, 1:]

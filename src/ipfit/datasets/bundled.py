"""Real shapes shipped with ipfit: the Stanford bunny, an apple, a rubber duck and three 2D contours.

Credits are in ``data/CREDITS.md`` and in :func:`list_datasets`.

Normals: the 2D contours are ordered, so their normals come from the order (perpendicular
of a central difference over ±2 points, outward). The apple has its own vertex normals.
The bunny and the duck get area-weighted normals from their faces (bunny vertices in no face,
about 3 %, take their nearest vertex's).

>>> points, normals = load_dataset("boot")
>>> points.shape, normals.shape
((1354, 2), (1354, 2))
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..exceptions import InvalidInputError
from ..geometry.mesh import fill_missing_normals, vertex_normals_from_faces
from ..io import CONTOUR_SPAN, PointCloud, read_mesh, read_points

__all__ = ["DatasetInfo", "list_datasets", "dataset_names", "dataset_path", "load_dataset", "dataset_faces",
           "DATA_DIR"]

DATA_DIR = Path(__file__).with_name("data")

_STANFORD = "Stanford 3D Scanning Repository, Stanford Computer Graphics Laboratory"
_MPEG7 = "MPEG-7 CE-Shape-1 Part B (Latecki, Temple University)"


class DatasetInfo(NamedTuple):
    name: str
    dim: int
    description: str
    credit: str


class _Entry(NamedTuple):
    file: str
    dim: int
    description: str
    credit: str
    normals: str  # "contour", "file" or "faces"


_DATASETS: dict[str, _Entry] = {
    "bunny": _Entry("3d/bun_zipper.ply", 3, "Stanford bunny, 35,947 points, with faces (paper Fig. 13)",
                    _STANFORD, "faces"),
    "bunny_res2": _Entry("3d/bun_zipper_res2.ply", 3, "Stanford bunny, 8,171 points", _STANFORD, "faces"),
    "bunny_res3": _Entry("3d/bun_zipper_res3.ply", 3, "Stanford bunny, 1,889 points", _STANFORD, "faces"),
    "bunny_res4": _Entry("3d/bun_zipper_res4.ply", 3, "Stanford bunny, 453 points", _STANFORD, "faces"),
    "apple": _Entry("3d/apple.ply", 3, "apple, 867 points with vertex normals and faces (paper Fig. 11)",
                    "Greg Turk's PLY sample models (Georgia Tech); normals from a 2002 Harvard course copy", "file"),
    "duck": _Entry("3d/rubber_duck.ply", 3, "rubber duck, 5,482 points (32,575 rows merged), faces (paper Fig. 12)",
                   "public GitHub copy of a robotics pose-estimation model (likely the LINEMOD duck); "
                   "provenance not stated by its source", "faces"),
    "boot": _Entry("2d/boot.csv", 2, "boot: ordered contour of MPEG-7 shoe-3, 1,354 points (paper Fig. 9)",
                   _MPEG7, "contour"),
    "airplane": _Entry("2d/airplane.csv", 2, "airplane seen from above: ordered contour, 200 points (paper Fig. 8)",
                       "Kimia-99 shape database (Brown University LEMS)", "contour"),
    "butterfly": _Entry("2d/butterfly.csv", 2, "butterfly: ordered contour of MPEG-7 butterfly-2, 3,214 points "
                        "(paper Fig. 10)", _MPEG7, "contour"),
}


def list_datasets() -> list[DatasetInfo]:
    """Name, dimension, description and credit of every bundled dataset."""
    return [DatasetInfo(name, e.dim, e.description, e.credit) for name, e in _DATASETS.items()]


def dataset_names() -> list[str]:
    return list(_DATASETS)


def resolve_name(name: str) -> str | None:
    """The bundled dataset ``name`` refers to, ignoring case ("Boot" is "boot"); None if none."""
    if not isinstance(name, str):
        return None
    folded = {key.casefold(): key for key in _DATASETS}
    return folded.get(name.casefold())


def suggestion(name: str) -> str:
    """" Did you mean 'boot'?" for a near miss of a dataset name, else ""."""
    import difflib

    close = difflib.get_close_matches(str(name).casefold(), list(_DATASETS), n=1, cutoff=0.6)
    return f" Did you mean {close[0]!r}?" if close else ""


def _entry(name: str) -> _Entry:
    key = resolve_name(name)
    if key is None:
        raise InvalidInputError(f"name: expected one of {', '.join(_DATASETS)}, got {name!r}.{suggestion(name)} "
                                "See ipfit.datasets.list_datasets() or `ipfit datasets`.")
    return _DATASETS[key]


def dataset_path(name: str) -> Path:
    """Path of the bundled file behind dataset ``name``."""
    return DATA_DIR / _entry(name).file


def load_dataset(name: str) -> PointCloud:
    """``(points, normals)`` of a bundled dataset (fresh copies: safe to modify); names ignore case.

    Its ``normals_source`` says where the normals come from: "contour", "file" or "faces".
    """
    points, normals, _, source = _load(name)
    return PointCloud(points.copy(), normals.copy(), source)


def dataset_faces(name: str) -> NDArray[np.int64] | None:
    """Triangles of a bundled mesh as (M, 3) indices into ``load_dataset(name).points``; None in 2D."""
    faces = _load(name)[2]
    return None if faces is None else faces.copy()


@functools.cache
def _load(name: str):
    entry = _entry(name)
    path = DATA_DIR / entry.file
    if entry.normals == "contour":
        from ..normals import contour_normals

        points = read_points(path).points
        return points, contour_normals(points, span=CONTOUR_SPAN), None, "contour"
    mesh = read_mesh(path)
    faces = _bundled(mesh.faces, "faces", path)
    if entry.normals == "file" and mesh.normals is not None:
        normals, source = mesh.normals, "file"
    else:
        filled = fill_missing_normals(mesh.points, vertex_normals_from_faces(mesh.points, faces))
        normals, source = _bundled(filled, "normals", path), "faces"
    for arr in (mesh.points, normals, faces):
        arr.setflags(write=False)
    return mesh.points, normals, faces, source


def _bundled(arr: NDArray | None, what: str, path: Path) -> NDArray:
    """``arr``, which every bundled mesh has (its faces, normals where none has a direction)."""
    if arr is None:
        raise RuntimeError(f"{path}: a bundled mesh without {what}")  # a bug of ipfit's data, not an input error
    return arr

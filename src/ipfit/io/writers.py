"""Writing point clouds (points and normals): PLY, OBJ, OFF/NOFF, CSV, XYZ/TXT, NPY, NPZ.

Every file is written atomically (:mod:`ipfit._utils.atomic`): a reader never sees half a file and
a failed write leaves the old file in place. 2D points written to the 3D-only formats (PLY,
OBJ, OFF) get z = 0 and a comment, so that :func:`ipfit.io.read_points` gives them back as 2D.
"""

from __future__ import annotations

import io as _io
import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.atomic import atomic_path, write_text_atomic
from .._utils.validation import as_points, error
from ..exceptions import InvalidInputError
from ._base import IPFIT_2D, as_path

__all__ = ["write_points", "WRITE_FORMATS"]


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
    path = as_path(path)
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


def _write_ply(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    from plyfile import PlyData, PlyElement

    n, dim = pts.shape
    cols = [pts[:, 0], pts[:, 1], pts[:, 2] if dim == 3 else np.zeros(n)]
    names = ["x", "y", "z"]
    if nrm is not None:
        cols += [nrm[:, 0], nrm[:, 1], nrm[:, 2] if dim == 3 else np.zeros(n)]
        names += ["nx", "ny", "nz"]
    table = np.empty(n, dtype=[(name, "f8") for name in names])
    for name, col in zip(names, cols, strict=True):
        table[name] = col
    comments = ["written by ipfit"] + ([IPFIT_2D] if dim == 2 else [])
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
        # numpy's stubs fear a key allow_pickle=; the keys are "points" and "normals"
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]


def _as_3d(pts: NDArray) -> NDArray:
    return pts if pts.shape[1] == 3 else np.column_stack([pts, np.zeros(len(pts))])


def _comments(dim: int) -> list[str]:
    return ["# written by ipfit"] + ([f"# {IPFIT_2D}"] if dim == 2 else [])


def _write_obj(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    buffer = _io.StringIO()
    buffer.write("".join(line + "\n" for line in _comments(pts.shape[1])))
    for prefix, table in [("v", pts)] + ([("vn", nrm)] if nrm is not None else []):
        np.savetxt(buffer, _as_3d(table), fmt=prefix + " %.17g %.17g %.17g")
    write_text_atomic(path, buffer.getvalue())


def _write_off(path: Path, pts: NDArray, nrm: NDArray | None, binary: bool) -> None:
    header = ["OFF" if nrm is None else "NOFF"] + _comments(pts.shape[1]) + [f"{len(pts)} 0 0"]
    write_text_atomic(path, _table_text(_as_3d(pts), None if nrm is None else _as_3d(nrm), " ", "\n".join(header)))


_WRITERS = {".ply": _write_ply, ".obj": _write_obj, ".off": _write_off, ".csv": _write_csv, ".xyz": _write_xyz,
            ".txt": _write_xyz, ".npy": _write_npy, ".npz": _write_npz}
#: Extensions :func:`write_points` can write.
WRITE_FORMATS = tuple(_WRITERS)

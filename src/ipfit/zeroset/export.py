"""Write extracted zero sets: meshes as PLY, OBJ or STL (trimesh), curves as SVG or CSV.

Every writer goes through :func:`ipfit._utils.atomic.atomic_path`: a reader never sees half a file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._utils.atomic import atomic_path, write_text_atomic
from ..exceptions import InvalidInputError

__all__ = ["MESH_FORMATS", "CURVE_FORMATS", "save_zero_set", "write_mesh", "write_curves_svg", "write_curves_csv"]

MESH_FORMATS = (".ply", ".obj", ".stl")
CURVE_FORMATS = (".svg", ".csv")


def write_mesh(path: str | os.PathLike, vertices, faces) -> None:
    """Write a triangle mesh; the format follows the extension (.ply binary, .obj, .stl binary)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        raise InvalidInputError(f"{path}: expected a mesh file ending in {', '.join(MESH_FORMATS)}, "
                                f"got {suffix or 'no extension'!r}. Choose one of those extensions.")
    faces = np.asarray(faces, dtype=np.int64)
    if faces.size == 0:
        raise InvalidInputError(f"{path}: the zero set is empty inside the box, so there is no mesh to write. "
                                "Enlarge the box (margin) or check the fit.")
    import trimesh

    mesh = trimesh.Trimesh(vertices=np.asarray(vertices, dtype=np.float64), faces=faces, process=False)
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type=suffix[1:])


def _svg_number(v: float) -> str:
    return f"{v:.6g}"


def write_curves_svg(path: str | os.PathLike, curves, bounds, *, stroke: str = "black",
                     stroke_width: float | None = None) -> None:
    """Write polylines as an SVG drawing of the box ``bounds`` (y flipped to point up).

    Path coordinates are the data's (as in the CSV); a transform on the group mirrors y
    inside the box, since SVG's y grows downwards. Closed curves (first point repeated at
    the end) become closed paths.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    (x0, x1), (y0, y1) = bounds
    width, height = x1 - x0, y1 - y0
    stroke_width = stroke_width if stroke_width is not None else 0.004 * max(width, height)
    paths = []
    for curve in curves:
        c = np.asarray(curve, dtype=np.float64)
        if len(c) < 2:
            continue
        closed = len(c) > 2 and np.array_equal(c[0], c[-1])
        pts = c[:-1] if closed else c
        coords = " L ".join(f"{_svg_number(x)} {_svg_number(y)}" for x, y in pts.tolist())
        paths.append(f'  <path d="M {coords}{" Z" if closed else ""}"/>')
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{_svg_number(x0)} {_svg_number(y0)} '
        f'{_svg_number(width)} {_svg_number(height)}" width="800" '
        f'height="{max(1, round(800 * height / width))}">\n'
        "<desc>ipfit zero set. Path coordinates are data coordinates (as in the CSV); the group's transform "
        "mirrors y inside the box so that y points up.</desc>\n"
        f'<g transform="matrix(1 0 0 -1 0 {_svg_number(y0 + y1)})" fill="none" stroke="{stroke}" '
        f'stroke-width="{_svg_number(stroke_width)}" stroke-linejoin="round" stroke-linecap="round">\n'
        + "\n".join(paths) + ("\n" if paths else "")
        + "</g>\n</svg>\n"
    )
    write_text_atomic(path, text)


def write_curves_csv(path: str | os.PathLike, curves) -> None:
    """Write polylines as CSV rows ``curve,x,y`` (closed curves repeat their first point)."""
    lines = ["# ipfit zero set: one row per polyline vertex; 'curve' numbers the polylines",
             "# a closed curve ends with its first point repeated", "curve,x,y"]
    for index, curve in enumerate(curves):
        c = np.asarray(curve, dtype=np.float64)
        lines.extend(f"{index},{x!r},{y!r}" for x, y in c.tolist())
    write_text_atomic(path, "\n".join(lines) + "\n")


def save_zero_set(zero_set, path: str | os.PathLike) -> None:
    """Write a :class:`ipfit.zeroset.extract.ZeroSet` to ``path``, choosing the format by extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if zero_set.dim == 3:
        if suffix not in MESH_FORMATS:
            raise InvalidInputError(f"{path}: a 3D zero set is a mesh; expected an extension in "
                                    f"{', '.join(MESH_FORMATS)}, got {suffix or 'none'!r}. Use e.g. out.ply.")
        write_mesh(path, zero_set.vertices, zero_set.faces)
        return
    if suffix == ".svg":
        write_curves_svg(path, zero_set.curves, zero_set.bounds)
    elif suffix == ".csv":
        write_curves_csv(path, zero_set.curves)
    else:
        raise InvalidInputError(f"{path}: a 2D zero set is a set of curves; expected an extension in "
                                f"{', '.join(CURVE_FORMATS)}, got {suffix or 'none'!r}. Use e.g. out.svg.")

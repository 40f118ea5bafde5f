"""Pictures and zero sets of a scene: every object in one figure, one page, one file.

* :func:`object_zero_sets` — each object's zero set, extracted in its own box (grown by ``margin``);
* :func:`write_zero_sets` — them as one file (a mesh, or curves) or one file per object;
* :func:`plot_scene` — a matplotlib figure: each object's zero set (and points) in its colour;
* :func:`scene_figure` / :func:`write_scene_html` — the plotly viewer: every object its colour,
  each a legend entry (click to hide or show it, double-click to show it alone).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._utils.atomic import write_text_atomic
from .._utils.validation import error
from ..zeroset.export import save_zero_set, write_curves_csv, write_curves_svg, write_mesh
from ..zeroset.extract import ZeroSet, data_bounds, extract_zero_set
from .results import SceneView, load_scene

__all__ = ["COLORS", "object_zero_sets", "write_zero_sets", "plot_scene", "scene_figure", "write_scene_html",
           "object_path"]

#: The objects' colours, in order (matplotlib's tab10, which the viewer also uses).
COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
          "#17becf")
PLANE_COLOR = "#b0b0b0"


def _color(i: int) -> str:
    return COLORS[i % len(COLORS)]


def object_path(path: str | os.PathLike, index: int) -> Path:
    """``OUT-object-I.ext``: object ``index``'s own file beside ``OUT.ext``."""
    path = Path(path)
    return path.with_name(f"{path.stem}-object-{index}{path.suffix}")


def object_zero_sets(scene, margin: float = 0.1, resolution: int | None = None,
                     points: NDArray | None = None, trim=None) -> list[ZeroSet]:
    """Each object's zero set in its own box (``bounding_box`` grown by ``margin`` of its longest side).

    ``points`` and ``trim`` (a distance, or 'auto'): trim each zero set to its own object's points
    (the scene's labels pick them), as ``ipfit fit --trim`` does for one shape.
    """
    view = load_scene(scene)
    labels = view.labels
    out = []
    for i, obj in enumerate(view.objects):
        box = np.asarray(obj.data["bounding_box"], dtype=np.float64)
        zs = extract_zero_set(obj.polynomial, bounds=data_bounds(box, margin), resolution=resolution)
        if trim is not None and points is not None and labels is not None and len(labels) == len(points):
            mine = points[labels == i]
            zs = zs.trimmed(mine, None if trim == "auto" else trim)
        out.append(zs)
    return out


def write_zero_sets(zero_sets: list[ZeroSet], path: str | os.PathLike, *, separate: bool = False) -> list[Path]:
    """Write the objects' zero sets: one file holding all (default), or ``OUT-object-I.ext`` each."""
    path = Path(path)
    if separate:
        written = []
        for i, zs in enumerate(zero_sets):
            if zs.is_empty:
                continue
            save_zero_set(zs, object_path(path, i))
            written.append(object_path(path, i))
        return written
    dim = zero_sets[0].dim
    if dim == 3:
        vertices, faces, offset = [], [], 0
        for zs in zero_sets:
            v, f = zs._mesh()
            vertices.append(v)
            faces.append(np.asarray(f) + offset)
            offset += len(v)
        write_mesh(path, np.vstack(vertices), np.vstack(faces))
    else:
        curves = [c for zs in zero_sets for c in zs.curves]
        if path.suffix.lower() == ".svg":
            box = np.array([[min(zs.bounds[a][0] for zs in zero_sets), max(zs.bounds[a][1] for zs in zero_sets)]
                            for a in range(2)])
            write_curves_svg(path, curves, box)
        elif path.suffix.lower() == ".csv":
            write_curves_csv(path, curves)
        else:
            raise error(str(path), "a file ending in .svg or .csv for 2D curves", repr(path.suffix))
    return [path]


def _scene_box(view: SceneView, points: NDArray | None, margin: float) -> NDArray[np.float64]:
    boxes = [np.asarray(o.data["bounding_box"], dtype=np.float64) for o in view.objects]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    if points is not None and len(points):
        lo, hi = np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0))
    return data_bounds(np.vstack([lo, hi]), margin)


def plot_scene(scene, points: NDArray | None = None, path: str | os.PathLike | None = None, *,
               zero_sets: list[ZeroSet] | None = None, title: str | None = None, margin: float = 0.05,
               view: tuple[float, float] = (25.0, -60.0), up: str = "z", dpi: int = 110):
    """One figure of the whole scene: each object's zero set (and its points) in its colour.

    ``points``: the scan (drawn light grey where not an object's, in the object's colour where the
    scene's labels say so). Returns the figure; saved to ``path`` when given.
    """
    from ..viz.plotting import _pyplot, plot_curve, plot_surface, save_figure

    scene_view = load_scene(scene)
    zero_sets = zero_sets if zero_sets is not None else object_zero_sets(scene_view)
    labels = scene_view.labels
    if points is not None and (labels is None or len(labels) != len(points)):
        labels = None
    plt = _pyplot()
    dim = scene_view.dim
    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(111, projection="3d" if dim == 3 else None)
    box = _scene_box(scene_view, points, margin)
    if points is not None:
        step = max(1, len(points) // 20000)
        shown = np.arange(0, len(points), step)
        other = shown if labels is None else shown[labels[shown] < 0]
        ax.scatter(*points[other].T, s=1.5, color=PLANE_COLOR, alpha=0.5, linewidths=0)
    for i, (obj, zs) in enumerate(zip(scene_view.objects, zero_sets, strict=True)):
        color = _color(i)
        mine = None if points is None or labels is None else points[labels == i]
        label = f"object {i}: degree {obj.polynomial.degree}"
        if dim == 2:
            plot_curve(None, None, ax, zero_set=zs, color=color, label=label)
            if mine is not None and len(mine):
                ax.scatter(*mine[:: max(1, len(mine) // 3000)].T, s=1.5, color=color, alpha=0.35, linewidths=0)
        elif not zs.is_empty:
            plot_surface(None, None, ax, zero_set=zs, color=color, view=view, up=up, max_faces=8000)
            ax.plot([], [], color=color, label=label)
    if dim == 2:
        ax.set_xlim(*box[0])
        ax.set_ylim(*box[1])
        ax.set_aspect("equal")
    else:
        from ..viz.plotting import _frame

        _frame(ax, box, 3, axis_off=False)
    n = len(scene_view.objects)
    ax.legend(loc="best" if dim == 2 else "upper right", fontsize=7, frameon=False)
    ax.set_title(title or f"{n} object{'s' if n != 1 else ''}, each its own polynomial", fontsize=10)
    if path is not None:
        save_figure(fig, path, dpi=dpi)
        plt.close(fig)
    return fig


def scene_figure(scene, points: NDArray | None = None, *, zero_sets: list[ZeroSet] | None = None,
                 title: str | None = None, max_faces: int = 15000):
    """The plotly figure of a scene: per object a legend group (its zero set, its points) in its colour."""
    from ..viz.viewer.figure import _plotly
    from ..viz.viewer.geometry import decimate

    go = _plotly()
    scene_view = load_scene(scene)
    zero_sets = zero_sets if zero_sets is not None else object_zero_sets(scene_view)
    labels = scene_view.labels
    if points is not None and (labels is None or len(labels) != len(points)):
        labels = None
    dim = scene_view.dim
    traces = []
    per_object = max(1000, max_faces // max(1, len(zero_sets)))
    for i, (obj, zs) in enumerate(zip(scene_view.objects, zero_sets, strict=True)):
        color, group = _color(i), f"object {i}"
        note = " (may be two touching objects)" if obj.data.get("touching") else ""
        name = f"object {i}: degree {obj.polynomial.degree}, {obj.data.get('n_points', '?')} points{note}"
        if dim == 3 and not zs.is_empty:
            v, f = zs._mesh()
            v, f, _ = decimate(v, f, per_object)
            traces.append(go.Mesh3d(x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2], color=color,
                                    opacity=0.85, name=name, legendgroup=group, showlegend=True, flatshading=False))
        elif dim == 2:
            first = True
            for c in zs.curves:
                traces.append(go.Scatter(x=c[:, 0], y=c[:, 1], mode="lines", line={"color": color, "width": 2},
                                         name=name, legendgroup=group, showlegend=first))
                first = False
        if points is not None and labels is not None:
            mine = points[labels == i][:: max(1, int(np.sum(labels == i)) // 4000)]
            kind = go.Scatter3d if dim == 3 else go.Scatter
            marker = {"size": 1.5 if dim == 3 else 3, "color": color, "opacity": 0.5}
            traces.append(kind(**dict(zip("xyz", mine.T, strict=False)), mode="markers", marker=marker,
                               name=f"{group} points", legendgroup=group, showlegend=False))
    if points is not None:
        rest = points if labels is None else points[labels < 0]
        rest = rest[:: max(1, len(rest) // 8000)]
        kind = go.Scatter3d if dim == 3 else go.Scatter
        traces.append(kind(**dict(zip("xyz", rest.T, strict=False)), mode="markers",
                           marker={"size": 1 if dim == 3 else 2, "color": PLANE_COLOR, "opacity": 0.4},
                           name="not an object (planes, clutter, outliers)", visible="legendonly"))
    fig = go.Figure(traces)
    n = len(scene_view.objects)
    segmentation = scene_view.segmentation
    fig.update_layout(title={"text": title or f"{n} object{'s' if n != 1 else ''}: "
                             + str(segmentation.get("message", ""))},
                      legend={"itemclick": "toggle", "itemdoubleclick": "toggleothers"})
    if dim == 3:
        fig.update_layout(scene={"aspectmode": "data"})
    else:
        fig.update_yaxes(scaleanchor="x", scaleratio=1)
    return fig


def write_scene_html(scene, points: NDArray | None, path: str | os.PathLike, **kwargs) -> None:
    """Write the scene's viewer page (offline: plotly's JavaScript inlined) to ``path`` atomically."""
    from ..viz.viewer.pages import page

    fig = scene_figure(scene, points, **kwargs)
    div = fig.to_html(full_html=False, include_plotlyjs=True, default_width="100%", default_height="100vh",
                      config={"responsive": True})
    write_text_atomic(path, page(f"ipfit scene: {fig.layout.title.text}", div))

"""Interactive views of a fit: one self-contained HTML page per result (plotly).

The page holds one plotly figure: on the left the data and the zero set of every degree
tried (a rotatable 3D scene, or pannable 2D axes), a slider that switches the degree shown,
the spurious components of each zero set in their own colour and, behind a legend click,
the normals as short segments; on the right why the degree was selected, the per-degree
table and the smoothness (and F-score) against the degree. Hovering a data point shows its
index and the first-order distance |f| / ‖∇f‖ at the degree shown.

plotly's JavaScript is inlined, so the file works offline. Meshes are decimated for display
(:func:`decimate`, vertex clustering) to keep the page small; the table's measures come from
the result, not from the decimated meshes.

:func:`result_figure` builds the figure, :func:`to_html` its HTML (a whole page, or a
``<div>`` for notebooks), :func:`write_html` writes the page atomically. plotly is an
optional dependency (``pip install 'ipfit[viewer]'``), imported only here.

>>> import numpy as np
>>> from ipfit.datasets import synthetic
>>> shape = synthetic.circle(64)
>>> fig = result_figure(shape.polynomial, points=shape.points)
>>> [t.name for t in fig.data][:2]
['data points', 'degree 2']
"""

from __future__ import annotations

import html
import math
import os
import textwrap
from pathlib import Path
from typing import Any, Mapping, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validation import as_normals, as_points, check_choice, check_int, error
from .exceptions import IpfitError
from .plotting import load_result, result_view
from .polynomial import ImplicitPolynomial
from .zeroset import ZeroSet, data_bounds, default_bounds, extract_zero_set

__all__ = ["result_figure", "to_html", "write_html", "decimate", "spurious_flags", "page"]

MAX_FACES = 15000      # per degree: enough to read the shape, small enough for a page
MAX_POINTS = 40000     # data points drawn (every k-th beyond); the full bunny has 35 947
MAX_NORMALS = 1500     # normal segments drawn
SURFACE_COLOR = "#7ea6e0"
SPURIOUS_COLOR = "#e4572e"
CURVE_COLOR = "#1f5fbf"
POINT_COLOR = "#444444"
CURRENT_ROW = "#dbe8ff"
#: What each stop reason of :func:`ipfit.fit_adaptive` means, shown under "why".
REASONS = {
    "criterion": "Algorithm 1: the smoothness gained no more than ε = {epsilon} at the next degree, "
                 "so this degree suffices.",
    "max_degree": "the smoothness still gained more than ε = {epsilon} at the last degree tried, "
                  "so the last degree was taken.",
    "geometric": "the paper's rule chose a degree whose zero set has spurious components or leaves the "
                 "box; the clean degree with the best F-score was taken instead.",
    "interrupted": "the run was interrupted; the rule was applied to the degrees already finished.",
    "incomplete": "the run ended before the rule fired; its last degree was taken.",
}
_RULE_KEYS = ("rule", "reason", "reasons", "why")  # per-degree explanations a result may carry


def _plotly():
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise IpfitError("the viewer needs plotly: pip install 'ipfit[viewer]' (or pip install plotly).") from None
    return go


def _as_dict(result) -> dict:
    if hasattr(result, "to_dict") and not isinstance(result, (Mapping, ImplicitPolynomial)):
        return result.to_dict()  # an AdaptiveResult
    return load_result(result)


# -- geometry for display --------------------------------------------------------------------

def decimate(vertices: ArrayLike, faces: ArrayLike, max_faces: int,
             labels: ArrayLike | None = None) -> tuple[NDArray, NDArray, NDArray]:
    """Vertex clustering: merge the vertices of each cubic cell until at most ``max_faces`` remain.

    Each cell's vertices become their mean; faces that collapse are dropped, as are
    repeated ones. The cell grows until the face count fits, so every vertex moves by at
    most one cell diagonal. ``labels`` (one per face) follow their faces.

    Returns ``(vertices, faces, labels)``.

    >>> import trimesh
    >>> sphere = trimesh.creation.icosphere(subdivisions=4)
    >>> v, f, _ = decimate(sphere.vertices, sphere.faces, 500)
    >>> len(f) <= 500, bool(abs(np.linalg.norm(v, axis=1) - 1).max() < 0.1)
    (True, True)
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    lab = np.zeros(len(f), dtype=np.int64) if labels is None else np.asarray(labels, dtype=np.int64)
    max_faces = check_int(max_faces, "max_faces", minimum=1)
    if len(f) <= max_faces:
        return v, f, lab
    edges = np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1)
    cell = float(np.mean(edges)) * math.sqrt(len(f) / max_faces)
    while True:
        keys = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
        _, cluster = np.unique(keys, axis=0, return_inverse=True)
        cluster = cluster.ravel()
        counts = np.bincount(cluster)
        merged = np.column_stack([np.bincount(cluster, weights=v[:, j]) for j in range(3)]) / counts[:, None]
        g = cluster[f]
        keep = (g[:, 0] != g[:, 1]) & (g[:, 1] != g[:, 2]) & (g[:, 0] != g[:, 2])
        g, kept = g[keep], lab[keep]
        _, first = np.unique(np.sort(g, axis=1), axis=0, return_index=True)
        first.sort()
        if len(first) <= max_faces:
            used, g = np.unique(g[first], return_inverse=True)
            return merged[used], g.reshape(-1, 3), kept[first]
        cell *= 1.25


def spurious_flags(zero_set: ZeroSet, points: ArrayLike, *, faces: ArrayLike | None = None,
                   ordered_contour: bool = False, tau: float | None = None,
                   n_spurious: int | None = None) -> NDArray[np.bool_]:
    """Which components of ``zero_set`` are spurious, by the rule of :func:`ipfit.quality`.

    A component is spurious when no part of it comes within τ of the data. Each component
    is measured by :func:`ipfit.quality` on its own, so the rule is quality's, not a copy.
    ``n_spurious`` (the count a result already records) skips the work when it decides the
    answer: 0, or every component.
    """
    from .quality import quality

    n = zero_set.n_components
    if n_spurious is not None and n_spurious in (0, n):
        return np.full(n, bool(n_spurious))
    flags = np.zeros(n, dtype=bool)
    pieces = zero_set.components()
    for c, piece in enumerate(pieces):
        if zero_set.dim == 2:
            part = ZeroSet(2, zero_set.bounds, zero_set.spacing, zero_set.shape, curves=(piece,))
        else:
            part = ZeroSet(3, zero_set.bounds, zero_set.spacing, zero_set.shape, vertices=piece[0], faces=piece[1])
        flags[c] = quality(part, points, faces=faces, ordered_contour=ordered_contour, tau=tau).n_spurious > 0
    return flags


# -- the figure ------------------------------------------------------------------------------

class _Fit(NamedTuple):
    degree: int
    polynomial: ImplicitPolynomial
    entry: dict


def _fits(data: dict) -> tuple[list[_Fit], int | None]:
    view = result_view(data)
    fits = [_Fit(d.degree, d.polynomial, d.entry) for d in view.degrees if d.polynomial is not None]
    if not fits:  # a plain fit: one degree, its measures at the top level
        entry = {"degree": view.polynomial.degree, **(data.get("measures") or {})}
        if "quality" in data:
            entry["quality"] = data["quality"]
        fits = [_Fit(view.polynomial.degree, view.polynomial, entry)]
    return fits, view.selected


def _fmt(value, digits: int = 4) -> str:
    if isinstance(value, bool) or value is None:
        return "–" if value is None else str(value)
    if isinstance(value, (int, float)) and math.isfinite(value):
        return f"{value:.{digits}g}"
    if isinstance(value, Mapping):
        return "; ".join(f"{k}: {_fmt(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return "; ".join(_fmt(v) for v in value)
    return str(value)


def _rule_text(entry: dict) -> str | None:
    found = [entry[k] for k in _RULE_KEYS if entry.get(k) not in (None, "", [], {})]
    return "; ".join(_fmt(v) for v in found) if found else None


def _why(data: dict, selected: int | None) -> str:
    adaptive = data.get("adaptive") or {}
    reason = adaptive.get("reason")
    if selected is None:
        return "A single fit (no degree selection)."
    text = f"<b>Selected degree {selected}</b>"
    if reason:
        detail = REASONS.get(reason, "").format(epsilon=_fmt(adaptive.get("epsilon")))
        text += f" — {html.escape(str(reason))}" + (f": {detail}" if detail else "")
    rule = adaptive.get("rule")
    if rule:
        text += f" (rule: {html.escape(str(rule))})"
    return "<br>".join(textwrap.wrap(text, 90, break_long_words=False))


def _table(go, fits: list[_Fit], selected: int | None, current: int, visible: bool):
    rules = [_rule_text(f.entry) for f in fits]
    header = ["degree", "dissimilarity", "smoothness", "distance", "F-score", "spurious", "seconds"]
    q = [f.entry.get("quality") or {} for f in fits]
    columns = [[f"{f.degree} ★" if f.degree == selected else str(f.degree) for f in fits],
               [_fmt(f.entry.get("dissimilarity")) for f in fits],
               [_fmt(f.entry.get("smoothness")) for f in fits],
               [_fmt(f.entry.get("distance")) for f in fits],
               [_fmt(x.get("f_score"), 3) for x in q],
               [f"{x['n_spurious']} of {x.get('n_components', '?')}" if "n_spurious" in x else "–" for x in q],
               [_fmt(f.entry.get("seconds"), 3) for f in fits]]
    if any(rules):
        header.append("rule")
        columns.append([r or "" for r in rules])
    fill = [CURRENT_ROW if i == current else "white" for i in range(len(fits))]
    return go.Table(header=dict(values=[f"<b>{h}</b>" for h in header], fill_color="#eeeeee", align="left"),
                    cells=dict(values=columns, fill_color=[fill], align="left", height=24),
                    domain=dict(x=[0.6, 1.0], y=[0.42, 0.86]), visible=visible, name=f"table {fits[current].degree}")


def _zero_set_traces(go, dim: int, zs: ZeroSet, flags: NDArray[np.bool_], degree: int, visible: bool,
                     max_faces: int) -> list:
    traces = []
    if zs.is_empty:
        return traces
    if dim == 2:
        for spurious in (False, True):
            curves = [c for c, s in zip(zs.curves, flags) if s == spurious]
            if not curves:
                continue
            xy = np.concatenate([np.vstack([c, [[np.nan, np.nan]]]) for c in curves])
            traces.append(go.Scatter(x=xy[:, 0], y=xy[:, 1], mode="lines", visible=visible,
                                     line=dict(color=SPURIOUS_COLOR if spurious else CURVE_COLOR, width=2.5),
                                     name=f"degree {degree}" + (" spurious" if spurious else ""),
                                     hovertemplate=f"degree {degree} zero set<extra></extra>"))
        return traces
    face_flags = flags[zs.component_labels]
    for spurious in (False, True):
        sel = zs.faces[face_flags == spurious]
        if not len(sel):
            continue
        # Each class on its own: a small spurious bubble keeps its faces whatever the main sheet needs.
        used, sel = np.unique(sel, return_inverse=True)
        v, f, _ = decimate(zs.vertices[used], sel.reshape(-1, 3), max_faces)
        # A spurious part often sits inside the shape: see through the sheet around it.
        opacity = 1.0 if spurious or not face_flags.any() else 0.45
        traces.append(go.Mesh3d(x=v[:, 0].astype(np.float32), y=v[:, 1].astype(np.float32),
                                z=v[:, 2].astype(np.float32), i=f[:, 0].astype(np.int32),
                                j=f[:, 1].astype(np.int32), k=f[:, 2].astype(np.int32),
                                color=SPURIOUS_COLOR if spurious else SURFACE_COLOR, opacity=opacity,
                                lighting=dict(ambient=0.45, diffuse=0.7, specular=0.15), visible=visible,
                                name=f"degree {degree}" + (" spurious" if spurious else ""), showlegend=True,
                                hovertemplate=f"degree {degree} zero set<extra></extra>"))
    return traces


def _scatter(go, dim: int, xyz: NDArray, **kwargs):
    if dim == 3:
        return go.Scatter3d(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], **kwargs)
    kind = go.Scattergl if len(xyz) > 5000 else go.Scatter
    return kind(x=xyz[:, 0], y=xyz[:, 1], **kwargs)


def _point_template(degree: int, column: int) -> str:
    return f"point %{{customdata[0]}}<br>|f|/‖∇f‖ at degree {degree}: %{{customdata[{column}]:.3g}}<extra></extra>"


def result_figure(result, points: ArrayLike | None = None, *, faces: ArrayLike | None = None,
                  normals: ArrayLike | None = None, ordered_contour: bool | None = None, title: str | None = None,
                  margin: float = 0.25, resolution: int | None = None, max_faces: int = MAX_FACES,
                  max_points: int = MAX_POINTS, up: str = "z"):
    """The interactive figure of a result (a ``plotly.graph_objects.Figure``).

    Parameters
    ----------
    result : result dict (``ipfit fit``'s JSON), path to one, an AdaptiveResult or an
        ImplicitPolynomial.
    points : (N, dim) data: drawn, hoverable, framing the box and finding the spurious
        components. Without it the box comes from the result's ``bounds`` (or its
        normalisation) and spurious components are not marked.
    faces : the data's triangles, when a mesh (the spurious test then measures to them).
    normals : (N, dim) normals, drawn as short segments (hidden until clicked in the legend).
    ordered_contour : 2D points in order along a contour (default: detected).
    margin, resolution : the box and grid of :func:`ipfit.extract_zero_set` (default the
        same as the fit's quality measures, so the components match its counts).
    max_faces : faces per degree after :func:`decimate`.
    max_points : data points drawn (every k-th beyond).
    up : 3D: the axis pointing up on screen ('x', 'y' or 'z'; the bunny is y-up).
    """
    go = _plotly()
    data = _as_dict(result)
    fits, selected = _fits(data)
    dim = fits[0].polynomial.dim
    up = check_choice(up, "up", ("x", "y", "z"))
    max_points = check_int(max_points, "max_points", minimum=1)
    pts = None if points is None else as_points(points, dims=(dim,), min_points=2)
    if pts is not None:
        box = data_bounds(pts, margin)
    elif data.get("bounds") is not None:
        box = data_bounds(np.asarray(data["bounds"], dtype=np.float64).reshape(dim, 2).T, margin)
    else:
        box = default_bounds(fits[0].polynomial, margin)
    if pts is not None and ordered_contour is None:
        from .quality import looks_like_contour

        ordered_contour = dim == 2 and looks_like_contour(pts)
    current = next((i for i, f in enumerate(fits) if f.degree == selected), len(fits) - 1)

    traces, owner = [], []  # owner: index of the degree a trace belongs to; -1 always shown; None not switched

    def add(trace, who):
        traces.append(trace)
        owner.append(who)

    if pts is not None:
        stride = max(1, math.ceil(len(pts) / max_points))
        index = np.arange(0, len(pts), stride)
        custom = np.column_stack([index] + [f.polynomial.taubin_distance(pts[index]) for f in fits])
        marker = dict(size=1.0 if dim == 3 else 3, color=POINT_COLOR if dim == 3 else "#8c8c8c",
                      opacity=0.5 if dim == 3 else 1.0)
        add(_scatter(go, dim, pts[index].astype(np.float32), mode="markers", marker=marker, name="data points",
                     customdata=custom.astype(np.float32),
                     hovertemplate=_point_template(fits[current].degree, current + 1)), -1)
    for i, fit in enumerate(fits):
        zs = extract_zero_set(fit.polynomial, bounds=box, resolution=resolution)
        q = fit.entry.get("quality") or {}
        flags = np.zeros(zs.n_components, dtype=bool)
        if pts is not None:
            flags = spurious_flags(zs, pts, faces=faces, ordered_contour=bool(ordered_contour), tau=q.get("tau"),
                                   n_spurious=q.get("n_spurious"))
        for trace in _zero_set_traces(go, dim, zs, flags, fit.degree, i == current, max_faces):
            add(trace, i)
    if normals is not None and pts is not None:
        unit = as_normals(normals, pts)
        pick = np.arange(0, len(pts), max(1, math.ceil(len(pts) / MAX_NORMALS)))
        length = 0.04 * float(np.linalg.norm(np.ptp(pts, axis=0)))
        ends = pts[pick] + length * unit[pick]
        seg = np.stack([pts[pick], ends, np.full_like(ends, np.nan)], axis=1).reshape(-1, dim)
        add(_scatter(go, dim, seg.astype(np.float32), mode="lines", line=dict(color="#2a9d8f", width=2),
                     name="normals", visible="legendonly", hoverinfo="skip"), None)

    smooth = [f.entry.get("smoothness") for f in fits]
    fscore = [(f.entry.get("quality") or {}).get("f_score") for f in fits]
    degrees = [f.degree for f in fits]
    chart = dict(xaxis="x2", yaxis="y2")
    add(go.Scatter(x=degrees, y=smooth, mode="lines+markers", name="smoothness", line=dict(color="#333333"),
                   **chart), -1)
    if any(v is not None for v in fscore):
        add(go.Scatter(x=degrees, y=fscore, mode="lines+markers", name="F-score",
                       line=dict(color="#2a9d8f", dash="dash"), **chart), -1)
    if selected in degrees:
        add(go.Scatter(x=[selected], y=[smooth[degrees.index(selected)]], mode="markers", name="selected",
                       marker=dict(symbol="star", size=14, color="#d62728"), **chart), -1)
    for i, fit in enumerate(fits):
        add(go.Scatter(x=[fit.degree], y=[smooth[i]], mode="markers", showlegend=False, visible=i == current,
                       marker=dict(size=18, color="rgba(0,0,0,0)", line=dict(color=CURVE_COLOR, width=2)),
                       hoverinfo="skip", **chart), i)
        add(_table(go, fits, selected, i, i == current), i)

    fig = go.Figure(traces)
    name = title or (data.get("input") or {}).get("source") or "ipfit result"
    switched = [t for t, who in enumerate(owner) if who is not None]
    steps = []
    for i, fit in enumerate(fits):
        templates = [_point_template(fit.degree, i + 1) if t == 0 and pts is not None
                     else getattr(traces[t], "hovertemplate", None) for t in switched]
        visible = [owner[t] in (-1, i) for t in switched]
        steps.append(dict(label=str(fit.degree), method="update",
                          args=[{"visible": visible, "hovertemplate": templates},
                                {"title.text": f"{html.escape(str(name))}: degree {fit.degree}"}, switched]))
    fig.update_layout(
        title=dict(text=f"{html.escape(str(name))}: degree {fits[current].degree}", x=0.02),
        sliders=[dict(active=current, steps=steps, currentvalue=dict(prefix="degree shown: "),
                      x=0.02, len=0.5, y=0.02, pad=dict(t=10))],
        xaxis2=dict(domain=[0.66, 0.86], anchor="y2", title="degree", tickvals=degrees),
        yaxis2=dict(domain=[0.06, 0.34], anchor="x2", title="smoothness / F-score"),
        legend=dict(x=0.88, y=0.36, yanchor="top"),
        margin=dict(l=20, r=20, t=60, b=20), template="plotly_white", hovermode="closest",
        annotations=[dict(text=_why(data, selected), x=0.6, y=0.97, xref="paper", yref="paper", showarrow=False,
                          xanchor="left", yanchor="top", align="left")])
    if dim == 3:
        camera_up = dict(zip("xyz", (float(a == up) for a in "xyz")))
        fig.update_layout(scene=dict(domain=dict(x=[0.0, 0.58], y=[0.1, 1.0]), aspectmode="data",
                                     camera=dict(up=camera_up), **{f"{a}axis": dict(range=list(box[j]))
                                                                 for j, a in enumerate("xyz")}))
    else:
        fig.update_layout(xaxis=dict(domain=[0.0, 0.58], range=list(box[0])),
                          yaxis=dict(domain=[0.12, 1.0], range=list(box[1]), scaleanchor="x"))
    return fig


# -- HTML ------------------------------------------------------------------------------------

def page(title: str, body: str) -> str:
    """A minimal standalone HTML page around ``body`` (the viewer's, and a future index page's)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title>"
            "<style>html,body{margin:0;height:100%;font-family:sans-serif}</style></head>\n"
            f"<body>{body}</body></html>\n")


def to_html(result, points: ArrayLike | None = None, *, full_html: bool = True, include_plotlyjs=True,
            **kwargs) -> str:
    """The viewer as HTML: a whole offline page, or with ``full_html=False`` a ``<div>`` (notebooks).

    ``include_plotlyjs=True`` inlines plotly's JavaScript (offline, ~4.8 MB); other values
    are passed to plotly (e.g. ``"cdn"``). ``kwargs`` go to :func:`result_figure`.
    """
    fig = result_figure(result, points, **kwargs)
    div = fig.to_html(full_html=False, include_plotlyjs=include_plotlyjs, default_width="100%",
                      default_height="100vh" if full_html else "720px", config={"responsive": True})
    if not full_html:
        return div
    return page(f"ipfit viewer: {fig.layout.title.text}", div)


def write_html(result, points: ArrayLike | None, path: str | os.PathLike, **kwargs) -> None:
    """Write the viewer page of ``result`` to ``path`` atomically (see :func:`result_figure`)."""
    from ._atomic import write_text_atomic

    # Checked before the figure is built: a big result takes seconds to draw.
    if not str(path).lower().endswith((".html", ".htm")):
        raise error("path", "a file name ending in .html", repr(str(path)), "Name the page e.g. view.html.")
    folder = Path(path).parent
    if not folder.is_dir():
        raise error("path", "a file in an existing folder", f"{str(path)!r}", f"Create {folder} first.")
    write_text_atomic(path, to_html(result, points, **kwargs))

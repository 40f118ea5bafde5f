"""The interactive plotly figure of a result; see :mod:`ipfit.viz.viewer`."""

from __future__ import annotations

import html
import math
import textwrap
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._utils.validation import as_faces, as_normals, as_points, check_choice, check_int, check_positive, error
from ...degree.results import ResultView, result_view
from ...exceptions import IpfitError
from ...polynomial import ImplicitPolynomial
from ...zeroset.extract import ZeroSet, data_bounds, default_bounds, extract_zero_set
from ..plotting import OUTLIER_COLOR, without_outliers
from .geometry import decimate, spurious_flags

__all__ = ["result_figure", "OUTLIER_COLOR"]

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
    "captured": "the shape was captured: a clean degree reached an F-score within the tolerance of 1; the "
                "lowest clean degree within that tolerance of the best F-score was taken.",
    "flattened": "several degrees in a row gained nothing substantial (smoothness, F-score, recall, "
                 "distances); the lowest clean degree within the tolerance of the best F-score was taken.",
    "no_f_gain": "a degree above the usual highest (8 in 3D) is tried only after one that raised the best clean "
                 "F-score substantially and left it below 0.95, and the last degree did not; the lowest clean "
                 "degree within the tolerance of the best F-score was taken.",
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


def _as_view(result) -> ResultView:
    if hasattr(result, "to_dict") and not isinstance(result, (Mapping, ImplicitPolynomial)):
        return result_view(result.to_dict())  # an AdaptiveResult
    return result_view(result)  # a ResultView as it is: a warning names its file


class _Fit(NamedTuple):
    degree: int
    polynomial: ImplicitPolynomial
    entry: Mapping[str, Any]


def _fits(view: ResultView, data: dict) -> tuple[list[_Fit], int | None]:
    fits = [_Fit(d.degree, d.polynomial, d.entry) for d in view.degrees if d.polynomial is not None]
    if not fits:  # a plain fit: one degree, its measures at the top level
        entry = {"degree": view.polynomial.degree, **(data.get("measures") or {})}
        if "quality" in data:
            entry["quality"] = data["quality"]
        fits = [_Fit(view.polynomial.degree, view.polynomial, entry)]
    return fits, view.selected_degree


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


def _rule_text(entry: Mapping[str, Any]) -> str | None:
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
    traces: list[Any] = []  # plotly traces
    if zs.is_empty:
        return traces
    if dim == 2:
        for spurious in (False, True):
            curves = [c for c, s in zip(zs.curves, flags, strict=True) if s == spurious]
            if not curves:
                continue
            xy = np.concatenate([np.vstack([c, [[np.nan, np.nan]]]) for c in curves])
            traces.append(go.Scatter(x=xy[:, 0], y=xy[:, 1], mode="lines", visible=visible,
                                     line=dict(color=SPURIOUS_COLOR if spurious else CURVE_COLOR, width=2.5),
                                     name=f"degree {degree}" + (" spurious" if spurious else ""),
                                     hovertemplate=f"degree {degree} zero set<extra></extra>"))
        return traces
    vertices, faces = zs._mesh()
    face_flags = flags[zs.component_labels]
    for spurious in (False, True):
        sel = faces[face_flags == spurious]
        if not len(sel):
            continue
        # Each class on its own: a small spurious bubble keeps its faces whatever the main sheet needs.
        used, sel = np.unique(sel, return_inverse=True)
        v, f, _ = decimate(vertices[used], sel.reshape(-1, 3), max_faces)
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


def _points_traces(go, pts: NDArray, outliers: NDArray[np.bool_] | None, fits: list[_Fit], current: int,
                   max_points: int) -> list:
    """The data points, and the outliers (when marked) as a trace of their own, "outliers (N)".

    Every k-th point of each kind beyond ``max_points`` in all; the hover shows a point's
    index in the data, whichever trace it is in.
    """
    dim = pts.shape[1]
    stride = max(1, math.ceil(len(pts) / max_points))
    marked = np.zeros(len(pts), dtype=bool) if outliers is None else outliers
    kinds = [("data points", np.flatnonzero(~marked)[::stride],
              dict(size=1.0 if dim == 3 else 3, color=POINT_COLOR if dim == 3 else "#8c8c8c",
                   opacity=0.5 if dim == 3 else 1.0))]
    if marked.any():
        kinds.append((f"outliers ({int(marked.sum())})", np.flatnonzero(marked)[::stride],
                      dict(size=2.5 if dim == 3 else 5, color=OUTLIER_COLOR, opacity=0.9 if dim == 3 else 1.0)))
    traces = []
    for name, index, marker in kinds:
        if not len(index):
            continue
        custom = np.column_stack([index] + [f.polynomial.taubin_distance(pts[index]) for f in fits])
        traces.append(_scatter(go, dim, pts[index].astype(np.float32), mode="markers", marker=marker, name=name,
                               customdata=custom.astype(np.float32),
                               hovertemplate=_point_template(fits[current].degree, current + 1)))
    return traces


def _normals_trace(go, pts: NDArray, unit: NDArray):
    pick = np.arange(0, len(pts), max(1, math.ceil(len(pts) / MAX_NORMALS)))
    length = 0.04 * float(np.linalg.norm(np.ptp(pts, axis=0)))
    ends = pts[pick] + length * unit[pick]
    seg = np.stack([pts[pick], ends, np.full_like(ends, np.nan)], axis=1).reshape(-1, pts.shape[1])
    return _scatter(go, pts.shape[1], seg.astype(np.float32), mode="lines", line=dict(color="#2a9d8f", width=2),
                    name="normals", visible="legendonly", hoverinfo="skip")


def _chart_traces(go, fits: list[_Fit], selected: int | None, current: int) -> list[tuple[Any, int]]:
    smooth = [f.entry.get("smoothness") for f in fits]
    fscore = [(f.entry.get("quality") or {}).get("f_score") for f in fits]
    degrees = [f.degree for f in fits]
    chart = dict(xaxis="x2", yaxis="y2")
    out = [(go.Scatter(x=degrees, y=smooth, mode="lines+markers", name="smoothness", line=dict(color="#333333"),
                       **chart), -1)]
    if any(v is not None for v in fscore):
        out.append((go.Scatter(x=degrees, y=fscore, mode="lines+markers", name="F-score",
                               line=dict(color="#2a9d8f", dash="dash"), **chart), -1))
    if selected in degrees:
        out.append((go.Scatter(x=[selected], y=[smooth[degrees.index(selected)]], mode="markers", name="selected",
                               marker=dict(symbol="star", size=14, color="#d62728"), **chart), -1))
    for i, fit in enumerate(fits):  # the ring on the degree shown, and the table with its row lit
        out.append((go.Scatter(x=[fit.degree], y=[smooth[i]], mode="markers", showlegend=False,
                               visible=i == current, hoverinfo="skip", **chart,
                               marker=dict(size=18, color="rgba(0,0,0,0)", line=dict(color=CURVE_COLOR, width=2))),
                    i))
        out.append((_table(go, fits, selected, i, i == current), i))
    return out


def result_figure(result, points: ArrayLike | None = None, *, faces: ArrayLike | None = None,
                  normals: ArrayLike | None = None, ordered_contour: bool | None = None, title: str | None = None,
                  margin: float = 0.25, resolution: int | None = None, max_faces: int = MAX_FACES,
                  max_points: int = MAX_POINTS, up: str = "z", trim: float | None = None):
    """The interactive figure of a result (a ``plotly.graph_objects.Figure``).

    Parameters
    ----------
    result : result dict (``ipfit fit``'s JSON), path to one, a
        :class:`~ipfit.degree.results.ResultView`, an AdaptiveResult or an ImplicitPolynomial.
    points : (N, dim) data: drawn, hoverable, framing the box and finding the spurious
        components. Without it the box comes from the result's ``bounds`` (or its
        normalisation) and spurious components are not marked.
    faces : the data's triangles, when a mesh (the spurious test then measures to them).
    normals : (N, dim) normals, drawn as short segments (hidden until clicked in the legend).

    When the result records outliers and ``points`` are the points it fitted, the outliers
    are a trace of their own, "outliers (N)", in :data:`OUTLIER_COLOR` (click it in the
    legend to hide them), and spurious components are judged against the other points;
    when the rows cannot be the fitted ones, a warning says why and every point is drawn as
    data (the rule of :func:`ipfit.viz.plotting.plot_result`).
    ordered_contour : 2D points in order along a contour (default: detected).
    margin, resolution : the box and grid of :func:`ipfit.extract_zero_set` (default the
        same as the fit's quality measures, so the components match its counts).
    max_faces : faces per degree after :func:`decimate`.
    max_points : data points drawn (every k-th beyond).
    up : 3D: the axis pointing up on screen ('x', 'y' or 'z'; the bunny is y-up).
    trim : draw only the parts of each zero set within this distance of the data
        (:meth:`ipfit.zeroset.extract.ZeroSet.trimmed`, as ``ipfit fit --trim`` exports them; needs
        ``points``); the polynomial is unchanged.
    """
    go = _plotly()
    view = _as_view(result)
    data = dict(view.data)
    fits, selected = _fits(view, data)
    dim = fits[0].polynomial.dim
    up = check_choice(up, "up", ("x", "y", "z"))
    max_points = check_int(max_points, "max_points", minimum=1)
    pts = None if points is None else as_points(points, dims=(dim,), min_points=2)
    if trim is not None:
        trim = check_positive(trim, "trim")
        if pts is None:
            raise error("points", "the data to trim the zero sets to", "None", "Pass points or drop trim.")
    if pts is not None:
        box = data_bounds(pts, margin)
    elif data.get("bounds") is not None:
        box = data_bounds(np.asarray(data["bounds"], dtype=np.float64).reshape(dim, 2).T, margin)
    else:
        box = default_bounds(fits[0].polynomial, margin)
    outliers = None if pts is None else view.outlier_mask(len(pts))  # warns once when the rows do not match
    if outliers is not None and outliers.all():
        outliers = None  # nothing left to call the data: draw it as data
    # kept: the data the fit kept (every point, or the inliers), which spurious pieces are judged against
    kept, kept_faces = pts, faces
    if pts is not None and outliers is not None:
        kept, kept_faces = without_outliers(pts, None if faces is None else as_faces(faces, len(pts)), outliers)
    if kept is not None and ordered_contour is None:
        from ...zeroset.quality import looks_like_contour

        ordered_contour = dim == 2 and looks_like_contour(kept)
    current = next((i for i, f in enumerate(fits) if f.degree == selected), len(fits) - 1)

    # (trace, owner): owner is the index of the degree the trace belongs to, -1 for a trace
    # always shown, None for one the slider leaves alone (the normals, toggled in the legend)
    layers: list[tuple[Any, int | None]] = []
    if pts is not None:
        layers += [(t, -1) for t in _points_traces(go, pts, outliers, fits, current, max_points)]
    n_point_traces = len(layers)
    for i, fit in enumerate(fits):
        zs = extract_zero_set(fit.polynomial, bounds=box, resolution=resolution)
        q = fit.entry.get("quality") or {}
        recorded = q.get("n_spurious")
        if trim is not None and pts is not None:  # pts is always set with trim (checked above)
            zs = zs.trimmed(pts, trim, faces=faces)
            # trimming splits components: a recorded count no longer matches them, unless it is 0
            recorded = 0 if recorded == 0 else None
        flags = np.zeros(zs.n_components, dtype=bool)
        if kept is not None:
            flags = spurious_flags(zs, kept, faces=kept_faces, ordered_contour=bool(ordered_contour),
                                   tau=q.get("tau"), n_spurious=recorded)
        layers += [(t, i) for t in _zero_set_traces(go, dim, zs, flags, fit.degree, i == current, max_faces)]
    if normals is not None and pts is not None:
        layers.append((_normals_trace(go, pts, as_normals(normals, pts)), None))
    layers += _chart_traces(go, fits, selected, current)
    traces, owner = [t for t, _ in layers], [who for _, who in layers]
    fig = go.Figure(traces)
    name = title or (data.get("input") or {}).get("source") or "ipfit result"
    switched = [t for t, who in enumerate(owner) if who is not None]
    steps = []
    for i, fit in enumerate(fits):
        templates = [_point_template(fit.degree, i + 1) if t < n_point_traces
                     else getattr(traces[t], "hovertemplate", None) for t in switched]
        visible = [owner[t] in (-1, i) for t in switched]
        steps.append(dict(label=str(fit.degree), method="update",
                          args=[{"visible": visible, "hovertemplate": templates},
                                {"title.text": f"{html.escape(str(name))}: degree {fit.degree}"}, switched]))
    fig.update_layout(
        title=dict(text=f"{html.escape(str(name))}: degree {fits[current].degree}", x=0.02),
        sliders=[dict(active=current, steps=steps, currentvalue=dict(prefix="degree shown: "),
                      x=0.02, len=0.5, y=0.02, pad=dict(t=10))],
        xaxis2=dict(domain=[0.66, 0.86], anchor="y2", title="degree", tickvals=[f.degree for f in fits]),
        yaxis2=dict(domain=[0.06, 0.34], anchor="x2", title="smoothness / F-score"),
        legend=dict(x=0.88, y=0.36, yanchor="top"),
        margin=dict(l=20, r=20, t=60, b=20), template="plotly_white", hovermode="closest",
        annotations=[dict(text=_why(data, selected), x=0.6, y=0.97, xref="paper", yref="paper", showarrow=False,
                          xanchor="left", yanchor="top", align="left")])
    if dim == 3:
        camera_up = dict(zip("xyz", (float(a == up) for a in "xyz"), strict=True))
        fig.update_layout(scene=dict(domain=dict(x=[0.0, 0.58], y=[0.1, 1.0]), aspectmode="data",
                                     camera=dict(up=camera_up), **{f"{a}axis": dict(range=list(box[j]))
                                                                 for j, a in enumerate("xyz")}))
    else:
        fig.update_layout(xaxis=dict(domain=[0.0, 0.58], range=list(box[0])),
                          yaxis=dict(domain=[0.12, 1.0], range=list(box[1]), scaleanchor="x"))
    return fig

"""Figures of fits, in the manner of the paper's Figs. 8–13 (matplotlib, no display needed).

Every plotting function takes ``ax=None`` and returns the axes it drew on; with no axes it
makes a new figure through pyplot (on the Agg backend when there is no display).
:func:`plot_result` builds a whole multi-panel figure (the points, the zero set of every
degree tried, the smoothness-versus-degree curve, the classic and 3L fits at the selected
degree) without touching pyplot's global state, and can save it atomically.

matplotlib is imported only when a function here is called.
"""

from __future__ import annotations

import math
import os
import sys
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validation import as_points, error
from .exceptions import InvalidInputError, ReadError
from .polynomial import ImplicitPolynomial, Normalization
from .zeroset import ZeroSet, data_bounds, default_bounds, extract_zero_set

__all__ = [
    "plot_curve",
    "plot_surface",
    "plot_points",
    "plot_smoothness",
    "plot_result",
    "save_figure",
    "load_result",
    "ResultView",
    "result_view",
]

CURVE_COLOR = "#1f5fbf"
SURFACE_COLOR = (0.55, 0.70, 0.92)
POINT_COLOR = "0.45"
METHOD_TITLES = {"lstsq": "classic linear", "3l": "3L", "ridge": "3L + ridge", "taubin": "Taubin",
                 "gradient_one": "gradient-one", "de": "DE", "pso": "PSO", "de+polish": "DE + polish",
                 "pso+polish": "PSO + polish", "polish": "polish (L-BFGS from the best seed)"}
_PLOT_RESOLUTION = {2: 400, 3: 72}


def _method_label(name) -> str | None:
    if not name:
        return None
    return METHOD_TITLES.get(str(name).lower(), str(name))


# -- matplotlib access ---------------------------------------------------------------------

def _pyplot():
    import matplotlib

    headless = sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless and "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _new_axes(dim: int):
    plt = _pyplot()
    if dim == 3:
        import mpl_toolkits.mplot3d  # noqa: F401  registers the 3d projection

        fig = plt.figure(figsize=(5, 5))
        return fig.add_subplot(projection="3d")
    _, ax = plt.subplots(figsize=(5, 5))
    return ax


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> None:
    """Save a matplotlib figure atomically; the format follows the extension."""
    from ._atomic import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)


# -- single panels -------------------------------------------------------------------------

def _zero_set_for(poly, zero_set, points, bounds, margin, resolution) -> ZeroSet:
    if zero_set is not None:
        return zero_set
    if not isinstance(poly, ImplicitPolynomial):
        raise error("poly", "an ImplicitPolynomial", type(poly).__name__)
    return extract_zero_set(poly, bounds=bounds, points=points, margin=margin,
                            resolution=resolution or _PLOT_RESOLUTION[poly.dim])


def plot_points(points: ArrayLike, ax=None, *, max_points: int = 4000, size: float | None = None,
                color=POINT_COLOR, **kwargs):
    """Scatter the data (every k-th point beyond ``max_points``); returns ``ax``."""
    pts = as_points(points)
    if ax is None:
        ax = _new_axes(pts.shape[1])
    stride = max(1, math.ceil(len(pts) / max_points))
    shown = pts[::stride]
    if pts.shape[1] == 3:
        ax.scatter(shown[:, 0], shown[:, 1], shown[:, 2], s=size if size is not None else 1.0, c=color,
                   alpha=0.5, depthshade=False, linewidths=0, **kwargs)
    else:
        ax.scatter(shown[:, 0], shown[:, 1], s=size if size is not None else 3.0, c=color, linewidths=0,
                   zorder=1, **kwargs)
    return ax


def _camera(ax, view: tuple[float, float], up: str) -> None:
    from ._validation import check_choice

    ax.view_init(elev=view[0], azim=view[1], vertical_axis=check_choice(up, "up", ("x", "y", "z")))


def _frame(ax, bounds: NDArray, dim: int, axis_off: bool) -> None:
    ax.set_xlim(*bounds[0])
    ax.set_ylim(*bounds[1])
    if dim == 3:
        ax.set_zlim(*bounds[2])
        ax.set_box_aspect(tuple(np.ptp(bounds, axis=1)), zoom=1.15)  # 3D axes leave wide margins
    else:
        ax.set_aspect("equal")
    if axis_off:
        ax.set_axis_off()


def plot_curve(poly: ImplicitPolynomial | None, points: ArrayLike | None = None, ax=None, *,
               zero_set: ZeroSet | None = None, bounds: ArrayLike | None = None, margin: float = 0.25,
               resolution: int | None = None, color=CURVE_COLOR, linewidth: float = 1.6, label: str | None = None,
               axis_off: bool = False):
    """Draw the zero set of a 2D polynomial (and the data points, if given); returns ``ax``.

    Parameters
    ----------
    poly : 2D polynomial (may be None when ``zero_set`` is given).
    points : data points to draw underneath, and to choose the box from.
    zero_set : an already extracted zero set to draw instead of extracting one.
    bounds, margin, resolution : see :func:`ipfit.zeroset.extract_zero_set`.
    """
    pts = None if points is None else as_points(points, dims=(2,))
    zs = _zero_set_for(poly, zero_set, pts, bounds, margin, resolution)
    if zs.dim != 2:
        raise error("poly", "a 2D polynomial (use plot_surface for 3D)", f"a {zs.dim}D one")
    if ax is None:
        ax = _new_axes(2)
    if pts is not None:
        plot_points(pts, ax)
    for i, curve in enumerate(zs.curves):
        ax.plot(curve[:, 0], curve[:, 1], color=color, lw=linewidth, zorder=2, label=label if i == 0 else None)
    _frame(ax, zs.bounds, 2, axis_off)
    return ax


def _shaded_colors(vertices: NDArray, faces: NDArray, color, light=(0.35, -0.45, 0.82)) -> NDArray:
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals / np.where(length > 0, length, 1.0)
    direction = np.asarray(light, dtype=float) / np.linalg.norm(light)
    # Two-sided Lambert shading: the mesh's orientation does not matter for the picture.
    intensity = 0.3 + 0.7 * np.abs(normals @ direction)
    rgb = np.clip(np.asarray(color, dtype=float)[None, :3] * intensity[:, None], 0, 1)
    return np.column_stack([rgb, np.ones(len(rgb))])


def plot_surface(poly: ImplicitPolynomial | None, points: ArrayLike | None = None, ax=None, *,
                 zero_set: ZeroSet | None = None, bounds: ArrayLike | None = None, margin: float = 0.25,
                 resolution: int | None = None, max_faces: int = 30000, color=SURFACE_COLOR,
                 show_points: bool = False, view: tuple[float, float] = (20.0, -60.0), up: str = "z",
                 axis_off: bool = False):
    """Draw the zero set of a 3D polynomial as a shaded mesh; returns ``ax`` (a 3D axes).

    Parameters
    ----------
    poly : 3D polynomial (may be None when ``zero_set`` is given).
    points : data, used to choose the box, and drawn when ``show_points``.
    zero_set : an already extracted zero set.
    max_faces : a mesh with more faces is re-extracted on a coarser grid (matplotlib
        draws every face as a polygon; beyond some 10⁴ faces it only gets slower).
    view : (elevation, azimuth) in degrees.
    up : the axis drawn vertically, 'x', 'y' or 'z' (scanned meshes such as the bunny are y-up).
    """
    pts = None if points is None else as_points(points, dims=(3,))
    zs = _zero_set_for(poly, zero_set, pts, bounds, margin, resolution)
    if zs.dim != 3:
        raise error("poly", "a 3D polynomial (use plot_curve for 2D)", f"a {zs.dim}D one")
    if not zs.is_empty and len(zs.faces) > max_faces and zs.polynomial is not None:
        coarser = max(8, int(max(zs.shape) * math.sqrt(max_faces / len(zs.faces))))
        zs = extract_zero_set(zs.polynomial, bounds=zs.bounds, resolution=coarser)
    if ax is None:
        ax = _new_axes(3)
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if not zs.is_empty:
        faces = zs.faces
        if len(faces) > max_faces:  # no polynomial to re-extract from: thin out evenly
            faces = faces[:: math.ceil(len(faces) / max_faces)]
        # Without antialiasing, neighbouring faces leave no hairline seams between them.
        collection = Poly3DCollection(zs.vertices[faces], facecolors=_shaded_colors(zs.vertices, faces, color),
                                      edgecolors="none", linewidths=0, antialiased=False)
        ax.add_collection3d(collection)
    if show_points and pts is not None:
        plot_points(pts, ax)
    _camera(ax, view, up)
    _frame(ax, zs.bounds, 3, axis_off)
    return ax


def plot_smoothness(degrees: Sequence[int], smoothness: Sequence[float], selected: int | None = None, ax=None, *,
                    color="#333333"):
    """The smoothness measure against the degree (the paper's Figs. 4 and 8c); returns ``ax``."""
    deg = np.asarray(degrees, dtype=float)
    sm = np.asarray(smoothness, dtype=float)
    if deg.shape != sm.shape or deg.ndim != 1:
        raise error("smoothness", f"{deg.size} values, one per degree", f"{sm.size} values")
    if ax is None:
        ax = _new_axes(2)
    ax.plot(deg, sm, "o-", color=color, lw=1.4, ms=5)
    if selected is not None and np.any(deg == selected):
        k = int(np.flatnonzero(deg == selected)[0])
        ax.plot([deg[k]], [sm[k]], "o", ms=11, mfc="none", mec="#d62728", mew=2, label=f"selected: {selected}")
        ax.legend(loc="lower right", fontsize="small", frameon=False)
    ax.set_xticks(deg)
    ax.set_xlabel("degree")
    ax.set_ylabel("smoothness")
    ax.grid(alpha=0.3)
    return ax


# -- results -------------------------------------------------------------------------------

def load_result(result: Mapping[str, Any] | str | os.PathLike | ImplicitPolynomial) -> dict:
    """A result as a dict: from a JSON path, a dict, or an :class:`ImplicitPolynomial`."""
    if isinstance(result, ImplicitPolynomial):
        return result.to_dict()
    if isinstance(result, Mapping):
        return dict(result)
    if isinstance(result, (str, os.PathLike)):
        from .polynomial import read_result_json

        return read_result_json(result)
    raise error("result", "a result dict, a path to a result JSON or an ImplicitPolynomial", type(result).__name__)


class DegreeFit(NamedTuple):
    degree: int
    polynomial: ImplicitPolynomial | None
    entry: dict


class ResultView(NamedTuple):
    """The polynomials of a result JSON, whether a plain fit or an adaptive run."""

    polynomial: ImplicitPolynomial
    degrees: list[DegreeFit]
    selected: int | None
    comparisons: dict[str, ImplicitPolynomial]
    bounds: NDArray[np.float64] | None


def result_view(result, source: str = "result") -> ResultView:
    """Read the final polynomial, the per-degree fits and the comparison fits of a result."""
    data = load_result(result)
    try:
        poly = ImplicitPolynomial.from_dict(data, source=source)
    except InvalidInputError as exc:
        raise ReadError(str(exc)) from None
    norm: Normalization = poly.normalization

    def build(coefficients, what: str, own_norm=None) -> ImplicitPolynomial:
        # Entries share the top-level normalisation unless they carry their own.
        try:
            entry_norm = norm if not own_norm else Normalization(own_norm["center"], own_norm["scale"])
            return ImplicitPolynomial.from_coefficients(coefficients, poly.dim, normalization=entry_norm)
        except (InvalidInputError, TypeError, ValueError, KeyError) as exc:
            raise ReadError(f"{source}: malformed {what} ({exc}). Regenerate the result with ipfit.") from None

    degrees = []
    for entry in data.get("degrees") or []:
        if not isinstance(entry, Mapping) or "degree" not in entry:
            raise ReadError(f"{source}: malformed \"degrees\" entry (no \"degree\"). Regenerate the result with ipfit.")
        fit = build(entry["coefficients"], f"coefficients of degree {entry['degree']}", entry.get("normalization")) \
            if entry.get("coefficients") is not None else None
        degrees.append(DegreeFit(int(entry["degree"]), fit, dict(entry)))
    comparisons = {}
    for name, entry in (data.get("comparisons") or {}).items():
        if isinstance(entry, Mapping) and entry.get("coefficients") is not None:
            comparisons[str(name)] = build(entry["coefficients"], f"comparison {name!r}", entry.get("normalization"))
    selected = data.get("selected_degree")
    bounds = data.get("bounds")
    if bounds is not None:
        try:
            bounds = np.asarray(bounds, dtype=np.float64).reshape(poly.dim, 2)
        except (TypeError, ValueError):
            bounds = None
    return ResultView(poly, degrees, int(selected) if selected is not None else None, comparisons, bounds)


def _panel_bounds(view: ResultView, points: NDArray | None, margin: float) -> NDArray:
    if points is not None:
        return data_bounds(points, margin)
    if view.bounds is not None:
        return data_bounds(view.bounds.T, margin)
    return default_bounds(view.polynomial, margin)


def plot_result(result, points: ArrayLike | None = None, path: str | os.PathLike | None = None, *,
                title: str | None = None, margin: float = 0.25, resolution: int | None = None,
                max_faces: int = 15000, view: tuple[float, float] = (20.0, -60.0), up: str = "z",
                ncols: int = 4, dpi: int = 110):
    """A paper-style figure of a result (Figs. 8–13), optionally saved to ``path``.

    Panels, lettered (a), (b), ...: the original point cloud (3D, when ``points`` are
    given); the zero set of every degree tried, the selected one marked; the smoothness
    against the degree; the comparison fits at the selected degree (classic linear, 3L).
    A plain polynomial result gives one panel with its zero set.

    Parameters
    ----------
    result : dict, path to a result JSON, or ImplicitPolynomial.
    points : the data (drawn under 2D curves; its box frames every panel).
    path : where to save the figure (atomically; format by extension).
    resolution : grid nodes along the box's longest side (default 400 in 2D, 72 in 3D).
    view, up : 3D camera (elevation, azimuth) and vertical axis, see :func:`plot_surface`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    view_ = result_view(result, source=str(result) if isinstance(result, (str, os.PathLike)) else "result")
    dim = view_.polynomial.dim
    pts = None if points is None else as_points(points, dims=(dim,))
    box = _panel_bounds(view_, pts, margin)
    resolution = resolution or _PLOT_RESOLUTION[dim]

    panels: list[tuple[str, Any]] = []
    if dim == 3 and pts is not None:
        panels.append(("original point cloud", ("points", None)))
    fitted = [d for d in view_.degrees if d.polynomial is not None]
    if fitted:
        for d in fitted:
            mark = " (selected)" if view_.selected == d.degree else ""
            method = _method_label(d.entry.get("method"))
            panels.append((f"degree {d.degree}{mark}" + (f"\n{method}" if method else ""), ("fit", d.polynomial)))
    else:
        method = _method_label(view_.polynomial.method)
        panels.append((f"degree {view_.polynomial.degree}" + (f", {method}" if method else ""),
                       ("fit", view_.polynomial)))
    smooth = [(d.degree, d.entry.get("smoothness")) for d in view_.degrees]
    smooth = [(g, s) for g, s in smooth if isinstance(s, (int, float)) and math.isfinite(s)]
    if smooth:
        panels.append(("smoothness vs degree", ("smoothness", smooth)))
    for name, poly in view_.comparisons.items():
        label = _method_label(name)
        panels.append((f"{label}, degree {poly.degree}", ("fit", poly)))

    nrows = math.ceil(len(panels) / max(1, ncols))
    ncols = math.ceil(len(panels) / nrows)  # balance the rows: 5 panels as 3 + 2, not 4 + 1
    fig = Figure(figsize=(3.4 * ncols, 3.4 * nrows + (0.4 if title else 0)), layout="constrained")
    if dim == 3:
        import mpl_toolkits.mplot3d  # noqa: F401  registers the 3d projection
    for index, (label, (kind, payload)) in enumerate(panels):
        letter = f"({chr(ord('a') + index)}) " if index < 26 else ""
        projection = "3d" if dim == 3 and kind in ("fit", "points") else None
        ax = fig.add_subplot(nrows, ncols, index + 1, projection=projection)
        if kind == "points":
            plot_points(pts, ax)
            _camera(ax, view, up)
            _frame(ax, box, 3, axis_off=True)
        elif kind == "fit" and dim == 2:
            plot_curve(payload, pts, ax, bounds=box, resolution=resolution, axis_off=True)
        elif kind == "fit":
            plot_surface(payload, None, ax, bounds=box, resolution=resolution, max_faces=max_faces, view=view,
                         up=up, axis_off=True)
        else:
            g, s = zip(*payload)
            plot_smoothness(g, s, view_.selected, ax)
        ax.set_title(letter + label, fontsize="medium")
    if title:
        fig.suptitle(title)
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig

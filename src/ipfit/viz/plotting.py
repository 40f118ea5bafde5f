"""Figures of fits, in the manner of the paper's Figs. 8–13 (matplotlib, no display needed).

Every plotting function takes ``ax=None`` and returns the axes it drew on; with no axes it
makes a new figure through pyplot (on the Agg backend when there is no display).
:func:`plot_result` builds a whole multi-panel figure (the zero set of every degree tried
with the data, the smoothness-versus-degree curve, the classic and 3L fits at the selected
degree) without touching pyplot's global state, and can save it atomically. Pieces of a
zero set with no data near them (spurious components, see :mod:`ipfit.zeroset.quality`) are drawn
in :data:`SPURIOUS_COLOR`; the points a fit treated as outliers (the result's ``outliers``
section) in :data:`OUTLIER_COLOR`, with a legend entry "outliers (N)". In 3D figures the surface
is drawn over the data, which shows see-through beneath it (a cloud drawn over a surface hides
its shape), and with ``trim`` the parts away from the data are drawn lighter, not left out.

matplotlib is imported only when a function here is called.
"""

from __future__ import annotations

import math
import os
import sys
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import as_faces, as_points, check_choice, check_int, check_positive, error
from ..cloud import as_cloud
from ..degree.results import ResultView, result_view
from ..polynomial import ImplicitPolynomial
from ..zeroset.extract import ZeroSet, data_bounds, default_bounds, extract_zero_set
from ..zeroset.quality import looks_like_contour, spurious_components
from ..zeroset.trim import trim_mask

__all__ = [
    "plot_curve",
    "plot_surface",
    "plot_points",
    "plot_smoothness",
    "plot_result",
    "save_figure",
    "display_points",
    "check_figure_path",
    "FIGURE_FORMATS",
    "SPURIOUS_COLOR",
    "OUTLIER_COLOR",
    "COMPONENT_COLORS",
]

CURVE_COLOR = "#1f5fbf"
_TRIMMED_CURVE_COLOR = "#a9c1e8"  # the curve's blue, 60 % of the way to white
SURFACE_COLOR = (0.55, 0.70, 0.92)
SPURIOUS_COLOR = "#d62728"
SPURIOUS_ALPHA = 0.25  # 3D: spurious pieces are see-through
#: 3D: the parts of a surface trimmed away from the data are drawn this much of the way to white,
#: and see-through (this opacity)
TRIMMED_LIGHTEN = 0.6
TRIMMED_ALPHA = 0.45
POINT_COLOR = "0.45"
POINT_COLOR_3D = "#303030"
#: 3D: the data drawn beneath a surface, see-through
POINT_ALPHA_UNDER = 0.35
#: The points a fit treated as outliers, in the figure and the viewer: the amber of IBM's
#: colour-blind-safe palette. Under simulated protanopia, deuteranopia and tritanopia (Machado
#: et al. 2009) it stays at a CIEDE2000 difference of 16 or more from the grey data, the blue
#: zero set and the red spurious pieces (a light yellow where the reds turn a dark olive);
#: Okabe and Ito's orange came within 12 of the viewer's red.
OUTLIER_COLOR = "#ffb000"
#: Each component its own colour where a zero set's topology differs from the data's (blue
#: first, then colours clear of the spurious red and the outliers' amber).
COMPONENT_COLORS = ("#1f5fbf", "#2ca02c", "#9467bd", "#17becf", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")
METHOD_TITLES = {"lstsq": "classic linear", "3l": "3L", "ridge": "3L + ridge", "taubin": "Taubin",
                 "gradient_one": "gradient-one", "de": "DE", "pso": "PSO", "de+polish": "DE + polish",
                 "pso+polish": "PSO + polish", "polish": "polish (L-BFGS from the best seed)"}
#: Figure file types (matplotlib's, less the raw and LaTeX ones).
FIGURE_FORMATS = (".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".tif", ".tiff", ".webp")
#: A figure may not exceed this many pixels at the requested dpi (4 bytes each in memory).
MAX_PIXELS = 100_000_000
#: The smoothness axis spans at least this much, so that differences in the 5th decimal of
#: a near-perfect fit do not look like a dip.
MIN_SMOOTHNESS_SPAN = 0.02
_PLOT_RESOLUTION = {2: 400, 3: 72}
_DISPLAY_SAMPLES = 2000
# Inches per panel of a result's figure: a surface needs more room than a curve to show its shape
# (and matplotlib's 3D axes keep wide margins), so 3D figures have larger panels, at most 3 a row.
_PANEL_INCHES = {2: 3.4, 3: 4.8}
_MAX_COLUMNS_3D = 3
# A title line wider than its panel runs into the next panel's (a nesting mismatch reads "3 loops
# nested (depths 0, 0, 0) where the data's are nested (depths 0, 1, 1)"); a medium-size character
# of the default font is about 6 points wide on average.
_TITLE_CHARACTERS = {dim: int(inches * 72 / 6) for dim, inches in _PANEL_INCHES.items()}
# A result's box is the data's grown by a quarter of its longest side on every side: at this zoom
# the data's part of it fills the panel, and a piece of zero set near the box's edge may be cut.
_RESULT_ZOOM_3D = 1.6


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


def check_figure_path(path: str | os.PathLike, name: str = "path") -> Path:
    """``path`` as a Path when its extension is a figure format (:data:`FIGURE_FORMATS`)."""
    if not isinstance(path, (str, os.PathLike)):
        raise error(name, "a file name such as figure.png", type(path).__name__)
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FIGURE_FORMATS:
        raise error(name, "a figure file name ending in " + ", ".join(FIGURE_FORMATS),
                    f"{suffix!r}" if suffix else f"{str(path)!r} with no extension", "Use e.g. figure.png.")
    return path


def _check_dpi(dpi: Any, size_inches: Sequence[float]) -> int:
    dpi = check_int(dpi, "dpi", minimum=1)
    width, height = (float(v) for v in size_inches)
    limit = math.floor(math.sqrt(MAX_PIXELS / (width * height)))
    if dpi > limit:
        raise error("dpi", f"at most {limit} for a {width:.3g} × {height:.3g} in figure "
                    f"(at most {MAX_PIXELS // 1_000_000} million pixels)", str(dpi), "Lower the dpi.")
    return dpi


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> None:
    """Save a matplotlib figure atomically; the format follows the extension (:data:`FIGURE_FORMATS`)."""
    from .._utils.atomic import atomic_path

    path = check_figure_path(path)
    dpi = _check_dpi(dpi, fig.get_size_inches())
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix[1:].lower())


# -- single panels -------------------------------------------------------------------------

def _zero_set_for(poly, zero_set, points, bounds, margin, resolution) -> ZeroSet:
    if zero_set is not None:
        return zero_set
    if not isinstance(poly, ImplicitPolynomial):
        raise error("poly", "an ImplicitPolynomial", type(poly).__name__)
    return extract_zero_set(poly, bounds=bounds, points=points, margin=margin,
                            resolution=resolution or _PLOT_RESOLUTION[poly.dim])


def _spurious_flags(spurious, zs: ZeroSet) -> NDArray[np.bool_]:
    if spurious is None:
        return np.zeros(zs.n_components, dtype=bool)
    flags = np.asarray(spurious, dtype=bool).ravel()
    if flags.shape != (zs.n_components,):
        raise error("spurious", f"{zs.n_components} flags, one per zero-set component", f"{flags.size} flags",
                    "Use ipfit.zeroset.quality.spurious_components(zero_set, points).")
    return flags


def display_points(points: ArrayLike, faces: ArrayLike | None = None, count: int = _DISPLAY_SAMPLES,
                   rng: int = 0) -> NDArray[np.float64]:
    """Points that show the data's shape: samples of its faces for a mesh, else the points.

    A mesh's vertices alone can look like fragments (a capsule has none along its
    cylinder); ``count`` samples spread over the faces by area do not.
    """
    pts = as_points(points)
    if faces is None or pts.shape[1] != 3:
        return pts
    face_array = as_faces(faces, len(pts))
    if len(face_array) == 0:
        return pts
    import trimesh

    mesh = trimesh.Trimesh(vertices=pts, faces=face_array, process=False)
    if not mesh.area > 0:
        return pts
    samples, _ = trimesh.sample.sample_surface(mesh, count, seed=rng)
    return np.asarray(samples, dtype=np.float64)


def _outlier_flags(outliers: ArrayLike | None, n_points: int) -> NDArray[np.bool_] | None:
    """``outliers`` (a mask over the points, or their indices) as a mask; None when it marks none."""
    if outliers is None:
        return None
    given = np.asarray(outliers)
    if given.dtype == bool:
        if given.shape != (n_points,):
            raise error("outliers", f"{n_points} flags, one per point, or indices", f"{given.size} flags")
        return given if given.any() else None
    if given.size == 0:
        return None
    if given.ndim != 1 or given.dtype.kind not in "iu" or given.min() < 0 or given.max() >= n_points:
        raise error("outliers", f"a mask of {n_points} flags or indices from 0 to {n_points - 1}",
                    f"an array of shape {given.shape} and dtype {given.dtype}"
                    + (f" from {given.min()} to {given.max()}" if given.dtype.kind in "iu" and given.ndim == 1 else ""),
                    "Use the result's outlier indices (ResultView.outlier_indices).")
    flags = np.zeros(n_points, dtype=bool)
    flags[given] = True
    return flags


def _outlier_legend(ax) -> None:
    ax.legend(loc="upper right", fontsize="small", frameon=False, markerscale=2.0, handletextpad=0.2)


def plot_points(points: ArrayLike, ax=None, *, max_points: int = 4000, size: float | None = None,
                color=None, outliers: ArrayLike | None = None, outlier_color=OUTLIER_COLOR, **kwargs):
    """Scatter the data (every k-th point beyond ``max_points``); returns ``ax``.

    ``outliers`` (a mask over the points, or their indices) are drawn over the others in
    ``outlier_color``, twice the area, as their own collection labelled "outliers (N)"
    (N counts them all, drawn or not) with a legend.
    """
    pts = as_points(points)
    if ax is None:
        ax = _new_axes(pts.shape[1])
    flags = _outlier_flags(outliers, len(pts))
    dim = pts.shape[1]
    size = size if size is not None else 2.0 if dim == 3 else 3.0
    color = color if color is not None else POINT_COLOR_3D if dim == 3 else POINT_COLOR
    # One stride for both kinds: the picture keeps their proportions, and at most max_points in all.
    stride = max(1, math.ceil(len(pts) / max_points))
    if flags is None:
        _scatter(ax, pts[::stride], size, color, **kwargs)
        return ax
    if not flags.all():
        _scatter(ax, pts[~flags][::stride], size, color, **kwargs)
    _scatter(ax, pts[flags][::stride], 2 * size, outlier_color, label=f"outliers ({int(flags.sum())})", **kwargs)
    _outlier_legend(ax)
    return ax


def _scatter(ax, shown: NDArray, size: float, color, **kwargs) -> None:
    if shown.shape[1] == 3:
        ax.scatter(shown[:, 0], shown[:, 1], shown[:, 2], s=size, c=color, depthshade=False, linewidths=0,
                   **{"alpha": 0.8, **kwargs})
    else:
        ax.scatter(shown[:, 0], shown[:, 1], s=size, c=color, linewidths=0, **{"zorder": 1, **kwargs})


def _eye(view: tuple[float, float], up: str) -> NDArray[np.float64]:
    """Unit vector from the scene towards the camera, as matplotlib's 3D axes place it."""
    elev, azim = np.radians(view[0]), np.radians(view[1])
    eye = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    return np.roll(eye, "xyz".index(up) - 2)


def _facing_camera(points: NDArray, poly: ImplicitPolynomial, view, up: str) -> NDArray[np.bool_]:
    """Points on the side of the surface the camera sees (their ∇f points towards it).

    matplotlib draws a whole scatter above or below a surface, never interleaved; drawing
    only the points that face the camera is what a depth test would show on a closed shape.
    """
    grads = poly.gradient(points)
    # A canonical fit has f > 0 outside; check, so that a flipped sign does not hide the front.
    if np.sum(grads * (points - points.mean(axis=0))) < 0:
        grads = -grads
    return grads @ _eye(view, up) > 0


def _camera(ax, view: tuple[float, float], up: str) -> None:
    ax.view_init(elev=view[0], azim=view[1], vertical_axis=check_choice(up, "up", ("x", "y", "z")))


def _frame(ax, bounds: NDArray, dim: int, axis_off: bool, zoom: float = 1.15) -> None:
    ax.set_xlim(*bounds[0])
    ax.set_ylim(*bounds[1])
    if dim == 3:
        ax.set_zlim(*bounds[2])
        ax.set_box_aspect(tuple(np.ptp(bounds, axis=1)), zoom=zoom)  # 3D axes leave wide margins
    else:
        ax.set_aspect("equal")
    if axis_off:
        ax.set_axis_off()


def plot_curve(poly: ImplicitPolynomial | None, points: ArrayLike | None = None, ax=None, *,
               zero_set: ZeroSet | None = None, bounds: ArrayLike | None = None, margin: float = 0.25,
               resolution: int | None = None, color=CURVE_COLOR, linewidth: float = 1.6, label: str | None = None,
               spurious: ArrayLike | None = None, spurious_color=SPURIOUS_COLOR, outliers: ArrayLike | None = None,
               outlier_color=OUTLIER_COLOR, axis_off: bool = False, separate: bool = False):
    """Draw the zero set of a 2D polynomial (and the data points, if given); returns ``ax``.

    Parameters
    ----------
    poly : 2D polynomial (may be None when ``zero_set`` is given).
    points : data points to draw underneath, and to choose the box from.
    zero_set : an already extracted zero set to draw instead of extracting one.
    bounds, margin, resolution : see :func:`ipfit.zeroset.extract.extract_zero_set`.
    spurious : one flag per curve of the zero set; flagged curves are drawn in
        ``spurious_color`` (see :func:`ipfit.zeroset.quality.spurious_components`).
    outliers : a mask over ``points``, or their indices: drawn in ``outlier_color``, with a
        legend entry "outliers (N)" (see :func:`plot_points`).
    separate : each curve its own colour (:data:`COMPONENT_COLORS`), spurious ones still red:
        how :func:`plot_result` shows a zero set whose topology differs from the data's.
    """
    pts = None if points is None else as_points(points, dims=(2,))
    zs = _zero_set_for(poly, zero_set, pts, bounds, margin, resolution)
    if zs.dim != 2:
        raise error("poly", "a 2D polynomial (use plot_surface for 3D)", f"a {zs.dim}D one")
    flags = _spurious_flags(spurious, zs)
    marked = None if pts is None else _outlier_flags(outliers, len(pts))
    if ax is None:
        ax = _new_axes(2)
    if pts is not None:
        plot_points(pts, ax, outliers=marked, outlier_color=outlier_color)
    for i, curve in enumerate(zs.curves):
        own = COMPONENT_COLORS[i % len(COMPONENT_COLORS)] if separate else color
        ax.plot(curve[:, 0], curve[:, 1], color=spurious_color if flags[i] else own, lw=linewidth, zorder=2,
                label=label if i == 0 else None)
    if marked is not None:  # again, with the curve's label
        _outlier_legend(ax)
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


def _coarser(zs: ZeroSet, max_faces: int) -> ZeroSet:
    """Re-extract a mesh with more than ``max_faces`` faces on a coarser grid.

    matplotlib draws every face as a polygon; beyond some 10⁴ faces it only gets slower.
    """
    faces = cast(NDArray[np.int64], zs.faces)  # read only when a 3D zero set is not empty: it has faces then
    if zs.dim == 3 and not zs.is_empty and len(faces) > max_faces and zs.polynomial is not None:
        resolution = max(8, int(max(zs.shape) * math.sqrt(max_faces / len(faces))))
        return extract_zero_set(zs.polynomial, bounds=zs.bounds, resolution=resolution)
    return zs


def plot_surface(poly: ImplicitPolynomial | None, points: ArrayLike | None = None, ax=None, *,
                 zero_set: ZeroSet | None = None, bounds: ArrayLike | None = None, margin: float = 0.25,
                 resolution: int | None = None, max_faces: int = 30000, color=SURFACE_COLOR,
                 show_points: bool | str = False, spurious: ArrayLike | None = None, spurious_color=SPURIOUS_COLOR,
                 separate: bool = False,
                 trimmed: ArrayLike | None = None, outliers: ArrayLike | None = None, outlier_color=OUTLIER_COLOR,
                 view: tuple[float, float] = (20.0, -60.0), up: str = "z", axis_off: bool = False,
                 zoom: float = 1.15):
    """Draw the zero set of a 3D polynomial as a shaded mesh; returns ``ax`` (a 3D axes).

    Parameters
    ----------
    poly : 3D polynomial (may be None when ``zero_set`` is given).
    points : data, used to choose the box, and drawn when ``show_points`` is
        ``"under"``: every point, see-through, beneath the surface (which hides those it
        covers: what shows is the data the surface misses); or True (``"front"``): over the
        surface, only the points on the side facing the camera (judged by the polynomial's
        gradient), so that the surface hides the back of the cloud.
    zero_set : an already extracted zero set.
    max_faces : a mesh with more faces is re-extracted on a coarser grid (or thinned out
        when it has no polynomial, or when flags are given for its faces).
    spurious : one flag per component of the zero set (as ``zero_set.component_labels``);
        flagged components are drawn in ``spurious_color``.
    separate : each component its own colour (:data:`COMPONENT_COLORS`), as :func:`plot_result`
        shows a zero set whose topology differs from the data's.
    trimmed : one flag per face of the zero set: the faces a trim leaves out
        (:func:`ipfit.zeroset.trim.trim_mask` is the opposite), drawn lighter and see-through
        (:data:`TRIMMED_LIGHTEN`, :data:`TRIMMED_ALPHA`).
    outliers : a mask over ``points``, or their indices: drawn (all of them, on either side
        of the surface and over it: they are off it) in ``outlier_color``, with a legend entry
        "outliers (N)" (see :func:`plot_points`).
    view : (elevation, azimuth) in degrees.
    up : the axis drawn vertically, 'x', 'y' or 'z' (scanned meshes such as the bunny are y-up).
    zoom : how much of the panel the box fills (matplotlib's ``set_box_aspect`` zoom); the
        box is the data's grown by the margin on every side, so up to about 1.6 keeps the
        data's part of it inside the panel.
    """
    style = ("front" if show_points else None) if isinstance(show_points, (bool, np.bool_)) else \
        check_choice(show_points, "show_points", ("front", "under"))
    pts = None if points is None else as_points(points, dims=(3,))
    zs = _zero_set_for(poly, zero_set, pts, bounds, margin, resolution)
    if zs.dim != 3:
        raise error("poly", "a 3D polynomial (use plot_curve for 2D)", f"a {zs.dim}D one")
    if spurious is None and trimmed is None:  # flags given are for this very zero set: keep it as it is
        zs = _coarser(zs, max_faces)
    flags = _spurious_flags(spurious, zs)
    faint = _trimmed_flags(trimmed, zs)
    if ax is None:
        ax = _new_axes(3)
    from matplotlib.colors import to_rgba
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ax.computed_zorder = False  # draw in zorder: the data under the surface, outliers over it
    if not zs.is_empty:
        # a 3D zero set that is not empty has its mesh
        vertices, faces = cast(NDArray[np.float64], zs.vertices), cast(NDArray[np.int64], zs.faces)
        labels = zs.component_labels
        if len(faces) > max_faces:  # cannot re-extract: thin out evenly
            keep = slice(None, None, math.ceil(len(faces) / max_faces))
            faces, labels, faint = faces[keep], labels[keep], faint[keep]
        flagged = flags[labels]
        # Spurious pieces go over the shape, see-through (one inside it still shows, one around it hides
        # nothing). The trimmed parts share the shape's collection, so that matplotlib sorts their faces
        # by depth together: a light lid in front of the wall stays in front of it.
        for part, rgb, alpha, zorder in ((~flagged, color, 1.0, 1), (flagged, spurious_color, SPURIOUS_ALPHA, 2)):
            if part.any():
                colors = _shaded_colors(vertices, faces[part], to_rgba(rgb)[:3])
                if separate and zorder == 1:  # each component its own colour, shaded alike
                    own = np.array([to_rgba(c)[:3] for c in COMPONENT_COLORS])[labels[part] % len(COMPONENT_COLORS)]
                    colors[:, :3] = np.clip(own * (colors[:, :3] / np.maximum(to_rgba(rgb)[:3], 1e-9)), 0, 1)
                colors[:, 3] = alpha
                if zorder == 1:
                    light = faint[part]
                    colors[light, :3] = 1.0 - (1.0 - colors[light, :3]) * (1.0 - TRIMMED_LIGHTEN)
                    colors[light, 3] = TRIMMED_ALPHA
                # Without antialiasing, neighbouring faces leave no hairline seams between them.
                ax.add_collection3d(Poly3DCollection(vertices[faces[part]], facecolors=colors, edgecolors="none",
                                                     linewidths=0, antialiased=False, zorder=zorder))
    if style is not None and pts is not None:
        marked = _outlier_flags(outliers, len(pts))
        if style == "under":
            _points_under(ax, pts, marked, outlier_color)
        else:
            surface = poly if poly is not None else zs.polynomial
            if surface is not None:
                # An outlier's gradient says nothing about the side it is on: every outlier is drawn.
                front = _facing_camera(pts, surface, view, up) | (False if marked is None else marked)
                pts, marked = pts[front], None if marked is None else marked[front]
            if len(pts):
                plot_points(pts, ax, zorder=3, outliers=marked, outlier_color=outlier_color)
    _camera(ax, view, up)
    _frame(ax, zs.bounds, 3, axis_off, check_positive(zoom, "zoom"))
    return ax


def _trimmed_flags(trimmed, zs: ZeroSet) -> NDArray[np.bool_]:
    n_faces = 0 if zs.is_empty else len(cast(NDArray[np.int64], zs.faces))
    if trimmed is None:
        return np.zeros(n_faces, dtype=bool)
    flags = np.asarray(trimmed, dtype=bool).ravel()
    if flags.shape != (n_faces,):
        raise error("trimmed", f"{n_faces} flags, one per face of the zero set", f"{flags.size} flags",
                    "Use ~ipfit.zeroset.trim.trim_mask(zero_set, points).")
    return flags


def _points_under(ax, pts: NDArray, marked: NDArray[np.bool_] | None, outlier_color, max_points: int = 4000) -> None:
    """The data beneath the surface, see-through, and the outliers (if any) over it."""
    stride = max(1, math.ceil(len(pts) / max_points))
    data = pts if marked is None else pts[~marked]
    if len(data):
        _scatter(ax, data[::stride], 1.5, POINT_COLOR_3D, alpha=POINT_ALPHA_UNDER, zorder=0)
    if marked is not None:
        _scatter(ax, pts[marked][::stride], 4.0, outlier_color, zorder=3, label=f"outliers ({int(marked.sum())})")
        _outlier_legend(ax)


def plot_smoothness(degrees: Sequence[int], smoothness: Sequence[float], selected: int | None = None, ax=None, *,
                    color="#333333", min_span: float = MIN_SMOOTHNESS_SPAN):
    """The smoothness measure against the degree (the paper's Figs. 4 and 8c); returns ``ax``.

    Tick labels are plain numbers (no offset such as ``1e−5 + 8.96e−1``) and the y-axis
    spans at least ``min_span``, so a flat curve looks flat.
    """
    from matplotlib.ticker import ScalarFormatter

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
    finite = sm[np.isfinite(sm)]
    if finite.size:
        lo, hi = float(finite.min()), float(finite.max())
        half = 0.55 * max(hi - lo, min_span)
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - half, mid + half)
    formatter = ScalarFormatter(useOffset=False)
    formatter.set_scientific(False)
    ax.yaxis.set_major_formatter(formatter)
    ax.set_xticks(deg)
    ax.set_xlabel("degree")
    ax.set_ylabel("smoothness")
    ax.grid(alpha=0.3)
    return ax


# -- results -------------------------------------------------------------------------------

def _panel_bounds(view: ResultView, points: NDArray | None, margin: float) -> NDArray:
    if points is not None:
        return data_bounds(points, margin)
    if view.bounds is not None:
        return data_bounds(view.bounds.T, margin)
    return default_bounds(view.polynomial, margin)


def without_outliers(points: NDArray, faces: NDArray | None,
                      outliers: NDArray[np.bool_]) -> tuple[NDArray, NDArray | None]:
    """The data less its outliers: their rows, and the faces touching one (the others renumbered).

    Shared with the viewer (not public): both judge spurious pieces against what the fit kept.
    """
    keep = ~outliers
    if faces is None:
        return points[keep], None
    kept = (np.cumsum(keep) - 1)[faces[keep[faces].all(axis=1)]]
    return points[keep], kept if len(kept) else None


def _number(value, digits: int = 3) -> str | None:
    return f"{value:.{digits}f}" if isinstance(value, (int, float)) and math.isfinite(value) else None


def _topology_note(view: ResultView, poly) -> str:
    """The recorded topology mismatch of the degree drawn ('5 loops where the data has 1'), or ''."""
    from ..zeroset.topology import Topology, describe_mismatch

    entry = next((d.entry for d in view.degrees if d.polynomial is poly), None)
    stored = (entry or {}).get("quality") or (view.data.get("quality") if poly is view.polynomial else None) or {}
    if not stored.get("topology") or not stored.get("data_topology"):
        return ""
    return describe_mismatch(Topology.from_dict(stored["topology"]), Topology.from_dict(stored["data_topology"]))


def _panels(view: ResultView) -> list[tuple[str, str, Any]]:
    """(title, kind, payload) of each panel of a result's figure."""
    panels: list[tuple[str, str, Any]] = []
    fitted = [d for d in view.degrees if d.polynomial is not None]
    if len(fitted) > 1 and not view.fixed_degree:  # a search to show
        for d in fitted:
            mark = " (selected)" if view.selected_degree == d.degree else ""
            method = _method_label(d.entry.get("method"))
            panels.append((f"degree {d.degree}{mark}" + (f"\n{method}" if method else ""), "fit", d.polynomial))
    else:  # one polynomial to show: title it with its measures
        entry = fitted[0].entry if fitted else {}
        # fitted: the degrees that have a polynomial
        poly = cast(ImplicitPolynomial, fitted[0].polynomial) if fitted else view.polynomial
        method = _method_label(entry.get("method") or poly.method or view.polynomial.method)
        measures = {**(view.data.get("measures") or {}), **entry}
        stats = ", ".join(f"{name} {text}" for name in ("smoothness", "distance")
                          if (text := _number(measures.get(name))) is not None)
        stopped = (view.data.get("adaptive") or {}).get("reason") in ("interrupted", "incomplete")
        mark = ("" if not view.degrees else " (interrupted)" if stopped else " (fixed)" if view.fixed_degree
                else " (selected)")
        title = f"degree {poly.degree}{mark}" + (f", {method}" if method else "") + (f"\n{stats}" if stats else "")
        panels.append((title, "fit", poly))
    smooth = [(d.degree, d.entry.get("smoothness")) for d in view.degrees]
    smooth = [(g, s) for g, s in smooth if isinstance(s, (int, float)) and math.isfinite(s)]
    if len(smooth) > 1:
        panels.append(("smoothness vs degree", "smoothness", smooth))
    for name, poly in view.comparisons.items():
        panels.append((f"{_method_label(name)}, degree {poly.degree}", "fit", poly))
    return panels


def plot_result(result, points: ArrayLike | None = None, path: str | os.PathLike | None = None, *,
                faces: ArrayLike | None = None, title: str | None = None, margin: float = 0.25,
                resolution: int | None = None, max_faces: int = 15000, view: tuple[float, float] = (20.0, -60.0),
                up: str = "z", ncols: int = 4, dpi: int = 110, mark_spurious: bool = True,
                trim: float | None = None):
    """A paper-style figure of a result (Figs. 8–13), optionally saved to ``path``.

    Panels, lettered (a), (b), ...: the zero set of every degree tried with the data (in
    3D the data see-through beneath each surface, on larger panels), the selected one marked;
    the smoothness against the degree; the comparison fits (classic linear, 3L) when the
    result holds them. A result of one degree (a fixed-degree fit or a plain polynomial)
    gives one panel for that degree, titled with its measures. With ``points``, spurious
    components (no data within τ, as counted by :func:`ipfit.zeroset.quality.quality`) are drawn
    in :data:`SPURIOUS_COLOR`.

    When the result records outliers (its ``outliers`` section, count > 0) and ``points``
    are the points it fitted, the outliers are drawn in :data:`OUTLIER_COLOR` with a legend
    entry "outliers (N)", and spurious components are judged against the other points (the
    data the fit kept, as its own quality was). The points must be exactly the fitted ones:
    ``input.n_points`` rows when the result records it, else rows that every index falls
    among and whose count the recorded share matches (see
    :meth:`ipfit.degree.results.ResultView.outlier_mask`). Otherwise an
    :class:`~ipfit.exceptions.IpfitWarning` says why and every point is drawn as data.

    Parameters
    ----------
    result : path to a result JSON, a dict, an ImplicitPolynomial (see
        :func:`ipfit.degree.results.load_result`) or a :class:`~ipfit.degree.results.ResultView`.
    points : the data (drawn with the zero sets; its box frames every panel), in the order
        it was fitted in.
    path : where to save the figure (atomically; format by extension, :data:`FIGURE_FORMATS`).
    faces : triangles over ``points`` when the data is a mesh: the faces are sampled for
        display, and spurious components are judged against them.
    resolution : grid nodes along the box's longest side (default 400 in 2D, 72 in 3D).
    view, up : 3D camera (elevation, azimuth) and vertical axis, see :func:`plot_surface`.
    mark_spurious : colour the spurious components (needs ``points``).
    trim : draw the parts of each zero set that trimming to the data at this distance leaves
        out (:meth:`ipfit.zeroset.extract.ZeroSet.trimmed`, as ``ipfit fit --trim`` exports it;
        needs ``points``) lighter than the rest: see-through in 3D, thin and pale in 2D.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    if path is not None:
        path = check_figure_path(path)
    view_ = result_view(result)
    dim = view_.dim
    pts = None if points is None else as_points(points, dims=(dim,))
    face_array = None if faces is None or pts is None or dim != 3 else as_faces(faces, len(pts))
    if face_array is not None and len(face_array) == 0:
        face_array = None
    # kept: the data the fit kept (every point, or the inliers), which spurious pieces are judged
    # against; shown: the points drawn (samples of a mesh's faces), the outliers last
    kept: NDArray[np.float64] | None = None
    kept_faces, shown, shown_outliers = face_array, None, None
    if pts is not None:
        outliers = view_.outlier_mask(len(pts))  # warns once when the rows do not match
        if outliers is not None and outliers.all():
            outliers = None  # nothing left to call the data: draw it as data
        kept, kept_faces = (pts, face_array) if outliers is None else without_outliers(pts, face_array, outliers)
        shown = display_points(kept, kept_faces)
        if outliers is not None:
            shown_outliers = np.repeat([False, True], [len(shown), int(outliers.sum())])
            shown = np.vstack([shown, pts[outliers]])
    box = _panel_bounds(view_, pts, margin)
    resolution = resolution or _PLOT_RESOLUTION[dim]
    panels = _panels(view_)
    ncols = max(1, ncols) if dim == 2 else max(1, min(ncols, _MAX_COLUMNS_3D))
    nrows = math.ceil(len(panels) / ncols)
    ncols = math.ceil(len(panels) / nrows)  # balance the rows: 5 panels as 3 + 2, not 4 + 1
    inches = _PANEL_INCHES[dim]
    size = (inches * ncols, inches * nrows + (0.4 if title else 0))
    dpi = _check_dpi(dpi, size)
    fig = Figure(figsize=size, layout="constrained")
    if dim == 3:
        import mpl_toolkits.mplot3d  # noqa: F401  registers the 3d projection
    ordered = dim == 2 and kept is not None and looks_like_contour(kept)
    # one cloud for every panel: the data's side of the measurement (its samples, k-d tree and
    # topology) is built once, not once per degree
    judged = None if kept is None else as_cloud(kept, faces=kept_faces, min_points=2)
    for index, (label, kind, payload) in enumerate(panels):
        letter = f"({chr(ord('a') + index)}) " if 1 < len(panels) and index < 26 else ""
        ax = fig.add_subplot(nrows, ncols, index + 1, projection="3d" if dim == 3 and kind == "fit" else None)
        if kind == "fit":
            zs = _coarser(extract_zero_set(payload, bounds=box, resolution=resolution), max_faces)
            faint = None  # 3D: the faces the trim leaves out
            if trim is not None and pts is not None:
                if dim == 2:  # the whole curve thin and pale, then the trimmed one over it
                    plot_curve(None, zero_set=zs, ax=ax, color=_TRIMMED_CURVE_COLOR, linewidth=0.8)
                    zs = zs.trimmed(pts, trim)
                else:
                    faint = ~cast(NDArray[np.bool_], trim_mask(zs, pts, trim, faces=face_array))
            flags = None
            if mark_spurious and judged is not None and not zs.is_empty:
                flags = spurious_components(zs, judged, ordered_contour=ordered)
                if flags.any():
                    label += f"\n{int(flags.sum())} spurious piece{'s' if flags.sum() > 1 else ''} (red)"
            mismatch = _topology_note(view_, payload)
            if mismatch:
                label += "\n" + textwrap.fill(mismatch, _TITLE_CHARACTERS[dim])
            if dim == 2:
                plot_curve(payload, shown, ax, zero_set=zs, spurious=flags, outliers=shown_outliers, axis_off=True,
                           separate=bool(mismatch))
            else:
                plot_surface(payload, shown, ax, zero_set=zs, spurious=flags, trimmed=faint, outliers=shown_outliers,
                             show_points="under", view=view, up=up, max_faces=max_faces, axis_off=True,
                             zoom=_RESULT_ZOOM_3D, separate=bool(mismatch))
        else:
            g, s = zip(*payload, strict=True)  # payload: (degree, smoothness) pairs
            plot_smoothness(g, s, view_.selected_degree, ax)
        ax.set_title(letter + label, fontsize="medium")
    if title:
        fig.suptitle(title)
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig

"""A batch's thumbnail of one shape: the selected degree alone, large, with the data.

The index page of ``ipfit batch --html`` shows each thumbnail 260 px wide. ``ipfit fit``'s
figure (one panel per degree tried and the smoothness curve) is unreadable at that size,
so a thumbnail is one panel filling the picture, titled in a large font.
"""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["write_thumbnail", "THUMBNAIL_INCHES", "THUMBNAIL_DPI"]

#: Side of the square thumbnail in inches, and its dots per inch: 320 px, shown at 260.
THUMBNAIL_INCHES = 3.2
THUMBNAIL_DPI = 100
#: Grid nodes along the box's longest side: finer than the eye can tell at 320 px.
_RESOLUTION = {2: 300, 3: 56}
#: The box around the data, as a share of its size: the shape fills the panel (``ipfit fit``'s
#: figure leaves 0.25 to show far-off pieces; a piece beyond still counts as spurious in the F-score).
_MARGIN = 0.1


def write_thumbnail(result, points: ArrayLike | None, path: str | os.PathLike, *, faces: ArrayLike | None = None,
                    title: str | None = None) -> None:
    """Save the zero set of ``result``'s selected degree over its data to ``path`` (PNG).

    Parameters
    ----------
    result : a result dict (or anything :func:`ipfit.degree.results.result_view` takes).
    points : the fitted points (drawn, and framing the box), or None: the box then comes
        from the result's ``bounds``. Outliers the result records are drawn in amber, and
        spurious pieces of the zero set (no data near them) in red, as in ``ipfit fit``'s figure.
    faces : the data's triangles, for a mesh: its surface is sampled for display.
    title : the panel's title (default ``"degree N"``, with the F-score when the result has it).
    """
    from matplotlib.figure import Figure

    from ..degree.results import result_view
    from ..viz.plotting import display_points, plot_curve, plot_surface, save_figure
    from ..zeroset.extract import data_bounds, default_bounds, extract_zero_set
    from ..zeroset.quality import spurious_components

    view = result_view(result)
    poly, dim = view.polynomial, view.dim
    pts = None if points is None else np.asarray(points, dtype=np.float64)
    outliers = None if pts is None else view.outlier_mask(len(pts))
    if pts is not None:
        box = data_bounds(pts, _MARGIN)
    elif view.bounds is not None:
        box = data_bounds(view.bounds.T, _MARGIN)
    else:
        box = default_bounds(poly, _MARGIN)
    zero_set = extract_zero_set(poly, bounds=box, resolution=_RESOLUTION[dim])
    flags = None
    if pts is not None and not zero_set.is_empty:
        kept = pts if outliers is None else pts[~outliers]
        flags = spurious_components(zero_set, kept, faces=faces if outliers is None else None)
    # a mesh's vertices can look like fragments: show samples of its faces (outliers are vertices)
    shown = pts if pts is None or faces is None or outliers is not None else display_points(pts, faces)
    fig = Figure(figsize=(THUMBNAIL_INCHES, THUMBNAIL_INCHES), layout="constrained")
    if dim == 2:
        ax = fig.add_subplot()
        plot_curve(poly, shown, ax, zero_set=zero_set, spurious=flags, outliers=outliers, linewidth=2.2,
                   axis_off=True)
    else:
        import mpl_toolkits.mplot3d  # noqa: F401  registers the 3d projection

        ax = fig.add_subplot(projection="3d")
        plot_surface(poly, shown, ax, zero_set=zero_set, spurious=flags, outliers=outliers, show_points=True,
                     axis_off=True)
        ax.set_box_aspect(ax.get_box_aspect(), zoom=1.35)  # 3D axes leave wide margins: fill the panel
    if title is None:
        f_score = (view.data.get("quality") or {}).get("f_score")
        title = f"degree {poly.degree}" + (f", F {f_score:.3f}" if isinstance(f_score, (int, float)) else "")
    ax.set_title(title, fontsize=15, fontweight="bold")
    save_figure(fig, path, dpi=THUMBNAIL_DPI)

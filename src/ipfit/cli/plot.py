"""``ipfit plot RESULT.json -o OUT.png``: the paper-style figure of a result."""

from __future__ import annotations

import argparse

from ._common import Outputs, finite_float, nonnegative_float, positive_int, recorded_sources
from .mesh import TRIM_DRAW_HELP, add_trim_argument

NAME = "plot"
HELP = "draw a result: the zero set of each degree with the data, smoothness vs degree, classic and 3L fits"
DESCRIPTION = """\
Draw RESULT.json (written by `ipfit fit`) as in the paper's Figs. 8-13: the zero set of every
degree tried with the data (in 3D the points see-through beneath each surface), the smoothness against the
degree, and the classic linear and 3L fits at the selected degree when the result holds them.
A fixed-degree result or a plain polynomial gives one panel. Spurious pieces of a zero set (no
data near them) are drawn in red. Rendered without a display; the format follows OUT's extension
(.png, .pdf, .svg, .eps, .jpg, .tif, .webp, ...).

Without --points, the data the result records ("input": its path, or a bundled dataset's name)
is drawn; when it cannot be found, a warning says so and the figure has no points.

When the fit treated points as outliers (the result's "outliers"), they are drawn in amber with a
legend entry "outliers (N)", if the data drawn are the points fitted (as many rows as "input"
records); otherwise a warning says so and every point is drawn as data.

--trim [DIST] draws the part of each zero set within DIST of the data as `ipfit fit --trim` and
`ipfit mesh --trim` export it (an open scan stays open), the rest lighter; without DIST, 2 x the
data's median point spacing, or 1% of its box diagonal if larger, holes between samples kept.
"""

MAX_DPI = 2400


def _dpi(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not 1 <= value <= MAX_DPI:
        raise argparse.ArgumentTypeError(f"expected a whole number from 1 to {MAX_DPI}, got {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.png",
                        help="figure file; the format follows the extension (.png .pdf .svg ...)")
    parser.add_argument("--points", metavar="DATA", help="the data (file or bundled name), drawn and framing the box")
    parser.add_argument("--no-points", action="store_true",
                        help="do not look for the data recorded in the result (\"input\") when --points is absent")
    parser.add_argument("--title", help="figure title")
    parser.add_argument("--margin", type=nonnegative_float, default=0.25,
                        help="margin around the data's box, as a fraction of its longest side (default 0.25)")
    parser.add_argument("--resolution", type=positive_int, metavar="N",
                        help="grid nodes along the box's longest side (default 400 in 2D, 72 in 3D)")
    parser.add_argument("--view", type=finite_float, nargs=2, default=(20.0, -60.0), metavar=("ELEV", "AZIM"),
                        help="3D camera elevation and azimuth in degrees (default 20 -60)")
    parser.add_argument("--up", choices=("x", "y", "z"), default="z",
                        help="3D: the axis drawn vertically (default z; scanned meshes like the bunny are y-up)")
    parser.add_argument("--dpi", type=_dpi, default=110,
                        help=f"resolution of raster output, 1 to {MAX_DPI} (default 110)")
    add_trim_argument(parser, help=TRIM_DRAW_HELP)


def run(args: argparse.Namespace) -> int:
    from ..degree.results import result_view
    from ..viz.plotting import check_figure_path, plot_result
    from ._scene import is_scene_file, run_plot
    from .mesh import check_trim_with_points, drawing_trim, load_points, trim_data, trimmed_note

    if is_scene_file(args.result):  # a scene: every object in one page, figure or export (cli/_scene.py)
        return run_plot(args)

    check_figure_path(args.output, "-o/--output")
    check_trim_with_points(args)
    view = result_view(args.result)
    outputs = Outputs([args.output], inputs=[args.result, args.points, *recorded_sources(view.data)])
    points = faces = trim = None
    if args.trim is not None:
        points, faces = trim_data(view, args.points)
        trim = drawing_trim(args.trim, points)
    elif not args.no_points:
        points, faces = load_points(args.points, view, NAME, missing="drawing the zero sets without the points")
    with outputs.writing() as stage:
        fig = plot_result(view, points=points, faces=faces, path=stage(args.output), title=args.title,
                          margin=args.margin, resolution=args.resolution, view=tuple(args.view), up=args.up,
                          dpi=args.dpi, trim=trim)
    print(f"{args.output}: {len(fig.axes)} panel(s){trimmed_note(trim)}")
    return 0

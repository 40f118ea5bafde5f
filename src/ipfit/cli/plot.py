"""``ipfit plot RESULT.json -o OUT.png``: the paper-style figure of a result."""

from __future__ import annotations

import argparse

from ._common import Outputs, finite_float, nonnegative_float, positive_int, recorded_source

NAME = "plot"
HELP = "draw a result: the zero set of each degree, smoothness vs degree, classic and 3L fits"
DESCRIPTION = """\
Draw RESULT.json (written by `ipfit fit`) as in the paper's Figs. 8-13: the points (3D), the zero
set of every degree tried, the smoothness against the degree, and the classic linear and 3L fits
at the selected degree when the result holds them. A plain polynomial gives one panel.
Rendered without a display; the format follows OUT's extension (.png, .pdf, .svg).
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.png", help="figure file")
    parser.add_argument("--points", metavar="INPUT", help="the data (file or bundled name), drawn and framing the box")
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
    parser.add_argument("--dpi", type=positive_int, default=110, help="resolution of raster output (default 110)")


def run(args: argparse.Namespace) -> int:
    from ..plotting import load_result, plot_result, result_view
    from .mesh import load_points

    from matplotlib.backend_bases import FigureCanvasBase

    figure_suffixes = tuple(sorted("." + s for s in FigureCanvasBase.get_supported_filetypes()))
    data = load_result(args.result)
    outputs = Outputs([args.output], inputs=[args.result, args.points, recorded_source(data)],
                      suffixes=figure_suffixes)
    view = result_view(data, source=args.result)
    points, _ = load_points(None if args.no_points else args.points, view.polynomial.dim,
                            None if args.no_points else data)
    with outputs.writing() as stage:
        fig = plot_result(data, points=points, path=stage(args.output), title=args.title, margin=args.margin,
                          resolution=args.resolution, view=tuple(args.view), up=args.up, dpi=args.dpi)
    print(f"{args.output}: {len(fig.axes)} panel(s)")
    return 0

"""``ipfit view RESULT.json -o view.html``: the interactive, self-contained HTML viewer of a result."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import nonnegative_float, positive_int
from .mesh import TRIM_DRAW_HELP, add_trim_argument, check_trim_with_points, drawing_trim, trimmed_note

NAME = "view"
HELP = "write an interactive HTML viewer of a result (rotate, zoom, switch degrees), offline"
DESCRIPTION = """\
Write one self-contained HTML page (works offline: plotly's JavaScript is inlined) showing
RESULT.json (written by `ipfit fit`): the data and the zero set of every degree tried, a slider
to switch degrees, spurious components in red, the data's normals (click "normals" in the
legend), the per-degree table, why the degree was selected, and smoothness against degree.
Hovering a point shows its index and |f|/|grad f| at the degree shown. The points the fit
treated as outliers (the result's "outliers") are a trace of their own, "outliers (N)", in amber
(click it in the legend to hide them), when the data are the points fitted; otherwise a warning
says so and every point is drawn as data.

Without --points, the data recorded in the result ("input") is used when it can be read.
--trim [DIST] draws only the part of each zero set within DIST of the data, as `ipfit fit --trim`
and `ipfit mesh --trim` export it; without DIST, 2 x the data's median point spacing, or 1% of its
box diagonal if larger, holes between samples kept.
Needs plotly: pip install 'ipfit[viewer]'.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("-o", "--output", metavar="VIEW.html",
                        help="the page to write (default: RESULT with the extension .html)")
    parser.add_argument("--points", metavar="INPUT", help="the data (file or bundled name)")
    parser.add_argument("--no-points", action="store_true",
                        help="do not look for the data recorded in the result (\"input\") when --points is absent")
    parser.add_argument("--no-normals", action="store_true", help="leave the data's normals out of the page")
    parser.add_argument("--title", help="page title (default: the input's name)")
    parser.add_argument("--up", choices=("x", "y", "z"), default="z",
                        help="3D: the axis pointing up on screen (default z; scanned meshes like the bunny are y-up)")
    parser.add_argument("--max-faces", type=positive_int, default=None, metavar="N",
                        help="faces per degree in the page after decimation (default 15000)")
    parser.add_argument("--margin", type=nonnegative_float, default=0.25,
                        help="margin around the data's box, as a fraction of its longest side (default 0.25)")
    parser.add_argument("--open", action="store_true", help="open the page in the web browser")
    add_trim_argument(parser, help=TRIM_DRAW_HELP)


def run(args: argparse.Namespace) -> int:
    from .._result_schema import check_coordinates
    from ..datasets.loading import load
    from ..degree.results import result_view
    from ..exceptions import InvalidInputError
    from ..viz.viewer import MAX_FACES, write_html
    from ._common import Outputs, recorded_sources
    from ._scene import is_scene_file, run_view

    if is_scene_file(args.result):  # a scene: every object in one page, figure or export (cli/_scene.py)
        return run_view(args)

    check_trim_with_points(args)
    view = result_view(args.result)
    data = view.data
    output = Path(args.output) if args.output else Path(args.result).with_suffix(".html")
    outputs = Outputs([output], inputs=[args.result, args.points, *recorded_sources(data)])
    dim = view.dim  # from the exponents: "dim" and "normalization" are optional keys
    points = faces = normals = None
    recorded = view.input.get("source")
    spec = args.points or (None if args.no_points else recorded)
    if spec is not None:
        try:
            found = load(spec)
        except InvalidInputError:
            if args.points:
                raise
            found = None  # the recorded data moved away: view the result without it
        if found is not None and found.points.shape[1] != dim:
            if args.points:
                raise InvalidInputError(f"--points: expected {dim}D points to match the result, got "
                                        f"{found.points.shape[1]}D. Pass the data the result was fitted to.")
            found = None
        if found is not None:
            check_coordinates(found.points, "--points" if args.points else spec)
            points, faces = found.points, found.faces
            normals = None if args.no_normals else found.normals
    if args.trim is not None and points is None:
        raise InvalidInputError("--trim: it needs the data to trim to, and the result's recorded input could "
                                "not be read. Pass the data with --points DATA.")
    trim = drawing_trim(args.trim, points)
    with outputs.writing() as stage:
        write_html(view, points, stage(output), faces=faces, normals=normals, title=args.title, up=args.up,
                   margin=args.margin, max_faces=args.max_faces or MAX_FACES, trim=trim)
    size = output.stat().st_size / 1e6
    print(f"{output}: {size:.1f} MB" + ("" if points is not None else " (without the data points)")
          + trimmed_note(trim))
    if args.open:
        import webbrowser

        webbrowser.open(output.resolve().as_uri())
    return 0

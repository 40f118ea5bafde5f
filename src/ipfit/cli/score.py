"""``ipfit score RESULT.json --points DATA``: geometric quality of a fit, measured on its zero set."""

from __future__ import annotations

import argparse
import json

from ._common import Outputs, nonnegative_float, positive_int, recorded_sources

NAME = "score"
HELP = "measure a fit geometrically: recall, precision, F-score, Chamfer, spurious components"
DESCRIPTION = """\
Measure how well the zero set of RESULT.json matches the data (--points DATA: a point file or a
bundled dataset; default: the data the result records), without trusting the fitting objective.
With a tolerance tau (default 2% of the data's bounding-box diagonal):
  recall        fraction of points within tau of the zero set
  precision     fraction of the zero set within tau of the data's shape (its faces for a mesh,
                its polyline for an ordered 2D contour, else the points)
  f_score       harmonic mean of the two
  chamfer       symmetric Chamfer distance (mean of the two mean nearest distances)
  n_components  pieces of the zero set in the box; n_spurious: those with nothing within tau
  closed        whether the zero set closes inside the box
--write adds them to RESULT.json as "quality" (atomically; other keys are kept as they are).
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("--points", metavar="DATA",
                        help="the data: point file or bundled dataset name (default: the data the result records)")
    parser.add_argument("--degree", type=positive_int, metavar="G",
                        help="score the fit of degree G from the result's per-degree table")
    tol = parser.add_mutually_exclusive_group()
    tol.add_argument("--tau", type=nonnegative_float, help="tolerance in the data's units")
    tol.add_argument("--tau-fraction", type=nonnegative_float, default=0.02,
                     help="tolerance as a fraction of the data's box diagonal (default 0.02)")
    parser.add_argument("--contour", choices=("auto", "yes", "no"), default="auto",
                        help="2D: are the points in order along a contour? (default: detect)")
    parser.add_argument("--margin", type=nonnegative_float, default=0.25,
                        help="margin around the data's box, as a fraction of its longest side (default 0.25)")
    parser.add_argument("--resolution", type=positive_int, metavar="N",
                        help="grid nodes along the box's longest side (default 128 in 3D, 512 in 2D)")
    parser.add_argument("--json", action="store_true", help="print the measures as JSON")
    parser.add_argument("--write", action="store_true", help='store the measures in RESULT.json as "quality"')


def run(args: argparse.Namespace) -> int:
    from ..degree.results import result_view, write_result
    from ..exceptions import InvalidInputError
    from ..zeroset.quality import looks_like_contour, quality
    from .mesh import load_points

    if args.write and args.degree is not None:
        raise InvalidInputError("--write: expected the selected fit, got --degree too. "
                                "Drop --degree to store the measures of the result's polynomial.")
    if args.tau is not None and args.tau <= 0:
        raise InvalidInputError(f"--tau: expected a number > 0, got {args.tau}. Pass a positive tolerance.")
    if args.tau is None and args.tau_fraction <= 0:
        raise InvalidInputError(f"--tau-fraction: expected a number > 0, got {args.tau_fraction}.")
    spec = args.points
    view = result_view(args.result)
    # --write updates RESULT.json in place (that is its purpose); the data must never be the target
    outputs = (Outputs([args.result], inputs=[spec, *recorded_sources(view.data)], option="--write") if args.write
               else None)
    poly = view.fit(args.degree, name="--degree")
    points, faces = load_points(spec, view, NAME, required=True)
    ordered = poly.dim == 2 and faces is None and (
        args.contour == "yes" or (args.contour == "auto" and looks_like_contour(points)))
    q = quality(poly, points, faces=faces, ordered_contour=ordered, tau=args.tau, tau_fraction=args.tau_fraction,
                margin=args.margin, resolution=args.resolution)
    from ..analysis.projection import distance_summary

    dist = distance_summary(poly, points)  # true distance (closest points) beside Taubin's estimate
    if args.json:
        print(json.dumps({**q.to_dict(), "distance_to_zero_set": dist}, indent=1))
    else:
        data_name = spec if spec is not None else view.input.get("source", "its recorded data")
        print(f"{args.result} against {data_name} (degree {poly.degree}):")
        print(q)
        print(f"{'distance_true':<18}mean {dist['projected_mean']:.6g}, max {dist['projected_max']:.6g} "
              f"(closest points on the zero set, {dist['n_points']} data points)")
        print(f"{'distance_taubin':<18}mean {dist['taubin_mean']:.6g}, max {dist['taubin_max']:.6g} (|f| / |grad f|)")
    if outputs is not None:  # args.write
        data = dict(view.data)
        data["quality"] = q.to_dict()  # a new key at the end, or the old one updated in place
        with outputs.writing() as stage:
            write_result(stage(args.result), data)
    return 0

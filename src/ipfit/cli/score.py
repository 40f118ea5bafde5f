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
  distance_true the closest points on the zero set of (at most 4000) data points: mean and
                max distance, beside Taubin's estimate |f| / |grad f|
The fit measured the same quality already: when the data, tau and the grid are those of the fit
(the recorded data, the default --margin and --resolution, no outliers left out), the measures
stored in RESULT.json are shown instead of measured again, and a true distance stored by an
earlier --write is shown as it is. --write adds what was measured to RESULT.json: "quality" and
"distance_to_zero_set" (atomically; other keys are kept as they are) and says in one line what it
wrote.
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
    from ..analysis.projection import distance_summary
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
    fitted = _fitted_data(view, spec, points)
    stored_q = _stored_quality(view, args, points, faces, ordered) if fitted else None
    if stored_q is not None:
        q = stored_q
    else:
        q = quality(poly, points, faces=faces, ordered_contour=ordered, tau=args.tau, tau_fraction=args.tau_fraction,
                    margin=args.margin, resolution=args.resolution)
    stored_d = _stored_distance(view, args, points) if fitted else None
    # true distance (closest points) beside Taubin's estimate
    dist = stored_d if stored_d is not None else distance_summary(poly, points, max_points=_DISTANCE_POINTS)
    reused = [name for name, kept in (("quality", stored_q), ("distance_to_zero_set", stored_d)) if kept is not None]
    if args.json:
        print(json.dumps({**q.to_dict(), "distance_to_zero_set": dist, "from_result": reused}, indent=1))
    else:
        data_name = spec if spec is not None else view.input.get("source", "its recorded data")
        print(f"{args.result} against {data_name} (degree {poly.degree}):")
        print(q)
        print(f"{'distance_true':<18}mean {dist['projected_mean']:.6g}, max {dist['projected_max']:.6g} "
              f"(closest points on the zero set, {dist['n_points']} data points)")
        print(f"{'distance_taubin':<18}mean {dist['taubin_mean']:.6g}, max {dist['taubin_max']:.6g} (|f| / |grad f|)")
        if stored_q is not None:
            print(f"(quality as {args.result} stores it: the fit measured the same data with the same tau and grid)")
        if stored_d is not None:
            print(f"(distances as {args.result} stores them: an earlier score --write on the same data)")
    if outputs is not None:  # args.write
        data = dict(view.data)
        # new keys at the end, or the old ones updated in place
        data["quality"] = q.to_dict()
        data["distance_to_zero_set"] = dict(dist)
        changed = [name for name in ("quality", "distance_to_zero_set") if view.data.get(name) != data[name]]
        with outputs.writing() as stage:
            write_result(stage(args.result), data)
        if changed:
            print(f"wrote {args.result}: " + " and ".join(_WRITTEN[name] for name in changed))
        else:
            print(f"wrote {args.result}: nothing new (it already held these measures)")
    return 0


# at most this many evenly strided data points get closest points (the summary is a statistic)
_DISTANCE_POINTS = 4000
_WRITTEN = {"quality": '"quality" (recall, precision, F-score, Chamfer, spurious components)',
            "distance_to_zero_set": '"distance_to_zero_set" (true and Taubin distances)'}


def _fitted_data(view, spec: str | None, points) -> bool:
    """Whether ``points`` are the points the result's fit measured: its recorded data (``spec``
    None, or the same file or dataset name), all of it (no --max-points subset, no outliers
    left out)."""
    from pathlib import Path

    recorded = view.input
    if spec is not None and spec != recorded.get("source"):
        path = recorded.get("path")
        if path is None or not Path(spec).exists() or Path(spec).resolve() != Path(path).resolve():
            return False
    return recorded.get("n_points") == len(points) and not (view.outliers.get("count") or 0)


def _stored_quality(view, args, points, faces, ordered: bool):
    """The result's stored ``quality`` of the polynomial scored, as a :class:`Quality`, when it
    was measured with the tolerance and the grid this run would use; else None."""
    import math

    import numpy as np

    from ..zeroset.extract import DEFAULT_RESOLUTION
    from ..zeroset.quality import Quality

    if args.degree is None:
        stored = view.data.get("quality")
    else:
        stored = next((d.entry.get("quality") for d in view.degrees if d.degree == args.degree), None)
    if not stored or any(stored.get(name) is None for name in _QUALITY_NEEDED):
        return None
    extent = np.ptp(points, axis=0)
    tau = args.tau if args.tau is not None else args.tau_fraction * float(np.linalg.norm(extent))
    # the grid step of extract_zero_set on the data's box grown by the margin
    resolution = args.resolution if args.resolution is not None else DEFAULT_RESOLUTION[points.shape[1]]
    step = float(extent.max()) * (1 + 2 * args.margin) / (resolution - 1)
    reference = "faces" if faces is not None else "contour" if ordered else "points"
    if (stored["reference"] != reference or not math.isclose(stored["tau"], tau, rel_tol=1e-9)
            or not math.isclose(stored["grid_step"], step, rel_tol=1e-9)):
        return None
    values = {name: stored.get(name) for name in Quality.__dataclass_fields__ if name in stored}
    for name in ("chamfer", "data_to_zero_set", "zero_set_to_data"):  # to_dict wrote inf as null
        values[name] = math.inf if values.get(name) is None else values[name]
    return Quality.from_dict(values)


_QUALITY_NEEDED = ("recall", "precision", "f_score", "n_components", "n_spurious", "closed", "n_open", "tau",
                   "grid_step", "reference")


def _stored_distance(view, args, points) -> dict | None:
    """The result's stored ``distance_to_zero_set`` (an earlier ``score --write``) when it is of
    the polynomial scored and of the same data points; else None."""
    stored = view.data.get("distance_to_zero_set")
    if args.degree is not None or not stored:
        return None
    n = len(points[:: max(1, -(-len(points) // _DISTANCE_POINTS))])
    names = ("projected_mean", "projected_max", "taubin_mean", "taubin_max")
    if stored.get("n_points") != n or any(stored.get(name) is None for name in names):
        return None
    return {**{name: float(stored[name]) for name in names}, "n_points": n}

"""``ipfit mesh RESULT.json -o OUT.ply``: extract the zero set and write it as a mesh or curves."""

from __future__ import annotations

import argparse

from ._common import Outputs, nonnegative_float, positive_int, recorded_source

NAME = "mesh"
HELP = "extract the zero set of a result: mesh (PLY/OBJ/STL) in 3D, curves (SVG/CSV) in 2D"
DESCRIPTION = """\
Extract the zero set of the polynomial in RESULT.json (written by `ipfit fit`) over the data's
bounding box plus a margin, by marching cubes (3D) or marching squares (2D), and write it:
  3D: OUT.ply, OUT.obj or OUT.stl      2D: OUT.svg or OUT.csv (rows: curve,x,y)

Without --points, the data recorded in the result ("input") frames the box when it can be read;
else the result's "bounds" if present, else its normalisation.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="output file; the format follows the extension (.ply .obj .stl | .svg .csv)")
    parser.add_argument("--points", metavar="INPUT", help="the data (file or bundled name), to frame the box")
    parser.add_argument("--degree", type=positive_int, metavar="G",
                        help="use the fit of degree G from the result's per-degree table instead of the selected one")
    parser.add_argument("--margin", type=nonnegative_float, default=0.25,
                        help="margin around the data's box, as a fraction of its longest side (default 0.25)")
    parser.add_argument("--resolution", type=positive_int, metavar="N",
                        help="grid nodes along the box's longest side (default 128 in 3D, 512 in 2D)")


def pick_polynomial(view, degree: int | None, source: str):
    """The result's final polynomial, or its fit at ``degree``."""
    from ..exceptions import InvalidInputError

    if degree is None or (degree == view.polynomial.degree and not view.degrees):
        return view.polynomial
    for entry in view.degrees:
        if entry.degree == degree and entry.polynomial is not None:
            return entry.polynomial
    tried = ", ".join(str(d.degree) for d in view.degrees if d.polynomial is not None) or "none"
    raise InvalidInputError(f"--degree: expected a degree with coefficients in {source} ({tried}), got {degree}. "
                            "Pick one of those.")


def box_for(view, points, margin: float):
    from ..zeroset import data_bounds, default_bounds

    if points is not None:
        return data_bounds(points, margin)
    if view.bounds is not None:
        return data_bounds(view.bounds.T, margin)
    return default_bounds(view.polynomial, margin)


def load_points(spec: str | None, dim: int, result: dict | None = None):
    """(points, faces) of INPUT, or of the result's recorded input, or (None, None).

    Without INPUT, the ``"input": {"source": ...}`` that ``ipfit fit`` records is tried
    quietly: a result moved away from its data still plots, just without the points.
    """
    from ..exceptions import InvalidInputError

    from ._common import load_input

    if spec is None:
        recorded = (result or {}).get("input")
        source = recorded.get("source") if isinstance(recorded, dict) else None
        if not isinstance(source, str):
            return None, None
        try:
            data = load_input(source)
        except Exception:  # noqa: BLE001  best effort: any failure means "no points"
            return None, None
        if data.points.shape[1] != dim:
            return None, None
        return data.points, data.faces
    data = load_input(spec)
    if data.points.shape[1] != dim:
        raise InvalidInputError(f"{spec}: expected {dim}D points to match the result, got "
                                f"{data.points.shape[1]}D. Pass the data the result was fitted to.")
    return data.points, data.faces


def run(args: argparse.Namespace) -> int:
    from ..plotting import result_view
    from ..zeroset import extract_zero_set

    from ..plotting import load_result

    from ..export import CURVE_FORMATS, MESH_FORMATS

    data = load_result(args.result)
    outputs = Outputs([args.output], inputs=[args.result, args.points, recorded_source(data)],
                      suffixes=MESH_FORMATS + CURVE_FORMATS)
    view = result_view(data, source=args.result)
    poly = pick_polynomial(view, args.degree, args.result)
    points, _ = load_points(args.points, poly.dim, data)
    box = box_for(view, points, args.margin)
    zero_set = extract_zero_set(poly, bounds=box, resolution=args.resolution)
    with outputs.writing() as stage:
        zero_set.save(stage(args.output))
    what = (f"{len(zero_set.vertices)} vertices, {len(zero_set.faces)} faces" if zero_set.dim == 3
            else f"{len(zero_set.curves)} curves")
    print(f"{args.output}: degree {poly.degree}, {what}, {zero_set.n_components} component(s), "
          f"{'closed' if zero_set.closed else 'open'} in the box, grid step {zero_set.step:.4g}")
    return 0

"""``ipfit mesh RESULT.json -o OUT.ply``: extract the zero set and write it as a mesh or curves."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ._common import Outputs, nonnegative_float, positive_int, recorded_sources

NAME = "mesh"
HELP = "extract the zero set of a result: mesh (PLY/OBJ/STL) in 3D, curves (SVG/CSV) in 2D"
DESCRIPTION = """\
Extract the zero set of the polynomial in RESULT.json (written by `ipfit fit`) over the data's
bounding box plus a margin, by marching cubes (3D) or marching squares (2D), and write it:
  3D: OUT.ply, OUT.obj or OUT.stl      2D: OUT.svg or OUT.csv (rows: curve,x,y)

The box is that of --points DATA when given, else the result's "bounds", else that of the data
the result records ("input"), else one around the result's normalisation.

--trim [DIST] writes only the part of the zero set within DIST of the data (--points DATA, else
the data the result records), e.g. to export an open scan open: faces with a vertex farther than
DIST go. Without DIST: 2 x the data's median point spacing, or 1% of its box diagonal if larger;
holes between samples (up to 5 spacings, or 2% of the diagonal, across) are kept.
"""

TRIM_DEFAULT = "auto"
TRIM_HELP = ("export only the zero set within DIST of the data (data units; default, or 'auto': 2 x the median "
             "point spacing, at least 1%% of the box diagonal, holes between samples kept); the polynomial is "
             "unchanged")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="output file; the format follows the extension (.ply .obj .stl | .svg .csv)")
    parser.add_argument("--points", metavar="DATA", help="the data (file or bundled name), to frame the box")
    parser.add_argument("--degree", type=positive_int, metavar="G",
                        help="use the fit of degree G from the result's per-degree table instead of the selected one")
    parser.add_argument("--margin", type=nonnegative_float, default=0.25,
                        help="margin around the data's box, as a fraction of its longest side (default 0.25)")
    parser.add_argument("--resolution", type=positive_int, metavar="N",
                        help="grid nodes along the box's longest side (default 128 in 3D, 512 in 2D)")
    add_trim_argument(parser)
    parser.add_argument("--combined", action="store_true",
                        help="a scene: one file holding every object's zero set (default: OUT-object-I.EXT each)")


def trim_distance(text: str):
    """``--trim`` value: a distance > 0, or 'auto' for the default."""
    if text == TRIM_DEFAULT:
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a distance > 0 in the data's units or 'auto', got {text!r} "
                                         "(a bare --trim goes after the input, or write --trim=DIST)") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a finite distance > 0 in the data's units, got {text!r}")
    return value


def add_trim_argument(parser: argparse.ArgumentParser, help: str = TRIM_HELP) -> None:
    parser.add_argument("--trim", nargs="?", const=TRIM_DEFAULT, type=trim_distance, metavar="DIST", help=help)


TRIM_DRAW_HELP = ("draw only the zero set within DIST of the data (the picture: the rest lighter; data units; "
                  "default, or 'auto': 2 x the median point spacing, at least 1%% of the box diagonal, holes between "
                  "samples kept)")


def check_trim_with_points(args: argparse.Namespace) -> None:
    """``--trim`` of a drawing command (plot, view) needs the data that ``--no-points`` leaves out."""
    from ..exceptions import InvalidInputError

    if args.trim is not None and args.no_points:
        raise InvalidInputError("--trim: it trims to the data, which --no-points leaves out. Drop one of them.")


def drawing_trim(trim, points) -> float | None:
    """The distance a drawing is trimmed to for ``--trim``'s value (None: not trimmed)."""
    from ..zeroset.trim import default_trim_distance

    if trim is None:
        return None
    return default_trim_distance(points) if trim == TRIM_DEFAULT else trim


def trimmed_note(trim: float | None) -> str:
    return "" if trim is None else f", zero sets trimmed to within {trim:.4g} of the data"


def trim_for_export(zero_set, points, faces, trim):
    """The zero set trimmed to the data as ``--trim`` asks (``trim`` is its value), with its
    one-line summary; an error when nothing is left to write."""
    from ..exceptions import InvalidInputError

    out = zero_set.trimmed(points, None if trim == TRIM_DEFAULT else trim, faces=faces)
    if out.is_empty and not zero_set.is_empty:
        raise InvalidInputError(f"--trim: no part of the zero set lies within {out.trim.distance:.4g} of the data, "
                                "so nothing would be written. Pass a larger distance, or check the fit.")
    return out, out.trim.describe()


def warn(command: str, message: str) -> None:
    print(f"ipfit {command}: warning: {message}", file=sys.stderr)


def check_output_suffix(path: str, dim: int) -> None:
    """Refuse an OUT whose extension is not a zero-set format for a ``dim``-D result, before any work."""
    from ..exceptions import InvalidInputError
    from ..zeroset.export import CURVE_FORMATS, MESH_FORMATS

    allowed, kind, example = (MESH_FORMATS, "a mesh", "out.ply") if dim == 3 else (CURVE_FORMATS, "curves",
                                                                                    "out.svg")
    suffix = Path(path).suffix.lower()
    if suffix not in allowed:
        got = repr(suffix) if suffix else f"{path!r} with no extension"
        raise InvalidInputError(f"-o/--output: expected a file name ending in {' or '.join(allowed)} for a {dim}D "
                                f"result ({kind}), got {got}. Use e.g. {example}.")


def _recorded_input(view):
    """The data recorded in a result: (Cloud, None) or (None, why it could not be used)."""
    from ..datasets import dataset_names
    from ..datasets.loading import load
    from ..exceptions import InvalidInputError

    record = view.input
    path, source = record.get("path"), record.get("source")
    candidates = []
    if isinstance(path, str):
        candidates.append(path)
    if isinstance(source, str) and (source in dataset_names() or path is None):
        candidates.append(source)  # a bundled name; a path typed for a result older than "input.path"
    if not candidates:
        return None, f"{view.source} does not record its data"
    reasons = []
    for spec in candidates:
        if spec not in dataset_names() and not Path(spec).is_file():
            reasons.append(f"{spec} does not exist" + ("" if Path(spec).is_absolute() else " (here)"))
            continue
        try:
            data = load(spec)
        except InvalidInputError as exc:
            reasons.append(str(exc).rstrip("."))
            continue
        n = record.get("n_points")
        if data.points.shape[1] != view.dim or (isinstance(n, int) and len(data.points) != n):
            reasons.append(f"{spec} has {len(data.points)} {data.points.shape[1]}D points, the result was "
                           f"fitted to {n if isinstance(n, int) else 'others'} {view.dim}D points")
            continue
        return data, None
    return None, "the data it records could not be found: " + "; ".join(reasons)


def _recorded_name(view) -> str:
    """How messages name the data a result records."""
    return f"{view.input.get('path') or view.input.get('source')} (the data {view.source} records)"


def load_points(spec: str | None, view, command: str, *, required: bool = False, missing: str = ""):
    """(points, faces) of --points DATA, or of the data recorded in the result, or (None, None).

    When the recorded data cannot be found, one warning line says so and what is done
    instead (``missing``); with ``required`` it is an error.
    """
    from .._result_schema import check_coordinates
    from ..datasets.loading import load
    from ..exceptions import InvalidInputError

    if spec is None:
        data, why = _recorded_input(view)
        if data is None:
            if required:
                raise InvalidInputError(f"--points: {why}. Pass the data with --points DATA.")
            if view.input:  # a plain polynomial records no data: nothing was expected
                warn(command, f"{why}; {missing}. Pass the data with --points DATA.")
            return None, None
    else:
        data = load(spec)
        if data.points.shape[1] != view.dim:
            raise InvalidInputError(f"--points: expected {view.dim}D points to match the result, got "
                                    f"{data.points.shape[1]}D in {spec}. Pass the data the result was fitted to.")
    check_coordinates(data.points, "--points" if spec is not None else _recorded_name(view))
    faces = data.faces if data.faces is not None and len(data.faces) else None
    return data.points, faces


def trim_data(view, spec: str | None):
    """(points, faces) to trim to: --points DATA, else the data the result records."""
    from .._result_schema import check_coordinates
    from ..exceptions import InvalidInputError

    if spec is not None:
        return load_points(spec, view, NAME)
    data, why = _recorded_input(view)
    if data is None:
        raise InvalidInputError(f"--trim: it needs the data to trim to, and {why}. Pass the data with --points DATA.")
    check_coordinates(data.points, _recorded_name(view))
    return data.points, data.faces if data.faces is not None and len(data.faces) else None


def result_box(view, spec: str | None, margin: float, command: str):
    """The box to extract or draw a result's zero set in: that of --points DATA when given, else
    the result's "bounds", else that of the data it records, else one around its normalisation."""
    from ..zeroset.extract import data_bounds, default_bounds

    points = None
    if spec is not None or view.bounds is None:
        points, _ = load_points(spec, view, command, missing="framing the box by the result's normalisation")
    if points is not None:
        return data_bounds(points, margin)
    if view.bounds is not None:
        return data_bounds(view.bounds.T, margin)
    return default_bounds(view.polynomial, margin)


def run(args: argparse.Namespace) -> int:
    from ..degree.results import result_view
    from ..exceptions import InvalidInputError
    from ..zeroset.extract import data_bounds, extract_zero_set
    from ._scene import is_scene_file, run_mesh

    if is_scene_file(args.result):  # a scene: every object in one page, figure or export (cli/_scene.py)
        return run_mesh(args, check_output_suffix)

    view = result_view(args.result)
    check_output_suffix(args.output, view.dim)
    outputs = Outputs([args.output], inputs=[args.result, args.points, *recorded_sources(view.data)])
    poly = view.fit(args.degree, name="--degree")
    summary = None
    if args.trim is None:
        box = result_box(view, args.points, args.margin, NAME)
        zero_set = extract_zero_set(poly, bounds=box, resolution=args.resolution)
    else:
        points, faces = trim_data(view, args.points)
        # the box of result_box, without loading the data a second time
        box = data_bounds(points if args.points is not None or view.bounds is None else view.bounds.T, args.margin)
        zero_set, summary = trim_for_export(extract_zero_set(poly, bounds=box, resolution=args.resolution), points,
                                            faces, args.trim)
    if zero_set.is_empty:  # refused here, where the output's own name (not its staged copy) is known
        raise InvalidInputError(f"{args.output}: the degree-{poly.degree} zero set is empty inside the box "
                                f"{box.tolist()}, so there is nothing to write. Widen the box (--margin, or "
                                "--points DATA), or check the fit.")
    with outputs.writing() as stage:
        zero_set.save(stage(args.output))
    if zero_set.dim == 3:
        mesh_vertices, mesh_faces = zero_set._mesh()
        what = f"{len(mesh_vertices)} vertices, {len(mesh_faces)} faces"
    else:
        what = f"{len(zero_set.curves)} curves"
    print(f"{args.output}: degree {poly.degree}, {what}, {zero_set.n_components} component(s), "
          f"{'closed' if zero_set.closed else 'open'} in the box, grid step {zero_set.step:.4g}")
    if summary:
        print(summary)
    return 0

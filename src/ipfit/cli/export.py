"""``ipfit export RESULT.json --to LANGUAGE [-o FILE]``: the fitted polynomial as source code."""

from __future__ import annotations

import argparse

from ._common import positive_int

NAME = "export"
HELP = "write the fitted polynomial (and its gradient) as Python, C, GLSL, LaTeX or SymPy source"
DESCRIPTION = """\
Write f and its gradient as a standalone function with the data normalisation folded in, in
nested Horner form (see ipfit.analysis.codegen): Python (f, gradient; works on numpy arrays), C
(ipfit_f, ipfit_gradient), GLSL (ipfit_f, ipfit_gradient, and ipfit_sdf = f/|grad f| for ray
marching, single precision), LaTeX (an aligned block listing the monomials in ipfit's graded
order) or SymPy (a script defining the expression f). Without -o the source goes to stdout.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..analysis.codegen import LANGUAGES

    parser.add_argument("result", metavar="RESULT.json", help="a result written by ipfit fit")
    parser.add_argument("--to", required=True, choices=LANGUAGES, help="target language")
    parser.add_argument("-o", "--output", metavar="FILE", help="write the source there (atomically) instead of stdout")
    parser.add_argument("--degree", type=positive_int, metavar="G",
                        help="export the fit of degree G from the result's per-degree table")


def run(args: argparse.Namespace) -> int:
    from .._utils.atomic import write_text_atomic
    from ..analysis.codegen import to_source
    from ..degree.results import result_view
    from ._common import Outputs, recorded_sources
    from ._scene import is_scene_file, run_export

    if is_scene_file(args.result):  # a scene: every object in one page, figure or export (cli/_scene.py)
        return run_export(args)

    view = result_view(args.result)
    outputs = Outputs([args.output], inputs=[args.result, *recorded_sources(view.data)]) if args.output else None
    poly = view.fit(args.degree, name="--degree")
    source = to_source(poly, args.to)
    if outputs is not None:  # args.output
        with outputs.writing() as stage:
            write_text_atomic(stage(args.output), source)
        print(f"{args.output}: {args.to} source of a degree-{poly.degree} {poly.dim}D polynomial")
    else:
        print(source, end="")
    return 0

"""``ipfit render RESULT.json -o IMAGE.png``: ray-cast image of a fitted surface."""

from __future__ import annotations

import argparse

from ._common import finite_float, nonnegative_float, positive_int

NAME = "render"
HELP = "ray-cast a 3D fit to a PNG: the exact zero set, shaded from the gradient"
DESCRIPTION = """\
Cast one ray per pixel (orthographic camera) into the box around the data, find every
intersection with the zero set exactly (roots of f restricted to the ray, see ipfit.analysis.rays) and
shade the first one from the normal grad f / |grad f|. Unlike `ipfit plot`, no mesh is built,
so thin parts and sharp features are drawn as they are. The box is the one recorded in the
result, or the data's (INPUT) with a margin.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a 3D result written by ipfit fit")
    parser.add_argument("-o", "--output", required=True, metavar="IMAGE.png", help="PNG file to write")
    parser.add_argument("--points", metavar="INPUT", help="the data (file or bundled name) framing the box")
    parser.add_argument("--degree", type=positive_int, metavar="G",
                        help="render the fit of degree G from the result's per-degree table")
    parser.add_argument("--size", type=positive_int, nargs=2, default=(480, 480), metavar=("W", "H"),
                        help="image size in pixels (default 480 480)")
    parser.add_argument("--margin", type=nonnegative_float, default=0.1,
                        help="margin around the box, as a fraction of its longest side (default 0.1)")
    parser.add_argument("--view", type=finite_float, nargs=2, default=(20.0, -60.0), metavar=("ELEV", "AZIM"),
                        help="camera elevation and azimuth in degrees (default 20 -60)")
    parser.add_argument("--up", choices=("x", "y", "z"), default="z",
                        help="the axis drawn vertically (default z; scanned meshes like the bunny are y-up)")


def run(args: argparse.Namespace) -> int:
    from ..analysis.rays import render
    from ..degree.results import result_view
    from ..exceptions import InvalidInputError
    from ._common import Outputs, recorded_sources, say_if_compiling
    from .mesh import result_box, warn

    if not args.output.lower().endswith(".png"):
        raise InvalidInputError(f"--output: expected a file ending in .png, got {args.output!r}. Use e.g. out.png.")
    view = result_view(args.result)
    outputs = Outputs([args.output], inputs=[args.result, args.points, *recorded_sources(view.data)])
    poly = view.fit(args.degree, name="--degree")
    if poly.dim != 3:
        raise InvalidInputError(f"{args.result}: expected a 3D surface to ray-cast, got a 2D curve. "
                                "Draw curves with ipfit plot.")
    box = result_box(view, args.points, args.margin, NAME)
    say_if_compiling("render", ("ipfit.analysis._ray_kernels",))
    with outputs.writing() as stage:
        image = render(poly, box, stage(args.output), size=tuple(args.size), view=tuple(args.view), up=args.up)
    covered = float((image < 255).any(axis=2).mean())
    if covered == 0:
        warn(NAME, f"no ray meets the degree-{poly.degree} zero set inside the box {box.round(6).tolist()}: the "
             "image is blank. Frame the surface with --points DATA or a larger --margin, or check the fit.")
    print(f"{args.output}: {image.shape[1]}x{image.shape[0]} ray-cast image, surface on {covered:.0%} of the pixels")
    return 0

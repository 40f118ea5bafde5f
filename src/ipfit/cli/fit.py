"""``ipfit fit INPUT``: read, normals, normalise, adaptive degree, write JSON + picture + zero set."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ._common import OutputSet, finite_float, load_input, nonnegative_float, positive_int, prepare_output_dir, show_progress

NAME = "fit"
HELP = "fit an implicit polynomial to a point file or a bundled dataset"
DESCRIPTION = """\
Fit an implicit polynomial to INPUT (a point file: PLY, OBJ, OFF, STL, XYZ/TXT/CSV, NPY/NPZ, or a
silhouette image; or the name of a bundled dataset, see `ipfit datasets`).

The degree is chosen adaptively (the paper's Algorithm 1, refusing degrees whose zero set has
spurious components when a clean one exists) unless --degree N fixes it. The default method is
DE + L-BFGS polish with a far-field term; --paper runs the paper's exact pipeline instead.
Outputs, all written
together or not at all:
  PREFIX.json   coefficients, normalisation, measures, selected_degree and the per-degree table
  PREFIX.png    the points with the zero set of each degree tried and the smoothness curve
  PREFIX.ply    the zero-set mesh (3D)   |   PREFIX.svg + PREFIX.csv  the zero-set curves (2D)

Ctrl-C stops cleanly: the outputs keep every degree already finished.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..adaptive import DEFAULT_METHOD, fixed_degree_methods

    parser.add_argument("input", metavar="INPUT", help="point file or bundled dataset name")
    parser.add_argument("-o", "--output", metavar="PREFIX",
                        help="output path prefix (default: the input's name in the current folder)")
    parser.add_argument("--degree", default="auto", metavar="auto|N",
                        help="'auto' for the adaptive degree (default), or a fixed even degree N")
    parser.add_argument("--max-degree", type=positive_int, metavar="G",
                        help="largest degree the adaptive loop tries (default 10 in 2D, 8 in 3D)")
    parser.add_argument("--method", default=DEFAULT_METHOD, choices=fixed_degree_methods(), metavar="METHOD",
                        help="fixed-degree method: " + ", ".join(fixed_degree_methods())
                        + f" (default {DEFAULT_METHOD}; 'de' and 'pso' are the paper's metaheuristics)")
    parser.add_argument("--epsilon", type=finite_float, default=0.01,
                        help="stop when smoothness improves by no more than this (default 0.01)")
    parser.add_argument("--delta", type=nonnegative_float, default=0.25,
                        help="penalty weight δ of the paper's distance (default 0.25)")
    parser.add_argument("--far-weight", type=nonnegative_float, default=None, metavar="W",
                        help="weight of the far-field term that keeps the zero set from growing spurious sheets "
                        "(default 0.1; 0 is the paper's objective)")
    parser.add_argument("--rule", choices=("geometric", "paper"), default="geometric",
                        help="degree rule: 'paper' is Algorithm 1 exactly; 'geometric' (default) also refuses a "
                        "degree whose zero set has spurious components or leaves the box when a clean one exists")
    parser.add_argument("--paper", action="store_true",
                        help="the paper's exact pipeline: --method de --far-weight 0 --rule paper, DE in the raw "
                        "coefficients seeded with the classic and 3L fits only")
    parser.add_argument("--iterations", type=positive_int, help="metaheuristic iterations (default 500)")
    parser.add_argument("--population", type=positive_int,
                        help="metaheuristic population (default 4 × the number of coefficients)")
    parser.add_argument("--seed", type=int, default=0, help="random seed for a reproducible run (default 0)")
    parser.add_argument("--normals", choices=("file", "estimate"), default=None,
                        help="use the file's normals or estimate them (default: the file's when present)")
    parser.add_argument("--no-picture", action="store_true", help="skip the PNG picture")
    parser.add_argument("--no-zero-set", action="store_true", help="skip the mesh / curve export")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    parser.add_argument("--max-points", type=positive_int, metavar="N",
                        help="keep a random subset of N points of a larger file (fixed seed; for big scans)")


class _Progress:
    def __init__(self, enabled: bool, iterations: int | None) -> None:
        self.enabled = enabled
        self.iterations = iterations
        self._last = 0.0

    def __call__(self, event: dict) -> None:
        if not self.enabled:
            return
        kind = event.get("event")
        if kind == "degree_start":
            sys.stderr.write(f"\rdegree {event['degree']}: fitting...{' ' * 30}")
        elif kind == "iteration":
            now = time.monotonic()
            if now - self._last < 0.1:
                return
            self._last = now
            total = f"/{self.iterations}" if self.iterations else ""
            fun = event.get("fun")
            best = f", best distance {fun:.5f}" if fun is not None else ""
            sys.stderr.write(f"\rdegree {event['degree']}: iteration {event.get('nit', '?')}{total}{best}   ")
        elif kind == "degree_done":
            sys.stderr.write(f"\rdegree {event['degree']}: distance {event['distance']:.5f}, smoothness "
                             f"{event['smoothness']:.4f}, dissimilarity {event['dissimilarity']:.5f} "
                             f"({event['seconds']:.1f} s)\n")
        sys.stderr.flush()


def _parse_degree(text: str, dim: int) -> int | None:
    from ..exceptions import InvalidInputError

    if text == "auto":
        return None
    try:
        value = int(text)
    except ValueError:
        raise InvalidInputError(f"--degree: expected 'auto' or a whole number, got {text!r}.") from None
    if value < 1:
        raise InvalidInputError(f"--degree: expected a degree >= 1, got {value}.")
    return value


def run(args: argparse.Namespace) -> int:
    from .. import basis
    from ..adaptive import fit_adaptive
    from ..exceptions import InvalidInputError
    from ..linear import LINEAR_METHODS

    data = load_input(args.input, max_points=args.max_points)
    points, normals = data.points, data.normals
    dim = points.shape[1]
    degree = _parse_degree(args.degree, dim)
    if degree is not None and basis.n_coefficients(dim, degree) > len(points):
        raise InvalidInputError(f"--degree: degree {degree} needs at least {basis.n_coefficients(dim, degree)} "
                                f"points, the input has {len(points)}. Lower the degree.")
    if args.normals == "file" and normals is None:
        raise InvalidInputError(f"--normals file: {args.input} has no normals. Use --normals estimate.")
    source = "file"
    if normals is None or args.normals == "estimate":
        from ..normals import estimate_normals

        normals = estimate_normals(points)
        source = "estimated"
    prefix = Path(args.output) if args.output else Path(data.label)
    params = {}
    if args.iterations is not None:
        params["iterations"] = args.iterations
    if args.population is not None:
        params["population"] = args.population
    if args.method in LINEAR_METHODS and params:
        raise InvalidInputError(f"--iterations/--population: method {args.method!r} is a linear fit and has no "
                                "iterations. Drop them or pick de, pso, de+polish or pso+polish.")
    method, far_weight, rule = args.method, args.far_weight, args.rule
    if args.paper:
        method, far_weight, rule = "de", 0.0, "paper"
        params.update(search_space="coefficients", seeds=["lstsq", "3l"])
    progress = _Progress(show_progress(args.quiet), args.iterations or 500)
    lo = degree if degree is not None else 2
    hi = degree if degree is not None else args.max_degree
    result = fit_adaptive(points, normals, method=method, min_degree=lo, max_degree=hi, epsilon=args.epsilon,
                          delta=args.delta, rule=rule, far_weight=far_weight, faces=data.faces, rng=args.seed,
                          progress=progress, **params)
    payload = result.to_dict()
    payload["input"] = {"source": str(args.input), "n_points": int(len(points)), "normals": source}
    payload["bounds"] = np.column_stack([points.min(axis=0), points.max(axis=0)]).tolist()
    _write_outputs(prefix, payload, result, points, data, args)
    if not args.quiet:
        table = ", ".join(f"{d.degree}: {d.smoothness:.4f}" for d in result.degrees)
        print(f"selected degree {result.selected_degree} ({result.reason}); smoothness by degree {table}")
        print(f"wrote {prefix}.json" + ("" if args.no_picture else f", {prefix}.png")
              + ("" if args.no_zero_set else (f", {prefix}.ply" if dim == 3 else f", {prefix}.svg, {prefix}.csv")))
    return 130 if result.reason == "interrupted" else 0


def _beside(prefix: Path, suffix: str) -> Path:
    return prefix.with_name(prefix.name + suffix)


def _write_outputs(prefix: Path, payload: dict, result, points, data, args) -> None:
    from ..export import save_zero_set
    from ..zeroset import extract_zero_set

    prepare_output_dir(prefix)
    with OutputSet() as out:
        zero_set = None
        if not (args.no_zero_set and args.no_picture):
            zero_set = extract_zero_set(result.polynomial, points=points)
        if not args.no_zero_set:
            if points.shape[1] == 3:
                save_zero_set(zero_set, out.path(_beside(prefix, ".ply")))
            else:
                save_zero_set(zero_set, out.path(_beside(prefix, ".svg")))
                save_zero_set(zero_set, out.path(_beside(prefix, ".csv")))
        if not args.no_picture:
            from ..plotting import plot_result

            plot_result(payload, points=points, path=out.path(_beside(prefix, ".png")))
        out.path(_beside(prefix, ".json")).write_text(json.dumps(payload, indent=1), encoding="utf-8")
        out.commit()

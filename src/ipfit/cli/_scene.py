"""Scenes on the command line: ``ipfit fit FILE --objects`` and the result commands on a scene JSON.

``fit`` adds its options here (:func:`add_fit_arguments`) and hands ``--objects`` over to
:func:`run_fit`; ``view``, ``plot``, ``mesh`` and ``export`` hand a scene result (one listing
``objects``) to :func:`run_view`, :func:`run_plot`, :func:`run_mesh` and :func:`run_export`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ._common import Outputs, beside, cli_names, default_prefix, fit_prefix, positive_int


def add_fit_arguments(parser: argparse.ArgumentParser) -> None:
    """``ipfit fit``'s scene options."""
    parser.add_argument("--objects", action="store_true",
                        help="a scene: find every object (dominant planes removed, the rest split by connectivity; "
                        "every silhouette of an image) and fit each with its own polynomial; PREFIX.json lists them")
    parser.add_argument("--keep-planes", action="store_true",
                        help="with --objects: also keep each removed plane as a degree-1 polynomial in the result")
    parser.add_argument("--workers", type=positive_int, default=None, metavar="N",
                        help="with --objects: fit the objects on an embedded Dask cluster of N worker processes")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="with --objects: fit the objects on the Dask scheduler at ADDRESS")


def is_scene_file(path) -> bool:
    """Whether RESULT.json is a scene (it lists ``objects``); a file that cannot be read is not
    (its own reader then says why)."""
    from ..degree.results import load_result
    from ..exceptions import InvalidInputError

    try:
        return isinstance(load_result(path).get("objects"), list)
    except (InvalidInputError, OSError):
        return False


def _read_scan(args):
    """(points, normals or None, labels or None, name, normals source) of INPUT."""
    from ..datasets.loading import load
    from ..io.silhouettes import IMAGE_SUFFIXES, read_silhouettes

    path = Path(args.input)
    if path.suffix.lower() in IMAGE_SUFFIXES and path.is_file():
        shapes = read_silhouettes(path)
        points = np.vstack([p for p, _ in shapes])
        normals = np.vstack([n for _, n in shapes])
        labels = np.concatenate([np.full(len(p), i) for i, (p, _) in enumerate(shapes)])
        return points, normals, labels, path.stem, "contour"
    data = load(args.input, max_points=args.max_points)
    given = None if args.normals == "estimate" else data.normals
    return data.points, given, None, data.name, "file" if given is not None else "estimated"


def _suffixes(args, dim: int) -> list[str]:
    suffixes = [".json"] + ([] if args.no_picture else [".png"])
    suffixes += [] if args.no_zero_set else ([".ply"] if dim == 3 else [".svg", ".csv"])
    return suffixes + ([".html"] if args.html else [])


def run_fit(args: argparse.Namespace, settings, parse_degree, names: dict) -> int:
    """``ipfit fit INPUT --objects``: PREFIX.json (the scene), PREFIX.png, the zero sets, PREFIX.html.

    ``settings`` is ``(method, options, rule)`` and ``parse_degree(text, dim)`` reads --degree, as
    ``ipfit fit`` has them (passed in: this module is below ``cli/fit.py``); ``names`` maps the
    library's parameters to the options typed."""
    from .._result_schema import check_coordinates
    from ..exceptions import InvalidInputError
    from ..scene.draw import object_zero_sets, plot_scene, write_scene_html, write_zero_sets
    from ..scene.fit import fit_scene

    if args.workers is not None and args.scheduler is not None:
        raise InvalidInputError("--workers/--scheduler: pick one (an embedded cluster of N workers, or the "
                                "scheduler at ADDRESS).")
    if args.trim is not None and args.no_zero_set:
        raise InvalidInputError("--trim: it trims the exported zero set, which --no-zero-set skips. Drop one of them.")
    points, normals, labels, name, normals_source = _read_scan(args)
    if args.normals == "file" and normals is None:
        raise InvalidInputError(f"--normals file: {args.input} has no normals. Use --normals estimate.")
    check_coordinates(points)
    dim = points.shape[1]
    degree = parse_degree(args.degree, dim)
    suffixes = _suffixes(args, dim)
    prefix = fit_prefix(args.output) if args.output else default_prefix(name, suffixes, [args.input])
    outputs = Outputs([beside(prefix, s) for s in suffixes], inputs=[args.input], make_folders=True)
    method, options, rule = settings
    outliers = "none" if args.paper else ("auto" if args.outliers is None else args.outliers)

    def progress(event):
        if args.quiet:
            return
        f = event["f_score"]
        print(f"object {event['index']} of {event['n_objects']}: {event['n_points']:,} points, degree "
              f"{event['selected_degree']}" + ("" if f is None else f", F-score {f:.3f}")
              + (" (may be two touching objects, fitted as one)" if event["touching"] else ""), file=sys.stderr)

    with cli_names({**names, "workers": "--workers", "labels": "INPUT"}):
        scene = fit_scene(points, normals, labels=labels, keep_planes=args.keep_planes, outliers=outliers,
                          method=method, options=options, min_degree=degree or 2,
                          max_degree=degree if degree is not None else args.max_degree, epsilon=args.epsilon,
                          delta=args.delta, rule=rule, rng=args.seed, workers=args.workers,
                          scheduler=args.scheduler, progress=progress)
    source = str(args.input)
    payload = scene.to_dict(source, str(Path(args.input).resolve()) if Path(args.input).exists() else None,
                            normals_source)
    trim_note = None
    with outputs.writing() as stage:
        zero_sets = object_zero_sets(payload, points=points, trim=args.trim) if not (
            args.no_zero_set and args.no_picture and not args.html) else None
        if not args.no_zero_set and zero_sets is not None:
            for suffix in [".ply"] if dim == 3 else [".svg", ".csv"]:
                write_zero_sets(zero_sets, stage(beside(prefix, suffix)))
            if args.trim is not None:
                trim_note = f"zero sets trimmed to each object's points (--trim {args.trim})"
        if not args.no_picture:
            plot_scene(payload, points, stage(beside(prefix, ".png")), zero_sets=zero_sets)
        if args.html:
            write_scene_html(payload, points, stage(beside(prefix, ".html")), zero_sets=zero_sets)
        stage(beside(prefix, ".json")).write_text(json.dumps(payload, indent=1), encoding="utf-8")
    if not args.quiet:
        for i in scene.touching:
            print(f"object {i}: {scene.segmentation.objects[i].note}")
        print(f"found {scene.message}")
        for i, result in enumerate(scene):
            chosen = result.at_degree(result.selected_degree)
            f = "" if chosen.quality is None else f", F-score {chosen.quality.f_score:.3f}"
            print(f"object {i}: {scene.segmentation.objects[i].n_points:,} points, degree "
                  f"{result.selected_degree}{f}")
        print("wrote " + ", ".join(str(beside(prefix, s)) for s in suffixes))
        if trim_note:
            print(trim_note)
    return 0


def _scan_points(view, spec: str | None, no_points: bool = False):
    """The scene's scan (--points DATA, else the file it records), or None; its labels must match."""
    from ..datasets.loading import load
    from ..exceptions import InvalidInputError
    from ..io.silhouettes import IMAGE_SUFFIXES, read_silhouettes

    if no_points:
        return None
    record = view.input
    target = spec or record.get("path")
    if target is None:
        return None
    try:
        if Path(target).suffix.lower() in IMAGE_SUFFIXES and Path(target).is_file():
            points = np.vstack([p for p, _ in read_silhouettes(target)])
        else:
            points = load(target).points
    except InvalidInputError:
        if spec:
            raise
        print(f"ipfit: warning: the scan {target} could not be read; drawing the zero sets without it",
              file=sys.stderr)
        return None
    if points.shape[1] != view.dim:
        raise InvalidInputError(f"--points: expected {view.dim}D points to match the scene, got {points.shape[1]}D.")
    return points


def run_view(args: argparse.Namespace) -> int:
    from ..scene.draw import write_scene_html
    from ..scene.results import load_scene
    from ._common import recorded_sources

    view = load_scene(args.result)
    output = Path(args.output) if args.output else Path(args.result).with_suffix(".html")
    outputs = Outputs([output], inputs=[args.result, args.points, *recorded_sources(view.data)])
    points = _scan_points(view, args.points, args.no_points)
    with outputs.writing() as stage:
        write_scene_html(view, points, stage(output), title=args.title)
    print(f"{output}: {output.stat().st_size / 1e6:.1f} MB, {len(view)} objects")
    return 0


def run_plot(args: argparse.Namespace) -> int:
    from ..scene.draw import plot_scene
    from ..scene.results import load_scene
    from ..viz.plotting import check_figure_path
    from ._common import recorded_sources

    check_figure_path(args.output, "-o/--output")
    view = load_scene(args.result)
    outputs = Outputs([args.output], inputs=[args.result, args.points, *recorded_sources(view.data)])
    points = _scan_points(view, args.points, args.no_points)
    with outputs.writing() as stage:
        plot_scene(view, points, stage(args.output), title=args.title, view=tuple(args.view), up=args.up, dpi=args.dpi)
    print(f"{args.output}: {len(view)} objects")
    return 0


def run_mesh(args: argparse.Namespace, check_output_suffix) -> int:
    """``ipfit mesh SCENE.json``; ``check_output_suffix(path, dim)`` is ``cli/mesh.py``'s (this module is below it)."""
    from ..exceptions import InvalidInputError
    from ..scene.draw import object_path, object_zero_sets, write_zero_sets
    from ..scene.results import load_scene
    from ._common import recorded_sources

    view = load_scene(args.result)
    check_output_suffix(args.output, view.dim)
    if args.degree is not None:
        raise InvalidInputError("--degree: a scene holds one fit per object; export their selected degrees, or "
                                "take one object's result out of \"objects\".")
    targets = [Path(args.output)] if args.combined else [object_path(args.output, i) for i in range(len(view))]
    outputs = Outputs(targets, inputs=[args.result, args.points, *recorded_sources(view.data)])
    points = _scan_points(view, args.points) if args.trim is not None else None
    if args.trim is not None and points is None:
        raise InvalidInputError("--trim: it needs the scan, which the scene does not record. Pass --points DATA.")
    zero_sets = object_zero_sets(view, margin=args.margin, resolution=args.resolution, points=points, trim=args.trim)
    empty = [i for i, zs in enumerate(zero_sets) if zs.is_empty]
    if empty:
        raise InvalidInputError(f"{args.output}: the zero set of object{'s' if len(empty) > 1 else ''} "
                                f"{', '.join(map(str, empty))} is empty in its box, so there is nothing to write. "
                                "Widen the box (--margin), or check the fit.")
    with outputs.writing() as stage:
        if args.combined:
            write_zero_sets(zero_sets, stage(targets[0]))
        else:
            for target, zs in zip(targets, zero_sets, strict=True):
                write_zero_sets([zs], stage(target))
    print(f"{'one file' if args.combined else f'{len(targets)} files'} for {len(view)} objects: "
          + ", ".join(map(str, targets)))
    return 0


def run_export(args: argparse.Namespace) -> int:
    from .._utils.atomic import write_text_atomic
    from ..exceptions import InvalidInputError
    from ..scene.results import load_scene
    from ._common import recorded_sources

    view = load_scene(args.result)
    if args.degree is not None:
        raise InvalidInputError("--degree: a scene holds one fit per object; its export is every object's "
                                "selected degree.")
    outputs = Outputs([args.output], inputs=[args.result, *recorded_sources(view.data)]) if args.output else None
    source = scene_source(view, args.to)
    if outputs is not None:
        with outputs.writing() as stage:
            write_text_atomic(stage(args.output), source)
        print(f"{args.output}: {args.to} source of {len(view)} objects (one function per object)")
    else:
        print(source, end="")
    return 0


# The names each language's export defines, renamed per object (f -> f_0, ipfit_f -> ipfit_f_0, ...).
_NAMES = {"python": ("f", "gradient"), "sympy": ("f", "gradient"), "c": ("ipfit_f", "ipfit_gradient"),
          "glsl": ("ipfit_f", "ipfit_gradient", "ipfit_sdf"), "latex": ()}


def scene_source(view, language: str) -> str:
    """Every object's export, one after the other, with its names suffixed by the object's index."""
    import re

    from ..analysis.codegen import to_source

    parts = []
    for i, obj in enumerate(view.objects):
        text = to_source(obj.polynomial, language)
        for name in _NAMES.get(language, ()):
            text = re.sub(rf"(?<![\w.]){re.escape(name)}(?!\w)", f"{name}_{i}", text)
        if language == "latex":
            text = text.replace("f(", f"f_{{{i}}}(", 1).replace("\nf(", f"\nf_{{{i}}}(")
        comment = "%" if language == "latex" else "#" if language in ("python", "sympy") else "//"
        box = obj.data.get("bounding_box")
        parts.append(f"{comment} object {i} of {len(view)}: {obj.data.get('n_points', '?')} points in the box "
                     f"{box}\n{text}")
    return "\n".join(parts)

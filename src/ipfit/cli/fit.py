"""``ipfit fit INPUT``: read, normals, normalise, adaptive degree, write JSON + picture + zero set."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ._common import (
    FIT_KERNELS,
    LazyChoices,
    Outputs,
    beside,
    cli_names,
    default_prefix,
    finite_float,
    fit_prefix,
    nonnegative_float,
    nonnegative_int,
    positive_int,
    say_if_compiling,
    stop_at_iterations,
)
from ._progress import Progress, progress_mode
from .mesh import add_trim_argument, trim_for_export

# Library parameter -> the option the user typed, for error messages.
_OPTION_NAMES = {"max_degree": "--max-degree", "min_degree": "--degree", "rng": "--seed", "epsilon": "--epsilon",
                 "delta": "--delta", "iterations": "--iterations", "population_size": "--population",
                 "far_term_weight": "--far-term-weight",
                 "method": "--method", "rule": "--rule", "outliers": "--outliers"}

NAME = "fit"
HELP = "fit an implicit polynomial to a point file or a bundled dataset"
DESCRIPTION = """\
Fit an implicit polynomial to INPUT: a point file (PLY, OBJ, OFF, STL, glTF/GLB, 3MF, XYZ/TXT/CSV,
NPY/NPZ, LAS/LAZ, PCD, E57 or a silhouette image; `ipfit datasets --formats` lists them) or the
name of a bundled dataset (`ipfit datasets`).

The degree is chosen adaptively (the paper's Algorithm 1, refusing degrees whose zero set has
spurious components when a clean one exists, after trying to polish them away) unless --degree N
fixes it. The default is the recommended pipeline (DE + L-BFGS polish with a far-field term);
--paper runs the paper's exact pipeline instead. Every degree's reason (selected, rejected, not
needed) is printed and stored in the JSON.

Outputs, all written together or not at all (-o PREFIX, or -o PREFIX.json):
  PREFIX.json   coefficients, normalisation, measures, selected_degree and the per-degree table
  PREFIX.png    the points with the zero set of each degree tried and the smoothness curve
  PREFIX.ply    the zero-set mesh (3D)   |   PREFIX.svg + PREFIX.csv  the zero-set curves (2D)
  PREFIX.html   with --html: an interactive viewer of every degree (works offline)

--trim [DIST] exports only the part of the zero set within DIST of the data (an open scan stays
open; without DIST: 2 x the median point spacing, or 1% of the box diagonal if larger, holes
between samples kept); the picture draws the trimmed part lighter and the HTML viewer shows the
same trimmed zero sets; the polynomial and the JSON keep the whole fit, and one line says what
went. Without --trim, one line says so when the selected zero set reaches the data but part of
it lies away from the data (its precision at least 0.1 below its recall, the lid a polynomial
puts over an open scan's opening).

Odd degrees are accepted with a warning: their zero set is never bounded. Ctrl-C (or SIGTERM)
stops cleanly: the outputs keep every degree already finished; before the first one, nothing
is written.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="point file or bundled dataset name")
    parser.add_argument("-o", "--output", metavar="PREFIX",
                        help="output path prefix (default: the input's name in the current folder)")
    add_fit_options(parser)
    parser.add_argument("--normals", choices=("file", "estimate"), default=None,
                        help="use the file's normals or estimate them (default: the file's when present)")
    parser.add_argument("--no-picture", action="store_true", help="skip the PNG picture")
    parser.add_argument("--no-zero-set", action="store_true", help="skip the mesh / curve export")
    add_trim_argument(parser)
    parser.add_argument("--html", action="store_true",
                        help="also write PREFIX.html: an interactive viewer of every degree (works offline)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    parser.add_argument("--max-points", type=positive_int, metavar="N",
                        help="keep a random subset of N points of a larger file (fixed seed; for big scans)")
    parser.add_argument("--largest-outline", action="store_true",
                        help="a silhouette image: fit the outline of the largest shape alone, without its holes")
    from ._scene import add_fit_arguments

    add_fit_arguments(parser)


def add_fit_options(parser: argparse.ArgumentParser) -> None:
    """The fit options shared by ``ipfit fit`` and ``ipfit batch`` (read back by :func:`search_settings`).

    The method and rule names are listed on first use (:class:`LazyChoices`): their registries
    import the whole fitting stack, which a batch with nothing to do never needs.
    """
    from ..fitting.options import (
        DEFAULT_DELTA,
        DEFAULT_EPSILON,
        DEFAULT_ITERATIONS,
        DEFAULT_METHOD,
        PAPER,
        PAPER_METHOD,
        PAPER_RULE,
        RECOMMENDED,
    )

    parser.add_argument("--degree", default="auto", metavar="auto|N",
                        help="'auto' for the adaptive degree (default), or a fixed even degree N")
    parser.add_argument("--max-degree", type=positive_int, metavar="G",
                        help="largest degree the adaptive loop tries (default: 20 in 2D and 12 in 3D with the capture "
                        "rule, beyond 14 in 2D and 8 in 3D only while each degree raises the F-score, within 2 "
                        "points per coefficient; 10 in 2D and 8 in 3D with the other rules)")
    parser.add_argument("--method", default=None, choices=LazyChoices(_method_names), metavar="METHOD",
                        help="fixed-degree method: %(choices)s"
                        f" (default {DEFAULT_METHOD}; 'de' and 'pso' are the paper's metaheuristics)")
    parser.add_argument("--epsilon", type=finite_float, default=DEFAULT_EPSILON,
                        help=f"stop when smoothness improves by no more than this (default {DEFAULT_EPSILON})")
    parser.add_argument("--delta", type=nonnegative_float, default=DEFAULT_DELTA,
                        help=f"penalty weight δ of the paper's distance (default {DEFAULT_DELTA})")
    parser.add_argument("--far-term-weight", dest="far_term_weight", type=nonnegative_float,
                        default=None, metavar="W",
                        help="weight of the far-field term that keeps the zero set from growing spurious sheets "
                        f"(default {RECOMMENDED.far_term_weight:g}; 0 is the paper's objective)")
    parser.add_argument("--rule", choices=LazyChoices(_rule_names), default=None, metavar="RULE",
                        help="degree rule: 'capture' (default) goes on while a degree gains substantially, stops "
                        "once the shape is captured and takes the lowest clean degree within 0.01 of the best "
                        "F-score; 'geometric' is Algorithm 1 restricted to clean degrees; 'paper' is Algorithm 1 "
                        "exactly")
    parser.add_argument("--outliers", type=outlier_setting, default=None, metavar="auto|none|SHARE",
                        help="which points are stray returns, left out of the fit: 'auto' (default) finds them "
                        "from the data (none on clean data), 'none' fits every point, a share such as 0.1 marks "
                        "that many of the most outlying points")
    parser.add_argument("--paper", action="store_true",
                        help=f"the paper's exact pipeline: --method {PAPER_METHOD} --far-term-weight "
                        f"{PAPER.far_term_weight:g} --rule {PAPER_RULE}, DE in the raw coefficients started from "
                        "the " + " and ".join(PAPER.start_fits) + " fits only")
    parser.add_argument("--iterations", type=positive_int,
                        help=f"metaheuristic iterations (default {DEFAULT_ITERATIONS})")
    parser.add_argument("--population", type=positive_int,
                        help="metaheuristic population (default 4 × the number of coefficients)")
    parser.add_argument("--seed", type=nonnegative_int, default=0,
                        help="random seed for a reproducible run (default 0)")


def _method_names() -> tuple[str, ...]:
    """``degree.adaptive.fixed_degree_methods()`` from the registries themselves: importing
    degree.adaptive (robust, scipy.stats, ...) would cost a batch with nothing to do a second
    (tests/test_newuser_messages.py checks the two agree)."""
    from ..fitting.linear import LINEAR_METHODS
    from ..fitting.refine import REFINE_METHODS

    return tuple(LINEAR_METHODS) + REFINE_METHODS


def _rule_names() -> list[str]:
    from ..degree.rules import RULES

    return list(RULES)


def outlier_setting(text: str) -> str | float:
    """--outliers: 'auto', 'none' or a share, checked by the library's one rule."""
    from ..exceptions import InvalidInputError
    from ..robust import check_outliers

    try:
        return check_outliers(text if text in ("auto", "none") else float(text))
    except (ValueError, InvalidInputError):
        raise argparse.ArgumentTypeError(f"expected auto, none or a share from 0 to 0.9, got {text!r}") from None


def search_settings(args: argparse.Namespace):
    """(method, options, rule) from the command line: --paper is the library's preset exactly."""
    from ..exceptions import InvalidInputError
    from ..fitting.linear import LINEAR_METHODS
    from ..fitting.options import DEFAULT_METHOD, DEFAULT_RULE, PAPER, PAPER_METHOD, PAPER_RULE, RECOMMENDED

    if args.paper:
        clash = [flag for flag, value in (("--method", args.method), ("--rule", args.rule),
                                          ("--far-term-weight", args.far_term_weight),
                                          ("--outliers", args.outliers)) if value is not None]
        if clash:
            raise InvalidInputError(f"--paper: it fixes {', '.join(clash)}; drop {'it' if len(clash) == 1 else 'them'} "
                                    "or drop --paper.")
        method, options, rule = PAPER_METHOD, PAPER, PAPER_RULE
    else:
        method, options, rule = args.method or DEFAULT_METHOD, RECOMMENDED, args.rule or DEFAULT_RULE
        if args.far_term_weight is not None:
            options = options.replace(far_term_weight=args.far_term_weight)
    changes = {name: value for name, value in (("iterations", args.iterations), ("population_size", args.population))
               if value is not None}
    if method in LINEAR_METHODS:
        if changes or args.far_term_weight is not None:
            raise InvalidInputError(f"--iterations/--population/--far-term-weight: method {method!r} is a linear fit "
                                    "and has no search. Drop them or pick de, pso, de+polish or pso+polish.")
        return method, None, rule
    return method, options.replace(**changes) if changes else options, rule


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
    if value % 2:
        # Accepted (a user may want it), but said: the highest-degree part of an odd-degree
        # polynomial changes sign, so its zero set always runs off to infinity.
        print(f"ipfit fit: warning: --degree {value} is odd: an odd-degree zero set is never bounded (it always "
              "reaches infinity); use an even degree for a closed curve or surface.", file=sys.stderr)
    return value


def _warn_high_degree(option: str, degree: int | None, dim: int, limit: int | None = None) -> None:
    """One stderr line when a degree goes beyond the highest the capture rule tries by default
    (``CAPTURE_MAX_DEGREE``, the README's "last degree"): ipfit accepts up to its hard limit
    (``basis.MAX_DEGREE``), but the monomial basis conditions badly and each degree costs more.
    ``limit``: the option's value when ``degree`` is the highest one the loop reached under it."""
    from ..degree.rules import CAPTURE_MAX_DEGREE

    top = CAPTURE_MAX_DEGREE[dim]
    if degree is None or degree <= top:
        return
    what = f"{option} {degree} is" if limit is None else f"{option} {limit}: the fit went to degree {degree},"
    print(f"ipfit fit: warning: {what} above {top}, the highest degree ipfit tries and is tested at in {dim}D: "
          "expect slow fits, poor conditioning and spurious pieces.", file=sys.stderr)


def _report_kept(data, max_points: int | None) -> None:
    """One stderr line when --max-points dropped points: the loader only records the counts."""
    if max_points is None or len(data) >= data.n_file:
        return
    if isinstance(data.source, Path):
        print(f"ipfit: {data.source}: kept {len(data):,} of the file's {data.n_file:,} points "
              f"(--max-points {max_points}, fixed seed)", file=sys.stderr)
    else:
        print(f"ipfit: {data.source}: kept {len(data):,} of its {data.n_file:,} points (--max-points, fixed seed)",
              file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    from .. import basis
    from .._result_schema import check_coordinates
    from ..datasets.loading import load
    from ..degree.adaptive import fit_adaptive
    from ..exceptions import InvalidInputError

    if args.objects:  # a scene: every object its own fit (cli/_scene.py)
        from ._scene import run_fit

        return run_fit(args, search_settings(args), _parse_degree, _OPTION_NAMES)
    if args.keep_planes or args.workers is not None or args.scheduler is not None:
        raise InvalidInputError("--keep-planes/--workers/--scheduler: they apply to a scene; add --objects.")
    data = load(args.input, max_points=args.max_points, largest_outline=args.largest_outline)
    _report_kept(data, args.max_points)
    points, normals = data.points, data.normals
    check_coordinates(points)  # before any line about the fit: data it cannot record is refused first
    dim = points.shape[1]
    degree = _parse_degree(args.degree, dim)
    if degree is not None and basis.n_coefficients(dim, degree) > len(points):
        raise InvalidInputError(f"--degree: degree {degree} needs at least {basis.n_coefficients(dim, degree)} "
                                f"points, the input has {len(points)}. Lower the degree.")
    if args.normals == "file" and normals is None:
        raise InvalidInputError(f"--normals file: {args.input} has no normals. Use --normals estimate.")
    if args.trim is not None and args.no_zero_set:
        raise InvalidInputError("--trim: it trims the exported zero set, which --no-zero-set skips. Drop one of them.")
    prefix, outputs = _plan_outputs(args, data.name, dim)
    # the paper fits every point; otherwise stray returns are found first ("auto" on a mesh finds none)
    outliers = "none" if args.paper else ("auto" if args.outliers is None else args.outliers)
    source = "file"
    if not args.quiet:  # the first run after an install sits ~20 s compiling: say so first
        say_if_compiling("fit", FIT_KERNELS + (("ipfit.normals._scale_kernels",)
                                               if normals is None or args.normals == "estimate" else ()))
    if normals is None or args.normals == "estimate":
        source = "estimated"
        if not args.quiet:  # on a big noisy cloud this takes a while: say what is happening
            after = "" if outliers == "none" else ", after setting its outliers aside"
            print(f"ipfit fit: {args.input} has no normals: estimating them from its {len(points):,} points{after}"
                  if normals is None else f"ipfit fit: estimating normals from the {len(points):,} points{after} "
                  "(--normals estimate: the file's are not used)", file=sys.stderr)
        if outliers == "none":
            from ..normals import estimate_normals

            normals = estimate_normals(points, progress=Progress(progress_mode(args.quiet)))
        else:
            normals = None  # estimated by the fit, on the points it keeps
    method, options, rule = search_settings(args)
    if degree is not None:  # once every check has passed: the warning starts a fit, never precedes an error
        _warn_high_degree("--degree", degree, dim)
    resolved = options.for_method(method, dim=dim) if options is not None else None
    shown = Progress(progress_mode(args.quiet), resolved and resolved.iterations,
                     resolved and resolved.polish_iterations)
    progress = stop_at_iterations(shown)
    lo = degree if degree is not None else 2
    hi = degree if degree is not None else args.max_degree
    try:
        with cli_names(_OPTION_NAMES):
            result = fit_adaptive(points, normals, method=method, options=options, min_degree=lo, max_degree=hi,
                                  epsilon=args.epsilon, delta=args.delta, rule=rule, faces=data.faces,
                                  outliers=outliers, rng=args.seed, progress=progress)
    finally:
        shown.close()
    if degree is None:  # --max-degree: said when the loop went there (it may stop before; the fit checked it)
        _warn_high_degree("--max-degree", max((d.degree for d in result.degrees), default=None), dim,
                          limit=args.max_degree)
    payload = result.to_dict()
    payload["input"] = {"source": str(args.input), "n_points": len(points), "normals": source}
    if Path(args.input).exists():  # found again by ipfit plot/mesh/score from any folder
        payload["input"]["path"] = str(Path(args.input).resolve())
    payload["bounds"] = np.column_stack([points.min(axis=0), points.max(axis=0)]).tolist()
    trimmed = _write_outputs(outputs, prefix, payload, result, points, normals, data, args)
    if not args.quiet:
        found = result.outliers
        if found is not None and found.count:
            print(f"{found.count:,} points ({found.outlier_share:.1%}) treated as outliers and left out of the fit"
                  + (f"; noise scale {found.noise_scale:.3g}" if found.noise_scale else ""))
        table = ", ".join(f"{d.degree}: {d.smoothness:.4f}" for d in result.degrees)
        for entry in result.degrees:
            if entry.reason.startswith("rejected"):
                print(f"degree {entry.degree} {entry.reason}")
            elif entry.quality is not None and entry.quality.topology_matches is False:
                print(_topology_line(entry))
        if result.reason == "fixed":
            chosen = result.at_degree(result.selected_degree)
            line = f"fixed degree {result.selected_degree}: smoothness {table.split(': ')[1]}"
            if chosen.quality is not None:
                line += f", F-score {chosen.quality.f_score:.3f}"
                # the figure marks them in red; a fixed degree has no rule to reject it, so say it here
                count = chosen.quality.n_spurious
                if count:
                    line += (f"; {count} spurious piece{'s' if count > 1 else ''} (zero-set components away from "
                             "the data" + ("" if args.no_picture else ", red in the figure") + ")")
            print(line)
        else:
            print(f"selected {result.message}; smoothness by degree {table}")
        print("wrote " + ", ".join(str(beside(prefix, suffix)) for suffix in _suffixes(args, dim)))
        if trimmed:
            print(trimmed)
        elif args.trim is None:
            hint = _trim_hint(result.at_degree(result.selected_degree).quality, args, prefix)
            if hint:
                print(hint)
    return 130 if result.reason == "interrupted" else 0


#: The zero set reaches the data (recall at least the capture rule's REPAIR_RECALL) and has this
#: much more of it away from the data than the data has away from it: a lid over an open scan (the
#: open cup of tests/test_trim.py: precision 0.83-0.86 at recall 1), a sheet over a thin part; a
#: closed shape fitted well has the two within a few hundredths (the bunny 0.998 / 0.998).
_HINT_EXCESS = 0.1


def _trim_hint(q, args: argparse.Namespace, prefix: Path) -> str | None:
    """One line pointing at ``--trim`` when the selected zero set covers the data but part of it
    lies away from the data, as a polynomial's zero set does over an open scan's openings."""
    from ..degree.rules import REPAIR_RECALL

    if q is None or q.recall < REPAIR_RECALL or q.recall - q.precision < _HINT_EXCESS:
        return None
    how = (f"`ipfit mesh {beside(prefix, '.json')} --trim` writes" if args.no_zero_set else
           "--trim exports")
    return (f"part of the zero set lies away from the data (precision {q.precision:.3f} at recall "
            f"{q.recall:.3f}: a lid over an open scan's opening, or a bulge past a thin part); {how} only the "
            "part near the data")


def _topology_line(entry) -> str:
    """'degree 14: 5 loops where the data has 1': a zero set of another shape than the data's,
    and, when a repair round reached the data's (said while it ran) but the degree kept its own
    fit, that round's F-score: the progress line and this one then tell one story."""
    from ..zeroset.topology import describe_mismatch

    q = entry.quality
    line = f"degree {entry.degree}: {describe_mismatch(q.topology, q.data_topology)}"
    reached = [a for a in entry.cleanup if a.get("topology_matches") is True]
    if reached:
        best = max(reached, key=lambda a: (a["clean"], a["f_score"]))
        line += (f"; a repair reached the data's topology at F-score {best['f_score']:.3f}"
                 f"{'' if best['clean'] else ' with a zero set not clean'}, not kept")
    return line


def _suffixes(args: argparse.Namespace, dim: int) -> list[str]:
    """The outputs' suffixes: the ones checked before the fit and listed in the "wrote" line."""
    suffixes = [".json"] + ([] if args.no_picture else [".png"])
    suffixes += [] if args.no_zero_set else ([".ply"] if dim == 3 else [".svg", ".csv"])
    return suffixes + ([".html"] if args.html else [])


def _plan_outputs(args: argparse.Namespace, label: str, dim: int) -> tuple[Path, Outputs]:
    """The prefix and its outputs, checked (writable, not an input, not a folder) before the fit."""
    suffixes = _suffixes(args, dim)
    inputs = [args.input]
    prefix = fit_prefix(args.output) if args.output else default_prefix(label, suffixes, inputs)
    return prefix, Outputs([beside(prefix, s) for s in suffixes], inputs=inputs, make_folders=True)


def _write_outputs(outputs: Outputs, prefix: Path, payload: dict, result, points, normals, data, args) -> str | None:
    """Write every output; returns the --trim summary line, if any."""
    from ..zeroset.export import save_zero_set
    from ..zeroset.extract import extract_zero_set

    summary = None
    # the zero set's box and its trimming follow the points the fit kept, not the stray ones
    kept, faces = points, data.faces
    if result.outliers is not None and result.outliers.count:
        kept, faces = points[result.outliers.inliers], None
    with outputs.writing() as stage:
        zero_set = None
        if not args.no_zero_set:
            zero_set = extract_zero_set(result.polynomial, points=kept)
            if args.trim is not None:
                zero_set, summary = trim_for_export(zero_set, kept, faces, args.trim)
            for suffix in [".ply"] if points.shape[1] == 3 else [".svg", ".csv"]:
                save_zero_set(zero_set, stage(beside(prefix, suffix)))
        # with --trim the figure and the viewer show what the exported zero set holds
        trim = None if zero_set is None or zero_set.trim is None else zero_set.trim.distance
        if not args.no_picture:
            from ..viz.plotting import plot_result

            plot_result(payload, points=points, path=stage(beside(prefix, ".png")), trim=trim,
                        faces=None if trim is None else faces)
        if args.html:
            from ..viz.viewer import write_html

            write_html(payload, points, stage(beside(prefix, ".html")), faces=data.faces, normals=normals, trim=trim)
        stage(beside(prefix, ".json")).write_text(json.dumps(payload, indent=1), encoding="utf-8")
    return summary

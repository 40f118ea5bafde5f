"""``ipfit reproduce -o DIR``: rerun the paper's experiments and write the report."""

from __future__ import annotations

import argparse
import shlex
import sys

from ._common import nonnegative_int

NAME = "reproduce"
HELP = "rerun the paper's experiments (Figs. 7-16) and write a Markdown report with figures"
DESCRIPTION = """\
Rerun the experiments of Interian et al. (2017), Section 5, on ipfit's bundled datasets with
fixed seeds, and write into DIR:
  README.md      the report: settings, a summary table of the paper's claims against this run,
                 one section per experiment (tables and figures)
  results.json   every number of the run (the report is rendered from it alone)
  fig_*.png      the figures

Experiments: delta (Fig. 7), adaptive (Figs. 8-13, DE and PSO), ridge (3L + ridge, Figs. 14-15),
noise (Fig. 16), convergence (PSO vs DE vs polish).

Configurations: the default ('full': the paper's parameters, 3D data subsampled to 2,000 points)
regenerates docs/reproduction (about 6 minutes on two cores; the report states its wall time);
--medium runs 100 iterations instead of 500 (about 3 minutes); --quick is a smoke test of under
half a minute whose numbers mean nothing.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # imported here, not with the module: every command imports this module to list it
    from ..reproduce import CONFIGS, DATASETS, DEFAULT_CONFIG, EXPERIMENTS

    parser.add_argument("-o", "--output", dest="output", required=True, metavar="DIR",
                        help="output folder (created)")
    mode = parser.add_mutually_exclusive_group()
    for name, cfg in CONFIGS.items():
        mode.add_argument(f"--{name}", dest="config", action="store_const", const=name,
                          help=cfg.description + (" (the default)" if name == DEFAULT_CONFIG else ""))
    parser.set_defaults(config=DEFAULT_CONFIG)
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of every random choice (default 0)")
    parser.add_argument("--only", nargs="+", choices=EXPERIMENTS, metavar="EXPERIMENT",
                        help="run only these experiments: " + ", ".join(EXPERIMENTS))
    parser.add_argument("--datasets", nargs="+", choices=DATASETS, metavar="NAME",
                        help="restrict the adaptive experiment to these datasets: " + ", ".join(DATASETS))
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines")


def run(args: argparse.Namespace) -> int:
    from ..reproduce import reproduce

    def log(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    command = "ipfit reproduce " + " ".join(shlex.quote(a) for a in _argv(args))
    results = reproduce(args.output, args.config, seed=args.seed, only=args.only, datasets=args.datasets,
                        log=None if args.quiet else log, command=command)
    if not args.quiet:
        counts: dict[str, int] = {}  # verdict -> claims
        for row in results["summary"]:
            counts[row["verdict"]] = counts.get(row["verdict"], 0) + 1
        print(f"wrote {args.output}/README.md ({len(results['figures'])} figures); claims: "
              + ", ".join(f"{v} {k}" for k, v in counts.items()))
    return 0


def _argv(args: argparse.Namespace) -> list[str]:
    """The options as a canonical command line (recorded in the report)."""
    from ..reproduce import DEFAULT_CONFIG

    out = ["--output", str(args.output)]
    if args.config != DEFAULT_CONFIG:
        out.append(f"--{args.config}")
    if args.seed:
        out += ["--seed", str(args.seed)]
    if args.only:
        out += ["--only", *args.only]
    if args.datasets:
        out += ["--datasets", *args.datasets]
    return out

"""``ipfit datasets``: the bundled datasets, with their credits."""

from __future__ import annotations

import argparse
import textwrap

NAME = "datasets"
HELP = "list the bundled datasets (usable wherever a command takes INPUT) with their credits"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--paths", action="store_true", help="also show where each file is installed")


def run(args: argparse.Namespace) -> int:
    from ..datasets import bundled

    infos = bundled.list_datasets()
    width = max(len(info.name) for info in infos)
    for info in infos:
        print(f"{info.name:<{width}}  {info.dim}D  {info.description}")
        indent = " " * (width + 6)
        print(textwrap.fill(f"credit: {info.credit}", width=100, initial_indent=indent,
                            subsequent_indent=indent + "  "))
        if args.paths:
            print(f"{indent}file: {bundled.dataset_path(info.name)}")
    print(f"\nFull credits: {bundled.DATA_DIR / 'CREDITS.md'}")
    return 0

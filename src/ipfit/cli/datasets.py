"""``ipfit datasets``: the bundled datasets, with their credits; ``--formats``: the readable files."""

from __future__ import annotations

import argparse
import textwrap

NAME = "datasets"
HELP = "list the bundled datasets (usable wherever a command takes INPUT) and the readable file formats"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--paths", action="store_true", help="also show where each file is installed")
    parser.add_argument("--formats", action="store_true",
                        help="list the file formats INPUT can be, with the library that reads each")


def format_rows() -> list[tuple[str, str, str]]:
    """(format, library, suffixes) for every readable format, the suffixes of one format together."""
    from ..io import FORMATS

    rows: dict[tuple[str, str], list[str]] = {}
    for suffix, fmt in FORMATS.items():
        library = fmt.library + (f" (pip install 'ipfit[{fmt.extra}]')" if fmt.extra else "")
        rows.setdefault((fmt.name, library), []).append(suffix)
    return [(name, library, " ".join(suffixes)) for (name, library), suffixes in rows.items()]


def _print_formats() -> None:
    rows = [("FORMAT", "READ WITH", "SUFFIXES")] + format_rows()
    widths = [max(len(row[i]) for row in rows) for i in range(2)]
    for name, library, suffixes in rows:
        print(f"{name:<{widths[0]}}  {library:<{widths[1]}}  {suffixes}")


def run(args: argparse.Namespace) -> int:
    from ..datasets import bundled

    if args.formats:
        _print_formats()
        return 0
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
    print("Readable file formats: ipfit datasets --formats")
    return 0

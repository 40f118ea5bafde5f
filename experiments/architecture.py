"""Write the layer diagram of docs/architecture.md from .importlinter's layers contract.

    python experiments/architecture.py [--check]

The contract is what `lint-imports` (`make lint`, in .ci/run) checks against the real imports,
so the page shows the layers the code has, top (the command line) to bottom (the leaves).
``--check`` exits 1 when the page differs from what would be written (tests/test_imports.py
runs it).
"""

from __future__ import annotations

import argparse
import configparser
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
BEGIN, END = "<!-- layers: experiments/architecture.py -->", "<!-- /layers -->"


def layers() -> list[str]:
    config = configparser.ConfigParser(inline_comment_prefixes=("#",))
    config.read(ROOT / ".importlinter", encoding="utf-8")
    lines = config["importlinter:contract:layers"]["layers"].splitlines()
    return [line.strip() for line in lines if line.strip() and not line.strip().startswith("#")]


def block() -> str:
    rows = [", ".join(name.strip() for name in layer.split("|")) for layer in layers()]
    return "\n".join([BEGIN, "```", *rows, "```", END])


def page() -> str:
    text = PAGE.read_text(encoding="utf-8")
    head, rest = text.split(BEGIN, 1)
    return head + block() + rest.split(END, 1)[1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the page is not up to date")
    args = parser.parse_args(argv)
    new = page()
    if args.check:
        return int(new != PAGE.read_text(encoding="utf-8"))
    PAGE.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

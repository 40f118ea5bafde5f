"""Write the layer diagram of docs/architecture.md from .importlinter's layers contracts.

    python experiments/architecture.py [--check]

The contracts are what `lint-imports` (`make lint`, in .ci/run) checks against the real imports,
so the page shows the layers the code has, top (the command line) to bottom (the leaves): first
the top level, where a subpackage is one unit, then the layers inside each subpackage.
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
PACKAGE = "ipfit"


def _lines(value: str) -> list[str]:
    return [line.strip() for line in value.splitlines() if line.strip() and not line.strip().startswith("#")]


def contracts() -> dict[str, list[list[str]]]:
    """Container -> its layers, top first, each a list of module names (relative to the container)."""
    config = configparser.ConfigParser(inline_comment_prefixes=("#",))
    config.read(ROOT / ".importlinter", encoding="utf-8")
    out = {}
    for section in config.sections():
        if not section.startswith("importlinter:contract:") or config[section].get("type") != "layers":
            continue
        layers = [[name.strip() for name in layer.split("|")] for layer in _lines(config[section]["layers"])]
        for container in _lines(config[section]["containers"]):
            out[container] = layers
    return out


def block() -> str:
    found = contracts()
    top = [", ".join(layer) for layer in found.pop(PACKAGE)]
    width = max(len(container) for container in found) - len(PACKAGE)
    inner = [f"{container[len(PACKAGE) + 1:] + ':':{width}} " + " > ".join(", ".join(layer) for layer in layers)
             for container, layers in found.items()]
    return "\n".join([BEGIN, "The top level (a subpackage is one unit, with everything in it):", "", "```", *top, "```",
                      "", "Inside each subpackage (top > ... > bottom):", "", "```", *inner, "```", END])


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

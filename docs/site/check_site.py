"""Check a built site (``make docs`` runs it): no broken internal link, a page per public name.

    python docs/site/check_site.py build/docs/html

Sphinx's own ``linkcheck`` follows external links (no network here); the nitpicky build already
refuses a cross-reference it cannot resolve. This checks what lands in the HTML: every ``href``
and ``src`` that stays inside the site points to a file that exists, and a ``#fragment`` to an
``id`` in that file; every name of ``ipfit.__all__`` has its page under ``site/generated/``;
every gallery example has its page with at least one figure or printed output.
Exit code 1 with one line per problem.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import ipfit

EXAMPLES = Path(__file__).resolve().parent / "examples"


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name == "id" and value:
                self.ids.add(value)
            elif name in ("href", "src") and value:
                self.links.append(value)


def _parse(path: Path, cache: dict[Path, _Page]) -> _Page:
    if path not in cache:
        page = _Page()
        page.feed(path.read_text(encoding="utf-8", errors="replace"))
        cache[path] = page
    return cache[path]


def broken_links(root: Path) -> list[str]:
    """``page: link`` for every internal link whose file or fragment does not exist."""
    problems = []
    cache: dict[Path, _Page] = {}
    for page_path in sorted(root.rglob("*.html")):
        if page_path.relative_to(root).parts[0] == "_static":
            continue  # the theme's own template fragments, not pages
        page = _parse(page_path, cache)
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
                continue  # external: not checked here
            target = page_path if not parts.path else (page_path.parent / unquote(parts.path)).resolve()
            where = f"{page_path.relative_to(root)}: {link}"
            if not target.resolve().is_relative_to(root.resolve()):
                problems.append(f"{where} (leaves the site)")
            elif target.is_dir():
                if not (target / "index.html").is_file():
                    problems.append(f"{where} (a folder without index.html)")
            elif not target.is_file():
                problems.append(f"{where} (no such file)")
            elif (parts.fragment and target.suffix == ".html"
                  and unquote(parts.fragment) not in _parse(target, cache).ids):
                problems.append(f"{where} (no id {parts.fragment!r} there)")
    return problems


def missing_pages(root: Path) -> list[str]:
    problems = [f"ipfit.{name}: no page site/generated/ipfit.{name}.html" for name in ipfit.__all__
                if not (root / "site" / "generated" / f"ipfit.{name}.html").is_file()]
    for example in sorted(EXAMPLES.glob("plot_*.py")):
        page = root / "site" / "gallery" / f"{example.stem}.html"
        if not page.is_file():
            problems.append(f"{example.name}: no gallery page {page.relative_to(root)}")
        elif not any(mark in page.read_text(encoding="utf-8") for mark in ("sphx-glr-single-img",
                                                                            "sphx-glr-script-out")):
            problems.append(f"{example.name}: its page shows neither a figure nor output")
    return problems


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not (Path(argv[0]) / "index.html").is_file():
        print("usage: python docs/site/check_site.py BUILT_HTML_FOLDER (with index.html)", file=sys.stderr)
        return 2
    root = Path(argv[0])
    problems = broken_links(root) + missing_pages(root)
    for line in problems:
        print(f"check_site: {line}", file=sys.stderr)
    pages = sum(1 for _ in root.rglob("*.html"))
    print(f"check_site: {pages} pages, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

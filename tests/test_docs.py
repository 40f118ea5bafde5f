"""The documentation site's sources agree with the package (no Sphinx build: ``make docs`` does that).

Every public name has an entry in the API reference, the README sections the user guide includes
are found, every gallery example is a titled script, and the changelog names the version.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import ipfit

REPO = Path(__file__).resolve().parents[1]
SITE = REPO / "docs" / "site"


def _autosummary_entries(rst: str) -> list[str]:
    """The names listed in the ``autosummary`` directives of an reST page."""
    names, inside = [], False
    for line in rst.splitlines():
        if line.startswith(".. autosummary::"):
            inside = True
        elif inside and line and not line.startswith(" "):
            inside = False
        elif inside and line.startswith("   ") and not line.strip().startswith(":"):
            names.append(line.strip())
    return names


def test_every_public_name_has_one_entry_in_the_api_reference():
    entries = _autosummary_entries((SITE / "api.rst").read_text(encoding="utf-8"))
    assert sorted(entries) == sorted(set(entries)), "a name is listed twice"
    assert set(entries) == set(ipfit.__all__), (set(ipfit.__all__) - set(entries), set(entries) - set(ipfit.__all__))


def test_the_readme_sections_the_guide_includes_are_found_once():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    pages = sorted((SITE / "guide").glob("*.md"))
    markers = [m for page in pages for m in re.findall(r':(?:start-after|end-before): "([^"]+)"', page.read_text())]
    assert len(markers) >= 10
    for marker in markers:
        assert readme.count(marker) == 1, marker
    # the parts run from the top to the end of the README without a gap
    starts = [m for page in pages for m in re.findall(r':start-after: "([^"]+)"', page.read_text())]
    ends = [m for page in pages for m in re.findall(r':end-before: "([^"]+)"', page.read_text())]
    assert sorted(starts) == sorted(["# ipfit", *ends])


def test_the_gallery_examples_are_titled_scripts():
    examples = sorted((SITE / "examples").glob("plot_*.py"))
    assert 8 <= len(examples) <= 12
    for path in examples:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        assert doc is not None, path.name
        title, underline = doc.splitlines()[:2]
        assert set(underline) == {"="} and len(underline) == len(title), path.name


def test_the_changelog_names_the_version():
    changelog = (REPO / "CHANGELOG.md").read_text(encoding="utf-8")
    first = re.search(r"^## (.+)$", changelog, flags=re.M)
    assert first is not None and ipfit.__version__ in first.group(1)

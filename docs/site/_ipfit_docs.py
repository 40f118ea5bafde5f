"""Build hooks of the documentation site (loaded by conf.py).

Constants. The public names live in ``ipfit`` (one ``__all__``, loaded on first use), but their
constants are documented by ``#:`` comments in the modules that define them. autodoc reads such
comments from the module a name is documented under, ``ipfit``, where there are none; this hook
gives ``ipfit.RECOMMENDED`` the comment written above ``RECOMMENDED`` in ``ipfit.fitting.options``.

References. The site documents the public names (``ipfit.NAME``) and the public modules
``ipfit.basis``, ``ipfit.optimize`` and ``ipfit.analysis``. A docstring names other objects
relative to the module it is written in (``:data:`AUTO``` in ``ipfit.fitting.options``), or by
their home (``ipfit.zeroset.quality.quality``). A reference Sphinx does not find is resolved
here as Python would read it, from the docstring's own module and the packages above it:

* an object that is a public name, or a member of one, links to that name's page
  (``ipfit.zeroset.extract.ZeroSet.trimmed`` -> ``ipfit.ZeroSet.trimmed``);
* an object that exists but has no page (an internal setting or helper) is shown as code;
* a name that does not exist stays a warning, and the nitpicky build fails on it: a reference
  to a renamed or deleted object is always caught.

Figures. ``plot_result`` returns a matplotlib ``Figure`` made without pyplot (it leaves pyplot's
state alone), which sphinx-gallery's matplotlib scraper cannot see: :func:`figure_scraper` saves
the figures an example holds in its variables (``fig = ipfit.plot_result(...)``).
"""

from __future__ import annotations

import importlib
from typing import Any

from docutils import nodes
from sphinx.pycode import ModuleAnalyzer

import ipfit

_MISSING = object()


def home_module(name: str) -> str | None:
    """The module that defines the public name ``ipfit.NAME`` (None: not a lazy public name)."""
    module = ipfit._LAZY.get(name, "")
    return f"ipfit.{module}" if module else None


def constant_comment(app, what, name, obj, options, lines):
    if what != "data" or not name.startswith("ipfit.") or name.count(".") != 1:
        return
    short = name.split(".", 1)[1]
    home = home_module(short)
    if home is None:
        return
    # the home module, or the one it imported the name from (REFINE_METHODS: refine <- options)
    modules = [home] + sorted({f"ipfit.{m}" for m in ipfit._LAZY.values() if m} - {home})
    comment = next((c for m in modules if (c := ModuleAnalyzer.for_module(m).find_attr_docs().get(("", short)))), None)
    if comment:
        lines[:] = list(comment)
    elif obj.__doc__ == type(obj).__doc__:
        lines[:] = []  # not the docstring of str or tuple: the page shows the value alone


def docstring_owner(source: str | None) -> str | None:
    """The dotted name of the object whose docstring a node came from (None: not a docstring)."""
    if not source or ":docstring of " not in source:
        return None
    return source.rsplit(":docstring of ", 1)[1]


def table_owner(node) -> str | None:
    """The home of the public name an autosummary row describes, for a reference in its summary."""
    row = node.parent
    while row is not None and not isinstance(row, nodes.row):
        row = row.parent
    if row is None or not row.children:
        return None
    name = row.children[0].astext().split("(")[0].strip()
    home = home_module(name)
    return f"{home}.{name}" if home else None


def _attribute(owner: Any, name: str) -> Any:
    """owner.name, or a field declared on a class (annotation, dataclass field, __slots__)."""
    value = getattr(owner, name, _MISSING)
    if value is not _MISSING:
        return value
    if isinstance(owner, type):
        for klass in owner.__mro__:
            if name in getattr(klass, "__annotations__", {}) or name in getattr(klass, "__slots__", ()):
                return None  # declared: exists, no object to compare
            fields = getattr(klass, "_fields", ())  # NamedTuple
            if name in fields:
                return None
    return _MISSING


def locate(dotted: str) -> list[Any]:
    """The objects along ``a.b.c`` (module, then attributes), or [] when it does not exist."""
    parts = dotted.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        chain = [obj]
        for part in parts[split:]:
            obj = _attribute(obj, part)
            if obj is _MISSING:
                return []
            chain.append(obj)
        return chain
    return []


def public_name(dotted: str, chain: list[Any]) -> str | None:
    """``ipfit.NAME[.member]`` for an object that is a public name of ipfit or one's member."""
    parts = dotted.split(".")
    offset = len(parts) - len(chain) + 1  # parts[offset + i - 1] is the name of chain[i]
    for i, obj in enumerate(chain):
        if i == 0 or obj is None:  # the module itself; a declared field without a value
            continue
        for name in ipfit.__all__:
            if name in ipfit._LAZY and ipfit._LAZY[name] is not None and getattr(ipfit, name) is obj:
                return ".".join(["ipfit", name] + parts[offset + i:])
    return None


def resolve_from_home(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "").lstrip("~.")
    owner = docstring_owner(node.source) or table_owner(node)
    if not target:
        return None
    domain = env.get_domain("py")
    scopes = owner.split(".") if owner else []
    candidates = [".".join(scopes[:stop] + [target]) for stop in range(len(scopes), 0, -1)] + [target]
    for candidate in candidates:
        if not candidate.startswith("ipfit"):
            continue
        chain = locate(candidate)
        if not chain:
            continue
        for name in (candidate, public_name(candidate, chain)):
            if name is None:
                continue
            found = domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], name, node, contnode)
            if found is not None:
                return found
        # it exists, but the site has no page for it: code, not a link
        return nodes.literal("", contnode.astext())
    return None


def figure_scraper(block, block_vars, gallery_conf):
    """sphinx-gallery scraper: the example's new ``Figure`` objects that pyplot does not know."""
    from matplotlib.figure import Figure
    from sphinx_gallery.scrapers import figure_rst

    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and not getattr(value, "_ipfit_gallery_saved", False):
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=90)
            value._ipfit_gallery_saved = True
            paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])


def setup(app):
    # before numpydoc (priority 500) reads the docstring
    app.connect("autodoc-process-docstring", constant_comment, priority=100)
    app.connect("missing-reference", resolve_from_home)

"""Sphinx configuration of ipfit's documentation site (``make docs``).

The source directory is ``docs/`` (this folder is the configuration directory, ``-c docs/site``):
the pages written for the site live here, and the generated pages of the experiments
(``docs/*.md``, with their figures) are read where they are, so their links, and the README's
links to them, resolve without copies. The build is nitpicky and treats warnings as errors.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # the gallery draws off-screen

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # _ipfit_docs (the hooks below)

project = "ipfit"
author = "the ipfit developers"
copyright = "the ipfit developers"
import ipfit  # noqa: E402

release = ipfit.__version__  # the one version (pyproject.toml reads it from there too)
version = release

root_doc = "site/index"
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
templates_path = [str(HERE / "_templates")]  # absolute: autosummary reads it from the source directory
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
# docs/ holds the experiments' generated pages and their data; only the pages are sources.
exclude_patterns = ["site/examples/**", "site/_root/**", "site/_templates/**", "**/.ipynb_checkpoints"]
# the generated experiment pages and the README sections start below H1 or skip a level
suppress_warnings = ["myst.header"]

# Docstrings write absolute values as |f|, |∇f|: reStructuredText reads |...| as a substitution.
rst_prolog = "\n".join(f".. |{text}| replace:: \\|{text}\\|" for text in ("f", "∇f", "n_i·n_j", "τ"))

nitpicky = True
# No intersphinx: the build runs offline, so names of other packages (numpy, scipy, Python's own)
# cannot be resolved and are not checked; every reference to ipfit's own names is.
nitpick_ignore_regex = [
    (r"py:.*", (r"(numpy|np|npt|numpy\.typing|scipy|skimage|trimesh|matplotlib|plotly|dask|distributed|pandas"
                r"|pyarrow|threadpoolctl|numba|typing|collections|functools|os|pathlib|concurrent|threading"
                r"|dataclasses|enum|abc|json|io)(\..*)?")),
    (r"py:.*", (r"(int|float|str|bytes|bool|complex|object|dict|list|tuple|set|frozenset|type|callable|None|Any"
                r"|Path|PathLike|ArrayLike|NDArray|Sequence|Mapping|Iterable|Iterator|Callable|Generator|Literal"
                r"|Self|TypeGuard|NamedTuple|Exception|ValueError|TypeError|Warning|UserWarning|RuntimeWarning"
                r"|OSError|KeyboardInterrupt)")),
]

autosummary_generate = True
autosummary_ignore_module_all = False
autodoc_typehints = "none"  # the numpydoc sections give the types; signatures stay readable
autodoc_default_options = {"member-order": "bysource"}
numpydoc_show_class_members = False
numpydoc_xref_param_type = False

myst_heading_anchors = 3

html_theme = "pydata_sphinx_theme"
html_title = f"ipfit {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_extra_path = ["_root"]  # index.html at the top of the site: a link to site/index.html
html_show_sourcelink = False

sphinx_gallery_conf = {
    "examples_dirs": ["site/examples"],
    "gallery_dirs": ["site/gallery"],
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "reset_modules": ("matplotlib",),
    # pyplot's figures, and the Figure objects plot_result returns (it leaves pyplot alone)
    "image_scrapers": ("matplotlib", "_ipfit_docs.figure_scraper"),
    "min_reported_time": 1,
    "show_memory": False,
    "show_signature": False,
}


def setup(app):
    from _ipfit_docs import setup as hooks

    hooks(app)
    return {"parallel_read_safe": True}


"""The package as installed: its data files, its types marker, its version and its command.

From a source tree (``make test``: an editable install, or ``PYTHONPATH=src``) the package data
are checked where they lie; the checks of an installed distribution are skipped there and run by
``.ci/wheel-smoke``, which installs the wheel into a fresh virtual environment and runs this file
against it with ``IPFIT_REQUIRE_INSTALLED=1`` (then a skip is a failure).
"""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import pytest

import ipfit
from ipfit.datasets.bundled import dataset_path

PACKAGE = Path(ipfit.__file__).resolve().parent


def _installed_distribution() -> importlib.metadata.Distribution:
    """ipfit's distribution when the imported package is the one it installed, else skip (or fail)."""
    reason = None
    try:
        dist = importlib.metadata.distribution("ipfit")
    except importlib.metadata.PackageNotFoundError:
        reason = "ipfit is not installed (imported from a source tree)"
    else:
        recorded = {str(f) for f in dist.files or ()}
        if "ipfit/__init__.py" not in recorded or Path(dist.locate_file("ipfit/__init__.py")).resolve() != (
                PACKAGE / "__init__.py"):
            reason = f"ipfit is imported from {PACKAGE}, not from its installed distribution (editable or source tree)"
    if reason is not None:
        if os.environ.get("IPFIT_REQUIRE_INSTALLED") == "1":
            pytest.fail(reason)
        pytest.skip(reason + "; .ci/wheel-smoke runs this against the wheel")
    return dist


def test_py_typed_and_the_datasets_are_package_files():
    assert files("ipfit").joinpath("py.typed").is_file()
    assert files("ipfit.datasets").joinpath("data", "CREDITS.md").is_file()
    for name in ipfit.dataset_names():
        path = dataset_path(name).resolve()
        assert path.is_file() and path.stat().st_size > 0, name
        assert path.is_relative_to(PACKAGE), (name, path)  # inside the package, not a checkout's folder


def test_the_installed_distribution_is_complete():
    dist = _installed_distribution()
    assert dist.version == ipfit.__version__  # the one version, read from ipfit/__init__.py at build time
    recorded = {str(f) for f in dist.files or ()}
    assert "ipfit/py.typed" in recorded
    assert "ipfit/datasets/data/CREDITS.md" in recorded
    for name in ipfit.dataset_names():
        assert dataset_path(name).resolve().relative_to(PACKAGE.parent).as_posix() in recorded, name
    scripts = {ep.name: ep.value for ep in dist.entry_points if ep.group == "console_scripts"}
    assert scripts == {"ipfit": "ipfit.cli:main"}
    # the extras users install alone (pyproject.toml's optional-dependencies)
    assert {"viewer", "dask", "parquet", "scanners", "sympy"} <= set(dist.metadata.get_all("Provides-Extra") or ())


def test_the_installed_command_runs():
    _installed_distribution()
    script = Path(sys.executable).with_name("ipfit")
    assert script.is_file(), script
    out = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == f"ipfit {ipfit.__version__}", out

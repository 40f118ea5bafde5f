"""Optional packages: import one, or fail with one line naming the extra that installs it.

ipfit's core needs numpy, scipy, scikit-image, trimesh and friends; everything else is an
extra (``pip install 'ipfit[EXTRA]'``, see ``pyproject.toml``). :func:`require` is the one
way library code imports an optional package; the command line's error boundary turns any
other :class:`ModuleNotFoundError` for one of them into the same line (:func:`missing`).
"""

from __future__ import annotations

import importlib
from types import ModuleType

from ..exceptions import IpfitError

__all__ = ["EXTRAS", "MissingDependencyError", "require", "missing", "install_line"]

#: Top-level module -> the extra of ``pyproject.toml`` that installs it.
EXTRAS = {
    "dask": "dask", "distributed": "dask",
    "plotly": "viewer",
    "pyarrow": "parquet",
    "laspy": "scanners", "lazrs": "scanners", "pye57": "scanners", "pypcd4": "scanners", "lxml": "scanners",
    "collada": "scanners",
    "sympy": "sympy",
    "open3d": "open3d", "pyvista": "pyvista",
}


class MissingDependencyError(IpfitError, ImportError):
    """An optional package is not installed; the message says which extra installs it."""


def install_line(module: str) -> str:
    """``pip install 'ipfit[EXTRA]'`` for a module of an extra (the bare package otherwise)."""
    top = module.split(".")[0]
    extra = EXTRAS.get(top)
    return f"pip install 'ipfit[{extra}]'" if extra else f"pip install {top}"


def _error(module: str, what: str) -> MissingDependencyError:
    top = module.split(".")[0]
    return MissingDependencyError(f"{what} needs the optional package '{top}', which is not installed. "
                                  f"Install it with: {install_line(top)}")


def require(module: str, what: str) -> ModuleType:
    """``module`` imported, or :class:`MissingDependencyError` saying that ``what`` needs it.

    >>> require("numpy", "this example").__name__
    'numpy'
    >>> require("no_such_package_xyz", "the example")
    Traceback (most recent call last):
    ...
    ipfit._utils.optional.MissingDependencyError: the example needs the optional package 'no_such_package_xyz', \
which is not installed. Install it with: pip install no_such_package_xyz
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is None or not module.startswith(exc.name.split(".")[0]):
            raise  # a package that is there but broken: its own error says more
        raise _error(module, what) from None


def missing(exc: ModuleNotFoundError, what: str) -> MissingDependencyError | None:
    """The one-line error for a ``ModuleNotFoundError`` of an optional package (None for others)."""
    name = exc.name or ""
    return _error(name, what) if name.split(".")[0] in EXTRAS else None

"""What the format readers share: the raw result type, short error text, optional libraries."""

from __future__ import annotations

import contextlib
import importlib
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

from numpy.typing import NDArray

from .._utils.optional import install_line
from ..exceptions import InvalidInputError, ReadError

#: Fewer points than this make no point cloud.
MIN_POINTS = 3
#: Comment written by ipfit into 3D-only formats (z = 0) so that 2D points come back as 2D.
IPFIT_2D = "ipfit 2D points (z = 0)"


class Raw(NamedTuple):
    """What a format reader returns, before the common checks and merging.

    ``normals_source`` is "file" when the normals come from the file (or were traced from an
    image); ``dropped_normals`` explains normals the file has but that could not be used.
    """

    points: NDArray
    normals: NDArray | None = None
    faces: NDArray | None = None
    normals_source: str | None = None
    dropped_normals: str | None = None


def short(exc: BaseException) -> str:
    """An exception's message on one line of at most 160 characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def optional_module(name: str, path: Path, what: str):
    """Import an optional reader library, or say which extra installs it."""
    try:
        return importlib.import_module(name)
    except ImportError:
        raise ReadError(f"{path}: reading {what} files needs the '{name.split('.')[0]}' package. "
                        f"Install it with: {install_line(name)}") from None


@contextlib.contextmanager
def quiet_logger(name: str) -> Iterator[None]:
    """Silence a library's logger: trimesh and friends log tracebacks of their fallbacks, and
    our one-line error says it all."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)


def as_path(path, name: str = "path") -> Path:
    """A file path given as str or os.PathLike, or an InvalidInputError naming ``name``."""
    if isinstance(path, (str, os.PathLike)) and not isinstance(path, bytes):
        text = os.fspath(path)
        if isinstance(text, str) and text:
            return Path(text)
    shown = repr(path) if len(repr(path)) <= 60 else repr(path)[:57] + "..."
    raise InvalidInputError(f"{name}: expected a file path (str or pathlib.Path), got {type(path).__name__} "
                            f"{shown}. Pass the path of the file.")

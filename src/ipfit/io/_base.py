"""What the format readers share: the raw result type, short error text, optional libraries."""

from __future__ import annotations

import contextlib
import importlib
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
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


def chain_loops(loops: list[NDArray]) -> NDArray[np.float64]:
    """Closed loops (each without its repeated first point) as one ordered contour: each loop
    after the first starts at its point farthest from where the one before ended, so that the
    jump between them is far longer than the gaps along them, which is how an ordered contour's
    loops are told apart (:func:`ipfit.geometry.distance.contour_pieces`). Silhouettes and contour
    files of several loops are read this way.

    >>> square = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], dtype=float)
    >>> chain_loops([square, square / 4 + 1])[4:].tolist()
    [[2.0, 1.0], [2.0, 2.0], [1.0, 2.0], [1.0, 1.0]]
    """
    return np.concatenate([np.roll(np.asarray(loop, dtype=np.float64), -k, axis=0)
                           for loop, k in zip(loops, chain_offsets(loops), strict=True)])


def chain_offsets(loops: list[NDArray]) -> list[int]:
    """Where :func:`chain_loops` starts each loop."""
    offsets, end = [0], np.asarray(loops[0])[-1]
    for loop in loops[1:]:
        start = int(np.argmax(np.linalg.norm(np.asarray(loop) - end, axis=1)))
        offsets.append(start)
        end = np.asarray(loop)[start - 1]
    return offsets

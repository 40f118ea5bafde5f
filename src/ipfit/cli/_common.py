"""Helpers shared by the subcommands: input resolution, option types and all-or-nothing output."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..exceptions import InvalidInputError, ReadError


class Input(NamedTuple):
    points: np.ndarray
    normals: np.ndarray | None
    label: str
    faces: np.ndarray | None = None


def load_input(spec: str, max_points: int | None = None) -> Input:
    """A path to a point file, or the name of a bundled dataset (``ipfit datasets``).

    ``max_points`` keeps a fixed-seed random subset of a larger file (``--max-points``); the
    counts read and kept are reported on stderr when it does.
    """
    import warnings

    from .. import io
    from ..datasets import bundled

    path = Path(spec)
    if path.exists():
        cloud = io.read_points(path, max_points=max_points)
        faces = None
        if cloud.n_kept < cloud.n_file and max_points is not None:
            print(f"ipfit: {path}: kept {cloud.n_kept:,} of the file's {cloud.n_file:,} points "
                  f"(--max-points {max_points}, fixed seed)", file=sys.stderr)
        elif cloud.normals_source in ("faces", "file") or path.suffix.lower() in {".ply", ".obj", ".off", ".stl"}:
            with warnings.catch_warnings():  # the first read already said what it had to say
                warnings.simplefilter("ignore")
                faces = io.read_mesh(path).faces
        return Input(cloud.points, cloud.normals, path.stem, faces)
    if spec in bundled.dataset_names():
        points, normals = bundled.load_dataset(spec)
        if max_points is not None and len(points) > max_points:
            keep = np.sort(np.random.default_rng(0).choice(len(points), max_points, replace=False))
            print(f"ipfit: {spec}: kept {max_points:,} of its {len(points):,} points (--max-points, fixed seed)",
                  file=sys.stderr)
            return Input(points[keep], normals[keep], spec)
        return Input(points, normals, spec, bundled.dataset_faces(spec))
    names = ", ".join(bundled.dataset_names())
    raise ReadError(f"{spec}: no such file, nor a bundled dataset name ({names}). Check the path.")


def _whole_number_at_least(minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {value}")
        return value

    return parse


positive_int = _whole_number_at_least(1)
nonnegative_int = _whole_number_at_least(0)


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def nonnegative_float(text: str) -> float:
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


class OutputSet:
    """Files written all together or not at all.

    ``path(final)`` gives a temporary path beside ``final``; ``commit()`` renames every one
    into place; leaving the ``with`` block without ``commit()`` removes them all.
    """

    def __init__(self) -> None:
        self._pending: list[tuple[Path, Path]] = []
        self.written: list[Path] = []

    def path(self, final: str | os.PathLike) -> Path:
        final = Path(final)
        tmp = final.with_name(f".{final.name}.partial{final.suffix}")
        self._pending.append((tmp, final))
        return tmp

    def commit(self) -> list[Path]:
        for tmp, final in self._pending:
            if tmp.exists():
                os.replace(tmp, final)
                self.written.append(final)
        self._pending.clear()
        return self.written

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, *exc) -> None:
        for tmp, _ in self._pending:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
        self._pending.clear()


def prepare_output_dir(prefix: Path) -> None:
    parent = prefix.parent
    if parent.exists() and not parent.is_dir():
        raise InvalidInputError(f"--output: {parent} exists and is not a folder. Choose another output prefix.")
    parent.mkdir(parents=True, exist_ok=True)


def show_progress(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()

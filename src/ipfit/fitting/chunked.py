"""Linear fits of clouds bigger than memory: a Dask array of points and normals, chunk by chunk.

:func:`fit_chunked` runs the 3L, ridge, gradient-one and least-squares fits of
:mod:`ipfit.fitting.linear` on a chunked cloud without ever building its design matrix: each chunk's
rows are reduced to the small (d + 1) × (d + 1) triangular factor R of their QR (in row
blocks, by the same generators the in-memory fits use), the chunks' factors are stacked and
factorised once more (a tall-skinny QR across chunks) and the small system is solved as
in memory. Peak memory is ``in_flight`` chunks (computed at once, by default as many as
there are cores) and their row blocks, whatever the number of points.

What needs the whole cloud at once is computed differently:

* the normalisation (centre and mean distance) by two chunked reductions, which equal
  :meth:`~ipfit.Normalization.from_points` up to rounding;
* the ridge penalty's power sums by a chunked reduction (exact);
* the far-field rows (``far_row_weight > 0``) and the sign of the result (f > 0 outside)
  come from an evenly spaced subsample of ``sample_size`` points (the whole cloud when it
  is no bigger), whose box and kd-tree stand for the cloud's: the far-field samples are
  drawn in the subsample's box at its distances. Up to ``sample_size`` points the fit is
  therefore the in-memory fit, to rounding.

The measures and the polish are not chunked (they are per-shape refinements).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._utils.numeric import unit_rows
from .._utils.optional import require
from .._utils.validation import (
    as_points,
    check_choice,
    check_degree,
    check_enough_points,
    check_int,
    check_real_dtype,
    error,
)
from ..exceptions import ReadError
from ..polynomial import ImplicitPolynomial, Normalization
from .linear import LINEAR_METHODS, _fit_problem, _Problem, _r_of_blocks, check_params

__all__ = ["fit_chunked", "open_cloud", "CHUNKED_METHODS", "DEFAULT_SAMPLE_SIZE"]

#: The linear fits that run chunk by chunk (Taubin's centring needs the whole cloud).
CHUNKED_METHODS = ("lstsq", "3l", "ridge", "gradient_one", "3l-far")
DEFAULT_SAMPLE_SIZE = 100_000


def _as_dask(array, name: str, chunk_rows: int):
    import dask.array as da

    if not isinstance(array, (da.Array, np.ndarray)) or isinstance(array, np.ma.MaskedArray):
        array = as_points(array, name)  # lists, DataFrames...: in memory anyway, checked in full
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise error(name, "an (N, 2) or (N, 3) array", f"shape {array.shape}")
    check_real_dtype(array, name, "an (N, 2) or (N, 3) array of numbers")
    out = array if isinstance(array, da.Array) else da.from_array(array, chunks=(chunk_rows, -1))
    return out.rechunk({1: -1}).astype(np.float64)


def _npy_shape(file: Path) -> tuple[tuple[int, ...], np.dtype]:
    try:
        header = np.load(file, mmap_mode="r")  # reads the header only
    except (OSError, ValueError) as exc:
        raise ReadError(f"{file}: not a readable .npy array ({exc}). Check the file.") from None
    shape, dtype = header.shape, header.dtype
    del header
    return shape, dtype


def _read_rows(file: str, start: int, stop: int) -> NDArray:
    # A copy of the rows, the map closed at once: pages of a map kept open would stay in the
    # process's resident memory until the whole fit ends.
    rows = np.load(file, mmap_mode="r")
    try:
        return np.array(rows[start:stop], dtype=np.float64)
    finally:
        del rows


def _lazy_rows(file: Path, chunk_rows: int):
    import dask
    import dask.array as da

    shape, _ = _npy_shape(file)
    if len(shape) != 2 or shape[1] not in (2, 3):
        raise ReadError(f"{file}: expected an (N, 2) or (N, 3) array, got shape {shape}. Check the file.")
    pieces = [da.from_delayed(dask.delayed(_read_rows, pure=True)(str(file), a, min(a + chunk_rows, shape[0])),
                              (min(a + chunk_rows, shape[0]) - a, shape[1]), dtype=np.float64)
              for a in range(0, shape[0], chunk_rows)]
    return da.concatenate(pieces) if len(pieces) > 1 else pieces[0]


def open_cloud(path: str | Path, chunk_rows: int = 1 << 20):
    """(points, normals) Dask arrays of a cloud stored as ``.npy`` files, read chunk by chunk.

    ``path`` is a folder holding ``points.npy`` and ``normals.npy`` (read in chunks of
    ``chunk_rows`` rows), or chunk files ``points-*.npy`` / ``normals-*.npy`` (one chunk
    each, in name order, unless bigger than ``chunk_rows``). Nothing is read until the
    arrays are computed, and each task keeps only its own rows.
    """
    da = require("dask.array", "ipfit.fitting.chunked.open_cloud")

    folder = Path(path)
    if (folder / "points.npy").is_file() and (folder / "normals.npy").is_file():
        return tuple(_lazy_rows(folder / f"{n}.npy", chunk_rows) for n in ("points", "normals"))
    points, normals = sorted(folder.glob("points-*.npy")), sorted(folder.glob("normals-*.npy"))
    if not points or len(points) != len(normals):
        raise ReadError(f"{folder}: expected points.npy and normals.npy, or as many points-*.npy as normals-*.npy "
                        "chunk files. Check the folder.")
    return tuple(da.concatenate([_lazy_rows(f, chunk_rows) for f in files]) for files in (points, normals))


@dataclass(frozen=True)
class _Chunks:
    """The cloud's (points, normals) chunks, mapped a few at a time so that memory stays bounded."""

    points: Any  # dask (N, dim), user coordinates
    normals: Any
    scheduler: Any = None
    in_flight: int = 2

    @property
    def starts(self) -> NDArray[np.int64]:
        return np.concatenate([[0], np.cumsum(self.points.chunks[0])[:-1]]).astype(np.int64)

    def map(self, func: Callable[[NDArray, NDArray, int], Any]) -> list:
        """``func(points, normals, first_row)`` of every chunk, ``in_flight`` chunks at a time
        (Dask would otherwise read chunks ahead of the tasks that consume them)."""
        import dask

        pairs = list(zip(self.points.to_delayed().ravel(), self.normals.to_delayed().ravel(), self.starts, strict=True))
        out: list = []
        for wave in range(0, len(pairs), self.in_flight):
            out += dask.compute(*(dask.delayed(func)(p, n, int(start)) for p, n, start in
                                  pairs[wave: wave + self.in_flight]), scheduler=self.scheduler)
        return out


@dataclass(frozen=True)
class _ChunkedProblem(_Problem):
    """A :class:`~ipfit.fitting.linear._Problem` whose ``u`` is a subsample; the rows come chunk by chunk."""

    chunks: Any = None
    total: int = 0

    @property
    def n_points(self) -> int:
        return self.total

    def _per_chunk(self, reduce: Callable[[_Problem], Any]) -> list:
        norm, degree = self.normalization, self.degree

        def one(points, normals, start):
            return reduce(_Problem(norm.apply(points), unit_rows(np.asarray(normals, dtype=np.float64)), norm, degree))

        return self.chunks.map(one)

    def blocks(self, make: Callable[..., Iterable[NDArray]], *args) -> Iterable[NDArray]:
        # R of each chunk's rows has the R of those rows: stacking them loses nothing.
        return self._per_chunk(lambda sub: _r_of_blocks(make(sub, *args)))

    def r_of(self, make: Callable[..., Iterable[NDArray]], *args) -> NDArray:
        # Not kept: ``u`` is only a subsample of the chunks the rows come from.
        return _r_of_blocks(self.blocks(make, *args))

    def power_sums(self, top: int) -> NDArray[np.float64]:
        return np.sum(self._per_chunk(lambda sub: _Problem.power_sums(sub, top)), axis=0)


def _normalization(chunks: _Chunks, n: int) -> Normalization:
    center = np.sum(chunks.map(lambda p, _, start: np.asarray(p, dtype=np.float64).sum(axis=0)), axis=0) / n
    scale = float(np.sum(chunks.map(lambda p, _, start: np.linalg.norm(p - center, axis=1).sum())) / n)
    if not scale > 0:
        raise error("points", "points that are not all identical", "one repeated point",
                    "Pass a point cloud with some extent.")
    return Normalization(center, scale)


def _subsample(chunks: _Chunks, take: NDArray[np.int64]) -> tuple[NDArray, NDArray]:
    def rows(points, normals, start):
        local = take[(take >= start) & (take < start + len(points))] - start
        return np.asarray(points[local], dtype=np.float64), np.asarray(normals[local], dtype=np.float64)

    parts = chunks.map(rows)
    return np.concatenate([p for p, _ in parts]), np.concatenate([q for _, q in parts])


def fit_chunked(points, normals, degree: int, method: str = "3l", *, chunk_rows: int = 1 << 20,
                sample_size: int = DEFAULT_SAMPLE_SIZE, scheduler=None, in_flight: int | None = None,
                **params: float) -> ImplicitPolynomial:
    """A linear fit of a chunked cloud (Dask arrays, memmaps or arrays), as :func:`ipfit.fit_linear`.

    Parameters
    ----------
    points, normals : (N, dim) Dask arrays (e.g. from :func:`open_cloud`), or arrays and
        memmaps cut into chunks of ``chunk_rows`` rows. ``normals`` may be None for 'lstsq'.
    degree : int
    method : one of :data:`CHUNKED_METHODS`, with its parameters (``c``, ``kappa``, ``mu``,
        ``far_row_weight``) as in :func:`ipfit.fit_linear`.
    sample_size : points of the evenly spaced subsample used for the far-field rows and the sign.
    scheduler : passed to ``dask.compute`` (default: Dask's current one, e.g. a Client's).
    in_flight : chunks computed at once (default: the number of cores; with a cluster, its
        number of worker threads): peak memory is about this many chunks and row blocks.

    Examples
    --------
    >>> import dask.array as da
    >>> from ipfit import fit_3l
    >>> from ipfit.datasets.synthetic import torus
    >>> shape = torus(3000)
    >>> chunked = fit_chunked(da.from_array(shape.points, chunks=(700, 3)),
    ...                       da.from_array(shape.normals, chunks=(700, 3)), 4, "3l", scheduler="sync")
    >>> bool(np.allclose(chunked.coefficients, fit_3l(shape.points, shape.normals, 4).coefficients, rtol=1e-10))
    True
    """
    require("dask.array", "ipfit.fit_chunked")
    method = check_choice(method, "method", CHUNKED_METHODS)
    degree = check_degree(degree)
    chunk_rows = check_int(chunk_rows, "chunk_rows", minimum=1)
    sample_size = check_int(sample_size, "sample_size", minimum=1)
    params = check_params(method, params)
    spec = LINEAR_METHODS[method]
    pts = _as_dask(points, "points", chunk_rows)
    if normals is None:
        if spec.needs_normals:
            raise error("normals", f"unit normals for the {method} fit", "None", "Pass the normals or use 'lstsq'.")
        nrm = pts * 0.0
    else:
        nrm = _as_dask(normals, "normals", chunk_rows)
        if nrm.shape != pts.shape:
            raise error("normals", f"an array of the points' shape {pts.shape}", f"shape {nrm.shape}")
        nrm = nrm.rechunk(pts.chunks)
    n = int(pts.shape[0])
    check_enough_points(n, pts.shape[1], degree)
    chunks = _Chunks(pts, nrm, scheduler, check_int(in_flight or os.cpu_count() or 1, "in_flight", minimum=1))
    norm = _normalization(chunks, n)
    take = np.unique(np.linspace(0, n - 1, min(n, sample_size)).round().astype(np.int64))
    sample, sample_normals = _subsample(chunks, take)
    problem = _ChunkedProblem(norm.apply(sample), None if normals is None else unit_rows(sample_normals), norm, degree,
                              chunks=chunks, total=n)
    return _fit_problem(method, problem, params, n_points=n, sample_size=len(take), chunks=len(pts.chunks[0]))

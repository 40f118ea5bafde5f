"""How many worker threads the package's parallel parts use.

One answer for the objective's worker threads (:mod:`ipfit.fitting.objective`) and the k-d
tree queries of the distance engine (:mod:`ipfit.geometry.distance`), and one way to run a
compiled kernel that releases the GIL over even parts of its rows (:func:`in_parts`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from itertools import pairwise

import numpy as np

__all__ = ["default_threads", "in_parts"]


def default_threads() -> int:
    """Worker threads for population evaluation (and big k-d tree queries): the CPUs this process
    may use, at most ``OMP_NUM_THREADS`` when that is set (a batch's Dask workers set it to 1:
    one thread per worker process)."""
    try:
        usable = max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        usable = max(1, os.cpu_count() or 1)
    try:
        return max(1, min(usable, int(os.environ.get("OMP_NUM_THREADS", ""))))
    except ValueError:  # unset or not a number
        return usable


def in_parts(run: Callable[[slice], object], n: int, threads: int, min_part: int) -> None:
    """``run(rows)`` over ``threads`` even slices of ``range(n)`` at once, each of at least
    ``min_part`` rows (fewer rows: one call, on this thread). ``run`` must release the GIL (a
    compiled ``nogil`` kernel) and write only its own rows: each row's result is then the
    same, to the bit, whatever the number of parts."""
    parts = max(1, min(threads, n // max(min_part, 1)))
    if parts == 1:
        run(slice(0, n))
        return
    edges = np.linspace(0, n, parts + 1).astype(int)
    with ThreadPoolExecutor(parts) as pool:
        list(pool.map(run, [slice(a, b) for a, b in pairwise(edges)]))

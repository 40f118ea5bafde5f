"""How many worker threads the package's parallel parts use.

One answer for the objective's worker threads (:mod:`ipfit.fitting.objective`) and the k-d
tree queries of the distance engine (:mod:`ipfit.geometry.distance`).
"""

from __future__ import annotations

import os

__all__ = ["default_threads"]


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

"""ASCII PLY: numpy's text reader against plyfile's, on every bundled PLY file.

Run with ``.venv/bin/python benchmarks/bench_readers.py``. For each file, both readers of
:mod:`ipfit.io.meshfiles` (``_ascii_ply``, the fast path ``read_ply`` takes for the usual
layout, and ``_plyfile_elements``, plyfile as before) parse the same bytes, already in memory;
seconds are the median of 5 runs, in turn. The last column says whether the two gave the same
arrays, value for value and type for type (vertices, comments, polygons).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

import sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

from ipfit.datasets.bundled import DATA_DIR
from ipfit.io.meshfiles import _ascii_ply, _plyfile_elements

REPEATS = 5


def _same(fast, slow) -> bool:
    if fast is None or fast[0] != slow[0] or fast[2] != slow[2] or fast[1].dtype != slow[1].dtype:
        return False
    if not all(np.array_equal(fast[1][name], slow[1][name]) for name in slow[1].dtype.names):
        return False
    if fast[3] is None or slow[3] is None:
        return fast[3] is None and slow[3] is None
    return np.array_equal(fast[3][0], slow[3][0]) and np.array_equal(fast[3][1], slow[3][1].astype(np.int64))


def main() -> None:
    print("| file | vertices | faces | numpy s | plyfile s | speed-up | same arrays |")
    print("|---|---|---|---|---|---|---|")
    for path in sorted((DATA_DIR / "3d").glob("*.ply")):
        raw = path.read_bytes()
        times: dict[str, list[float]] = {"numpy": [], "plyfile": []}
        for _ in range(REPEATS):
            start = time.perf_counter()
            fast = _ascii_ply(raw)
            times["numpy"].append(time.perf_counter() - start)
            start = time.perf_counter()
            slow = _plyfile_elements(path, raw)
            times["plyfile"].append(time.perf_counter() - start)
        fast_s, slow_s = statistics.median(times["numpy"]), statistics.median(times["plyfile"])
        n_faces = 0 if slow[3] is None else len(slow[3][0])
        print(f"| {path.name} | {len(slow[1]):,} | {n_faces:,} | {fast_s:.4f} | {slow_s:.4f} | "
              f"{slow_s / fast_s:.1f}× | {'yes' if _same(fast, slow) else 'no'} |")


if __name__ == "__main__":
    main()

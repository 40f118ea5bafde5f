"""ipfit._utils.threads.in_parts: a kernel run over even parts of its rows on worker threads."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from ipfit._utils.threads import in_parts


@pytest.mark.parametrize("n, threads, min_part, parts", [
    (10, 2, 100, 1),      # too few rows for two parts
    (200, 2, 100, 2),
    (199, 2, 100, 1),
    (1000, 3, 100, 3),
    (1000, 1, 10, 1),
    (0, 2, 10, 1),
])
def test_every_row_is_run_once_in_even_parts(n, threads, min_part, parts):
    seen = np.zeros(n, dtype=int)
    slices, names = [], set()

    def run(rows: slice) -> None:
        seen[rows] += 1
        slices.append((rows.start, rows.stop))
        names.add(threading.current_thread().name)

    in_parts(run, n, threads, min_part)
    assert np.all(seen == 1)
    assert len(slices) == parts
    sizes = [b - a for a, b in slices]
    assert max(sizes) - min(sizes) <= 1
    if parts == 1:
        assert names == {threading.current_thread().name}  # one part runs on the caller's thread
    else:
        assert all(size >= min_part for size in sizes)

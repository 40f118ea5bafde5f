"""Normal estimation: timing on the full bunny and quality figures on every bundled dataset.

Run with ``.venv/bin/python benchmarks/bench_normals.py``. Timings are the median of several
runs after a warm-up, on however many cores the neighbour search gets (``workers=-1``); other
jobs on the machine make them noisy.

Quality columns, against each dataset's reference normals (face-derived for the bunny and the
duck, the file's for the apple, from the ordered contour for 2D): the median angle between the
normal lines, the fraction of points whose estimated normal points the other way, and that
fraction among "resolvable" points only: those whose estimated line is within 45° of the
reference and whose reference agrees in sign with at least 3/4 of its k nearest neighbours'
(elsewhere no method working from points alone can tell which way is out: the apple's stem,
sampled far below its radius; the duck's mouth slit, two sheets closer than the sampling).
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np
from scipy.spatial import cKDTree

from ipfit.datasets import bundled
from ipfit.normals import DEFAULT_K, estimate_normals, normal_agreement

REPEATS = 7


def resolvable(points, reference, estimated, k):
    agreement = normal_agreement(estimated, reference)
    _, idx = cKDTree(points).query(points, k)
    opposite = (np.einsum("ij,ikj->ik", reference, reference[idx[:, 1:]]) < 0).mean(axis=1) > 0.25
    return (agreement.angles < 45) & ~opposite


def timing() -> None:
    points, _ = bundled.load_dataset("bunny")
    estimate_normals(points)  # warm-up: imports, caches
    runs = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        estimate_normals(points)
        runs.append(time.perf_counter() - start)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"estimate_normals on the full bunny ({len(points):,} points, k = {DEFAULT_K[3]}), "
          f"{os.cpu_count()} cores, load average {load:.1f}:")
    print(f"  median {statistics.median(runs):.3f} s, best {min(runs):.3f} s, worst {max(runs):.3f} s "
          f"over {REPEATS} runs")


def quality() -> None:
    rng = np.random.default_rng(0)
    print(f"\n{'dataset':<22} {'points':>7} {'median°':>8} {'flipped':>8} {'resolvable':>11} {'flipped(res.)':>14}")
    for name in bundled.dataset_names():
        points, reference = bundled.load_dataset(name)
        orders = [("", np.arange(len(points)))]
        if points.shape[1] == 2:
            orders.append((" (shuffled)", rng.permutation(len(points))))
        for label, order in orders:
            p, ref = points[order], reference[order]
            est = estimate_normals(p)
            a = normal_agreement(est, ref)
            mask = resolvable(p, ref, est, DEFAULT_K[p.shape[1]])
            print(f"{name + label:<22} {len(p):>7,} {a.median_angle:>8.2f} {100 * a.flipped_fraction:>7.2f}% "
                  f"{100 * mask.mean():>10.1f}% {100 * a.flipped[mask].mean():>13.2f}%")


if __name__ == "__main__":
    timing()
    quality()

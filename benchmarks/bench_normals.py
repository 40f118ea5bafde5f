"""Normal estimation: timing on the full bunny and quality figures on every bundled dataset.

Run with ``.venv/bin/python benchmarks/bench_normals.py``. Timings are the median of several
runs after a warm-up, on however many cores the neighbour search gets (``workers=-1``); other
jobs on the machine make them noisy.

Quality columns, against face-derived normals for the meshes (the issue's reference; the apple
also against its file's normals) and normals from the ordered contour in 2D: the median angle
between the normal lines and the fraction of points whose estimated normal points the other way;
then, for meshes, the share of vertices whose face normal does not point out of the solid
(:func:`ipfit.geometry.mesh.outward_vertices`: the mesh passes through itself there, as the duck's beak
does, or is open, as the bunny's base is) and the flipped fraction over the others. The winding
numbers this needs are skipped for meshes of over 20,000 vertices (minutes for the full bunny).

First, two scaling rows: a million points of a torus (uniformly random, exact normals known;
then with Gaussian noise of σ = 0.5 % of its bounding box's diagonal, which
``estimate_normals`` handles on an even sample of 40,000 points), with
the wall time, the peak of memory allocated through Python and numpy (``tracemalloc``; the
neighbour search's own C++ tree is not counted there) and the process's peak resident size
(``ru_maxrss``, input included), and the quality against the exact normals.
"""

from __future__ import annotations

import os
import resource
import statistics
import time
import tracemalloc

import numpy as np

import sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

from ipfit.datasets import bundled
from ipfit.geometry.mesh import fill_missing_normals, vertex_normals_from_faces
from ipfit.normals import DEFAULT_K, estimate_normals, normal_agreement
from ipfit.geometry.mesh import outward_vertices

MAX_WINDING_VERTICES = 20_000

REPEATS = 7


def references(name):
    points, reference = bundled.load_dataset(name)
    faces = bundled.dataset_faces(name)
    if faces is None:
        return points, [("contour", reference)]
    from_faces = fill_missing_normals(points, vertex_normals_from_faces(points, faces))
    if np.allclose(from_faces, reference, equal_nan=True):
        return points, [("faces", from_faces)]
    return points, [("faces", from_faces), ("file", reference)]


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


def million(n: int = 1_000_000, noise: float = 0.0) -> None:
    """``noise``: Gaussian, its σ a fraction of the bounding box's diagonal."""
    from ipfit.datasets import synthetic

    points, truth, _ = synthetic.torus(n, rng=np.random.default_rng(0))
    if noise:
        sigma = noise * float(np.linalg.norm(np.ptp(points, axis=0)))
        points = points + np.random.default_rng(1).normal(0.0, sigma, points.shape)
    stages = []
    tracemalloc.start()
    start = time.perf_counter()
    est = estimate_normals(points, progress=lambda event: stages.append(f"{event['seconds']:.1f} s {event['message']}"))
    seconds = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux
    a = normal_agreement(est, truth)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    what = f"noise σ = {100 * noise:g}% of the diagonal" if noise else "no noise"
    print(f"estimate_normals on a torus of {n:,} random points, {what} (k = {DEFAULT_K[3]}), {os.cpu_count()} cores, "
          f"load average {load:.1f}:")
    print(f"  {seconds:.1f} s, peak traced memory {peak / 2**20:,.0f} MiB, peak resident {rss:,.0f} MiB; "
          f"median angle {a.median_angle:.2f}°, 90th percentile {np.percentile(a.angles, 90):.2f}°, "
          f"flipped {100 * a.flipped_fraction:.2f}%")
    print("  stages: " + "; ".join(stages) + "\n")


def quality() -> None:
    rng = np.random.default_rng(0)
    print(f"\n{'dataset':<22} {'reference':>9} {'points':>7} {'median°':>8} {'flipped':>8} "
          f"{'not outward':>12} {'flipped(outward)':>17}")
    for name in bundled.dataset_names():
        points, refs = references(name)
        faces = bundled.dataset_faces(name)
        outward = None
        if faces is not None and len(points) <= MAX_WINDING_VERTICES:
            outward = outward_vertices(points, faces)
        orders = [("", np.arange(len(points)))]
        if points.shape[1] == 2:
            orders.append((" (shuffled)", rng.permutation(len(points))))
        for label, order in orders:
            p = points[order]
            est = estimate_normals(p)
            for kind, reference in refs:
                a = normal_agreement(est, reference[order])
                line = (f"{name + label:<22} {kind:>9} {len(p):>7,} {a.median_angle:>8.2f} "
                        f"{100 * a.flipped_fraction:>7.2f}%")
                if outward is not None:
                    ok = outward[order]
                    line += f" {100 * (~ok).mean():>11.1f}% {100 * a.flipped[ok].mean():>16.2f}%"
                print(line)


def noisy() -> None:
    """Gaussian noise of σ = 0.5-2% of the bounding box's diagonal (contours shuffled too)."""
    from ipfit.datasets import synthetic
    from ipfit.normals import contour_normals

    rng = np.random.default_rng(0)
    cases = []
    for name in ("boot", "butterfly"):
        points, _ = bundled.load_dataset(name)
        cases += [(name, f, points, contour_normals(points, span=2), True) for f in (0.005, 0.01, 0.02)]
    for name, make in (("sphere", synthetic.sphere), ("torus", synthetic.torus)):
        points, truth, _ = make(3000, rng=rng)
        cases += [(name, f, points, truth, False) for f in (0.005, 0.01)]
    points, refs = references("bunny_res2")
    cases += [("bunny_res2", f, points, refs[0][1], False) for f in (0.005, 0.01)]
    print(f"\n{'noisy dataset':<22} {'σ/diag':>7} {'points':>7} {'median°':>8} {'flipped':>8} {'time':>7}")
    for name, fraction, points, reference, shuffle in cases:
        sigma = fraction * float(np.linalg.norm(np.ptp(points, axis=0)))
        p = points + rng.normal(0.0, sigma, points.shape)
        order = rng.permutation(len(p)) if shuffle else np.arange(len(p))
        start = time.perf_counter()
        est = estimate_normals(p[order])
        elapsed = time.perf_counter() - start
        a = normal_agreement(est, reference[order])
        print(f"{name:<22} {100 * fraction:>6.1f}% {len(p):>7,} {a.median_angle:>8.2f} "
              f"{100 * a.flipped_fraction:>7.2f}% {elapsed:>6.2f}s")


if __name__ == "__main__":
    million()
    million(noise=0.005)
    timing()
    quality()
    noisy()

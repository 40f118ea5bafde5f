"""Timing of the zero-set machinery: ``python benchmarks/bench_zeroset.py``.

* separable grid evaluation of a random degree-8 surface on a 256³ grid (target: well
  under a second), checked against point-wise evaluation on a random subset;
* marching cubes on the same grid, and a full ``extract_zero_set`` + ``quality`` at the
  default resolution for the torus.

Timings are the best of ``--repeat`` runs (other jobs on the machine make them noisy).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one


def best_of(repeat: int, fn):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--degree", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    from skimage.measure import marching_cubes

    from ipfit import ImplicitPolynomial, Normalization, basis
    from ipfit.datasets import synthetic
    from ipfit.zeroset.quality import quality
    from ipfit.zeroset.extract import extract_zero_set, grid_axes, grid_values

    rng = np.random.default_rng(0)
    n, g = args.resolution, args.degree
    poly = ImplicitPolynomial.from_coefficients(rng.standard_normal(basis.n_coefficients(3, g)), 3,
                                                Normalization([0.1, -0.2, 0.3], 0.8))
    bounds = np.array([[-1.0, 1.2], [-1.1, 0.9], [-0.8, 1.3]])
    seconds, values = best_of(args.repeat, lambda: grid_values(poly, bounds, n))
    print(f"grid_values: degree {g}, {n}^3 = {n**3:,} nodes: {seconds:.3f} s "
          f"({n**3 / seconds / 1e6:.0f} M nodes/s)")

    axes = grid_axes(bounds, n)
    index = tuple(rng.integers(0, n, 20000) for _ in range(3))
    pts = np.column_stack([ax[i] for ax, i in zip(axes, index)])
    t0 = time.perf_counter()
    reference = poly(pts)
    pointwise = time.perf_counter() - t0
    rel = np.abs(values[index] - reference).max() / np.abs(reference).max()
    print(f"  vs point-wise on 20,000 nodes: max relative difference {rel:.1e}; point-wise would take "
          f"~{pointwise * n**3 / len(pts):.1f} s for the whole grid")

    seconds, (verts, faces, _, _) = best_of(max(1, args.repeat // 2), lambda: marching_cubes(values, 0.0))
    print(f"marching_cubes on the same grid: {seconds:.3f} s ({len(faces):,} faces)")

    torus = synthetic.torus(5000)
    seconds, zs = best_of(args.repeat, lambda: extract_zero_set(torus.polynomial, points=torus.points))
    print(f"extract_zero_set, torus, default resolution {max(zs.shape)}: {seconds:.3f} s ({len(zs.faces):,} faces)")
    seconds, q = best_of(max(1, args.repeat // 2), lambda: quality(zs, torus.points))
    print(f"quality on that zero set (5,000 points): {seconds:.3f} s (F = {q.f_score:.3f})")


if __name__ == "__main__":
    main()

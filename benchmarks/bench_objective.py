"""Speed of the population objective and of the DE/PSO loops: ``python benchmarks/bench_objective.py``.

For N points on a 3D surface (default 5000, a torus) and degrees 4, 6, 8 (d = 35, 84, 165
coefficients, population P = 4d):

* ``objective``: one population evaluation, ``Objective(...)(A)`` (float64, then float32);
* ``bare product``: the single product [M; M_x; M_y; M_z] (4N × d) @ Aᵀ (d × P) that a plain
  implementation would start with (same precision), and ``ratio`` = objective / bare product;
* ``bare, 1 thread``: the same product with BLAS limited to one thread (the one-core bound);
* ``serial``: the objective with ``threads=1`` (one block after the other, BLAS threads);
* ``DE`` / ``PSO`` loop overhead: time per generation outside the objective call, as used by
  :func:`ipfit.refine` (whitened coordinates, unit-sphere projection), and its share of a
  generation;
* ``scipy DE``: ``scipy.optimize.differential_evolution(vectorized=True)`` driving the same
  objective: time per generation and its overhead share.

Timings are medians (and minima) of ``--repeat`` runs; other jobs on the machine make them
noisy, so compare ratios measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one


def timed(repeat: int, fn) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times))


class Timed:
    """Wrap an objective and accumulate the time spent inside it."""

    def __init__(self, func):
        self.func, self.seconds, self.calls = func, 0.0, 0

    def __call__(self, x):
        t0 = time.perf_counter()
        out = self.func(x)
        self.seconds += time.perf_counter() - t0
        self.calls += 1
        return out


def loop_overhead(solver_cls, obj, start, r_inv, generations, **kwargs) -> tuple[float, float]:
    """(seconds per generation, overhead fraction) of a solver run the way refine runs it."""
    from ipfit.fitting.objective import single_threaded_blas
    from ipfit.optimize import unit_rows

    inner = Timed(obj)

    def func(y):  # refine's whitened-coordinates wrapper; its product counts as loop overhead
        return inner(y @ r_inv.T)

    with single_threaded_blas():
        solver = solver_cls(func, start, maxiter=generations, rng=0, project=unit_rows, **kwargs)
        inner.seconds = 0.0
        t0 = time.perf_counter()
        for _ in solver:
            pass
        total = time.perf_counter() - t0
        outside = total - inner.seconds
    return total / generations, outside / total


def scipy_de(obj, d, size, generations) -> tuple[float, float]:
    from scipy.optimize import differential_evolution

    inner = Timed(lambda x: obj(x.T))
    init = np.random.default_rng(0).uniform(-1, 1, (size, d))
    t0 = time.perf_counter()
    differential_evolution(inner, [(-1.0, 1.0)] * d, vectorized=True, updating="deferred", maxiter=generations,
                           init=init, polish=False, tol=0, atol=0, mutation=0.7, recombination=0.9, seed=0)
    total = time.perf_counter() - t0
    return total / (generations + 1), (total - inner.seconds) / total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=5000)
    parser.add_argument("--degrees", type=int, nargs="+", default=[4, 6, 8])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--generations", type=int, default=20)
    args = parser.parse_args()

    from ipfit import basis
    from ipfit.datasets import synthetic
    from ipfit.fitting.objective import Objective, _controller, default_threads, single_threaded_blas
    from ipfit.optimize import DifferentialEvolution, ParticleSwarm, unit_rows
    from ipfit.polynomial import Normalization

    shape = synthetic.torus(args.points, rng=0)
    u = Normalization.from_points(shape.points).apply(shape.points)
    print(f"# Objective benchmark: N = {args.points} points (torus), P = 4d, "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"worker threads {default_threads()}, threadpoolctl {'yes' if _controller() is not None else 'no'}")
    print()
    print("| degree | d | P | precision | objective ms | serial ms | bare product ms | bare, 1 thread ms | ratio | "
          "DE ms/gen | DE overhead | PSO ms/gen | PSO overhead | scipy DE ms/gen | scipy overhead |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for degree in args.degrees:
        d = basis.n_coefficients(3, degree)
        size = 4 * d
        rng = np.random.default_rng(degree)
        pop = unit_rows(rng.normal(size=(size, d)))
        m, dm = basis.monomials_and_gradients(u, degree)
        for dtype in (np.float64, np.float32):
            stacked = np.concatenate([m, dm.reshape(-1, d)]).astype(dtype)
            obj = Objective(u, shape.normals, degree, dtype=dtype)
            serial = Objective(u, shape.normals, degree, dtype=dtype, threads=1)
            pop_t = np.ascontiguousarray(pop.T, dtype=dtype)
            obj(pop), serial(pop), stacked @ pop_t  # warm up (compilation, pools)
            t_obj, t_obj_min = timed(args.repeat, lambda: obj(pop))
            t_ser, _ = timed(args.repeat, lambda: serial(pop))
            t_bare, t_bare_min = timed(args.repeat, lambda: stacked @ pop_t)
            with single_threaded_blas():
                t_one, _ = timed(args.repeat, lambda: stacked @ pop_t)
            row = [str(degree), str(d), str(size), np.dtype(dtype).name, f"{1e3 * t_obj:.2f} (min {1e3 * t_obj_min:.2f})",
                   f"{1e3 * t_ser:.2f}", f"{1e3 * t_bare:.2f} (min {1e3 * t_bare_min:.2f})", f"{1e3 * t_one:.2f}",
                   f"{t_obj / t_bare:.2f}"]
            if dtype == np.float64:
                r_inv = np.linalg.inv(obj.whitening())
                start = unit_rows(pop)
                de_gen, de_over = loop_overhead(DifferentialEvolution, obj, start, r_inv, args.generations)
                ps_gen, ps_over = loop_overhead(ParticleSwarm, obj, start, r_inv, args.generations)
                sp_gen, sp_over = scipy_de(obj, d, size, max(3, args.generations // 4))
                row += [f"{1e3 * de_gen:.2f}", f"{100 * de_over:.1f}%", f"{1e3 * ps_gen:.2f}", f"{100 * ps_over:.1f}%",
                        f"{1e3 * sp_gen:.2f}", f"{100 * sp_over:.1f}%"]
            else:
                row += [""] * 6
            print("| " + " | ".join(row) + " |", flush=True)


if __name__ == "__main__":
    main()

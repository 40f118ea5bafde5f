"""Cost of one polish step: ``python benchmarks/bench_polish.py [--out docs/polish-cost.md]``.

The L-BFGS polish calls :meth:`ipfit.fitting.objective.Objective.value_and_grad` once or twice per
iteration, on the data plus the far-field term's samples, thousands of times per fit. For
each bundled dataset at a degree the recommended pipeline reaches, on the rows the polish
sees (the search's spread subsample, then all points, each with the term's samples):

* ``rows``: data points + far-field samples, ``d`` coefficients;
* ``pass ms``: one ``value_and_grad`` (the compiled single pass over the stacked rows);
* ``numpy ms``: the same value and gradient written with numpy, each part on its own (four
  matrix-vector products and the per-point arithmetic for the data, the same again for the
  term's samples): the implementation before the compiled pass; the two agree to 1e-9;
* ``products ms``: the four matrix-vector products alone on the stacked rows (M a, L B, Mᵀc,
  Lᵀ C), the floor of any implementation that streams the matrix through BLAS four times;
* ``speed-up``: numpy / pass;
* ``L-BFGS ms/it``: a whole polish (at most 300 iterations from the 3L fit, preconditioned as
  in :func:`ipfit.refine`), per iteration, and ``pass share``: the share of one such polish
  spent inside ``value_and_grad`` (the rest is SciPy's L-BFGS-B and the preconditioning).

Timings are minima of interleaved runs (other jobs on a shared machine only add time).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

CASES = [("airplane", 10), ("boot", 6), ("butterfly", 14), ("apple", 8), ("duck", 8), ("bunny", 8)]
SEARCH_POINTS = {2: 1000, 3: 3000}


def interleaved(fns, budget: float = 2.0, min_repeat: int = 5, max_repeat: int = 200) -> list[float]:
    times: list[list[float]] = [[] for _ in fns]
    started = time.perf_counter()
    while len(times[0]) < max_repeat and (len(times[0]) < min_repeat or time.perf_counter() - started < budget):
        for fn, bucket in zip(fns, times):
            t0 = time.perf_counter()
            fn()
            bucket.append(time.perf_counter() - t0)
    return [float(np.min(t)) for t in times]


def numpy_value_and_grad(obj, term, a):
    """The paper's objective plus the far-field term, value and gradient, in plain numpy."""
    from ipfit import basis
    from ipfit.fitting.objective import TAUBIN_CAP

    tiny, floor = float(np.finfo(np.float64).tiny), 1e-100
    m = obj._design(0, obj.n_points, np.float64)
    low, nrm, n = m[:, : obj.n_lower], obj.normals64, obj.n_points
    bt = basis.gradient_coefficients(a[:, None], obj.dim, obj.degree)
    f, g = m @ a, low @ bt
    sq = np.maximum(np.einsum("ij,ij->i", g, g), tiny)
    inv = 1.0 / np.sqrt(sq)
    taubin = np.abs(f) * inv
    capped = taubin >= TAUBIN_CAP
    taubin = np.minimum(taubin, TAUBIN_CAP)
    cosine = np.einsum("ij,ij->i", g, nrm) * inv
    inv = np.where(~capped & (sq > floor), inv, 0.0)
    weight_g = -(taubin * inv * inv)[:, None] * g - obj.delta * (nrm - (cosine * inv)[:, None] * g) * inv[:, None]
    grad = m.T @ (np.sign(f) * inv)
    basis.add_gradient_adjoint(grad, low.T @ weight_g, obj.degree)
    value = taubin.sum() / n + obj.delta * (1 - cosine.sum() / n)
    tv, tg = term.value_and_grad(a)
    return value + tv, grad / n + tg


def case(name: str, degree: int, n_points: int | None):
    from ipfit import RECOMMENDED, fit_3l
    from ipfit.datasets import bundled
    from ipfit.fitting.farfield import FarFieldTerm
    from ipfit.fitting.objective import Objective
    from ipfit.optimize import polish
    from ipfit.geometry.sampling import spread_subsample

    pts, nrm = bundled.load_dataset(name)
    if n_points is not None and len(pts) > n_points:
        keep = spread_subsample(pts, n_points, rng=0)
        pts, nrm = pts[keep], nrm[keep]
    fit = fit_3l(pts, nrm, degree)
    u = fit.normalization.apply(pts)
    term = FarFieldTerm.from_data(u, nrm, degree, RECOMMENDED.far_term_weight)
    obj = Objective(u, nrm, degree, terms=[term])
    a = fit.coefficients
    value, grad = obj.value_and_grad(a)
    ref_value, ref_grad = numpy_value_and_grad(obj, term, a)
    assert abs(value - ref_value) <= 1e-9 * abs(ref_value)
    assert np.abs(grad - ref_grad).max() <= 1e-9 * np.abs(ref_grad).max()

    rows = np.vstack([obj._design(0, obj.n_points, np.float64), term._m])
    low = rows[:, : obj.n_lower]
    b = np.ones((obj.n_lower, obj.dim))
    c, cg = np.ones(len(rows)), np.ones((len(rows), obj.dim))

    def products():
        return rows @ a, low @ b, rows.T @ c, low.T @ cg

    r = obj.whitening()
    spent = [0.0]

    def timed_pass(x):
        t0 = time.perf_counter()
        out = obj.value_and_grad(x)
        spent[0] += time.perf_counter() - t0
        return out

    def run_polish():
        spent[0] = 0.0
        t0 = time.perf_counter()
        result = polish(timed_pass, a, maxiter=300, precondition=r)
        return result, time.perf_counter() - t0

    pass_s, numpy_s, products_s = interleaved([lambda: obj.value_and_grad(a), lambda: numpy_value_and_grad(obj, term, a),
                                               products])
    polish_s = interleaved([run_polish], budget=3.0, min_repeat=2, max_repeat=5)[0]
    result, total = run_polish()
    iterations = max(result.nit, 1)
    return {"shape": name, "degree": degree, "rows": f"{obj.n_points} + {len(term.samples)}", "d": obj.n_coefficients,
            "pass": 1e3 * pass_s, "numpy": 1e3 * numpy_s, "products": 1e3 * products_s, "speedup": numpy_s / pass_s,
            "iteration": 1e3 * polish_s / iterations, "share": spent[0] / total, "nit": result.nit}


def markdown(rows) -> str:
    head = ("| shape | degree | rows (data + far) | d | pass ms | numpy ms | products ms | speed-up | "
            "L-BFGS ms/it | pass share | iterations |\n|---|---|---|---|---|---|---|---|---|---|---|\n")
    body = "".join(f"| {r['shape']} | {r['degree']} | {r['rows']} | {r['d']} | {r['pass']:.3f} | {r['numpy']:.3f} | "
                   f"{r['products']:.3f} | {r['speedup']:.1f}× | {r['iteration']:.3f} | {100 * r['share']:.0f}% | "
                   f"{r['nit']} |\n" for r in rows)
    return head + body


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="write a markdown page here")
    args = parser.parse_args(argv)
    from ipfit.datasets import bundled

    rows = []
    for name, degree in CASES:
        dim = bundled.load_dataset(name)[0].shape[1]
        for n in (SEARCH_POINTS[dim], None):
            if n is None and len(bundled.load_dataset(name)[0]) <= SEARCH_POINTS[dim]:
                continue
            row = case(name, degree, n)
            if n is not None and len(bundled.load_dataset(name)[0]) > n:
                row["shape"] += f" ({n})"
            rows.append(row)
            print(markdown([row]).splitlines()[-1], flush=True)
    table = markdown(rows)
    print(table)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write("# Cost of one polish step\n\n"
                     f"Generated by `python benchmarks/bench_polish.py --out {args.out}` on "
                     f"{time.strftime('%Y-%m-%d')} ({platform.machine()}, shared 2-core machine). "
                     "What each column means is in the script's docstring; timings are minima of interleaved runs.\n\n"
                     + table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

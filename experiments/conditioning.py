"""What the monomial coefficients cost at high degrees: conditioning of the bases, and the rounding
of the stored polynomial against exact arithmetic (issue 32, item 1).

Usage::

    python experiments/conditioning.py [--out docs/conditioning.md]
    python experiments/conditioning.py --page-only [--out docs/conditioning.md]

For each shape (the bundled contours and meshes, the three worst MPEG-7 development contours of
docs/degree-rule.md and three Turk development models of docs/quality-3d.md) and each degree
(2D: 6, 10, 14, 20; 3D: 6, 8, 10, 12; only where the shape has the capture rule's 2 points per
coefficient), the recommended pipeline fits that degree alone (``fit_adaptive(min_degree=g,
max_degree=g)``, seed 0) and the page records, on the shape's normalised points:

* **κ monomial**: the condition number of the stacked values and gradients A = [M; ∂M/∂x; …]
  of the monomial basis the coefficients are written in (= κ(R), R its triangular QR factor);
* **κ whitened**: the condition number of A R⁻¹, with R⁻¹ the explicit inverse the search and the
  polish use (``ipfit.fitting.refine._whitening``): the basis they move in, orthonormal on the data
  in exact arithmetic; what it is in float64 says whether that basis survives rounding;
* **rounding of f**: the stored coefficients evaluated in float64 by ipfit
  (``ImplicitPolynomial.evaluate_normalized``) against the same coefficients evaluated exactly
  (``fractions.Fraction``, every product and sum exact) at 200 data points and 200 points uniform
  in the box of the zero-set extraction (the data's box grown by a quarter on each side): on the
  data the largest |Δf| / |∇f| (how far rounding moves the zero set) in units of τ (2 % of the box
  diagonal, the F-score's tolerance); in the box the largest |Δf| / |f| (below 1: the sign, and so
  the zero set drawn from a grid, is never wrong);
* **JSON round trip**: whether ``ImplicitPolynomial.from_json(poly.to_json())`` gives back every
  coefficient bit for bit;
* the fit's F-score at that degree (its own quality measure).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
SHARED = ROOT.parent / "shared"
SHAPES_2D = ["boot", "airplane", "butterfly", *(str(SHARED / "data" / "mpeg7-dev" / f"{n}.csv")
                                               for n in ("fly-5", "octopus-5", "octopus-15"))]
SHAPES_3D = ["apple", "duck", "bunny", *(str(SHARED / "data" / "turk-dev" / f"{n}.ply")
                                         for n in ("chopper", "walkman", "big_spider"))]
DEGREES = {2: (6, 10, 14, 20), 3: (6, 8, 10, 12)}
SAMPLES = 200
GROW = 0.25


def exact_values(poly, u: np.ndarray) -> np.ndarray:
    """f at the normalised points ``u`` from the stored coefficients, in exact rational arithmetic
    (rounded once, to float64, at the end)."""
    from ipfit import basis

    exps = basis.exponents(poly.dim, poly.degree)
    coefficients = [Fraction(float(c)) for c in poly.coefficients]
    out = np.empty(len(u))
    for i, row in enumerate(u):
        powers = []
        for x in row:
            x = Fraction(float(x))
            column = [Fraction(1)]
            for _ in range(poly.degree):
                column.append(column[-1] * x)
            powers.append(column)
        total = Fraction(0)
        for c, e in zip(coefficients, exps, strict=True):
            term = c
            for axis, k in enumerate(e):
                term *= powers[axis][k]
            total += term
        out[i] = float(total)
    return out


def whitened_condition(u: np.ndarray, degree: int) -> tuple[float, float]:
    """(κ of the monomial values and gradients A, κ of A R⁻¹ with the search's own R⁻¹)."""
    from ipfit import basis
    from ipfit.fitting.objective import Objective
    from ipfit.fitting.refine import _whitening

    objective = Objective(u, np.ones_like(u) / np.sqrt(u.shape[1]), degree)  # R depends on the points only
    r, r_inv = _whitening(objective)
    sv = np.linalg.svd(r, compute_uv=False)
    gram = np.zeros((len(r), len(r)))
    for start in range(0, len(u), 4096):
        m, grads = basis.monomials_and_gradients(u[start:start + 4096], degree)
        block = np.concatenate([m, grads.reshape(-1, m.shape[1])]) @ r_inv
        gram += block.T @ block
    eig = np.linalg.eigvalsh(gram)
    return float(sv[0] / sv[-1]), float(np.sqrt(eig[-1] / max(eig[0], 1e-300)))


def measure(shape: str, degree: int) -> dict | None:
    import ipfit
    from ipfit import basis

    cloud = ipfit.load(shape)
    points = np.asarray(cloud.points, dtype=np.float64)
    dim = points.shape[1]
    if len(points) < 2 * basis.n_coefficients(dim, degree):
        return None
    start = time.perf_counter()
    result = ipfit.fit_adaptive(cloud, min_degree=degree, max_degree=degree, rng=0)
    seconds = time.perf_counter() - start
    poly = result.polynomial
    u_all = poly.normalization.apply(points)
    kappa, kappa_white = whitened_condition(u_all, degree)
    rng = np.random.default_rng(0)
    data = u_all[rng.choice(len(u_all), size=min(SAMPLES, len(u_all)), replace=False)]
    lo, hi = u_all.min(axis=0), u_all.max(axis=0)
    box = rng.uniform(lo - GROW * (hi - lo), hi + GROW * (hi - lo), (SAMPLES, dim))
    tau = 0.02 * float(np.linalg.norm(hi - lo))  # the F-score's τ, in normalised units
    f_data, g_data = poly.evaluate_normalized(data, gradient=True)
    shift = np.abs(f_data - exact_values(poly, data)) / np.linalg.norm(g_data, axis=1)
    f_box = poly.evaluate_normalized(box)
    exact_box = exact_values(poly, box)
    relative = np.abs(f_box - exact_box) / np.abs(exact_box)
    back = ipfit.ImplicitPolynomial.from_json(poly.to_json())
    return {"shape": Path(shape).stem, "dim": dim, "n": len(points), "degree": degree,
            "selected": int(result.selected_degree), "f_score": float(result.degrees[-1].quality.f_score),
            "seconds": seconds, "kappa": kappa, "kappa_whitened": kappa_white,
            "shift_tau_max": float(shift.max() / tau), "shift_tau_median": float(np.median(shift) / tau),
            "box_relative_max": float(relative.max()),
            "json_exact": bool(np.array_equal(back.coefficients, poly.coefficients)
                               and np.array_equal(back.center, poly.center) and back.scale == poly.scale),
            "max_abs_coefficient": float(np.abs(poly.coefficients).max())}


def page(data: dict) -> str:
    rows = data["rows"]
    intro = ("ipfit writes, reads and evaluates a polynomial by its coefficients in the monomial basis of the "
             "normalised data (the result format, `docs/result-format.md`). That basis is ill-conditioned at high "
             "degrees (κ monomial below: how unevenly a unit change of the coefficients moves f and ∇f on the "
             "data). The fit never solves in it: the start fits are solved by QR of the data's design matrix, and "
             "the search and the polish move in y = R a, R the triangular factor of the stacked values and "
             "gradients (`Objective.whitening`), a discrete orthonormal basis of the data's monomials, whose "
             "condition number in float64 is the κ whitened column. Every evaluation of the objective, though, is at "
             "the monomial coefficients a = R⁻¹ y, and the coefficients written are that vector (scaled to unit "
             "norm), the one the quality measure then judges: the fit's answer is its monomial vector, and no "
             "conversion between bases happens after it. What is "
             "left to ask is whether evaluating the monomial form in float64 loses anything: the rounding columns "
             "compare it with exact arithmetic on the same coefficients.")
    header = ("| shape | N | degree | F | κ monomial | κ whitened − 1 | rounding on the data: max (median) of "
              "abs(Δf) / ‖∇f‖, in τ | rounding in the box: max of abs(Δf / f) | JSON round trip | largest "
              "abs(coefficient) | seconds |")
    lines = ["# Conditioning: what the monomial coefficients cost at high degrees", "",
             (f"Generated by `python experiments/conditioning.py` on {data['date']} ({data['machine']}; "
              f"{data['minutes']:.0f} minutes), seed 0. Re-render: `python experiments/conditioning.py "
              "--page-only`. The protocol is in the script's docstring."), "", intro, "", header,
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['shape']} | {r['n']:,} | {r['degree']} | {r['f_score']:.3f} | {r['kappa']:.1e} | "
                     f"{r['kappa_whitened'] - 1:.1e} | {r['shift_tau_max']:.1e} ({r['shift_tau_median']:.1e}) | "
                     f"{r['box_relative_max']:.1e} | {'bit for bit' if r['json_exact'] else 'CHANGED'} | "
                     f"{r['max_abs_coefficient']:.2f} | {r['seconds']:.1f} |")
    shift = max(rows, key=lambda r: r["shift_tau_max"])
    box = max(rows, key=lambda r: r["box_relative_max"])
    white = max(rows, key=lambda r: r["kappa_whitened"])
    kappa = max(rows, key=lambda r: r["kappa"])
    exact = all(r["json_exact"] for r in rows)
    signs = ": below 1, so no sign on the extraction grid is wrong" if box["box_relative_max"] < 1 else ""
    negligible = shift["shift_tau_max"] < 1e-3 and box["box_relative_max"] < 1e-3 and exact
    lines += ["", "## What it says", "",
              (f"* The monomial basis reaches κ {kappa['kappa']:.1e} ({kappa['shape']}, degree {kappa['degree']}); "
               f"the basis the search moves in has κ at most 1 + {white['kappa_whitened'] - 1:.1e} in float64 "
               f"({white['shape']}, degree {white['degree']}). Where κ monomial passes 1 / ε (about 4.5e15) "
               "nothing promises orthonormality any more; `tests/test_conditioning.py` holds the whitened κ of a "
               "curve at degree 20 whose monomial κ passes 1e15 below 10."),
              (f"* Evaluating the stored monomial coefficients in float64 moves the zero set by at most "
               f"{shift['shift_tau_max']:.1e} τ on the data ({shift['shape']}, degree {shift['degree']}); in the "
               f"grown box the value's relative error is at most {box['box_relative_max']:.1e} ({box['shape']}, "
               f"degree {box['degree']}){signs}. "
               "κ bounds how far the coefficients move for a change of f (the inverse problem, which the fit "
               "solves by QR), not how accurately f is evaluated from given coefficients: that error is about "
               "ε Σ|a_k m_k(u)| (ε = 2.2e-16), and the coefficients of a unit-norm fit on normalised data stay "
               "small (largest abs(coefficient) column)."),
              ("* Every JSON round trip gives the coefficients back bit for bit (Python writes the shortest "
               "decimal that reads back as the same float64)." if exact else
               "* Some JSON round trips changed the coefficients: see the table."),
              ("* So at these degrees a second set of coefficients in an orthogonal basis (Chebyshev or Legendre "
               "on the box) would add nothing: it would be converted from the monomial one, which holds the fit's "
               "own variables, and either gives the same surface to far below τ. The result format keeps one set."
               if negligible else
               "* The monomial form loses more than 1e-3 τ somewhere above: an orthogonal basis would be worth "
               "writing beside it."), ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "conditioning.md"))
    parser.add_argument("--page-only", action="store_true", help="rewrite the page from the .json twin")
    args = parser.parse_args(argv)
    out = Path(args.out)
    twin = out.with_suffix(".json")
    if args.page_only:
        data = json.loads(twin.read_text())
    else:
        from robust import _machine  # the processor's name

        start = time.perf_counter()
        rows = []
        for dim, shapes in ((2, SHAPES_2D), (3, SHAPES_3D)):
            for shape in shapes:
                for degree in DEGREES[dim]:
                    row = measure(shape, degree)
                    if row is not None:
                        rows.append(row)
                        print(row, flush=True)
        data = {"argv": sys.argv[1:] if argv is None else list(argv), "date": time.strftime("%Y-%m-%d"),
                "machine": _machine(), "minutes": (time.perf_counter() - start) / 60, "rows": rows}
        twin.write_text(json.dumps(data, indent=1))
    out.write_text(page(data))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

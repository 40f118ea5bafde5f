"""The degree rules compared on the bundled contours and the 140 MPEG-7 development contours.

Usage::

    git worktree add --detach ../ipfit-before 69d992a   # the code before the capture rule
    python experiments/degree_rule.py --before ../ipfit-before [--dev ../shared/data/mpeg7-dev]
                                      [--out docs/degree-rule.md] [--from-json docs/degree-rule.json]

For every contour it runs three pipelines and measures the selected degree's zero set with
:func:`ipfit.zeroset.quality.quality` (F-score, spurious components):

* **paper**: the paper's exact pipeline (``ipfit fit --paper``: DE, Algorithm 1);
* **geometric**: the recommended pipeline as it was before the capture rule (the paper's rule
  restricted to clean degrees, search on 3,000 points, degrees up to 10), run by the code of
  ``--before`` (a checkout of commit 69d992a);
* **capture**: today's recommended pipeline (the capture rule of :mod:`ipfit.degree.rules`,
  degrees up to 20, beyond 14 only while the F-score rises) on the points as arrays,
  ``fit_adaptive(points, normals)``: without the contour's order its topology is not known, so
  none is held (``ipfit fit FILE`` holds it: ``experiments/topology.py``'s default column).

Two worker processes run side by side (``experiments/_versions.py``): one with the code of
``--before`` (the geometric pipeline), one with this checkout (the paper's and the capture
pipelines). The seconds are each fit's wall-clock time. The rows go to ``--out`` with a
``.json`` twin, from which ``--from-json`` rewrites the Markdown without fitting again.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np
from _versions import load_data, n_beyond_specks, run_side_by_side, spurious_cell, spurious_record
import sys

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

PIPELINES = ("paper", "geometric", "capture")
BUNDLED = ("boot", "airplane", "butterfly")


def _settings(pipeline: str):
    from ipfit import PAPER, PAPER_METHOD, PAPER_RULE

    if pipeline == "paper":
        return {"method": PAPER_METHOD, "options": PAPER, "rule": PAPER_RULE}
    return {}  # "geometric" (the --before code's default) and "capture" (this code's default)


def fit_one(spec: str, pipeline: str, seed: int) -> dict:
    """One pipeline on one contour: selected degree, its quality and the fit's seconds."""
    from ipfit import fit_adaptive, quality  # public names: the same in either checkout

    data = load_data(spec)
    start = time.perf_counter()
    result = fit_adaptive(data.points, data.normals, rng=seed, **_settings(pipeline))
    seconds = time.perf_counter() - start
    chosen = result.at_degree(result.selected_degree)
    q = chosen.quality or quality(chosen.polynomial, data.points, ordered_contour=True)
    return {"shape": Path(spec).stem, "n": len(data.points), "pipeline": pipeline,
            "degree": result.selected_degree, "f_score": q.f_score, "precision": q.precision, "recall": q.recall,
            "n_spurious": q.n_spurious, "closed": bool(q.closed), "seconds": seconds, "reason": result.reason,
            "degrees_tried": [d.degree for d in result.degrees], **spurious_record(q)}


def run(specs: list[str], before: str, seed: int) -> list[dict]:
    return run_side_by_side(fit_one, before, [(spec, "geometric", seed) for spec in specs],
                            [(spec, pipeline, seed) for spec in specs for pipeline in ("capture", "paper")])


def _summary(rows: list[dict], pipeline: str) -> dict:
    mine = [r for r in rows if r["pipeline"] == pipeline]
    f = np.array([r["f_score"] for r in mine])
    return {"median": float(np.median(f)), "p10": float(np.percentile(f, 10)), "min": float(f.min()),
            "spurious": sum(n_beyond_specks(r) > 0 for r in mine), "not_closed": sum(not r["closed"] for r in mine),
            "seconds": float(sum(r["seconds"] for r in mine)), "mean_degree": float(np.mean([r["degree"] for r in mine])),
            "n": len(mine)}


def conditioning(names=BUNDLED, degrees=(6, 10, 14, 20), label: str = "contour") -> list[str]:
    """Condition numbers, on each shape's normalised points (a bundled dataset's name or a file),
    of the monomial basis the coefficients are written in (the stacked values and gradients);
    "—" where the shape has fewer than the capture rule's 2 points per coefficient."""
    from ipfit import basis, load
    from ipfit.polynomial import Normalization

    lines = [f"| {label} | " + " | ".join(f"κ at degree {g}" for g in degrees) + " |",
             "|---|" + "---|" * len(degrees)]
    for name in names:
        points = load(name).points
        u = Normalization.from_points(points).apply(points)
        cells = []
        for g in degrees:
            if len(u) < 2 * basis.n_coefficients(u.shape[1], g):
                cells.append("—")
                continue
            m, grads = basis.monomials_and_gradients(u, g)
            sv = np.linalg.svd(np.concatenate([m, grads.reshape(-1, m.shape[1])]), compute_uv=False)
            cells.append(f"{sv[0] / sv[-1]:.1e}")
        lines.append(f"| {Path(name).stem} | " + " | ".join(cells) + " |")
    return lines


def markdown(rows: list[dict], seed: int) -> str:
    by_shape: dict[str, dict[str, dict]] = {}
    for r in rows:
        by_shape.setdefault(r["shape"], {})[r["pipeline"]] = r
    sums = {p: _summary(rows, p) for p in PIPELINES}
    ratio = sums["capture"]["seconds"] / sums["geometric"]["seconds"]
    lines = [
        "# The degree rules on 143 contours",
        "",
        f"Generated by `python experiments/degree_rule.py` on {date.today().isoformat()} ({platform.machine()}), "
        f"seed {seed}, two worker processes side by side with one thread each (the geometric pipeline in one, with "
        "the code of commit 69d992a; the paper's and the capture pipelines in the other). Shapes: the bundled contours (boot, airplane, butterfly) and the 140 "
        "MPEG-7 development contours (instances 5 and 15 of each class). F-score, spurious components and "
        "closedness are measured by `ipfit.zeroset.quality.quality` (τ = 2% of the box diagonal) at the selected degree; "
        "spurious components are counted beyond *specks* (`ipfit.degree.rules.is_speck`: shorter than τ/2 and within 2τ of "
        "the data, fragments at the sampling resolution), which are shown in brackets.",
        "",
        "* **paper**: `ipfit fit --paper` (the paper's DE and Algorithm 1, degrees up to 10);",
        "* **geometric**: the recommended pipeline before the capture rule, run by the code of commit 69d992a "
        "(Algorithm 1 restricted to clean degrees, search on 3,000 points, degrees up to 10);",
        "* **capture**: the recommended pipeline today (the capture rule of `ipfit.degree.rules`, degrees up to 20 within "
        "2 points per coefficient, beyond 14 only while the F-score rises, the 2D search settings of "
        "`ipfit.fitting.options.AUTO`) on the points as arrays, `fit_adaptive(points, normals)`: without the contour's "
        "order its topology is not known, so none is held (`ipfit fit FILE` holds it: the default column of "
        "docs/topology.md).",
        "",
        "| pipeline | median F | 10th percentile | minimum | with spurious components | not closed | "
        "mean degree | total seconds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for p in PIPELINES:
        s = sums[p]
        lines.append(f"| {p} | {s['median']:.3f} | {s['p10']:.3f} | {s['min']:.3f} | {s['spurious']} | "
                     f"{s['not_closed']} | {s['mean_degree']:.1f} | {s['seconds']:.0f} |")
    lines += ["", f"Total time of the capture rule / the geometric rule: {ratio:.2f}×.", ""]
    lines += ["## Per shape", "",
              "*degree / F-score / spurious components / seconds*; the capture rule's stop reason last.", "",
              "| shape | N | paper | geometric | capture | stop |", "|---|---|---|---|---|---|"]

    def cell(r):
        return f"{r['degree']} / {r['f_score']:.3f} / {spurious_cell(r)} / {r['seconds']:.1f}"

    for shape in sorted(by_shape, key=lambda s: (s not in BUNDLED, s)):
        got = by_shape[shape]
        if len(got) < len(PIPELINES):
            continue
        lines.append(f"| {shape} | {got['capture']['n']} | {cell(got['paper'])} | {cell(got['geometric'])} | "
                     f"{cell(got['capture'])} | {got['capture']['reason']} |")
    worst = sorted((by_shape[s]["capture"] for s in by_shape if "capture" in by_shape[s]),
                   key=lambda r: r["f_score"])[:10]
    lines += ["", "## The ten lowest F-scores of the capture rule", "",
              "| shape | degree | F | precision | recall | degrees tried |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['shape']} | {r['degree']} | {r['f_score']:.3f} | {r['precision']:.3f} | {r['recall']:.3f} | "
              f"{', '.join(map(str, r['degrees_tried']))} |" for r in worst]
    lines += ["", "## Conditioning at high degrees", "",
              "The coefficients are written in the monomial basis of the normalised data (centred, divided by the "
              "mean distance to the centre), whose conditioning degrades with the degree: κ below is the condition "
              "number of the stacked values and gradients [M; ∂M/∂x; ∂M/∂y] on each contour's points, i.e. how "
              "unevenly a unit change of the coefficients moves f and ∇f on the data. DE, PSO and the L-BFGS polish "
              "do not move in those coefficients but in y = R a, R the triangular factor of that matrix "
              "(`Objective.whitening`), where every direction moves f and ∇f on the data alike (κ = 1); the start "
              "fits are solved by QR, never by the normal equations. Degree 20, the capture rule's last in 2D, is "
              "therefore as well posed for the search as degree 6; the rule also keeps at least 2 points per "
              "coefficient (—: fewer points). What evaluating the written monomial coefficients loses against "
              "exact arithmetic, and κ of the whitened basis in float64: `docs/conditioning.md`.", "",
              *conditioning(), ""]
    lines += ["", "Regenerate: `git worktree add --detach ../ipfit-before 69d992a`, then "
              "`python experiments/degree_rule.py --before ../ipfit-before` (about 12 minutes on 2 cores); "
              "`--from-json docs/degree-rule.json` rewrites this page from the stored rows.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dev", default="../shared/data/mpeg7-dev", help="folder of development contours (CSV)")
    parser.add_argument("--out", default="docs/degree-rule.md")
    parser.add_argument("--before", default="../ipfit-before",
                        help="a checkout of the code before the capture rule (commit 69d992a)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit", type=int, help="only the first N development contours (a quick look)")
    parser.add_argument("--from-json", help="rewrite the Markdown from stored rows instead of fitting")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if args.from_json:
        rows = json.loads(Path(args.from_json).read_text(encoding="utf-8"))
    else:
        dev = sorted(Path(args.dev).glob("*.csv"))[: args.limit]
        rows = run(list(BUNDLED) + [str(p) for p in dev], args.before, args.seed)
        out.with_suffix(".json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    out.write_text(markdown(rows, args.seed), encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

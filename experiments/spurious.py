"""Spurious zero-set components: 3L, the paper's DE and ipfit's default, on every dataset.

Usage::

    python experiments/spurious.py [--out docs/spurious.md] [--iterations 500] [--quick]

For each bundled dataset and a few generated shapes (sphere, torus, ellipsoid, a
superquadric, star-shaped contours) it runs ipfit's recommended adaptive pipeline, then, at the
degree it selected, plain 3L and the paper's DE (``refine(method="de", options=PAPER)``) and
measures all three with :func:`ipfit.zeroset.quality.quality`. It also times the paper's whole
pipeline (``ipfit fit --paper``: ``fit_adaptive(method=PAPER_METHOD, options=PAPER,
rule=PAPER_RULE)``) against the recommended one, in the same run. Every number in the written
Markdown comes from this run; ``benchmarks/bench_pipeline.py`` runs it and adds the timings.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np

import sys
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

import ipfit
from ipfit import PAPER, PAPER_METHOD, PAPER_RULE, RECOMMENDED
from ipfit.degree.adaptive import fit_adaptive
from ipfit.datasets import bundled, synthetic
from ipfit.zeroset.quality import quality
from ipfit.fitting.refine import refine

SUBSAMPLE = 3000  # 3D scans larger than this are subsampled (seed 0), as the paper did


def _superquadric(n: int = 800, axes=(1.5, 1.0, 0.8)):
    """Points on Σ (x_j / axes_j)⁴ = 1 with its normals (the gradient's direction)."""
    d = synthetic.sphere(n).points
    q = d / np.sum(d**4, axis=1, keepdims=True) ** 0.25
    nrm = q**3 / np.asarray(axes)
    return q * np.asarray(axes), nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def _star(points: int, arms: int, depth: float):
    t = np.linspace(0, 2 * np.pi, points, endpoint=False)
    r = 1 + depth * np.cos(arms * t)
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    dr = -depth * arms * np.sin(arms * t)
    tangent = np.column_stack([dr * np.cos(t) - r * np.sin(t), dr * np.sin(t) + r * np.cos(t)])
    nrm = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    return pts, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def shapes(quick: bool):
    """(name, points, normals, faces, ordered_contour) for every shape of the table."""
    names = ["airplane", "boot", "butterfly"] + ([] if quick else ["apple", "duck", "bunny"])
    for name in names:
        pts, nrm = bundled.load_dataset(name)
        faces = bundled.dataset_faces(name)
        if len(pts) > SUBSAMPLE:
            keep = np.sort(np.random.default_rng(0).choice(len(pts), SUBSAMPLE, replace=False))
            pts, nrm, faces = pts[keep], nrm[keep], None
        yield name, pts, nrm, faces, pts.shape[1] == 2
    sph = synthetic.sphere(600)
    yield "sphere", sph.points, sph.normals, None, False
    if not quick:
        tor = synthetic.torus(1500)
        yield "torus", tor.points, tor.normals, None, False
        ell = synthetic.ellipsoid(800, axes=(2.0, 1.2, 0.7))
        yield "ellipsoid", ell.points, ell.normals, None, False
        yield ("superquadric", *_superquadric(), None, False)
        yield ("star-5", *_star(400, 5, 0.3), None, True)
    yield ("star-3", *_star(300, 3, 0.35), None, True)


def _q(poly, pts, faces, contour):
    q = quality(poly, pts, faces=faces, ordered_contour=contour)
    return {"f_score": q.f_score, "n_spurious": q.n_spurious, "closed": bool(q.closed)}


def warm_up(paper) -> None:
    """Both pipelines once on a small circle and sphere, untimed: otherwise the first timed shape
    pays for loading the compiled kernels (numba's cache) of whichever pipeline runs first."""
    for shape in (synthetic.circle(60), synthetic.sphere(200)):
        fit_adaptive(shape.points, shape.normals, max_degree=4, rng=0)
        fit_adaptive(shape.points, shape.normals, method=PAPER_METHOD, rule=PAPER_RULE, rng=0, options=paper,
                     max_degree=4)


def _timed(fit):
    # Cold by construction: each fit builds its own Cloud, and nothing is kept between fits.
    t0 = time.perf_counter()
    result = fit()
    return result, time.perf_counter() - t0


def run(iterations: int, quick: bool, repeats: int = 1) -> list[dict]:
    """One row per shape. With ``repeats`` > 1 the two pipelines run that many times in turn
    (recommended, paper, recommended, ...) and the seconds are the medians: on a shared machine
    one run of a few seconds can be off by a third."""
    rows = []
    paper = PAPER.replace(iterations=iterations)
    warm_up(paper)
    for name, pts, nrm, faces, contour in shapes(quick):
        times_default, times_paper = [], []
        for _ in range(repeats):
            default, seconds = _timed(lambda: fit_adaptive(pts, nrm, faces=faces, ordered_contour=contour, rng=0,
                                                            options=RECOMMENDED.replace(iterations=iterations)))
            times_default.append(seconds)
            by_paper, seconds = _timed(lambda: fit_adaptive(pts, nrm, method=PAPER_METHOD, rule=PAPER_RULE, rng=0,
                                                             options=paper))
            times_paper.append(seconds)
        t_default, t_paper = float(np.median(times_default)), float(np.median(times_paper))
        g = default.selected_degree
        plain = ipfit.fit_3l(pts, nrm, g)
        de = refine(pts, nrm, g, method=PAPER_METHOD, rng=0, options=paper)
        rows.append({
            "shape": name, "n": int(len(pts)), "degree": g, "paper_degree": by_paper.selected_degree,
            "paper": _q(by_paper.polynomial, pts, faces, contour),
            "3l": _q(plain, pts, faces, contour), "de": _q(de.polynomial, pts, faces, contour),
            "default": _q(default.polynomial, pts, faces, contour),
            "seconds_default": t_default, "seconds_paper": t_paper,
            "seconds_default_runs": times_default, "seconds_paper_runs": times_paper,
        })
        print(json.dumps(rows[-1]), flush=True)
    return rows


def _cell(q: dict) -> str:
    return f"{q['f_score']:.3f} / {q['n_spurious']} / {'yes' if q['closed'] else 'no'}"


def timing_repeats(rows: list[dict]) -> int:
    """How many times each pipeline was timed per shape (1 for rows stored before --repeats)."""
    return len(rows[0].get("seconds_default_runs", [None])) if rows else 1


def _repeats_note(rows: list[dict]) -> str:
    count = timing_repeats(rows)
    if count <= 1:
        return ""
    return f" (medians of {count} runs of each pipeline in turn, each without the caches of the one before)"


def markdown(rows: list[dict], iterations: int) -> str:
    lines = [
        "# Spurious zero-set components: 3L, the paper's DE and ipfit's default",
        "",
        f"Generated by `python experiments/spurious.py` on {date.today().isoformat()} ({platform.machine()}), "
        f"{iterations} iterations, seed 0. Each cell is *F-score / spurious components / closed in the box*, "
        "measured by `ipfit.zeroset.quality.quality` (τ = 2% of the box diagonal). The degree is the one the default "
        "pipeline selected; 3L and the paper's DE (`refine(method='de', options=PAPER)`) are fitted at that "
        "degree; the last cells are the paper's whole pipeline at the degree it selected (`ipfit fit --paper`). "
        "3D scans with more than "
        f"{SUBSAMPLE} points are subsampled to {SUBSAMPLE} (seed 0). Both pipelines fit a small circle and sphere "
        "first, untimed, so that no timed fit loads the compiled kernels. Those subsamples and the generated 3D "
        "shapes are bare clouds: there a zero-set sample counts as within τ of the shape when it is within "
        "√(τ² + s²) of its nearest point, s that point's local spacing (see `ipfit.quality`).",
        "",
        "The default (recommended) pipeline: `fit_adaptive(points, normals)` = `ipfit.RECOMMENDED`: DE + "
        "L-BFGS polish on the paper's distance plus the far-field term, started from every linear fit, the "
        "search on a spread subsample (1,000 points in 2D, 3,000 in 3D) and stopped when it stalls, and the capture "
        "degree rule with its repairs of stray zero set (README, docs/degree-rule.md).",
        "",
        "| shape | N | degree (default / paper) | 3L | paper's DE | default | paper pipeline | seconds default | "
        "seconds paper pipeline | ratio |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['shape']} | {r['n']} | {r['degree']} / {r['paper_degree']} | {_cell(r['3l'])} | "
                     f"{_cell(r['de'])} | {_cell(r['default'])} | {_cell(r['paper'])} | {r['seconds_default']:.1f} | "
                     f"{r['seconds_paper']:.1f} | {r['seconds_default'] / max(r['seconds_paper'], 1e-9):.2f} |")
    clean = sum(r["default"]["n_spurious"] == 0 and r["default"]["closed"] for r in rows)
    at_least = sum(r["default"]["f_score"] >= r["3l"]["f_score"] - 1e-9 for r in rows)
    extra = sum(r["seconds_default"] for r in rows) / max(sum(r["seconds_paper"] for r in rows), 1e-9)
    worst = max(rows, key=lambda r: r["seconds_default"] / max(r["seconds_paper"], 1e-9))
    lines += [
        "",
        f"Default pipeline: clean (no spurious component, closed) on {clean} of {len(rows)} shapes; F-score at "
        f"least plain 3L's on {at_least} of {len(rows)}. Total time of the default pipeline / the paper's "
        f"pipeline: {extra:.2f}× (largest per shape: {worst['shape']}, "
        f"{worst['seconds_default'] / max(worst['seconds_paper'], 1e-9):.2f}×), measured in one run on a shared "
        f"2-core machine{_repeats_note(rows)}.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/spurious.md")
    parser.add_argument("--iterations", type=int, default=500)
    parser.add_argument("--quick", action="store_true", help="a few shapes, for a smoke test")
    parser.add_argument("--repeats", type=int, default=1, help="time each pipeline this many times (medians)")
    parser.add_argument("--from-json", help="rewrite the Markdown from stored rows instead of fitting")
    args = parser.parse_args(argv)
    if args.from_json:
        rows = json.loads(Path(args.from_json).read_text(encoding="utf-8"))
        Path(args.out).write_text(markdown(rows, args.iterations), encoding="utf-8")
        print(f"wrote {args.out}")
        return 0
    rows = run(args.iterations, args.quick, args.repeats)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(markdown(rows, args.iterations), encoding="utf-8")
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

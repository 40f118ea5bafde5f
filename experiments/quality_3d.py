"""3D quality of the recommended pipeline, before and after the capture rule and precision repair.

Usage::

    git worktree add --detach ../ipfit-before 69d992a   # the code before the change
    python experiments/quality_3d.py --before ../ipfit-before [--dev ../shared/data/turk-dev]
                                     [--out docs/quality-3d.md] [--from-json docs/quality-3d.json]

For the bundled 3D data (bunny, apple, duck) and the 12 ``turk-dev`` models it runs the
recommended pipeline (``ipfit fit``) of the code of ``--before`` (commit 69d992a: the
geometric rule, no precision repair) and of this checkout (the capture rule, which also repairs
degrees that bulge), and records per degree and at the selected degree the F-score, precision
(zero set → data), recall (data → zero set), spurious components and seconds, all measured by
``ipfit.quality.quality`` against the meshes' faces (τ = 2% of the box diagonal). Figures with
the data overlaid go to ``docs/quality-3d/``.

Two worker processes with one BLAS and numba thread each run side by side (one per code
version); each first fits a small shape once, so that no fit pays for numba's compilation.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from datetime import date
from pathlib import Path

import numpy as np

BUNDLED = ("bunny", "apple", "duck")
PIPELINES = ("before", "capture")


def _start_worker(src: str | None) -> None:
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[name] = "1"
    if src is not None:
        sys.path.insert(0, src)
    from ipfit import fit_adaptive
    from ipfit.datasets import synthetic

    shape = synthetic.sphere(200)
    fit_adaptive(shape.points, shape.normals, max_degree=4, rng=0)


def fit_one(spec: str, pipeline: str, seed: int) -> dict:
    """The recommended pipeline of this worker's code on one model."""
    from ipfit import fit_adaptive
    from ipfit.cli._common import load_input

    data = load_input(spec)
    start = time.perf_counter()
    result = fit_adaptive(data.points, data.normals, faces=data.faces, rng=seed)
    seconds = time.perf_counter() - start
    degrees = [{"degree": d.degree, "f_score": d.quality.f_score, "precision": d.quality.precision,
                "recall": d.quality.recall, "n_spurious": d.quality.n_spurious, "closed": bool(d.quality.closed),
                "seconds": d.seconds, "repairs": len(d.cleanup)} for d in result.degrees]
    chosen = next(d for d in degrees if d["degree"] == result.selected_degree)
    return {"model": Path(spec).stem, "n": len(data.points), "pipeline": pipeline, "selected": result.selected_degree,
            "seconds": seconds, "reason": result.reason, "degrees": degrees,
            **{k: chosen[k] for k in ("f_score", "precision", "recall", "n_spurious", "closed")},
            "polynomial": result.polynomial.to_dict()}


def run(specs: list[str], before: str, seed: int) -> list[dict]:
    rows = []
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, context, initializer=_start_worker, initargs=(str(Path(before) / "src"),)) as old, \
            ProcessPoolExecutor(1, context, initializer=_start_worker, initargs=(None,)) as new:
        futures = [old.submit(fit_one, spec, "before", seed) for spec in specs]
        futures += [new.submit(fit_one, spec, "capture", seed) for spec in specs]
        for done in as_completed(futures):
            row = done.result()
            rows.append(row)
            print(json.dumps({k: v for k, v in row.items() if k not in ("polynomial", "degrees")}), flush=True)
    return rows


def figures(rows: list[dict], specs: dict[str, str], folder: Path) -> None:
    """One PNG per model: the selected zero set of each pipeline with the data over it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ipfit import ImplicitPolynomial
    from ipfit.cli._common import load_input
    from ipfit.plotting import plot_surface, save_figure

    folder.mkdir(parents=True, exist_ok=True)
    by_model: dict[str, dict[str, dict]] = {}
    for r in rows:
        by_model.setdefault(r["model"], {})[r["pipeline"]] = r
    for model, got in sorted(by_model.items()):
        data = load_input(specs[model])
        up = "y" if model in ("bunny", "duck") else "z"
        fig = plt.figure(figsize=(9, 4.4))
        for k, pipeline in enumerate(PIPELINES):
            r = got[pipeline]
            ax = fig.add_subplot(1, 2, k + 1, projection="3d")
            plot_surface(ImplicitPolynomial.from_dict(r["polynomial"]), data.points, ax=ax, show_points=True,
                         up=up, axis_off=True, max_faces=20000)
            ax.set_title(f"{pipeline}: degree {r['selected']}, F {r['f_score']:.3f}\n"
                         f"precision {r['precision']:.3f}, recall {r['recall']:.3f}", fontsize=9)
        save_figure(fig, folder / f"{model}.png", dpi=90)
        plt.close(fig)


def markdown(rows: list[dict], seed: int) -> str:
    by_model: dict[str, dict[str, dict]] = {}
    for r in rows:
        by_model.setdefault(r["model"], {})[r["pipeline"]] = r
    models = sorted(by_model, key=lambda m: (m not in BUNDLED, m))
    lines = [
        "# 3D quality: the capture rule and the precision repair",
        "",
        f"Generated by `python experiments/quality_3d.py` on {date.today().isoformat()} ({platform.machine()}), "
        f"seed {seed}: the recommended pipeline (`ipfit fit`, all points, degrees 2-8) on the bundled 3D data and "
        "the 12 `turk-dev` models, with the code before the change (commit 69d992a: the geometric rule) and "
        "today's (the capture rule, which also repairs a clean degree whose zero set bulges away from the data). "
        "Measured by `ipfit.quality.quality` against each mesh's faces (τ = 2% of the box diagonal): "
        "**precision** is the share of the zero set within τ of the data's surface (a bulge or a lobe lowers it), "
        "**recall** the share of the data within τ of the zero set. Two worker processes with one thread each, "
        "one per code version, side by side.",
        "",
    ]
    summary = []
    for p in PIPELINES:
        f = np.array([by_model[m][p]["f_score"] for m in models])
        summary.append(f"| {p} | {np.median(f):.3f} | {f.min():.3f} | "
                       f"{sum(by_model[m][p]['n_spurious'] > 0 for m in models)} | "
                       f"{sum(by_model[m][p]['seconds'] for m in models):.0f} |")
    lines += ["| pipeline | median F | minimum F | models with spurious components | total seconds |",
              "|---|---|---|---|---|", *summary, ""]
    t_before = sum(by_model[m]["before"]["seconds"] for m in models)
    t_after = sum(by_model[m]["capture"]["seconds"] for m in models)
    worse = [m for m in models if by_model[m]["capture"]["f_score"] < by_model[m]["before"]["f_score"] - 0.01]
    lines += [f"Time of today's pipeline / the previous one: {t_after / t_before:.2f}×. Models more than 0.01 "
              f"below their previous F-score: {', '.join(worse) or 'none'}.", ""]
    lines += ["## Selected degree", "",
              "*degree / F / precision / recall / spurious / seconds*", "",
              "| model | N | before | capture | stop |", "|---|---|---|---|---|"]

    def cell(r):
        return (f"{r['selected']} / {r['f_score']:.3f} / {r['precision']:.3f} / {r['recall']:.3f} / "
                f"{r['n_spurious']} / {r['seconds']:.0f}")

    for m in models:
        got = by_model[m]
        lines.append(f"| {m} | {got['capture']['n']} | {cell(got['before'])} | {cell(got['capture'])} | "
                     f"{got['capture']['reason']} |")
    lines += ["", "## Every degree", "",
              "*F / precision / recall / spurious / seconds*; repairs: refits of that degree (clean-up or precision)",
              "", "| model | degree | before | capture | repairs (capture) |", "|---|---|---|---|---|"]
    for m in models:
        before = {d["degree"]: d for d in by_model[m]["before"]["degrees"]}
        after = {d["degree"]: d for d in by_model[m]["capture"]["degrees"]}
        for g in sorted(set(before) | set(after)):
            def c(d):
                return "—" if d is None else (f"{d['f_score']:.3f} / {d['precision']:.3f} / {d['recall']:.3f} / "
                                              f"{d['n_spurious']} / {d['seconds']:.1f}")
            lines.append(f"| {m} | {g} | {c(before.get(g))} | {c(after.get(g))} | "
                         f"{after[g]['repairs'] if g in after else '—'} |")
    lines += ["", "## Figures", "", "The selected zero set of each pipeline, the data's points drawn over it.", ""]
    lines += [f"![{m}](quality-3d/{m}.png)" for m in models]
    lines += ["", "Regenerate: `git worktree add --detach ../ipfit-before 69d992a`, then "
              "`python experiments/quality_3d.py --before ../ipfit-before` (about half an hour on 2 cores); "
              "`--from-json docs/quality-3d.json` rewrites the page and figures from the stored rows.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dev", default="../shared/data/turk-dev", help="folder of development models (PLY)")
    parser.add_argument("--before", default="../ipfit-before", help="a checkout of commit 69d992a")
    parser.add_argument("--out", default="docs/quality-3d.md")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--from-json", help="rewrite the Markdown and figures from stored rows instead of fitting")
    parser.add_argument("--models", nargs="+", help="only these models (a quick look)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    specs = {name: name for name in BUNDLED}
    specs.update({p.stem: str(p) for p in sorted(Path(args.dev).glob("*.ply"))})
    if args.models:
        specs = {name: spec for name, spec in specs.items() if name in args.models}
    if args.from_json:
        rows = json.loads(Path(args.from_json).read_text(encoding="utf-8"))
    else:
        # the largest models first, so that the two workers end together
        order = sorted(specs.values(), key=lambda s: -os.path.getsize(s) if os.path.exists(s) else -1e9)
        rows = run(order, args.before, args.seed)
        out.with_suffix(".json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    figures(rows, specs, out.parent / out.stem)
    out.write_text(markdown(rows, args.seed), encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

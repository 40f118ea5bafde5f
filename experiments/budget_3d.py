"""The 3D search budget of the recommended pipeline: a 30-generation stall against 60, whole pipeline.

Usage::

    git worktree add --detach ../ipfit-60 8b03b9b     # 60 generations, float64 search
    # this checkout with AUTO["stall_generations"][3] = 60 (float32 search only), seed 0:
    python experiments/quality_3d.py --before ../ipfit-60 --seed 0 --out /tmp/f32/quality-3d.md
    # this checkout as it is (float32 search, 30 generations), seeds 0 and 1:
    python experiments/quality_3d.py --before ../ipfit-60 --seed 0 --out /tmp/s0/quality-3d.md
    python experiments/quality_3d.py --before ../ipfit-60 --seed 1 --out /tmp/s1/quality-3d.md
    # the three quality-3d.json files copied to docs/budget-3d/, then:
    python experiments/budget_3d.py [--out docs/budget-3d.md]

Each JSON holds, per model, the recommended pipeline of commit 8b03b9b ("before": the search
in float64, stopped after 60 generations without progress) and of the variant ("capture"),
on the bundled 3D data and the 12 ``turk-dev`` models (``experiments/quality_3d.py``). The page
sets the selected degree's F-score of each side by side.
"""

from __future__ import annotations

import argparse
import json
from datetime import date
from pathlib import Path

import numpy as np

RUNS = (("float32-seed0.json", "float32 search, stall 60", 0),
        ("stall30-seed0.json", "float32 search, stall 30", 0),
        ("stall30-seed1.json", "float32 search, stall 30", 1))


def load(folder: Path) -> list[tuple[str, int, dict]]:
    out = []
    for name, label, seed in RUNS:
        rows = json.loads((folder / name).read_text(encoding="utf-8"))
        by = {}
        for r in rows:
            by.setdefault(r["model"], {})[r["pipeline"]] = r
        out.append((label, seed, by))
    return out


def markdown(runs) -> str:
    lines = ["# The 3D search budget: a 30-generation stall", "",
             f"Written by `python experiments/budget_3d.py` on {date.today().isoformat()} from the runs of "
             "`experiments/quality_3d.py` stored in `docs/budget-3d/` (the script's docstring has the commands). "
             "*before*: commit 8b03b9b, the recommended pipeline with its search in float64, stopped after 60 "
             "generations without progress; each variant ran side by side with it, in two worker processes "
             "with one thread each. F-score of the selected degree, measured against each mesh's faces "
             "(τ = 2% of the box diagonal).", "",
             "| run | seed | models | mean F before | mean F variant | mean difference | largest drop | "
             "largest gain | identical selections | seconds before | seconds variant | time ratio |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, seed, by in runs:
        models = sorted(by)
        before = np.array([by[m]["before"]["f_score"] for m in models])
        after = np.array([by[m]["capture"]["f_score"] for m in models])
        diff = after - before
        same = sum(by[m]["before"]["selected"] == by[m]["capture"]["selected"] and abs(d) < 1e-9
                   for m, d in zip(models, diff))
        t0 = sum(by[m]["before"]["seconds"] for m in models)
        t1 = sum(by[m]["capture"]["seconds"] for m in models)
        lo, hi = int(np.argmin(diff)), int(np.argmax(diff))
        lines.append(f"| {label} | {seed} | {len(models)} | {before.mean():.3f} | {after.mean():.3f} | "
                     f"{diff.mean():+.4f} | {diff[lo]:+.3f} ({models[lo]}) | {diff[hi]:+.3f} ({models[hi]}) | "
                     f"{same} of {len(models)} | {t0:.0f} | {t1:.0f} | {t1 / t0:.2f} |")
    s0 = next(by for _, seed, by in runs[1:] if seed == 0)
    s1 = next(by for _, seed, by in runs[1:] if seed == 1)
    models = sorted(set(s0) & set(s1))
    spread = np.array([s1[m]["before"]["f_score"] - s0[m]["before"]["f_score"] for m in models])
    lines += ["", "The yardstick, the same code (*before*) at seeds 0 and 1: mean |difference| "
              f"{np.abs(spread).mean():.4f}, largest {spread[np.argmax(np.abs(spread))]:+.3f} "
              f"({models[int(np.argmax(np.abs(spread)))]})."]
    lines += ["", "## Per model", "", "*F-score of the selected degree (degree)*", "",
              "| model | " + " | ".join(f"before, seed {seed} | {label}, seed {seed}" for label, seed, _ in runs) + " |",
              "|---|" + "---|---|" * len(runs)]
    for m in sorted(runs[0][2]):
        cells = []
        for _, _, by in runs:
            b, a = by[m]["before"], by[m]["capture"]
            cells += [f"{b['f_score']:.3f} ({b['selected']})", f"{a['f_score']:.3f} ({a['selected']})"]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="docs/budget-3d", help="folder of the stored quality_3d JSON files")
    parser.add_argument("--out", default="docs/budget-3d.md")
    args = parser.parse_args(argv)
    Path(args.out).write_text(markdown(load(Path(args.runs))), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

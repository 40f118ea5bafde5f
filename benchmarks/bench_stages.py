"""Where a fit's time goes: seconds per stage and per degree (issue 33's cost model).

Usage::

    python benchmarks/bench_stages.py [--shapes boot butterfly apple duck bunny] [--million]
                                      [--out docs/stages.md]

Each shape is fitted once by the recommended pipeline (``ipfit.fit_adaptive`` with its defaults,
``rng=0``) under :mod:`cProfile`, one profile for what comes before the first degree (the outlier
score, normals) and one per degree, switched by the fit's own progress events. A stage's
seconds are the cumulative time of the function that does it, summed over its calls:

* **outlier score** ``robust.score.score_outliers``; **normals** ``normals.estimate.estimate_normals``;
* **start fits** ``fitting.starts.start_fits``; **search** ``fitting.refine._search`` (DE or PSO on
  the search subsample); **polish** ``fitting.refine._polish`` (L-BFGS on all points);
  **objectives** ``fitting.refine._objectives`` (design matrices, far-field samples);
* **quality** ``zeroset.quality._measure_now`` (the zero set's extraction, marching squares/cubes,
  is inside it and shown apart as **extraction**, ``zeroset.extract.extract_zero_set``);
* **repair** ``degree.repair.repair``: its polishes and measurements are inside it *and* counted in
  the stages above (so the rows of a degree add up to more than its total when it repaired).

The profiler slows pure-Python code more than compiled or BLAS code, so the shares are indicative;
the totals are the profiled run's. ``--million`` adds the bunny's surface sampled to 10⁶ points with
its face normals (minutes); a cloud of more than ``SearchOptions.fit_points`` points has its
degrees fitted on a subsample of it, and its last row, "degree g on every point", is the
selected degree measured on every point. Every number printed (and written with ``--out``) comes from this run.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

STAGES = (
    ("outlier score", "robust/score.py", "score_outliers"),
    ("normals", "normals/estimate.py", "estimate_normals"),
    ("objectives", "fitting/refine.py", "_objectives"),
    ("start fits", "fitting/starts.py", "start_fits"),
    ("search", "fitting/refine.py", "_search"),
    ("polish", "fitting/refine.py", "_polish"),
    ("quality", "zeroset/quality.py", "_measure_now"),
    ("extraction", "zeroset/extract.py", "extract_zero_set"),
    ("repair", "degree/repair.py", "repair"),
)


def stage_seconds(profile: cProfile.Profile) -> dict[str, float]:
    """Cumulative seconds of each stage's function in ``profile`` (0 when it was not called)."""
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    out = {}
    for label, path, name in STAGES:
        out[label] = sum(value[3] for (file, _, func), value in stats.items()
                         if func == name and file.replace(os.sep, "/").endswith(path))
    return out


class _Profiler:
    """A progress callback that profiles before the first degree and each degree apart."""

    def __init__(self) -> None:
        self.parts: list[tuple[str, cProfile.Profile, float]] = []
        self._current = cProfile.Profile()
        self._label = "setup"
        self._start = time.perf_counter()
        self._current.enable()

    def __call__(self, event: dict) -> None:
        kind = event.get("event")
        if kind == "degree_start":
            self._close()
            self._label = f"degree {event['degree']}"
            self._open()
        elif kind == "degree_done":
            self._close()
            self._label = "after"
            self._open()
        elif kind == "every_point":  # a big cloud's selected degree, on every point (fit_points)
            self._close()
            self._label = f"degree {event['degree']} on every point"
            self._open()

    def finish(self) -> None:
        self._close()

    def _open(self) -> None:
        self._current = cProfile.Profile()
        self._start = time.perf_counter()
        self._current.enable()

    def _close(self) -> None:
        self._current.disable()
        self.parts.append((self._label, self._current, time.perf_counter() - self._start))


def profile_fit(points, normals=None, faces=None) -> tuple[list[tuple[str, float, dict[str, float]]], object]:
    from ipfit import fit_adaptive

    profiler = _Profiler()
    try:
        result = fit_adaptive(points, normals, faces=faces, rng=0, progress=profiler)
    finally:
        profiler.finish()
    rows = [(label, seconds, stage_seconds(prof)) for label, prof, seconds in profiler.parts
            if label != "after" or seconds > 0.05]
    return rows, result


def table(name: str, n: int, rows, result) -> list[str]:
    total = sum(seconds for _, seconds, _ in rows)
    labels = [label for label, _, _ in STAGES if any(stages[label] > 0.005 for _, _, stages in rows)]
    lines = [f"### {name} ({n:,} points; selected degree {result.selected_degree}; {total:.1f} s profiled)", "",
             "| part | seconds | " + " | ".join(labels) + " |", "|---|---" + "|---" * len(labels) + "|"]
    for label, seconds, stages in rows:
        lines.append(f"| {label} | {seconds:.2f} | " + " | ".join(f"{stages[s]:.2f}" for s in labels) + " |")
    sums = {s: sum(stages[s] for _, _, stages in rows) for s in labels}
    lines.append(f"| **all** | **{total:.2f}** | " + " | ".join(f"**{sums[s]:.2f}** ({100 * sums[s] / total:.0f}%)"
                                                              for s in labels) + " |")
    return lines + [""]


def million_points():
    """The bunny's surface sampled to 10⁶ points (area-weighted, seeded) with its face normals."""
    import ipfit
    from ipfit.geometry.mesh import face_normals

    bunny = ipfit.load("bunny")
    import trimesh

    mesh = trimesh.Trimesh(bunny.points, bunny.faces, process=False)
    points, face = trimesh.sample.sample_surface(mesh, 1_000_000, seed=0)
    return np.asarray(points), face_normals(bunny.points, bunny.faces)[face]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=["boot", "butterfly", "apple", "duck", "bunny"],
                        help="bundled dataset names")
    parser.add_argument("--million", action="store_true", help="add the bunny sampled to 10⁶ points")
    parser.add_argument("--out", help="also write the tables as Markdown")
    args = parser.parse_args(argv)

    import ipfit

    ipfit.fit_adaptive(ipfit.load("boot"), max_degree=2, rng=0)  # compile the kernels before any profile
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [f"## Seconds per stage and degree ({date.today().isoformat()}, {platform.machine()}, "
             f"{os.cpu_count()} cores, load average {load:.1f} at the start)", ""]
    cases = [(name, ipfit.load(name)) for name in args.shapes]
    for name, cloud in cases:
        rows, result = profile_fit(cloud)
        lines += table(name, len(cloud.points), rows, result)
        print("\n".join(table(name, len(cloud.points), rows, result)), flush=True)
    if args.million:
        points, normals = million_points()
        rows, result = profile_fit(points, normals)
        lines += table("bunny surface, 10⁶ points", len(points), rows, result)
        print("\n".join(table("bunny surface, 10⁶ points", len(points), rows, result)), flush=True)
    command = "python benchmarks/bench_stages.py " + " ".join(argv if argv is not None else sys.argv[1:])
    lines += [f"Regenerate: `{command.strip()}`.", ""]
    if args.out:
        intro = (__doc__ or "").split("\n\n", 2)[2].replace("``", "`").replace(":mod:", "")
        Path(args.out).write_text("# Where a fit's time goes\n\n" + intro + "\n" + "\n".join(lines), encoding="utf-8")
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Batch throughput on Dask and chunked-cloud fits against N; writes docs/scaling.md.

Run with ``PYTHONPATH=src .venv/bin/python benchmarks/bench_batch.py`` (about 15 minutes on a
loaded 2-core machine; ``--shapes``, ``--sizes`` and ``--skip-default`` make it shorter).

Part 1 fits the same generated shapes (:func:`ipfit.datasets.collection`) three ways, in one
run so that the ratios share the machine's load: in this process one after the other (the
per-shape costs), then with :func:`ipfit.fit_many` on an embedded LocalCluster of 1 and of 2
worker processes. Fast settings (3L at each degree up to 6, geometric rule) keep it short; the
default pipeline's per-shape cost is measured on a few shapes to scale the projection.

Part 2 writes generated tori of up to 20 million points as chunk files of 1 million points
(``points-*.npy`` / ``normals-*.npy``) and fits each size with :func:`ipfit.fit_chunked` (3L,
degree 4) in a fresh subprocess, which reports its wall time and peak resident memory
(``resource.getrusage``); at 2 million points (two chunks) the in-memory fit is run too and compared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

REPO = Path(__file__).resolve().parents[1]
FAST = dict(method="3l", max_degree=6)
CHUNK = 1_000_000


def _sequential_costs(shapes, settings) -> list[float]:
    import threadpoolctl

    from ipfit.batch import FitSettings

    fit = FitSettings(**settings)
    costs = []
    with threadpoolctl.threadpool_limits(1):  # as in a worker
        for shape in shapes:
            start = time.perf_counter()
            fit.fit(shape.points, shape.normals, shape.name)
            costs.append(time.perf_counter() - start)
    return costs


def _warm() -> None:
    import ipfit.degree.adaptive
    import ipfit.zeroset.quality

    assert ipfit.degree.adaptive and ipfit.quality


def _batch_wall(shapes, workers: int, settings) -> tuple[float, float, float]:
    from ipfit.batch import fit_many, local_cluster

    start = time.perf_counter()
    with local_cluster(workers) as client:
        started = time.perf_counter()
        client.run(_warm)  # imports, which a long batch amortises
        batch = fit_many(shapes, client=client, **settings)
        wall = time.perf_counter() - started
    assert batch.counts() == {"ok": len(shapes)}, batch.counts()
    return wall, started - start, sum(row["seconds"] for row in batch.rows)  # the fits' own time, on the workers


def part_batch(n_shapes: int, skip_default: bool) -> dict:
    from ipfit.datasets import collection

    shapes = collection(n_shapes, seed=0)
    costs = _sequential_costs(shapes, FAST)
    wall1, start1, inside1 = _batch_wall(shapes, 1, FAST)
    wall2, start2, inside2 = _batch_wall(shapes, 2, FAST)
    out = {"n": n_shapes, "sequential": sum(costs), "mean": statistics.mean(costs), "max": max(costs),
           "median": statistics.median(costs), "wall1": wall1, "wall2": wall2, "inside1": inside1,
           "inside2": inside2, "startup": (start1 + start2) / 2}
    if not skip_default:
        sample = [s for s in shapes if s.kind in ("star", "ellipsoid")][:2]
        out["default_costs"] = _sequential_costs(sample, {})
    return out


def _write_cloud(folder: Path, n_total: int) -> None:
    from ipfit.datasets import synthetic

    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n_total // CHUNK):
        if (folder / f"normals-{i:04d}.npy").exists():
            continue
        shape = synthetic.torus(CHUNK, major=2.0, minor=0.7, rng=np.random.default_rng([7, i]))
        noise = 0.005 * np.random.default_rng([8, i]).standard_normal(CHUNK)
        np.save(folder / f"points-{i:04d}.npy", shape.points + shape.normals * noise[:, None] + [1.0, -2.0, 0.5])
        np.save(folder / f"normals-{i:04d}.npy", shape.normals)


def _child(folder: str, n: int, compare: bool) -> None:
    """In a fresh process: fit the first n points of the cloud; print time and peak memory."""
    from ipfit.fitting.chunked import fit_chunked, open_cloud

    points, normals = open_cloud(folder)
    points, normals = points[:n], normals[:n]
    start = time.perf_counter()
    fit = fit_chunked(points, normals, 4, "3l", scheduler="threads")
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB -> MiB on Linux
    out = {"n": n, "seconds": seconds, "peak_mib": peak, "chunks": fit.info["chunks"]}
    if compare:
        from ipfit import fit_3l

        memory = fit_3l(np.asarray(points), np.asarray(normals), 4)
        out["relative_difference"] = float(np.linalg.norm(fit.coefficients - memory.coefficients)
                                           / np.linalg.norm(memory.coefficients))
    print(json.dumps(out))


def part_chunked(sizes: list[int], folder: Path) -> list[dict]:
    _write_cloud(folder, max(sizes))
    rows = []
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    for n in sizes:
        cmd = [sys.executable, __file__, "--child", str(folder), str(n)] + (["--compare"] if n == 2 * CHUNK else [])
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
        print(rows[-1], file=sys.stderr)
    return rows


def _projection(mean: float, overhead: float, startup: float, longest: float, workers: int, n: int = 1400) -> float:
    return startup + n * (mean + overhead) / workers + longest


def render(batch: dict, chunked: list[dict]) -> str:
    import dask
    import distributed

    n = batch["n"]
    eff = batch["wall1"] / (2 * batch["wall2"])
    overhead = max(0.0, (batch["wall1"] - batch["inside1"]) / n)
    lines = [
        "# Scaling: batches on Dask and clouds bigger than memory",
        "",
        "Generated by `benchmarks/bench_batch.py` (do not edit by hand). Machine: "
        f"{os.cpu_count()} cores shared with other jobs (load average {os.getloadavg()[0]:.1f} at the end), "
        f"Python {platform.python_version()}, dask {dask.__version__}, distributed {distributed.__version__}. "
        "The machine is loaded and shared, so absolute times are noisy; the ratios below come from "
        "one run, in which every variant saw the same load.",
        "",
        "## Batch throughput (`ipfit batch`, `ipfit.fit_many`)",
        "",
        f"{n} generated shapes (`ipfit.datasets.collection({n}, seed=0)`: 2D stars and blobs of 200 points, "
        "3D superquadrics, tori and ellipsoids of 800 points, three noise levels), with **fast settings**: "
        "`method='3l'`, `max_degree=6`, geometric rule (each degree's zero set is extracted and measured, "
        "which dominates the cost). Workers are processes with one thread each.",
        "",
        "| run | wall time | shapes / s | wall per shape | the fits' own time (Σ) |",
        "| --- | ---: | ---: | ---: | ---: |",
        f"| in this process, one after the other (1 BLAS thread) | {batch['sequential']:.1f} s | "
        f"{n / batch['sequential']:.2f} | {batch['mean']:.3f} s | {batch['sequential']:.1f} s |",
        f"| LocalCluster, 1 worker | {batch['wall1']:.1f} s | {n / batch['wall1']:.2f} | {batch['wall1'] / n:.3f} s "
        f"| {batch['inside1']:.1f} s |",
        f"| LocalCluster, 2 workers | {batch['wall2']:.1f} s | {n / batch['wall2']:.2f} | {batch['wall2'] / n:.3f} s "
        f"| {batch['inside2']:.1f} s |",
        "",
        "The last column adds up `fit_adaptive`'s own time per shape, measured where it ran: the "
        "difference between the runs in it is the machine's load (and numba compiling in each fresh "
        "worker), not Dask.",
        "",
        f"- **Scaling efficiency** 1 → 2 workers: {eff:.0%} (wall₁ / (2 · wall₂)). The machine has "
        f"{os.cpu_count()} cores shared with other jobs, so 2 workers cannot have two free cores to themselves.",
        f"- **Dask overhead per shape**: {overhead * 1000:.0f} ms ((wall with 1 worker − the fits' own time "
        f"on it) / {n}: submitting, scheduling, sending the points, building and returning the result "
        "JSON).",
        f"- Starting and stopping the embedded cluster: {batch['startup']:.1f} s (not in the wall times above).",
        f"- Per-shape cost (fast settings): median {batch['median']:.3f} s, mean {batch['mean']:.3f} s, "
        f"longest {batch['max']:.3f} s.",
        "",
        "### Projected wall time for 1,400 shapes (MPEG-7 CE-Shape-1's size)",
        "",
        "Model: start-up + 1,400 × (mean cost + overhead) / workers + the longest shape (the tail), "
        "assuming one free core per worker and perfect packing otherwise (the measured efficiency "
        "above is what a shared machine gives).",
        "",
    ]
    costs = [("fast settings (measured above)", batch["mean"])]
    if batch.get("default_costs"):
        mean_default = statistics.mean(batch["default_costs"])
        costs.append((f"default settings (de+polish; measured on {len(batch['default_costs'])} easy shapes: "
                      f"{', '.join(f'{c:.1f} s' for c in batch['default_costs'])})", mean_default))
    costs += [("5 s (assumed: the low end of the default pipeline on real silhouettes)", 5.0),
              ("90 s (assumed: the high end)", 90.0)]
    lines += ["| per-shape cost | 8 workers | 32 workers | 128 workers |", "| --- | ---: | ---: | ---: |"]
    for label, mean in costs:
        longest = max(batch["max"], mean * 3)
        cells = [_projection(mean, overhead, batch["startup"], longest, w) for w in (8, 32, 128)]
        lines.append(f"| {label} | " + " | ".join(_duration(c) for c in cells) + " |")
    lines += [
        "",
        "## Chunked-cloud fits (`ipfit.fit_chunked`)",
        "",
        "A torus (R = 2, r = 0.7, noise 0.005 along the normal), stored as chunk files of 1 million "
        "points (`points-*.npy`, `normals-*.npy`, read chunk by chunk by `ipfit.fitting.chunked.open_cloud`), fitted "
        "by 3L at degree 4 (35 coefficients, 3N rows) with Dask's threaded scheduler, each size in a "
        "fresh process. Peak memory is the process's peak resident set (`ru_maxrss`), Python and "
        "the libraries included.",
        "",
        "| points | chunks | time | peak memory |",
        "| ---: | ---: | ---: | ---: |",
    ]
    for row in chunked:
        lines.append(f"| {row['n']:,} | {row['chunks']} | {row['seconds']:.1f} s | {row['peak_mib']:.0f} MiB |")
    compared = [r for r in chunked if "relative_difference" in r]
    if compared:
        lines += ["", f"At {compared[0]['n']:,} points the in-memory `fit_3l` (which holds the whole cloud) "
                  f"gives the same coefficients to {compared[0]['relative_difference']:.1e} (relative)."]
    lines += ["", f"Memory is bounded by the chunks in flight ({os.cpu_count()} at once by default, "
              "`in_flight`), each with its block of 2¹⁷ rows of the design matrix, not by N: the full "
              "3N × 35 matrix (16.8 GB at 20 million points) never exists.", ""]
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", type=int, default=100)
    parser.add_argument("--sizes", default="1000000,2000000,5000000,20000000")
    parser.add_argument("--skip-default", action="store_true")
    parser.add_argument("--cloud-folder", default=None)
    parser.add_argument("--output", default=str(REPO / "docs" / "scaling.md"))
    parser.add_argument("--batch-results", metavar="JSON", help="reuse part 1's results (its JSON line) from a run")
    parser.add_argument("--child", nargs=2, metavar=("FOLDER", "N"), help=argparse.SUPPRESS)
    parser.add_argument("--compare", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child[0], int(args.child[1]), args.compare)
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.cloud_folder) if args.cloud_folder else Path(tmp) / "cloud"
        chunked = part_chunked(sizes, folder)
    if args.batch_results:  # part 1 of an earlier run (its JSON line), e.g. after changing part 2 only
        batch = json.loads(Path(args.batch_results).read_text(encoding="utf-8"))
    else:
        batch = part_batch(args.shapes, args.skip_default)
        print(json.dumps(batch), file=sys.stderr)
    Path(args.output).write_text(render(batch, chunked), encoding="utf-8")
    print(f"wrote {args.output}", file=sys.stderr)


if __name__ == "__main__":
    main()

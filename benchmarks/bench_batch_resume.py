"""``ipfit batch`` with nothing to do: how long a rerun over finished shapes takes.

Run with ``python benchmarks/bench_batch_resume.py`` (about a minute). A batch of the bundled
datasets at ``--max-degree 2`` is fitted once into a temporary folder (on Dask's local cluster,
as a user's first run is); then the same command is run ``--repeat`` times: every shape is
already done, so it answers without starting a cluster (issue 34 asks for 2 s at most). Each
rerun is a fresh process, as a user runs it: its wall time and its CPU time (user + system).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [sys.path[0], os.environ.get("PYTHONPATH")]))  # its child processes too


def run(cmd: list[str], cwd: str) -> tuple[float, float, str]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    from ipfit.datasets import dataset_names

    names = list(dataset_names())
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "ipfit.cli", "batch", *names, "-o", "out", "--max-degree", "2", "--workers", "2"]
        wall, cpu, last = run(cmd, tmp)
        print(f"first run, {len(names)} shapes: {wall:.1f} s wall ({last})")
        runs = [run(cmd, tmp) for _ in range(args.repeat)]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    walls = sorted(w for w, _, _ in runs)
    cpus = sorted(c for _, c, _ in runs)
    print(f"rerun with nothing to do ({runs[-1][2]}), {args.repeat} fresh processes, load average {load:.1f}:")
    print(f"  wall median {walls[len(walls) // 2]:.2f} s (best {walls[0]:.2f}, worst {walls[-1]:.2f}); "
          f"CPU median {cpus[len(cpus) // 2]:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``ipfit render``: seconds and peak memory of a 480 x 480 ray-cast image at degrees 4 and 8.

Run with ``python benchmarks/bench_render.py`` (about a minute). The fits are 3L fits of the
full bunny (35,947 points; y up) at each degree, made once into a temporary folder. Rows:

* ``render()``: the library call alone, in this process after a warm-up (the compiled kernel
  loaded): best of ``--repeat`` wall times, the CPU seconds of that run (all threads), and the
  peak of memory allocated through Python and numpy during it (``tracemalloc``);
* ``ipfit render``: the command in a fresh process, as a user runs it: wall seconds, CPU
  seconds and the process's peak resident size (Python, numpy, numba and the
  command line's imports included; Linux's ``VmHWM``), best of ``--repeat``;
* ``ipfit --version``: the same process doing nothing but start: the command line's fixed cost,
  which every command pays.

The issue's figures for the eigenvalue method this replaced: 12 s (degree 4) and 50 s, 484 MB
(degree 8) for the command. Other jobs on the machine make the wall times noisy; the CPU times
are steadier.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [sys.path[0], os.environ.get("PYTHONPATH")]))  # its child processes too

# A child reports its own CPU time and peak resident size. Not ru_maxrss: Linux carries the
# parent's peak into a forked child (this process holds numpy and numba), and RUSAGE_CHILDREN is
# the largest over every child so far; /proc's VmHWM is this process image's own.
_CHILD = """
import json, resource, sys
from ipfit.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
usage = resource.getrusage(resource.RUSAGE_SELF)
with open("/proc/self/status") as status:
    hwm = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))
print(json.dumps({"code": code, "cpu": usage.ru_utime + usage.ru_stime, "rss_mb": hwm / 1024}), file=sys.stderr)
"""


def command(argv: list[str]) -> dict:
    """Wall seconds, CPU seconds and peak RSS (MB) of ``ipfit ARGV`` in a fresh process."""
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _CHILD, *argv], capture_output=True, text=True,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})
    wall = time.perf_counter() - t0
    report = json.loads(done.stderr.strip().splitlines()[-1])
    if report["code"] != 0:
        raise SystemExit(f"ipfit {' '.join(argv)} failed: {done.stderr}")
    return {"wall": wall, **report}


def best(runs: list[dict]) -> dict:
    return min(runs, key=lambda r: r["wall"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--degrees", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--size", type=int, default=480)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    from ipfit.analysis.rays import render
    from ipfit.cli.mesh import result_box
    from ipfit.degree.results import result_view

    print(f"480 x 480 is {args.size} x {args.size} here; {os.cpu_count()} CPUs; bunny, 3L fits, --up y\n")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for degree in args.degrees:
            prefix = Path(folder) / f"bunny{degree}"
            command(["fit", "bunny", "--degree", str(degree), "--method", "3l", "--no-picture", "--no-zero-set",
                     "-q", "-o", str(prefix)])
            view = result_view(f"{prefix}.json")
            box = result_box(view, None, 0.1, "render")
            render(view.polynomial, box, size=8, up="y")  # warm-up: the compiled kernel loaded
            walls, cpus = [], []
            for _ in range(args.repeat):
                c0, t0 = time.process_time(), time.perf_counter()
                image = render(view.polynomial, box, size=args.size, up="y")
                walls.append(time.perf_counter() - t0)
                cpus.append(time.process_time() - c0)
            tracemalloc.start()
            render(view.polynomial, box, size=args.size, up="y")
            peak = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
            covered = float((image < 255).any(axis=2).mean())
            i = walls.index(min(walls))
            rows.append((f"render(), degree {degree}", walls[i], cpus[i], f"{peak:.0f} MB traced",
                         f"surface on {covered:.0%} of the pixels"))
            out = Path(folder) / f"bunny{degree}.png"
            run = best([command(["render", f"{prefix}.json", "-o", str(out), "--up", "y",
                                 "--size", str(args.size), str(args.size)]) for _ in range(args.repeat)])
            rows.append((f"ipfit render, degree {degree}", run["wall"], run["cpu"], f"{run['rss_mb']:.0f} MB peak RSS",
                         ""))
        start = best([command(["--version"]) for _ in range(args.repeat)])
        rows.append(("ipfit --version", start["wall"], start["cpu"], f"{start['rss_mb']:.0f} MB peak RSS",
                     "the command line's start-up"))
    print(f"{'':<26}{'wall s':>8}{'CPU s':>8}  memory")
    for name, wall, cpu, memory, note in rows:
        print(f"{name:<26}{wall:8.2f}{cpu:8.2f}  {memory:<20} {note}")


if __name__ == "__main__":
    main()

"""Two versions of ipfit side by side: this checkout and an earlier one (``--before``).

Each runs in its own worker process with one BLAS and numba thread, so that the two share the
2 cores alike; each worker first fits a small shape once, so that no timed fit pays for numba's
compilation. Also the helpers the experiment scripts share: the data's loader, a page run's
``meta`` and its page with a ``.json`` twin.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import platform
import shlex
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from datetime import date
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one


def start_worker(src: str | None) -> None:
    """Runs in each worker: one thread, ``src`` (another checkout's src/) first on the path."""
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[name] = "1"
    if src is not None:
        sys.path.insert(0, src)
    from ipfit import fit_adaptive
    from ipfit.datasets import synthetic

    for shape in (synthetic.circle(60), synthetic.sphere(200)):
        fit_adaptive(shape.points, shape.normals, max_degree=4, rng=0)


def load_data(spec: str):
    """The data of ``spec`` (a path or a bundled dataset's name) with this worker's code:
    :func:`ipfit.load`, or in a checkout older than it the command line's loader, which read
    the same points, normals and faces."""
    try:
        from ipfit import load
    except ImportError:  # a --before checkout from before ipfit.load
        from ipfit.cli._common import load_input as load
    return load(spec)


def run_side_by_side(task: Callable, before: str, old_jobs: list[tuple], new_jobs: list[tuple]) -> list[dict]:
    """``task(*job)`` for the old jobs with the code of ``before`` and the new ones with this
    checkout, the two workers side by side; returns the rows as they finish (each also printed)."""
    rows = []
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, context, initializer=start_worker, initargs=(str(Path(before) / "src"),)) as old, \
            ProcessPoolExecutor(1, context, initializer=start_worker, initargs=(None,)) as new:
        futures = [old.submit(task, *job) for job in old_jobs] + [new.submit(task, *job) for job in new_jobs]
        for done in as_completed(futures):
            row = done.result()
            rows.append(row)
            print(json.dumps({k: v for k, v in row.items() if k not in ("polynomial", "degrees")}), flush=True)
    return rows


def spurious_record(q) -> dict:
    """A quality's spurious components, as stored in a row (either code version's quality)."""
    return {"tau": q.tau, "spurious": [{"size": c["size"], "distance": c["distance"], "dim": len(c["center"])}
                                       for c in q.spurious]}


def spurious_cell(row: dict) -> str:
    """Spurious components beyond specks (:func:`ipfit.degree.rules.is_speck`, judged by this checkout),
    and the specks in brackets."""
    from ipfit.degree.rules import is_speck

    specks = sum(is_speck({**c, "center": [0.0] * c["dim"]}, row["tau"]) for c in row["spurious"])
    return f"{len(row['spurious']) - specks}" + (f" (+{specks} speck{'s' if specks > 1 else ''})" if specks else "")


def n_beyond_specks(row: dict) -> int:
    return int(spurious_cell(row).split()[0])


def page_meta(script: str, argv, out: Path, started: float, **extra) -> dict:
    """The ``meta`` of a page's run by ``experiments/script``: its command line, date, machine,
    commit, Python, minutes since ``started`` (``time.perf_counter()``), ``out`` and ``extra``."""
    from bench_peers import _commit, _machine  # benchmarks/ is on the caller's path

    command = f"python experiments/{script} " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    return {"command": command.strip(), "date": date.today().isoformat(), "machine": _machine(),
            "commit": _commit(), "python": platform.python_version(), "minutes": (time.perf_counter() - started) / 60,
            "out": str(out), **extra}


def write_page(out: Path, page: Callable[[list, dict], str], rows: list | None = None,
               meta: dict | None = None) -> None:
    """``page(rows, meta)`` written to ``out`` and both to its ``.json`` twin; without ``rows``,
    the page again from the twin (``--page-only``)."""
    store = out.with_suffix(".json")
    if rows is None:
        saved = json.loads(store.read_text())
        rows, meta = saved["rows"], saved["meta"]
    else:
        store.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    out.write_text(page(rows, meta or {}))


def regenerate(meta: dict, script: str) -> str:
    """A page's last line: the command that wrote it, and the one that rewrites it from its twin."""
    return (f"\nRegenerate: `{meta['command']}`; `python experiments/{script} --out {meta['out']} --page-only` "
            "rewrites this page from its JSON.")

"""Fit many shapes on Dask: an embedded cluster of worker processes, or the caller's own.

:func:`fit_many` submits one :func:`~ipfit.fit_adaptive` per shape to a
``dask.distributed`` cluster and gathers one row per shape (:data:`COLUMNS`) and its result
JSON. Without a ``client`` it starts a :class:`~distributed.LocalCluster` of worker
processes, one thread each, with the BLAS/OpenMP/numba thread counts set to 1 (so the
workers do not fight over the cores), and stops it at the end.

Reproducibility: shape ``name`` is fitted with ``rng=shape_rng(seed, name)``, a generator
derived from the batch seed and the shape's *name* (not from its place in the queue or the
worker that runs it), so ``fit_adaptive(points, normals, rng=shape_rng(seed, name), ...)``
alone gives the same result, bit for bit, with the same thread counts.

Resume: with an ``output`` folder each result is written to ``OUTPUT/NAME.json`` with
``"batch": {"settings_hash": ..., "name": ..., "seed": ...}``; a shape whose stored hash
equals the current settings' hash is skipped (status ``skipped``, its row read back).

Failures stay with their shape: an error while reading or fitting it, or the death of the
worker process running it, makes its row ``failed`` with a one-line message; the rest go
on. (On an existing cluster Dask retries a shape whose worker died on other workers, up to
the scheduler's ``distributed.scheduler.allowed-failures``, 3 by default; the embedded
cluster sets it to 0.) KeyboardInterrupt cancels the pending shapes (status ``cancelled``), keeps every
finished result and returns (``BatchResult.interrupted``).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
import uuid
from pathlib import Path
from typing import Callable

from .. import _atomic
from .._validation import check_int
from ..exceptions import InvalidInputError
from ..options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions
from ._cluster import THREAD_ENV, _client_for, local_cluster
from ._shapes import (COLUMNS, GENERATED_PREFIX, BatchResult, FitSettings, _fit_task, _one_line, _row, _row_of,
                      expand_inputs, shape_rng)

__all__ = ["fit_many", "BatchResult", "FitSettings", "shape_rng", "local_cluster", "expand_inputs", "COLUMNS",
           "THREAD_ENV", "GENERATED_PREFIX", "write_summary"]


# -- outputs ---------------------------------------------------------------------------------------
def _stored(path: Path) -> dict | None:
    """The ipfit result at ``path`` (None when absent); refuses to replace a file ipfit did not write."""
    from .._result_schema import FORMAT_NAME

    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME or path.is_dir():
        raise InvalidInputError(f"--output: {path} exists and is not an ipfit result; the batch would replace it. "
                                "Move it or choose another output folder.")
    return data


def write_summary(folder: Path, batch: BatchResult) -> list[Path]:
    """``summary.csv`` (and ``summary.parquet`` when pyarrow is installed), written atomically."""
    written = [folder / "summary.csv"]
    _atomic.write_text_atomic(written[0], batch.to_csv())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    table = pa.Table.from_pylist([{k: row.get(k) for k in COLUMNS} for row in batch.rows])
    buffer = pa.BufferOutputStream()
    pq.write_table(table, buffer)
    written.append(folder / "summary.parquet")
    _atomic.write_bytes_atomic(written[1], buffer.getvalue().to_pybytes())
    return written


# -- the batch -------------------------------------------------------------------------------------
def fit_many(inputs, *, client=None, workers: int | None = None, scheduler: str | None = None,
             output: str | os.PathLike | None = None, method=DEFAULT_METHOD, options: SearchOptions | None = None,
             min_degree: int = 2, max_degree: int | None = None, epsilon: float = DEFAULT_EPSILON,
             delta: float = DEFAULT_DELTA, rule: str = DEFAULT_RULE, seed: int = 0,
             progress: Callable[[dict], None] | None = None) -> BatchResult:
    """Fit every shape of ``inputs`` with :func:`~ipfit.fit_adaptive` on a Dask cluster.

    Parameters
    ----------
    inputs : paths, folders, globs, bundled names, ``"generated:N[:SEED]"``, generated shapes
        (:func:`ipfit.datasets.collection`) or a ``{name: (points, normals)}`` mapping.
    client : a ``distributed.Client`` to use (a notebook's own); else ``scheduler`` (an
        address) is connected to, else an embedded LocalCluster of ``workers`` processes
        (default 2) runs the batch and is stopped at the end.
    output : a folder for ``NAME.json`` per shape and ``summary.csv``; shapes whose result
        there has the same settings are skipped (resume).
    method, options, min_degree, max_degree, epsilon, delta, rule : as :func:`~ipfit.fit_adaptive`.
    seed : the batch seed; shape ``name`` uses :func:`shape_rng` ``(seed, name)``.
    progress : called after each shape with ``{"event": "shape", "name", "status", "done",
        "failed", "skipped", "running", "total", "elapsed", "eta"}`` (``eta`` in seconds or None).

    Returns
    -------
    BatchResult

    Examples
    --------
    >>> from ipfit.datasets import collection
    >>> batch = fit_many(collection(2), method="3l", max_degree=2, workers=1)  # an embedded cluster
    >>> [(row["name"], row["status"], row["selected_degree"]) for row in batch.rows]
    [('star-0000', 'ok', 2), ('blob-0001', 'ok', 2)]

    With a notebook's own cluster: ``fit_many(inputs, client=Client("tcp://host:8786"))``.
    """
    tasks = expand_inputs(inputs)
    settings = FitSettings(method, options, min_degree, max_degree, epsilon, delta, rule,
                           check_int(seed, "seed", minimum=0))
    _check_settings(settings)
    folder = None if output is None else Path(output)
    if folder is not None:
        if folder.exists() and not folder.is_dir():
            raise InvalidInputError(f"--output: {folder} is a file; the batch writes a folder. Choose a folder.")
        folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows: dict[str, dict] = {}
    results: dict[str, dict] = {}
    todo = []
    for task in tasks:
        stored = None if folder is None else _stored(folder / f"{task.name}.json")
        if stored is not None and (stored.get("batch") or {}).get("settings_hash") == settings.hash \
                and (stored.get("input") or {}).get("source") == task.source:
            rows[task.name], results[task.name] = _row_of(task, stored, "skipped"), stored
        else:
            todo.append(task)
    # The summary is written before the cluster stops: stopping it may take seconds, and a
    # second Ctrl-C then must not lose the summary of the first.
    with _client_for(client, workers, scheduler) if todo else contextlib.nullcontext() as active:
        interrupted = bool(todo) and _run(active, todo, settings, folder, rows, results, progress, len(tasks), start)
        batch = BatchResult(tuple(rows[t.name] for t in tasks), results, interrupted, time.perf_counter() - start)
        if folder is not None:
            write_summary(folder, batch)
    return batch


def _check_settings(settings: FitSettings) -> None:
    """Bad settings fail once, here, not once per shape on the workers."""
    from ..adaptive import check_settings

    check_settings(settings.method, settings.options, settings.rule, settings.epsilon, settings.delta,
                   settings.min_degree, settings.max_degree)


def _run(active, todo, settings, folder, rows, results, progress, total, start) -> bool:
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures = {active.submit(_fit_task, task, settings, key=f"ipfit-fit-{token}-{i}", pure=False, retries=0): task
               for i, task in enumerate(todo)}
    slots = max(1, sum(active.nthreads().values()))
    counts = {"done": 0, "failed": 0}
    fit_started = time.perf_counter()
    try:
        for future in as_completed(futures):
            task = futures[future]
            try:
                out = future.result()
            except Exception as exc:  # noqa: BLE001 - the worker died (KilledWorker) or the task was lost
                reason = "the worker process running it died" if type(exc).__name__ == "KilledWorker" else \
                    _one_line(exc)
                out = {"row": _row(task, status="failed", error=reason), "result": None}
            row, payload = out["row"], out["result"]
            if payload is not None and folder is not None:
                from ..results import write_result

                write_result(folder / f"{task.name}.json", payload)
            rows[task.name] = row
            if payload is not None:
                results[task.name] = payload
            counts["done" if row["status"] == "ok" else "failed"] += 1
            if progress is not None:
                progress(_event(row, counts, len(todo), total, slots, fit_started, start))
    except KeyboardInterrupt:
        pending = [f for f, t in futures.items() if t.name not in rows]
        with contextlib.suppress(Exception):
            active.cancel(pending)
        for task in todo:
            rows.setdefault(task.name, _row(task, status="cancelled"))
        return True
    return False


def _event(row, counts, n_todo, total, slots, fit_started, start) -> dict:
    finished = counts["done"] + counts["failed"]
    left = n_todo - finished
    elapsed = time.perf_counter() - fit_started
    eta = elapsed / finished * left if finished else None
    return {"event": "shape", "name": row["name"], "status": row["status"], "error": row["error"],
            "done": counts["done"], "failed": counts["failed"], "skipped": total - n_todo,
            "running": min(left, slots), "total": total, "elapsed": time.perf_counter() - start, "eta": eta}

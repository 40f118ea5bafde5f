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
on. KeyboardInterrupt cancels the pending shapes (status ``cancelled``), keeps every
finished result and returns (``BatchResult.interrupted``).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import logging
import os
import time
import uuid
from dataclasses import dataclass, field
from glob import glob, has_magic
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping

import numpy as np

from . import _atomic
from ._validation import check_int, error
from .exceptions import InvalidInputError
from .options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions

__all__ = ["fit_many", "BatchResult", "FitSettings", "shape_rng", "local_cluster", "expand_inputs", "COLUMNS",
           "THREAD_ENV"]

#: The summary table's columns, in order.
COLUMNS = ("name", "input", "points", "dim", "selected_degree", "dissimilarity", "smoothness", "distance", "f_score",
           "n_spurious", "seconds", "status", "error")
#: Set in every embedded worker: one BLAS / OpenMP / numba thread per worker process.
THREAD_ENV = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                     "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}
GENERATED_PREFIX = "generated:"


def shape_rng(seed: int, name: str) -> np.random.Generator:
    """The generator shape ``name`` is fitted with in a batch of seed ``seed``.

    >>> a, b = shape_rng(0, "heart").random(), shape_rng(0, "heart").random()
    >>> a == b, a == shape_rng(0, "bunny").random(), a == shape_rng(1, "heart").random()
    (True, False, False)
    """
    words = np.frombuffer(hashlib.sha256(name.encode("utf-8")).digest()[:16], dtype="<u4")
    return np.random.default_rng(np.random.SeedSequence([check_int(seed, "seed", minimum=0), *map(int, words)]))


@dataclass(frozen=True)
class FitSettings:
    """The ``fit_adaptive`` settings of a batch, with the hash that marks its results."""

    method: Any = DEFAULT_METHOD
    options: SearchOptions | None = None
    min_degree: int = 2
    max_degree: int | None = None
    epsilon: float = DEFAULT_EPSILON
    delta: float = DEFAULT_DELTA
    rule: str = DEFAULT_RULE
    seed: int = 0

    def to_dict(self) -> dict:
        method = self.method if isinstance(self.method, str) else \
            f"{getattr(self.method, '__module__', '')}.{getattr(self.method, '__qualname__', repr(self.method))}"
        return {"method": method, "options": None if self.options is None else self.options.to_dict(),
                "min_degree": self.min_degree, "max_degree": self.max_degree, "epsilon": self.epsilon,
                "delta": self.delta, "rule": self.rule, "seed": self.seed}

    @property
    def hash(self) -> str:
        from . import __version__

        text = json.dumps({**self.to_dict(), "ipfit": __version__}, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    def fit(self, points, normals, name: str, faces=None):
        from .adaptive import fit_adaptive

        return fit_adaptive(points, normals, method=self.method, options=self.options, min_degree=self.min_degree,
                            max_degree=self.max_degree, epsilon=self.epsilon, delta=self.delta, rule=self.rule,
                            faces=faces, rng=shape_rng(self.seed, name))


@dataclass(frozen=True)
class _Task:
    name: str
    source: str  # a path, a bundled name, or "generated:N:SEED#i"
    data: tuple | None = None  # (points, normals) given in memory


@dataclass(frozen=True)
class BatchResult:
    """What :func:`fit_many` returns: one row per shape (:data:`COLUMNS`) and the result JSONs by name."""

    rows: tuple[dict, ...]
    results: Mapping[str, dict] = field(default_factory=dict)
    interrupted: bool = False
    seconds: float = 0.0

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for row in self.rows:
            out[row["status"]] = out.get(row["status"], 0) + 1
        return out

    def to_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if row.get(k) is None else row.get(k)) for k in COLUMNS} for row in self.rows)
        return buffer.getvalue()


# -- inputs ----------------------------------------------------------------------------------
def _point_files(folder: Path) -> list[Path]:
    from .io import READ_FORMATS

    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in READ_FORMATS)


def _generated(spec: str) -> list[_Task]:
    parts = spec[len(GENERATED_PREFIX):].split(":")
    try:
        n, seed = int(parts[0]), int(parts[1]) if len(parts) > 1 else 0
        if len(parts) > 2 or n < 1 or seed < 0:
            raise ValueError
    except ValueError:
        raise InvalidInputError(f"{spec}: expected generated:N or generated:N:SEED (N >= 1, SEED >= 0). "
                                "Fix the input.") from None
    from .datasets.collection import collection

    return [_Task(s.name, f"{GENERATED_PREFIX}{n}:{seed}#{i}", (s.points, s.normals))
            for i, s in enumerate(collection(n, seed))]


def expand_inputs(inputs: Iterable[Any] | Mapping[str, Any]) -> list[_Task]:
    """Files, folders (their point files), globs, bundled names, ``generated:N[:SEED]`` (the
    :func:`~ipfit.datasets.collection`), ``{name: (points, normals)}`` mappings or generated shapes ->
    one task per shape, with unique names (a repeated file stem gets ``-2``, ``-3``, ...)."""
    from .datasets import bundled
    from .datasets.collection import GeneratedShape

    tasks: list[_Task] = []
    items = []
    for item in [inputs] if isinstance(inputs, Mapping) else inputs:
        items += item.items() if isinstance(item, Mapping) else [(None, item)]
    for name, item in items:
        if name is not None:
            points, normals = item if isinstance(item, tuple) else (item, None)
            tasks.append(_Task(str(name), str(name), (np.asarray(points), normals)))
        elif isinstance(item, GeneratedShape):
            tasks.append(_Task(item.name, item.name, (item.points, item.normals)))
        elif isinstance(item, (str, os.PathLike)):
            text = os.fspath(item)
            path = Path(text)
            if text.startswith(GENERATED_PREFIX):
                tasks += _generated(text)
            elif path.is_dir():
                tasks += [_Task(p.stem, str(p)) for p in _point_files(path)]
            elif path.exists():
                tasks.append(_Task(path.stem, text))
            elif has_magic(text):
                tasks += [_Task(Path(p).stem, p) for p in sorted(glob(text)) if Path(p).is_file()]
            elif text in bundled.dataset_names():
                tasks.append(_Task(text, text))
            else:
                raise InvalidInputError(f"{text}: no such file or folder, nor a glob, a bundled dataset name or "
                                        "generated:N. Check the input.")
        else:
            raise error("inputs", "paths, names, GeneratedShape objects or a {name: (points, normals)} mapping",
                        type(item).__name__)
    if not tasks:
        raise InvalidInputError("inputs: no shapes found (empty folder or glob). Check the inputs.")
    seen: dict[str, int] = {}
    unique = []
    for task in tasks:
        count = seen[task.name] = seen.get(task.name, 0) + 1
        unique.append(task if count == 1 else _Task(f"{task.name}-{count}", task.source, task.data))
    return unique


# -- one shape, on a worker ---------------------------------------------------------------------
def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _row(task: _Task, **values) -> dict:
    return {**dict.fromkeys(COLUMNS), "name": task.name, "input": task.source, **values}


def _row_of(task: _Task, payload: Mapping, status: str) -> dict:
    measures, quality = payload.get("measures") or {}, payload.get("quality") or {}
    return _row(task, points=payload.get("input", {}).get("n_points"), dim=payload.get("dim"),
                selected_degree=payload.get("selected_degree"), dissimilarity=measures.get("dissimilarity"),
                smoothness=measures.get("smoothness"), distance=measures.get("distance"),
                f_score=quality.get("f_score"), n_spurious=quality.get("n_spurious"),
                seconds=(payload.get("adaptive") or {}).get("seconds"), status=status)


def _fit_task(task: _Task, settings: FitSettings) -> dict:
    """Read and fit one shape; every error becomes a failed row (the worker lives on)."""
    start = time.perf_counter()
    try:
        if task.data is not None:
            points, normals, faces, path = task.data[0], task.data[1], None, None
        else:
            from .cli._common import load_input

            data = load_input(task.source)
            points, normals, faces = data.points, data.normals, data.faces
            path = str(Path(task.source).resolve()) if Path(task.source).exists() else None
        with np.errstate(all="ignore"):
            result = settings.fit(points, normals, task.name, faces)
        points = np.asarray(points, dtype=float)
        payload = result.to_dict()
        payload["input"] = {"source": task.source, "n_points": int(len(points)),
                            "normals": "estimated" if normals is None else "file"}
        if path is not None:
            payload["input"]["path"] = path
        payload["bounds"] = np.column_stack([points.min(axis=0), points.max(axis=0)]).tolist()
        payload["batch"] = {"settings_hash": settings.hash, "name": task.name, "seed": settings.seed}
        return {"row": _row_of(task, payload, "ok"), "result": payload}
    except Exception as exc:  # noqa: BLE001 - isolate the shape: its row says what went wrong
        return {"row": _row(task, seconds=time.perf_counter() - start, status="failed", error=_one_line(exc)),
                "result": None}


# -- the cluster ----------------------------------------------------------------------------------
@contextlib.contextmanager
def local_cluster(workers: int = 2) -> Iterator[Any]:
    """A ``distributed.Client`` on a LocalCluster of ``workers`` processes, one thread each (closed on exit).

    A worker that dies fails the shape it was running at once (``allowed-failures`` 0; a
    shape that kills its worker would otherwise kill three more), and each worker holds only
    the shape it runs (``worker-saturation`` 1), so a death fails no queued shape.
    """
    import dask
    from distributed import Client, LocalCluster

    workers = check_int(workers, "workers", minimum=1)
    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **THREAD_ENV}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                          "distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               env=THREAD_ENV, silence_logs=logging.CRITICAL)
        try:
            client = Client(cluster)
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()


@contextlib.contextmanager
def _client_for(client, workers: int | None, scheduler: str | None) -> Iterator[Any]:
    if client is not None:
        yield client
    elif scheduler is not None:
        from distributed import Client

        try:
            connected = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise InvalidInputError(f"--scheduler: cannot connect to {scheduler} ({_one_line(exc)}). "
                                    "Check the address and that the scheduler is running.") from None
        try:
            yield connected
        finally:
            connected.close()
    else:
        with local_cluster(workers or 2) as embedded:
            yield embedded


# -- outputs ---------------------------------------------------------------------------------------
def _stored(path: Path) -> dict | None:
    """The ipfit result at ``path`` (None when absent); refuses to replace a file ipfit did not write."""
    from ._result_schema import FORMAT_NAME

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
    from . import basis
    from .adaptive import fit_adaptive
    from .datasets.synthetic import circle

    shape = circle(basis.n_coefficients(2, max(2, check_int(settings.min_degree, "min_degree", minimum=1))) + 2)
    try:
        fit_adaptive(shape.points, shape.normals, method="lstsq" if callable(settings.method) else settings.method,
                     options=settings.options if not callable(settings.method) else None,
                     min_degree=settings.min_degree, max_degree=None, epsilon=settings.epsilon,
                     delta=settings.delta, rule=settings.rule, rng=0, progress=_stop_at_once)
    except _Checked:
        pass
    if settings.max_degree is not None:
        check_int(settings.max_degree, "max_degree", minimum=settings.min_degree)


class _Checked(Exception):
    pass


def _stop_at_once(event: dict) -> None:
    raise _Checked


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
                from .results import write_result

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

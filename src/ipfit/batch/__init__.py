"""Fit many shapes on Dask: an embedded cluster of worker processes, or the caller's own.

:func:`fit_many` submits one :func:`~ipfit.fit_adaptive` per shape to a
``dask.distributed`` cluster and gathers one row per shape (:data:`COLUMNS`) and its result
JSON. Without a ``client`` it starts a :class:`~distributed.LocalCluster` of worker
processes, one thread each, with the BLAS/OpenMP/numba thread counts set to 1 (so the
workers do not fight over the cores), and stops it at the end.

Reproducibility: shape ``name`` is fitted with ``rng=shape_seed(seed, name)``, a seed derived
from the batch seed and the shape's *name* (not from its place in the queue or the worker that
runs it) and written in its row (``seed``) and its result (``batch.shape_seed``), so
``ipfit fit FILE --seed THAT`` or ``fit_adaptive(points, normals, rng=THAT, ...)`` alone gives the
same result, bit for bit, on the same kind of machine (another processor rounds matrix products
differently, see the README). A batch whose every shape is finished starts no cluster.

Names: each shape has a unique name, stable for the same inputs in any order
(:func:`unique_names`: the file's stem; on a clash, or for ``summary`` and ``index``, the
file name with dashes, ``a.ply`` -> ``a-ply``, then a hash of the source). A caller's name
(a mapping key) must be a plain file name: no ``/`` or ``\\``, not empty, no leading dot.

Outputs: nothing is ever written outside ``output``, and no file there that ipfit did not
write is replaced. The batch records what it writes in ``OUTPUT/.ipfit-batch.json``
(:data:`MANIFEST`); before any work it refuses, in one line, to replace a file that is not
listed there (nor an ipfit result, for ``NAME.json``), or an input.

Resume: each result is written to ``OUTPUT/NAME.json`` with
``"batch": {"settings_hash": ..., "name": ..., "seed": ...}``; a shape whose stored result
is valid (:func:`ipfit.degree.results.validate_result`), records the same file (or source) and
name, and has the current settings' hash is skipped (status ``skipped``, its row read
back); a broken one is fitted again and replaced.

Limits, checked before the work: ``generated:N`` up to :data:`MAX_GENERATED` shapes; an
embedded cluster up to :func:`max_workers` processes (4 per core, 512 MiB of available
memory each); a ``scheduler`` must answer within :data:`CONNECT_TIMEOUT` seconds.

Failures stay with their shape: an error while reading or fitting it, or the death of the
worker process running it, makes its row ``failed`` with a one-line message; the rest go
on. (On an existing cluster Dask retries a shape whose worker died on other workers, up to
the scheduler's ``distributed.scheduler.allowed-failures``, 3 by default; the embedded
cluster sets it to 0.) KeyboardInterrupt cancels the pending shapes (status ``cancelled``), keeps every
finished result and returns (``BatchResult.interrupted``). The embedded workers ignore
SIGINT (the batch process stops them), and a signal arriving while the cluster stops is
held until it has stopped.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import time
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import cast

from .._result_schema import FORMAT_NAME, validate_result
from .._utils import atomic as _atomic
from .._utils.validation import check_int, error
from ..exceptions import InvalidInputError
from ..fitting.options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions
from ._cluster import (
    CONNECT_TIMEOUT,
    LOGGER,
    THREAD_ENV,
    HeldSignals,
    _client_for,
    check_workers,
    dask_warnings_logged,
    local_cluster,
    max_workers,
    require_distributed,
)
from ._shapes import (
    COLUMNS,
    GENERATED_PREFIX,
    MAX_GENERATED,
    RESERVED_NAMES,
    BatchResult,
    FitSettings,
    _fit_task,
    _one_line,
    _row,
    _row_of,
    expand_inputs,
    shape_rng,
    shape_seed,
    unique_names,
)
from ._thumbnail import write_thumbnail

__all__ = ["fit_many", "BatchResult", "FitSettings", "shape_seed", "shape_rng", "local_cluster", "expand_inputs",
           "unique_names",
           "COLUMNS", "THREAD_ENV", "GENERATED_PREFIX", "MAX_GENERATED", "RESERVED_NAMES", "MANIFEST",
           "CONNECT_TIMEOUT", "LOGGER", "max_workers", "write_summary", "dask_warnings_logged",
           "write_thumbnail", "client_for", "require_distributed"]


#: A Dask client for a run: the caller's ``client``, a connection to ``scheduler`` (checked, one line
#: when it cannot be reached), or an embedded cluster of ``workers`` processes (stopped on exit).
client_for = _client_for


# -- outputs ---------------------------------------------------------------------------------------
#: The batch's record in OUTPUT of the files it wrote (or was about to): only those it replaces.
MANIFEST = ".ipfit-batch.json"
_MANIFEST_FORMAT = "ipfit-batch"


def _refuse(path: Path, why: str = "ipfit did not write it") -> InvalidInputError:
    return InvalidInputError(f"--output: {path} exists and {why}; the batch would replace it. "
                             "Move it or choose another output folder.")


def _json_or_none(path: Path):
    """The JSON in ``path``, or None when it is unreadable, not JSON, nested too deeply or too big a number."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None


def _manifest(folder: Path) -> set[str]:
    """The file names :data:`MANIFEST` lists (none without one); a foreign file there is refused."""
    path = folder / MANIFEST
    if not (path.exists() or path.is_symlink()):
        return set()
    data = _json_or_none(path) if path.is_file() else None
    files = data.get("files") if isinstance(data, dict) and data.get("format") == _MANIFEST_FORMAT else None
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        raise _refuse(path, "is not ipfit's record of a batch")
    return set(files)


def _has_pyarrow() -> bool:
    import importlib.util

    return importlib.util.find_spec("pyarrow") is not None


class _Outputs:
    """OUTPUT's files, checked before the work: a file that ipfit did not write or that is an input
    is refused; the others are claimed in :data:`MANIFEST`."""

    def __init__(self, folder: Path, tasks, also_writes=()) -> None:
        self.folder, self.own = folder, _manifest(folder) if folder.is_dir() else set()
        self._inputs = set()
        for task in tasks:
            with contextlib.suppress(OSError):
                if task.path:
                    self._inputs.add(_file_id(Path(task.path)))
        names = ["summary.csv", *(["summary.parquet"] if _has_pyarrow() else [])]
        for pattern in also_writes:
            names += sorted({pattern.format(name=t.name) for t in tasks}) if "{name}" in pattern else [pattern]
        for name in names:
            self._check(folder / name, name in self.own)
        self.claimed = set(names) | {f"{t.name}.json" for t in tasks}

    def _check(self, path: Path, own: bool) -> None:
        if not (path.exists() or path.is_symlink()):
            return
        with contextlib.suppress(OSError):
            if _file_id(path) in self._inputs:
                raise _refuse(path, "is an input file")
        if not own or not path.is_file():
            raise _refuse(path)

    def finished(self, task, settings: FitSettings) -> dict | None:
        """The valid result of ``task`` with these settings in OUTPUT, else None (fit it).

        A result of ipfit's (listed, or with ``"format": "ipfit"``) that is broken or has other
        settings is fitted again and replaced; any other file is refused.
        """
        path = self.folder / f"{task.name}.json"
        if not (path.exists() or path.is_symlink()):
            return None
        data = _json_or_none(path) if path.is_file() else None
        self._check(path, path.name in self.own or (isinstance(data, dict) and data.get("format") == FORMAT_NAME))
        try:
            # returns data itself (it raises on None), now known to be a JSON object: a dict
            data = cast(dict, validate_result(data, str(path)))
        except (InvalidInputError, RecursionError, ValueError, TypeError, KeyError):
            return None
        recorded, batch = data.get("input") or {}, data.get("batch") or {}
        same = (batch.get("settings_hash") == settings.hash and batch.get("name") == task.name
                and recorded.get("path" if task.path else "source") == task.identity)
        return data if same else None

    def claim(self) -> None:
        """Record the files this batch may write, before it writes any."""
        self.folder.mkdir(parents=True, exist_ok=True)
        record = {"format": _MANIFEST_FORMAT, "version": 1, "files": sorted(self.own | self.claimed)}
        _atomic.write_text_atomic(self.folder / MANIFEST, json.dumps(record, indent=0) + "\n")


def _file_id(path: Path) -> tuple[int, int]:
    stat = path.stat()
    return stat.st_dev, stat.st_ino


#: The summary's column types (the rest are text), for ``summary.parquet``.
_INTEGER_COLUMNS = ("seed", "points", "dim", "selected_degree", "n_spurious")
_FLOAT_COLUMNS = ("dissimilarity", "smoothness", "distance", "f_score", "seconds")


def write_summary(folder: Path, batch: BatchResult) -> list[Path]:
    """``summary.csv`` (and ``summary.parquet`` when pyarrow is installed), written atomically."""
    written = [folder / "summary.csv"]
    text = batch.to_csv()
    _atomic.write_text_atomic(written[0], text)
    try:
        import pyarrow as pa
        import pyarrow.csv as pcsv
        import pyarrow.parquet as pq
    except ImportError:
        return written
    # The table is read back from the CSV (floats are written as repr: exact), with every column's
    # type fixed: building it from Python rows would import pandas, seconds for a batch with
    # nothing to do, and would guess each column's type from its values.
    types = {name: pa.int64() if name in _INTEGER_COLUMNS else pa.float64() if name in _FLOAT_COLUMNS
             else pa.string() for name in COLUMNS}
    table = pcsv.read_csv(pa.py_buffer(text.encode("utf-8")), parse_options=pcsv.ParseOptions(newlines_in_values=True),
                          convert_options=pcsv.ConvertOptions(column_types=types, null_values=[""],
                                                              strings_can_be_null=True,
                                                              quoted_strings_can_be_null=False))
    buffer = pa.BufferOutputStream()
    pq.write_table(table, buffer)
    written.append(folder / "summary.parquet")
    _atomic.write_bytes_atomic(written[1], buffer.getvalue().to_pybytes())
    return written


# -- the batch -------------------------------------------------------------------------------------
def fit_many(inputs, *, client=None, workers: int | None = None, scheduler: str | None = None,
             output: str | os.PathLike | None = None, method=DEFAULT_METHOD, options: SearchOptions | None = None,
             min_degree: int = 2, max_degree: int | None = None, epsilon: float = DEFAULT_EPSILON,
             delta: float = DEFAULT_DELTA, rule=DEFAULT_RULE, seed: int = 0, outliers: str | float = "auto",
             progress: Callable[[dict], None] | None = None, also_writes: Iterable[str] = ()) -> BatchResult:
    """Fit every shape of ``inputs`` with :func:`~ipfit.fit_adaptive` on a Dask cluster.

    Parameters
    ----------
    inputs : iterable or mapping
        Paths, folders, globs, bundled names, ``"generated:N[:SEED]"``, generated shapes
        (:func:`ipfit.datasets.collection`) or a ``{name: (points, normals)}`` mapping.
    client : distributed.Client, optional
        A client to use (a notebook's own); else ``scheduler`` (an address) is connected to,
        else an embedded LocalCluster of ``workers`` processes (default 2; at most
        :func:`max_workers`) runs the batch and is stopped at the end.
    workers, scheduler : int or str, optional
        See ``client``.
    output : str or os.PathLike, optional
        A folder for ``NAME.json`` per shape and ``summary.csv``; shapes whose valid result
        there has the same settings are skipped (resume). Files there that ipfit did not write
        are never replaced (see the module's notes).
    method, options, min_degree, max_degree, epsilon, delta, rule, outliers
        As :func:`~ipfit.fit_adaptive`.
    seed : int
        The batch seed; shape ``name`` uses :func:`shape_rng` ``(seed, name)``.
    progress : callable, optional
        Called after each shape with ``{"event": "shape", "name", "status", "done", "failed",
        "skipped", "running", "total", "elapsed", "eta"}`` (``eta`` in seconds or None).
    also_writes : iterable of str
        More file names the caller will write into ``output`` (``"{name}.html"`` for each
        shape, ``"index.html"``), checked and recorded with the batch's own.

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

    Raises
    ------
    InvalidInputError
        Bad inputs, names, settings or limits, an output file ipfit did not write, an
        unreachable scheduler: one line, before any shape is fitted.
    IpfitError
        ``dask.distributed`` is not installed (``pip install 'ipfit[dask]'``) and a shape is to be
        fitted (a batch with nothing to do needs no Dask).
    """
    if client is None and scheduler is None:
        workers = min(2, max_workers()) if workers is None else check_workers(workers)
    tasks = expand_inputs(inputs)
    if not (isinstance(outliers, str) and outliers in ("auto", "none")):  # else already what the check returns
        from ..robust import check_outliers  # robust imports scipy.stats: a second a batch with nothing to do saves

        outliers = check_outliers(outliers)
    settings = FitSettings(method, options, min_degree, max_degree, epsilon, delta, _rule_name(rule),
                           check_int(seed, "seed", minimum=0), outliers)
    folder = None if output is None else Path(output)
    outputs = None
    if folder is not None:
        if folder.exists() and not folder.is_dir():
            raise InvalidInputError(f"--output: {folder} is a file; the batch writes a folder. Choose a folder.")
        outputs = _Outputs(folder, tasks, also_writes)
    start = time.perf_counter()
    rows: dict[str, dict] = {}
    results: dict[str, dict] = {}
    todo = []
    for task in tasks:
        stored = None if outputs is None else outputs.finished(task, settings)
        if stored is not None:
            rows[task.name], results[task.name] = _row_of(task, settings.seed, stored, "skipped"), stored
        else:
            todo.append(task)
    if todo:
        # Only with work to do: a batch whose every shape is finished answers at once, with no
        # cluster (its results' settings hash is these settings', which were checked then).
        require_distributed()
        _check_settings(settings)
    # The summary is written before the cluster stops: stopping it may take seconds, and a
    # second Ctrl-C then must not lose the summary of the first (it is held until the end).
    with HeldSignals() as held, contextlib.ExitStack() as cluster:
        if todo:  # Dask's warnings (a busy port, ...) go to the log from the cluster's start to its end
            cluster.enter_context(dask_warnings_logged())
            active = cluster.enter_context(_client_for(client, workers, scheduler))
        if outputs is not None:  # once the cluster runs: a scheduler that cannot be reached writes nothing
            outputs.claim()
        try:
            stopped_by = _run(active, todo, settings, folder, rows, results, progress, len(tasks), start) \
                if todo else None
        finally:
            held.start()
        batch = BatchResult(tuple(rows[t.name] for t in tasks), results, stopped_by is not None,
                            time.perf_counter() - start, stopped_by)
        if folder is not None:
            write_summary(folder, batch)
    if held.signals and not batch.interrupted:  # Ctrl-C while the cluster stopped: all was done, but say so
        batch = dataclasses.replace(batch, interrupted=True, signal=held.signals[0])
    return batch


def _rule_name(rule):
    """A batch records its rule by name (in every result and in the hash that resumes it), and its
    workers look the name up: a registered rule object is its name; a name is kept as given."""
    if isinstance(rule, str):  # checked with the other settings (degree.rules is slow to import)
        return rule
    from ..degree.rules import RULES, DegreeRule

    if not isinstance(rule, DegreeRule):
        return rule
    if RULES.get(rule.name) is not rule:
        raise error("rule", "a rule's name or a rule of ipfit.degree.rules.RULES", repr(rule),
                    "A batch records its rule by name: register the rule in ipfit.degree.rules.RULES.")
    return rule.name


def _check_settings(settings: FitSettings) -> None:
    """Bad settings fail once, here, not once per shape on the workers."""
    from ..degree.adaptive import check_settings

    check_settings(settings.method, settings.options, settings.rule, settings.epsilon, settings.delta,
                   settings.min_degree, settings.max_degree)


def _run(active, todo, settings, folder, rows, results, progress, total, start) -> int | None:
    """Fit ``todo``; the signal that interrupted it (rows ``cancelled``), or None."""
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
                out = {"row": _row(task, settings.seed, status="failed", error=reason), "result": None}
            row, payload = out["row"], out["result"]
            if payload is not None and folder is not None:
                from ..degree.results import write_result

                write_result(folder / f"{task.name}.json", payload)
            rows[task.name] = row
            if payload is not None:
                results[task.name] = payload
            counts["done" if row["status"] == "ok" else "failed"] += 1
            if progress is not None:
                progress(_event(row, counts, len(todo), total, slots, fit_started, start))
    except KeyboardInterrupt as exc:  # the command line's SIGTERM is one too (with its signum)
        pending = [f for f, t in futures.items() if t.name not in rows]
        with contextlib.suppress(Exception):
            active.cancel(pending)
        for task in todo:
            rows.setdefault(task.name, _row(task, settings.seed, status="cancelled"))
        return getattr(exc, "signum", signal.SIGINT)
    return None


def _event(row, counts, n_todo, total, slots, fit_started, start) -> dict:
    finished = counts["done"] + counts["failed"]
    left = n_todo - finished
    elapsed = time.perf_counter() - fit_started
    eta = elapsed / finished * left if finished else None
    return {"event": "shape", "name": row["name"], "status": row["status"], "error": row["error"],
            "done": counts["done"], "failed": counts["failed"], "skipped": total - n_todo,
            "running": min(left, slots), "total": total, "elapsed": time.perf_counter() - start, "eta": eta}

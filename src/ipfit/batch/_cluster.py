"""The Dask cluster of a batch: an embedded LocalCluster, or the caller's client or scheduler.

Dask's own warnings in this process (``Port 8787 is already in use`` when another cluster
holds the port of its HTTP server, ...) become records of the :data:`LOGGER` logger while a
batch runs (:func:`dask_warnings_logged`), not lines on the terminal; ``ipfit batch`` writes
them to ``OUTDIR/batch.log``. The embedded cluster's log records are silenced.

Ctrl-C in a terminal reaches the whole process group, the embedded workers included. The
workers ignore SIGINT (inherited while the cluster starts, and set again by the preload
:mod:`ipfit.batch._worker` in a worker that replaces a dead one): the batch process alone
handles it, cancels the pending shapes and stops the cluster, so the workers neither print
tracebacks nor die under their tasks.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import signal
import threading
import warnings
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from .._utils.optional import require
from .._utils.validation import check_int
from ..exceptions import InvalidInputError
from ._shapes import _one_line

#: The logger that receives Dask's warnings during a batch (a library's: a NullHandler, so that
#: nothing reaches the terminal unless the caller configures logging).
LOGGER = "ipfit.batch"
logging.getLogger(LOGGER).addHandler(logging.NullHandler())
#: Set in every embedded worker: one BLAS / OpenMP / numba thread per worker process.
THREAD_ENV = dict.fromkeys(("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS",
                           "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"), "1")
#: Seconds to wait for a ``scheduler`` to answer (environment: ``IPFIT_BATCH_CONNECT_TIMEOUT``).
CONNECT_TIMEOUT = 10.0
#: The embedded cluster's bound: at most this many worker processes per core ...
WORKERS_PER_CORE = 4
#: ... and this much available memory per worker process (bytes).
WORKER_MEMORY = 512 * 2**20


def require_distributed() -> None:
    """Refuse in one line, before any work, when ``dask.distributed`` is not installed."""
    for module in ("dask", "distributed"):
        require(module, "the batch (it runs on dask.distributed)")


def max_workers() -> int:
    """The most worker processes an embedded cluster may start here: :data:`WORKERS_PER_CORE` per
    core, and no more than the available memory holds at :data:`WORKER_MEMORY` each."""
    import psutil  # a dependency of distributed

    by_memory = psutil.virtual_memory().available // WORKER_MEMORY
    return max(1, min((os.cpu_count() or 1) * WORKERS_PER_CORE, int(by_memory)))


def check_workers(workers: Any) -> int:
    workers = check_int(workers, "workers", minimum=1)
    bound = max_workers()
    if workers > bound:
        raise InvalidInputError(f"workers: expected at most {bound} worker processes on this machine "
                                f"({os.cpu_count()} cores, {WORKERS_PER_CORE} per core, {WORKER_MEMORY >> 20} MiB "
                                f"of available memory each), got {workers}. Pass fewer workers.")
    return workers


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while the block runs, so that the processes it starts inherit that.

    An ignored signal is the one disposition that survives fork and exec: a worker then starts
    immune to a terminal's Ctrl-C (sent to the whole process group) until its preload
    (:mod:`ipfit.batch._worker`) makes that permanent. The price: a Ctrl-C in the seconds the
    cluster starts is lost (blocking it instead does not protect the workers: other threads,
    BLAS's, receive and drop it).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class HeldSignals:
    """From :meth:`start` to the end of the ``with`` block, SIGINT and SIGTERM are only recorded
    in :attr:`signals`: stopping the cluster takes a moment, and a second Ctrl-C must neither
    abandon it half-way nor raise inside Dask's callbacks (printed as "Exception ignored")."""

    def __init__(self) -> None:
        self.signals: list[int] = []
        self._previous: dict = {}

    def __enter__(self) -> HeldSignals:
        return self

    def start(self) -> None:
        if threading.current_thread() is threading.main_thread() and not self._previous:
            self._previous = {sig: signal.signal(sig, self._record) for sig in (signal.SIGINT, signal.SIGTERM)}

    def _record(self, signum: int, frame) -> None:
        self.signals.append(signum)

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous = {}


def _dask_roots() -> tuple[str, ...]:
    """The folders of the packages whose warnings are Dask's own."""
    import importlib.util

    roots = []
    for name in ("dask", "distributed", "tornado", "bokeh"):
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            roots.append(str(Path(spec.origin).parent) + os.sep)
    return tuple(roots)


@contextlib.contextmanager
def dask_warnings_logged() -> Iterator[None]:
    """While the block runs, Python warnings raised in Dask's code (dask, distributed, tornado,
    bokeh) are records of the :data:`LOGGER` logger, on one line each; other warnings show as before.

    Dask warns from its own threads too (the scheduler's event loop), so this swaps the one
    process-wide ``warnings.showwarning``, restored at the end (``warnings.catch_warnings``).
    """
    roots = _dask_roots()
    logger = logging.getLogger(LOGGER)
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def route(message, category, filename, lineno, file=None, line=None) -> None:
            if str(filename).startswith(roots):
                logger.warning("%s: %s", category.__name__, " ".join(str(message).split()))
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.showwarning = route
        yield


@contextlib.contextmanager
def local_cluster(workers: int = 2) -> Iterator[Any]:
    """A ``distributed.Client`` on a LocalCluster of ``workers`` processes, one thread each (closed on exit).

    A worker that dies fails the shape it was running at once (``allowed-failures`` 0; a
    shape that kills its worker would otherwise kill three more), and each worker holds only
    the shape it runs (``worker-saturation`` 1), so a death fails no queued shape. The
    workers ignore SIGINT (see the module's notes); ``workers`` is bounded by :func:`max_workers`.
    """
    require_distributed()
    import dask
    from distributed import Client, LocalCluster

    workers = check_workers(workers)
    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **THREAD_ENV}
    preload = [*dask.config.get("distributed.worker.preload", []), "ipfit.batch._worker"]
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                          "distributed.worker.preload": preload,
                          "distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}):
        with _sigint_ignored():
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


def connect_timeout() -> float:
    """:data:`CONNECT_TIMEOUT`, or ``IPFIT_BATCH_CONNECT_TIMEOUT`` seconds when set."""
    text = os.environ.get("IPFIT_BATCH_CONNECT_TIMEOUT")
    if not text:
        return CONNECT_TIMEOUT
    try:
        value = float(text)
        if not 0 < value < float("inf"):
            raise ValueError
    except ValueError:
        raise InvalidInputError(f"IPFIT_BATCH_CONNECT_TIMEOUT: expected a number of seconds > 0, got {text!r}. "
                                "Fix or unset that environment variable.") from None
    return value


async def _identity(address: str, timeout: float) -> Any:
    from distributed.comm import connect
    from distributed.security import Security

    comm = await connect(address, timeout=timeout, **Security().get_connection_args("client"))
    try:
        await comm.write({"op": "identity"})
        return await comm.read()
    finally:
        comm.abort()


def _probe(address: str, timeout: float) -> None:
    """Ask the scheduler who it is, with a hard deadline: ``Client()`` waits forever on a server
    that accepts the connection and never answers."""
    def ask():
        return asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))

    try:
        with ThreadPoolExecutor(1) as pool:  # its own thread: the caller may be inside an event loop (Jupyter)
            reply = pool.submit(ask).result()
    except (TimeoutError, OSError, ValueError, TypeError) as exc:
        reason = f"no answer within {timeout:g} s" if isinstance(exc, asyncio.TimeoutError) else _one_line(exc)
        raise InvalidInputError(f"--scheduler: cannot connect to {address} ({reason}). "
                                "Check the address and that the scheduler is running.") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise InvalidInputError(f"--scheduler: {address} did not answer as a Dask scheduler. "
                                "Check the address (the scheduler's, usually port 8786).")


@contextlib.contextmanager
def _client_for(client, workers: int | None, scheduler: str | None) -> Iterator[Any]:
    if client is not None:
        yield client
    elif scheduler is not None:
        from distributed import Client

        timeout = connect_timeout()
        _probe(scheduler, timeout)
        try:
            connected = Client(scheduler, timeout=f"{timeout}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InvalidInputError(f"--scheduler: cannot connect to {scheduler} ({_one_line(exc)}). "
                                    "Check the address and that the scheduler is running.") from None
        try:
            yield connected
        finally:
            connected.close()
    else:
        with local_cluster(workers or 2) as embedded:
            yield embedded

"""The Dask cluster of a batch: an embedded LocalCluster, or the caller's client or scheduler."""

from __future__ import annotations

import contextlib
import logging
from typing import Any, Iterator

from .._validation import check_int
from ..exceptions import InvalidInputError
from ._shapes import _one_line

#: Set in every embedded worker: one BLAS / OpenMP / numba thread per worker process.
THREAD_ENV = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                     "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}


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

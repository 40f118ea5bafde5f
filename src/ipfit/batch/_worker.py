"""Preloaded in every embedded worker process (``distributed.worker.preload``).

Ctrl-C in a terminal signals the whole process group; the batch process handles it and
stops the workers, so a worker ignores SIGINT instead of dying with a traceback. Until this
runs, a worker has SIGINT blocked (inherited from the batch process, which blocks it while
it starts the cluster; the cluster's own threads keep that mask, so a replacement worker
inherits it too): a Ctrl-C meanwhile stays pending, and ignoring the signal discards it.
"""

import signal
import threading


def dask_setup(worker) -> None:  # worker unused: the preload hook's signature
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)

"""Preloaded in every embedded worker process (``distributed.worker.preload``).

Ctrl-C in a terminal signals the whole process group; the batch process handles it and
stops the workers, so a worker ignores SIGINT instead of dying with a traceback. The first
workers inherit that from the batch process (which ignores SIGINT while it starts the
cluster); this covers one started later to replace a worker that died.
"""

import signal
import threading


def dask_setup(worker) -> None:  # worker unused: the preload hook's signature
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)

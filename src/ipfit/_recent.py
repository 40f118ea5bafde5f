"""The last few results of a costly computation on the same data: one small, thread-safe cache.

An adaptive fit builds the same far-field samples, point spacing and zero-set measurement again
and again (every degree, every repair round); keying them by the data's content lets each be
computed once per fit without callers passing handles around.
"""

from __future__ import annotations

import threading
import weakref
from typing import Any, Callable, Hashable

import numpy as np

__all__ = ["Recent", "array_key", "forget_all"]

_INSTANCES: "weakref.WeakSet[Recent]" = weakref.WeakSet()


def forget_all() -> None:
    """Empty every :class:`Recent` cache, so that the next fit computes everything again (a
    benchmark timing fits one after the other on the same data wants each one cold)."""
    for cache in list(_INSTANCES):
        cache.clear()


def array_key(a: np.ndarray) -> tuple:
    """A hashable stand-in for an array's content (shape, dtype and a hash of its bytes)."""
    a = np.ascontiguousarray(a)
    return a.shape, a.dtype.str, hash(a.tobytes())


class Recent:
    """The results of the last ``size`` distinct keys computed (the earliest dropped first).

    >>> computed = []
    >>> cache = Recent(2)
    >>> [cache.get(k, lambda k=k: computed.append(k) or k * 10) for k in (1, 2, 1, 3, 1)]
    [10, 20, 10, 30, 10]
    >>> computed  # 1 was stored again after 3 pushed it out
    [1, 2, 3, 1]
    >>> forget_all(); cache.get(1, lambda: 11)  # every cache emptied: computed again
    11
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self._items: dict = {}
        self._lock = threading.Lock()  # fits may run from several threads
        _INSTANCES.add(self)

    def clear(self) -> None:
        """Forget every stored result."""
        with self._lock:
            self._items.clear()

    def get(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """The stored result for ``key``, or ``compute()`` stored under it (computed unlocked)."""
        with self._lock:
            if key in self._items:
                return self._items[key]
        value = compute()
        with self._lock:
            while len(self._items) >= self.size:
                self._items.pop(next(iter(self._items)))
            self._items[key] = value
        return value

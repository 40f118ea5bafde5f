"""Small numeric kernels shared across the package: one copy of each.

Zero-length rows
----------------
:func:`unit_rows` is the only place that scales vectors to unit length. A row of zeros (or one
whose length is not finite) has no direction: it comes back as zeros and is flagged in the
returned mask, so each caller decides what a missing direction means (a reader warns, the
optimisers keep the zero row, the measures ignore it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["row_norms", "unit_rows", "unit_rows_mask"]


def row_norms(v: ArrayLike) -> NDArray[np.float64]:
    """Euclidean length of every row (last axis), without overflow or underflow.

    Each row is divided by its largest absolute entry before squaring, so coordinates of
    1e200 or 1e-200 give their true length instead of inf or 0.

    >>> row_norms([[3e200, 4e200], [3e-200, 4e-200], [0.0, 0.0]])
    array([5.e+200, 5.e-200, 0.e+000])
    """
    a = np.asarray(v, dtype=np.float64)
    big = np.max(np.abs(a), axis=-1, keepdims=True)
    safe = np.where((big > 0) & np.isfinite(big), big, 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.sqrt(np.sum((a / safe) ** 2, axis=-1)) * safe[..., 0]


def unit_rows_mask(v: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Rows scaled to unit length, and a mask of the rows that had a direction.

    Rows of zeros, or with a non-finite entry, come back as zeros with mask False.

    >>> u, ok = unit_rows_mask([[3.0, 4.0], [0.0, 0.0]])
    >>> u, ok
    (array([[0.6, 0.8],
           [0. , 0. ]]), array([ True, False]))
    """
    a = np.asarray(v, dtype=np.float64)
    length = row_norms(a)
    ok = (length > 0) & np.isfinite(length) & np.all(np.isfinite(a), axis=-1)
    out = np.zeros(a.shape)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        # scaled by the largest entry first, so subnormal rows (1e-310) keep unit length too
        scaled = a[ok] / np.max(np.abs(a[ok]), axis=-1, keepdims=True)
        out[ok] = scaled / np.sqrt(np.sum(scaled * scaled, axis=-1, keepdims=True))
    return out, ok


def unit_rows(v: ArrayLike) -> NDArray[np.float64]:
    """Rows scaled to unit length; rows without a direction stay zero (see the module notes).

    The hot loops of the optimisers call this on every generation, so for finite,
    moderately sized input it is a plain division.

    >>> unit_rows([[0.0, 2.0], [0.0, 0.0]])
    array([[0., 1.],
           [0., 0.]])
    """
    a = np.asarray(v, dtype=np.float64)
    length = np.linalg.norm(a, axis=-1, keepdims=True)
    if np.all(np.isfinite(length)) and (length.size == 0 or length.max() < 1e150):
        return a / np.where(length > 0, length, 1.0)
    return unit_rows_mask(a)[0]

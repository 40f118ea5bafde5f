"""Compiled kernel of :mod:`ipfit.basis`, imported lazily.

Kept apart from :mod:`ipfit.basis` so that ``import ipfit`` does not pay numba's import time;
the first population gradient (:func:`ipfit.basis.gradient_coefficients`) loads (and caches) it.
It sits beside the basis, below every layer that uses the basis, with the compile settings of
:mod:`ipfit.fitting._objective_kernels`.
"""

from __future__ import annotations

from typing import Any

from numba import njit

# The settings of ipfit.fitting._objective_kernels: error_model="numpy" lets LLVM vectorise
# (no per-element zero checks).
_JIT: dict[str, Any] = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)


@njit(**_JIT)
def gather_gradients(at, source, factor, out):  # pragma: no cover - compiled
    """``out[i, k·P + p] = factor[k, i] · at[source[k, i], p]``: the coefficients of ∂f/∂x_k of
    every member (:func:`ipfit.basis.gradient_coefficients`), in one pass without temporaries."""
    dim, n_low = source.shape
    n_members = at.shape[1]
    for k in range(dim):
        for i in range(n_low):
            f = factor[k, i]
            row = at[source[k, i]]
            for p in range(n_members):
                out[i, k * n_members + p] = row[p] * f

"""Compiled kernel of :mod:`ipfit.basis`, imported lazily.

Kept apart from :mod:`ipfit.basis` so that ``import ipfit`` does not pay numba's import time;
the first population gradient (:func:`ipfit.basis.gradient_coefficients`) or design matrix
(:func:`ipfit.basis.monomials`) loads (and caches) it.
It sits beside the basis, below every layer that uses the basis, with the compile settings of
:mod:`ipfit.fitting._objective_kernels`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
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


@njit(**_JIT)
def monomial_rows(points, exps, degree, out):  # pragma: no cover - compiled
    """``out[i, k] = Π_j points[i, j] ** exps[k, j]`` (:func:`ipfit.basis.monomials`), a row at a time.

    The same products in the same order as the array version: each power by repeated
    multiplication from 1, then the factors multiplied left to right, so every entry is the
    same to the bit (products only, no fast-math: nothing for the compiler to reassociate or
    fuse); without its (N, dim, g + 1) power table and (N, d) temporaries.
    """
    n, dim = points.shape
    d = exps.shape[0]
    powers = np.empty((dim, degree + 1))
    for i in range(n):
        for j in range(dim):
            x = points[i, j]
            powers[j, 0] = 1.0
            for e in range(1, degree + 1):
                powers[j, e] = powers[j, e - 1] * x
        for k in range(d):
            value = powers[0, exps[k, 0]]
            for j in range(1, dim):
                value = value * powers[j, exps[k, j]]
            out[i, k] = value

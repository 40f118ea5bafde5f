"""Compiled per-point reduction of the paper's objective (Eq. 4), imported lazily.

Kept apart from :mod:`ipfit.objective` so that ``import ipfit`` does not pay numba's import
time; the first :class:`~ipfit.objective.Objective` evaluation loads (and caches) it.

Threading: the kernel itself is serial and releases the GIL (``nogil``); parallelism comes
from :class:`~ipfit.objective.Objective` running blocks of points on its own worker threads,
each with single-threaded BLAS followed by this reduction while the block's products are
still in cache. numba's parallel layers are not used: with OpenBLAS's worker threads spinning
between calls, ``prange`` over the reduction was measured 2-50x slower than a serial loop on a
2-core machine, and the worker-thread design gets both the products and the reduction onto
both cores without either runtime waiting for the other.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# error_model="numpy": division follows IEEE rules instead of raising, which lets LLVM
# vectorise the inner loop (no per-element zero checks).
_JIT = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)


@njit(**_JIT)
def reduce_population(values, grads, normals, tiny, cap, sum_taubin, sum_cosine):  # pragma: no cover - compiled
    """Accumulate Σ_i min(|f|/||∇f||, cap) and Σ_i ∇f·n/||∇f|| for every member p.

    ``values`` is (n, P) = f at n points for P members; ``grads`` is (n, dim·P) with ∂f/∂x_k
    of member p in column k·P + p; ``normals`` is (n, dim) unit vectors. Squared norms are
    clamped below by ``tiny``: where ∇f = 0 the cosine is then exactly 0 (the dot product is 0)
    and the Taubin term is ``cap`` (or 0 when f = 0 too). Sums are accumulated in float64.
    """
    n, P = values.shape
    # Two copies of the loop rather than a branch on dim inside it, so each vectorises.
    if normals.shape[1] == 3:
        for i in range(n):
            n0 = np.float64(normals[i, 0])
            n1 = np.float64(normals[i, 1])
            n2 = np.float64(normals[i, 2])
            for p in range(P):
                gx = np.float64(grads[i, p])
                gy = np.float64(grads[i, P + p])
                gz = np.float64(grads[i, 2 * P + p])
                s = max(gx * gx + gy * gy + gz * gz, tiny)
                inv = 1.0 / np.sqrt(s)
                sum_taubin[p] += min(abs(np.float64(values[i, p])) * inv, cap)
                sum_cosine[p] += (gx * n0 + gy * n1 + gz * n2) * inv
    else:
        for i in range(n):
            n0 = np.float64(normals[i, 0])
            n1 = np.float64(normals[i, 1])
            for p in range(P):
                gx = np.float64(grads[i, p])
                gy = np.float64(grads[i, P + p])
                s = max(gx * gx + gy * gy, tiny)
                inv = 1.0 / np.sqrt(s)
                sum_taubin[p] += min(abs(np.float64(values[i, p])) * inv, cap)
                sum_cosine[p] += (gx * n0 + gy * n1) * inv


@njit(**_JIT)
def reduce_far_field(values, grads, scale, weight, tiny, sum_far):  # pragma: no cover - compiled
    """Accumulate Σ_i w_i · clip(1 − k_i f/||∇f||, 0, 2) for every member p (the far-field term).

    ``values`` (n, P) and ``grads`` (n, dim·P) are laid out as in :func:`reduce_population`;
    ``scale`` (n,) is k_i = sign(t_i)/(ρ|t_i|) and ``weight`` (n,) is w_i (the term's weight
    over its number of samples). Squared norms are clamped below by ``tiny``.
    """
    n, P = values.shape
    z = 2 * P if grads.shape[1] == 3 * P else -1  # column offset of ∂f/∂z, or none (2D)
    for i in range(n):
        k = scale[i]
        w = weight[i]
        for p in range(P):
            gx = np.float64(grads[i, p])
            gy = np.float64(grads[i, P + p])
            # A loop-invariant branch: LLVM unswitches it, so both versions vectorise.
            gz = np.float64(grads[i, z + p]) if z >= 0 else 0.0
            short = 1.0 - k * np.float64(values[i, p]) / np.sqrt(max(gx * gx + gy * gy + gz * gz, tiny))
            sum_far[p] += w * min(max(short, 0.0), 2.0)

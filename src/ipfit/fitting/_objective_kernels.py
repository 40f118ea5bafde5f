"""Compiled per-point reduction of the paper's objective (Eq. 4), imported lazily.

Kept apart from :mod:`ipfit.fitting.objective` so that ``import ipfit`` does not pay numba's import
time; the first :class:`~ipfit.fitting.objective.Objective` evaluation loads (and caches) it.

Threading: the kernel itself is serial and releases the GIL (``nogil``); parallelism comes
from :class:`~ipfit.fitting.objective.Objective` running blocks of points on its own worker threads,
each with single-threaded BLAS followed by this reduction while the block's products are
still in cache. numba's parallel layers are not used: with OpenBLAS's worker threads spinning
between calls, ``prange`` over the reduction was measured 2-50x slower than a serial loop on a
2-core machine, and the worker-thread design gets both the products and the reduction onto
both cores without either runtime waiting for the other.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

# error_model="numpy": division follows IEEE rules instead of raising, which lets LLVM
# vectorise the inner loop (no per-element zero checks).
_JIT: dict[str, Any] = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)


@njit(**_JIT)
def reduce_population(values, grads, normals, weights, tiny, cap, sum_taubin,
                      sum_cosine):  # pragma: no cover - compiled
    """Accumulate Σ_i w_i min(|f|/||∇f||, cap) and Σ_i w_i ∇f·n/||∇f|| for every member p.

    ``values`` is (n, P) = f at n points for P members; ``grads`` is (n, dim·P) with ∂f/∂x_k
    of member p in column k·P + p; ``normals`` is (n, dim) unit vectors, ``weights`` (n,) the
    points' weights (ones: the plain sums, to the bit). Squared norms are clamped below by
    ``tiny``: where ∇f = 0 the cosine is then exactly 0 (the dot product is 0) and the Taubin
    term is ``cap`` (or 0 when f = 0 too). Sums are accumulated in float64.
    """
    n, P = values.shape
    # Two copies of the loop rather than a branch on dim inside it, so each vectorises.
    if normals.shape[1] == 3:
        for i in range(n):
            n0 = np.float64(normals[i, 0])
            n1 = np.float64(normals[i, 1])
            n2 = np.float64(normals[i, 2])
            w = np.float64(weights[i])
            for p in range(P):
                gx = np.float64(grads[i, p])
                gy = np.float64(grads[i, P + p])
                gz = np.float64(grads[i, 2 * P + p])
                s = max(gx * gx + gy * gy + gz * gz, tiny)
                inv = 1.0 / np.sqrt(s)
                sum_taubin[p] += w * min(abs(np.float64(values[i, p])) * inv, cap)
                sum_cosine[p] += w * ((gx * n0 + gy * n1 + gz * n2) * inv)
    else:
        for i in range(n):
            n0 = np.float64(normals[i, 0])
            n1 = np.float64(normals[i, 1])
            w = np.float64(weights[i])
            for p in range(P):
                gx = np.float64(grads[i, p])
                gy = np.float64(grads[i, P + p])
                s = max(gx * gx + gy * gy, tiny)
                inv = 1.0 / np.sqrt(s)
                sum_taubin[p] += w * min(abs(np.float64(values[i, p])) * inv, cap)
                sum_cosine[p] += w * ((gx * n0 + gy * n1) * inv)


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


# Reassociation lets LLVM vectorise the dot products of one row (the polish's pass works on
# one member, so there is no population axis to vectorise over); no other fast-math liberties:
# infinities and NaNs keep their IEEE meaning.
_JIT_DOTS = dict(_JIT, fastmath={"reassoc", "contract"})


@njit(**_JIT_DOTS)
def member_pass(rows, a, source, factor, normals, point_weights, scale, weight, n_data, inv_n, delta, tiny, cap,
                singular, floor, grad):  # pragma: no cover - compiled
    """Value and gradient of one member over stacked rows, in one pass over the design matrix.

    ``rows`` (n, d) is the design matrix M, its first d_{g−1} columns the lower-degree block
    L; rows ``< n_data`` are data points with unit ``normals``, the others far-field samples
    with k_i = ``scale`` and w_i = ``weight`` (indexed from the first far row); the data rows'
    terms are weighted by ``point_weights`` (ones: the plain sums, to the bit). ``a`` (d,) are
    the coefficients; ``source``, ``factor`` are :func:`ipfit.basis.derivative_gather`'s tables,
    giving b_k = D_k a, the coefficients of ∂f/∂x_k, so f = M a and ∂f/∂x_k = L b_k.
    Adds to ``grad`` (d,) the gradient of ``inv_n`` · Σ_data w_i (Taubin + δ(1 − cosine)) +
    Σ_far w_i clip(1 − k_i f/||∇f||, 0, 2) over these rows: Mᵀ c_f plus Σ_k D_kᵀ Lᵀ c_k, c_f
    and c_k being the weights of df and d(∂f/∂x_k) below. Each row is read once and used from
    cache for both directions: four matrix-vector products would stream the matrix from memory
    four times.
    Returns (Σ w Taubin, Σ w cosine, far-field term), the Taubin term min(|f|/||g||, ``cap``).

    Data rows: d|f|/||g|| = sign(f)/||g|| df − |f| gᵀ/||g||³ dg and
    d(g·n/||g||) = (n − cos g/||g||)/||g|| dg. A point whose Taubin term is truncated at ``cap``
    (a robust loss) has no Taubin gradient, its cosine's only; points at ``singular`` (∇f
    vanishes next to f: no gradient is meaningful, :data:`~ipfit.fitting.objective.TAUBIN_CAP`)
    and where ∇f (nearly) vanishes (||g||² ≤ ``floor``) get none, which is unbounded there. Far rows:
    d(1 − k f/||g||) = −k/||g|| df + k f gᵀ/||g||³ dg where 0 < 1 − k f/||g|| < 2, else 0.
    """
    n, d = rows.shape
    dim, n_low = source.shape
    bt = np.empty((dim, n_low))
    for k in range(dim):
        for j in range(n_low):
            bt[k, j] = factor[k, j] * a[source[k, j]]
    low_t_w = np.zeros((dim, n_low))
    g = np.empty(dim)
    coef_g = np.empty(dim)
    sum_t = 0.0
    sum_c = 0.0
    far = 0.0
    for i in range(n):
        r = rows[i]
        f = 0.0
        for j in range(d):
            f += r[j] * a[j]
        sq = 0.0
        for k in range(dim):
            s = 0.0
            for j in range(n_low):
                s += r[j] * bt[k, j]
            g[k] = s
            sq += s * s
        sq = max(sq, tiny)
        inv = 1.0 / np.sqrt(sq)
        coef_f = 0.0
        if i < n_data:
            dot = 0.0
            for k in range(dim):
                dot += g[k] * normals[i, k]
            w = point_weights[i]
            taubin = abs(f) * inv
            capped = taubin >= cap
            if taubin >= singular or sq <= floor:
                sum_t += w * min(taubin, cap)
                sum_c += w * (dot * inv)
                continue
            taubin = min(taubin, cap)
            cosine = dot * inv
            sum_t += w * taubin
            sum_c += w * cosine
            scale_i = inv_n * w
            if capped:  # truncated: constant in f, only the cosine pulls
                coef_f = 0.0
                along = 0.0
            else:
                coef_f = (1.0 if f > 0 else (-1.0 if f < 0 else 0.0)) * inv * scale_i
                along = taubin * inv * inv
            for k in range(dim):
                coef_g[k] = (-along * g[k] - delta * (normals[i, k] - cosine * inv * g[k]) * inv) * scale_i
        else:
            j = i - n_data
            ratio = scale[j] * f * inv
            short = 1.0 - ratio
            far += weight[j] * min(max(short, 0.0), 2.0)
            if not 0.0 < short < 2.0:
                continue
            coef_f = -weight[j] * scale[j] * inv
            for k in range(dim):
                coef_g[k] = weight[j] * ratio * inv * inv * g[k]
        for j in range(d):
            grad[j] += coef_f * r[j]
        for k in range(dim):
            c = coef_g[k]
            for j in range(n_low):
                low_t_w[k, j] += c * r[j]
    for k in range(dim):  # the adjoint of the gather: the chain rule through ∂f/∂x_k = L D_k a
        for j in range(n_low):
            grad[source[k, j]] += factor[k, j] * low_t_w[k, j]
    return sum_t, sum_c, far

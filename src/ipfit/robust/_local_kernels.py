"""The compiled local quadric fits of :func:`ipfit.robust.local.fit_local`.

numpy's version ran each step (the frame's PCA, the pick along the tangent, three weighted
least-squares solves) as batched array operations over blocks of queries: every step wrote and
read arrays of (queries × 4k × D) elements, and the 3×3 ``eigh`` and 6×6 ``solve`` calls cost
more in their batching than in their arithmetic (a million-point cloud's score took 14 s,
a third of its fit). Here one query's frame stays in a few small buffers from the neighbours'
gather to its residual.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..normals._scale_kernels import jacobi_eigen

# Tukey's consistency factor: the MAD of Gaussian residuals times this is their σ.
_MAD_TO_SIGMA = 1.4826
# Added to the normal equations' diagonal: the tangent coordinates are scaled into [-1, 1].
_RIDGE = 1e-9


@njit(cache=True, nogil=True, boundscheck=False)
def quadric_frames(ref, query, dist, wide, k, tukey, steps, leverage_cap,
                   residual, offset, extent, chosen):  # pragma: no cover - compiled
    """The local quadric of each query (row of ``wide``), its outputs written in place.

    ``dist``/``wide`` (n, W): each query's frame neighbourhood, nearest first (``inf`` distance =
    not in the frame; the first k are always in it). The frame is the PCA of the points in it
    about their centroid; of those, the k nearest along the tangent are fitted by a quadric
    height function over the tangent coordinates (scaled by the farthest), by ``steps`` rounds
    of Tukey-weighted least squares (MAD scale, constant ``tukey``) and a last weighted solve.
    Outputs per query: ``residual`` |h(0)| / sqrt(1 + min(leverage, ``leverage_cap``)),
    ``offset`` the distance of the k points' tangent centroid from the query in units of their
    RMS spread ``extent``, and ``chosen`` their indices.
    """
    n, width = wide.shape
    d = ref.shape[1]
    p = 3 if d == 2 else 6
    rel = np.empty((width, d))
    inside = np.empty(width, dtype=np.bool_)
    centre = np.empty(d)
    cov = np.empty((d, d))
    vec = np.empty((d, d))
    values = np.empty(d)
    tangents = np.empty(d - 1, dtype=np.int64)
    u = np.empty((width, d - 1))
    h = np.empty(width)
    along = np.empty(width)
    design = np.empty((k, p))
    height = np.empty(k)
    weight = np.empty(k)
    misfit = np.empty(k)
    system = np.empty((p, p + 2))
    solution = np.empty((p, 2))
    mean = np.empty(d - 1)
    for i in range(n):
        count = 0
        centre[:] = 0.0
        for j in range(width):
            inside[j] = np.isfinite(dist[i, j])
            for a in range(d):
                rel[j, a] = ref[wide[i, j], a] - query[i, a]
            if inside[j]:
                count += 1
                for a in range(d):
                    centre[a] += rel[j, a]
        for a in range(d):
            centre[a] /= count
        cov[:, :] = 0.0
        for j in range(width):
            if inside[j]:
                for a in range(d):
                    for c in range(a, d):
                        cov[a, c] += (rel[j, a] - centre[a]) * (rel[j, c] - centre[c])
        for a in range(d):
            for c in range(a):
                cov[a, c] = cov[c, a]
        jacobi_eigen(cov, vec, values)
        normal = 0
        for a in range(1, d):
            if values[a] < values[normal]:
                normal = a
        m = 0
        for a in range(d):
            if a != normal:
                tangents[m] = a
                m += 1
        for j in range(width):
            s = 0.0
            for a in range(d):
                s += rel[j, a] * vec[a, normal]
            h[j] = s
            total = 0.0
            for t in range(d - 1):
                s = 0.0
                for a in range(d):
                    s += rel[j, a] * vec[a, tangents[t]]
                u[j, t] = s
                total += s * s
            along[j] = total if inside[j] else np.inf
        pick = np.argsort(along, kind="mergesort")[:k] if width > k else np.arange(k)
        size = 0.0
        for q in range(k):
            if along[pick[q]] > size:
                size = along[pick[q]]
        size = np.sqrt(size) if size > 0.0 else 1.0
        for q in range(k):
            j = pick[q]
            chosen[i, q] = wide[i, j]
            height[q] = h[j]
            x = u[j, 0] / size
            design[q, 0] = 1.0
            design[q, 1] = x
            if d == 2:
                design[q, 2] = x * x
            else:
                y = u[j, 1] / size
                design[q, 2] = y
                design[q, 3] = x * x
                design[q, 4] = x * y
                design[q, 5] = y * y
        weight[:] = 1.0
        top = 0.0
        for q in range(k):
            top = max(top, abs(height[q]))
        floor = 1e-12 * top + 1e-300  # exact data: keep every point
        for _ in range(steps):
            _weighted_solve(design, height, weight, system, solution, False)
            for q in range(k):
                s = 0.0
                for c in range(p):
                    s += design[q, c] * solution[c, 0]
                misfit[q] = height[q] - s
            scale = _MAD_TO_SIGMA * np.median(np.abs(misfit))
            cut = tukey * max(scale, floor)
            for q in range(k):
                t = misfit[q] / cut
                weight[q] = (1.0 - t * t) ** 2 if abs(t) < 1.0 else 0.0
        _weighted_solve(design, height, weight, system, solution, True)
        residual[i] = abs(solution[0, 0]) / np.sqrt(1.0 + min(solution[0, 1], leverage_cap))
        mean[:] = 0.0
        for q in range(k):
            for t in range(d - 1):
                mean[t] += u[pick[q], t]
        for t in range(d - 1):
            mean[t] /= k
        spread = 0.0
        for q in range(k):
            for t in range(d - 1):
                spread += (u[pick[q], t] - mean[t]) ** 2
        rms = np.sqrt(spread / k)
        extent[i] = rms
        far = 0.0
        for t in range(d - 1):
            far += mean[t] * mean[t]
        offset[i] = np.sqrt(far) / rms if rms > 0.0 else 0.0


@njit(cache=True, nogil=True, boundscheck=False)
def _weighted_solve(design, height, weight, system, solution, leverage):  # pragma: no cover - compiled
    """Solve (Xᵀ W X + ridge I) β = Xᵀ W h into ``solution[:, 0]``; with ``leverage`` also
    (Xᵀ W X + ridge I) e = e₀ into ``solution[:, 1]`` (its first entry is the leverage of a
    unit-weight point at u = 0). Gaussian elimination with partial pivoting, as LAPACK's gesv."""
    k, p = design.shape
    rhs = 2 if leverage else 1
    for a in range(p):
        for c in range(p):
            s = 0.0
            for q in range(k):
                s += design[q, a] * weight[q] * design[q, c]
            system[a, c] = s + (_RIDGE if a == c else 0.0)
        s = 0.0
        for q in range(k):
            s += design[q, a] * weight[q] * height[q]
        system[a, p] = s
        system[a, p + 1] = 1.0 if a == 0 else 0.0
    for col in range(p):
        best = col
        for r in range(col + 1, p):
            if abs(system[r, col]) > abs(system[best, col]):
                best = r
        if best != col:
            for c in range(p + rhs):
                system[col, c], system[best, c] = system[best, c], system[col, c]
        pivot = system[col, col]
        for r in range(col + 1, p):
            factor = system[r, col] / pivot
            if factor != 0.0:
                for c in range(col, p + rhs):
                    system[r, c] -= factor * system[col, c]
    for e in range(rhs):
        for r in range(p - 1, -1, -1):
            s = system[r, p + e]
            for c in range(r + 1, p):
                s -= system[r, c] * solution[c, e]
            solution[r, e] = s / system[r, r]

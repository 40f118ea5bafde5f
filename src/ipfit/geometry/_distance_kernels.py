"""Compiled exact point–segment and point–triangle distances for :mod:`ipfit.geometry.distance`, imported lazily.

Kept apart so that ``import ipfit`` does not pay numba's import time. The kernels are serial
(``nogil``, no ``prange``): on a 2-core machine numba's threads fight OpenBLAS's spinning
workers (see :mod:`ipfit.fitting._objective_kernels`), and one pass over a few hundred thousand
candidates takes tens of milliseconds anyway.

The nearest point of a segment is the clamped projection; that of a triangle is the
projection onto its plane when it falls inside, else the nearest point of its three edges
(tests/test_quality_speed.py checks both against trimesh and a numpy brute force).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)


@njit(**_JIT)
def _segment_d2(p, a, b):  # pragma: no cover - compiled
    ab2 = 0.0
    t = 0.0
    for j in range(p.shape[0]):
        ab2 += (b[j] - a[j]) * (b[j] - a[j])
        t += (p[j] - a[j]) * (b[j] - a[j])
    t = min(max(t / ab2, 0.0), 1.0) if ab2 > 0 else 0.0
    out = 0.0
    for j in range(p.shape[0]):
        r = p[j] - a[j] - t * (b[j] - a[j])
        out += r * r
    return out


@njit(**_JIT)
def _triangle_d2(p, a, b, c):  # pragma: no cover - compiled
    e0x, e0y, e0z = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    e1x, e1y, e1z = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    wx, wy, wz = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d20 = wx * e0x + wy * e0y + wz * e0z
    d21 = wx * e1x + wy * e1y + wz * e1z
    denom = d00 * d11 - d01 * d01
    # A (near-)flat triangle is its edges: its barycentric coordinates are all rounding error.
    if denom > 1e-12 * d00 * d11 and denom > 0:
        v = (d11 * d20 - d01 * d21) / denom
        t = (d00 * d21 - d01 * d20) / denom
        if v >= 0 and t >= 0 and v + t <= 1:
            nx = e0y * e1z - e0z * e1y
            ny = e0z * e1x - e0x * e1z
            nz = e0x * e1y - e0y * e1x
            h = wx * nx + wy * ny + wz * nz
            return h * h / denom  # |n|² = denom (Lagrange's identity)
    return min(_segment_d2(p, a, b), _segment_d2(p, b, c), _segment_d2(p, c, a))


@njit(**_JIT)
def nearest_candidates(query, idx, n, elements, a, b, c, upper, triangles):  # pragma: no cover - compiled
    """Distance from each query to the nearest of its candidate elements, capped at ``upper``.

    ``idx`` (m, k) are sample indices sorted by distance (``n`` = no sample within the bound);
    a candidate is the element (segment a–b or triangle a–b–c) a sample lies on, each one
    computed once per query even when several of its samples are among the k.
    """
    m, k = idx.shape
    out = np.empty(m)
    seen = np.full(a.shape[0], -1, dtype=np.int64)  # the last query each element was computed for
    for i in range(m):
        best = upper[i] * upper[i]
        for j in range(k):
            s = idx[i, j]
            if s >= n:
                break
            e = elements[s]
            if seen[e] == i:
                continue
            seen[e] = i
            if triangles:
                d2 = _triangle_d2(query[i], a[e], b[e], c[e])
            else:
                d2 = _segment_d2(query[i], a[e], b[e])
            best = min(best, d2)
        out[i] = np.sqrt(best)
    return out


@njit(**_JIT)
def farthest_points(candidates, reach, first, chosen):  # pragma: no cover - compiled
    """Farthest-point selection with gaps relative to ``reach``: fills ``chosen`` with indices
    into ``candidates``, starting at ``first``; each next pick maximises the smallest
    ||c − chosen|| / reach(c) (the first such index on ties, like ``np.argmax``)."""
    n, dim = candidates.shape
    gap = np.full(n, np.inf)
    pick = first
    for j in range(chosen.shape[0]):
        chosen[j] = pick
        best = -1.0
        following = 0
        for i in range(n):
            s = 0.0
            for k in range(dim):
                t = candidates[i, k] - candidates[pick, k]
                s += t * t
            g = np.sqrt(s) / reach[i]
            if g < gap[i]:
                gap[i] = g
            if gap[i] > best:
                best = gap[i]
                following = i
        pick = following

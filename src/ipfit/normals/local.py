"""Neighbourhoods and their PCA: the building blocks every other normals module uses.

A point's neighbourhood is its k nearest points (itself included, :func:`neighbours`); its
normal is the direction of least spread of those points and its *flatness* says how well a
line or plane fits them (:func:`pca_normals`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._validation import check_int

# Default neighbourhood sizes (the point itself included). A contour is a curve: k points
# reach about k/2 samples to each side. 6 (±2-3 samples) is enough to average the 45° steps of
# pixel-traced contours, and small enough not to round off the tips of coarse polygons (the
# 200-point airplane) nor to reach across thin parts. A surface needs a 2D patch: 12 is about
# the first two rings of neighbours, which averages scanner noise on the bunny and the duck
# while staying inside thin parts (ears, beak); larger k blurs creases.
DEFAULT_K = {2: 6, 3: 12}

_CHUNK = 1 << 15  # points per block of the batched eigen-decomposition: bounds memory
_BLOCK_ELEMENTS = 1 << 19  # and points × neighbours per block, for wide neighbourhoods


def default_k(k, dim: int, n: int) -> int:
    k = DEFAULT_K[dim] if k is None else check_int(k, "k", minimum=dim)
    return int(min(k, n))


def neighbours(points: NDArray, k: int, workers: int) -> NDArray[np.intp]:
    _, idx = cKDTree(points).query(points, k=k, workers=workers)
    return np.asarray(idx, dtype=np.intp).reshape(len(points), k)


def pca_normals(points: NDArray, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Direction of least spread of each neighbourhood (row of ``idx``), and how flat it is."""
    n, dim = len(idx), points.shape[1]
    normals = np.empty((n, dim))
    flatness = np.empty(n)
    chunk = min(_CHUNK, max(1, _BLOCK_ELEMENTS // idx.shape[1]))
    for start in range(0, n, chunk):  # blocks of points, not points: bounds the (B, k, D) copy
        nb = points[idx[start:start + chunk]]
        centred = nb - nb.mean(axis=1, keepdims=True)
        cov = np.matmul(centred.transpose(0, 2, 1), centred)
        # Unit trace: eigh's tolerances and the flatness no longer depend on the data's units.
        trace = np.trace(cov, axis1=1, axis2=2)
        cov /= np.where(trace > 0, trace, 1.0)[:, None, None]
        values, vectors = np.linalg.eigh(cov)  # ascending eigenvalues
        normals[start:start + chunk] = vectors[:, :, 0]
        # Share of the spread along the normal: 0 on a flat patch, 1/D when isotropic.
        flatness[start:start + chunk] = np.clip(1.0 - dim * values[:, 0], 0.0, 1.0)
    return normals, flatness



def argmax_per_group(values: NDArray, labels: NDArray, ngroups: int) -> NDArray[np.intp]:
    order = np.lexsort((values, labels))
    last = np.cumsum(np.bincount(labels, minlength=ngroups)) - 1
    return order[last]


"""Neighbourhoods and their PCA: the building blocks every other normals module uses.

A point's neighbourhood is its k nearest points (itself included, :func:`neighbours`); its
normal is the direction of least spread of those points and its *flatness* says how well a
line or plane fits them (:func:`pca_normals`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import row_norms
from .._utils.validation import check_int, error

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


def check_workers(workers) -> int:
    """Threads for the neighbour search: -1 (all cores) or a positive number."""
    workers = check_int(workers, "workers")
    if workers == 0 or workers < -1:
        raise error("workers", "-1 (all cores) or a positive number of threads", str(workers),
                    "Pass workers=-1 or workers=1, 2, ...")
    return workers


def check_flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise error(name, "True or False", f"{type(value).__name__} {value!r}"[:80])
    return bool(value)


def standardise(points: NDArray) -> NDArray[np.float64]:
    """The points centred and divided by a robust size, so that squares neither overflow nor underflow.

    Normals do not depend on position or scale, but the squared distances of the neighbour
    search and the covariances do: coordinates of 1e155 overflow them, 1e-160 underflow. The
    size is the median distance to the median point (robust to a few far outliers); dividing
    first by a power of two (exact) keeps the subtraction itself from overflowing.

    >>> standardise(np.array([[0.0, 0.0], [1e200, 0.0], [2e200, 0.0]])).tolist()
    [[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]]
    """
    big = float(np.max(np.abs(points), initial=0.0))
    if big == 0.0:
        return points.copy()
    p = points / 2.0 ** np.frexp(big)[1]
    p -= np.median(p, axis=0)
    size = float(np.median(row_norms(p)))
    if not size > 0.0:  # most points coincide: the farthest one sets the size
        size = float(row_norms(p).max())
    # Bounded below, so that a far outlier stays finite (its squares may not: see estimate_normals).
    return p / max(size, 1e-270) if size > 0.0 else p


def neighbours(tree: cKDTree, k: int, workers: int, query: NDArray | None = None) -> NDArray[np.intp]:
    """Indices of the k nearest points of each query point (default: every point of ``tree``).

    Where a distance overflows (a far outlier), the search finds fewer than k: the missing
    ones are the point's nearest found neighbour, so that every row indexes real points.
    """
    query = tree.data if query is None else query
    _, idx = tree.query(query, k=k, workers=workers)
    idx = np.asarray(idx, dtype=np.intp).reshape(len(query), k)
    missing = idx >= tree.n
    if missing.any():
        idx = np.where(missing, idx[:, :1], idx)
    return idx


def covariances(points: NDArray, idx: NDArray[np.intp]) -> NDArray[np.float64]:
    """Covariance of each neighbourhood (row of ``idx``), scaled to unit trace.

    Unit trace: eigh's tolerances and the flatness do not depend on the data's units. Each
    neighbourhood is divided by its own largest offset before squaring, so a far outlier's
    neighbourhood does not overflow.
    """
    nb = points[idx]
    nb -= nb.mean(axis=1, keepdims=True)
    big = np.abs(nb).max(axis=(1, 2))
    nb /= np.where(big > 0, big, 1.0)[:, None, None]
    cov = np.matmul(nb.transpose(0, 2, 1), nb)
    trace = np.trace(cov, axis1=1, axis2=2)
    cov /= np.where(trace > 0, trace, 1.0)[:, None, None]
    return cov


def blocks(n: int, width: int):
    """Slices of at most _CHUNK rows and _BLOCK_ELEMENTS row × width elements: bounded memory."""
    chunk = min(_CHUNK, max(1, _BLOCK_ELEMENTS // max(width, 1)))
    return (slice(start, min(start + chunk, n)) for start in range(0, n, chunk))


def pca_normals(points: NDArray, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Direction of least spread of each neighbourhood (row of ``idx``), and how flat it is."""
    normals, values = pca(points, idx)
    return normals, flatness_of(values)


def pca(points: NDArray, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Direction of least spread of each neighbourhood (row of ``idx``), and the spreads.

    The spreads are the covariance's eigenvalues, ascending, scaled to sum to 1.
    """
    n, dim = len(idx), points.shape[1]
    normals = np.empty((n, dim))
    values = np.empty((n, dim))
    for rows in blocks(n, idx.shape[1]):
        values[rows], vectors = np.linalg.eigh(covariances(points, idx[rows]))  # ascending eigenvalues
        normals[rows] = vectors[:, :, 0]
    return normals, np.clip(values, 0.0, None)


def flatness_of(values: NDArray) -> NDArray[np.float64]:
    """Share of the spread along the normal, turned round: 1 on a flat patch, 0 when isotropic."""
    return np.clip(1.0 - values.shape[1] * values[:, 0], 0.0, 1.0)


def normal_confidence(points: NDArray, idx: NDArray[np.intp], normals: NDArray) -> NDArray[np.float64]:
    """How well each neighbourhood (row of ``idx``) supports its normal line, from 0 to 1.

    1 − (spread along the normal) / (least spread across it): near 1 where the neighbours lie
    on a plane (line in 2D) through the normal's foot, 0 where they spread as much along the
    normal as across it (noise, a crease, a thin part's two sides) or lie on one row in 3D (no
    plane is determined). For the plane fit's own normal it is 1 − λ₁/λ₂ of the covariance.
    """
    n, dim = normals.shape
    confidence = np.empty(n)
    for rows in blocks(n, idx.shape[1]):
        cov = covariances(points, idx[rows])
        nrm = normals[rows]
        nn = nrm[:, :, None] * nrm[:, None, :]
        along = np.einsum("ij,ijk,ik->i", nrm, cov, nrm)
        proj = np.eye(dim) - nn
        # the normal's own direction moved above every spread (trace 1): the least is across it
        across = np.linalg.eigvalsh(proj @ cov @ proj + 2.0 * nn)[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            confidence[rows] = np.where(across > 0, 1.0 - along / across, 0.0)
    return np.clip(np.nan_to_num(confidence), 0.0, 1.0)


def spread(points: NDArray, most: int) -> NDArray[np.intp]:
    """At most ``most`` indices of ``points``, every step-th in coordinate order, ascending.

    Spread over the cloud, and independent of the input order.
    """
    n = len(points)
    if n <= most:
        return np.arange(n)
    return np.sort(np.lexsort(points.T[::-1])[::-(-n // most)])


def argmax_per_group(values: NDArray, labels: NDArray, ngroups: int) -> NDArray[np.intp]:
    order = np.lexsort((values, labels))
    last = np.cumsum(np.bincount(labels, minlength=ngroups)) - 1
    return order[last]


"""Monomial basis of implicit polynomials: exponents, design matrices and derivative maps.

The basis is graded as in the paper (Eq. 1 and Table 1): ``1, x, y, z, x², xy, xz, y², …``;
within one total degree, exponents are in descending lexicographic order. Design matrices
are built from per-axis power tables by gathering columns, never by ``x**e`` per entry.
"""

from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

__all__ = [
    "n_coefficients",
    "degree_from_n_coefficients",
    "exponents",
    "power_table",
    "monomials",
    "derivative_map",
    "derivative_maps",
    "monomials_and_gradients",
]


def n_coefficients(dim: int, degree: int) -> int:
    """Number of monomials of total degree <= ``degree`` in ``dim`` variables: C(degree+dim, dim).

    >>> n_coefficients(2, 4), n_coefficients(3, 6)
    (15, 84)
    """
    return comb(degree + dim, dim)


def degree_from_n_coefficients(dim: int, d: int) -> int:
    """Inverse of :func:`n_coefficients`; raises ``ValueError`` when ``d`` is not such a count."""
    degree = 0
    while n_coefficients(dim, degree) < d:
        degree += 1
    if n_coefficients(dim, degree) != d:
        raise ValueError(f"{d} is not the number of coefficients of a {dim}D polynomial of any degree")
    return degree


@lru_cache(maxsize=64)
def _exponents(dim: int, degree: int) -> NDArray[np.int64]:
    rows: list[tuple[int, ...]] = []

    def compositions(total: int, parts: int):
        if parts == 1:
            yield (total,)
            return
        for first in range(total, -1, -1):
            for rest in compositions(total - first, parts - 1):
                yield (first, *rest)

    for t in range(degree + 1):
        rows.extend(compositions(t, dim))
    out = np.array(rows, dtype=np.int64).reshape(-1, dim)
    out.setflags(write=False)
    return out


def exponents(dim: int, degree: int) -> NDArray[np.int64]:
    """Exponent table (d, dim) in the paper's graded order (read-only).

    >>> exponents(2, 2).tolist()
    [[0, 0], [1, 0], [0, 1], [2, 0], [1, 1], [0, 2]]
    """
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    if degree < 0:
        raise ValueError(f"degree must be >= 0, got {degree}")
    return _exponents(int(dim), int(degree))


def power_table(points: NDArray, degree: int) -> NDArray:
    """Powers ``points[:, j] ** e`` for e = 0..degree as an (N, dim, degree+1) array.

    Built by repeated multiplication, so its cost is N·dim·degree products.
    """
    n, dim = points.shape
    table = np.empty((n, dim, degree + 1), dtype=points.dtype)
    table[:, :, 0] = 1
    for e in range(1, degree + 1):
        np.multiply(table[:, :, e - 1], points, out=table[:, :, e])
    return table


def monomials(points: NDArray, exps: NDArray[np.int64], powers: NDArray | None = None) -> NDArray:
    """Monomial (design) matrix M of shape (N, d): ``M[i, k] = prod_j points[i, j] ** exps[k, j]``."""
    degree = int(exps.max(initial=0))
    if powers is None:
        powers = power_table(points, degree)
    m = powers[:, 0, exps[:, 0]].copy()
    for j in range(1, exps.shape[1]):
        m *= powers[:, j, exps[:, j]]
    return m


@lru_cache(maxsize=128)
def _derivative_map(dim: int, degree: int, axis: int) -> sparse.csr_matrix:
    high = exponents(dim, degree)
    low = exponents(dim, max(degree - 1, 0))
    index = {tuple(e): i for i, e in enumerate(low.tolist())}
    rows, cols, vals = [], [], []
    for k, e in enumerate(high.tolist()):
        if e[axis] == 0:
            continue
        lowered = list(e)
        lowered[axis] -= 1
        rows.append(index[tuple(lowered)])
        cols.append(k)
        vals.append(float(e[axis]))
    mat = sparse.csr_matrix((vals, (rows, cols)), shape=(len(low), len(high)))
    return mat


def derivative_map(dim: int, degree: int, axis: int) -> sparse.csr_matrix:
    """Sparse map D_k (d_{g-1} × d_g) from coefficients to those of ∂f/∂x_axis.

    ``∂f/∂x_k (x) = m_{g-1}(x)ᵀ (D_k a)``, so gradients of many polynomials are products
    with the narrower degree-(g-1) design matrix.
    """
    return _derivative_map(int(dim), int(degree), int(axis))


def derivative_maps(dim: int, degree: int) -> tuple[sparse.csr_matrix, ...]:
    """All ``dim`` derivative maps of :func:`derivative_map`."""
    return tuple(derivative_map(dim, degree, k) for k in range(dim))


def monomials_and_gradients(points: NDArray, degree: int) -> tuple[NDArray, NDArray]:
    """Design matrix M (N, d) and its partial derivatives (dim, N, d) at ``points``.

    ``gradients[k] @ a`` is ∂f/∂x_k at every point for coefficients ``a``.
    """
    dim = points.shape[1]
    exps = exponents(dim, degree)
    powers = power_table(points, degree)
    m = monomials(points, exps, powers)
    low = monomials(points, exponents(dim, max(degree - 1, 0)), powers[:, :, : max(degree, 1)])
    grads = np.empty((dim, *m.shape), dtype=m.dtype)
    for k in range(dim):
        source, factor = _derivative_gather(dim, degree, k)
        np.multiply(low[:, source], factor, out=grads[k])
    return m, grads


@lru_cache(maxsize=128)
def _derivative_gather(dim: int, degree: int, axis: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    # ∂(x^α)/∂x_k = α_k x^(α - e_k): a column gather from the degree-(g-1) matrix, then a scale.
    dmap = derivative_map(dim, degree, axis).tocsc()
    source = np.zeros(dmap.shape[1], dtype=np.int64)
    factor = np.zeros(dmap.shape[1])
    for k in range(dmap.shape[1]):
        start, stop = dmap.indptr[k], dmap.indptr[k + 1]
        if stop > start:
            source[k] = dmap.indices[start]
            factor[k] = dmap.data[start]
    return source, factor

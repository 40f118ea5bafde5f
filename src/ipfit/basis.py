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
    "MAX_DEGREE",
    "n_coefficients",
    "degree_from_n_coefficients",
    "exponents",
    "power_table",
    "monomials",
    "derivative_map",
    "derivative_maps",
    "derivative_gather",
    "gradient_coefficients",
    "add_gradient_adjoint",
    "monomials_and_gradients",
    "point_blocks",
    "blocked_products",
]

#: Highest degree ipfit fits or reads, per dimension: far beyond what the data need (20 in 2D and
#: 12 in 3D by default), low enough that one evaluation of f over a default grid stays in seconds
#: (a degree-20 surface has 1,771 coefficients).
MAX_DEGREE = {2: 30, 3: 20}


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


# Below this many rows the array version's few calls cost less than entering the compiled kernel
# (and a first call would pay numba's import for a handful of points).
_COMPILED_ROWS = 256


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
    """Monomial (design) matrix M of shape (N, d): ``M[i, k] = prod_j points[i, j] ** exps[k, j]``.

    Each power by repeated multiplication, the factors multiplied in axis order; float64 points
    go through a compiled row-at-a-time kernel with the same products (the same bits), a few
    times faster than the array version for big designs.
    """
    degree = int(exps.max(initial=0))
    if powers is None:
        if points.dtype == np.float64 and points.ndim == 2 and len(points) >= _COMPILED_ROWS:
            from ._basis_kernels import monomial_rows

            out = np.empty((len(points), len(exps)))
            monomial_rows(np.ascontiguousarray(points), np.ascontiguousarray(exps, dtype=np.int64), degree, out)
            return out
        powers = power_table(points, degree)
    m = powers[:, 0, exps[:, 0]].copy()
    for j in range(1, exps.shape[1]):
        m *= powers[:, j, exps[:, j]]
    return m


@lru_cache(maxsize=128)
def _gather_tables(dim: int, degree: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    # ∂(x^α)/∂x_k = α_k x^(α − e_k): every degree-(g−1) monomial β is hit by exactly one
    # monomial of degree <= g, β + e_k, with factor β_k + 1. So D_k has one entry per row.
    high = {tuple(e): i for i, e in enumerate(exponents(dim, degree).tolist())}
    low = exponents(dim, max(degree - 1, 0)).tolist() if degree > 0 else []
    source = np.zeros((dim, len(low)), dtype=np.int64)
    factor = np.zeros((dim, len(low)))
    for k in range(dim):
        for i, beta in enumerate(low):
            raised = list(beta)
            raised[k] += 1
            source[k, i] = high[tuple(raised)]
            factor[k, i] = raised[k]
    source.setflags(write=False)
    factor.setflags(write=False)
    return source, factor


def derivative_gather(dim: int, degree: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The derivative maps as gather tables ``source``, ``factor`` of shape (dim, d_{g−1}).

    ``(D_k a)[i] = factor[k, i] * a[source[k, i]]``: the one copy of the derivative kernel,
    used by :func:`gradient_coefficients` (gather), :func:`add_gradient_adjoint` (scatter)
    and :func:`monomials_and_gradients`. The sources of one axis are distinct.

    >>> source, factor = derivative_gather(2, 2)  # basis 1, x, y, x², xy, y²
    >>> source.tolist(), factor.tolist()
    ([[1, 3, 4], [2, 4, 5]], [[1.0, 2.0, 1.0], [1.0, 1.0, 2.0]])
    """
    return _gather_tables(int(dim), int(degree))


def derivative_map(dim: int, degree: int, axis: int) -> sparse.csr_matrix:
    """Sparse map D_k (d_{g-1} × d_g) from coefficients to those of ∂f/∂x_axis.

    ``∂f/∂x_k (x) = m_{g-1}(x)ᵀ (D_k a)``, so gradients of many polynomials are products
    with the narrower degree-(g-1) design matrix.
    """
    source, factor = derivative_gather(dim, degree)
    n_low = source.shape[1]
    return sparse.csr_matrix((factor[axis], source[axis], np.arange(n_low + 1)),
                             shape=(n_low, n_coefficients(dim, degree)))


def derivative_maps(dim: int, degree: int) -> tuple[sparse.csr_matrix, ...]:
    """All ``dim`` derivative maps of :func:`derivative_map`."""
    return tuple(derivative_map(dim, degree, k) for k in range(dim))


def gradient_coefficients(at: NDArray, dim: int, degree: int) -> NDArray:
    """Coefficients of ∂f/∂x_k for a population: (d, P) → (d_{g−1}, dim·P).

    Axis k of member p is column ``k·P + p``, so ``L @ gradient_coefficients(Aᵀ)`` gives all
    partial derivatives of all members in one product with the degree-(g−1) design matrix L.
    Keeps the dtype of ``at``.
    """
    from ._basis_kernels import gather_gradients  # compiled: called once or twice per generation

    source, factor = derivative_gather(dim, degree)
    out = np.empty((source.shape[1], dim * at.shape[1]), dtype=at.dtype)
    gather_gradients(at, source, factor.astype(at.dtype, copy=False), out)
    return out


def add_gradient_adjoint(grad: NDArray[np.float64], low_t_w: NDArray[np.float64], degree: int) -> None:
    """``grad += Σ_k D_kᵀ low_t_w[:, k]`` in place: the adjoint (scatter) of the gather.

    ``low_t_w`` is (d_{g−1}, dim), typically Lᵀ W for per-point weights W on ∇f; the chain
    rule through ∇f = L (D_k a) then lands on the coefficients.
    """
    source, factor = derivative_gather(low_t_w.shape[1], degree)
    for k in range(low_t_w.shape[1]):
        grad[source[k]] += factor[k] * low_t_w[:, k]  # distinct sources: no lost updates


def monomials_and_gradients(points: NDArray, degree: int) -> tuple[NDArray, NDArray]:
    """Design matrix M (N, d) and its partial derivatives (dim, N, d) at ``points``.

    ``gradients[k] @ a`` is ∂f/∂x_k at every point for coefficients ``a``.
    """
    dim = points.shape[1]
    m = monomials(points, exponents(dim, degree))
    n_low = n_coefficients(dim, degree - 1) if degree > 0 else 0
    grads = np.zeros((dim, *m.shape), dtype=m.dtype)
    source, factor = derivative_gather(dim, degree)
    for k in range(dim):
        # The graded order puts every monomial of degree <= g−1 first: L is M's first columns.
        grads[k][:, source[k]] = m[:, :n_low] * factor[k]
    return m, grads


def point_blocks(n_points: int, rows: int):
    """``(start, stop)`` of consecutive blocks of at most ``rows`` points.

    >>> list(point_blocks(5, 2))
    [(0, 2), (2, 4), (4, 5)]
    """
    for start in range(0, n_points, max(int(rows), 1)):
        yield start, min(start + rows, n_points)


def blocked_products(points: NDArray, degree: int, fn, rows: int = 1 << 15):
    """Sum of ``fn(start, stop, M_block)`` over point blocks, never holding all of M.

    For products such as MᵀW or MᵀM on clouds too big for the full N × d matrix: each block's
    design matrix is built, used and dropped. ``fn`` returns an array (or a tuple of arrays).

    >>> pts = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    >>> gram = blocked_products(pts, 1, lambda lo, hi, m: m.T @ m, rows=2)
    >>> bool(np.allclose(gram, monomials(pts, exponents(2, 1)).T @ monomials(pts, exponents(2, 1))))
    True
    """
    exps = exponents(points.shape[1], degree)
    total = None
    for start, stop in point_blocks(points.shape[0], rows):
        part = fn(start, stop, monomials(points[start:stop], exps))
        if total is None:
            total = part
        elif isinstance(part, tuple):
            total = tuple(t + p for t, p in zip(total, part, strict=True))
        else:
            total = total + part
    return total

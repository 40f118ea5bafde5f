"""Rotation-, translation- and scale-invariant descriptors of implicit polynomials.

Recognition was the motivation of implicit polynomial fitting: two fits of the same object
under different poses should give the same descriptor. Here the descriptor of f is built in
three steps, each covariant with similarity transforms so the result is invariant:

1. **Centre.** The point x₀ minimising the Bombieri norm of the degree-(g−1) part of
   f(x + x₀): that part is p_{g−1} + Σ_j x₀_j ∂_j p_g, linear in x₀, so x₀ is a weighted
   least-squares solution. The Bombieri norm ‖h‖² = Σ_α a_α² α!/m! is invariant under
   rotations, hence x₀ moves with the shape (Taubin and Cooper's centring idea).
2. **Rotation invariants.** Each homogeneous part h_m of f(x + x₀) splits into harmonic
   components of orders l = m, m−2, …; their energies E_{m,l} on the unit circle/sphere are
   rotation invariant. They are computed exactly by quadrature with the addition theorem:
   E_l = c_l ∬ h(x) h(y) K_l(x·y), with K_l the Chebyshev (2D) or Legendre (3D) polynomial.
3. **Scale and factor.** f(x/σ) multiplies h_m by σ^{−m}, and f is defined up to a factor.
   With N_m the L2 norm of h_m on the sphere and ρ = (N_0/N_g)^{1/g}, the descriptor entries
   √E_{m,l} ρ^m / N_0 (m = 1..g) are free of both.

:func:`similarity` builds the exactly moved copy of a polynomial (the rotation is expanded
algebraically; translation and scale go into its normalisation), which the tests use.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from functools import lru_cache
from math import factorial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import eval_chebyt, eval_legendre

from .. import basis
from .._utils.validation import check_positive, error
from ..polynomial import ImplicitPolynomial, Normalization

__all__ = ["compose_linear", "similarity", "invariants", "descriptors", "invariant_center"]


def _to_tensor(coef: NDArray, exps: NDArray, degree: int) -> NDArray:
    t = np.zeros((degree + 1,) * exps.shape[1])
    t[tuple(exps.T)] = coef
    return t


def compose_linear(poly: ImplicitPolynomial, matrix: ArrayLike, offset: ArrayLike | None = None) -> ImplicitPolynomial:
    """The polynomial u ↦ p(M u + v) in the same normalised variables, expanded exactly.

    Each monomial of ``M u + v`` is the product of a lower monomial with one linear form, a
    small n-dimensional convolution of coefficient tensors; no fitting or sampling.

    >>> from ipfit.datasets.synthetic import from_terms
    >>> p = from_terms(2, 2, {(2, 0): 1.0, (0, 0): -1.0})          # x² − 1
    >>> q = compose_linear(p, [[0.0, 1.0], [1.0, 0.0]], [1.0, 0.0])  # (y + 1)² − 1
    >>> q.coefficients.tolist()
    [0.0, 0.0, 2.0, 0.0, 0.0, 1.0]
    """
    dim, degree = poly.dim, poly.degree
    m = np.asarray(matrix, dtype=np.float64)
    v = np.zeros(dim) if offset is None else np.asarray(offset, dtype=np.float64)
    if m.shape != (dim, dim) or not np.all(np.isfinite(m)):
        raise error("matrix", f"a finite ({dim}, {dim}) array", f"shape {m.shape}")
    if v.shape != (dim,) or not np.all(np.isfinite(v)):
        raise error("offset", f"a finite vector of length {dim}", f"shape {v.shape}")
    forms = []
    for j in range(dim):
        form = np.zeros((2,) * dim)
        form[(0,) * dim] = v[j]
        for k in range(dim):
            form[tuple(1 if i == k else 0 for i in range(dim))] = m[j, k]
        forms.append(form)
    exps = poly.exponents
    from scipy import signal  # scipy.signal is slow to import: only here

    from .rays import _parents  # the same "monomial = parent × one variable" table

    parent, axis = _parents(dim, degree)
    trim = (slice(0, degree + 1),) * dim
    products = [np.zeros((degree + 1,) * dim) for _ in range(len(exps))]
    products[0][(0,) * dim] = 1.0
    total = poly.coefficients[0] * products[0]
    for k in range(1, len(exps)):
        products[k] = signal.convolve(products[parent[k]], forms[axis[k]], method="direct")[trim]
        total = total + poly.coefficients[k] * products[k]
    return poly.with_coefficients(total[tuple(exps.T)])


def similarity(poly: ImplicitPolynomial, rotation: ArrayLike | None = None, translation: ArrayLike | None = None,
               scale: float = 1.0) -> ImplicitPolynomial:
    """The polynomial whose zero set is that of ``poly`` moved by x ↦ scale · R x + t.

    The new polynomial is g(x) = f(Rᵀ(x − t) / scale): the rotation is expanded exactly with
    :func:`compose_linear`, translation and scale are folded into the normalisation.

    >>> from ipfit.datasets.synthetic import circle
    >>> moved = similarity(circle().polynomial, translation=[3.0, 0.0], scale=2.0)
    >>> moved([[5.0, 0.0], [3.0, 2.0]]).round(12).tolist()
    [0.0, 0.0]
    """
    dim = poly.dim
    r = np.eye(dim) if rotation is None else np.asarray(rotation, dtype=np.float64)
    if r.shape != (dim, dim) or not np.allclose(r @ r.T, np.eye(dim), atol=1e-12):
        raise error("rotation", f"an orthogonal ({dim}, {dim}) matrix", f"{r.tolist()}",
                    "Pass a rotation matrix (e.g. scipy.spatial.transform.Rotation(...).as_matrix()).")
    t = np.zeros(dim) if translation is None else np.asarray(translation, dtype=np.float64).reshape(dim)
    scale = check_positive(scale, "scale")
    rotated = compose_linear(poly, r.T)
    norm = poly.normalization
    return rotated.with_coefficients(rotated.coefficients,
                                     normalization=Normalization(t + scale * r @ norm.center, scale * norm.scale))


def _bombieri_weights(exps: NDArray) -> NDArray[np.float64]:
    m = exps.sum(axis=1)
    return np.array([np.prod([factorial(a) for a in e]) / factorial(k) for e, k in zip(exps.tolist(), m, strict=True)])


def invariant_center(poly: ImplicitPolynomial) -> NDArray[np.float64]:
    """Centre x₀ of step 1 of the module notes, in user coordinates (moves with the shape).

    >>> from ipfit.datasets.synthetic import torus
    >>> from ipfit.analysis.invariants import similarity
    >>> invariant_center(similarity(torus().polynomial, translation=[1.0, 2.0, 3.0])).round(9).tolist()
    [1.0, 2.0, 3.0]
    """
    g, dim = poly.degree, poly.dim
    if g < 2:
        raise error("poly", "a polynomial of degree >= 2", f"degree {g}")
    exps, coef = poly.exponents, poly.coefficients
    top = np.where(exps.sum(axis=1) == g, coef, 0.0)
    rows = basis.exponents(dim, g - 1).sum(axis=1) == g - 1
    derivs = np.column_stack([(dmap @ top)[rows] for dmap in basis.derivative_maps(dim, g)])
    below = coef[exps.sum(axis=1) == g - 1]
    w = np.sqrt(_bombieri_weights(basis.exponents(dim, g - 1)[rows]))
    u0 = np.linalg.lstsq(derivs * w[:, None], -below * w, rcond=None)[0]
    return poly.normalization.invert(u0)


@lru_cache(maxsize=16)
def _sphere_rule(dim: int, degree: int) -> tuple[NDArray, NDArray]:
    # Nodes and weights integrating polynomials of degree <= 2·degree exactly on the sphere.
    n_phi = 2 * degree + 2
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    if dim == 2:
        return np.column_stack([np.cos(phi), np.sin(phi)]), np.full(n_phi, 2 * np.pi / n_phi)
    z, wz = np.polynomial.legendre.leggauss(degree + 1)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1 - zz**2)
    nodes = np.column_stack([(r * np.cos(pp)).ravel(), (r * np.sin(pp)).ravel(), zz.ravel()])
    weights = (wz[:, None] * np.full(n_phi, 2 * np.pi / n_phi)[None, :]).ravel()
    return nodes, weights


def _harmonic_energies(values: NDArray, nodes: NDArray, weights: NDArray, orders: Iterable[int]) -> list[float]:
    dim = nodes.shape[1]
    cosines = np.clip(nodes @ nodes.T, -1.0, 1.0)
    wv = weights * values
    out = []
    for order in orders:
        if dim == 2:
            kernel, c = eval_chebyt(order, cosines), (1.0 if order else 0.5) / np.pi
        else:
            kernel, c = eval_legendre(order, cosines), (2 * order + 1) / (4 * np.pi)
        out.append(max(float(c * wv @ kernel @ wv), 0.0))
    return out


def invariants(poly: ImplicitPolynomial) -> NDArray[np.float64]:
    """The invariant descriptor of one polynomial (see the module notes for the definition).

    Entries are ordered by degree m = 1..g and, within a degree, by harmonic order
    l = m, m−2, …; the length depends only on the dimension and degree.

    >>> from ipfit.datasets.synthetic import ellipse
    >>> from ipfit.analysis.invariants import similarity
    >>> a = invariants(ellipse(a=2.0, b=1.0).polynomial)
    >>> b = invariants(similarity(ellipse(a=2.0, b=1.0).polynomial, [[0.6, -0.8], [0.8, 0.6]], [5.0, 1.0], 3.0))
    >>> bool(np.allclose(a, b, rtol=1e-9, atol=1e-12)), a.shape
    (True, (3,))
    """
    if not isinstance(poly, ImplicitPolynomial):
        raise error("poly", "an ImplicitPolynomial", type(poly).__name__)
    g, dim = poly.degree, poly.dim
    centre = poly.normalization.apply(invariant_center(poly)[None, :])[0]
    centred = compose_linear(poly, np.eye(dim), centre)
    nodes, weights = _sphere_rule(dim, g)
    mono = basis.monomials(nodes, poly.exponents)
    degree_of = poly.exponents.sum(axis=1)
    energies = {}
    for m in range(g + 1):
        values = mono[:, degree_of == m] @ centred.coefficients[degree_of == m]
        energies[m] = _harmonic_energies(values, nodes, weights, range(m, -1, -2))
    norms = {m: np.sqrt(sum(e)) for m, e in energies.items()}
    if not (norms[0] > 0 and norms[g] > 0):
        raise error("poly", "a polynomial with f(centre) != 0 and a non-zero top-degree part",
                    "a degenerate polynomial", "Invariants need a bounded shape around its centre.")
    rho = (norms[0] / norms[g]) ** (1.0 / g)
    return np.array([np.sqrt(e) * rho**m / norms[0] for m in range(1, g + 1) for e in energies[m]])


def descriptors(results) -> NDArray[np.float64]:
    """Invariant descriptors of a collection of fits, one row each.

    Parameters
    ----------
    results : iterable of :class:`~ipfit.ImplicitPolynomial`, result dicts or paths to
        result JSON files, all of the same dimension and degree.

    Returns
    -------
    (K, n) array of :func:`invariants`; compare rows with a distance on ``log`` values.

    >>> from ipfit.datasets.synthetic import circle, ellipse
    >>> descriptors([circle().polynomial, ellipse().polynomial]).shape
    (2, 3)
    """
    rows = []
    for k, item in enumerate(results):
        if isinstance(item, (str, os.PathLike)):
            item = ImplicitPolynomial.load(item)
        elif isinstance(item, dict):
            item = ImplicitPolynomial.from_dict(item, source=f"results[{k}]")
        rows.append(invariants(item))
    if not rows:
        raise error("results", "at least one fit", "an empty collection")
    if len({r.shape for r in rows}) > 1:
        raise error("results", "fits of one dimension and degree", "mixed ones",
                    "Fit every shape at the same degree to compare descriptors.")
    return np.vstack(rows)

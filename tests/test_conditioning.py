"""High degrees in the monomial basis: the stored coefficients evaluate as exact arithmetic does,
and the basis the search moves in stays orthonormal where the monomial one is singular
(docs/conditioning.md measures both on fitted shapes)."""

from __future__ import annotations

from fractions import Fraction
from math import comb

import numpy as np
import pytest

from ipfit import ImplicitPolynomial, basis
from ipfit.fitting.objective import Objective
from ipfit.fitting.refine import _whitening


def _ring_power(power: int) -> ImplicitPolynomial:
    """(x² + y² − 1)^power expanded into the graded monomial basis: integer coefficients up to
    C(power, power/2) · …, whose sum cancels to nearly nothing on the unit circle."""
    exps = basis.exponents(2, 2 * power)
    index = {tuple(e): k for k, e in enumerate(exps)}
    coefficients = np.zeros(len(exps))
    for i in range(power + 1):  # (x² + y²)^i (−1)^(power − i)
        for j in range(i + 1):
            coefficients[index[(2 * j, 2 * (i - j))]] += comb(power, i) * comb(i, j) * (-1) ** (power - i)
    return ImplicitPolynomial.from_coefficients(coefficients, dim=2)


def _exact(poly: ImplicitPolynomial, u: np.ndarray) -> list[Fraction]:
    exps = basis.exponents(poly.dim, poly.degree)
    coefficients = [Fraction(float(c)) for c in poly.coefficients]
    out = []
    for row in u:
        x = [Fraction(float(v)) for v in row]
        total = Fraction(0)
        for c, e in zip(coefficients, exps, strict=True):
            term = c
            for axis, k in enumerate(e):
                term *= x[axis] ** int(k)
            total += term
        out.append(total)
    return out


@pytest.mark.parametrize("seed", range(3))
def test_a_degree_20_polynomial_evaluates_as_exact_arithmetic_does(seed):
    # (x² + y² − 1)^10: coefficients up to 2520 cancel to (r² − 1)^10, nearly nothing near the circle.
    # Summing d terms of at most 20 factors each, float64 is within γ · Σ_k |a_k m_k(u)|, γ ≈ (d + 20) ε,
    # and Σ_k |a_k m_k(u)| = (x² + y² + 1)^10 for this polynomial (every sign made positive)
    poly = _ring_power(10)
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, 60)
    radius = rng.uniform(0.5, 1.5, 60)
    u = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    exact = _exact(poly, u)
    for value, (x, y) in zip(exact, u, strict=True):  # the expansion is right, exactly
        assert value == (Fraction(float(x)) ** 2 + Fraction(float(y)) ** 2 - 1) ** 10
    gamma = (poly.n_coefficients + 20) * np.finfo(float).eps
    bound = gamma * (np.sum(u ** 2, axis=1) + 1) ** 10
    assert np.all(np.abs(poly.evaluate_normalized(u) - np.array([float(v) for v in exact])) <= bound)


def _blob(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed curve that no polynomial of degree <= 20 vanishes on (so no direction of the
    basis is flat on it), and its normals."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    radius = 1 + 0.3 * np.cos(3 * t) + 0.2 * np.sin(5 * t)
    u = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    return u, u / np.linalg.norm(u, axis=1, keepdims=True)


@pytest.mark.parametrize(("degree", "tolerance"), [(14, 1e-5), (20, None)])
def test_the_search_basis_stays_well_conditioned_where_the_monomial_basis_is_singular(degree, tolerance):
    # AᵀA = RᵀR by construction, so A R⁻¹ (with the search's own explicit inverse) has orthonormal
    # columns in exact arithmetic; QR's backward error leaves them within about κ(A) ε of it.
    # Degree 14: κ(A) ≈ 1.6e9, orthonormal to 1e-5. Degree 20: κ(A) beyond 1 / ε, where nothing is
    # promised; A R⁻¹ still has a condition number of a few units (1.7-1.9 measured), not 1e17
    u, normals = _blob(400)
    r, r_inv = _whitening(Objective(u, normals, degree))
    m, grads = basis.monomials_and_gradients(u, degree)
    a = np.concatenate([m, grads.reshape(-1, m.shape[1])])
    sv = np.linalg.svd(a, compute_uv=False)
    assert sv[0] / sv[-1] > (1e9 if degree == 14 else 1e15)
    gram = (a @ r_inv).T @ (a @ r_inv)
    if tolerance is not None:
        np.testing.assert_allclose(gram, np.eye(len(r)), atol=tolerance)
    eig = np.linalg.eigvalsh(gram)
    assert np.sqrt(eig[-1] / eig[0]) < (1 + 1e-4 if tolerance is not None else 10)

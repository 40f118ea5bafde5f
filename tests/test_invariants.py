"""Invariant descriptors: exact invariance under similarities, class separation, retrieval."""

from __future__ import annotations

import numpy as np
import pytest

import ipfit
from ipfit import ImplicitPolynomial, Normalization
from ipfit.datasets.synthetic import torus
from ipfit.analysis.invariants import compose_linear, invariant_center, invariants, similarity
from ipfit.analysis.recognition import CLASSES, demo_collection, demo_contour, retrieval_precision


def _rotation(rng, dim):
    q, _ = np.linalg.qr(rng.standard_normal((dim, dim)))
    return q * np.sign(np.linalg.det(q))


def _random_closed_poly(rng, dim, degree):
    """A random polynomial with a bounded zero set: a perturbed |u|^degree − 1."""
    exps = ipfit.basis.exponents(dim, degree)
    coef = 0.3 * rng.standard_normal(len(exps))
    top = exps.sum(axis=1) == degree
    # (Σ u_j²)^(g/2) has positive coefficients on the even top monomials: dominate with them.
    even = top & np.all(exps % 2 == 0, axis=1)
    coef[even] += 3.0
    coef[0] = -3.0
    return ImplicitPolynomial(exps, coef, Normalization(rng.uniform(-2, 2, dim), float(rng.uniform(0.5, 2))))


@pytest.mark.parametrize("dim,degree", [(2, 4), (2, 6), (3, 4), (3, 6)])
def test_invariant_under_exact_similarities(rng, dim, degree):
    poly = _random_closed_poly(rng, dim, degree)
    base = invariants(poly)
    for _ in range(3):
        moved = similarity(poly, _rotation(rng, dim), rng.uniform(-5, 5, dim), float(rng.uniform(0.2, 5)))
        # Also a factor on f, and a translation expanded into the coefficients instead of the normalisation.
        shift = rng.uniform(-0.3, 0.3, dim)
        moved = compose_linear(moved, np.eye(dim), shift)
        moved = moved.with_coefficients(-2.5 * moved.coefficients,
                                        normalization=Normalization(moved.center - moved.scale * shift, moved.scale))
        np.testing.assert_allclose(invariants(moved), base, rtol=1e-8, atol=1e-10 * np.abs(base).max())


def test_similarity_moves_points_of_the_zero_set(rng):
    shape = torus(major=1.0, minor=0.3, n=200)
    r, t, s = _rotation(rng, 3), np.array([1.0, -2.0, 3.0]), 1.7
    moved = similarity(shape.polynomial, r, t, s)
    # f_moved(s R x + t) = f(x): exactly the same values, not merely the same zero set.
    np.testing.assert_allclose(moved(s * shape.points @ r.T + t), shape.polynomial(shape.points), atol=1e-12)
    x = rng.uniform(-2, 2, (50, 3))
    np.testing.assert_allclose(moved(s * x @ r.T + t), shape.polynomial(x), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(invariant_center(moved), t, atol=1e-9)


def test_compose_linear_is_composition(rng):
    poly = _random_closed_poly(rng, 3, 5)
    m, v = rng.standard_normal((3, 3)), rng.standard_normal(3)
    composed = compose_linear(poly, m, v)
    u = rng.uniform(-1, 1, (40, 3))
    np.testing.assert_allclose(composed.evaluate_normalized(u), poly.evaluate_normalized(u @ m.T + v),
                               rtol=1e-10, atol=1e-10)


@pytest.fixture(scope="module")
def demo_descriptors():
    contours = demo_collection(5, n=120, noise=0.01, rng=123)
    fits = [ipfit.fit_3l(c.points, c.normals, 6) for c in contours]
    return ipfit.descriptors(fits), np.array([c.label for c in contours])


def test_fits_of_moved_shapes_separate_by_class(demo_descriptors):
    desc, labels = demo_descriptors
    logd = np.log(np.maximum(desc, 1e-12))
    dist = np.linalg.norm(logd[:, None] - logd[None], axis=2)
    same = labels[:, None] == labels[None]
    off_diagonal = ~np.eye(len(labels), dtype=bool)
    within, between = dist[same & off_diagonal].mean(), dist[~same].mean()
    assert within < 0.6 * between
    assert retrieval_precision(desc, labels) > 0.8


def test_descriptors_accept_paths_and_dicts(tmp_path, rng):
    c = demo_contour("star5", rng=rng)
    poly = ipfit.fit_3l(c.points, c.normals, 6)
    poly.save(tmp_path / "a.json")
    rows = ipfit.descriptors([poly, tmp_path / "a.json", poly.to_dict()])
    np.testing.assert_array_equal(rows[0], rows[1])
    np.testing.assert_array_equal(rows[0], rows[2])
    with pytest.raises(ipfit.InvalidInputError, match="one dimension and degree"):
        ipfit.descriptors([poly, ipfit.fit_3l(c.points, c.normals, 4)])
    with pytest.raises(ipfit.InvalidInputError, match="kind"):
        demo_contour("triangle")
    assert set(CLASSES) == {"ellipse", "star3", "star5", "square"}

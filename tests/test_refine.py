"""Metaheuristic refinement (issue 4): seeded DE/PSO, the polish, and the result."""

from __future__ import annotations

import numpy as np
import pytest

from ipfit import ImplicitPolynomial, InvalidInputError, Normalization, fit_3l
from ipfit.datasets import synthetic
from ipfit.objective import measures
from ipfit.refine import REFINE_METHODS, RefineResult, refine


def wobbly(n=160, rng=None):
    """A closed curve r = 1 + 0.15 cos 3θ + 0.1 sin 5θ with outward normals, plus a little noise:
    no low-degree polynomial fits it exactly, so the refinement has something to do."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.15 * np.cos(3 * t) + 0.1 * np.sin(5 * t)
    dr = -0.45 * np.sin(3 * t) + 0.5 * np.cos(5 * t)
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    tangent = np.column_stack([dr * np.cos(t) - r * np.sin(t), dr * np.sin(t) + r * np.cos(t)])
    normals = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    if rng is not None:
        pts = pts + 0.003 * rng.normal(size=pts.shape)
    return pts * 50 + [300.0, -20.0], normals  # user units far from the origin


def alignment(a, b):
    return abs(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b))


@pytest.mark.parametrize("method", ["de", "pso"])
def test_converges_to_an_exact_conic_without_seeds(seed, method):
    shape = synthetic.ellipse(30, 2.0, 1.0, center=(0.3, -0.2))
    res = refine(shape.points, shape.normals, 2, method, seeds=[], iterations=300, rng=seed)
    assert res.best_seed is None and res.seed_distances == {}
    assert res.distance < 1e-4
    # Same zero set as the exact ellipse: compare in user coordinates at a few points.
    probe = np.array([[2.3, -0.2], [0.3, 0.8], [-1.7, -0.2], [0.3, -1.2]])
    np.testing.assert_allclose(res.polynomial(probe), 0.0, atol=1e-3)


def test_converges_to_an_exact_quadric_without_seeds(seed):
    shape = synthetic.ellipsoid(60, axes=(1.5, 1.0, 0.7), center=(0.1, 0.2, 0.3))
    res = refine(shape.points, shape.normals, 2, "pso", seeds=[], iterations=300, rng=seed)
    assert res.distance < 1e-4
    exact = shape.polynomial.coefficients
    # Express the fit in user coordinates by sampling: both vanish on the data and agree in sign.
    inside = np.array([[0.1, 0.2, 0.3]])
    assert res.polynomial(inside)[0] < 0 and shape.polynomial(inside)[0] < 0
    assert np.max(np.abs(res.polynomial(shape.points))) < 1e-3 * np.max(np.abs(exact))


@pytest.mark.parametrize("method", REFINE_METHODS)
def test_never_above_the_best_seed_and_result_contract(rng, method):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, method, iterations=15, population=40, rng=rng, n_solutions=3)
    assert isinstance(res, RefineResult)
    assert res.distance <= res.best_seed_distance
    assert res.best_seed_distance == min(res.seed_distances.values())
    poly = res.polynomial
    assert isinstance(poly, ImplicitPolynomial) and poly.method == method and poly.degree == 4
    assert np.linalg.norm(poly.coefficients) == pytest.approx(1.0)
    assert list(poly.measures) == ["dissimilarity", "smoothness", "distance", "delta"]
    assert poly.measures["distance"] == pytest.approx(res.distance)
    assert poly.measures["smoothness"] > 0.5  # canonical orientation: ∇f along the normals
    # The measures are the public function's, on the user's points.
    assert measures(poly, pts, nrm).distance == pytest.approx(res.distance, rel=1e-12)
    assert res.solutions[0] is poly and 1 <= len(res.solutions) <= 3
    dists = [s.measures["distance"] for s in res.solutions]
    assert dists == sorted(dists)
    coefs = np.array([s.coefficients for s in res.solutions])
    assert all(np.linalg.norm(coefs[i] - coefs[j]) > 1e-4 for i in range(len(coefs)) for j in range(i))
    assert np.all(np.diff(res.history) <= 1e-12)
    if method == "polish":
        assert res.nit == 0 and len(res.history) == 1
    else:
        assert res.nit == 15 and len(res.history) == 16 and res.population_size == 40
    assert ("polish" in method) == (len(res.polish_history) > 0)
    assert res.nfev > 0 and res.seconds > 0 and res.success


def test_polish_improves_on_the_seeds(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de+polish", iterations=10, population=60, rng=rng)
    assert res.distance < 0.8 * res.best_seed_distance  # about 0.55 under every seed tried


def test_fixed_rng_is_bit_reproducible(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    kwargs = dict(iterations=12, population=40)
    for method in ("de+polish", "pso"):
        a = refine(pts, nrm, 4, method, rng=seed, **kwargs)
        b = refine(pts, nrm, 4, method, rng=np.random.default_rng(seed), **kwargs)
        np.testing.assert_array_equal(a.polynomial.coefficients, b.polynomial.coefficients)
        np.testing.assert_array_equal(a.history, b.history)
        assert a.nfev == b.nfev


def test_different_rng_similar_quality(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    results = [refine(pts, nrm, 4, "de+polish", iterations=20, population=40, rng=seed + k) for k in range(3)]
    histories = [r.history for r in results]
    assert not all(np.array_equal(histories[0], h) for h in histories[1:])
    d = np.array([r.distance for r in results])
    assert d.max() <= 1.15 * d.min()


def test_invariant_to_the_users_units(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    a = refine(pts, nrm, 4, "de+polish", iterations=8, population=30, rng=seed)
    b = refine(pts * 1e-3, nrm, 4, "de+polish", iterations=8, population=30, rng=seed)
    # Same normalised problem up to rounding: the seeds agree to rounding; the search, which
    # amplifies rounding differences, ends at the same quality.
    for label, value in a.seed_distances.items():
        assert b.seed_distances[label] == pytest.approx(value, rel=1e-8)
    assert b.distance == pytest.approx(a.distance, rel=1e-3)


def test_seeds_argument(rng):
    pts, nrm = wobbly(rng=rng)
    seed_poly = fit_3l(pts, nrm, 4)
    res = refine(pts, nrm, 4, "polish", seeds=[seed_poly])
    assert list(res.seed_distances) == ["3l"]
    assert res.best_seed_distance == pytest.approx(measures(seed_poly, pts, nrm).distance)
    assert res.distance < res.best_seed_distance
    by_name = refine(pts, nrm, 4, "de", seeds=["taubin", seed_poly.coefficients], iterations=3, population=12, rng=rng)
    assert set(by_name.seed_distances) == {"taubin", "seed1"}
    other = ImplicitPolynomial.from_coefficients(seed_poly.coefficients, 2, Normalization.identity(2))
    with pytest.raises(InvalidInputError, match=r"seeds\[0\]"):
        refine(pts, nrm, 4, seeds=[other])
    with pytest.raises(InvalidInputError, match=r"seeds\[0\]"):
        refine(pts, nrm, 4, seeds=[np.ones(3)])
    with pytest.raises(InvalidInputError, match="seeds"):
        refine(pts, nrm, 4, "polish", seeds=[])


def test_callback_sees_every_iteration_and_can_stop(rng):
    pts, nrm = wobbly(rng=rng)
    stages = []

    def record(state):
        stages.append((state.message, state.nit))
        assert np.linalg.norm(state.x) == pytest.approx(1.0) and np.isfinite(state.fun)

    res = refine(pts, nrm, 4, "pso+polish", iterations=6, population=20, rng=rng, callback=record)
    assert [n for s, n in stages if s == "pso"] == [1, 2, 3, 4, 5, 6]
    assert any(s == "polish" for s, _ in stages) and res.nit == 6
    stop = refine(pts, nrm, 4, "de", iterations=50, population=20, rng=rng, callback=lambda s: s.nit >= 2)
    assert stop.nit == 2 and "callback" in stop.message


def test_float32_screening(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de+polish", iterations=10, population=30, rng=rng, dtype=np.float32)
    assert res.distance <= res.best_seed_distance
    assert res.info["dtype"] == "float32"


def test_search_in_raw_coefficients(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de", iterations=10, population=30, rng=rng, search_space="coefficients")
    assert res.distance <= res.best_seed_distance


@pytest.mark.parametrize("kwargs, match", [
    ({"method": "ga"}, "method"),
    ({"method": "de", "population": 3}, "population"),
    ({"iterations": -1}, "iterations"),
    ({"seed_fraction": 1.5}, "seed_fraction"),
    ({"F": 3.0}, "F"),
    ({"CR": -0.1}, "CR"),
    ({"method": "pso", "chi": 1.0}, "chi"),
    ({"delta": -0.25}, "delta"),
    ({"polish": -1}, "polish"),
    ({"n_solutions": 0}, "n_solutions"),
    ({"rng": "x"}, "rng"),
    ({"dtype": np.float16}, "dtype"),
    ({"search_space": "polar"}, "search_space"),
    ({"callback": 3}, "callback"),
])
def test_invalid_arguments(kwargs, match):
    pts, nrm = wobbly()
    with pytest.raises(InvalidInputError, match=match):
        refine(pts, nrm, 4, **kwargs)


def test_invalid_data():
    pts, nrm = wobbly(n=12)
    with pytest.raises(InvalidInputError, match="normals"):
        refine(pts, None, 2)
    with pytest.raises(InvalidInputError, match="at least 15 points"):
        refine(pts, nrm, 4)

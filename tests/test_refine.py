"""Metaheuristic refinement (issue 4): seeded DE/PSO, the polish, and the result."""

from __future__ import annotations

import numpy as np
import pytest

from ipfit import (PAPER, RECOMMENDED, ImplicitPolynomial, InvalidInputError, Normalization, SearchOptions, fit_3l,
                   fit_linear)
from ipfit.datasets import synthetic
from ipfit.fitting.objective import measures
from ipfit.fitting.refine import REFINE_METHODS, RefineResult, refine


def opts(**changes):
    return RECOMMENDED.replace(**changes)


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
    res = refine(shape.points, shape.normals, 2, method, options=opts(start_fits=(), iterations=300, far_term_weight=0.0),
                 rng=seed)
    assert res.best_start is None and dict(res.start_distances) == {}
    assert res.distance < 1e-4
    # Same zero set as the exact ellipse: compare in user coordinates at a few points.
    probe = np.array([[2.3, -0.2], [0.3, 0.8], [-1.7, -0.2], [0.3, -1.2]])
    np.testing.assert_allclose(res.polynomial(probe), 0.0, atol=1e-3)


def test_converges_to_an_exact_quadric_without_seeds(seed):
    shape = synthetic.ellipsoid(60, axes=(1.5, 1.0, 0.7), center=(0.1, 0.2, 0.3))
    res = refine(shape.points, shape.normals, 2, "pso", options=opts(start_fits=(), iterations=300, far_term_weight=0.0),
                 rng=seed)
    assert res.distance < 1e-4
    exact = shape.polynomial.coefficients
    # Express the fit in user coordinates by sampling: both vanish on the data and agree in sign.
    inside = np.array([[0.1, 0.2, 0.3]])
    assert res.polynomial(inside)[0] < 0 and shape.polynomial(inside)[0] < 0
    assert np.max(np.abs(res.polynomial(shape.points))) < 1e-3 * np.max(np.abs(exact))


@pytest.mark.parametrize("method", REFINE_METHODS)
def test_never_above_the_best_start_and_result_contract(rng, method):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, method, options=opts(iterations=15, population_size=40, n_solutions=3, far_term_weight=0.0),
                 rng=rng)
    assert isinstance(res, RefineResult)
    # Independent reference: every start fit, fitted and measured here by the public functions.
    best_linear = min(measures(fit_linear(pts, nrm, 4, m), pts, nrm).distance for m in ("3l", "ridge", "lstsq"))
    assert res.distance <= best_linear * (1 + 1e-9)
    np.testing.assert_array_equal(res.x, res.polynomial.coefficients)
    assert res.fun == pytest.approx(res.distance, rel=1e-12)  # no far-field term: fun is the distance
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


def test_polish_improves_on_the_start_fits(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de+polish", options=opts(iterations=10, population_size=60, far_term_weight=0.0), rng=rng)
    best_3l = measures(fit_3l(pts, nrm, 4), pts, nrm).distance
    assert res.distance < 0.8 * min(res.best_start_value, best_3l)  # about 0.55 under every seed tried


def test_a_search_that_does_nothing_returns_the_best_start_fit(rng):
    pts, nrm = wobbly(rng=rng)
    # A swarm of exactly the two start fits that never moves.
    res = refine(pts, nrm, 4, "pso", options=opts(iterations=0, population_size=2, start_fraction=1.0,
                                                   start_fits=("3l", "lstsq"), far_term_weight=0.0), rng=rng)
    fits = {m: fit_linear(pts, nrm, 4, m) for m in ("3l", "lstsq")}
    best = min(fits, key=lambda m: measures(fits[m], pts, nrm).distance)
    assert res.best_start == best and res.nit == 0 and res.success
    assert res.distance == pytest.approx(measures(fits[best], pts, nrm).distance, rel=1e-12)
    assert "no candidate beat the best start fit" in res.message


def test_fixed_rng_is_bit_reproducible(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    o = opts(iterations=12, population_size=40)
    for method in ("de+polish", "pso"):
        a = refine(pts, nrm, 4, method, options=o, rng=seed)
        b = refine(pts, nrm, 4, method, options=o, rng=np.random.default_rng(seed))
        np.testing.assert_array_equal(a.polynomial.coefficients, b.polynomial.coefficients)
        np.testing.assert_array_equal(a.history, b.history)
        assert a.nfev == b.nfev


def test_different_rng_similar_quality(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    results = [refine(pts, nrm, 4, "de+polish", options=opts(iterations=20, population_size=40), rng=seed + k)
               for k in range(3)]
    histories = [r.history for r in results]
    assert not all(np.array_equal(histories[0], h) for h in histories[1:])
    d = np.array([r.distance for r in results])
    assert d.max() <= 1.15 * d.min()


def test_invariant_to_the_users_units(seed):
    pts, nrm = wobbly(rng=np.random.default_rng(seed))
    o = opts(iterations=8, population_size=30, far_term_weight=0.0)
    a = refine(pts, nrm, 4, "de+polish", options=o, rng=seed)
    b = refine(pts * 1e-3, nrm, 4, "de+polish", options=o, rng=seed)
    # Same normalised problem up to rounding: the seeds agree to rounding; the search, which
    # amplifies rounding differences, ends at the same quality.
    for label, value in a.start_distances.items():
        assert b.start_distances[label] == pytest.approx(value, rel=1e-8)
    assert b.distance == pytest.approx(a.distance, rel=1e-3)


def test_starts_and_start_fits(rng):
    pts, nrm = wobbly(rng=rng)
    start = fit_3l(pts, nrm, 4)
    no_fits = opts(start_fits=(), far_term_weight=0.0)
    res = refine(pts, nrm, 4, "polish", options=opts(start_fits=("3l",), far_term_weight=0.0), starts=[start])
    assert set(res.start_distances) == {"3l#0", "3l#1"}
    assert res.best_start_value == pytest.approx(measures(start, pts, nrm).distance)
    assert res.distance < res.best_start_value
    by_name = refine(pts, nrm, 4, "de", options=opts(start_fits=("taubin",), iterations=3, population_size=12,
                                                      far_term_weight=0.0), starts=[start.coefficients], rng=rng)
    assert set(by_name.start_distances) == {"taubin", "start0"}
    other = ImplicitPolynomial.from_coefficients(start.coefficients, 2, Normalization.identity(2))
    with pytest.raises(InvalidInputError, match=r"starts\[0\]"):
        refine(pts, nrm, 4, options=no_fits, starts=[other])
    with pytest.raises(InvalidInputError, match=r"starts\[0\]"):
        refine(pts, nrm, 4, options=no_fits, starts=[np.ones(3)])
    with pytest.raises(InvalidInputError, match="at least one start fit or start polynomial"):
        refine(pts, nrm, 4, "polish", options=no_fits)


def test_far_field_term_adds_the_3l_far_start_and_changes_fun(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de", options=opts(iterations=2, population_size=20), rng=rng)
    assert "3l-far" in res.start_distances
    assert res.fun >= res.distance  # the term is never negative
    assert res.info["far_term_weight"] == RECOMMENDED.far_term_weight


def test_old_keyword_names_are_gone():
    # Before the first release there are no deprecated aliases: an old name is a TypeError.
    pts, nrm = wobbly()
    for old in ("iterations", "population", "seeds", "far_weight", "F", "CR"):
        with pytest.raises(TypeError, match=old):
            refine(pts, nrm, 4, "de", **{old: 3})


@pytest.mark.parametrize("method, changes, name", [
    ("de", {"chi": 0.7}, "chi"), ("pso", {"mutation": 0.5}, "mutation"), ("pso+polish", {"recombination": 0.5},
                                                                         "recombination"),
    ("de", {"polish_iterations": 10}, "polish_iterations"), ("polish", {"c1": 2.0}, "c1"),
])
def test_an_option_that_does_not_apply_is_an_error(method, changes, name):
    pts, nrm = wobbly()
    with pytest.raises(InvalidInputError, match=rf"^{name}: expected a setting used by method"):
        refine(pts, nrm, 4, method, options=SearchOptions(**changes))


def test_paper_preset_pins_the_papers_parameters():
    resolved = PAPER.for_method("de", dim=2)
    assert resolved.mutation == 0.7 and resolved.recombination == 0.9 and resolved.iterations == 500
    assert resolved.population_size is None and resolved.start_fraction == 0.1  # 4·d members, N/10 started
    assert PAPER.start_fits == ("lstsq", "3l") and PAPER.search_space == "coefficients"
    assert PAPER.far_term_weight == 0.0 and PAPER.dtype == "float64"


def test_straight_line_and_plane_data_are_fitted():
    # Axis-aligned: every monomial with y (or z) vanishes on the data; the search must cope.
    x = np.linspace(-1, 1, 40)
    line = np.column_stack([x, np.zeros_like(x)])
    res = refine(line, np.tile([0.0, 1.0], (40, 1)), 2, options=opts(iterations=5), rng=0)
    assert res.success and np.max(np.abs(res.polynomial(line))) < 1e-6 * np.max(np.abs(res.polynomial([[0, 1.0]])))
    gx, gy = np.meshgrid(x[::4], x[::4])
    plane = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    res = refine(plane, np.tile([0.0, 0.0, 1.0], (len(plane), 1)), 2, options=opts(iterations=5), rng=0)
    assert res.success and np.max(np.abs(res.polynomial(plane))) < 1e-6 * np.max(np.abs(res.polynomial([[0, 0, 1.0]])))


def test_callback_sees_every_iteration_and_can_stop(rng):
    pts, nrm = wobbly(rng=rng)
    stages = []

    def record(state):
        stages.append((state.message, state.nit))
        assert np.linalg.norm(state.x) == pytest.approx(1.0) and np.isfinite(state.fun)

    res = refine(pts, nrm, 4, "pso+polish", options=opts(iterations=6, population_size=20), rng=rng, callback=record)
    assert [n for s, n in stages if s == "pso"] == [1, 2, 3, 4, 5, 6]
    assert any(s == "polish" for s, _ in stages) and res.nit == 6
    stop = refine(pts, nrm, 4, "de", options=opts(iterations=50, population_size=20), rng=rng,
                  callback=lambda s: s.nit >= 2)
    assert stop.nit == 2 and "callback" in stop.message


def test_float32_screening(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de+polish", options=opts(iterations=10, population_size=30, dtype=np.float32), rng=rng)
    assert res.fun <= res.best_start_value
    assert res.info["dtype"] == "float32"


def test_search_in_raw_coefficients(rng):
    pts, nrm = wobbly(rng=rng)
    res = refine(pts, nrm, 4, "de", options=opts(iterations=10, population_size=30, search_space="coefficients"),
                 rng=rng)
    assert res.fun <= res.best_start_value


@pytest.mark.parametrize("kwargs, match", [
    ({"method": "ga"}, "method"),
    ({"options": {"iterations": 3}}, "options: expected a SearchOptions"),
    ({"delta": -0.25}, "delta"),
    ({"rng": "x"}, "rng"),
    ({"callback": 3}, "callback"),
])
def test_invalid_arguments(kwargs, match):
    pts, nrm = wobbly()
    with pytest.raises(InvalidInputError, match=match):
        refine(pts, nrm, 4, **kwargs)


@pytest.mark.parametrize("changes, match", [
    ({"population_size": 1}, "population_size"),
    ({"iterations": -1}, "iterations"),
    ({"start_fraction": 1.5}, "start_fraction"),
    ({"mutation": 3.0}, "mutation"),
    ({"recombination": -0.1}, "recombination"),
    ({"chi": 1.0}, "chi"),
    ({"polish_iterations": -1}, "polish_iterations"),
    ({"n_solutions": 0}, "n_solutions"),
    ({"dtype": np.float16}, "dtype"),
    ({"dtype": "x"}, "dtype"),
    ({"search_space": "polar"}, "search_space"),
    ({"start_fits": "3l"}, "start_fits"),
    ({"start_fits": ("3l(k=2)",)}, "start_fits"),
    ({"far_term_weight": -1.0}, "far_term_weight"),
])
def test_invalid_options(changes, match):
    with pytest.raises(InvalidInputError, match=match):
        SearchOptions(**changes)
    with pytest.raises(InvalidInputError, match="unknown"):
        RECOMMENDED.replace(populaton_size=3)


def test_invalid_data():
    pts, nrm = wobbly(n=12)
    with pytest.raises(InvalidInputError, match="normals"):
        refine(pts, None, 2)
    with pytest.raises(InvalidInputError, match="at least 15 points"):
        refine(pts, nrm, 4)


def test_a_big_clouds_solutions_have_the_sign_all_its_normals_give(rng):
    # The sign of each solution comes from the objective's normal moments (one pass over the
    # design matrix, not the gradients at every point per solution); it must be the one every
    # point's normal gives: f grows outwards (the gradient agrees with the normals).
    from ipfit.fitting.refine import FULL_POLISH_POINTS

    shape = synthetic.torus(3 * FULL_POLISH_POINTS // 2)
    res = refine(shape.points, shape.normals, 4, "polish", options=opts(start_fits=("3l", "lstsq")), rng=rng)
    assert len(res.solutions) >= 2
    for poly in res.solutions:
        assert np.sum(poly.gradient(shape.points) * shape.normals) > 0
        assert np.allclose(poly.canonical(shape.points, shape.normals).coefficients, poly.coefficients, atol=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_polishes_on_two_threads_are_the_polishes_one_after_the_other(seed):
    # The same arithmetic whichever thread runs it: the results are equal to the bit, and the
    # callback hears only the first polish, always on the caller's thread.
    import threading

    from ipfit.fitting.objective import Objective
    from ipfit.fitting.refine import _polish_each

    rng = np.random.default_rng(seed)
    shape = synthetic.torus(1500, rng=rng)
    exact = shape.polynomial.coefficients
    x0s = [exact + 0.3 * rng.normal(size=exact.size), exact + 0.3 * rng.normal(size=exact.size)]
    r = Objective(shape.points, shape.normals, 4).whitening()
    heard = []

    def callback(state):
        heard.append((threading.get_ident(), state.nit))

    runs = {threads: _polish_each(Objective(shape.points, shape.normals, 4, threads=threads), x0s, 200, r,
                                  callback) for threads in (1, 2)}
    for alone, side_by_side in zip(runs[1], runs[2], strict=True):
        assert np.array_equal(alone.x, side_by_side.x) and alone.fun == side_by_side.fun
        assert alone.nit == side_by_side.nit > 0
    assert {ident for ident, _ in heard} == {threading.get_ident()}
    assert len(heard) == 2 * runs[1][0].nit  # the first polish's iterations, in each of the two calls
    assert runs[1][0].fun < Objective(shape.points, shape.normals, 4)(x0s[0])[0]  # it did polish

"""The paper's measures (Eq. 2-4) and the population objective."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from ipfit import ImplicitPolynomial, InvalidInputError, Normalization, basis
from numeric_checks import value_grad_and_differences
from ipfit.fitting import objective as objective_module
from ipfit.datasets import synthetic
from ipfit.fitting.objective import TAUBIN_CAP, Measures, Objective, measures

CIRCLE = [-1.0, 0, 0, 1.0, 0, 1.0]  # x² + y² − 1 in the graded order 1, x, y, x², xy, y²


def _reference(population, u, normals, degree, delta=0.25):
    """Plain-numpy Eq. 2-4, member by member (the slow, obvious way)."""
    m, dm = basis.monomials_and_gradients(u, degree)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    out = []
    for a in np.atleast_2d(population):
        f = m @ a
        g = np.stack([dk @ a for dk in dm], axis=1)
        norm = np.linalg.norm(g, axis=1)
        dissim = np.mean(np.abs(f) / norm)
        smooth = np.mean(np.sum(g * unit, axis=1) / norm)
        out.append((dissim, smooth, dissim + delta * (1 - smooth)))
    return np.array(out)


def test_hand_computed_circle():
    # (1, 0), n = (1, 0): f = 0, ∇f = (2, 0)      → Taubin 0,   cosine 1
    # (2, 0), n = (0, 1): f = 3, ∇f = (4, 0)      → Taubin 3/4, cosine 0
    # (0, ½), n = (0, −2): f = −¾, ∇f = (0, 1)    → Taubin 3/4, cosine −1 (normal normalised)
    pts = [[1.0, 0.0], [2.0, 0.0], [0.0, 0.5]]
    nrm = [[1.0, 0.0], [0.0, 1.0], [0.0, -2.0]]
    m = measures(np.array(CIRCLE), pts, nrm)
    assert m.dissimilarity == pytest.approx(0.5, abs=1e-15)
    assert m.smoothness == pytest.approx(0.0, abs=1e-15)
    assert m.distance == pytest.approx(0.5 + 0.25 * 1.0, abs=1e-15)
    assert m.delta == 0.25
    poly = ImplicitPolynomial.from_coefficients(CIRCLE, dim=2)
    assert measures(poly, pts, nrm, delta=0.5).distance == pytest.approx(0.5 + 0.5, abs=1e-15)


@pytest.mark.parametrize("shape", [synthetic.circle(50, radius=2.0, center=(1.0, -3.0)),
                                   synthetic.ellipse(64, 3.0, 0.5),
                                   synthetic.sphere(80, radius=0.5, center=(1.0, 2.0, 3.0)),
                                   synthetic.torus(200)],
                         ids=["circle", "ellipse", "sphere", "torus"])
def test_exact_shape_has_zero_dissimilarity_and_unit_smoothness(shape):
    m = measures(shape.polynomial, shape.points, shape.normals)
    assert m.dissimilarity == pytest.approx(0.0, abs=1e-12)
    assert m.smoothness == pytest.approx(1.0, abs=1e-12)
    assert m.distance == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("dim, degree", [(2, 1), (2, 4), (3, 2), (3, 5)])
def test_population_equals_member_by_member(rng, dim, degree):
    u = rng.normal(size=(300, dim))
    normals = rng.normal(size=(300, dim))
    d = basis.n_coefficients(dim, degree)
    population = rng.normal(size=(9, d))
    got = measures(population, u, normals)
    ref = _reference(population, u, normals, degree)
    np.testing.assert_allclose(got.dissimilarity, ref[:, 0], rtol=1e-10)
    np.testing.assert_allclose(got.smoothness, ref[:, 1], rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(got.distance, ref[:, 2], rtol=1e-10)
    for p in range(len(population)):
        single = measures(population[p], u, normals)
        assert isinstance(single.distance, float)
        assert single.distance == pytest.approx(got.distance[p], rel=1e-12)
        assert got[p].distance == pytest.approx(single.distance, rel=1e-12)


def test_blocks_do_not_change_the_result(rng, monkeypatch):
    u = rng.normal(size=(1000, 3))
    normals = rng.normal(size=(1000, 3))
    population = rng.normal(size=(5, basis.n_coefficients(3, 3)))
    whole = Objective(u, normals, 3)(population)
    monkeypatch.setattr(objective_module, "_BLOCK_BYTES", 1)
    monkeypatch.setattr(objective_module, "_MIN_ROWS", 7)  # 1000 = 142·7 + 6: a ragged last block
    obj = Objective(u, normals, 3)
    assert obj.block_rows(5) == 7
    np.testing.assert_allclose(obj(population), whole, rtol=1e-13)


def test_invariant_to_positive_scaling(rng):
    shape = synthetic.torus(150, rng=rng)
    a = shape.polynomial.coefficients + 0.05 * rng.normal(size=shape.polynomial.n_coefficients)
    base = measures(a, shape.points, shape.normals)
    for factor in (1e-6, 0.3, 7.0, 1e5):
        scaled = measures(factor * a, shape.points, shape.normals)
        assert scaled.dissimilarity == pytest.approx(base.dissimilarity, rel=1e-12)
        assert scaled.smoothness == pytest.approx(base.smoothness, rel=1e-12)
    flipped = measures(-a, shape.points, shape.normals)
    assert flipped.smoothness == pytest.approx(-base.smoothness, rel=1e-12)
    assert flipped.dissimilarity == pytest.approx(base.dissimilarity, rel=1e-12)


def test_polynomial_measures_use_normalised_coordinates(rng):
    # The same polynomial expressed for data scaled by 1000: identical (normalised) measures.
    shape = synthetic.ellipse(40, 2.0, 1.0)
    pts = shape.points + 0.01 * rng.normal(size=shape.points.shape)
    norm = Normalization.from_points(pts)
    coef = rng.normal(size=6)
    poly = ImplicitPolynomial.from_coefficients(coef, 2, norm)
    big = ImplicitPolynomial.from_coefficients(coef, 2, Normalization(norm.center * 1000, norm.scale * 1000))
    small_m = measures(poly, pts, shape.normals)
    big_m = measures(big, pts * 1000, shape.normals)
    assert big_m.dissimilarity == pytest.approx(small_m.dissimilarity, rel=1e-10)
    assert big_m.smoothness == pytest.approx(small_m.smoothness, rel=1e-10)
    # ... and equal to the raw-array call in normalised coordinates.
    raw = measures(coef, norm.apply(pts), shape.normals)
    assert raw.distance == pytest.approx(small_m.distance, rel=1e-12)


def test_vanishing_gradient_is_finite_and_silent():
    poly = ImplicitPolynomial.from_coefficients(CIRCLE, dim=2)
    paraboloid = ImplicitPolynomial.from_coefficients([0, 0, 0, 1.0, 0, 1.0], dim=2)  # x² + y²
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Centre of the circle: f = −1, ∇f = 0 → Taubin term capped, cosine 0.
        m = measures(poly, [[0.0, 0.0]], [[1.0, 0.0]])
        assert m.dissimilarity == TAUBIN_CAP and m.smoothness == 0.0
        # Singular point on the zero set: f = 0 and ∇f = 0 → both terms 0.
        m = measures(paraboloid, [[0.0, 0.0], [1.0, 0.0]], [[1.0, 0.0], [1.0, 0.0]])
        assert m.dissimilarity == pytest.approx(0.5 * 0.5)  # (0 + 1/2) / 2
        assert m.smoothness == pytest.approx(0.5)  # (0 + 1) / 2
        # The zero polynomial: finite, smoothness 0.
        z = measures(np.zeros(6), [[1.0, 2.0]], [[0.0, 1.0]])
        assert np.isfinite(z.distance) and z.smoothness == 0.0
        v, g = Objective([[0.0, 0.0], [1.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]], 2).value_and_grad(CIRCLE)
        assert np.isfinite(v) and np.isfinite(g).all()


def test_to_dict_is_the_json_contract():
    m = measures(np.array(CIRCLE), [[1.0, 0.0], [2.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]])
    d = m.to_dict()
    assert list(d) == ["dissimilarity", "smoothness", "distance", "delta"]
    assert all(type(v) is float for v in d.values())
    assert json.loads(json.dumps(d)) == d
    pop = measures(np.array([CIRCLE, CIRCLE]), [[1.0, 0.0]], [[1.0, 0.0]]).to_dict()
    assert pop["distance"] == [0.0, 0.0] and pop["delta"] == 0.25
    with pytest.raises(Exception):
        m.distance = 1.0  # frozen


def test_float32_matches_float64(rng):
    shape = synthetic.torus(400, rng=rng)
    obj64 = Objective(shape.points, shape.normals, 4)
    obj32 = Objective(shape.points, shape.normals, 4, dtype=np.float32)
    population = shape.polynomial.coefficients + 0.1 * rng.normal(size=(20, obj64.n_coefficients))
    np.testing.assert_allclose(obj32(population), obj64(population), rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("dim, degree", [(2, 3), (3, 4)])
def test_gradient_matches_finite_differences(rng, dim, degree):
    u = rng.normal(size=(200, dim))
    normals = rng.normal(size=(200, dim))
    obj = Objective(u, normals, degree, delta=0.3)
    a = rng.normal(size=obj.n_coefficients)
    _, grad, numeric = value_grad_and_differences(obj, a)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-7 * np.abs(grad).max())
    assert abs(grad @ a) < 1e-10 * np.linalg.norm(grad) * np.linalg.norm(a)  # scale invariance


def test_extra_terms_extend_the_objective(rng):
    class Constant:
        def __init__(self, weight):
            self.weight = weight

        def __call__(self, population):
            return np.full(len(population), self.weight)

        def value_and_grad(self, a):
            return self.weight, np.zeros_like(a)

    shape = synthetic.circle(30)
    pop = rng.normal(size=(4, 6))
    plain = Objective(shape.points, shape.normals, 2)
    zero = Objective(shape.points, shape.normals, 2, terms=[Constant(0.0)])
    two = Objective(shape.points, shape.normals, 2, terms=[Constant(2.0)])
    np.testing.assert_array_equal(zero(pop), plain(pop))
    np.testing.assert_allclose(two(pop), plain(pop) + 2.0)
    assert two.value_and_grad(pop[0])[0] == pytest.approx(plain(pop[0])[0] + 2.0)
    with pytest.raises(InvalidInputError, match="terms"):
        Objective(shape.points, shape.normals, 2, terms=[object()])


def test_whitening_factorises_the_gram_matrix(rng):
    u = rng.normal(size=(500, 3))
    obj = Objective(u, u, 3)
    r = obj.whitening()
    m, dm = basis.monomials_and_gradients(u, 3)
    gram = m.T @ m + sum(g.T @ g for g in dm)
    np.testing.assert_allclose(r.T @ r, gram, rtol=1e-10, atol=1e-10 * np.abs(gram).max())
    assert np.all(np.diag(r) > 0) and np.allclose(r, np.triu(r))


def test_errors_use_the_template():
    pts, nrm = [[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]]
    with pytest.raises(InvalidInputError, match="poly_or_population: expected .*length 5"):
        measures(np.ones(5), pts, nrm)
    with pytest.raises(InvalidInputError, match="normals"):
        measures(np.ones(6), pts, None)
    with pytest.raises(InvalidInputError, match="zero-length"):
        measures(np.ones(6), pts, [[0.0, 0.0], [0.0, 1.0]])
    with pytest.raises(InvalidInputError, match="dtype"):
        Objective(pts, nrm, 2, dtype=np.int32)
    with pytest.raises(InvalidInputError, match="delta"):
        measures(np.ones(6), pts, nrm, delta=-1)
    with pytest.raises(InvalidInputError, match=r"population: expected a \(P, 6\)"):
        Objective(pts, nrm, 2)(np.ones((2, 7)))
    poly3d = ImplicitPolynomial.from_coefficients(np.ones(10), dim=3)
    with pytest.raises(InvalidInputError, match="points"):
        measures(poly3d, pts, nrm)


def test_measures_getitem():
    m = Measures(np.array([1.0, 2.0]), np.array([0.5, 0.25]), np.array([1.125, 2.1875]), 0.25)
    assert m[1].distance == 2.1875 and isinstance(m[1].distance, float)
    assert np.array_equal(m[[0, 1]].distance, m.distance)


def test_threaded_and_serial_evaluation_agree(rng, monkeypatch):
    u = rng.normal(size=(3000, 3))
    normals = rng.normal(size=(3000, 3))
    population = rng.normal(size=(140, basis.n_coefficients(3, 4)))
    threaded = Objective(u, normals, 4, threads=2)
    serial = Objective(u, normals, 4, threads=1)
    assert threaded.block_rows(140) < 3000  # several blocks, so two workers really share them
    np.testing.assert_allclose(threaded(population), serial(population), rtol=1e-12)
    np.testing.assert_array_equal(threaded(population), threaded(population))  # fixed summation order
    monkeypatch.setattr(objective_module, "_controller", lambda: None)  # threadpoolctl missing
    np.testing.assert_allclose(threaded(population), serial(population), rtol=1e-12)
    with pytest.raises(InvalidInputError, match="threads"):
        Objective(u, normals, 4, threads=0)


def test_default_threads_follow_omp_num_threads(monkeypatch):
    import os

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    usable = len(os.sched_getaffinity(0))
    assert objective_module.default_threads() == usable
    monkeypatch.setenv("OMP_NUM_THREADS", "1")  # what a batch's Dask workers set
    assert objective_module.default_threads() == 1
    assert Objective(np.eye(3), np.eye(3), 1).threads == 1
    monkeypatch.setenv("OMP_NUM_THREADS", str(usable + 5))  # never more than the usable CPUs
    assert objective_module.default_threads() == usable
    monkeypatch.setenv("OMP_NUM_THREADS", "many")
    assert objective_module.default_threads() == usable


def test_from_data_normalises_like_the_linear_fits(rng):
    shape = synthetic.ellipse(50, 3.0, 1.0, center=(10.0, 5.0))
    obj = Objective.from_data(shape.points * 7, shape.normals, 2)
    norm = Normalization.from_points(shape.points * 7)
    np.testing.assert_allclose(obj.u, norm.apply(shape.points * 7))
    assert obj.normalization.scale == pytest.approx(norm.scale)


def test_normal_agreement_of_the_unit_circle_is_two_per_point():
    # f = x² + y² − 1: ∇f = 2 (x, y) = 2 n on the circle, so Σ ∇f·n = 2 N by hand.
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    ring = np.c_[np.cos(t), np.sin(t)]
    agreement = Objective(ring, ring, 2).normal_agreement()
    assert agreement @ np.array(CIRCLE) == pytest.approx(80.0, rel=1e-12)
    assert agreement @ -np.array(CIRCLE) == pytest.approx(-80.0, rel=1e-12)


@pytest.mark.parametrize("dim, degree", [(2, 5), (3, 4)])
def test_normal_agreement_is_the_weighted_sum_of_gradients_along_the_normals(rng, dim, degree, monkeypatch):
    u = rng.normal(size=(700, dim))
    normals = rng.normal(size=(700, dim))
    weights = rng.uniform(0.0, 1.0, 700)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    m, dm = basis.monomials_and_gradients(u, degree)
    population = rng.normal(size=(4, m.shape[1]))
    expected = [np.sum(weights * np.sum(np.stack([dk @ a for dk in dm], axis=1) * unit, axis=1)) for a in population]
    cached = Objective(u, normals, degree, weights=weights).normal_agreement()
    monkeypatch.setattr(objective_module, "CACHE_BYTES", 0)
    monkeypatch.setattr(objective_module, "_SINGLE_ROWS", 97)  # the design rebuilt in ragged blocks
    rebuilt = Objective(u, normals, degree, weights=weights).normal_agreement()
    size = np.abs(population).sum(axis=1) * np.abs(dm).max() * len(u)
    for agreement in (cached, rebuilt):
        np.testing.assert_allclose(population @ agreement, expected, rtol=1e-9, atol=1e-12 * size.max())


def test_uncached_blocks_give_the_cached_results(rng, monkeypatch):
    shape = synthetic.torus(1500, rng=rng)
    population = shape.polynomial.coefficients + 0.1 * rng.normal(size=(6, 35))
    cached = Objective(shape.points, shape.normals, 4)
    value, grad = cached.value_and_grad(population[0])
    monkeypatch.setattr(objective_module, "CACHE_BYTES", 0)
    monkeypatch.setattr(objective_module, "_SINGLE_ROWS", 97)  # ragged blocks in the gradient pass too
    rebuilt = Objective(shape.points, shape.normals, 4)
    assert rebuilt._m is None
    np.testing.assert_allclose(rebuilt(population), cached(population), rtol=1e-13)
    v2, g2 = rebuilt.value_and_grad(population[0])
    assert v2 == pytest.approx(value, rel=1e-13)
    np.testing.assert_allclose(g2, grad, rtol=1e-10, atol=1e-13 * np.abs(grad).max())
    np.testing.assert_allclose(rebuilt.whitening(), cached.whitening(), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("kept", [False, True])
def test_a_polish_pass_shared_between_threads_sums_the_same_to_rounding(rng, monkeypatch, kept):
    # The single-member pass (the polish's) splits its blocks between the worker threads when the
    # design is rebuilt at every evaluation (too big to keep), or when a kept design's caller asks
    # (split=True: the final polish, which runs alone). The sums must be those of one thread to
    # rounding, the same on every call, and the far-field rows and weights counted once; on one
    # thread a split pass is the plain one, to the bit.
    from ipfit.fitting.farfield import FarFieldTerm

    shape = synthetic.torus(2000, rng=rng)
    weights = rng.uniform(0.2, 1.0, len(shape.points))
    a = shape.polynomial.coefficients + 0.05 * rng.normal(size=35)
    far = [FarFieldTerm.from_data(shape.points, shape.normals, 4, weight=0.5)]
    plain = Objective(shape.points, shape.normals, 4, weights=weights, terms=far, threads=1).value_and_grad(a)
    if not kept:
        monkeypatch.setattr(objective_module, "CACHE_BYTES", 0)
    monkeypatch.setattr(objective_module, "_SINGLE_ROWS", 300)  # 7 blocks of points, then the far rows
    one = Objective(shape.points, shape.normals, 4, weights=weights, terms=far, threads=1)
    two = Objective(shape.points, shape.normals, 4, weights=weights, terms=far, threads=2)
    assert (two._m is not None) == kept and len(two._member_jobs()) == 8
    pools, pool = [], objective_module._pool
    monkeypatch.setattr(objective_module, "_pool", lambda workers: pools.append(workers) or pool(workers))
    for value, grad in (one.value_and_grad(a, split=kept), two.value_and_grad(a, split=kept)):
        assert value == pytest.approx(plain[0], rel=1e-13)
        np.testing.assert_allclose(grad, plain[1], rtol=1e-10, atol=1e-13 * np.abs(plain[1]).max())
    assert pools and set(pools) == {2}  # two threads shared the blocks (one thread never asks for a pool)
    first, again = two.value_and_grad(a, split=kept), two.value_and_grad(a, split=kept)
    assert first[0] == again[0] and np.array_equal(first[1], again[1])  # a fixed summation order
    if kept:
        alone, unsplit = one.value_and_grad(a, split=True), one.value_and_grad(a)
        assert alone[0] == unsplit[0] and np.array_equal(alone[1], unsplit[1])


def test_a_kept_design_runs_the_polish_pass_on_one_thread(rng):
    # What a cloud whose design is kept computes does not depend on the thread count, to the bit.
    shape = synthetic.torus(3000, rng=rng)
    a = shape.polynomial.coefficients + 0.05 * rng.normal(size=35)
    one = Objective(shape.points, shape.normals, 4, threads=1).value_and_grad(a)
    two = Objective(shape.points, shape.normals, 4, threads=2).value_and_grad(a)
    assert one[0] == two[0] and np.array_equal(one[1], two[1])


@pytest.mark.slow
def test_a_million_points_need_no_full_design_matrix(rng):
    import tracemalloc

    n, degree = 10**6, 6
    d = basis.n_coefficients(3, degree)
    shape = synthetic.sphere(n, rng=rng)
    population = rng.normal(size=(8, d))
    Objective(shape.points[:500], shape.normals[:500], degree)(population)  # load the kernels first
    tracemalloc.start()
    try:
        obj = Objective(shape.points, shape.normals, degree, threads=1)
        built = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        obj(population)
        value, grad = obj.value_and_grad(population[0])
        peak = tracemalloc.get_traced_memory()[1] - built
    finally:
        tracemalloc.stop()
    full = n * d * 8  # 672 MB: the matrix a plain implementation would hold
    assert built < full / 4  # points and normals only
    assert peak < full / 20
    assert np.isfinite(value) and grad.shape == (d,)

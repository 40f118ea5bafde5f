"""Far-field information: samples, the objective term, and the linear rows (issue 8)."""

import numpy as np
import pytest

import ipfit
from numeric_checks import value_grad_and_differences
from ipfit.basis import n_coefficients
from ipfit.datasets import synthetic
from ipfit.fitting.farfield import FarFieldTerm, far_field_samples
from ipfit.fitting.objective import Objective


def test_samples_are_signed_by_the_normals_and_keep_clear_of_the_data():
    shape = synthetic.sphere(400, radius=1.0)
    samples, targets = far_field_samples(shape.points, shape.normals, c=0.05)
    r = np.linalg.norm(samples, axis=1)
    assert np.all(np.sign(targets) == np.sign(r - 1))
    assert np.all(np.abs(targets) > 0.15)
    np.testing.assert_allclose(np.abs(targets), np.abs(r - 1), atol=0.15)  # nearest data point ≈ nearest surface point


def test_exact_shape_costs_nothing_and_a_spurious_circle_is_penalised():
    shape = synthetic.circle(200, radius=1.0)
    exact = synthetic.from_terms(2, 4, {(0, 0): -1, (2, 0): 1, (0, 2): 1})
    # (x² + y² − 1)((x − 1.5)² + y² − 0.04): the unit circle plus a small loop away from the data
    circle = {(0, 0): -1, (2, 0): 1, (0, 2): 1}
    loop = {(0, 0): 1.5**2 - 0.04, (1, 0): -3.0, (2, 0): 1, (0, 2): 1}
    product = {}
    for e1, c1 in circle.items():
        for e2, c2 in loop.items():
            e = (e1[0] + e2[0], e1[1] + e2[1])
            product[e] = product.get(e, 0) + c1 * c2
    spurious = synthetic.from_terms(2, 4, product)
    term = FarFieldTerm.from_data(shape.points, shape.normals, 4, weight=1.0)
    assert term(exact.coefficients)[0] == 0
    assert term(spurious.coefficients)[0] > 0.01
    assert term(-exact.coefficients)[0] > 1.0  # everything on the wrong side


@pytest.mark.parametrize("dim,degree", [(2, 4), (3, 4)])
def test_gradient_matches_finite_differences(dim, degree, rng):
    shape = synthetic.circle(80) if dim == 2 else synthetic.sphere(200)
    term = FarFieldTerm.from_data(shape.points, shape.normals, degree, weight=0.7)
    a = rng.normal(size=n_coefficients(dim, degree))
    value, grad = term.value_and_grad(a)
    assert value == pytest.approx(term(a)[0])
    h = 1e-6
    fd = np.array([(term(a + h * e)[0] - term(a - h * e)[0]) / (2 * h) for e in np.eye(len(a))])
    np.testing.assert_allclose(grad, fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_scale_invariance_and_population_vectorisation(rng):
    shape = synthetic.circle(80)
    term = FarFieldTerm.from_data(shape.points, shape.normals, 4, weight=1.0)
    pop = rng.normal(size=(7, 15))
    values = term(pop)
    np.testing.assert_allclose(values, [term(p)[0] for p in pop])
    np.testing.assert_allclose(term(3.5 * pop), values)


def test_weight_zero_is_the_papers_objective_exactly(rng):
    shape = synthetic.ellipse(120)
    plain = Objective(shape.points, shape.normals, 4)
    with_term = Objective(shape.points, shape.normals, 4,
                          terms=[FarFieldTerm.from_data(shape.points, shape.normals, 4, weight=0.0)])
    pop = rng.normal(size=(9, 15))
    np.testing.assert_array_equal(with_term(pop), plain(pop))
    v0, g0 = plain.value_and_grad(pop[0])
    v1, g1 = with_term.value_and_grad(pop[0])
    assert v0 == v1
    np.testing.assert_array_equal(g0, g1)


def test_far_field_rows_remove_the_spurious_sheets_of_3l_on_a_sphere():
    from ipfit.zeroset.quality import quality

    shape = synthetic.sphere(500)
    plain = quality(ipfit.fit_3l(shape.points, shape.normals, 4), shape.points)
    far = quality(ipfit.fit_3l(shape.points, shape.normals, 4, far_row_weight=1e-3), shape.points)
    assert plain.n_spurious > 0  # the example: 3L at degree 4 grows extra components
    assert far.n_spurious == 0 and far.n_components == 1 and far.closed
    assert far.f_score >= plain.f_score


def test_far_field_weight_zero_is_plain_3l(rng):
    shape = synthetic.ellipse(100)
    a = ipfit.fit_3l(shape.points, shape.normals, 4, far_row_weight=0.0)
    b = ipfit.fit_3l(shape.points, shape.normals, 4)
    np.testing.assert_array_equal(a.coefficients, b.coefficients)


def test_refine_with_far_field_reports_both_values():
    from ipfit.fitting.refine import refine

    shape = synthetic.ellipse(80)
    plain = refine(shape.points, shape.normals, 4, options=ipfit.RECOMMENDED.replace(iterations=5, far_term_weight=0.0),
                   rng=0)
    far = refine(shape.points, shape.normals, 4, options=ipfit.RECOMMENDED.replace(iterations=5, far_term_weight=0.1),
                 rng=0)
    assert plain.fun == pytest.approx(plain.distance)  # weight 0: the paper's objective
    assert far.fun >= far.distance  # the term is non-negative and reported separately
    assert far.info["far_term_weight"] == 0.1 and "3l-far" in far.start_distances
    np.testing.assert_array_equal(far.x, far.polynomial.coefficients)


def test_term_samples_follow_the_count_rule_keep_clear_and_spread_evenly():
    from scipy.spatial import cKDTree

    from ipfit.fitting.farfield import SPREAD_OFFSET, term_sample_count, term_samples

    shape = synthetic.circle(120)
    samples, targets = term_samples(shape.points, shape.normals, c=0.05)
    assert len(samples) == term_sample_count(120, 2) == 240
    assert term_sample_count(10, 2) == 48 and term_sample_count(10**6, 3) == 2400  # floor and cap
    dist, _ = cKDTree(shape.points).query(samples)
    np.testing.assert_allclose(np.abs(targets), dist)
    assert dist.min() > 3 * 0.05
    # Farthest-point selection in the relative metric |x − s| / reach(x), reach = distance +
    # offset: when a sample was picked, every earlier one was at least (final largest hole) ×
    # its reach away, so any two samples are at least that × the smaller of their reaches apart.
    candidates, cand_targets = far_field_samples(shape.points, shape.normals, c=0.05, per_axis=96)
    hole = (cKDTree(samples).query(candidates)[0] / (np.abs(cand_targets) + SPREAD_OFFSET)).max()
    assert 0 < hole < 0.5  # the unit circle's mean radius is 1
    reach = np.abs(targets) + SPREAD_OFFSET
    apart = np.linalg.norm(samples[:, None] - samples[None], axis=-1) / np.minimum(reach[:, None], reach[None])
    np.fill_diagonal(apart, np.inf)
    assert apart.min() >= hole * (1 - 1e-12)
    # denser near the data: more samples in the inner half of the distance range
    near = np.abs(targets) < np.median(np.abs(cand_targets))
    assert near.mean() > 0.5


def test_objective_evaluates_the_term_in_its_own_pass(rng):
    shape = synthetic.torus(300, rng=rng)
    term = FarFieldTerm.from_data(shape.points, shape.normals, 4, weight=0.3)
    plain = Objective(shape.points, shape.normals, 4)
    fused = Objective(shape.points, shape.normals, 4, terms=[term])
    pop = shape.polynomial.coefficients + 0.2 * rng.normal(size=(12, 35))
    np.testing.assert_allclose(fused(pop), plain(pop) + term(pop), rtol=1e-12)
    assert np.all(term(pop) > 0) and np.any(term(pop) != term(pop)[0])
    # the measures stay the paper's: the term's samples are not data
    np.testing.assert_array_equal(fused.measures(pop).distance, plain.measures(pop).distance)
    fused32 = Objective(shape.points, shape.normals, 4, terms=[term], dtype=np.float32)
    np.testing.assert_allclose(fused32(pop), fused(pop), rtol=1e-4)
    with pytest.raises(ipfit.InvalidInputError, match="terms: expected far-field terms of degree 4"):
        Objective(shape.points, shape.normals, 4, terms=[FarFieldTerm.from_data(shape.points, shape.normals, 2, 1.0)])


@pytest.mark.parametrize("dim,degree", [(2, 6), (3, 4)])
def test_gradient_of_the_fused_objective_matches_finite_differences(dim, degree, rng):
    shape = synthetic.ellipse(150) if dim == 2 else synthetic.torus(300, rng=rng)
    fit = ipfit.fit_3l(shape.points, shape.normals, degree)
    u = fit.normalization.apply(shape.points)  # the fit's coefficients live in these coordinates
    term = FarFieldTerm.from_data(u, shape.normals, degree, weight=0.5)
    obj = Objective(u, shape.normals, degree, terms=[term])
    a = fit.coefficients + 0.05 * rng.normal(size=obj.n_coefficients)
    assert 0 < term(a)[0] < 0.5 * 2  # live, but not everywhere saturated
    _, grad, fd = value_grad_and_differences(obj, a)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_bound_screens_members_that_lose_on_the_data_alone(dim, rng):
    # A selection only needs to know which trials beat their bound: members whose distance
    # already exceeds it get that distance (a lower bound), the others their exact value.
    shape = synthetic.ellipse(200) if dim == 2 else synthetic.torus(400, rng=rng)
    degree = shape.polynomial.degree
    term = FarFieldTerm.from_data(shape.points, shape.normals, degree, weight=0.5)
    plain = Objective(shape.points, shape.normals, degree)
    fused = Objective(shape.points, shape.normals, degree, terms=[term])
    pop = shape.polynomial.coefficients + 0.3 * rng.normal(size=(40, n_coefficients(dim, degree)))
    exact, data = fused(pop), plain(pop)
    bound = np.median(data) + 0.01 * rng.normal(size=len(pop))
    screened = fused(pop, bound)
    beaten = data > bound
    assert 0 < beaten.sum() < len(pop)
    np.testing.assert_allclose(screened[~beaten], exact[~beaten], rtol=1e-12)
    np.testing.assert_allclose(screened[beaten], data[beaten], rtol=1e-12)
    assert np.all(screened[beaten] > bound[beaten]) and np.all(exact >= screened - 1e-12)
    # without a far-field term the bound changes nothing
    np.testing.assert_array_equal(plain(pop, bound), data)
    with pytest.raises(ipfit.InvalidInputError, match="bound: expected a \\(40,\\) array"):
        fused(pop, bound[:3])


def test_compiled_farthest_points_match_a_plain_numpy_selection(rng):
    from ipfit.geometry._distance_kernels import farthest_points

    candidates = rng.normal(size=(500, 3))
    reach = 0.5 + rng.random(500)
    gap, pick, expected = np.full(500, np.inf), int(np.argmin(reach)), []
    for _ in range(60):
        expected.append(pick)
        gap = np.minimum(gap, np.linalg.norm(candidates - candidates[pick], axis=1) / reach)
        pick = int(np.argmax(gap))
    chosen = np.empty(60, dtype=np.int64)
    farthest_points(candidates, reach, int(np.argmin(reach)), chosen)
    assert chosen.tolist() == expected and len(set(expected)) == 60


@pytest.mark.parametrize("dim", [2, 3])
def test_single_member_pass_is_the_sum_of_its_parts(dim, rng, monkeypatch):
    # The polish's compiled pass stacks the data and every far-field term's samples; its value
    # and gradient must be the paper's objective plus each term's own (numpy) value_and_grad,
    # whether the rows fit in one block or run in ragged blocks, and in a float32 objective too.
    import ipfit.fitting.objective as objective_module

    shape = synthetic.ellipse(300) if dim == 2 else synthetic.torus(600, rng=rng)
    degree = 4
    fit = ipfit.fit_3l(shape.points, shape.normals, degree)
    u = fit.normalization.apply(shape.points)
    terms = [FarFieldTerm.from_data(u, shape.normals, degree, weight=0.5),
             FarFieldTerm(1.6 * u[::20], np.full(len(u[::20]), 0.6), degree, weight=3.0)]  # kept-clear places
    a = fit.coefficients + 0.05 * rng.normal(size=fit.coefficients.size)
    value, grad = Objective(u, shape.normals, degree).value_and_grad(a)
    for term in terms:
        tv, tg = term.value_and_grad(a)
        value, grad = value + tv, grad + tg
    assert all(t.value_and_grad(a)[0] > 0 for t in terms)
    one = Objective(u, shape.normals, degree, terms=terms).value_and_grad(a)
    single32 = Objective(u, shape.normals, degree, terms=terms, dtype=np.float32).value_and_grad(a)
    monkeypatch.setattr(objective_module, "_SINGLE_ROWS", 97)
    blocked = Objective(u, shape.normals, degree, terms=terms).value_and_grad(a)
    for v, g in (one, single32, blocked):
        assert v == pytest.approx(value, rel=1e-12)
        np.testing.assert_allclose(g, grad, rtol=1e-9, atol=1e-12 * np.abs(grad).max())


def test_a_big_cloud_takes_its_far_field_from_an_even_subsample(monkeypatch):
    # Beyond FAR_FIELD_POINTS points the grid nodes' distances and sides come from an even
    # subsample: the same nodes away from the data, each distance at most the subsample's
    # covering radius longer than the exact one, and every side the same (a sphere: inside < 0).
    from scipy.spatial import cKDTree

    import ipfit.fitting.farfield as farfield_module

    shape = synthetic.sphere(4000, rng=np.random.default_rng(3))
    exact_nodes, exact = far_field_samples(shape.points, shape.normals)
    monkeypatch.setattr(farfield_module, "FAR_FIELD_POINTS", 1000)
    monkeypatch.setattr(farfield_module, "FAR_FIELD_SUBSAMPLE", 400)
    nodes, targets = far_field_samples(shape.points, shape.normals)
    pick = ipfit.geometry.sampling.spread_subsample(shape.points, 400)
    cover = float(cKDTree(shape.points[pick]).query(shape.points)[0].max())
    assert 0 < cover < 0.3  # coarser than the cloud, finer than the clearance (0.15) plus the grid
    common, at_exact, at_sub = np.intersect1d(exact_nodes.view("f8,f8,f8").ravel(), nodes.view("f8,f8,f8").ravel(),
                                              return_indices=True)
    assert len(common) >= 0.97 * len(exact_nodes) and len(nodes) <= len(exact_nodes) * 1.03
    gap = np.abs(targets[at_sub]) - np.abs(exact[at_exact])
    assert gap.min() >= -1e-12 and gap.max() <= cover + 1e-12
    assert np.array_equal(np.sign(targets[at_sub]), np.sign(exact[at_exact]))
    inside = np.linalg.norm(nodes, axis=1) < 1
    assert np.all(targets[inside] < 0) and np.all(targets[~inside] > 0)

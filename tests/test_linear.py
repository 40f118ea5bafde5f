"""Linear fits against exact shapes, invariances, the ridge penalty and bad input."""

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ipfit
from ipfit import basis
from ipfit.datasets import synthetic
from ipfit.fitting.linear import LINEAR_METHODS, fit_linear, ridge_penalty

EXACT_SHAPES = {
    "circle": (lambda: synthetic.circle(120, radius=2.5, center=(1.0, -3.0)), (2, 4)),
    "ellipse": (lambda: synthetic.ellipse(150, a=3.0, b=1.2, center=(-2.0, 0.5)), (2, 4)),
    "sphere": (lambda: synthetic.sphere(400, radius=0.5, center=(1.0, 2.0, -1.0)), (2, 4)),
    "torus": (lambda: synthetic.torus(1200, major=1.0, minor=0.4), (4,)),
}

# 3L targets ±c at distance c, but a polynomial of the shape's degree cannot be an exact signed
# distance off a curved shape: the zero set shifts by O(c² · curvature) with c = 0.05
# normalised units, i.e. about 1e-3 (measured up to 7e-3 on the torus, whose tube is thin).
TOLERANCE = {"3l": 1e-2, "ridge": 1e-2}
# Gradient-one asks ∇f = n: where no polynomial of that degree has unit gradient on the shape
# (an ellipse, a torus) the zero set is pulled off in proportion to μ (default 0.01; measured
# 1.2e-2 on the 3:1.2 ellipse at degree 2 and 1.3e-2 on the torus).
TOLERANCE["gradient_one"] = 3e-2


def _max_taubin(poly, points):
    return float(np.max(poly.taubin_distance(points)) / poly.scale)


@pytest.mark.parametrize("name", EXACT_SHAPES)
@pytest.mark.parametrize("method", ["lstsq", "taubin"])
def test_exact_methods_recover_exact_shapes(name, method):
    make, degrees = EXACT_SHAPES[name]
    shape = make()
    for degree in degrees:
        poly = fit_linear(shape.points, None, degree, method)
        assert _max_taubin(poly, shape.points) < 1e-8


@pytest.mark.parametrize("name", EXACT_SHAPES)
@pytest.mark.parametrize("method", ["3l", "ridge", "gradient_one"])
def test_normal_methods_recover_exact_shapes_within_tolerance(name, method):
    make, degrees = EXACT_SHAPES[name]
    shape = make()
    params = {"kappa": 1e-6} if method == "ridge" else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ipfit.ConditioningWarning)  # exact data: non-unique solutions
        for degree in degrees:
            poly = fit_linear(shape.points, shape.normals, degree, method, **params)
            assert _max_taubin(poly, shape.points) < TOLERANCE[method]
            # the gradient points along the outward normals
            grad = poly.gradient(shape.points)
            cos = np.sum(grad * shape.normals, axis=1) / np.linalg.norm(grad, axis=1)
            assert cos.min() > 0.9


def test_3l_on_the_circle_at_degree_two_is_the_circle():
    shape = synthetic.circle(100, radius=2.0)
    poly = ipfit.fit_3l(shape.points, shape.normals, 2)
    exact = shape.polynomial.canonical()
    np.testing.assert_allclose(poly.coefficients[[3, 5]] / poly.coefficients[0], exact.coefficients[[3, 5]] / exact.coefficients[0] * 4, rtol=5e-3)


def test_fits_are_canonical():
    shape = synthetic.ellipse(100)
    for method in LINEAR_METHODS:
        poly = fit_linear(shape.points, shape.normals, 2, method)
        assert np.linalg.norm(poly.coefficients) == pytest.approx(1.0)
        assert poly([[0.0, 0.0]])[0] < 0 < poly([[10.0, 0.0]])[0]
        assert poly.method == method
        assert "condition_number" in poly.info


def _blob(dim, rng):
    """A smooth star-shaped, slightly noisy closed shape that no low-degree polynomial fits exactly."""
    if dim == 2:
        t = np.sort(rng.uniform(0, 2 * np.pi, 300))
        r = 1 + 0.25 * np.cos(3 * t) + 0.1 * np.sin(2 * t) + rng.normal(0, 0.005, t.size)
        pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
        tang = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
        nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    else:
        d = rng.normal(size=(800, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        r = 1 + 0.2 * d[:, 0] ** 2 - 0.15 * d[:, 1] * d[:, 2]
        pts = d * r[:, None] * [1.5, 1.0, 0.8]
        nrm = pts / np.array([1.5, 1.0, 0.8]) ** 2  # approximate outward normals
    return pts, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def _transform(dim, rng):
    rot = Rotation.random(random_state=rng).as_matrix() if dim == 3 else None
    if dim == 2:
        angle = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return rot, rng.uniform(0.01, 100), rng.normal(0, 50, dim)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", ["taubin", "3l", "ridge", "gradient_one"])
def test_rotation_translation_scale_give_the_same_zero_set(dim, method, rng):
    pts, nrm = _blob(dim, rng)
    rot, scale, shift = _transform(dim, rng)
    moved = scale * pts @ rot.T + shift
    moved_normals = nrm @ rot.T
    before = fit_linear(pts, nrm, 4, method)
    after = fit_linear(moved, moved_normals, 4, method)
    d_before = before.taubin_distance(pts)
    d_after = after.taubin_distance(moved) / scale
    np.testing.assert_allclose(d_after, d_before, rtol=1e-5, atol=1e-9)
    # and the zero set itself: points of the fitted curve/surface map onto it
    grad = before.gradient(pts)
    on_zero_set = pts - (before(pts) / np.sum(grad**2, axis=1))[:, None] * grad  # one Newton step
    mapped = scale * on_zero_set @ rot.T + shift
    assert np.max(np.abs(after.taubin_distance(mapped)) / scale) < 10 * np.max(before.taubin_distance(on_zero_set)) + 1e-9


@pytest.mark.parametrize("dim", [2, 3])
def test_classic_least_squares_is_translation_and_scale_invariant(dim, rng):
    pts, nrm = _blob(dim, rng)
    before = ipfit.fit_lstsq(pts, degree=4)
    after = ipfit.fit_lstsq(pts * 3.7 - 12.0, degree=4)
    np.testing.assert_allclose(after.taubin_distance(pts * 3.7 - 12.0) / 3.7, before.taubin_distance(pts), rtol=1e-6, atol=1e-9)


def _homogeneous_rotated(coef, exps, rot, rng):
    """Coefficients of x ↦ f(Rᵀx) for a polynomial f, by interpolation at random points."""
    pts = rng.normal(size=(4 * len(exps), exps.shape[1]))
    values = basis.monomials(pts @ rot, exps) @ coef  # rows of pts @ rot are Rᵀx
    solved, *_ = np.linalg.lstsq(basis.monomials(pts, exps), values, rcond=None)
    return solved


@pytest.mark.parametrize("dim,degree", [(2, 4), (3, 2), (3, 4), (3, 6)])
def test_ridge_penalty_is_rotation_invariant_on_homogeneous_forms(dim, degree, rng):
    exps = basis.exponents(dim, degree)
    top = exps.sum(axis=1) == degree
    coef = np.where(top, rng.normal(size=len(exps)), 0.0)
    rot, _, _ = _transform(dim, rng)
    rotated = _homogeneous_rotated(coef, exps, rot, rng)
    assert np.abs(rotated[~top]).max() < 1e-8  # still homogeneous
    d = ridge_penalty(rng.normal(size=(30, dim)), exps)
    assert rotated @ (d * rotated) == pytest.approx(coef @ (d * coef), rel=1e-8)


def test_ridge_penalty_by_hand():
    u = np.array([[1.0, 0.0], [0.0, 2.0]])  # ||u||² = 1, 4
    d = ridge_penalty(u, basis.exponents(2, 2))
    # γ0 = 2, γ1 = 1 + 4 = 5, γ2 = 1 + 16 = 17; weights α!/|α|!: 1; 1, 1; 1, 1/2, 1
    np.testing.assert_allclose(d, [2, 5, 5, 17, 8.5, 17])


def test_ridge_with_zero_kappa_is_3l(rng):
    pts, nrm = _blob(2, rng)
    a = ipfit.fit_ridge(pts, nrm, 4, kappa=0.0)
    b = ipfit.fit_3l(pts, nrm, 4)
    np.testing.assert_allclose(a.coefficients, b.coefficients, atol=1e-10)


def test_larger_kappa_gives_a_rounder_fit(rng):
    pts, nrm = _blob(2, rng)
    dists = [np.mean(ipfit.fit_ridge(pts, nrm, 6, kappa=k).taubin_distance(pts)) for k in (0.0, 1e-3, 1e-1)]
    assert dists[0] < dists[1] < dists[2]


# -- bad input -------------------------------------------------------------------------
GOOD = synthetic.circle(50)


@pytest.mark.parametrize("call,match", [
    (lambda: ipfit.fit_3l(np.zeros((10, 4)), np.ones((10, 4)), 2), r"points: expected an array of shape \(N, 2\) or \(N, 3\)"),
    (lambda: ipfit.fit_lstsq(np.zeros(10), None, 2), r"points: expected an array of shape"),
    (lambda: ipfit.fit_lstsq(GOOD.points[:10], None, 4), r"at least 15 points .* got 10 points. Pass more points or lower the degree"),
    (lambda: ipfit.fit_lstsq(np.where(np.arange(50)[:, None] == 3, np.nan, GOOD.points), None, 2), r"finite coordinates, got 1 rows with NaN or inf \(first at row 3\)"),
    (lambda: ipfit.fit_lstsq(np.where(np.arange(50)[:, None] == 7, np.inf, GOOD.points), None, 2), r"NaN or inf \(first at row 7\)"),
    (lambda: ipfit.fit_3l(GOOD.points, None, 2), r"normals: expected .*required by fit_3l.* got None. Pass the file's normals or ipfit.estimate_normals"),
    (lambda: ipfit.fit_ridge(GOOD.points, np.zeros_like(GOOD.points), 2), r"non-zero normal vectors, got 50 zero-length normals"),
    (lambda: ipfit.fit_gradient_one(GOOD.points, GOOD.normals[:20], 2), r"normals: expected shape \(50, 2\) to match the points"),
    (lambda: ipfit.fit_3l(GOOD.points, GOOD.normals, 0), r"degree: expected an integer >= 1, got 0"),
    (lambda: ipfit.fit_lstsq(GOOD.points, None, 2.5), r"degree: expected an integer >= 1"),
    (lambda: ipfit.fit_3l(GOOD.points, GOOD.normals, 2, c=-1), r"c: expected a number > 0"),
    (lambda: ipfit.fit_3l(GOOD.points, GOOD.normals, 2, c=1e300), r"c: expected an offset in \(0, 10\]"),
    (lambda: ipfit.fit_ridge(GOOD.points, GOOD.normals, 2, kappa=1e300), r"kappa: expected a number in \[0, 1e\+12\]"),
    (lambda: ipfit.fit_linear(GOOD.points, GOOD.normals, 2, "lstsq", c=0.1), r"c: expected a parameter of the 'lstsq' fit"),
    (lambda: ipfit.fit_linear(GOOD.points, GOOD.normals, 2, method="nope"), r"method: expected one of 'lstsq', 'taubin', '3l', 'ridge', 'gradient_one', '3l-far'"),
    (lambda: ipfit.fit_lstsq([["a", "b"]], None, 2), r"points: expected an \(N, 2\) or \(N, 3\) array of numbers"),
])
def test_bad_input_names_the_problem_and_the_fix(call, match):
    with pytest.raises(ValueError, match=match) as info:
        call()
    assert isinstance(info.value, ipfit.InvalidInputError)
    assert "\n" not in str(info.value)


def test_all_fits_take_points_normals_degree_and_the_old_order_is_gone():
    shape = synthetic.ellipse(60)
    with pytest.raises(TypeError, match="normals"):  # (points, degree, normals) is no longer accepted
        ipfit.fit_lstsq(shape.points, 2, normals=shape.normals)
    with pytest.raises(TypeError, match="far_weight"):
        ipfit.fit_3l(shape.points, shape.normals, 2, far_weight=1e-3)
    far = ipfit.fit_linear(shape.points, shape.normals, 2, "3l-far")
    assert far.info["far_row_weight"] == ipfit.fitting.linear.DEFAULT_FAR_ROW_WEIGHT and far.info["far_samples"] > 0


@pytest.mark.parametrize("method", ["lstsq", "taubin", "3l", "ridge", "gradient_one", "3l-far"])
def test_blocked_qr_equals_the_one_shot_qr(monkeypatch, method):
    # Big clouds are factorised in row blocks (a running QR of [R; next block]); force tiny
    # blocks on a small cloud and compare with the one-shot factorisation.
    # Noisy, so that every method has one well-separated solution (an exact quadric has many at degree 4).
    shape = synthetic.ellipsoid(400, axes=(1.5, 1.0, 0.7))
    pts = shape.points + 0.02 * np.random.default_rng(1).normal(size=shape.points.shape)
    one_shot = ipfit.fit_linear(pts, shape.normals, 4, method)
    monkeypatch.setattr(ipfit.fitting.linear, "_BLOCK_ROWS", 97)  # arrays: nothing kept, so factored again, in blocks
    blocked = ipfit.fit_linear(pts, shape.normals, 4, method)
    np.testing.assert_allclose(blocked.coefficients, one_shot.coefficients, rtol=1e-9, atol=1e-12)


def test_start_fits_share_their_big_factors_and_solve_the_stacked_systems(monkeypatch, rng):
    # The search's dozen start fits on one Cloud factor each big block once (3L at each offset,
    # the values M and the gradient rows), the same fits of arrays each factor their own (nothing
    # is kept across calls) to the same coefficients, and each fit is still the least-squares
    # solution of its whole stacked system, here against numpy's lstsq of the explicit rows.
    from ipfit.fitting.options import DEFAULT_START_FITS, parse_start_fit

    shape = synthetic.torus(500, rng=rng)
    pts = shape.points + 0.01 * rng.normal(size=shape.points.shape)
    factored = []
    real = ipfit.fitting.linear._r_of_blocks
    monkeypatch.setattr(ipfit.fitting.linear, "_r_of_blocks", lambda blocks: factored.append(1) or real(blocks))
    cloud = ipfit.Cloud(pts, shape.normals)

    def start_fits(data, normals):
        return {spec: fit_linear(data, normals, 4, parse_start_fit(spec).method, **parse_start_fit(spec).params)
                for spec in DEFAULT_START_FITS}

    fits = start_fits(cloud, None)
    assert len(DEFAULT_START_FITS) == 11 and len(factored) == 5  # 3L at c = 0.05, 0.02, 0.1; M; the gradient rows
    assert start_fits(cloud, None).keys() == fits.keys() and len(factored) == 5  # the cloud kept all five
    del factored[:]
    from_arrays = start_fits(pts, shape.normals)
    assert len(factored) == 13  # each fit its own: 3L and ridge one each, gradient-one two, lstsq one (Taubin none)
    for spec, poly in from_arrays.items():
        assert poly.coefficients.tobytes() == fits[spec].coefficients.tobytes(), spec
    u = fits["3l"].normalization.apply(pts)
    m, dm = basis.monomials_and_gradients(u, 4)
    for spec, a_rows, b_rows in [
            ("gradient_one(mu=10)", np.vstack([m, np.sqrt(10) * dm.reshape(-1, m.shape[1])]),
             np.concatenate([np.zeros(len(m)), np.sqrt(10) * shape.normals.T.ravel()])),
            ("ridge(kappa=1e-3)", None, None)]:
        if a_rows is None:  # 3L rows at ±c plus the ridge rows √(κ D)
            c = ipfit.fitting.linear.DEFAULT_OFFSET
            off = np.concatenate([u, u + c * shape.normals, u - c * shape.normals])
            a_rows = np.vstack([basis.monomials(off, basis.exponents(3, 4)),
                                np.diag(np.sqrt(1e-3 * ridge_penalty(u, basis.exponents(3, 4))))])
            b_rows = np.concatenate([np.zeros(len(u)), np.full(len(u), c), np.full(len(u), -c),
                                     np.zeros(a_rows.shape[1])])
        expected = np.linalg.lstsq(a_rows, b_rows, rcond=None)[0]
        got = fits[spec].coefficients
        assert abs(abs(got @ expected) / np.linalg.norm(expected) - 1) < 1e-9  # the same line (fits are unit, signed)


@pytest.mark.slow
def test_a_million_point_3l_fit_stays_in_bounded_memory():
    import tracemalloc

    rng = np.random.default_rng(0)
    v = rng.normal(size=(1_000_000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    tracemalloc.start()
    poly = ipfit.fit_3l(v * [2.0, 1.0, 1.0], v / [2.0, 1.0, 1.0], 6)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    full = 3 * len(v) * poly.n_coefficients * 8  # the 3N × d design matrix alone (2 GB)
    assert peak < 0.45 * full  # a few row blocks of 2^17 rows (and their QR copies), never the whole matrix
    assert np.max(np.abs(poly(v[:1000] * [2.0, 1.0, 1.0]))) < 1e-3


def test_a_method_registered_once_is_a_fit_a_start_fit_and_a_cli_choice(monkeypatch):
    # One registry: a method added to LINEAR_METHODS (with its parameters) is accepted by
    # fit_linear, as a start fit "name(param=...)" with its checks, and by `ipfit fit --method`.
    from ipfit.cli import build_parser
    from ipfit.fitting.linear import LinearMethod

    def solve_wide_3l(problem, c=0.3):  # 3L at a wider default offset: a method of one's own
        return ipfit.fitting.linear._solve_3l(problem, c=c)

    monkeypatch.setitem(LINEAR_METHODS, "wide3l", LinearMethod(solve_wide_3l, needs_normals=True,
                                                               params={"c": ipfit.fitting.linear._offset}))
    shape = synthetic.ellipse(80)
    own = fit_linear(shape.points, shape.normals, 2, "wide3l", c=0.2)
    np.testing.assert_array_equal(own.coefficients, ipfit.fit_3l(shape.points, shape.normals, 2, c=0.2).coefficients)
    with pytest.raises(ipfit.InvalidInputError, match="kappa: expected a parameter of the 'wide3l' fit"):
        fit_linear(shape.points, shape.normals, 2, "wide3l", kappa=1.0)
    options = ipfit.SearchOptions(start_fits=("wide3l(c=0.2)",), far_term_weight=0.0)
    res = ipfit.refine(shape.points, shape.normals, 2, "polish", options=options, rng=0)
    assert list(res.start_distances) == ["wide3l(c=0.2)"] and res.success
    with pytest.raises(ipfit.InvalidInputError, match=r"^start_fits: expected valid parameters of wide3l.*c: expected"):
        ipfit.SearchOptions(start_fits=("wide3l(c=-1)",))
    assert build_parser().parse_args(["fit", "boot", "--method", "wide3l"]).method == "wide3l"
    assert ipfit.fit_adaptive(shape.points, shape.normals, method="wide3l", max_degree=2).polynomial.method == "wide3l"

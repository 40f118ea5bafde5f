"""Per-point weights and the robust fit of a cloud with strays left in (issue 30).

References are independent of the weighting code: a point of integer weight k is the point
repeated k times, a point of weight 0 is no point, the objective's weighted and truncated means
are computed by hand, and the fits are judged against shapes whose polynomial is known.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from numeric_checks import value_grad_and_differences

import ipfit
from ipfit import Cloud, ImplicitPolynomial, InvalidInputError, Normalization, basis, fit_linear
from ipfit.cloud import as_cloud
from ipfit.datasets import synthetic
from ipfit.fitting.farfield import far_field_samples
from ipfit.fitting.objective import TAUBIN_CAP, Objective
from ipfit.fitting.options import parse_start_fit
from ipfit.fitting.refine import robust_scale
from ipfit.fitting.starts import start_fits
from ipfit.robust import score_outliers
from ipfit.zeroset.extract import extract_zero_set
from ipfit.zeroset.quality import quality

_METHODS = ("lstsq", "taubin", "3l", "ridge", "gradient_one")
_A, _B = 1.0, 1.1  # a Cassini oval (x²+y²)² − 2a²(x²−y²) = b⁴ − a⁴ with a deep waist: a quartic no ellipse follows


def _cassini(n: int, rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points of the Cassini oval and their outward unit normals (∇f normalised)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) if rng is None else rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(_A**2 * np.cos(2 * t) + np.sqrt(_B**4 - _A**4 * np.sin(2 * t) ** 2))
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    s = (pts**2).sum(axis=1)
    grad = np.column_stack([4 * s * pts[:, 0] - 4 * _A**2 * pts[:, 0], 4 * s * pts[:, 1] + 4 * _A**2 * pts[:, 1]])
    return pts, grad / np.linalg.norm(grad, axis=1, keepdims=True)


def _strays(points: np.ndarray, share: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``share`` × N points uniform in the box grown by 20 % on each side, with random unit normals."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    extra = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=(int(share * len(points)), points.shape[1]))
    normals = rng.normal(size=extra.shape)
    return extra, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _noisy_shape(dim: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A noisy sample with normals, which no quartic fits exactly (so that weights matter)."""
    if dim == 2:
        pts, normals = _cassini(150, rng)
    else:
        shape = synthetic.torus(300, rng=rng)
        pts, normals = shape.points, shape.normals
    return pts + 0.02 * rng.normal(size=pts.shape), normals


# -- the cloud owns the weights ------------------------------------------------------------------
def test_a_cloud_keeps_checked_read_only_weights_and_pickles_them():
    pts = synthetic.circle(20).points
    w = np.linspace(0.0, 1.0, 20)
    cloud = Cloud(pts, weights=w)
    w[:] = 0.5  # the cloud holds its own copy
    assert cloud.weights is not None and not cloud.weights.flags.writeable
    assert cloud.weights[0] == 0.0 and cloud.weights[-1] == 1.0 and cloud.weights.dtype == np.float64
    back = pickle.loads(pickle.dumps(cloud))
    np.testing.assert_array_equal(back.weights, cloud.weights)
    assert not back.weights.flags.writeable
    assert Cloud(pts).weights is None and "weighted" in repr(cloud)
    np.testing.assert_array_equal(as_cloud(pts, weights=np.ones(20)).weights, np.ones(20))


@pytest.mark.parametrize("bad, words", [(np.ones(19), "one per point"), (np.full(20, 1.5), r"\[0, 1\]"),
                                        (np.full(20, np.nan), "NaN"), (np.zeros(20), "positive"),
                                        (["a"] * 20, "numbers")])
def test_bad_weights_are_one_line_errors(bad, words):
    with pytest.raises(InvalidInputError, match=words) as caught:
        Cloud(synthetic.circle(20).points, weights=bad)
    assert "\n" not in str(caught.value) and str(caught.value).startswith("weights:")
    with pytest.raises(InvalidInputError, match="weights"):
        as_cloud(Cloud(synthetic.circle(20).points), weights=np.ones(20))  # a cloud's own weights are used


# -- weighted linear fits --------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", _METHODS)
def test_integer_weights_are_repeated_points(rng, dim, method):
    pts, normals = _noisy_shape(dim, rng)
    counts = rng.integers(1, 4, size=len(pts))  # 1, 2 or 3 copies
    norm = Normalization.from_points(pts)  # the same coordinates for both (repeats move the mean)
    repeated = fit_linear(np.repeat(pts, counts, axis=0), np.repeat(normals, counts, axis=0), 4, method,
                          normalization=norm)
    # weights k/3: a common factor changes no least-squares solution (nor the ridge, whose
    # penalty is weighted alike)
    weighted = fit_linear(Cloud(pts, normals, weights=counts / 3.0), None, 4, method, normalization=norm)
    np.testing.assert_allclose(weighted.coefficients, repeated.coefficients, rtol=1e-7, atol=1e-9)
    plain = fit_linear(pts, normals, 4, method, normalization=norm)
    assert np.abs(plain.coefficients - repeated.coefficients).max() > 1e-4  # the weights did matter


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", _METHODS)
def test_zero_weights_drop_far_strays(rng, dim, method):
    pts, normals = _noisy_shape(dim, rng)
    extra, extra_normals = _strays(pts, 0.2, rng)
    everything = np.vstack([pts, extra])
    norm = Normalization.from_points(everything)
    weights = np.r_[np.ones(len(pts)), np.zeros(len(extra))]
    weighted = fit_linear(Cloud(everything, np.vstack([normals, extra_normals]), weights=weights), None, 4, method,
                          normalization=norm)
    without = fit_linear(pts, normals, 4, method, normalization=norm)
    np.testing.assert_allclose(weighted.coefficients, without.coefficients, rtol=1e-7, atol=1e-9)


# -- robust start fits (IRLS) ----------------------------------------------------------------------
def _ellipse_error(poly: ImplicitPolynomial) -> float:
    """The largest distance either way between the zero set and the ellipse (x/2)² + y² = 1,
    relative to its size 4 (first-order distances, exact to O(d²) near the ellipse)."""
    truth = synthetic.ellipse(2000, a=2.0, b=1.0).points
    zs = extract_zero_set(poly, bounds=[[-4.0, 4.0], [-2.5, 2.5]])
    if zs.is_empty:
        return np.inf
    v = np.vstack(zs.curves)
    out = np.abs((v[:, 0] / 2) ** 2 + v[:, 1] ** 2 - 1) / np.maximum(np.hypot(v[:, 0] / 2, 2 * v[:, 1]), 1e-12)
    return float(max(out.max(), poly.residuals(truth).max())) / 4.0


@pytest.mark.parametrize("offset", range(5))
@pytest.mark.parametrize("method", ["3l", "taubin"])
def test_reweighted_start_fits_ignore_strays_left_in(seed, offset, method):
    rng = np.random.default_rng(seed + offset)
    shape = synthetic.ellipse(300, a=2.0, b=1.0, rng=rng, random=True)
    extra, extra_normals = _strays(shape.points, 0.2, rng)
    # a scanner's normals: right on the shape, anything on the strays (normals estimated among
    # strays can be flipped along whole arcs, which no weighting of the points mends)
    pts, normals = np.vstack([shape.points, extra]), np.vstack([shape.normals, extra_normals])
    norm = Normalization.from_points(pts)
    fits = [parse_start_fit(method)]
    # weights all 1: the score was told to keep every point, so only the reweighting can help
    weighted = Cloud(pts, normals, weights=np.ones(len(pts)))
    irls = start_fits(weighted, 2, norm, fits, None, False, scale=robust_scale(weighted))
    plain = start_fits(Cloud(pts, normals), 2, norm, fits, None, False)
    exps = basis.exponents(2, 2)
    assert _ellipse_error(ImplicitPolynomial(exps, irls.coefficients[0], norm)) < 0.01
    assert _ellipse_error(ImplicitPolynomial(exps, plain.coefficients[0], norm)) > 0.02
    assert any("reweighted" in note for note in irls.notes)


# -- the objective's weights and truncation -------------------------------------------------------
def test_unit_weights_and_the_default_cap_are_the_plain_objective(rng):
    shape = synthetic.torus(300, rng=rng)
    population = shape.polynomial.coefficients + 0.2 * rng.normal(size=(9, 35))
    plain = Objective(shape.points, shape.normals, 4)
    ones = Objective(shape.points, shape.normals, 4, weights=np.ones(300), cap=TAUBIN_CAP)
    np.testing.assert_allclose(ones(population), plain(population), rtol=1e-13)
    np.testing.assert_allclose(ones.measures(population).smoothness, plain.measures(population).smoothness, rtol=1e-13)
    (v1, g1), (v0, g0) = ones.value_and_grad(population[0]), plain.value_and_grad(population[0])
    assert v1 == pytest.approx(v0, rel=1e-13)
    np.testing.assert_allclose(g1, g0, rtol=1e-12, atol=1e-14 * np.abs(g0).max())


def test_weighted_truncated_measures_by_hand():
    # x² + y² − 1 at (1, 0) normal (1, 0): Taubin 0, cosine 1; at (2, 0) normal (0, 1): Taubin
    # 3/4, cosine 0; at (0, 3) normal (0, 1): Taubin 8/6, truncated to 1, cosine 1.
    circle = [-1.0, 0, 0, 1.0, 0, 1.0]
    obj = Objective([[1.0, 0.0], [2.0, 0.0], [0.0, 3.0]], [[1.0, 0.0], [0.0, 1.0], [0.0, 1.0]], 2,
                    weights=[1.0, 0.5, 0.25], cap=1.0)
    m = obj.measures(circle)[0]
    assert m.dissimilarity == pytest.approx((0.5 * 0.75 + 0.25 * 1.0) / 1.75)
    assert m.smoothness == pytest.approx((1.0 + 0.25) / 1.75)
    assert m.distance == pytest.approx(3.0 / 7.0)
    assert obj(circle)[0] == pytest.approx(3.0 / 7.0) and obj.value_and_grad(circle)[0] == pytest.approx(3.0 / 7.0)
    with pytest.raises(InvalidInputError, match="cap"):
        Objective([[1.0, 0.0]], [[1.0, 0.0]], 2, cap=0.0)


@pytest.mark.parametrize("dim, degree", [(2, 3), (3, 4)])
def test_gradient_with_weights_and_truncation_matches_finite_differences(rng, dim, degree):
    u = rng.normal(size=(200, dim))
    normals = rng.normal(size=(200, dim))
    a = rng.normal(size=basis.n_coefficients(dim, degree))
    m, dm = basis.monomials_and_gradients(u, degree)
    dist = np.sort(np.abs(m @ a) / np.linalg.norm(np.stack([dk @ a for dk in dm]), axis=0))
    # a cap between two distances far apart from each other: no point crosses it under a difference step
    k = 100 + int(np.argmax(np.diff(dist[100:160])))
    cap = 0.5 * (dist[k] + dist[k + 1])
    obj = Objective(u, normals, degree, delta=0.3, weights=rng.uniform(0.1, 1.0, 200), cap=cap)
    _, grad, numeric = value_grad_and_differences(obj, a)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-7 * np.abs(grad).max())
    assert abs(grad @ a) < 1e-10 * np.linalg.norm(grad) * np.linalg.norm(a)  # still scale invariant


# -- the far field of a cloud with strays ----------------------------------------------------------
def test_a_stray_with_a_wrong_normal_is_outvoted_on_the_side_of_the_far_field():
    shape = synthetic.circle(200)
    # a stray just inside the circle whose normal says "inside is outside"
    pts = np.vstack([shape.points, [[0.0, 0.55]]])
    normals = np.vstack([shape.normals, [[0.0, -1.0]]])
    inside = lambda s: np.linalg.norm(s, axis=1) < 1  # noqa: E731
    samples, targets = far_field_samples(pts, normals, voters=7)
    assert np.all((targets < 0) == inside(samples))
    samples, targets = far_field_samples(pts, normals)  # the nearest point alone: the stray decides
    assert np.any((targets < 0) != inside(samples))


# -- end to end: strays the score misses -----------------------------------------------------------
def test_strays_the_score_misses_stop_pulling_the_fit(seed):
    truth = _cassini(2000)[0]
    robust_f, plain_f = [], []
    for run in range(seed, seed + 5):
        rng = np.random.default_rng(run)
        shape, normals = _cassini(300, rng)
        extra, extra_normals = _strays(shape, 0.25, rng)
        pts, nrm = np.vstack([shape, extra]), np.vstack([normals, extra_normals])
        # 5 % forced while 20 % (25 % of the shape's points) were planted: most strays stay in the fit
        result = ipfit.fit_adaptive(pts, nrm, outliers=0.05, max_degree=4, rng=run)
        kept = result.outliers.inliers
        assert kept.tolist() == score_outliers(pts, outliers=0.05).inliers.tolist()
        assert kept[len(shape):].sum() >= 0.5 * len(extra)
        # today's fit: the same points left out, the rest fitted without weights or robust loss
        plain = ipfit.fit_adaptive(pts[kept], nrm[kept], outliers="none", max_degree=4, rng=run)
        robust_f.append(quality(result.polynomial, truth, ordered_contour=True).f_score)
        plain_f.append(quality(plain.polynomial, truth, ordered_contour=True).f_score)
    # Every robust fit finds the shape; a plain search sometimes does too (measured on seeds 0-14:
    # 3 of 15, F 0.41-0.48 otherwise), so it is judged on the five together.
    assert min(robust_f) > 0.95, robust_f
    assert all(r >= p - 0.01 for r, p in zip(robust_f, plain_f, strict=True)), (robust_f, plain_f)
    assert np.mean(robust_f) > np.mean(plain_f) + 0.1, (robust_f, plain_f)

"""ImplicitPolynomial.residuals and the scikit-image model protocol, with scikit-image's real ransac.

References are hand-derived first-order distances, analytic shapes with known polynomials, the
true distance of projected points, and invariances; the RANSAC tests plant outliers and check
the recovered shape and the inlier mask against what was planted.
"""

import warnings
from contextlib import contextmanager

import numpy as np
import pytest
from skimage.measure import ransac
from skimage.measure.fit import RansacModelProtocol

from ipfit import ImplicitPolynomial, ImplicitPolynomialModel, InvalidInputError, Normalization, fit_taubin
from ipfit.datasets import synthetic
from ipfit.fitting.model import MODEL_METHODS

UNIT_CIRCLE = [-1, 0, 0, 1, 0, 1]  # x² + y² − 1 in the graded basis 1, x, y, x², xy, y²


@contextmanager
def no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# -- residuals ---------------------------------------------------------------------------------
def test_residuals_are_the_hand_derived_first_order_distances():
    circle = ImplicitPolynomial.from_coefficients(UNIT_CIRCLE, dim=2)
    # |x² + y² − 1| / ||(2x, 2y)||: (2, 0) → 3/4, (0, 0.5) → 0.75/1, (0.6, 0.8) on the circle → 0
    np.testing.assert_allclose(circle.residuals([[2.0, 0.0], [0.0, 0.5], [0.6, 0.8], [0.0, -3.0]]),
                               [0.75, 0.75, 0.0, 8 / 6], rtol=1e-14, atol=1e-15)
    # the circle of radius 2 around (1, −1) in normalised coordinates u = (x − (1, −1)) / 2:
    # f = ((x−1)² + (y+1)²)/4 − 1, ∇f = ((x−1)/2, (y+1)/2); at (5, −1) f = 3, ||∇f|| = 2
    norm = Normalization([1.0, -1.0], 2.0)
    big = ImplicitPolynomial.from_coefficients(UNIT_CIRCLE, dim=2, normalization=norm)
    # and at (1, −2), inside, f = −3/4, ||∇f|| = 1/2
    np.testing.assert_allclose(big.residuals([[5.0, -1.0], [1.0, 1.0], [1.0, -2.0]]), [1.5, 0.0, 1.5],
                               rtol=1e-14, atol=1e-15)


def test_residuals_approach_the_true_distance_near_the_zero_set(rng):
    shape = synthetic.ellipse(400, a=3.0, b=1.0)
    offsets = rng.uniform(-1e-3, 1e-3, len(shape.points))
    pts = shape.points + offsets[:, None] * shape.normals  # known true distance |offset| to first order
    true = shape.polynomial.project(pts).distances
    np.testing.assert_allclose(shape.polynomial.residuals(pts), true, rtol=1e-2, atol=1e-9)


def test_zero_gradients_give_zero_on_the_zero_set_and_inf_off_it_without_warnings():
    # (x² + y² − 1)²: its gradient vanishes on the whole circle and at the origin
    square = ImplicitPolynomial.from_coefficients([1, 0, 0, -2, 0, -2, 0, 0, 0, 0, 1, 0, 2, 0, 1], dim=2)
    with no_warnings():
        got = square.residuals([[1.0, 0.0], [0.0, -1.0], [0.0, 0.0], [2.0, 0.0]])
    # (2, 0): f = 9, ∇f = 2(r² − 1)·2x = 24
    np.testing.assert_allclose(got, [0.0, 0.0, np.inf, 9 / 24], rtol=1e-14)


def test_residuals_do_not_overflow_far_from_the_data():
    circle = ImplicitPolynomial.from_coefficients(UNIT_CIRCLE, dim=2)
    quartic = synthetic.from_terms(2, 4, {(4, 0): 1, (0, 4): 1, (0, 0): -1})  # x⁴ + y⁴ − 1
    with no_warnings():
        far = circle.residuals([[1e200, 0.0], [0.0, -1e300], [1e-200, 0.0]])
        far4 = quartic.residuals([[1e100, 0.0], [3e200, 0.0]])
    # |x² − 1| / |2x| = |x/2 − 1/(2x)|, and |x⁴ − 1| / |4x³| = x/4 for these x
    np.testing.assert_allclose(far, [5e199, 5e299, 5e199], rtol=1e-14)
    np.testing.assert_allclose(far4, [2.5e99, 7.5e199], rtol=1e-14)


def test_residuals_scale_with_the_data_and_ignore_the_coefficients_scale(rng):
    shape = synthetic.ellipse(300, a=2.0, b=1.0, center=(0.5, -0.3))
    poly = fit_taubin(shape.points + rng.normal(scale=0.02, size=shape.points.shape), degree=4)
    pts = rng.uniform(-3, 3, (200, 2))
    base = poly.residuals(pts)
    assert np.isfinite(base).all() and base.max() > 0.5
    shift = rng.normal(size=2)
    for k in (1e-150, 3.7, 1e150):
        # the same polynomial on the data mapped by x → k (x + shift): distances scale by k
        moved = ImplicitPolynomial(poly.exponents, poly.coefficients,
                                   Normalization((poly.center + shift) * k, poly.scale * k))
        np.testing.assert_allclose(moved.residuals((pts + shift) * k) / k, base, rtol=1e-9)
    for c in (-1e-200, 7.0, 1e200):
        scaled = poly.with_coefficients(c * poly.coefficients)
        np.testing.assert_allclose(scaled.residuals(pts), base, rtol=1e-9, atol=1e-12)


def test_residuals_check_their_points():
    circle = ImplicitPolynomial.from_coefficients(UNIT_CIRCLE, dim=2)
    for bad in ([[np.nan, 0.0]], [[1.0, 2.0, 3.0]], "points"):
        with pytest.raises(InvalidInputError, match="points"):
            circle.residuals(bad)


# -- the model ---------------------------------------------------------------------------------
def _cassini(theta, a=1.0, b=1.2):
    """Points of the Cassini oval (x²+y²)² − 2a²(x²−y²) + a⁴ − b⁴ = 0 (one peanut loop, b > a)."""
    r = np.sqrt(a * a * np.cos(2 * theta) + np.sqrt(b**4 - a**4 * np.sin(2 * theta) ** 2))
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


CASSINI = synthetic.from_terms(2, 4, {(4, 0): 1, (0, 4): 1, (2, 2): 2, (2, 0): -2, (0, 2): 2, (0, 0): 1 - 1.2**4})


def test_a_minimal_sample_determines_the_known_polynomial(rng):
    ellipse = synthetic.ellipse(200, a=3.0, b=1.0, center=(2.0, -1.0))
    sphere = synthetic.sphere(300, radius=2.0, center=(1.0, 2.0, 3.0))
    cases = [(ImplicitPolynomialModel, ellipse.points, 2), (ImplicitPolynomialModel, sphere.points, 3),
             (ImplicitPolynomialModel.for_degree(4), _cassini(np.linspace(0, 2 * np.pi, 300)), 2)]
    assert np.abs(CASSINI(cases[2][1])).max() < 1e-12  # the points are on the known quartic
    for model_class, dense, dim in cases:
        n = model_class.min_samples(dim)
        for method in MODEL_METHODS:
            cls = model_class.for_degree(model_class.degree, method)
            model = cls.from_estimate(dense[rng.choice(len(dense), n, replace=False)])
            assert model and model.polynomial.degree == cls.degree and model.polynomial.method == method
            # the fitted zero set passes through every point of the known one
            assert model.residuals(dense).max() < 1e-7 * np.ptp(dense, axis=0).max()


def test_min_samples_is_the_number_of_coefficients_minus_one():
    expected = {(2, 2): 5, (3, 2): 9, (2, 4): 14, (3, 4): 34, (2, 6): 27}
    for (dim, degree), n in expected.items():
        assert ImplicitPolynomialModel.for_degree(degree).min_samples(dim) == n
    assert ImplicitPolynomialModel.min_samples(2) == 5  # the base class is the conic
    with pytest.raises(InvalidInputError, match="dim"):
        ImplicitPolynomialModel.min_samples(4)


def test_degenerate_samples_fail_without_raising_or_warning():
    t = np.linspace(-1.0, 2.0, 5)
    circle = synthetic.circle(40, radius=2.0).points
    quartic = ImplicitPolynomialModel.for_degree(4)
    cases = {
        "collinear": (ImplicitPolynomialModel, np.column_stack([t, 3 * t - 1])),
        "four on a line": (ImplicitPolynomialModel, np.vstack([np.column_stack([t[:4], 2 * t[:4]]), [[0.0, 5.0]]])),
        "a repeated point": (ImplicitPolynomialModel, np.vstack([circle[:4], circle[:1]])),
        "one point": (ImplicitPolynomialModel, np.repeat([[1.0, 2.0]], 6, axis=0)),
        "too few": (ImplicitPolynomialModel, circle[:4]),
        "none": (ImplicitPolynomialModel, np.empty((0, 2))),
        "coplanar": (ImplicitPolynomialModel, np.column_stack([circle[:12], np.zeros(12)])[:, [0, 2, 1]]),
        "exact circle, degree 4": (quartic, circle),
    }
    with no_warnings():
        for what, (cls, data) in cases.items():
            model = cls.from_estimate(data)
            assert not model and model.polynomial is None and model.message, what
            old = cls()
            assert old.estimate(data) is False and not old, what
            with pytest.raises(InvalidInputError, match="fitted model"):
                model.residuals(circle)


def test_bad_arguments_raise():
    with pytest.raises(InvalidInputError, match="data"):
        ImplicitPolynomialModel.from_estimate([[np.nan, 0.0]] * 6)
    with pytest.raises(InvalidInputError, match="data"):
        ImplicitPolynomialModel.from_estimate(np.zeros((6, 4)))
    with pytest.raises(InvalidInputError, match="method"):
        ImplicitPolynomialModel.for_degree(2, method="3l")  # needs normals, which a sample has not
    with pytest.raises(InvalidInputError, match="degree"):
        ImplicitPolynomialModel.for_degree(0)
    with pytest.raises(InvalidInputError, match="degree"):
        ImplicitPolynomialModel.for_degree(25).from_estimate(np.random.default_rng(0).normal(size=(40, 3)))


def test_both_protocols_fit_the_same_polynomial(rng):
    pts = synthetic.ellipse(50, a=2.0, b=1.0, rng=rng, random=True).points
    new = ImplicitPolynomialModel.from_estimate(pts)
    old = ImplicitPolynomialModel()
    assert not old and old.estimate(pts) is True and old
    np.testing.assert_array_equal(old.polynomial.coefficients, new.polynomial.coefficients)
    assert isinstance(ImplicitPolynomialModel, RansacModelProtocol)
    assert isinstance(ImplicitPolynomialModel.for_degree(4), RansacModelProtocol)


# -- with scikit-image's ransac ------------------------------------------------------------------
def _planted(rng, inliers: np.ndarray, fraction: float, grow: float = 0.2):
    """``inliers`` with uniform outliers in their box grown by ``grow`` on each side, shuffled."""
    n_out = round(fraction * len(inliers) / (1 - fraction))
    lo, hi = inliers.min(axis=0), inliers.max(axis=0)
    outliers = rng.uniform(lo - grow * (hi - lo), hi + grow * (hi - lo), (n_out, inliers.shape[1]))
    pts = np.vstack([inliers, outliers])
    planted = np.r_[np.zeros(len(inliers), bool), np.ones(n_out, bool)]
    order = rng.permutation(len(pts))
    return pts[order], planted[order]


def _centre_and_radius(poly: ImplicitPolynomial):
    """Centre and radius of a circle or sphere from a quadratic f alone: ∇f(x) = J x + g is
    affine, its zero the centre, and f = λ||x − c||² + f(c) with J = 2λI."""
    dim = poly.dim
    g0 = poly.gradient(np.zeros((1, dim)))[0]
    jac = (poly.gradient(np.eye(dim)) - g0).T
    centre = np.linalg.solve(jac, -g0)
    lam = np.trace(jac) / (2 * dim)
    radius = np.sqrt(-poly(centre[None])[0] / lam)
    return centre, radius, jac / (2 * lam)


@pytest.mark.parametrize("dim", [2, 3])
def test_ransac_recovers_a_circle_and_a_sphere_among_30_percent_outliers(seed, dim):
    centre, radius = np.array([2.0, -1.0, 0.5][:dim]), 5.0
    threshold = 0.01 * radius
    # A clean minimal sample is 0.7⁵ = 17% of conic samples and 0.7⁹ = 4% of quadric ones, and
    # the returned mask is that of the best sample's fit: quadrics need more trials.
    trials, n_seeds = {2: (150, 5), 3: (400, 3)}[dim]
    for s in range(seed, seed + n_seeds):
        rng = np.random.default_rng(s)
        directions = rng.normal(size=(300 if dim == 2 else 200, dim))
        on = centre + radius * directions / np.linalg.norm(directions, axis=1, keepdims=True)
        pts, planted = _planted(rng, on + rng.normal(scale=threshold / 5, size=on.shape), 0.3)
        with no_warnings():  # scikit-image 0.26 warns (FutureWarning) about models without from_estimate
            model, inliers = ransac(pts, ImplicitPolynomialModel, ImplicitPolynomialModel.min_samples(dim),
                                    threshold, max_trials=trials, stop_probability=0.999, rng=s)
        assert isinstance(model, ImplicitPolynomialModel) and model.polynomial.degree == 2
        got_centre, got_radius, shape = _centre_and_radius(model.polynomial)
        assert np.linalg.norm(got_centre - centre) < 0.01 * radius, s
        assert abs(got_radius - radius) < 0.01 * radius, s
        np.testing.assert_allclose(shape, np.eye(dim), atol=0.01)  # round, not an ellipse
        # The masks flag every planted outlier clear of the band (those that fell within the
        # threshold of the shape are inliers by definition). ransac's own is that of the best
        # sample's fit, a quadric through 9 noisy points that may miss a few inliers; the final
        # fit's (on all of them) keeps every planted inlier.
        true_distance = np.abs(np.linalg.norm(pts - centre, axis=1) - radius)
        clear = planted & (true_distance > 2 * threshold)
        final = model.residuals(pts) < threshold
        for mask in (inliers, final):
            assert not mask[clear].any(), s
            assert (~mask[planted]).mean() >= 0.85, s
        assert inliers[~planted].mean() >= 0.8, s
        assert final[~planted].mean() >= 0.99, s


def test_ransac_on_exact_points_keeps_exactly_the_points_near_the_shape(seed):
    # Exact ellipse points: the best sample is a clean one, whose fit is the ellipse itself, so the
    # mask is the known polynomial's, and the final fit (on those inliers, a few outliers within
    # the threshold among them) stays within a tenth of the threshold of the ellipse.
    for s in range(seed, seed + 5):
        rng = np.random.default_rng(s)
        shape = synthetic.ellipse(200, a=3.0, b=1.0, center=(1.0, 1.0), rng=rng, random=True)
        pts, planted = _planted(rng, shape.points, 0.3)
        model, inliers = ransac(pts, ImplicitPolynomialModel, 5, 0.02, max_trials=100, stop_probability=0.999, rng=s)
        np.testing.assert_array_equal(inliers, shape.polynomial.residuals(pts) < 0.02)
        assert inliers[~planted].all() and (~inliers[planted]).mean() > 0.9
        assert model.residuals(shape.points).max() < 0.002

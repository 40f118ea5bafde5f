"""Outlier scores, weights and noise scale from the points alone (ipfit.robust), and normals that
stray points do not spoil.

The clouds follow the real-clouds protocol (issue 30): Gaussian noise of σ = 0.5 % or 1 % of the
box diagonal, uniform strays in the bounding box grown by 20 % on each side, shuffled, no normals.
Quality tests hold for IPFIT_TEST_SEED = 0..4 (the seed fixture); each also runs two more seeds.
"""

import numpy as np
import pytest

from ipfit.datasets import synthetic
from ipfit.exceptions import InvalidInputError
from ipfit.normals import estimate_normals, normal_agreement
from ipfit.robust import OutlierScore, score_outliers


def planted(points, share, noise, rng):
    """The protocol: noise, then round(share * N) uniform strays in the grown box, shuffled."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    sigma = noise * float(np.linalg.norm(hi - lo))
    noisy = points + rng.normal(scale=sigma, size=points.shape)
    strays = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), (round(share * len(points)), points.shape[1]))
    cloud = np.vstack([noisy, strays])
    truth = np.r_[np.zeros(len(points), bool), np.ones(len(strays), bool)]
    order = rng.permutation(len(cloud))
    return cloud[order], truth[order], sigma


def ellipse(rng):
    return synthetic.ellipse(400, rng=rng, random=True).points


def sphere(rng):
    return synthetic.sphere(2000, rng=rng).points


SHAPES = pytest.mark.parametrize("shape", [ellipse, sphere], ids=["ellipse", "sphere"])


def seeds(seed):
    return [seed, seed + 100, seed + 200]


# -- finding planted strays -------------------------------------------------------------------

@SHAPES
@pytest.mark.parametrize("share", [0.1, 0.25, 0.4])
def test_planted_outliers_are_found_without_false_alarms(shape, share, seed):
    for s in seeds(seed):
        rng = np.random.default_rng(s)
        cloud, truth, _ = planted(shape(rng), share, 0.0, rng)
        result = score_outliers(cloud)
        found = (~result.inliers[truth]).mean()
        false_alarms = (~result.inliers[~truth]).mean()
        assert found >= 0.95, (s, found)
        assert false_alarms <= 0.02, (s, false_alarms)
        assert result.outlier_share == pytest.approx((~result.inliers).mean())


@SHAPES
@pytest.mark.parametrize("noise", [0.0, 0.005, 0.01])
def test_clean_clouds_flag_at_most_one_percent(shape, noise, seed):
    for s in seeds(seed):
        rng = np.random.default_rng(s)
        cloud, _, _ = planted(shape(rng), 0.0, noise, rng)
        assert score_outliers(cloud).outlier_share <= 0.01, s


@SHAPES
@pytest.mark.parametrize("noise", [0.005, 0.01])
@pytest.mark.parametrize("share", [0.0, 0.25])
def test_noise_scale_is_within_a_factor_1_5_of_the_true_sigma(shape, noise, share, seed):
    for s in seeds(seed):
        rng = np.random.default_rng(s)
        cloud, _, sigma = planted(shape(rng), share, noise, rng)
        ratio = score_outliers(cloud).noise_scale / sigma
        assert 1 / 1.5 <= ratio <= 1.5, (s, ratio)


def test_noisy_strays_far_from_the_shape_are_found(seed):
    # With noise, strays within a few σ of the curve are samples as far as anyone can tell;
    # those farther than 6 σ must be found.
    for s in seeds(seed):
        rng = np.random.default_rng(s)
        shape = synthetic.ellipse(400, rng=rng, random=True)
        cloud, truth, sigma = planted(shape.points, 0.25, 0.01, rng)
        poly = shape.polynomial
        # first-order distance to the ellipse, good to a few % this close to it
        distance = np.abs(poly(cloud)) / np.linalg.norm(poly.gradient(cloud), axis=1)
        far = truth & (distance > 6 * sigma)
        assert (~score_outliers(cloud).inliers[far]).mean() >= 0.95, s


def test_spacing_is_the_samples_spacing(seed):
    rng = np.random.default_rng(seed)
    circle = synthetic.circle(500).points  # evenly spaced: neighbours 2π/500 apart
    cloud, _, _ = planted(circle, 0.25, 0.0, rng)
    assert score_outliers(cloud).spacing == pytest.approx(2 * np.pi / 500, rel=1e-3)


def test_weights_fall_with_the_distance_from_the_shape():
    circle = synthetic.circle(400).points
    probes = np.array([[1.0 + d, 0.0] for d in (0.0, 0.001, 0.05, 0.2, 0.5)])
    # strays far from the circle (radius 1.6-2.5), enough of them (10 %) to be evidence
    rng = np.random.default_rng(3)
    angle, radius = rng.uniform(0, 2 * np.pi, 40), rng.uniform(1.6, 2.5, 40)
    strays = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    result = score_outliers(np.vstack([circle, strays, probes]))
    w = result.weights[-5:]
    assert w[0] > 0.99 and w[1] > 0.9
    assert np.all(np.diff(w) <= 0) and w[-1] < 0.01
    assert not result.inliers[400:440].any()
    np.testing.assert_array_equal(result.inliers, result.weights >= 0.5)
    np.testing.assert_allclose(result.weights, 1 / (1 + result.score ** 4))


def test_a_few_strays_are_scored_but_not_acted_on():
    """Under 2 % of the points beyond score 3 is no evidence: 'auto' keeps every point."""
    circle = synthetic.circle(400).points
    probes = np.array([[1.0 + d, 0.0] for d in (0.2, 0.5)])
    result = score_outliers(np.vstack([circle, probes]))
    assert np.all(result.score[-2:] > 3)
    assert result.count == 0 and np.all(result.weights == 1.0)


# -- invariances -------------------------------------------------------------------------------

def _agree(a: OutlierScore, b: OutlierScore, length_ratio: float = 1.0):
    # Rounding only: moving the cloud 3e3 away at scale 1e-4 leaves 7 digits of its shape, and
    # the scores keep 5 (1e-6 relative measured).
    np.testing.assert_allclose(a.score, b.score, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(a.weights, b.weights, rtol=1e-4, atol=1e-6)
    near_cut = np.abs(a.score - 1.0) < 1e-3
    assert np.array_equal(a.inliers[~near_cut], b.inliers[~near_cut])
    assert b.noise_scale == pytest.approx(a.noise_scale * length_ratio, rel=1e-6)
    assert b.spacing == pytest.approx(a.spacing * length_ratio, rel=1e-6)


@SHAPES
def test_invariant_to_translation_scale_rotation_and_order(shape, seed):
    rng = np.random.default_rng(seed)
    cloud, _, _ = planted(shape(rng), 0.25, 0.005, rng)
    base = score_outliers(cloud)
    dim = cloud.shape[1]
    rotation, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    _agree(base, score_outliers(cloud @ rotation.T))
    _agree(base, score_outliers(cloud * 1e-4 + 3e3), 1e-4)
    _agree(base, score_outliers(cloud * 7.5 - 2.0), 7.5)
    order = rng.permutation(len(cloud))
    shuffled = score_outliers(cloud[order])
    np.testing.assert_array_equal(shuffled.score, base.score[order])  # the same computation, reordered
    assert shuffled.noise_scale == base.noise_scale


def test_duplicate_points_share_their_score():
    rng = np.random.default_rng(0)
    cloud, _, _ = planted(synthetic.circle(300).points, 0.1, 0.0, rng)
    doubled = score_outliers(np.vstack([cloud, cloud[:50]]))
    np.testing.assert_array_equal(doubled.score[-50:], doubled.score[:50])


# -- the modes -----------------------------------------------------------------------------------

def test_none_keeps_every_point_with_weight_one(seed):
    rng = np.random.default_rng(seed)
    cloud, _, sigma = planted(synthetic.circle(300).points, 0.25, 0.01, rng)
    auto, none = score_outliers(cloud), score_outliers(cloud, outliers="NONE")
    assert np.all(none.weights == 1.0) and none.inliers.all() and none.outlier_share == 0.0
    assert (none.noise_scale, none.spacing) == (auto.noise_scale, auto.spacing)
    np.testing.assert_array_equal(none.score, auto.score)
    assert auto.outlier_share > 0.1 and 0.6 < none.noise_scale / sigma < 1.5


@pytest.mark.parametrize("fraction", [0.0, 0.05, 0.2, 0.5, 0.89])
def test_a_fraction_marks_exactly_that_many_highest_scored_points(fraction, seed):
    rng = np.random.default_rng(seed)
    cloud, _, _ = planted(synthetic.circle(301).points, 0.2, 0.005, rng)
    result = score_outliers(cloud, outliers=fraction)
    expected = round(fraction * len(cloud))
    assert (~result.inliers).sum() == expected
    assert result.outlier_share == pytest.approx(expected / len(cloud))
    np.testing.assert_array_equal(result.inliers, result.weights >= 0.5)
    if 0 < expected < len(cloud):
        assert result.score[~result.inliers].min() >= result.score[result.inliers].max()
    assert np.all((result.weights > 0) & (result.weights <= 1))


def test_a_fraction_of_tied_points_is_split_consistently():
    # 100 copies of one stray share one score: a fraction that cuts through them still marks
    # exactly round(F N) points, and their weights agree with the mask.
    circle = synthetic.circle(200).points
    cloud = np.vstack([circle, np.repeat([[3.0, 3.0]], 100, axis=0)])
    result = score_outliers(cloud, outliers=0.2)
    assert (~result.inliers).sum() == 60
    assert (~result.inliers[:200]).sum() == 0
    np.testing.assert_array_equal(result.inliers, result.weights >= 0.5)
    shuffled = score_outliers(cloud[::-1], outliers=0.2)
    assert (~shuffled.inliers).sum() == 60


def test_the_planted_fraction_marks_the_planted_points(seed):
    rng = np.random.default_rng(seed)
    cloud, truth, _ = planted(synthetic.sphere(1500, rng=rng).points, 0.25, 0.0, rng)
    result = score_outliers(cloud, outliers=truth.mean())
    assert (result.inliers == ~truth).mean() > 0.97


def test_result_is_read_only():
    result = score_outliers(synthetic.circle(100).points)
    for name in ("weights", "inliers", "score"):
        with pytest.raises(ValueError):
            getattr(result, name)[0] = 0
    with pytest.raises(AttributeError):
        result.noise_scale = 1.0


# -- bad arguments -------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, name", [
    ({"outliers": "sometimes"}, "outliers"),
    ({"outliers": 0.9}, "outliers"),
    ({"outliers": -0.1}, "outliers"),
    ({"outliers": True}, "outliers"),
    ({"outliers": None}, "outliers"),
    ({"outliers": float("nan")}, "outliers"),
    ({"k": 4}, "k"),
    ({"k": 10.0}, "k"),
    ({"workers": 0}, "workers"),
])
def test_bad_arguments_give_one_line_errors(kwargs, name):
    with pytest.raises(InvalidInputError) as info:
        score_outliers(synthetic.circle(50).points, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{name}: expected") and "\n" not in message


@pytest.mark.parametrize("points", [
    np.zeros((5, 2)),
    np.repeat([[0.0, 1.0, 2.0]], 50, axis=0),
    [[0.0, np.nan]] * 20,
    np.zeros((20, 4)),
    "points.xyz",
], ids=["too-few", "all-equal", "nan", "4-columns", "text"])
def test_bad_points_give_one_line_errors(points):
    with pytest.raises(InvalidInputError) as info:
        score_outliers(points)
    assert str(info.value).startswith("points: expected") and "\n" not in str(info.value)


def test_k_below_the_quadric_is_refused_in_3d_only():
    score_outliers(synthetic.circle(60).points, k=5)
    with pytest.raises(InvalidInputError, match="k: expected an integer >= 8"):
        score_outliers(synthetic.sphere(200).points, k=7)


# -- normals ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("make, share", [
    (lambda rng: synthetic.ellipse(400, rng=rng, random=True), 0.25),
    (lambda rng: synthetic.sphere(2000, rng=rng), 0.25),
    (lambda rng: synthetic.torus(3000, rng=rng), 0.1),
], ids=["ellipse", "sphere", "torus"])
def test_normals_on_the_inliers_are_not_flipped_by_strays(make, share, seed):
    rng = np.random.default_rng(seed)
    shape = make(rng)
    cloud, truth, _ = planted(shape.points, share, 0.0, rng)
    samples = np.flatnonzero(~truth)
    true_normals = shape.normals[_original_order(cloud[samples], shape.points)]
    inliers = score_outliers(cloud).inliers
    normals = estimate_normals(cloud, inliers=inliers)
    agreement = normal_agreement(normals[samples], true_normals)
    assert agreement.flipped_fraction == 0
    assert agreement.median_angle < 5
    # each stray takes the normal of its nearest inlier
    strays = np.flatnonzero(~inliers)
    kept = np.flatnonzero(inliers)
    nearest = kept[np.argmin(np.linalg.norm(cloud[strays][:, None] - cloud[kept][None], axis=2), axis=1)]
    np.testing.assert_array_equal(normals[strays], normals[nearest])


def _original_order(shuffled, original):
    """Index into ``original`` of each row of ``shuffled`` (the same points, reordered)."""
    lookup = {tuple(p): i for i, p in enumerate(original.tolist())}
    return np.array([lookup[tuple(p)] for p in shuffled.tolist()])


def test_every_point_an_inlier_is_the_plain_estimate(rng):
    points = synthetic.sphere(500, rng=rng).points
    np.testing.assert_array_equal(estimate_normals(points, inliers=np.ones(500, bool)), estimate_normals(points))


@pytest.mark.parametrize("inliers, expected", [
    (np.ones(10, bool), "a boolean mask of shape (500,)"),
    (np.ones(500), "a boolean mask of shape (500,)"),
    (np.zeros(500, bool), "at least 3 inliers"),
])
def test_bad_inlier_masks_give_one_line_errors(inliers, expected):
    with pytest.raises(InvalidInputError, match=r"^inliers: expected") as info:
        estimate_normals(synthetic.sphere(500).points, inliers=inliers)
    assert expected in str(info.value)


@pytest.mark.parametrize("seed", range(5))
def test_repeated_vertices_count_in_the_density(seed):
    """A mesh's vertices repeated along its seams are that much denser than strays: 600 positions
    of a sphere given 5 times each, and 25 % strays (750, more than the positions), all found."""
    rng = np.random.default_rng(seed)
    positions = synthetic.sphere(600, rng=rng).points
    samples = np.repeat(positions, 5, axis=0)
    strays = rng.uniform(-1.4, 1.4, size=(750, 3))
    strays = strays[np.linalg.norm(strays, axis=1) > 1.1]  # off the sphere by more than the spacing
    cloud = np.vstack([samples, strays])
    order = rng.permutation(len(cloud))
    result = score_outliers(cloud[order])
    is_stray = np.arange(len(cloud))[order] >= len(samples)
    assert np.mean(~result.inliers[is_stray]) >= 0.95
    assert np.mean(~result.inliers[~is_stray]) <= 0.01

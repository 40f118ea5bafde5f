"""ipfit.score_outliers: stray points and the noise scale, from the points alone (issue 30).

Clouds are analytic shapes with outliers planted by the issue's protocol (uniform in the box
grown by 20% on each side) or Gaussian noise of a known sigma; the truth is known for every point.
"""

from __future__ import annotations

import numpy as np
import pytest
from planted import with_outliers

import ipfit
from ipfit.datasets import synthetic
from ipfit.robust import score_outliers


@pytest.mark.parametrize("share", [0.1, 0.25, 0.4])
@pytest.mark.parametrize("offset", [0, 1, 2])
def test_planted_outliers_around_a_contour_are_found(seed, offset, share):
    rng = np.random.default_rng(seed + offset)
    cloud, planted = with_outliers(synthetic.ellipse(400, a=2.0, b=1.0, rng=rng, random=True).points, share, rng)
    found = ~score_outliers(cloud).inliers
    assert found[planted].mean() >= 0.95
    assert found[~planted].mean() <= 0.02


@pytest.mark.parametrize("share", [0.1, 0.25])
@pytest.mark.parametrize("offset", [0, 1])
def test_planted_outliers_around_a_surface_are_found(seed, offset, share):
    # A sparse sphere (1,000 samples): strays within a sample spacing or two of it are on it in
    # all but name, and a few strays clump into patches as dense as the surface (docs/robust.md).
    rng = np.random.default_rng(seed + offset)
    cloud, planted = with_outliers(synthetic.sphere(1000, rng=rng).points, share, rng)
    found = ~score_outliers(cloud).inliers
    far = planted & (np.abs(np.linalg.norm(cloud, axis=1) - 1.0) > 0.05)
    assert found[far].mean() >= 0.9
    assert found[~planted].mean() <= 0.02


@pytest.mark.parametrize("make", [lambda rng: synthetic.ellipse(300, rng=rng, random=True).points,
                                  lambda rng: synthetic.sphere(1500, rng=rng).points,
                                  lambda rng: synthetic.torus(2000, rng=rng).points])
def test_a_clean_cloud_has_no_outliers(seed, make):
    score = score_outliers(make(np.random.default_rng(seed)))
    assert score.count == 0 and score.inliers.all() and score.outlier_share == 0.0
    assert np.all(score.weights == 1.0)  # no evidence of strays: every point fully in


@pytest.mark.parametrize("sigma", [0.005, 0.01])
def test_the_noise_scale_is_the_noise(seed, sigma):
    rng = np.random.default_rng(seed)
    for points in (synthetic.ellipse(600, a=2.0, b=1.0, rng=rng, random=True).points,
                   synthetic.sphere(2000, rng=rng).points):
        true = sigma * float(np.linalg.norm(np.ptp(points, axis=0)))
        noisy = points + rng.normal(scale=true, size=points.shape)
        assert score_outliers(noisy).noise_scale == pytest.approx(true, rel=0.5)


def test_the_score_does_not_depend_on_position_scale_rotation_or_order(seed):
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(synthetic.ellipse(300, a=2.0, b=1.0, rng=rng, random=True).points, 0.25, rng)
    base = score_outliers(cloud)
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    order = rng.permutation(len(cloud))
    moved = score_outliers((cloud[order] @ rotation.T) * 1e3 + [5e4, -2e4])
    assert np.array_equal(moved.inliers, base.inliers[order])
    assert moved.noise_scale == pytest.approx(1e3 * base.noise_scale, rel=1e-6, abs=1e-9 * 1e3)


def test_none_and_a_forced_share_do_what_they_say(seed):
    rng = np.random.default_rng(seed)
    cloud, planted = with_outliers(synthetic.ellipse(300, rng=rng, random=True).points, 0.1, rng)
    none = score_outliers(cloud, outliers="none")
    assert none.inliers.all() and np.all(none.weights == 1.0) and none.mode == "none"
    for share in (0.0, 0.05, 0.2):
        forced = score_outliers(cloud, outliers=share)
        assert forced.count == round(share * len(cloud)) and forced.mode == share
    # the forced share takes the most outlying points: with exactly the planted share, the planted ones
    forced = score_outliers(cloud, outliers=planted.mean())
    assert (~forced.inliers)[planted].mean() >= 0.95


@pytest.mark.parametrize("bad", ["some", -0.1, 0.9, 2, float("nan"), True, None, [0.1]])
def test_a_bad_setting_is_one_line(bad):
    with pytest.raises(ipfit.InvalidInputError, match="^outliers: expected 'auto', 'none' or a fraction"):
        score_outliers(synthetic.ellipse(60).points, outliers=bad)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_a_big_cloud_scored_a_slice_of_queries_at_a_time_as_all_at_once(seed, noise, monkeypatch):
    # A million points' frames are found, and their roughness taken, 2^16 queries at a time
    # (bounded memory); slices of 97 must give the scores of a single pass, on clean and on noisy
    # data (wide frames).
    from ipfit.robust import local
    from ipfit.robust import score as scoring

    rng = np.random.default_rng(seed)
    surface = synthetic.torus(1500, rng=rng).points
    cloud, planted = with_outliers(surface + rng.normal(scale=noise, size=surface.shape), 0.25, rng)
    whole = score_outliers(cloud)
    monkeypatch.setattr(local, "_QUERIES", 97)
    monkeypatch.setattr(scoring, "_ROUGH_ROWS", 89)
    sliced = score_outliers(cloud)
    assert np.allclose(sliced.score, whole.score, rtol=1e-9, atol=1e-12)
    assert sliced.noise_scale == pytest.approx(whole.noise_scale, rel=1e-9)
    differ = sliced.inliers != whole.inliers
    assert np.all(np.abs(whole.score[differ] - 1.0) < 1e-6)  # only a tie at the threshold may flip
    assert (~whole.inliers)[planted].mean() > 0.5  # strays were found: the weights path ran


@pytest.mark.parametrize("share", [0.0, 0.25])
def test_a_big_cloud_is_scored_against_the_reference_of_a_random_sample(seed, share, monkeypatch):
    # Above _REFERENCE_POINTS distinct points the rounds run on a random sample of them, then
    # every point is scored once against that reference: the same decisions as the full rounds.
    from ipfit.robust import score

    rng = np.random.default_rng(seed)
    surface = synthetic.torus(6000, rng=rng).points
    cloud, planted = with_outliers(surface, share, rng) if share else (surface, np.zeros(len(surface), bool))
    full = score_outliers(cloud)
    monkeypatch.setattr(score, "_REFERENCE_POINTS", 2500)
    sampled = score_outliers(cloud)
    assert sampled.score.shape == (len(cloud),)
    found = ~sampled.inliers
    assert found[~planted].mean() <= 0.02
    if share:
        on_it = np.abs(np.hypot(np.hypot(*cloud[:, :2].T) - 1.0, cloud[:, 2]) - 0.4) < 0.05  # R = 1, r = 0.4
        far = planted & ~on_it
        assert found[far].mean() >= 0.95 and (~full.inliers)[far].mean() >= 0.95
    else:
        assert sampled.count == 0 and np.all(sampled.weights == 1.0)
    assert sampled.noise_scale < 0.01 * np.linalg.norm(np.ptp(surface, axis=0))
    assert np.array_equal(score_outliers(cloud[::-1]).score[::-1], sampled.score)  # order-free


def test_a_clean_big_cloud_is_decided_on_its_sample_and_scored_when_asked(seed, monkeypatch):
    # 'auto' on a big cloud whose sample shows no evidence keeps every point without scoring
    # them all; the scores, asked for later, are those the whole pass gives (a forced
    # fraction of 0 runs it at once), and the noise scale is the same.
    from ipfit.robust import score

    rng = np.random.default_rng(seed)
    cloud = synthetic.torus(6000, rng=rng).points
    monkeypatch.setattr(score, "_REFERENCE_POINTS", 2500)
    calls = []
    whole = score._score
    monkeypatch.setattr(score, "_score", lambda points, *a: calls.append(len(points)) or whole(points, *a))
    auto = score_outliers(cloud)
    assert len(cloud) not in calls  # the weights did not need every point's score
    assert auto.count == 0 and np.all(auto.weights == 1.0) and auto.inliers.all()
    forced = score_outliers(cloud, outliers=0.0)
    np.testing.assert_array_equal(auto.score, forced.score)
    assert auto.spacing == forced.spacing
    assert auto.noise_scale == pytest.approx(forced.noise_scale, rel=1e-12)
    none = score_outliers(cloud, outliers="none")
    assert np.all(none.weights == 1.0) and none.noise_scale == auto.noise_scale
    np.testing.assert_array_equal(none.score, auto.score)


def test_a_big_cloud_with_one_stray_position_repeated_is_scored_whole(monkeypatch):
    # A position repeated many times is one distinct point the sample may miss, but it counts
    # once per copy in the evidence: 400 copies of one stray (6 %) are evidence, and flagged.
    from ipfit.robust import score

    rng = np.random.default_rng(0)
    surface = synthetic.torus(6000, rng=rng).points
    cloud = np.vstack([surface, np.tile([[0.0, 0.0, 1.2]], (400, 1))])
    monkeypatch.setattr(score, "_REFERENCE_POINTS", 2500)
    result = score_outliers(cloud)
    assert not result.inliers[-400:].any()
    assert result.inliers[:6000].mean() > 0.98

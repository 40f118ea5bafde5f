"""Fits of clouds with stray points (issue 30): the outliers are found, left out, recorded.

The references are analytic: an ellipse and a sphere whose polynomial is known, with uniform
outliers planted by the issue's protocol (uniform in the box grown by 20% on each side). The fit
must recover the known zero set, not merely score well against the noisy cloud.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from planted import with_outliers

import ipfit
from ipfit.cli import main
from ipfit.datasets import synthetic
from ipfit.zeroset.extract import extract_zero_set


def _zero_set_error(poly, true_distance, truth: np.ndarray, size: float) -> float:
    """The largest distance, either way, between the fit's zero set and the true shape, relative
    to its size: from the zero set's points to the shape (``true_distance``, analytic), and from
    dense samples of the shape to the zero set (the fit's first-order distance)."""
    lo, hi = truth.min(axis=0), truth.max(axis=0)
    zs = extract_zero_set(poly, bounds=np.column_stack([lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo)]))
    assert not zs.is_empty, "no zero set at all"
    vertices = np.vstack(zs.curves) if zs.dim == 2 else np.asarray(zs.vertices)
    return float(max(np.abs(true_distance(vertices)).max(), poly.residuals(truth).max())) / size


def _ellipse_distance(points: np.ndarray) -> np.ndarray:
    """The first-order distance to the ellipse (x/2)² + y² = 1 (exact to O(d²) near it)."""
    x, y = points[:, 0], points[:, 1]
    return ((x / 2) ** 2 + y**2 - 1) / np.maximum(np.hypot(x / 2, 2 * y), 1e-12)


def _sphere_distance(points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points, axis=1) - 1.0


@pytest.mark.parametrize("offset", [0, 1, 2])
def test_an_ellipse_with_30_percent_outliers_keeps_its_zero_set(seed, offset):
    seed += offset
    rng = np.random.default_rng(seed)
    shape = synthetic.ellipse(300, a=2.0, b=1.0, rng=rng, random=True)
    cloud, planted = with_outliers(shape.points, 0.3, rng)
    result = ipfit.fit_adaptive(cloud, rng=seed)  # no normals: estimated on the inliers
    truth = synthetic.ellipse(4000, a=2.0, b=1.0).points
    assert _zero_set_error(result.polynomial, _ellipse_distance, truth, size=4.0) < 0.01
    assert result.outliers is not None and result.outliers.count > 0


@pytest.mark.parametrize("offset", [0, 1])
def test_a_sphere_with_30_percent_outliers_keeps_its_zero_set(seed, offset):
    seed += offset
    rng = np.random.default_rng(seed)
    shape = synthetic.sphere(800, radius=1.0, rng=rng)
    cloud, planted = with_outliers(shape.points, 0.3, rng)
    result = ipfit.fit_adaptive(cloud, max_degree=4, rng=seed)
    truth = synthetic.sphere(6000, radius=1.0, rng=np.random.default_rng(99)).points
    assert _zero_set_error(result.polynomial, _sphere_distance, truth, size=2.0) < 0.01


def test_a_surface_with_strays_is_fitted_with_both_weightings_and_says_which_it_kept(seed):
    # 3D: the normals' support factor on the weights also zeroes clean points, so the degrees are
    # fitted a second time with the score's weights alone (from the same random stream); one
    # announcement, every degree twice, the evaluations of both counted, the message says which.
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(synthetic.sphere(800, radius=1.0, rng=rng).points, 0.3, rng)
    events = []
    result = ipfit.fit_adaptive(cloud, max_degree=4, rng=seed, progress=events.append)
    kinds = [e["event"] for e in events if e["event"] in ("degree_start", "weights_variant")]
    # each loop tries the degrees its rule asks for (seed 3: the first stops at degree 2, captured)
    first = kinds.index("weights_variant")
    assert kinds.count("weights_variant") == 1 and first >= 1
    assert set(kinds[:first]) == set(kinds[first + 1:]) == {"degree_start"}
    assert "weights: the outlier score's" in result.message
    assert result.nfev > sum(d.nfev for d in result.degrees)
    truth = synthetic.sphere(6000, radius=1.0, rng=np.random.default_rng(99)).points
    assert _zero_set_error(result.polynomial, _sphere_distance, truth, size=2.0) < 0.01


def test_a_curve_with_strays_is_fitted_once(seed):
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(synthetic.ellipse(300, a=2.0, b=1.0, rng=rng, random=True).points, 0.3, rng)
    events = []
    result = ipfit.fit_adaptive(cloud, max_degree=4, rng=seed, progress=events.append)
    assert result.outliers is not None and result.outliers.count > 0
    assert not any(e["event"] == "weights_variant" for e in events)
    assert [e["degree"] for e in events if e["event"] == "degree_start"] == [d.degree for d in result.degrees]
    assert "weights:" not in result.message


def test_the_kept_weighting_is_the_one_that_measures_better():
    # The choice between the two weightings: the second replaces the first only with a higher
    # F-score on the points both trust, and never a clean zero set with one that is not there.
    from types import SimpleNamespace

    from ipfit.degree.looks import _measures_better
    from ipfit.degree.loop import Loop
    from ipfit.degree.rules import CAPTURE

    shape = synthetic.circle(200)
    points = ipfit.Cloud(shape.points)
    exact, shifted = shape.polynomial, synthetic.circle(200, center=(0.08, 0.0)).polynomial
    # the unit circle and a second loop inside it, of radius 0.5: every point on it, not clean
    spurious = synthetic.from_terms(2, 4, {(0, 0): 0.25, (2, 0): -1.25, (0, 2): -1.25, (4, 0): 1, (0, 4): 1,
                                           (2, 2): 2})
    q = {name: ipfit.quality(poly, points) for name, poly in
         (("exact", exact), ("shifted", shifted), ("spurious", spurious))}
    assert CAPTURE.is_clean(q["exact"]) and CAPTURE.is_clean(q["shifted"]) and not CAPTURE.is_clean(q["spurious"])
    assert q["shifted"].f_score < q["exact"].f_score

    def loop(poly):
        return Loop([SimpleNamespace(polynomial=poly)], 0, "captured", "")

    def better(one, other):
        return _measures_better(loop(one), loop(other), points, CAPTURE)

    assert better(exact, shifted) and not better(shifted, exact)
    assert not better(exact, exact)  # a tie keeps the first fit
    # with a margin, only a gain beyond it
    gain = q["exact"].f_score - q["shifted"].f_score
    assert _measures_better(loop(exact), loop(shifted), points, CAPTURE, 0.9 * gain)
    assert not _measures_better(loop(exact), loop(shifted), points, CAPTURE, 1.1 * gain)
    assert better(exact, spurious)
    # a spurious loop never replaces a clean fit, even one of a lower F-score
    assert q["spurious"].f_score > q["shifted"].f_score
    assert not better(spurious, shifted)
    # unless the clean fit misses the data: a small loop inside the circle that touches it is
    # clean (no part of it far from the data) but follows a tenth of it, and the fit through
    # every point is better however unclean
    tiny = synthetic.circle(200, radius=0.25, center=(0.75, 0.0)).polynomial
    missed = ipfit.quality(tiny, points)
    assert CAPTURE.is_clean(missed) and missed.f_score < 0.2
    assert better(spurious, tiny) and not better(tiny, spurious)
    assert not better(tiny, exact)


# An ellipse and a sphere leave a degree-2 fit no room to bend to the outliers (today's fit of
# every point survives them too); shapes of degree 4 do not: there the fit of every point
# fails, and the test shows what leaving the outliers out buys.
_A, _B = 1.0, 1.1  # a Cassini oval (x²+y²)² − 2a²(x²−y²) = b⁴ − a⁴: for b > a one loop, here with a deep waist that no ellipse follows


def _cassini(n: int, rng: np.random.Generator | None = None) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) if rng is None else rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(_A**2 * np.cos(2 * t) + np.sqrt(_B**4 - _A**4 * np.sin(2 * t) ** 2))  # its polar form
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def _cassini_distance(points: np.ndarray) -> np.ndarray:
    x, y = points[:, 0], points[:, 1]
    s = x * x + y * y
    f = s * s - 2 * _A**2 * (x * x - y * y) - (_B**4 - _A**4)
    return f / np.maximum(np.hypot(4 * s * x - 4 * _A**2 * x, 4 * s * y + 4 * _A**2 * y), 1e-12)


def _torus_distance(points: np.ndarray, major: float = 1.0, minor: float = 0.4) -> np.ndarray:
    return np.hypot(np.hypot(points[:, 0], points[:, 1]) - major, points[:, 2]) - minor


@pytest.mark.parametrize("offset", [0, 1])
def test_a_quartic_curve_with_30_percent_outliers_keeps_its_zero_set(seed, offset):
    seed += offset
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(_cassini(400, rng), 0.3, rng)
    truth = _cassini(4000)
    size = float(np.ptp(truth[:, 0]))
    result = ipfit.fit_adaptive(cloud, rng=seed)
    assert result.selected_degree == 4
    assert _zero_set_error(result.polynomial, _cassini_distance, truth, size) < 0.01
    plain = ipfit.fit_adaptive(cloud, outliers="none", rng=seed)
    assert _zero_set_error(plain.polynomial, _cassini_distance, truth, size) > 0.02


@pytest.mark.parametrize("offset", [0, 1])
def test_a_torus_with_30_percent_outliers_keeps_its_zero_set(seed, offset):
    seed += offset
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(synthetic.torus(1500, rng=rng).points, 0.3, rng)
    truth = synthetic.torus(8000, rng=np.random.default_rng(99)).points
    result = ipfit.fit_adaptive(cloud, max_degree=4, rng=seed)
    assert _zero_set_error(result.polynomial, _torus_distance, truth, size=2.8) < 0.01
    # no contrast with outliers="none" here: since the normals of sparse clouds are oriented with
    # exterior anchors and a winding vote, the plain degree-4 fit sometimes survives the strays
    # too (seed 0: error 0.0004); the ellipse, sphere and Cassini tests keep the contrast


@pytest.mark.parametrize("offset", [0, pytest.param(1, marks=pytest.mark.slow), pytest.param(2, marks=pytest.mark.slow),
                                    pytest.param(3, marks=pytest.mark.slow)])
def test_the_bare_apple_with_40_percent_outliers_keeps_its_surface(seed, offset):
    # A real scan's vertices (sparse, with a stem and a dimple) where the score misses some strays
    # near the surface: their normals must neither orient the shape's nor pull the fit (seed 0
    # gave F 0.946 with a spurious sheet when they did; 0.970 on seeds 0-3 now).
    seed += offset
    apple = ipfit.load("apple")
    cloud, _ = with_outliers(apple.points, 0.4, np.random.default_rng(seed))
    result = ipfit.fit_adaptive(cloud, rng=seed)
    q = ipfit.quality(result.polynomial, apple.points, faces=apple.faces)
    assert q.f_score >= 0.96 and q.n_spurious == 0, (q.f_score, q.n_spurious)


@pytest.mark.parametrize("offset", [0, 1, 2])
def test_the_json_names_the_planted_outliers(seed, offset):
    seed += offset
    rng = np.random.default_rng(seed)
    shape = synthetic.ellipse(400, a=2.0, b=1.0, rng=rng, random=True)
    cloud, planted = with_outliers(shape.points, 0.25, rng)
    result = ipfit.fit_adaptive(cloud, method="3l", max_degree=2)
    section = json.loads(json.dumps(result.to_dict()))["outliers"]
    flagged = np.zeros(len(cloud), bool)
    flagged[section["indices"]] = True
    # planted points that landed on the curve (within 1% of its size) are inliers in all but name
    near = np.abs(_ellipse_distance(cloud)) < 0.04  # 1% of the size
    missed = planted & ~flagged & ~near
    assert missed.sum() <= 0.05 * planted.sum()
    assert (flagged & ~planted).sum() <= 0.02 * (~planted).sum()
    assert section["count"] == flagged.sum() and section["share"] == pytest.approx(flagged.mean())
    assert section["mode"] == "auto" and section["noise_scale"] is None or section["noise_scale"] >= 0


def test_clean_data_is_fitted_exactly_as_without_outlier_handling():
    for cloud in (ipfit.load("boot"), synthetic.ellipse(200).points):
        auto = ipfit.fit_adaptive(cloud, method="3l", max_degree=6)
        none = ipfit.fit_adaptive(cloud, method="3l", max_degree=6, outliers="none")
        assert auto.outliers is not None and auto.outliers.count == 0
        assert none.outliers is None and "outliers" not in none.to_dict()
        np.testing.assert_array_equal(auto.x, none.x)  # the same computation, not merely close


def test_a_forced_share_marks_that_many_points():
    rng = np.random.default_rng(3)
    cloud, _ = with_outliers(synthetic.ellipse(200, rng=rng, random=True).points, 0.1, rng)
    result = ipfit.fit_adaptive(cloud, method="3l", max_degree=2, outliers=0.1)
    assert result.outliers.count == round(0.1 * len(cloud))
    assert result.outliers.to_dict()["mode"] == 0.1


@pytest.mark.parametrize("bad", ["some", -0.1, 0.9, 1.5, float("nan"), True, [0.1]])
def test_a_bad_outlier_setting_is_one_line(bad):
    with pytest.raises(ipfit.InvalidInputError, match="^outliers: expected"):
        ipfit.fit_adaptive(synthetic.ellipse(50).points, method="3l", outliers=bad)


def test_the_command_line_says_what_it_left_out(tmp_path, capsys):
    rng = np.random.default_rng(0)
    cloud, planted = with_outliers(synthetic.ellipse(300, rng=rng, random=True).points, 0.25, rng)
    data = tmp_path / "cloud.xyz"
    np.savetxt(data, cloud)
    prefix = tmp_path / "out" / "fit"
    assert main(["fit", str(data), "-o", str(prefix), "--method", "3l", "--degree", "2", "--no-picture"]) == 0
    out = capsys.readouterr().out
    payload = json.loads(prefix.with_suffix(".json").read_text())
    count = payload["outliers"]["count"]
    assert count > 0 and f"{count:,} points ({count / len(cloud):.1%}) treated as outliers" in out
    assert payload["input"]["n_points"] == len(cloud)


@pytest.mark.parametrize("args,words", [
    (["--paper", "--outliers", "auto"], "--paper: it fixes --outliers"),
    (["--outliers", "1.5"], "--outliers"),
    (["--outliers", "many"], "--outliers"),
])
def test_bad_outlier_flags_exit_2_with_one_line(tmp_path, capsys, args, words):
    data = tmp_path / "cloud.xyz"
    np.savetxt(data, synthetic.ellipse(60).points)
    try:
        code = main(["fit", str(data), "-o", str(tmp_path / "o" / "fit"), *args])
    except SystemExit as stop:  # argparse's own usage error
        code = stop.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_big_bare_scan_with_strays_is_scored_and_fitted_on_samples_of_it(seed):
    # 165,000 points: the outlier score's rounds on a random 65,536 of them, the degrees on
    # 50,000 spread evenly, the selected degree on every inlier; the strays are found and the
    # torus (R = 1, r = 0.4) is recovered.
    rng = np.random.default_rng(seed)
    cloud, planted = with_outliers(synthetic.torus(150_000, rng=rng).points, 0.1, rng)
    result = ipfit.fit_adaptive(cloud, rng=seed)
    found = ~np.asarray(result.outliers.inliers)
    on_it = np.abs(np.hypot(np.hypot(*cloud[:, :2].T) - 1.0, cloud[:, 2]) - 0.4) < 0.05
    assert found[planted & ~on_it].mean() >= 0.95 and found[~planted].mean() <= 0.02
    assert result.selected_degree == 4
    assert "degrees fitted on 50,000 of the" in result.message
    assert result.at_degree(4).quality.f_score > 0.99
    assert np.max(np.abs(result.polynomial.residuals(cloud[~planted]))) < 0.02


def test_planted_strays_do_not_pull_the_unweighted_look(seed, monkeypatch):
    # A 3D fit that measures poorly is fitted again on every point, unweighted (a sparse clean
    # cloud's thin parts can score as strays), and that fit is kept only when it measures better
    # on the points the score trusts. Forced here on a sphere with 30 % planted strays: whichever
    # is kept, the zero set is the sphere's, and the result says which.
    from ipfit.degree import looks

    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    rng = np.random.default_rng(seed)
    cloud, _ = with_outliers(synthetic.sphere(800, radius=1.0, rng=rng).points, 0.3, rng)
    events = []
    result = ipfit.fit_adaptive(cloud, max_degree=4, rng=seed, progress=events.append)
    looks = [e["message"] for e in events if e["event"] == "weights_variant"]
    assert any("on every point, unweighted" in m for m in looks)
    kept = "scored as outliers kept" in result.message
    assert result.outliers is not None and (result.outliers.count == 0) == kept
    # every decision around the degree loops is said, whichever loop's fit was kept at the end
    assert "weights: the outlier score's" in result.message and "unweighted, measured" in result.message
    truth = synthetic.sphere(6000, radius=1.0, rng=np.random.default_rng(99)).points
    assert _zero_set_error(result.polynomial, _sphere_distance, truth, size=2.0) < 0.01


@pytest.mark.parametrize("offset", [0, 5])
def test_the_unweighted_look_records_what_it_kept(seed, offset, monkeypatch):
    # A sparse thin torus (400 points, tube radius 0.1) whose clean points 'auto' scores as strays
    # on some seeds (0 and 5: 39 and 34 points); the unweighted look forced. Whichever fit is
    # kept, the result says so: kept, no point left out; not kept, the score's outliers stand.
    from ipfit.degree import looks

    seed += offset
    shape = synthetic.torus(400, 1.0, 0.1, rng=np.random.default_rng(seed))
    flagged = ipfit.score_outliers(shape.points).count
    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    events = []
    result = ipfit.fit_adaptive(shape.points, max_degree=4, rng=seed, progress=events.append)
    ran = any("on every point, unweighted" in e.get("message", "") for e in events)
    assert ran == (flagged > 0)
    if "scored as outliers kept" in result.message:
        assert f"{flagged:,} points" in result.message and result.outliers.count == 0
        assert np.all(result.outliers.weights == 1.0)
    elif ran:
        assert "unweighted, measured no better" in result.message and result.outliers.count == flagged
    # either way the fit is the torus: its zero set on the points
    assert ipfit.quality(result.polynomial, shape.points).f_score > 0.95

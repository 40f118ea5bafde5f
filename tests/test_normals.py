"""Normal estimation and orientation: synthetic shapes, the bundled data's figures, bad input."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ipfit.datasets import bundled, synthetic
from ipfit.exceptions import InvalidInputError
from ipfit.geometry.mesh import fill_missing_normals, vertex_normals_from_faces
from ipfit.geometry.mesh import outward_vertices
from ipfit.normals import DEFAULT_K, contour_normals, estimate_normals, normal_agreement, orient_normals
from ipfit.normals.local import pca_normals
from ipfit.normals.scale import noise_scale
from ipfit.robust import score_outliers


def face_normals(name):
    points, _ = bundled.load_dataset(name)
    return points, fill_missing_normals(points, vertex_normals_from_faces(points, bundled.dataset_faces(name)))


# -- synthetic shapes ------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda rng: synthetic.ellipse(300, rng=rng, random=True),
    lambda rng: synthetic.circle(80, rng=rng, random=True),
    lambda rng: synthetic.sphere(1500, rng=rng),
    lambda rng: synthetic.ellipsoid(1500, rng=rng),
    lambda rng: synthetic.torus(3000, rng=rng),
], ids=["ellipse", "circle", "sphere", "ellipsoid", "torus"])
def test_closed_shapes_get_accurate_outward_normals(make, rng):
    points, truth, _ = make(rng)
    estimated = estimate_normals(points)
    assert estimated.shape == points.shape
    np.testing.assert_allclose(np.linalg.norm(estimated, axis=1), 1.0)
    agreement = normal_agreement(estimated, truth)
    assert agreement.median_angle < 5
    assert agreement.flipped_fraction == 0


def test_result_does_not_depend_on_point_order(rng):
    points, _, _ = synthetic.ellipsoid(800, rng=rng)
    perm = rng.permutation(len(points))
    np.testing.assert_allclose(estimate_normals(points[perm]), estimate_normals(points)[perm], atol=1e-9)


def test_each_component_is_oriented_on_its_own(rng):
    a, na, _ = synthetic.circle(120, rng=rng, random=True)
    b, nb, _ = synthetic.ellipse(150, center=(6.0, 1.0), rng=rng, random=True)
    c, nc, _ = synthetic.sphere(600, center=(0.0, 0.0, 0.0), rng=rng)
    d, nd, _ = synthetic.sphere(600, radius=0.5, center=(4.0, 0.0, 0.0), rng=rng)
    for pts, nrm in ((np.vstack([a, b]), np.vstack([na, nb])), (np.vstack([c, d]), np.vstack([nc, nd]))):
        assert normal_agreement(estimate_normals(pts), nrm).flipped_fraction == 0


def test_noisy_sphere_with_larger_k(rng):
    points, truth, _ = synthetic.sphere(3000, rng=rng)
    noisy = points + rng.normal(0, 0.01, points.shape)
    agreement = normal_agreement(estimate_normals(noisy, k=30), truth)
    assert agreement.flipped_fraction == 0
    assert agreement.median_angle < 10


def test_orient_false_gives_the_lines_only(rng):
    points, truth, _ = synthetic.sphere(1000, rng=rng)
    lines = estimate_normals(points, orient=False)
    assert normal_agreement(lines, truth).median_angle < 5


def test_orient_normals_fixes_random_signs(rng):
    points, truth, _ = synthetic.torus(2000, rng=rng)
    signs = np.where(rng.random(len(points)) < 0.5, -1.0, 1.0)[:, None]
    oriented = orient_normals(points, 3.0 * truth * signs)  # not unit either
    np.testing.assert_allclose(oriented, truth, atol=1e-12)


def test_degenerate_clouds_do_not_crash():
    line = np.column_stack([np.arange(6.0), np.zeros(6)])
    out = estimate_normals(line)
    np.testing.assert_allclose(np.abs(out[:, 1]), 1.0)
    same = estimate_normals(np.zeros((4, 3)))
    np.testing.assert_allclose(np.linalg.norm(same, axis=1), 1.0)
    assert estimate_normals(np.eye(3)).shape == (3, 3)  # k larger than N is clipped


@pytest.mark.parametrize("bad, match", [
    (np.zeros((2, 2)), "at least 3"),
    (np.zeros((5, 4)), "shape"),
    (np.array([[0, 0], [1, np.nan], [2, 2]]), "finite"),
    ("abc", "array"),
])
def test_bad_points(bad, match):
    with pytest.raises(InvalidInputError, match=match):
        estimate_normals(bad)


@pytest.mark.parametrize("k", [1, 2.5, True, "8"])
def test_bad_k(k):
    with pytest.raises(InvalidInputError, match="k"):
        estimate_normals(np.random.default_rng(0).random((20, 3)), k=k)


def test_orient_normals_rejects_mismatched_or_zero_normals():
    pts = np.random.default_rng(0).random((10, 3))
    with pytest.raises(InvalidInputError, match="shape"):
        orient_normals(pts, pts[:5])
    with pytest.raises(InvalidInputError, match="zero"):
        orient_normals(pts, np.zeros_like(pts))


def test_contour_normals_square_and_direction_of_travel():
    square = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]], dtype=float)
    out = contour_normals(square)
    np.testing.assert_allclose(out[[1, 3, 5, 7]], [[0, -1], [1, 0], [0, 1], [-1, 0]])
    np.testing.assert_allclose(contour_normals(square[::-1])[::-1], out)
    np.testing.assert_allclose(contour_normals(square, span=2)[[1, 3, 5, 7]], out[[1, 3, 5, 7]])
    with pytest.raises(InvalidInputError, match="span"):
        contour_normals(square, span=0)


def test_normal_agreement_skips_nan_rows():
    a = normal_agreement([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]], [[1.0, 0.1], [0.0, -1.0], [np.nan, np.nan]])
    assert a.compared == 2
    assert a.flipped.tolist() == [False, True]
    assert a.angles[1] == pytest.approx(0.0)
    with pytest.raises(InvalidInputError):
        normal_agreement(np.ones((3, 2)), np.ones((4, 2)))


# -- the figures of issue 3 on the bundled data ---------------------------------------------------

def test_full_bunny_against_face_normals():
    points, reference = bundled.load_dataset("bunny")
    assert len(points) == 35_947
    agreement = normal_agreement(estimate_normals(points), reference)
    assert agreement.median_angle < 10
    assert agreement.flipped_fraction < 0.01


def test_bunny_res2_against_face_normals():
    points, reference = face_normals("bunny_res2")
    agreement = normal_agreement(estimate_normals(points), reference)
    assert agreement.median_angle < 10
    assert agreement.flipped_fraction < 0.01


@pytest.mark.parametrize("which", ["faces", "file"])
def test_apple_against_its_reference_normals(which):
    """The stem, three rings of 24 points 7 mm apart, needs the refit across sampled curves.

    Each ring's 12 nearest points lie on the ring, whose plane's normal is ~80° off the stem's;
    and the rings' k-nearest edges never leave the ring, so without the links across the curve
    the lowest ring, standing in the dimple, is oriented from the dimple's wall and comes out
    flipped (5.7% of the apple flipped before both fixes).
    """
    if which == "faces":
        points, reference = face_normals("apple")
    else:
        points, reference = bundled.load_dataset("apple")
    agreement = normal_agreement(estimate_normals(points), reference)
    assert agreement.median_angle < 10
    assert agreement.flipped_fraction < 0.01
    stem = (np.hypot(points[:, 0], points[:, 2]) < 0.004) & (points[:, 1] > 0.064)
    assert np.median(agreement.angles[stem]) < 30


def test_duck_against_face_normals():
    """Median below 10°; under 1% flipped wherever the face normals point out of the solid.

    Over all 5,482 vertices 1.9% are flipped (104). 90 of them are among the 116 vertices
    (2.1%) where the mesh passes through itself at the beak (see test_solid): there the face
    normals point from one part of the solid into another, and an orientation has no right
    answer. Of the 5,366 vertices whose face normals do point outward, 14 are flipped (0.26%;
    22 before the empty-ball lines of issue 30), all within 1 mm of that fold.
    """
    points, reference = face_normals("duck")
    outward = outward_vertices(points, bundled.dataset_faces("duck"))
    agreement = normal_agreement(estimate_normals(points), reference)
    assert agreement.median_angle < 10
    assert outward.mean() > 0.97
    assert agreement.flipped[outward].mean() < 0.01
    assert agreement.flipped_fraction < 0.02  # over all vertices: pins the figure
    far = cKDTree(points[~outward]).query(points[agreement.flipped & outward])[0] > 0.002
    assert not far.any()


@pytest.mark.parametrize("shuffled", [False, True], ids=["ordered", "shuffled"])
@pytest.mark.parametrize("name", ["boot", "airplane", "butterfly"])
def test_contours_against_their_ordered_normals(name, shuffled, rng):
    points, reference = bundled.load_dataset(name)
    if shuffled:
        perm = rng.permutation(len(points))
        points, reference = points[perm], reference[perm]
    agreement = normal_agreement(estimate_normals(points), reference)
    assert agreement.median_angle < 10
    assert agreement.flipped_fraction < 0.01


# -- sampling that defeats the k nearest neighbours -----------------------------------------------

def lathe_sphere(rings, per_ring):
    """Unit sphere sampled on latitude rings much farther apart than the points on each ring."""
    phi = np.linspace(0, np.pi, rings + 2)[1:-1]
    theta = np.linspace(0, 2 * np.pi, per_ring, endpoint=False)
    phi, theta = (a.ravel() for a in np.meshgrid(phi, theta, indexing="ij"))
    points = np.column_stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)])
    return np.vstack([points, [[0, 0, 1], [0, 0, -1]]])


@pytest.mark.parametrize("rings, per_ring", [(8, 90), (16, 120)])
def test_surface_sampled_on_distant_rings(rings, per_ring):
    # the 12 nearest points all lie on one ring: plain PCA tilts toward the ring's axis
    points = lathe_sphere(rings, per_ring)
    agreement = normal_agreement(estimate_normals(points), points)
    assert agreement.median_angle < 2
    assert agreement.flipped_fraction == 0


def test_thin_tube_sampled_on_distant_rings():
    # a torus (radii 3 and 0.5) as 24 rings of 60 points: rings 0.65-0.92 apart, points 0.05
    u, v = (a.ravel() for a in np.meshgrid(np.linspace(0, 2 * np.pi, 24, endpoint=False),
                                           np.linspace(0, 2 * np.pi, 60, endpoint=False), indexing="ij"))
    radial = np.column_stack([np.cos(u), np.sin(u), np.zeros_like(u)])
    truth = np.cos(v)[:, None] * radial + np.sin(v)[:, None] * np.array([0.0, 0.0, 1.0])
    agreement = normal_agreement(estimate_normals(3.0 * radial + 0.5 * truth), truth)
    assert agreement.median_angle < 2  # the plain fit gives the ring planes' normals: 90°
    assert agreement.flipped_fraction == 0


def star(arms, per_edge, inner=0.45):
    angle = np.arange(2 * arms) * np.pi / arms
    radius = np.where(np.arange(2 * arms) % 2 == 0, 1.0, inner)
    v = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    steps = np.arange(per_edge) / per_edge
    return np.vstack([v[i] + (v[(i + 1) % len(v)] - v[i]) * s for i in range(len(v)) for s in steps])


@pytest.mark.parametrize("arms, per_edge", [(5, 8), (4, 10)])
def test_coarse_contour_with_sharp_tips(arms, per_edge, rng):
    # near a tip the nearest points include the other edge; the neighbours along the curve do not
    points = star(arms, per_edge)
    reference = contour_normals(points, span=1)
    perm = rng.permutation(len(points))
    agreement = normal_agreement(estimate_normals(points[perm]), reference[perm])
    assert agreement.median_angle < 1
    assert agreement.flipped_fraction == 0


@pytest.mark.parametrize("make", [synthetic.sphere, synthetic.torus], ids=["sphere", "torus"])
def test_noisy_shapes_with_default_k(make, rng):
    points, truth, _ = make(3000, rng=rng)
    agreement = normal_agreement(estimate_normals(points + rng.normal(0, 0.01, points.shape)), truth)
    assert agreement.flipped_fraction == 0
    assert agreement.median_angle < 6


# -- noisy data -----------------------------------------------------------------------------------

def add_noise(points, fraction, rng):
    """Gaussian noise of σ = ``fraction`` of the bounding box's diagonal; returns the points and σ."""
    sigma = fraction * float(np.linalg.norm(np.ptp(points, axis=0)))
    return points + rng.normal(0.0, sigma, points.shape), sigma


def erased_by_noise(points, reference, distance):
    """Points of the clean shape with a point facing the other way (normals over 120° apart)
    within ``distance``: thin parts and tight bends, whose sides noise of about a third of that
    mixes. No method can tell which side such a noisy point came from."""
    pairs = cKDTree(points).query_pairs(distance, output_type="ndarray")
    opposed = pairs[np.einsum("ij,ij->i", reference[pairs[:, 0]], reference[pairs[:, 1]]) < -0.5]
    out = np.zeros(len(points), dtype=bool)
    out[opposed.ravel()] = True
    return out


@pytest.mark.parametrize("fraction", [0.005, 0.01, 0.02])
def test_noisy_boot(fraction, rng):
    """Noise of 2.5-10 px on a contour sampled every pixel: ~50% flipped before the noise handling.

    Measured (seeds 0-2): none flipped, median 5.7-7.7°. The reference is the clean ordered
    contour's normals (span 2, as the bundled ones).
    """
    clean, _ = bundled.load_dataset("boot")
    reference = contour_normals(clean, span=2)
    noisy, _ = add_noise(clean, fraction, rng)
    perm = rng.permutation(len(clean))
    agreement = normal_agreement(estimate_normals(noisy[perm]), reference[perm])
    assert agreement.flipped_fraction < 0.02
    assert agreement.median_angle < 15


@pytest.mark.parametrize("fraction, flipped, median", [(0.005, 0.02, 15), (0.01, 0.05, 15), (0.02, 0.03, 17)])
def test_noisy_butterfly(fraction, flipped, median, rng):
    """The butterfly's antennae are ~10 px wide and ~30 px from the wing: noise of 3.4-14 px mixes them.

    Measured over seeds 0-7, for noise of 0.5%, 1%, 2%: 9.5-11.3%, 11.5-14.9%, 16.9-19.1% of all
    points flipped (before the noise handling: ~50%), median 12.8-13.7°, 15.5-16.2°, 20.4-21.4°.
    Most flipped points are in the antennae, the notch on the left and where the antennae meet
    the wings (``erased_by_noise`` within 3σ: 25%, 30%, 44% of the points). Elsewhere
    0.3-1.0%, 0.8-4.5%, 0.1-2.1% flipped, median 12.5-13.1°, 13.7-14.4°, 14.9-16.1°. The 2% / 15°
    bars are not met everywhere: at 1% some seeds flip a stretch of the wing's edge ~5σ from an
    antenna, and at 2% the median is 15-16°.
    """
    clean, _ = bundled.load_dataset("butterfly")
    reference = contour_normals(clean, span=2)
    noisy, sigma = add_noise(clean, fraction, rng)
    perm = rng.permutation(len(clean))
    estimated = np.empty_like(noisy)
    estimated[perm] = estimate_normals(noisy[perm])
    agreement = normal_agreement(estimated, reference)
    assert agreement.flipped_fraction < 0.25
    resolvable = ~erased_by_noise(clean, reference, 3 * sigma)
    elsewhere = normal_agreement(estimated[resolvable], reference[resolvable])
    assert elsewhere.flipped_fraction < flipped
    assert elsewhere.median_angle < median


@pytest.mark.parametrize("fraction", [0.005, 0.01])
@pytest.mark.parametrize("make", [synthetic.sphere, synthetic.torus], ids=["sphere", "torus"])
def test_noisy_synthetic_surfaces(make, fraction, rng):
    """Measured (seeds 0-2): none flipped, median 1.6-2.6° (sphere), 3.9-8.0° (torus)."""
    points, truth, _ = make(3000, rng=rng)
    noisy, _ = add_noise(points, fraction, rng)
    agreement = normal_agreement(estimate_normals(noisy), truth)
    assert agreement.flipped_fraction < 0.02
    assert agreement.median_angle < 10


@pytest.mark.parametrize("make, median", [
    (lambda rng: synthetic.ellipsoid(3000, (1.0, 0.2, 0.1), rng=rng), 25),
    (lambda rng: synthetic.torus(3000, 1.0, 0.1, rng=rng), 30),
], ids=["flat ellipsoid", "thin torus"])
def test_a_known_noise_estimates_on_a_sample_whose_neighbours_see_past_it(make, median, rng):
    """σ = 1 % of the diagonal on shapes that curve within a few σ: the k nearest points (about
    2 σ wide) fit the noise. With the noise's σ, true or the outlier score's, the normals are the
    plain fit's on an even sample whose k nearest reach 4 σ. Measured (seeds 0-5): plain 26-30°
    median, 14-25 % flipped; on the sample 21-23° (ellipsoid) and 27-28° (torus), 2-4 % flipped."""
    points, truth, _ = make(rng)
    noisy, sigma = add_noise(points, 0.01, rng)
    plain = normal_agreement(estimate_normals(noisy), truth)
    assert plain.median_angle > 24 and plain.flipped_fraction > 0.1  # what the noise does without σ
    events = []
    for noise in (sigma, score_outliers(noisy).noise_scale):
        known = normal_agreement(estimate_normals(noisy, noise=noise, progress=events.append), truth)
        assert known.median_angle < median
        assert known.flipped_fraction < 0.06
    assert sum("its 12 nearest 4 σ of the noise wide" in e["message"] for e in events) == 2


def _lens(n, thickness, rng):
    """``n`` points uniform on the ellipsoid of semi-axes (1, 1, ``thickness``), and its normals."""
    axes = np.array([1.0, 1.0, thickness])
    directions = rng.normal(size=(40 * n, 3))
    on = directions / np.linalg.norm(directions, axis=1, keepdims=True) * axes
    # uniform by area: the surface element of x = axes·u is ∝ |x / axes²| ∏ axes
    element = np.linalg.norm(on / axes ** 2, axis=1)
    points = on[rng.random(len(on)) < element / element.max()][:n]
    normals = points / axes ** 2
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_a_known_noise_does_not_tilt_a_thin_rim(rng):
    """A dense lens 11 σ thick (σ = 0.5 % of the diagonal): neighbourhoods grown to where they look
    flattest reach across its rim, whose normals they turn towards the flat sides as a whole
    (median 71-75° off there, seeds 0-5): an error a fit cannot average out (the Turk hammerhead's
    flattened body, docs/robust-dense.md). On the even sample whose k nearest reach 4 σ, the rim's
    lines err at random: 35-51° median. The price is paid on the flat sides: there the grown
    neighbourhoods' 3.6° becomes 16-17°, and 5-6 % of all the signs come out wrong (not 0-3 %)."""
    points, truth = _lens(20_000, 0.08, rng)
    noisy, sigma = add_noise(points, 0.005, rng)
    rim = np.abs(truth[:, 2]) < 0.5
    grown = normal_agreement(estimate_normals(noisy)[rim], truth[rim])
    assert grown.median_angle > 65  # the case the sample is for
    sampled = normal_agreement(estimate_normals(noisy, noise=score_outliers(noisy).noise_scale), truth)
    assert normal_agreement(estimate_normals(noisy, noise=sigma)[rim], truth[rim]).median_angle < 58
    assert sampled.median_angle < 25 and sampled.flipped_fraction < 0.09


def test_the_noise_sample_reaches_four_sigma(rng):
    """The sample's k nearest points reach about 4 σ (median over the points); a cloud that
    reaches that already is not sampled."""
    from ipfit.normals.estimate import _noise_sample

    points, _, _ = synthetic.sphere(40_000, rng=rng)
    tree = cKDTree(points)
    reach_all = np.median(tree.query(points, 12)[0][:, -1])
    for sigma in (reach_all / 2, reach_all / 3):  # the k nearest of all the points reach 2 σ, 1⅓ σ
        sample = _noise_sample(points, tree, 12, sigma, 1)
        assert sample is not None and len(np.unique(sample)) == len(sample)
        reach = np.median(cKDTree(points[sample]).query(points[sample], 12)[0][:, -1])
        assert abs(reach / (4 * sigma) - 1) < 0.1
    assert _noise_sample(points, tree, 12, reach_all / 4, 1) is None


def test_a_known_noise_changes_nothing_where_a_size_flattens_or_the_points_are_clean(rng):
    """The noisy sphere flattens at a wider size, the clean torus is not noisy, a contour is 2D:
    ``noise`` is not used (the same computation, so the same normals)."""
    sphere, _, _ = synthetic.sphere(3000, rng=rng)
    noisy, sigma = add_noise(sphere, 0.01, rng)
    torus, _, _ = synthetic.torus(3000, 1.0, 0.1, rng=rng)
    boot, _ = add_noise(bundled.load_dataset("boot")[0], 0.01, rng)
    for points, noise in ((noisy, sigma), (torus, 0.05), (boot, 10.0)):
        np.testing.assert_allclose(estimate_normals(points, noise=noise), estimate_normals(points), atol=1e-12)


def test_a_known_noise_is_in_the_points_units(rng):
    points, truth, _ = synthetic.torus(3000, 1.0, 0.1, rng=rng)
    noisy, sigma = add_noise(points, 0.01, rng)
    agreement = np.einsum("ij,ij->i", estimate_normals(noisy * 1e3 + 5.0, noise=sigma * 1e3),
                          estimate_normals(noisy, noise=sigma))
    # the same lines; the signs of the few points that the two sides of the thin tube vote on
    # almost equally (1-9 of 3,000 over seeds 0-5) may follow the rounding
    np.testing.assert_allclose(np.abs(agreement), 1.0, atol=1e-9)
    assert np.mean(agreement < 0) < 0.01
    # σ ten times too small: the k nearest already reach 3 σ, nothing is grown
    np.testing.assert_allclose(estimate_normals(noisy, noise=sigma / 10), estimate_normals(noisy), atol=1e-12)


@pytest.mark.parametrize("fraction, flipped", [(0.005, 0.025), (0.01, 0.05)])
def test_noisy_bunny_res2(fraction, flipped, rng):
    """Noise of 1.25 and 2.5 mm; the ears are a few mm thick.

    Measured over seeds 0-7: 1.4-2.1% flipped at 0.5% (before the noise handling: 1.0-2.8%,
    median 14°), 3.4-4.6% at 1% (before: 27%, median 33°); median 9.5-9.6° and 13.4-14.0°. The
    flips are in the ears; at 1%, outside the points within 3σ of a face turned the other way
    (4.6% of them), 1.4-2.5%. The 2% bar is met on average at 0.5%, not on every seed.
    """
    clean, reference = face_normals("bunny_res2")
    noisy, sigma = add_noise(clean, fraction, rng)
    estimated = estimate_normals(noisy)
    agreement = normal_agreement(estimated, reference)
    assert agreement.flipped_fraction < flipped
    assert agreement.median_angle < 15
    resolvable = ~erased_by_noise(clean, reference, 3 * sigma)
    assert normal_agreement(estimated[resolvable], reference[resolvable]).flipped_fraction < 0.03


def plate(n, extents, rng):
    """``n`` points uniform on the surface of a box with these extents (centred), and their face normals."""
    extents = np.asarray(extents, float)
    areas = np.array([extents[1] * extents[2], extents[0] * extents[2], extents[0] * extents[1]])
    axis = rng.choice(3, size=n, p=areas / areas.sum())
    side = rng.choice([-1.0, 1.0], size=n)
    points = (rng.random((n, 3)) - 0.5) * extents
    points[np.arange(n), axis] = side * extents[axis] / 2
    normals = np.zeros((n, 3))
    normals[np.arange(n), axis] = side
    return points, normals


def test_noisy_thin_plate_keeps_its_two_sides(rng):
    """A small cloud under heavy noise: a plate 1 × 1 × 0.1, 2,000 points, σ = 1 % of its diagonal.

    Neighbourhoods wide enough to reach both faces look flatter than the noise-dominated small
    ones (they see the plate, not averaged noise); when the noise handling grew to them, both
    faces took one side's sign: 46-50 % flipped (seeds 0-7). Measured with neighbourhoods kept
    within 8 % of the diagonal (normals.scale): 2.5-4.0 %.
    """
    points, truth = plate(2000, (1.0, 1.0, 0.1), rng)
    noisy, _ = add_noise(points, 0.01, rng)
    assert normal_agreement(estimate_normals(noisy), truth).flipped_fraction < 0.08


@pytest.mark.slow
def test_noisy_thin_plate_is_fitted(rng):
    """The plate above through the whole fit: its zero set lies on the clean plate (F-score at
    2 % of the diagonal, against 20,000 samples of its faces): 0.999-1.000 at seeds 0-3, where
    the normals of the wide neighbourhoods gave 0.48-0.54."""
    from ipfit import fit_adaptive
    from ipfit.zeroset.quality import quality

    points, _ = plate(2000, (1.0, 1.0, 0.1), rng)
    noisy, _ = add_noise(points, 0.01, rng)
    dense, _ = plate(20_000, (1.0, 1.0, 0.1), np.random.default_rng(1))
    result = fit_adaptive(noisy, rng=0)
    assert quality(result.polynomial, dense).f_score > 0.95


def finned_sphere(n, thickness, rng):
    """``n`` points on a unit sphere with a thin fin (1 long, 0.8 wide, ``thickness`` thick) that
    sticks out along +x, the fin's part inside the sphere left out; their normals, and which
    points lie on the fin's two large faces (+z, -z)."""
    lo, hi = np.array([0.9, -0.4, -thickness / 2]), np.array([1.9, 0.4, thickness / 2])
    fin, fin_normals = plate(4 * n, hi - lo, rng)
    fin += (lo + hi) / 2
    outside = np.linalg.norm(fin, axis=1) > 1.0
    fin, fin_normals = fin[outside], fin_normals[outside]
    ball = rng.normal(size=(4 * n, 3))
    ball /= np.linalg.norm(ball, axis=1)[:, None]
    ball = ball[~np.all((ball >= lo) & (ball <= hi), axis=1)]
    fin_area = 2 * (0.8 * 0.9 + (0.8 + 0.9) * thickness)  # about: the part outside the sphere
    n_fin = round(n * fin_area / (fin_area + 4 * np.pi))
    points = np.vstack([ball[: n - n_fin], fin[:n_fin]])
    normals = np.vstack([ball[: n - n_fin], fin_normals[:n_fin]])
    face = np.zeros(n, dtype=int)
    face[n - n_fin:] = np.where(np.abs(normals[n - n_fin:, 2]) > 0.5, np.sign(normals[n - n_fin:, 2]), 0)
    return points, normals, face


def test_a_noisy_thin_part_seen_as_one_sheet_keeps_its_two_sides(rng):
    """A fin about 2 σ thick (a bunny's ear at σ = 1 % of the diagonal): the wide neighbourhoods'
    centroids of both its faces fall on its middle, one sheet of representatives oriented one way,
    and one face came out inside out as a whole (75-89 % of it flipped, seeds 0-2). Told apart by
    the winding number, each point takes the side of the sheet it lies on: what is left flipped
    are the points the noise carried across the middle (about Φ(-1.1) = 14 % at this thickness).
    The noise's σ not given: with it, the normals come from a sample instead (the test above)."""
    diagonal = float(np.linalg.norm([2.9, 2.0, 2.0]))
    sigma = 0.01 * diagonal
    points, truth, face = finned_sphere(20_000, 2.2 * sigma, rng)
    noisy = points + rng.normal(scale=sigma, size=points.shape)
    estimated = estimate_normals(noisy)  # the grown neighbourhoods, oriented by orient_coarse
    for side in (1, -1):
        assert normal_agreement(estimated[face == side], truth[face == side]).flipped_fraction < 0.3
    body = points[:, 0] < 0.8
    assert normal_agreement(estimated[body], truth[body]).flipped_fraction < 0.01


def test_one_sheet_sides_tells_a_solid_a_thin_solid_and_a_thin_gap_apart():
    """The winding number off each representative's sheet: a sphere's surface (0), a disc outside
    it seen as one sheet (+1: a thin solid, the shape on neither side) and a disc inside it (-1:
    a thin gap, the shape on both sides), whichever way the discs are oriented."""
    from ipfit.normals.scale import _one_sheet_sides

    golden = np.pi * (3.0 - np.sqrt(5.0))
    k = np.arange(3000) + 0.5
    z = 1 - 2 * k / 3000
    sphere = np.column_stack([np.sqrt(1 - z * z) * np.cos(golden * k), np.sqrt(1 - z * z) * np.sin(golden * k), z])
    grid = np.stack(np.meshgrid(np.linspace(-0.3, 0.3, 15), np.linspace(-0.3, 0.3, 15)), -1).reshape(-1, 2)
    size = 0.05
    for flip in (1.0, -1.0):
        outside = np.column_stack([np.full(len(grid), 1.6), grid])  # a disc across the x axis at x = 1.6
        inside = np.column_stack([grid, np.zeros(len(grid))])  # a disc at z = 0 through the middle
        points = np.vstack([sphere, outside, inside])
        normals = np.vstack([sphere, np.tile([flip, 0, 0], (len(grid), 1)), np.tile([0, 0, flip], (len(grid), 1))])
        sides = _one_sheet_sides(points, cKDTree(points), normals, size, 1)
        assert np.mean(sides[:3000] == 0) > 0.99
        assert np.mean(sides[3000:3000 + len(grid)] == 1) > 0.9
        assert np.mean(sides[3000 + len(grid):] == -1) > 0.9


def test_noisy_result_does_not_depend_on_point_order(rng):
    clean, _ = bundled.load_dataset("boot")
    noisy, _ = add_noise(clean, 0.01, rng)
    perm = rng.permutation(len(noisy))
    np.testing.assert_allclose(estimate_normals(noisy[perm]), estimate_normals(noisy)[perm], atol=1e-9)


def test_noisy_lines_without_orientation(rng):
    points, truth, _ = synthetic.sphere(3000, rng=rng)
    noisy, _ = add_noise(points, 0.01, rng)
    assert normal_agreement(estimate_normals(noisy, orient=False), truth).median_angle < 5


@pytest.mark.parametrize("name", bundled.dataset_names())
def test_clean_bundled_data_are_not_taken_for_noisy(name):
    """The noise handling leaves clean data to the fits above, however coarse (bunny_res4, airplane)."""
    points, _ = bundled.load_dataset(name)
    k = DEFAULT_K[points.shape[1]]
    tree = cKDTree(points)
    _, idx = tree.query(points, k)
    _, flatness = pca_normals(points, idx)
    assert noise_scale(points, tree, idx, flatness, 1) is None


# -- extreme but finite values, and argument checks (issue 13) -------------------------------------

def no_warnings(function, *args, **kwargs):
    """Call ``function``; any warning (a numpy RuntimeWarning above all) fails the test."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return function(*args, **kwargs)


@pytest.mark.parametrize("scale", [1e200, 1e155, 1e-200, 1e-160])
@pytest.mark.parametrize("which", ["torus", "boot", "noisy sphere"])
def test_normals_do_not_depend_on_scale_or_position(which, scale, rng):
    """Squares of 1e155 overflow and of 1e-160 underflow: the estimate must not see them."""
    if which == "boot":
        points, _ = bundled.load_dataset("boot")
    else:
        points, _, _ = (synthetic.torus if which == "torus" else synthetic.sphere)(1500, rng=rng)
        if which == "noisy sphere":
            points, _ = add_noise(points, 0.01, rng)
    expected = estimate_normals(points)
    moved = (points + 3.0) * scale  # a far offset too: the centre is not at the origin
    got = no_warnings(estimate_normals, moved)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, expected, atol=1e-9)  # the same lines and the same orientation
    lines = no_warnings(estimate_normals, moved, orient=False)
    assert normal_agreement(lines, estimate_normals(points, orient=False)).angles.max() < 1e-4


@pytest.mark.parametrize("scale", [1e200, 1e-200])
def test_orient_and_contour_normals_at_extreme_scales(scale, rng):
    points, truth, _ = synthetic.torus(800, rng=rng)
    signs = np.where(rng.random(len(points)) < 0.5, -1.0, 1.0)[:, None]
    np.testing.assert_allclose(no_warnings(orient_normals, points * scale, truth * signs * scale), truth, atol=1e-12)
    contour, _ = bundled.load_dataset("airplane")
    np.testing.assert_allclose(no_warnings(contour_normals, contour * scale), contour_normals(contour), atol=1e-9)


def test_a_far_outlier_gives_finite_unit_normals(rng):
    points, truth, _ = synthetic.sphere(500, rng=rng)
    with_outlier = np.vstack([points, [[1e300, -1e300, 1e300]]])
    got = no_warnings(estimate_normals, with_outlier)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0)
    # the sphere's own normals are not disturbed by one point 1e300 away
    assert normal_agreement(got[:-1], truth).median_angle < 5


@pytest.mark.parametrize("kwargs, words", [
    ({"workers": 0}, ["workers", "-1 (all cores) or a positive number", "got 0"]),
    ({"workers": -2}, ["workers", "got -2"]),
    ({"workers": 1.5}, ["workers", "an integer"]),
    ({"orient": "yes"}, ["orient", "True or False"]),
    ({"k": 0}, ["k", ">= 3"]),
    ({"noise": -1.0}, ["noise", "got -1.0"]),
    ({"noise": float("nan")}, ["noise", "a finite real number", "nan"]),
])
def test_bad_arguments_get_one_message(kwargs, words):
    points = np.random.default_rng(0).random((30, 3))
    with pytest.raises(InvalidInputError) as info:
        estimate_normals(points, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{words[0]}: expected ")
    for word in words:
        assert word in message
    if "workers" in kwargs:
        with pytest.raises(InvalidInputError, match="^workers: expected"):
            orient_normals(points, points, **kwargs)


def test_one_thread_gives_the_same_normals(rng):
    points, _, _ = synthetic.torus(2000, rng=rng)
    np.testing.assert_array_equal(estimate_normals(points, workers=1), estimate_normals(points, workers=-1))


# -- large clouds ---------------------------------------------------------------------------------

def test_large_piece_systems_are_solved_iteratively_to_the_direct_solution(rng):
    """Above _DIRECT_PIECES pieces conjugate gradients replace the direct solver: same solution."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    from ipfit.normals.orient import _DIRECT_PIECES, _solve

    side = int(np.sqrt(_DIRECT_PIECES)) + 10  # a grid of pieces, as on a surface
    m = side * side
    at = np.arange(m).reshape(side, side)
    i = np.concatenate([at[:, :-1].ravel(), at[:-1, :].ravel()])
    j = np.concatenate([at[:, 1:].ravel(), at[1:, :].ravel()])
    v = rng.uniform(-1, 1, len(i))
    coupling = sparse.csr_matrix((np.concatenate([v, v]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                                 shape=(m, m))
    pull = np.where(rng.random(m) < 0.05, 1.0, 0.0)
    diagonal = np.asarray(abs(coupling).sum(axis=1)).ravel() + pull + 1e-12
    system = (sparse.diags(diagonal) - coupling).tocsc()
    rhs = pull * rng.choice([-1.0, 1.0], m)
    np.testing.assert_allclose(_solve(system, diagonal, rhs), spsolve(system, rhs), atol=1e-6)


@pytest.mark.slow
def test_a_large_torus_is_oriented_outward(rng):
    """80,000 points: the convex hull of a sample anchors it, the piece system is solved iteratively."""
    points, truth, _ = synthetic.torus(80_000, rng=rng)
    agreement = normal_agreement(estimate_normals(points), truth)
    assert agreement.flipped_fraction == 0
    assert agreement.median_angle < 2


def test_normal_agreement_of_huge_and_tiny_vectors():
    huge_and_tiny = [[1e200, 0.0], [0.0, 1e-200], [3e300, 3e300]]
    a = no_warnings(normal_agreement, huge_and_tiny, [[2.0, 0.0], [0.0, -1.0], [1.0, 1.0]])
    np.testing.assert_allclose(a.angles, 0.0, atol=1e-5)  # arccos near 1: rounding gives ~1e-6°
    assert a.flipped.tolist() == [False, True, False]

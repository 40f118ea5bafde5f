"""Normal estimation and orientation: synthetic shapes, the bundled data's figures, bad input."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ipfit.datasets import bundled, synthetic
from ipfit.exceptions import InvalidInputError
from ipfit.normals import DEFAULT_K, contour_normals, estimate_normals, normal_agreement, orient_normals


def resolvable(points, reference, estimated, k):
    """Points whose orientation can be judged at all from the points alone.

    Excluded: (a) the estimated line is more than 45° off, so "which way" is meaningless
    (the apple's stem: 24-point rings 7 mm apart, far below what k neighbours can resolve;
    the airplane's one-point tips); (b) over a quarter of the point's k nearest neighbours have
    reference normals pointing the other way: two sheets closer than the sampling (the duck's
    mouth slit), where no point-based method can tell the sides apart.
    """
    agreement = normal_agreement(estimated, reference)
    _, idx = cKDTree(points).query(points, k)
    opposite = (np.einsum("ij,ikj->ik", reference, reference[idx[:, 1:]]) < 0).mean(axis=1) > 0.25
    return (agreement.angles < 45) & ~opposite


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


@pytest.mark.parametrize("name, strict_bound", [("apple", 0.07), ("duck", 0.025), ("bunny_res2", 0.01)])
def test_meshes_against_their_reference_normals(name, strict_bound):
    """Median below 10° and under 1% flipped among the points whose orientation is resolvable.

    Over all points the apple has 5.7% flipped (its stem: 74 points whose lines are ~80° off, so
    their signs are coin flips) and the duck 1.5% (its mouth slit);
    the bounds pin those figures so that a regression shows.
    """
    points, reference = bundled.load_dataset(name)
    estimated = estimate_normals(points)
    agreement = normal_agreement(estimated, reference)
    assert agreement.median_angle < 10
    assert agreement.flipped_fraction < strict_bound
    mask = resolvable(points, reference, estimated, DEFAULT_K[3])
    assert mask.mean() > 0.85
    assert agreement.flipped[mask].mean() < 0.01


@pytest.mark.parametrize("shuffled", [False, True], ids=["ordered", "shuffled"])
@pytest.mark.parametrize("name", ["boot", "airplane", "butterfly"])
def test_contours_against_their_ordered_normals(name, shuffled, rng):
    points, reference = bundled.load_dataset(name)
    if shuffled:
        perm = rng.permutation(len(points))
        points, reference = points[perm], reference[perm]
    estimated = estimate_normals(points)
    agreement = normal_agreement(estimated, reference)
    assert agreement.median_angle < 10
    # the airplane's 2 flipped points of 200 are one-sample tips whose line is 75° off
    assert agreement.flipped_fraction <= (0.01 if name == "airplane" else 0.001)
    mask = resolvable(points, reference, estimated, DEFAULT_K[2])
    assert agreement.flipped[mask].mean() < 0.01

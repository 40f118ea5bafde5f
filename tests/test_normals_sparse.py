"""Normals of sparse, unevenly sampled 3D clouds (issue 30): CAD-like boxes and fins, uneven
surfaces, coincident points, and the confidence of each normal.

The CAD-like shapes are sampled as the vertices of CAD meshes are: densely along the edges, a
few points on the faces. Their normals are known: a face's normal on the face, and on an edge a
line between its two faces' normals, pointing out.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ipfit.datasets import synthetic
from ipfit.normals import estimate_normals, normal_agreement, orient_normals
from ipfit.normals.local import DEFAULT_K, normal_confidence, pca, pca_normals, standardise
from ipfit.normals.poles import exterior_anchors
from ipfit.normals.scale import noise_scale


def cad_box(rng, size, spacing=0.04, face_spacing=0.25):
    """A box centred at 0: points every ~``spacing`` along its 12 edges (jittered), a sparse grid
    on each face. Returns the points, the outward face normal of face points (NaN rows on the
    edges) and the outward mean of the adjacent faces' normals (every point)."""
    size = np.asarray(size, float)
    points, faces = [], []
    for axis in range(3):
        m = max(2, round(size[axis] / spacing))
        other = [i for i in range(3) if i != axis]
        for a in (0.0, size[other[0]]):
            for b in (0.0, size[other[1]]):
                edge = np.zeros((m, 3))
                edge[:, axis] = (np.arange(m) + 0.5 + rng.uniform(-0.2, 0.2, m)) / m * size[axis]
                edge[:, other[0]], edge[:, other[1]] = a, b
                points.append(edge)
                faces.append(np.full((m, 3), np.nan))
    for axis in range(3):
        other = [i for i in range(3) if i != axis]
        u, v = (np.arange(face_spacing / 2, size[j], face_spacing) for j in other)
        u, v = (g.ravel() for g in np.meshgrid(u, v))
        for side in (0.0, size[axis]):
            face = np.zeros((len(u), 3))
            face[:, axis], face[:, other[0]], face[:, other[1]] = side, u, v
            normal = np.zeros((len(u), 3))
            normal[:, axis] = 1.0 if side else -1.0
            points.append(face)
            faces.append(normal)
    p = np.vstack(points) - size / 2
    on = np.isclose(np.abs(p), size / 2)  # on which faces each point lies
    out = np.where(on, np.sign(p), 0.0)
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    perm = rng.permutation(len(p))
    return p[perm], np.vstack(faces)[perm], out[perm]


def turned(points, vectors, angle, shift):
    rot = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    return (points + shift) @ rot.T, vectors @ rot.T


# -- CAD-like samples -------------------------------------------------------------------------------

@pytest.mark.parametrize("size", [(1.0, 1.0, 1.0), (2.0, 1.0, 0.15)], ids=["cube", "thin box"])
def test_cad_box_gets_its_face_normals_pointing_out(size, rng):
    """Before issue 30: the cube's face points 20° off (90th percentile), the thin box's 90° off,
    39-50 % of its face points flipped and 55 % of its edge points pointing in (its two big faces
    closer than the points on them, its 12-nearest neighbourhoods spanning both). Measured
    (seeds 0-4): 0.0°, none flipped, every edge point pointing out."""
    points, face, out = cad_box(rng, size)
    estimated = estimate_normals(points)
    on_face = normal_agreement(estimated, face)  # NaN rows (edges) skipped
    assert on_face.compared > 40
    assert np.percentile(on_face.angles, 90) < 3
    assert on_face.flipped_fraction == 0
    # on the edges and corners: pointing out, between the faces' normals
    assert np.mean(np.einsum("ij,ij->i", estimated, out) > 0.5) > 0.97


def test_fins_of_a_hub_are_oriented(rng):
    """Six thin fins (1 × 0.06 × 0.5) round a hub, CAD-like: each fin's two big faces are closer
    than the points on them, and the neighbour links cross from one to the other. Before issue 30:
    median 50° off, 29-39 % of the face points flipped. Measured (seeds 0-4): median 0°, none
    flipped; a third of the face points next to a fin's corner still get a line tilted toward
    it (the empty ball there only sees the corner's points)."""
    parts, faces = [], []
    for i in range(6):
        p, face, _ = cad_box(rng, (1.0, 0.06, 0.5), face_spacing=0.3)
        p, face = turned(p, face, 2.0 * np.pi * i / 6, [0.7, 0.0, 0.0])
        parts.append(p)
        faces.append(face)
    points, face = np.vstack(parts), np.vstack(faces)
    agreement = normal_agreement(estimate_normals(points), face)
    assert agreement.median_angle < 2
    assert agreement.flipped_fraction == 0


@pytest.mark.parametrize("size", [(1.0, 1.0, 1.0), (2.0, 1.0, 0.15)], ids=["cube", "thin box"])
def test_clean_cad_box_is_not_taken_for_noisy(size, rng):
    """A CAD box is rough at 12 neighbours (edges, corners, both sides of the thin box), and wider
    neighbourhoods look flatter (its faces): before issue 30 it was taken for noisy, and its
    normals fitted on up to 384 points. Its tetrahedra of 4 nearest points are flat: it is clean."""
    points, _, _ = cad_box(rng, size)
    std = standardise(points)
    tree = cKDTree(std)
    _, idx = tree.query(std, DEFAULT_K[3])
    _, flatness = pca_normals(std, idx)
    assert np.median(1.0 - flatness) / 3 > 0.025  # rough at 12 points, as noise
    assert noise_scale(std, tree, idx, flatness, 1) is None


def test_exterior_anchors_point_out_of_a_thin_box(rng):
    """A large empty ball on one side, a crowd on the other: the outside, on both big faces."""
    points, _, out = cad_box(rng, (2.0, 1.0, 0.15))
    std = standardise(points)
    lines = estimate_normals(points, orient=False)
    anchor, direction = exterior_anchors(std, cKDTree(std), lines, np.arange(len(std)), 1)
    assert len(anchor) > 0.3 * len(points)
    assert (np.einsum("ij,ij->i", direction, out[anchor]) > 0).all()


def test_exterior_anchors_of_a_sphere_point_out(rng):
    """A ball of a sixth of the diagonal fits inside a sphere, so the rule must not take the inside
    for the outside; and the inside is not crowded (a ball of a twenty-fourth fits): no anchors."""
    points, _, _ = synthetic.sphere(1000, rng=rng)
    std = standardise(points)
    lines = estimate_normals(points, orient=False)
    anchor, direction = exterior_anchors(std, cKDTree(std), lines, np.arange(len(std)), 1)
    assert (np.einsum("ij,ij->i", direction, std[anchor]) > 0).all()
    assert len(anchor) <= 0.01 * len(points)


# -- uneven sampling of smooth surfaces -------------------------------------------------------------

def uneven(make, rng, dense, sparse):
    """Samples of ``make`` dense where x > 0, sparse (about dense/sparse times fewer) elsewhere."""
    points, normals, _ = make(4 * (dense + sparse), rng=rng)
    right = np.flatnonzero(points[:, 0] > 0)[:dense]
    left = np.flatnonzero(points[:, 0] <= 0)[:sparse]
    keep = np.concatenate([right, left])
    return points[keep], normals[keep]


@pytest.mark.parametrize("make, dense, sparse", [
    (synthetic.sphere, 3000, 60),
    (synthetic.ellipsoid, 3000, 150),
    (synthetic.torus, 4000, 400),
], ids=["sphere", "ellipsoid", "torus"])
def test_unevenly_sampled_surfaces(make, dense, sparse, rng):
    """Dense on one half, 10-50 times sparser on the other. Measured (seeds 0-4): median 0.7-1.7°,
    none flipped."""
    points, truth = uneven(make, rng, dense, sparse)
    agreement = normal_agreement(estimate_normals(points), truth)
    assert agreement.median_angle < 4
    assert agreement.flipped_fraction == 0


# -- coincident points ------------------------------------------------------------------------------

def test_coincident_points_are_estimated_once(rng):
    """A mesh's vertices split per face: every point three times, the copies shuffled in. The
    copies get one normal, as good as on the distinct points (0.0° at the 90th percentile; the
    plain fit on 12 nearest of which 4 distinct: 0.1-0.8°)."""
    points, face, _ = cad_box(rng, (1.0, 1.0, 1.0))
    tripled = np.vstack([points, points, points])
    perm = rng.permutation(len(tripled))
    got = estimate_normals(tripled[perm])
    back = np.empty_like(got)
    back[perm] = got
    n = len(points)
    np.testing.assert_array_equal(back[:n], back[n: 2 * n])
    np.testing.assert_array_equal(back[:n], back[2 * n:])
    agreement = normal_agreement(back[:n], face)
    assert np.percentile(agreement.angles, 90) < 3
    assert agreement.flipped_fraction == 0


# -- confidence -------------------------------------------------------------------------------------

def test_confidence_is_optional_and_leaves_the_normals_alone(rng):
    points, _, _ = synthetic.torus(2000, rng=rng)
    normals, confidence = estimate_normals(points, return_confidence=True)
    np.testing.assert_array_equal(normals, estimate_normals(points))
    assert confidence.shape == (len(points),)
    assert (confidence >= 0).all() and (confidence <= 1).all()


def test_confidence_falls_with_noise(rng):
    """1 − (spread along the normal)/(least spread across it) on the 12 nearest points: on a clean
    sphere of 3,000 points 0.998 (median), with noise of 0.3 % and 1 % of the radius (below the
    noise handling's threshold) 0.995 and 0.965 (seeds 0-4)."""
    points, _, _ = synthetic.sphere(3000, rng=rng)
    medians = [np.median(estimate_normals(points + rng.normal(0.0, sigma, points.shape), return_confidence=True)[1])
               for sigma in (0.0, 0.003, 0.01)]
    assert medians[0] > 0.99
    assert medians[0] > medians[1] > medians[2] + 0.01


def test_confidence_is_low_where_no_plane_is_determined(rng):
    """On a CAD box's edges the nearest points lie on one row: a plane through the normal is not
    determined (confidence near 0); on the faces, away from the edges, it is higher."""
    points, face, _ = cad_box(rng, (1.0, 1.0, 1.0))
    _, confidence = estimate_normals(points, return_confidence=True)
    on_face = np.isfinite(face).all(axis=1)
    assert np.median(confidence[~on_face]) < 0.2
    assert np.median(confidence[on_face]) > np.median(confidence[~on_face]) + 0.3


def test_confidence_of_the_plane_fit_is_one_minus_its_eigenvalue_ratio(rng):
    """For a neighbourhood's own PCA normal the confidence is 1 − λ₁/λ₂ (independent check by
    eigenvalues of the covariance)."""
    points = rng.normal(size=(200, 3)) * [1.0, 0.5, 0.1]
    _, idx = cKDTree(points).query(points, 12)
    normals, values = pca(points, idx)
    np.testing.assert_allclose(normal_confidence(points, idx, normals), 1.0 - values[:, 0] / values[:, 1],
                               atol=1e-9)


def test_confidence_of_outliers_is_zero(rng):
    points, _, _ = synthetic.sphere(500, rng=rng)
    strays = rng.uniform(-2.0, 2.0, (20, 3))
    cloud = np.vstack([points, strays])
    inliers = np.arange(len(cloud)) < len(points)
    _, confidence = estimate_normals(cloud, inliers=inliers, return_confidence=True)
    assert (confidence[~inliers] == 0).all()
    assert np.median(confidence[inliers]) > 0.9


def test_return_confidence_must_be_a_flag():
    with pytest.raises(Exception, match="return_confidence"):
        estimate_normals(np.random.default_rng(0).random((20, 3)), return_confidence="yes")



def test_orient_normals_orients_a_sparse_scan_as_estimate_normals_does():
    """bunny_res4 (453 vertices) is sparse: a quarter of its points or more have neighbours that
    are a poor plane sample, so estimate_normals orients with empty-ball anchors and a winding vote.
    orient_normals, given the same lines, now does the same (before: 1.99 % flipped against the
    mesh, 1.77 % from estimate_normals)."""
    import ipfit

    points = ipfit.load("bunny_res4").points
    oriented = orient_normals(points, estimate_normals(points, orient=False))
    assert np.all(np.einsum("ij,ij->i", oriented, estimate_normals(points)) > 0)

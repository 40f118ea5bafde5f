"""Winding numbers of triangle meshes against shapes whose inside is known."""

import numpy as np
import pytest
import trimesh

from ipfit.exceptions import InvalidInputError
from ipfit.geometry.mesh import outward_vertices, winding_number


def test_sphere_inside_is_one_outside_is_zero(rng):
    sphere = trimesh.creation.icosphere(subdivisions=3)  # radius 1, vertices on the sphere
    query = rng.uniform(-1.5, 1.5, (400, 3))
    radius = np.linalg.norm(query, axis=1)
    query = query[np.abs(radius - 1.0) > 0.05]  # the facets cut inside the sphere by up to 0.01
    w = winding_number(sphere.vertices, sphere.faces, query)
    np.testing.assert_allclose(w, (np.linalg.norm(query, axis=1) < 1.0).astype(float), atol=1e-9)


def test_reversed_faces_and_overlaps_count_with_sign():
    a = trimesh.creation.box()  # [-0.5, 0.5]³
    b = trimesh.creation.box()
    b.apply_translation([0.5, 0.3, 0.2])
    vertices = np.vstack([a.vertices, b.vertices])
    faces = np.vstack([a.faces, b.faces + len(a.vertices)])
    query = [[0.25, 0.25, 0.25], [-0.4, -0.4, -0.4], [0.9, 0.7, 0.6], [3.0, 0.0, 0.0]]
    np.testing.assert_allclose(winding_number(vertices, faces, query), [2, 1, 1, 0], atol=1e-9)
    np.testing.assert_allclose(winding_number(a.vertices, a.faces[:, ::-1], query[:2]), [-1, -1], atol=1e-9)


def test_vertices_inside_the_other_part_of_a_self_overlapping_mesh_are_not_outward():
    # Two unit cubes, the second shifted by (0.5, 0.3, 0.2): of the first cube's corners only
    # (0.5, 0.5, 0.5) lies inside the second, and of the second's only (0, -0.2, -0.3) inside
    # the first. Their face normals point from one part of the solid into the other.
    a = trimesh.creation.box()
    b = trimesh.creation.box()
    b.apply_translation([0.5, 0.3, 0.2])
    vertices = np.vstack([a.vertices, b.vertices])
    faces = np.vstack([a.faces, b.faces + len(a.vertices)])
    outward = outward_vertices(vertices, faces)
    inside = {(0.5, 0.5, 0.5), (0.0, -0.2, -0.3)}
    expected = [tuple(np.round(v, 6)) not in inside for v in vertices]
    assert outward.tolist() == expected
    assert (~outward).sum() == 2


def test_outward_vertices_takes_given_normals_and_skips_missing_ones():
    box = trimesh.creation.box()
    radial = np.asarray(box.vertices, dtype=float)
    normals = radial.copy()
    normals[0] = -normals[0]  # pointing in
    normals[1] = np.nan  # no normal
    outward = outward_vertices(box.vertices, box.faces, normals)
    assert outward.tolist() == [False, False] + [True] * (len(radial) - 2)


def test_the_bundled_duck_passes_through_itself_at_the_beak():
    """The duck's beak is a thin blade whose upper surface dips through the lower one.

    Its cross-sections there are curves that cross themselves; 2% of the vertices lie on the
    surface inside the solid or on the crossing, where their face normals point from one part
    of the solid into another (winding numbers 2 | 1 on their two sides), not outward.
    """
    from ipfit.datasets import bundled

    points, _ = bundled.load_dataset("duck")
    outward = outward_vertices(points, bundled.dataset_faces("duck"))
    inside = points[~outward]
    assert 0.015 < (~outward).mean() < 0.025
    # all in a band 20 mm wide and 0.6 mm high at the beak
    assert np.ptp(inside[:, 0]) < 0.021 and np.ptp(inside[:, 2]) < 0.001


@pytest.mark.parametrize("call, match", [
    (lambda: winding_number([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]], [[0, 0, 1]]), "faces: expected indices"),
    (lambda: winding_number([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], [[0, 0]]), "vertices: expected"),
    (lambda: winding_number([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0.0, 1.0, 2.0]], [[0, 0, 1]]), "faces: expected"),
    (lambda: outward_vertices([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], [[0, 0, 1]]), "normals: expected"),
    (lambda: outward_vertices([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], step=-1.0), "step: expected"),
])
def test_bad_input_gets_one_clear_line(call, match):
    with pytest.raises(InvalidInputError, match=match):
        call()

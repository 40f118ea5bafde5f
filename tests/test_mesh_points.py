"""A sparse mesh is fitted with points spread over its faces (SearchOptions.mesh_points)."""

import numpy as np
import pytest
import trimesh

import ipfit
from ipfit.geometry.sampling import surface_points


def _coarse_torus():
    """60 vertices: too few for degree 4 at 2 points per coefficient (70), which a torus needs."""
    return trimesh.creation.torus(major_radius=1.0, minor_radius=0.4, major_sections=10, minor_sections=6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_points_lie_on_the_faces_in_proportion_to_their_area(seed):
    # two triangles in the plane z = 0 of areas 1/2 and 3/2: a quarter and three quarters of the points
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 3, 0]])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    normals = np.tile([0.0, 0.0, 1.0], (6, 1))
    pts, nrm = surface_points(vertices, faces, normals, 2000, rng=seed)
    assert pts.shape == nrm.shape == (2000, 3)
    assert np.all(pts[:, 2] == 0) and np.allclose(nrm, [0, 0, 1])
    in_small = (pts[:, 0] >= 0) & (pts[:, 1] >= 0) & (pts[:, 0] + pts[:, 1] <= 1 + 1e-12)
    in_big = (pts[:, 0] >= 2) & (pts[:, 1] >= 0) & (3 * (pts[:, 0] - 2) + pts[:, 1] <= 3 + 1e-12)
    assert np.all(in_small | in_big)
    # spread evenly over the area, so each triangle keeps about its share (area 1/2 of 2)
    assert 0.25 - 0.04 < in_small.mean() < 0.25 + 0.04


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_normals_are_the_vertex_normals_interpolated(seed):
    # a unit icosphere's vertex normals are its vertices: interpolated with a point's barycentric
    # weights they are the point itself, whose direction is radial, where the flat facets' own
    # normals are up to 10 degrees off it
    sphere = trimesh.creation.icosphere(subdivisions=2)
    pts, nrm = surface_points(sphere.vertices, sphere.faces, sphere.vertices, 1500, rng=seed)
    radial = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    assert np.allclose(nrm, radial, atol=1e-12)
    assert np.linalg.norm(pts, axis=1).min() < 0.99  # the points lie on the facets, inside the sphere


def test_the_same_seed_gives_the_same_points_and_bad_normals_are_refused():
    torus = _coarse_torus()
    one = surface_points(torus.vertices, torus.faces, torus.vertex_normals, 300, rng=4)
    two = surface_points(torus.vertices, torus.faces, torus.vertex_normals, 300, rng=4)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
    with pytest.raises(ipfit.InvalidInputError, match=r"^normals: expected shape \(60, 3\), one per vertex"):
        surface_points(torus.vertices, torus.faces, torus.vertex_normals[:10], 300)
    flat = surface_points([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], np.tile([0.0, 0, 1], (3, 1)), 10)
    assert flat[0].shape == (0, 3)  # no area, no points


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_coarse_torus_mesh_gets_the_degree_its_vertices_alone_could_not(seed):
    torus = _coarse_torus()
    events = []
    result = ipfit.fit_adaptive(torus.vertices, torus.vertex_normals, faces=torus.faces, rng=seed,
                                progress=events.append)
    chosen = result.at_degree(result.selected_degree)
    assert result.selected_degree == 4 and chosen.quality.f_score > 0.98
    assert chosen.quality.topology.genus == (1,)
    note = "fitted on the mesh's 60 vertices and 1,940 points spread over its faces"
    assert result.message.endswith(note)
    assert {"event": "mesh_points", "message": note} in events
    # the vertices alone (the paper's setting) allow degree 2 only: a closed blob, not a torus
    alone = ipfit.fit_adaptive(torus.vertices, torus.vertex_normals, faces=torus.faces, rng=seed,
                               options=ipfit.RECOMMENDED.replace(mesh_points=None))
    assert alone.selected_degree == 2 and "faces" not in alone.message
    assert alone.at_degree(2).quality.f_score < 0.5


def test_only_sparse_meshes_with_normals_get_points_on_their_faces():
    duck = ipfit.load("duck")  # 5,482 vertices: more than degree 12 asks for
    events = []
    result = ipfit.fit_adaptive(duck, rng=0, max_degree=2, progress=events.append)
    # its first fit is on the vertices alone; its degree 2 measures poorly (F 0.3), so the second
    # look, on points spread over its faces too, may follow (docs/quality-3d.md)
    looks = [e["message"] for e in events if e["event"] == "mesh_points"]
    assert looks in ([], [f"the fit measured poorly: fitted on the mesh's {len(duck):,} vertices and 2,000 points "
                          "spread over its faces"])
    assert result.at_degree(2).quality.f_score < 0.95
    torus = _coarse_torus()
    # without normals (estimated from the vertices), for a bare cloud, and in the paper's pipeline: none
    for kwargs in ({"faces": torus.faces}, {"normals": torus.vertex_normals},
                   {"normals": torus.vertex_normals, "faces": torus.faces, "options": ipfit.PAPER,
                    "method": ipfit.PAPER_METHOD, "rule": ipfit.PAPER_RULE}):
        events = []
        res = ipfit.fit_adaptive(torus.vertices, rng=0, max_degree=2, progress=events.append, **kwargs)
        assert "faces" not in res.message and not any(e["event"] == "mesh_points" for e in events)
    assert ipfit.PAPER.mesh_points is None


def test_an_explicit_maximum_degree_counts_the_face_points():
    # degree 4 asks for 35 coefficients: more than the 60 vertices allow at 2 per coefficient
    # once there are points on the faces, an explicit maximum of 6 is possible too
    torus = _coarse_torus()
    res = ipfit.fit_adaptive(torus.vertices, torus.vertex_normals, faces=torus.faces, rng=0, max_degree=6,
                             options=ipfit.RECOMMENDED.replace(mesh_points=1000))
    assert res.message.endswith("fitted on the mesh's 60 vertices and 940 points spread over its faces")
    assert res.selected_degree >= 4


def test_mesh_points_is_checked():
    with pytest.raises(ipfit.InvalidInputError, match=r"^mesh_points: expected an integer >= 1"):
        ipfit.RECOMMENDED.replace(mesh_points=0)


def test_the_command_says_it_fitted_points_on_the_faces(tmp_path):
    import json
    import subprocess
    import sys

    src = tmp_path / "torus.ply"
    _coarse_torus().export(src)
    out = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", str(src), "-o", str(tmp_path / "t"),
                          "--no-picture", "--no-zero-set"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    note = "fitted on the mesh's 60 vertices and 1,940 points spread over its faces"
    assert note in out.stderr.splitlines()
    result = json.loads((tmp_path / "t.json").read_text())
    assert result["selected_degree"] == 4 and result["adaptive"]["message"].endswith(note)
    assert result["input"]["n_points"] == 60  # the data are the mesh's vertices


def test_a_maximum_degree_beyond_the_limit_is_refused_before_any_sampling():
    torus = _coarse_torus()
    with pytest.raises(ipfit.InvalidInputError, match=r"^max_degree: expected at most \d+ in 3D"):
        ipfit.fit_adaptive(torus.vertices, torus.vertex_normals, faces=torus.faces, max_degree=400)

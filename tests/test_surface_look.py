"""A mesh whose fit measures poorly is fitted again on points spread over its faces (issue 32).

A mesh's vertices sample its surface as its modeller placed them; the fit weighs every point
alike and follows where they crowd. The reference: a cube of side 2 whose top face is a fine
40 × 40 grid (1,681 of its 1,685 vertices) and whose five other faces are two triangles each. At
degree 4 the fit on the vertices flattens onto the top (F about 0.68 against the faces); on the
vertices and 2,000 points spread evenly over the faces it rounds the whole cube (about 0.91).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import ipfit
from ipfit.datasets import synthetic
from ipfit.degree import looks
from ipfit.zeroset.quality import quality


def _lopsided_cube(n: int = 40) -> ipfit.Cloud:
    box = trimesh.creation.box(extents=(2, 2, 2))
    sides = box.faces[box.triangles_center[:, 2] < 0.99]  # the top's two triangles left out
    g = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    top = np.column_stack([x.ravel(), y.ravel(), np.ones(x.size)])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    grid = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    mesh = trimesh.util.concatenate([trimesh.Trimesh(box.vertices, sides), trimesh.Trimesh(top, grid)])
    mesh.merge_vertices()
    mesh.fix_normals()
    return ipfit.Cloud(np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals), np.asarray(mesh.faces))


@pytest.fixture(scope="module")
def cube() -> ipfit.Cloud:
    return _lopsided_cube()


def _looks(events: list[dict]) -> list[str]:
    return [e["message"] for e in events if e["event"] == "mesh_points" and "measured poorly" in e["message"]]


def test_a_poor_mesh_fit_is_fitted_again_on_its_faces_and_kept_when_better(cube, seed):
    events: list[dict] = []
    result = ipfit.fit_adaptive(cube, rng=seed, max_degree=4, progress=events.append)
    assert _looks(events) == ["the fit measured poorly: fitted on the mesh's 1,685 vertices and 2,000 points "
                              "spread over its faces"]
    assert "fitted on the mesh's 1,685 vertices and 2,000 points spread over its faces (the first fit " \
           "measured F" in result.message
    # the fit on the vertices alone (no face points: mesh_points=None) is the look's first fit
    alone = ipfit.fit_adaptive(cube, rng=seed, max_degree=4, options=ipfit.RECOMMENDED.replace(mesh_points=None))
    assert "spread over its faces" not in alone.message
    on_faces, on_vertices = quality(result.polynomial, cube).f_score, quality(alone.polynomial, cube).f_score
    assert on_vertices < 0.8 and on_faces > 0.85
    assert result.nfev > sum(d.nfev for d in result.degrees)  # both loops' evaluations counted


def test_the_look_is_not_kept_when_it_measures_worse(cube, seed, monkeypatch):
    # the face points put a quarter of the cube's size outside it: that fit misses the faces
    def outside(vertices, faces, normals, n, rng=0):
        points, unit = ipfit.geometry.sampling.surface_points(vertices, faces, normals, n, rng=rng)
        return 1.5 * points, unit

    monkeypatch.setattr(looks, "surface_points", outside)
    result = ipfit.fit_adaptive(cube, rng=seed, max_degree=4)
    alone = ipfit.fit_adaptive(cube, rng=seed, max_degree=4, options=ipfit.RECOMMENDED.replace(mesh_points=None))
    assert "a fit on the mesh's 1,685 vertices and 2,000 points spread over its faces measured F" in result.message
    assert result.message.endswith(": kept")
    assert np.allclose(result.polynomial.coefficients, alone.polynomial.coefficients)


def test_no_look_for_a_good_fit_bare_points_or_the_paper(cube, seed):
    ball = trimesh.creation.icosphere(subdivisions=3)
    sphere = ipfit.Cloud(np.asarray(ball.vertices), np.asarray(ball.vertex_normals), np.asarray(ball.faces))
    torus = synthetic.torus(800, rng=np.random.default_rng(seed))
    cases = ((sphere, None, {}),  # a good fit: F about 1
             (cube.points, cube.unit_normals, {}),  # no faces
             (cube, None, {"options": ipfit.PAPER, "method": ipfit.PAPER_METHOD, "rule": ipfit.PAPER_RULE}),
             (torus.points, torus.normals, {}))
    for points, normals, kwargs in cases:
        events: list[dict] = []
        result = ipfit.fit_adaptive(points, normals, rng=seed, max_degree=4, progress=events.append, **kwargs)
        assert not _looks(events) and "spread over its faces" not in result.message

"""A sparse bare 3D cloud whose fit measures poorly is fitted again with points spread over the
triangles between its points (issue 30: bare clouds as good as meshes).

``local_triangles`` is checked against shapes whose surface is known (a sphere; a thin plate
whose two sides must not be joined); the look is checked for what it decides: run only where it
applies, kept only when it measures better against those triangles, and said in the message.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ipfit
from ipfit.datasets import synthetic
from ipfit.degree import looks
from ipfit.geometry.sampling import LOCAL_EDGE, local_triangles, surface_points


def _sphere(n: int, rng) -> np.ndarray:
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def test_the_triangles_of_a_sphere_sample_lie_on_it(seed):
    rng = np.random.default_rng(seed)
    p = _sphere(600, rng)
    tri = local_triangles(p, p)
    assert len(tri) > len(p)  # a closed surface has about two triangles per point
    assert len(np.unique(tri)) >= 0.95 * len(p)  # nearly every point is a corner
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    centre = (a + b + c) / 3
    # wound outward, as the points' normals are, and close to the sphere's own normal
    assert (np.einsum("ij,ij->i", normal, centre / np.linalg.norm(centre, axis=1, keepdims=True)) > 0.7).all()
    # a point x = sum w_i v_i of a triangle inscribed in the unit sphere has
    # |x|^2 = 1 - 1/2 sum_ij w_i w_j |v_i - v_j|^2 >= 1 - E^2 / 3 for its longest edge E
    longest = max(np.linalg.norm(u - v, axis=1).max() for u, v in ((b, c), (c, a), (a, b)))
    spread, unit = surface_points(p, tri, p, 2000, rng=seed)
    radius = np.linalg.norm(spread, axis=1)
    assert (radius <= 1 + 1e-12).all() and (radius >= np.sqrt(1 - longest ** 2 / 3) - 1e-12).all()
    assert np.median(1 - radius) < 0.01
    # no triangle's longest edge spans more than LOCAL_EDGE spacings (median distance to the 6
    # nearest) of its widest-spaced corner
    spacing = np.median(cKDTree(p).query(p, 7)[0][:, 1:], axis=1)
    longest_each = np.max([np.linalg.norm(u - v, axis=1) for u, v in ((b, c), (c, a), (a, b))], axis=0)
    assert (longest_each <= LOCAL_EDGE * spacing[tri].max(axis=1) + 1e-12).all()
    assert (np.einsum("ij,ij->i", unit, spread) > 0.9).all()


def test_the_two_sides_of_a_thin_plate_are_not_joined(seed):
    # two sides 0.05 apart, each sampled with a spacing of about 0.1: every point's nearest
    # neighbours include the other side's, whose normals face the other way
    rng = np.random.default_rng(seed)
    top = np.column_stack([rng.uniform(-1, 1, (400, 2)), np.full(400, 0.025)])
    bottom = np.column_stack([rng.uniform(-1, 1, (400, 2)), np.full(400, -0.025)])
    points = np.vstack([top, bottom])
    normals = np.repeat([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], 400, axis=0)
    tri = local_triangles(points, normals)
    side = tri >= 400
    assert len(tri) > 400 and (side.all(axis=1) | ~side.any(axis=1)).all()


def test_too_few_points_give_no_triangles_and_bad_normals_are_refused():
    assert local_triangles(np.eye(3)[:2], np.eye(3)[:2]).shape == (0, 3)
    with pytest.raises(ipfit.InvalidInputError, match="normals"):
        local_triangles(np.eye(3), np.eye(3)[:2])


def _torus(seed: int) -> np.ndarray:
    return synthetic.torus(300, rng=np.random.default_rng(seed)).points


def _local_looks(events: list[dict]) -> list[str]:
    return [e["message"] for e in events if e["event"] == "local_surface"]


def test_the_look_is_kept_only_when_it_measures_better_against_the_triangles(seed, monkeypatch):
    # every first fit looked at again: whichever fit is kept, the message's two F-scores say why
    points = _torus(seed)
    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    events: list[dict] = []
    result = ipfit.fit_adaptive(points, max_degree=4, rng=seed, progress=events.append)
    assert _local_looks(events) == ["the fit measured poorly: fitted on the 300 points and 2,000 points spread "
                                    "over the triangles between neighbouring points"]
    monkeypatch.setattr(looks, "_LOCAL_SURFACE_MOST", 0)  # the same fit without the look
    alone = ipfit.fit_adaptive(points, max_degree=4, rng=seed)
    assert "triangles" not in alone.message
    kept = re.search(r"the first fit measured F ([\d.]+) against those triangles, this one ([\d.]+)\)", result.message)
    if kept:
        assert float(kept[2]) > float(kept[1])
        assert result.nfev > alone.nfev
    else:
        first = re.search(r"measured F ([\d.]+) against those triangles, the first ([\d.]+): kept", result.message)
        assert first and float(first[1]) <= float(first[2])
        assert np.allclose(result.polynomial.coefficients, alone.polynomial.coefficients)


def test_a_look_that_measures_worse_is_not_kept(seed, monkeypatch):
    # the spread points put a quarter of the torus's size outside it: that fit misses the triangles
    def outside(vertices, faces, normals, n, rng=0):
        spread, unit = surface_points(vertices, faces, normals, n, rng=rng)
        return 1.25 * spread, unit

    points = _torus(seed)
    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    monkeypatch.setattr(looks, "surface_points", outside)
    result = ipfit.fit_adaptive(points, max_degree=4, rng=seed)
    monkeypatch.setattr(looks, "_LOCAL_SURFACE_MOST", 0)
    alone = ipfit.fit_adaptive(points, max_degree=4, rng=seed)
    assert re.search(r"a fit on the 300 points and 2,000 points spread over the triangles between neighbouring "
                     r"points measured F [\d.]+ against those triangles, the first [\d.]+: kept", result.message)
    assert np.allclose(result.polynomial.coefficients, alone.polynomial.coefficients)


def test_no_look_for_given_normals_2d_the_paper_or_a_dense_cloud(seed, monkeypatch):
    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    shape = synthetic.torus(300, rng=np.random.default_rng(seed))
    circle = synthetic.circle(200, rng=np.random.default_rng(seed))
    cases = [((shape.points, shape.normals), {}),  # the user's normals
             ((circle.points,), {}),  # 2D
             ((shape.points,), {"method": ipfit.PAPER_METHOD, "options": ipfit.PAPER, "rule": ipfit.PAPER_RULE,
                                "outliers": "none"})]
    for args, kwargs in cases:
        events: list[dict] = []
        ipfit.fit_adaptive(*args, max_degree=4, rng=seed, progress=events.append, **kwargs)
        assert not _local_looks(events)
    monkeypatch.setattr(looks, "_LOCAL_SURFACE_MOST", 299)  # one point more than allowed
    events = []
    ipfit.fit_adaptive(shape.points, max_degree=4, rng=seed, progress=events.append)
    assert not _local_looks(events)

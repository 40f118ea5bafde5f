"""Ray intersections against analytic surfaces, and ray-cast rendering."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ipfit
from ipfit.datasets.synthetic import circle, sphere, torus
from ipfit.exceptions import InvalidInputError
from ipfit.analysis.invariants import similarity
from ipfit.analysis.rays import camera_rays, intersect_rays, render


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_sphere_hits_equal_the_quadratic_formula(rng):
    r, c = 1.3, np.array([0.2, -0.4, 0.5])
    poly = sphere(radius=r, center=c).polynomial
    origins = rng.uniform(-4, 4, (500, 3))
    # Aim near the centre so most rays hit; scale the directions to test t's units.
    directions = (c + rng.uniform(-1.6, 1.6, (500, 3)) - origins) * rng.uniform(0.3, 3, (500, 1))
    hits = poly.intersect_rays(origins, directions, tmin=-math.inf)
    a = np.sum(directions**2, axis=1)
    b = 2 * np.sum(directions * (origins - c), axis=1)
    cc = np.sum((origins - c) ** 2, axis=1) - r * r
    disc = b * b - 4 * a * cc
    expected_count = np.where(disc > 0, 2, 0)
    assert np.array_equal(hits.count, expected_count)
    assert 100 < (expected_count == 2).sum() < 500  # both hits and misses are exercised
    two = disc > 0
    root = np.sqrt(disc[two])
    expected = np.column_stack([(-b[two] - root) / (2 * a[two]), (-b[two] + root) / (2 * a[two])])
    np.testing.assert_allclose(hits.t[two], expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(hits.points[two] - c, axis=2), r, atol=1e-9)


def test_torus_four_hits_along_diameters(rng):
    R, r = 1.0, 0.4
    poly = torus(major=R, minor=r).polynomial
    # Lines in the plane z = 0 through the axis cross the tube four times: |x| = R ± r.
    angles = rng.uniform(0, 2 * np.pi, 50)
    d = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(50)])
    origins = -3.0 * d + np.array([0.0, 0.0, 0.0])
    hits = intersect_rays(origins, d, poly)
    assert np.all(hits.count == 4)
    np.testing.assert_allclose(hits.t, np.tile(3.0 + np.array([-R - r, -R + r, R - r, R + r]), (50, 1)), atol=1e-9)
    # Lines in z = h off the axis: x² + h² ... the tube's circles at radius R ± sqrt(r² − h²).
    h = 0.25
    w = math.sqrt(r * r - h * h)
    offsets = np.column_stack([np.zeros(50), np.zeros(50), np.full(50, h)])
    hits = intersect_rays(origins + offsets, d, poly)
    np.testing.assert_allclose(hits.t, np.tile(3.0 + np.array([-R - w, -R + w, R - w, R + w]), (50, 1)), atol=1e-9)


def test_torus_random_rays_agree_with_dense_sign_changes(rng):
    poly = similarity(torus(major=1.0, minor=0.35).polynomial, rotation=_rotation(rng), translation=[0.3, -0.2, 0.1])
    origins = rng.uniform(-3, 3, (60, 3))
    directions = _unit(rng.uniform(-1, 1, (60, 3)) * 0.5 - origins)
    hits = poly.intersect_rays(origins, directions, tmax=8.0)
    t = np.linspace(0, 8.0, 4001)
    values = poly((origins[:, None, :] + t[None, :, None] * directions[:, None, :]).reshape(-1, 3)).reshape(60, -1)
    crossings = np.sum(np.diff(np.sign(values), axis=1) != 0, axis=1)
    # Sampling every 0.002 sees every crossing except pairs closer than a few steps (grazing rays).
    gaps = np.diff(hits.t, axis=1)  # NaN where a ray has fewer hits
    resolved = ~np.any(gaps < 0.01, axis=1)
    assert resolved.mean() > 0.9
    assert np.array_equal(hits.count[resolved], crossings[resolved])
    assert set(np.unique(hits.count)) >= {0, 2, 4}
    found = np.isfinite(hits.t)
    assert np.all(np.abs(poly(hits.points[found])) < 1e-12)


def _rotation(rng):
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_interval_and_tangent_and_miss():
    poly = circle(radius=1.0).polynomial
    # t in [tmin, tmax]: the ray from (-3, 0) meets the circle at t = 2 and 4.
    assert intersect_rays([-3.0, 0.0], [1.0, 0.0], poly, tmin=2.5).t.tolist() == [[4.0]]
    assert intersect_rays([-3.0, 0.0], [1.0, 0.0], poly, tmax=1.0).count.tolist() == [0]
    tangent = intersect_rays([[-3.0, 1.0]], [[1.0, 0.0]], poly)
    assert tangent.count.tolist() == [1]
    assert abs(tangent.t[0, 0] - 3.0) < 1e-6  # a double root is only ~sqrt(eps) accurate
    miss = intersect_rays([[-3.0, 1.001]], [[1.0, 0.0]], poly)
    assert miss.count.tolist() == [0] and np.isnan(miss.first[0])


def test_ray_inside_a_zero_set_is_flagged():
    plane = ipfit.ImplicitPolynomial.from_coefficients([0, 0, 0, 1], dim=3)  # z = 0
    hits = intersect_rays([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]], plane)
    assert hits.on_zero_set.tolist() == [True, False]
    assert hits.count.tolist() == [0, 1] and hits.t[1, 0] == pytest.approx(1.0, abs=1e-12)


def test_zero_direction_is_a_clear_error():
    poly = circle().polynomial
    with pytest.raises(InvalidInputError, match=r"directions: expected non-zero direction vectors, got 1 zero-length"):
        intersect_rays([[0.0, 0.0], [1.0, 1.0]], [[1.0, 0.0], [0.0, 0.0]], poly)
    with pytest.raises(InvalidInputError, match="tmax"):
        intersect_rays([0.0, 0.0], [1.0, 0.0], poly, tmin=1.0, tmax=0.0)


def test_render_draws_a_sphere_disc(tmp_path):
    path = tmp_path / "sphere.png"
    img = render(sphere(radius=1.0).polynomial, [[-2.0, 2.0]] * 3, path, size=(64, 48))
    assert img.shape == (48, 64, 3) and path.exists()
    from PIL import Image

    assert np.array_equal(np.asarray(Image.open(path)), img)
    covered = (img < 255).any(axis=2).ravel()
    # Orthographic camera: a pixel shows the unit sphere iff its ray passes within 1 of the centre.
    origins, direction, _ = camera_rays([[-2.0, 2.0]] * 3, (64, 48))
    miss_distance = np.linalg.norm(np.cross(origins, direction), axis=1)
    clear = np.abs(miss_distance - 1.0) > 0.05  # pixels not on the silhouette
    assert np.array_equal(covered[clear], miss_distance[clear] < 1.0)
    assert 0.02 < covered.mean() < 0.6
    with pytest.raises(InvalidInputError, match="3D surface"):
        render(circle().polynomial, [[-2, 2]] * 3)


def test_render_refuses_a_box_beyond_float64s_reach_naming_the_box():
    # the camera sits two box radii away: beyond the coordinate limit its rays start at inf
    from ipfit.datasets.synthetic import sphere
    from ipfit.degree.results import MAX_COORDINATE

    with pytest.raises(InvalidInputError, match=r"^bounds: expected a box within ±1e\+150") as info:
        render(sphere().polynomial, [[-1e300, 1e300]] * 3, size=8)
    assert "origins" not in str(info.value)
    assert render(sphere().polynomial, [[-MAX_COORDINATE, MAX_COORDINATE]] * 3, size=8).shape == (8, 8, 3)

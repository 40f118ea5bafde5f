"""Curvature and Hessian against analytic values: circle, sphere, cylinder, torus."""

from __future__ import annotations

import numpy as np
import pytest

import ipfit
from ipfit.analysis.curvature import curvature, hessian
from ipfit.datasets.synthetic import circle, from_terms, sphere, torus
from ipfit.analysis.invariants import similarity


def _rotation(rng, dim):
    q, _ = np.linalg.qr(rng.standard_normal((dim, dim)))
    return q * np.sign(np.linalg.det(q))


def test_circle_curvature_and_tangent(rng):
    r = 1.7
    poly = similarity(circle(radius=r).polynomial, translation=[0.4, -1.0], scale=1.0)
    t = rng.uniform(0, 2 * np.pi, 100)
    pts = np.array([0.4, -1.0]) + r * np.column_stack([np.cos(t), np.sin(t)])
    c = poly.curvature(pts)
    np.testing.assert_allclose(c.mean, 1 / r, rtol=0, atol=1e-8)
    assert c.gaussian is None
    tangent = np.column_stack([-np.sin(t), np.cos(t)])
    np.testing.assert_allclose(np.abs(np.sum(c.directions[:, 0] * tangent, axis=1)), 1.0, atol=1e-8)


def test_sphere_curvature_under_a_similarity(rng):
    r, sigma = 0.6, 2.5  # the moved sphere has radius r·σ
    poly = similarity(sphere(radius=r).polynomial, _rotation(rng, 3), [1.0, -2.0, 0.5], sigma)
    d = rng.standard_normal((100, 3))
    pts = np.array([1.0, -2.0, 0.5]) + r * sigma * d / np.linalg.norm(d, axis=1, keepdims=True)
    c = curvature(poly, pts)
    np.testing.assert_allclose(c.principal, 1 / (r * sigma), rtol=0, atol=1e-8)
    np.testing.assert_allclose(c.mean, 1 / (r * sigma), atol=1e-8)
    np.testing.assert_allclose(c.gaussian, 1 / (r * sigma) ** 2, atol=1e-8)


def test_cylinder_principal_directions(rng):
    r = 0.9
    poly = from_terms(3, 2, {(2, 0, 0): 1.0, (0, 2, 0): 1.0, (0, 0, 0): -r * r})
    t, z = rng.uniform(0, 2 * np.pi, 50), rng.uniform(-2, 2, 50)
    pts = np.column_stack([r * np.cos(t), r * np.sin(t), z])
    c = curvature(poly, pts)
    np.testing.assert_allclose(c.principal, np.tile([0.0, 1 / r], (50, 1)), atol=1e-8)
    np.testing.assert_allclose(c.gaussian, 0.0, atol=1e-8)
    np.testing.assert_allclose(c.mean, 0.5 / r, atol=1e-8)
    np.testing.assert_allclose(np.abs(c.directions[:, 0, 2]), 1.0, atol=1e-8)  # straight along the axis
    np.testing.assert_allclose(c.normals, np.column_stack([np.cos(t), np.sin(t), np.zeros(50)]), atol=1e-12)


def test_torus_curvatures(rng):
    R, r = 1.0, 0.4
    poly = torus(major=R, minor=r).polynomial
    u, v = rng.uniform(0, 2 * np.pi, 200), rng.uniform(0, 2 * np.pi, 200)
    ring = np.column_stack([np.cos(u), np.sin(u), np.zeros(200)])
    normal = ring * np.cos(v)[:, None] + np.array([0.0, 0.0, 1.0]) * np.sin(v)[:, None]
    pts = R * ring + r * normal
    c = poly.curvature(pts)
    # Around the tube: 1/r; along the ring: cos v / (R + r cos v) (negative on the inner side).
    k_tube, k_ring = np.full(200, 1 / r), np.cos(v) / (R + r * np.cos(v))
    np.testing.assert_allclose(c.principal, np.sort(np.column_stack([k_tube, k_ring]), axis=1), atol=1e-8)
    np.testing.assert_allclose(c.gaussian, k_tube * k_ring, atol=1e-8)
    np.testing.assert_allclose(c.mean, (k_tube + k_ring) / 2, atol=1e-8)
    np.testing.assert_allclose(c.normals, normal, atol=1e-10)
    # The ring direction is the horizontal tangent (−sin u, cos u, 0).
    ring_dir = c.directions[np.arange(200), np.argmin(np.abs(c.principal - k_ring[:, None]), axis=1)]
    np.testing.assert_allclose(np.abs(ring_dir @ np.array([0.0, 0.0, 1.0])), 0.0, atol=1e-8)


def test_hessian_matches_differences_of_the_gradient(rng):
    points, normals = ipfit.load_dataset("boot")
    poly = ipfit.fit_3l(points, normals, 6)
    pts = points[rng.choice(len(points), 20, replace=False)]
    h = poly.hessian(pts)
    assert np.array_equal(h, hessian(poly, pts))
    eps = 1e-4 * poly.scale
    numeric = np.stack([(poly.gradient(pts + eps * e) - poly.gradient(pts - eps * e)) / (2 * eps)
                        for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(h, numeric, rtol=1e-5, atol=1e-6 * np.abs(h).max())  # O(eps²) differences
    np.testing.assert_allclose(h, np.swapaxes(h, 1, 2), rtol=1e-12, atol=1e-15 * np.abs(h).max())


def test_singular_points_are_nan():
    cone = from_terms(3, 2, {(2, 0, 0): 1.0, (0, 2, 0): 1.0, (0, 0, 2): -1.0})  # apex: ∇f = 0
    c = curvature(cone, [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0]])
    assert np.isnan(c.principal[0]).all() and np.isfinite(c.principal[1]).all()
    with pytest.raises(ipfit.InvalidInputError, match="points"):
        curvature(cone, [[0.0, 0.0]])

"""Closest points on the zero set: analytic distances, and properties on a bundled fit."""

from __future__ import annotations

import numpy as np
import pytest

import ipfit
from ipfit.datasets.synthetic import circle, sphere
from ipfit.analysis.projection import distance_summary, project


def test_circle_fit_distances_are_analytic(rng):
    centre, radius = np.array([0.3, -0.2]), 1.7
    shape = circle(100, radius=radius, center=centre)
    poly = ipfit.fit_lstsq(shape.points, degree=2)  # exact data: the fit is the circle up to rounding
    queries = centre + rng.uniform(-4, 4, (300, 2))
    far_from_centre = np.linalg.norm(queries - centre, axis=1) > 0.05
    queries = queries[far_from_centre]
    proj = poly.project(queries)
    expected = np.abs(np.linalg.norm(queries - centre, axis=1) - radius)
    np.testing.assert_allclose(proj.distances, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(proj.points - centre, axis=1), radius, atol=1e-9)
    assert proj.converged.all()


def test_sphere_fit_distances_are_analytic(rng):
    centre, radius = np.array([1.0, 2.0, -0.5]), 0.8
    shape = sphere(300, radius=radius, center=centre)
    poly = ipfit.fit_taubin(shape.points, degree=2)
    queries = centre + rng.uniform(-3, 3, (300, 3))
    queries = queries[np.linalg.norm(queries - centre, axis=1) > 0.05]
    proj = project(poly, queries)
    expected = np.abs(np.linalg.norm(queries - centre, axis=1) - radius)
    np.testing.assert_allclose(proj.distances, expected, rtol=0, atol=1e-9)
    # The closest point lies on the ray from the centre through the query.
    direction = (queries - centre) / np.linalg.norm(queries - centre, axis=1, keepdims=True)
    np.testing.assert_allclose(proj.points, centre + radius * direction, atol=1e-9)


def test_centre_of_a_circle_is_at_radius_distance():
    poly = circle(radius=2.0).polynomial
    proj = project(poly, [[0.0, 0.0]])  # ∇f = 0 there: the axis fallback takes over
    assert proj.distances[0] == pytest.approx(2.0, abs=1e-12)


@pytest.fixture(scope="module")
def boot_fit():
    points, normals = ipfit.load_dataset("boot")
    return points, ipfit.fit_3l(points, normals, 4)


def test_bundled_fit_projections_lie_on_the_zero_set(boot_fit, rng):
    points, poly = boot_fit
    lo, hi = points.min(axis=0), points.max(axis=0)
    queries = np.vstack([points[::4], lo + (hi - lo) * rng.uniform(-0.2, 1.2, (300, 2))])
    proj = poly.project(queries)
    assert np.all(np.isfinite(proj.distances))
    u = poly.normalization.apply(proj.points)
    terms = np.abs(ipfit.basis.monomials(u, poly.exponents)) @ np.abs(poly.coefficients)
    assert np.all(np.abs(poly(proj.points)) <= 1e-10 * terms)
    assert proj.converged.mean() > 0.95
    # Converged points satisfy the closest-point condition: query − point parallel to ∇f.
    offset = queries - proj.points
    grad = poly.gradient(proj.points)
    c = proj.converged & (np.linalg.norm(offset, axis=1) > 1e-9)
    cosine = np.abs(np.sum(offset[c] * grad[c], axis=1)) / (np.linalg.norm(offset[c], axis=1)
                                                           * np.linalg.norm(grad[c], axis=1))
    assert np.all(cosine > 1 - 1e-9)
    # Never farther than the nearest vertex of an independently extracted zero set (+ its grid error).
    zs = ipfit.extract_zero_set(poly, points=points, resolution=800)
    vertices = np.vstack(zs.curves)
    nearest = np.min(np.linalg.norm(queries[:, None, :] - vertices[None, :, :], axis=2), axis=1)
    step = np.max(np.diff(zs.bounds, axis=1)) / 800
    assert np.all(proj.distances <= nearest + step)
    assert np.median(nearest - proj.distances) < step


def test_distance_summary_matches_quality_mean(boot_fit):
    points, poly = boot_fit
    summary = distance_summary(poly, points, max_points=len(points))
    q = ipfit.quality(poly, points, ordered_contour=True)
    # quality measures data→zero-set distances on the extracted curve: same quantity, other route.
    assert summary["projected_mean"] == pytest.approx(q.data_to_zero_set, rel=1e-3)
    assert summary["projected_max"] >= summary["projected_mean"] > 0

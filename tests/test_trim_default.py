"""The default trim: it hugs an open dome's rim (two point spacings) while closed shapes, and
holes between samples, lose nothing (``ipfit.zeroset.trim``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ipfit
from ipfit.datasets import synthetic
from ipfit.zeroset.trim import default_gap_distance, default_trim_distance

RIM_Z = -0.2  # the dome: the unit sphere's points with z >= RIM_Z
RIM_ANGLE = math.acos(RIM_Z)  # polar angle of the rim circle


def dome(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """n points spread at random by area over the spherical cap z >= RIM_Z, and their normals."""
    z = rng.uniform(RIM_Z, 1.0, n)  # uniform in z is uniform by area on a sphere (Archimedes)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    points = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    return points, points.copy()


def distance_to_cap(p: np.ndarray) -> np.ndarray:
    """Exact distance from points to the cap z >= RIM_Z of the unit sphere."""
    rho = np.hypot(p[:, 0], p[:, 1])
    theta = np.arctan2(rho, p[:, 2])  # polar angle
    on_cap = np.abs(np.linalg.norm(p, axis=1) - 1.0)
    # below the rim, the nearest point of the cap is on the rim circle (radius sin θ_rim, height RIM_Z)
    rim = np.hypot(rho - math.sin(RIM_ANGLE), p[:, 2] - RIM_Z)
    return np.where(theta <= RIM_ANGLE, on_cap, rim)


@pytest.mark.parametrize("n", [500, 2000])
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_the_default_trim_hugs_an_open_domes_rim(n, seed):
    points, _ = dome(n, np.random.default_rng(seed))
    zs = ipfit.extract_zero_set(synthetic.sphere().polynomial, points=points, resolution=96)
    bottom = zs.vertices[:, 2].min()
    assert bottom < RIM_Z - 0.45  # the sphere closes the dome: surface down to the box's floor
    trimmed = zs.trimmed(points)
    distance = trimmed.trim.distance
    assert distance == default_trim_distance(points)
    spacing = np.median(cKDTree(points).query(points, k=2)[0][:, 1])
    assert distance == pytest.approx(max(2 * spacing, 0.01 * np.linalg.norm(np.ptp(points, axis=0))))
    # what is kept ends within the trim distance (plus the grid's own error) of the rim ...
    assert distance_to_cap(trimmed.vertices).max() <= distance + zs.step
    below = trimmed.vertices[:, 2] < RIM_Z
    assert below.any() and trimmed.vertices[:, 2].min() > RIM_Z - distance - zs.step
    # ... and all the data is still on it: every point within a grid step of a kept vertex
    assert cKDTree(trimmed.vertices).query(points)[0].max() <= zs.step
    # the surface the data does not support goes: the band below the collar (a band of the unit
    # sphere between heights z1 < z2 has area 2π(z2 − z1), Archimedes again)
    assert trimmed.trim.removed_share > (RIM_Z - distance - zs.step - bottom) / (1 - bottom) - 0.01


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_a_fitted_dome_is_trimmed_near_its_rim(seed):
    points, normals = dome(1500, np.random.default_rng(seed))
    poly = ipfit.fit_3l(points, normals, 4)
    zs = ipfit.extract_zero_set(poly, points=points, resolution=80)
    trimmed = zs.trimmed(points)
    # a fit deviates from the dome a little; what is kept stays within the trim distance of it
    assert distance_to_cap(trimmed.vertices).max() <= trimmed.trim.distance + zs.step + 0.02
    assert trimmed.vertices[:, 2].min() > RIM_Z - 0.15 > zs.vertices[:, 2].min()


@pytest.mark.parametrize("n", [300, 1000, 3000])
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_a_closed_sphere_loses_nothing(n, seed):
    shape = synthetic.sphere(n, rng=np.random.default_rng(seed))
    for poly in (shape.polynomial, ipfit.fit_3l(shape.points, shape.normals, 2)):
        zs = ipfit.extract_zero_set(poly, points=shape.points, resolution=64)
        trimmed = zs.trimmed(shape.points)
        assert trimmed.trim.removed_faces == 0 and trimmed.closed
        # the holes between random samples reach beyond the trim distance: they are what the gap keeps
        assert cKDTree(shape.points).query(zs.vertices)[0].max() > trimmed.trim.distance


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_a_hole_in_the_data_is_kept_and_an_opening_is_not(seed):
    rng = np.random.default_rng(seed)
    shape = synthetic.sphere(6000, rng=rng)
    zs = ipfit.extract_zero_set(shape.polynomial, points=shape.points, resolution=64)
    north = shape.points[:, 2]
    gap = default_gap_distance(shape.points)
    distance = default_trim_distance(shape.points)
    # a hole around the north pole whose centre is farther than the trim distance from the data
    # but not than the gap distance: kept whole
    hole_angle = 2 * math.asin(0.5 * (distance + gap) / 2)  # the pole is (distance + gap) / 2 from its rim
    holed = shape.points[north < math.cos(hole_angle)]
    assert distance < cKDTree(holed).query([[0, 0, 1.0]])[0][0] < gap
    kept = zs.trimmed(holed)
    assert kept.trim.removed_faces == 0
    # an opening: the data's rim at 60° from the pole; the surface over it gets 1 from every point
    opened = shape.points[north < 0.5]
    cut = zs.trimmed(opened)
    assert cut.vertices[:, 2].max() < 0.5 + cut.trim.distance + zs.step
    assert cut.trim.removed_share > 0.25 - 0.05  # the cap z > 0.5 is a quarter of the sphere


def test_an_explicit_distance_at_least_the_gap_is_the_plain_rule(rng):
    shape = synthetic.sphere(800, rng=rng)
    zs = ipfit.extract_zero_set(shape.polynomial, points=shape.points, resolution=48)
    bowl = shape.points[shape.points[:, 2] < 0.3]
    gap = default_gap_distance(bowl)
    for distance in (gap, 1.5 * gap):
        trimmed = zs.trimmed(bowl, distance)
        assert trimmed.trim.gap == distance
        d = cKDTree(bowl).query(zs.vertices)[0]
        assert len(trimmed.faces) == (d <= distance)[zs.faces].all(axis=1).sum()
        assert "holes" not in trimmed.trim.describe()
    assert "(holes in the data kept up to" in zs.trimmed(bowl).trim.describe()


def test_a_curve_keeps_its_gaps_and_loses_its_opening():
    zs = ipfit.extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    # a missing arc of 0.12 rad at 5.78 rad (its middle 0.06 from the data), and no data for y > 0.8
    keep = ~((t > 5.72) & (t < 5.84)) & (np.sin(t) < 0.8)
    points = np.column_stack([np.cos(t[keep]), np.sin(t[keep])])
    distance, gap = default_trim_distance(points), default_gap_distance(points)
    assert distance < 0.06 < gap
    trimmed = zs.trimmed(points)
    kept = np.concatenate(trimmed.curves)
    assert len(trimmed.curves) == 1  # one arc: the gap kept, the top cut out
    middle = np.array([math.cos(5.78), math.sin(5.78)])
    assert np.linalg.norm(kept - middle, axis=1).min() < 0.01
    assert kept[:, 1].max() < 0.8 + distance + zs.step

"""Geometric quality measures on hand-built cases with known answers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import ipfit
from ipfit import InvalidInputError
from ipfit.datasets import synthetic
from ipfit.zeroset.quality import Quality, looks_like_contour, quality
from ipfit.zeroset.extract import extract_zero_set

from test_zeroset import product


def test_perfect_circle_fit():
    shape = synthetic.circle(200)
    q = quality(shape.polynomial, shape.points)
    assert q.recall == 1.0 and q.precision == 1.0 and q.f_score == 1.0
    assert q.n_components == 1 and q.n_spurious == 0 and q.closed
    assert q.reference == "points"
    assert q.data_to_zero_set < q.grid_step / 4
    assert math.isclose(q.tau, 0.02 * math.hypot(2, 2), rel_tol=1e-3)


def test_perfect_sphere_fit_against_mesh_faces():
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    poly = synthetic.sphere().polynomial
    q = quality(poly, mesh.vertices, faces=mesh.faces, resolution=64)
    assert q.reference == "faces"
    assert q.f_score == 1.0 and q.n_spurious == 0 and q.closed and q.n_components == 1
    assert q.chamfer < 0.01  # the icosphere's flat faces are within 0.01 of the unit sphere
    # Against the 162 bare vertices the sphere between them is up to half an edge from the
    # nearest one (more than τ): the gap allowance keeps the perfect fit perfect ...
    sparse = quality(poly, mesh.vertices, resolution=64)
    assert sparse.reference == "points" and sparse.tau < 0.5 * mesh.edges_unique_length.min()
    assert sparse.recall == 1.0 and sparse.precision == 1.0
    # ... where τ alone would not (the bias the allowance removes) ...
    from scipy.spatial import cKDTree
    from ipfit.zeroset.extract import extract_zero_set

    samples = extract_zero_set(poly, points=mesh.vertices, resolution=64).sample(sparse.tau).points
    assert np.mean(cKDTree(mesh.vertices).query(samples)[0] > sparse.tau) > 0.2
    # ... while a sphere two edges out is still imprecise (and misses every point)
    edge = float(mesh.edges_unique_length.max())
    bigger = synthetic.sphere(radius=1 + 2 * edge).polynomial
    off = quality(bigger, mesh.vertices, resolution=64)
    assert off.precision == 0.0 and off.recall == 0.0


def test_the_gap_allowance_follows_its_definition_far_from_the_points():
    # A zero-set sample of a bare cloud is within τ of the shape when it is within √(τ² + s²) of
    # its nearest point, s that point's spacing. 12 points on a circle are 0.52 apart, 9 τ: the
    # circle between them is up to 4.6 τ from both, beyond the 4 τ within which the spacing of
    # the nearest points alone is looked up; every sample is still within the allowance. Around
    # 60 points (s = 0.21) a circle 0.4 out is beyond it everywhere; the brute-force definition
    # decides every sample.
    from scipy.spatial import cKDTree

    from ipfit.cloud import Cloud
    from ipfit.zeroset.quality import _measure

    for count, radius in ((12, 1.0), (60, 1.4)):
        t = np.linspace(0, 2 * np.pi, count, endpoint=False)
        ring = np.c_[np.cos(t), np.sin(t)]
        spacing = cKDTree(ring).query(ring, k=[3])[0][:, 0]  # the 2nd nearest other point (dim = 2)
        poly = synthetic.circle(radius=radius).polynomial
        q = quality(poly, Cloud(ring))
        _, _, samples, _, tau, _ = _measure(poly, Cloud(ring), details=True)
        d, nearest = cKDTree(ring).query(samples.points)
        within = d <= np.sqrt(tau**2 + spacing[nearest] ** 2)
        assert q.precision == pytest.approx(samples.weights[within].sum() / samples.weights.sum(), abs=1e-12)
        assert d.max() > 4 * tau
        assert q.precision == (1.0 if count == 12 else 0.0)


def test_spacing_at_some_points_is_the_cloud_s_spacing_there(rng):
    from ipfit.cloud import Cloud

    points = rng.normal(size=(500, 3))
    points[7] = points[8]  # a repeated point: spacing 0 at k = 1
    index = np.array([8, 3, 7, 3, 499])
    fresh = Cloud(points)
    for k in (1, 3):
        assert np.array_equal(fresh.point_spacing_at(index, k), Cloud(points).point_spacing(k)[index])
    assert np.array_equal(fresh.point_spacing_at(index, 1)[[0, 2]], [0.0, 0.0])
    assert np.array_equal(Cloud(points[:2]).point_spacing_at(np.array([0, 1]), 2), [0.0, 0.0])


def test_ordered_contour_reference():
    shape = synthetic.circle(24)
    poly = shape.polynomial
    q = quality(poly, shape.points, ordered_contour=True)
    assert q.reference == "contour" and q.f_score == 1.0
    # the bare points agree on this perfect fit, thanks to their gap allowance
    assert quality(poly, shape.points).precision == 1.0


def test_extra_component_in_the_box_is_spurious():
    shape = synthetic.circle(200)
    extra = synthetic.circle(radius=0.1, center=(1.3, 1.3)).polynomial  # inside the box's margin
    poly = product(shape.polynomial, extra)
    q = quality(poly, shape.points)
    assert q.n_components == 2 and q.n_spurious == 1
    assert q.recall == 1.0 and 0.7 < q.precision < 1.0
    assert q.closed


def test_far_away_component_counts_when_the_box_holds_it():
    shape = synthetic.circle(200)
    far = synthetic.circle(radius=1.0, center=(6.0, 0.0)).polynomial
    poly = product(shape.polynomial, far)
    assert quality(poly, shape.points).n_spurious == 0  # outside the default box
    q = quality(poly, shape.points, bounds=[[-2, 8], [-2, 2]])
    assert q.n_components == 2 and q.n_spurious == 1
    assert q.precision == pytest.approx(0.5, abs=0.02)


def test_extra_sphere_is_spurious_in_3d():
    shape = synthetic.sphere(2000)
    extra = synthetic.sphere(radius=0.15, center=(1.25, 1.25, 1.25)).polynomial
    q = quality(product(shape.polynomial, extra), shape.points, resolution=64)
    assert q.n_components == 2 and q.n_spurious == 1 and q.recall == 1.0


@pytest.mark.parametrize("case", ["contour", "bare 2D", "mesh", "bare 3D"])
def test_spurious_flags_alone_are_the_full_measurements(case):
    # spurious_components measures only the zero set's side; its flags are the full measurement's
    from ipfit.zeroset.quality import _measure, spurious_components

    if case in ("contour", "bare 2D"):
        shape = synthetic.circle(200)
        poly = product(shape.polynomial, synthetic.circle(radius=0.1, center=(1.3, 1.3)).polynomial)
        data, options = shape.points, {"ordered_contour": case == "contour"}
    else:
        import trimesh

        mesh = trimesh.creation.icosphere(subdivisions=3)
        poly = product(synthetic.sphere(10).polynomial,
                       synthetic.sphere(radius=0.15, center=(1.25, 1.25, 1.25)).polynomial)
        vertices = np.asarray(mesh.vertices)
        data = ipfit.Cloud(vertices, faces=np.asarray(mesh.faces)) if case == "mesh" else vertices
        options = {}
    zs = extract_zero_set(poly, points=shape.points if case in ("contour", "bare 2D") else vertices)
    flags = spurious_components(zs, data, **options)
    assert flags.tolist() == _measure(zs, data, **options)[1].tolist()
    assert flags.sum() == 1 and len(flags) == zs.n_components == 2
    with pytest.raises(InvalidInputError, match="points to match the zero set"):
        spurious_components(zs, np.zeros((5, 5 - zs.dim)) + np.arange(5)[:, None])


def test_zero_set_leaving_the_box_is_not_closed():
    shape = synthetic.sphere(500)
    hyperboloid = synthetic.from_terms(3, 2, {(2, 0, 0): 1, (0, 2, 0): 1, (0, 0, 2): -1, (0, 0, 0): -1})
    q = quality(hyperboloid, shape.points, resolution=48)
    assert not q.closed and q.n_components == 1
    plane = synthetic.from_terms(3, 1, {(0, 0, 1): 1.0})
    assert not quality(plane, shape.points, resolution=32).closed


def test_empty_zero_set():
    shape = synthetic.circle(50)
    nothing = synthetic.from_terms(2, 2, {(2, 0): 1, (0, 2): 1, (0, 0): 1})
    q = quality(nothing, shape.points, resolution=64)
    assert q.recall == 0 and q.precision == 0 and q.f_score == 0 and q.n_components == 0 and not q.closed
    assert math.isinf(q.chamfer)
    d = q.to_dict()
    assert d["chamfer"] is None
    json.dumps(d)


def test_distances_of_a_scaled_circle():
    shape = synthetic.circle(400)
    bigger = synthetic.circle(radius=1.1).polynomial
    q = quality(bigger, shape.points, tau=0.05)
    assert q.recall == 0.0 and q.precision == 0.0
    # exact distances to the extracted segments: only the grid's own error remains
    assert q.data_to_zero_set == pytest.approx(0.1, abs=q.grid_step / 4)
    assert q.zero_set_to_data == pytest.approx(0.1, abs=0.002)  # the data's points are 0.016 apart
    assert q.chamfer == pytest.approx(0.1, abs=0.002)
    assert quality(bigger, shape.points, tau=0.15).f_score == 1.0


def test_accepts_a_zero_set_and_serialises():
    shape = synthetic.torus(2000)
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=48)
    q = quality(zs, shape.points)
    assert isinstance(q, Quality)
    assert q.recall == 1.0 and q.n_spurious == 0 and q.closed
    d = q.to_dict()
    assert set(d) >= {"recall", "precision", "f_score", "chamfer", "n_components", "n_spurious", "closed", "tau"}
    assert json.loads(json.dumps(d)) == d
    assert "f_score" in str(q)


def test_looks_like_contour(rng):
    shape = synthetic.circle(100)
    assert looks_like_contour(shape.points)
    assert not looks_like_contour(rng.permutation(shape.points))
    assert not looks_like_contour(synthetic.sphere(50).points)


@pytest.mark.parametrize("kwargs, match", [
    ({"tau": -1.0}, "tau"),
    ({"tau_fraction": 0.0}, "tau_fraction"),
    ({"faces": [[0, 1, 2]]}, "faces"),
    ({"max_samples": 10}, "max_samples"),
])
def test_bad_arguments_2d(kwargs, match):
    shape = synthetic.circle(20)
    with pytest.raises(InvalidInputError, match=match):
        quality(shape.polynomial, shape.points, **kwargs)


def test_bad_faces_and_dimensions():
    shape = synthetic.sphere(20)
    with pytest.raises(InvalidInputError, match="faces"):
        quality(shape.polynomial, shape.points, faces=[[0, 1, 99]])
    with pytest.raises(InvalidInputError, match="faces"):
        quality(shape.polynomial, shape.points, faces=np.zeros((3, 4), dtype=int))
    with pytest.raises(InvalidInputError, match="points"):
        quality(shape.polynomial, synthetic.circle(20).points)
    with pytest.raises(InvalidInputError, match="model"):
        quality("sphere", shape.points)


def test_far_distances_enter_the_chamfer_mean():
    shape = synthetic.circle(3000, radius=1.0)
    far = synthetic.circle(radius=0.2).polynomial
    q = quality(far, shape.points, tau=0.01, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
    # every distance is 0.8, far outside the exact band, on both sides
    assert q.recall == 0 and q.precision == 0 and q.n_spurious == 1
    assert q.data_to_zero_set == pytest.approx(0.8, abs=0.005)
    assert q.zero_set_to_data == pytest.approx(0.8, abs=0.005)


def test_measurements_are_reused_only_for_the_same_polynomial_cloud_and_options(monkeypatch):
    import importlib

    from ipfit.zeroset.quality import stray_samples

    quality_module = importlib.import_module("ipfit.zeroset.quality")

    shape = synthetic.circle(60)
    cloud = ipfit.Cloud(shape.points)
    wide = synthetic.from_terms(2, 2, {(2, 0): 1.0, (0, 2): 1.0, (0, 0): -1.3})  # radius 1.14
    extractions = []
    real = quality_module.extract_zero_set
    monkeypatch.setattr(quality_module, "extract_zero_set", lambda *a, **k: extractions.append(1) or real(*a, **k))
    q = quality(wide, cloud)
    assert len(extractions) == 1 and q.recall == 0.0
    # the repair's stray samples of the degree just judged: the same measurement
    assert len(stray_samples(wide, cloud)) > 0 and len(extractions) == 1
    assert quality(wide, cloud) == q and len(extractions) == 1
    # other options, another cloud of the same points: measured again
    assert quality(wide, cloud, tau=0.2).recall == 1.0 and len(extractions) == 2
    assert quality(wide, ipfit.Cloud(shape.points)) == q and len(extractions) == 3
    # arrays: a transient cloud per call, nothing kept across calls
    assert quality(wide, shape.points) == q and quality(wide, shape.points) == q and len(extractions) == 5
    assert quality(wide, ipfit.Cloud(1.14 * shape.points)).recall == 1.0 and len(extractions) == 6


def test_concurrent_measurements_match_sequential_ones():
    from concurrent.futures import ThreadPoolExecutor

    shape = synthetic.circle(80)
    polys = [synthetic.from_terms(2, 2, {(2, 0): 1.0, (0, 2): 1.0, (0, 0): -(r * r)}) for r in np.linspace(0.8, 1.2, 9)]
    expected = [quality(p, shape.points).f_score for p in polys]
    with ThreadPoolExecutor(4) as pool:  # more polynomials than the cache holds, from 4 threads
        got = list(pool.map(lambda p: quality(p, shape.points + 0.0).f_score, polys * 3))
    assert got == expected * 3

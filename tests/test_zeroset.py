"""Zero-set extraction: separable grid values, marching squares/cubes on exact shapes, export."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from ipfit import ImplicitPolynomial, InvalidInputError, Normalization, basis
from ipfit.datasets import synthetic
from ipfit.zeroset.extract import (ZeroSet, data_bounds, extract_zero_set, grid_axes, grid_values, sample_segments,
                           sample_triangles)


def product(p: ImplicitPolynomial, q: ImplicitPolynomial) -> ImplicitPolynomial:
    """p·q for identity-normalised polynomials (expanded coefficient by coefficient)."""
    terms: dict[tuple[int, ...], float] = {}
    for ea, ca in zip(p.exponents.tolist(), p.coefficients):
        for eb, cb in zip(q.exponents.tolist(), q.coefficients):
            key = tuple(a + b for a, b in zip(ea, eb))
            terms[key] = terms.get(key, 0.0) + ca * cb
    return synthetic.from_terms(p.dim, p.degree + q.degree, terms)


def random_poly(rng, dim: int, degree: int) -> ImplicitPolynomial:
    norm = Normalization(rng.normal(size=dim), 0.7)
    return ImplicitPolynomial.from_coefficients(rng.standard_normal(basis.n_coefficients(dim, degree)), dim, norm)


def _pointwise_check(poly, bounds, shape, rng):
    values = grid_values(poly, bounds, shape)
    assert values.shape == tuple(shape)
    axes = grid_axes(bounds, shape)
    index = tuple(rng.integers(0, n, 400) for n in shape)
    pts = np.column_stack([ax[i] for ax, i in zip(axes, index)])
    reference = poly(pts)
    # Compare against the size of the terms: near the zero set the sum cancels.
    magnitude = np.abs(basis.monomials(poly.normalization.apply(pts), poly.exponents)) @ np.abs(poly.coefficients)
    np.testing.assert_array_less(np.abs(values[index] - reference), 1e-10 * magnitude + 1e-300)


def test_grid_values_match_pointwise_degree8_3d(rng):
    poly = random_poly(rng, 3, 8)
    _pointwise_check(poly, np.array([[-1.0, 1.2], [-0.5, 1.5], [-2.0, 0.3]]), (23, 17, 29), rng)


def test_grid_values_match_pointwise_2d(rng):
    poly = random_poly(rng, 2, 10)
    _pointwise_check(poly, np.array([[-1.0, 1.2], [-0.5, 1.5]]), (41, 37), rng)


def test_grid_values_full_grid_equals_meshgrid():
    poly = synthetic.torus().polynomial
    bounds = np.array([[-1.5, 1.5], [-1.4, 1.4], [-0.6, 0.6]])
    values = grid_values(poly, bounds, 9)
    mesh = np.stack(np.meshgrid(*grid_axes(bounds, 9), indexing="ij"), axis=-1).reshape(-1, 3)
    np.testing.assert_allclose(values.ravel(), poly(mesh), rtol=1e-12, atol=1e-12)


def test_circle_zero_set_within_grid_step():
    center, radius = np.array([1.0, -0.5]), 2.0
    shape = synthetic.circle(radius=radius, center=tuple(center))
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=101)
    assert zs.n_components == 1 and zs.closed and zs.curve_closed == (True,)
    pts = np.concatenate(zs.curves)
    error = np.abs(np.linalg.norm(pts - center, axis=1) - radius)
    assert error.max() <= zs.step
    assert abs(zs.size - 2 * np.pi * radius) < 0.01 * 2 * np.pi * radius
    # every curve point is inside the box searched
    assert np.all((pts >= zs.bounds[:, 0] - 1e-12) & (pts <= zs.bounds[:, 1] + 1e-12))


def test_ellipse_zero_set_within_grid_step():
    shape = synthetic.ellipse(a=2.0, b=0.7, center=(3.0, 4.0))
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=200)
    assert zs.n_components == 1 and zs.closed
    pts = np.concatenate(zs.curves)
    assert shape.polynomial.taubin_distance(pts).max() <= zs.step


def test_sphere_zero_set_within_grid_step_in_user_coordinates():
    center, radius, scale = np.array([5.0, -3.0, 2.0]), 1.5, 0.8
    # |u|² − (r/s)² in normalised coordinates u = (x − c)/s: the sphere |x − c| = r.
    norm = Normalization(center, scale)
    poly = synthetic.from_terms(3, 2, {(2, 0, 0): 1, (0, 2, 0): 1, (0, 0, 2): 1, (0, 0, 0): -(radius / scale) ** 2})
    poly = ImplicitPolynomial(poly.exponents, poly.coefficients, norm)
    zs = extract_zero_set(poly, resolution=48)
    assert zs.dim == 3 and zs.n_components == 1 and zs.closed
    error = np.abs(np.linalg.norm(zs.vertices - center, axis=1) - radius)
    assert error.max() <= zs.step
    assert abs(zs.size - 4 * np.pi * radius**2) < 0.02 * 4 * np.pi * radius**2


def test_torus_zero_set_within_grid_step():
    R, r = 1.0, 0.4
    shape = synthetic.torus(major=R, minor=r)
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=64)
    assert zs.n_components == 1 and zs.closed
    v = zs.vertices
    distance = np.hypot(np.hypot(v[:, 0], v[:, 1]) - R, v[:, 2]) - r
    assert np.abs(distance).max() <= zs.step
    # Euler characteristic of a torus: V − E + F = 0 (the mesh shares its vertices)
    edges = np.unique(np.sort(np.concatenate([zs.faces[:, [0, 1]], zs.faces[:, [1, 2]], zs.faces[:, [2, 0]]]),
                              axis=1), axis=0)
    assert len(v) - len(edges) + len(zs.faces) == 0


def test_empty_and_open_zero_sets():
    empty = synthetic.from_terms(2, 2, {(2, 0): 1, (0, 2): 1, (0, 0): 1})
    zs = extract_zero_set(empty, bounds=[[-1, 1], [-1, 1]], resolution=32)
    assert zs.is_empty and zs.n_components == 0 and not zs.closed and zs.size == 0
    assert zs.sample().points.shape == (0, 2)
    empty3 = synthetic.from_terms(3, 2, {(2, 0, 0): 1, (0, 0, 0): 1})
    zs3 = extract_zero_set(empty3, bounds=[[-1, 1]] * 3, resolution=16)
    assert zs3.is_empty and zs3.n_components == 0 and not zs3.closed
    line = synthetic.from_terms(2, 1, {(1, 0): 1.0, (0, 0): -0.1})
    zs = extract_zero_set(line, bounds=[[-1, 1], [-1, 1]], resolution=64)
    assert zs.n_components == 1 and zs.reaches_boundary and not zs.closed and zs.curve_closed == (False,)
    plane = synthetic.from_terms(3, 1, {(0, 0, 1): 1.0})
    zs = extract_zero_set(plane, bounds=[[-1, 1]] * 3, resolution=16)
    assert zs.n_components == 1 and not zs.closed


def test_components_of_two_spheres_and_two_circles():
    a = synthetic.sphere(radius=0.5, center=(-1, 0, 0)).polynomial
    b = synthetic.sphere(radius=0.4, center=(1, 0, 0)).polynomial
    zs = extract_zero_set(product(a, b), bounds=[[-2, 2], [-1, 1], [-1, 1]], resolution=60)
    assert zs.n_components == 2 and zs.closed
    parts = zs.components()
    assert len(parts) == 2
    centers = sorted(v.mean(axis=0)[0] for v, _ in parts)
    np.testing.assert_allclose(centers, [-1, 1], atol=zs.step)
    for v, f in parts:
        assert f.max() < len(v)
    c1 = synthetic.circle(radius=0.5, center=(-1, 0)).polynomial
    c2 = synthetic.circle(radius=0.5, center=(1, 0)).polynomial
    zs2 = extract_zero_set(product(c1, c2), bounds=[[-2, 2], [-1, 1]], resolution=200)
    assert zs2.n_components == 2 and len(zs2.components()) == 2


def test_samples_weights_measure_length_and_area():
    circle = extract_zero_set(synthetic.circle().polynomial, bounds=[[-2, 2], [-2, 2]], resolution=200)
    s = circle.sample(0.01)
    assert abs(s.weights.sum() - circle.size) < 1e-9
    assert np.all(s.labels == 0)
    sphere = extract_zero_set(synthetic.sphere().polynomial, bounds=[[-2, 2]] * 3, resolution=40)
    s3 = sphere.sample(sphere.step / 3)
    assert abs(s3.weights.sum() - sphere.size) < 1e-9 * sphere.size
    assert len(s3.points) > 4 * len(sphere.faces)
    capped = sphere.sample(sphere.step / 10, max_samples=5 * len(sphere.faces))
    assert len(capped.points) <= 5 * len(sphere.faces)


def test_sample_helpers_cover_their_shapes():
    seg = sample_segments(np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]]), 0.1)
    np.testing.assert_allclose(seg.points[:, 0], np.arange(10) * 0.1 + 0.05)
    np.testing.assert_allclose(seg.weights, 0.1)
    tri = sample_triangles(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), 0.25)
    assert len(tri.points) == 36  # k = ceil(√2 / 0.25) = 6 → 36 sub-triangles
    np.testing.assert_allclose(tri.weights.sum(), 0.5)
    assert np.all(tri.points[:, :2].sum(axis=1) < 1)


def test_data_bounds_margin():
    box = data_bounds([[0.0, 0.0, 0.0], [4.0, 2.0, 0.0]], margin=0.25)
    np.testing.assert_allclose(box[0], [-1, 5])
    np.testing.assert_allclose(box[1], [-1, 3])
    assert box[2, 1] - box[2, 0] > 0  # a flat cloud still gets a thick box


def test_default_box_and_isotropic_grid():
    shape = synthetic.ellipse(a=3.0, b=1.0)
    zs = extract_zero_set(shape.polynomial, points=shape.points, resolution=100)
    np.testing.assert_allclose(zs.spacing[0], zs.spacing[1])
    assert zs.shape[0] == 100 and zs.shape[1] < 100
    assert zs.n_components == 1 and zs.closed


@pytest.mark.parametrize("kwargs, match", [
    ({"bounds": [[0, 1]]}, "bounds"),
    ({"bounds": [[1, 0], [0, 1]]}, "bounds"),
    ({"resolution": 1}, "resolution"),
    ({"resolution": 10**6}, "resolution"),
    ({"margin": -1.0}, "margin"),
])
def test_bad_arguments(kwargs, match):
    poly = synthetic.circle().polynomial
    with pytest.raises(InvalidInputError, match=match):
        extract_zero_set(poly, **kwargs)


def test_grid_values_rejects_non_polynomial():
    with pytest.raises(InvalidInputError, match="poly"):
        grid_values(np.zeros(6), [[0, 1], [0, 1]], 4)


# -- contains: the sign test ------------------------------------------------------------------

@pytest.mark.parametrize("make", [synthetic.circle, synthetic.ellipse, synthetic.sphere, synthetic.ellipsoid,
                                  synthetic.torus])
def test_contains_classifies_inside_and_outside(make):
    shape = make()
    step = 0.05
    assert shape.polynomial.contains(shape.points - step * shape.normals).all()
    assert not shape.polynomial.contains(shape.points + step * shape.normals).any()


def test_contains_on_bundled_shapes():
    bundled = pytest.importorskip("ipfit.datasets.bundled")
    from ipfit import fit_3l
    from ipfit.normals import estimate_normals

    checked = 0
    for name in bundled.dataset_names():
        points, normals = bundled.load_dataset(name)
        if len(points) > 5000:
            continue
        normals = estimate_normals(points) if normals is None else normals
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        poly = fit_3l(points, normals, 6)
        tau = 0.02 * np.linalg.norm(np.ptp(points, axis=0))
        values, grads = poly.value_and_gradient(points)
        norm = np.linalg.norm(grads, axis=1)
        # Where the fit is accurate (zero set within τ/4, gradient along the normal), a step
        # of τ along the normal crosses it: the sign test must say inside, then outside.
        good = (np.abs(values) < norm * tau / 4) & (np.sum(grads * normals, axis=1) > 0.9 * norm)
        assert good.mean() > 0.2, name
        assert poly.contains(points[good] - tau * normals[good]).all(), name
        assert not poly.contains(points[good] + tau * normals[good]).any(), name
        checked += 1
    if not checked:
        pytest.skip("no bundled dataset with fewer than 5000 points")


# -- export -------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl"])
def test_mesh_export_round_trip(tmp_path, suffix):
    import trimesh

    zs = extract_zero_set(synthetic.sphere().polynomial, bounds=[[-1.5, 1.5]] * 3, resolution=24)
    path = tmp_path / f"sphere{suffix}"
    zs.save(path)
    mesh = trimesh.load(path, force="mesh", process=True)
    assert len(mesh.faces) == len(zs.faces)
    np.testing.assert_allclose(np.linalg.norm(mesh.vertices, axis=1), 1.0, atol=zs.step)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary file left


def test_curve_export_svg_and_csv(tmp_path):
    c1 = synthetic.circle(radius=0.5, center=(-1, 0)).polynomial
    line = synthetic.from_terms(2, 1, {(0, 1): 1.0, (0, 0): -0.8})
    zs = extract_zero_set(product(c1, line), bounds=[[-2, 2], [-1, 1]], resolution=120)
    assert zs.n_components == 2
    zs.save(tmp_path / "z.svg")
    zs.save(tmp_path / "z.csv")
    root = ET.parse(tmp_path / "z.svg").getroot()
    paths = root.findall(".//{http://www.w3.org/2000/svg}path")
    assert len(paths) == 2
    assert sum(p.get("d").endswith("Z") for p in paths) == 1  # the circle closes, the line does not
    rows = np.loadtxt(tmp_path / "z.csv", delimiter=",", comments="#", skiprows=3)
    assert rows.shape == (sum(len(c) for c in zs.curves), 3)
    assert set(rows[:, 0].astype(int)) == {0, 1}
    np.testing.assert_allclose(rows[:, 1:], np.concatenate(zs.curves))


def test_export_errors(tmp_path):
    zs2 = extract_zero_set(synthetic.circle().polynomial, resolution=32)
    zs3 = extract_zero_set(synthetic.sphere().polynomial, resolution=12)
    with pytest.raises(InvalidInputError, match="svg"):
        zs2.save(tmp_path / "c.ply")
    with pytest.raises(InvalidInputError, match="ply"):
        zs3.save(tmp_path / "s.svg")
    empty = extract_zero_set(synthetic.from_terms(3, 2, {(2, 0, 0): 1, (0, 0, 0): 1}), bounds=[[-1, 1]] * 3,
                             resolution=8)
    with pytest.raises(InvalidInputError, match="empty"):
        empty.save(tmp_path / "e.ply")
    with pytest.raises(InvalidInputError, match="does not exist"):
        zs3.save(tmp_path / "missing" / "s.ply")
    assert list(tmp_path.iterdir()) == []


def test_zero_set_repr_and_json_free():
    zs = extract_zero_set(synthetic.circle().polynomial, resolution=32)
    assert isinstance(zs, ZeroSet)
    assert "components=1" in repr(zs)
    json.dumps({"step": zs.step, "closed": zs.closed})

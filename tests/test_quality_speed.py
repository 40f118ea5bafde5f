"""The fast quality path against independent references.

Analytic shapes with known distances (the "within τ" decisions must switch exactly where the
known gap crosses τ), a brute-force exact computation on small cases (every point–triangle
or point–segment distance, in numpy, here), and trimesh's closest points for the compiled
kernel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ipfit
from ipfit.datasets import synthetic
from ipfit.zeroset.quality import quality, spurious_components
from ipfit.zeroset.extract import ZeroSet, extract_zero_set

from test_zeroset import product


# -- brute force: every distance, numpy only ----------------------------------------------------

def brute_segments(p, a, b):
    """(P, S) distances from points to segments."""
    ab = (b - a)[None]
    ap = p[:, None] - a[None]
    t = np.clip(np.sum(ap * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-300), 0, 1)
    return np.linalg.norm(ap - t[..., None] * ab, axis=-1)


def brute_triangles(p, a, b, c, block=256):
    """min over all triangles of the point–triangle distance, per point."""
    out = np.empty(len(p))
    n = np.cross(b - a, c - a)
    nn = np.maximum(np.sum(n * n, 1), 1e-300)
    for s in range(0, len(p), block):
        q = p[s:s + block, None]  # (B, 1, 3)
        # projection onto each plane; inside test by the signs of the sub-triangle normals
        h = np.sum((q - a) * n, -1) / nn
        foot = q - h[..., None] * n
        inside = np.ones(h.shape, dtype=bool)
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.sum(np.cross(v - u, foot - u) * n, -1) >= 0
        plane = np.abs(h) * np.sqrt(nn)
        edges = np.minimum.reduce([brute_segments(q[:, 0], u, v) for u, v in ((a, b), (b, c), (c, a))])
        out[s:s + block] = np.where(inside, plane, edges).min(axis=1)
    return out


def brute_measures(zs, points, tau, spacing, faces=None, contour=None):
    """Recall, precision and spurious flags from all distances (same quadrature samples)."""
    samples = zs.sample(spacing)
    if zs.dim == 3:
        v, f = zs.vertices, zs.faces
        d_data = brute_triangles(points, v[f[:, 0]], v[f[:, 1]], v[f[:, 2]])
    else:
        starts, ends, _ = zs.segments()
        d_data = brute_segments(points, starts, ends).min(axis=1)
    if faces is not None:
        d_zero = brute_triangles(samples.points, points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]])
    elif contour is not None:
        d_zero = brute_segments(samples.points, contour, np.roll(contour, -1, axis=0)).min(axis=1)
    else:
        d_all = np.linalg.norm(samples.points[:, None] - points[None], axis=-1)
        d_zero = d_all.min(axis=1)
    recall = float(np.mean(d_data <= tau))
    within = d_zero <= tau
    if faces is None and contour is None:  # a bare cloud: the gap allowance, by brute force
        gaps = np.sort(np.linalg.norm(points[:, None] - points[None], axis=-1), axis=1)[:, points.shape[1]]
        within = d_zero <= np.sqrt(tau**2 + gaps[d_all.argmin(axis=1)] ** 2)
    precision = float(samples.weights[within].sum() / samples.weights.sum())
    nearest = np.full(zs.n_components, np.inf)
    np.minimum.at(nearest, samples.labels, d_zero)
    return recall, precision, nearest > tau, d_data, d_zero, samples


# -- analytic shapes ----------------------------------------------------------------------------

@pytest.mark.parametrize("factor, expected", [(0.9, 0.0), (1.1, 1.0)])
def test_sphere_inside_a_larger_sphere_switches_at_the_gap(factor, expected):
    import trimesh

    gap = 0.05
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=1 + gap)  # flat faces sag by < 0.002
    zs = extract_zero_set(synthetic.sphere().polynomial, bounds=[[-1.3, 1.3]] * 3, resolution=64)
    q = quality(zs, mesh.vertices, faces=mesh.faces, tau=factor * gap)
    assert q.recall == expected and q.precision == expected
    assert q.n_spurious == (1 if expected == 0 else 0) and q.closed


def test_plane_over_a_square_precision_is_the_offset_area():
    # data: the unit square at z = 0 as a mesh; zero set: the plane z = c. A point (x, y, c) is
    # within τ of the square iff (x, y) is within r = √(τ² − c²) of it: area 1 + 4r + πr².
    n = 11
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)])
    idx = np.arange(n * n).reshape(n, n)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()])
    faces = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    c, tau = 0.02, 0.05
    plane = synthetic.from_terms(3, 1, {(0, 0, 1): 1.0, (0, 0, 0): -c})
    zs = extract_zero_set(plane, bounds=[[-0.3, 1.3], [-0.3, 1.3], [-0.2, 0.2]], resolution=129)
    q = quality(zs, pts, faces=faces, tau=tau)
    r = math.sqrt(tau ** 2 - c ** 2)
    expected = (1 + 4 * r + math.pi * r ** 2) / 1.6 ** 2
    # one sample per extracted triangle (0.0125 grid): a midpoint quadrature of the indicator;
    # finer samples converge to the area
    assert q.precision == pytest.approx(expected, abs=0.005)
    assert quality(zs, pts, faces=faces, tau=tau, spacing=tau / 10).precision == pytest.approx(expected, abs=0.0015)
    assert q.recall == 1.0 and q.n_spurious == 0 and not q.closed
    assert quality(zs, pts, faces=faces, tau=0.9 * c).recall == 0.0  # every vertex is c below the plane


@pytest.mark.parametrize("factor, expected", [(0.9, 0.0), (1.1, 1.0)])
def test_circle_against_a_larger_contour_switches_at_the_gap(factor, expected):
    gap = 0.04
    contour = synthetic.circle(2000, radius=1 + gap).points  # chords sag by 1e-6
    zs = extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.3, 1.3]] * 2)
    q = quality(zs, contour, ordered_contour=True, tau=factor * gap)
    assert q.reference == "contour"
    assert q.recall == expected and q.precision == expected
    assert q.data_to_zero_set == pytest.approx(gap, abs=zs.step / 4)


# -- brute force on small cases -----------------------------------------------------------------

def test_3d_matches_brute_force_exactly():
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    pts, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    # an ellipsoid crossing the sphere (distances on both sides of τ) and a small sphere just
    # off it: one component near, one spurious
    ellipsoid = synthetic.from_terms(3, 2, {(2, 0, 0): 1 / 1.12 ** 2, (0, 2, 0): 1.0, (0, 0, 2): 1 / 0.93 ** 2,
                                            (0, 0, 0): -1.0})
    blob = synthetic.sphere(radius=0.12, center=(0.0, 1.35, 0.0)).polynomial
    zs = extract_zero_set(product(ellipsoid, blob), bounds=[[-1.4, 1.4], [-1.4, 1.6], [-1.4, 1.4]], resolution=30)
    tau = 0.06
    q = quality(zs, pts, faces=faces, tau=tau)
    recall, precision, flags, d_data, d_zero, samples = brute_measures(zs, pts, tau, tau, faces=faces)
    assert 0.2 < recall < 0.9 and 0.2 < precision < 0.9  # a case with decisions on both sides
    assert q.recall == recall and q.precision == pytest.approx(precision, abs=1e-12)
    assert list(spurious_components(zs, pts, faces=faces, tau=tau)) == list(flags) and q.n_spurious == flags.sum() == 1
    assert q.data_to_zero_set == pytest.approx(d_data.mean(), rel=1e-9)
    assert q.zero_set_to_data == pytest.approx(np.dot(samples.weights, d_zero) / samples.weights.sum(), rel=1e-9)


def test_2d_matches_brute_force_exactly():
    contour = synthetic.ellipse(300, a=1.0, b=0.8).points
    wavy = synthetic.from_terms(2, 4, {(2, 0): 1.0, (0, 2): 1 / 0.85 ** 2, (4, 0): 0.08, (0, 0): -1.08})
    zs = extract_zero_set(wavy, bounds=[[-1.4, 1.4], [-1.2, 1.2]], resolution=300)
    tau = 0.05
    for options, brute in (({"ordered_contour": True}, {"contour": contour}), ({}, {})):
        q = quality(zs, contour, tau=tau, **options)
        recall, precision, flags, d_data, _, _ = brute_measures(zs, contour, tau, tau, **brute)
        assert 0.1 < recall < 0.95 and 0.1 < precision < 0.95
        assert q.recall == recall and q.precision == pytest.approx(precision, abs=1e-12)
        assert q.n_spurious == flags.sum()
        assert q.data_to_zero_set == pytest.approx(d_data.mean(), rel=1e-9)


def test_within_tau_is_decided_even_when_the_nearest_element_has_no_near_sample():
    # A long sliver whose only sample (its centroid) is far away, and eight small triangles
    # 1.3τ above the query point whose centroids are its nearest samples: the sliver, 0.9τ
    # below, is still found, since a sample within τ + (the sliver's reach) was left out.
    tau, half = 0.01, 1.0
    tiny = 0.002
    verts = [[-half, 0.0, 0.0], [half, 0.0, 0.0], [0.0, 0.001, 0.0]]
    tris = [[0, 1, 2]]
    for i in range(8):
        x0 = 0.9 - 0.004 * i
        base = len(verts)
        verts += [[x0, 0.0, 2.2 * tau], [x0 + tiny, 0.0, 2.2 * tau], [x0, tiny, 2.2 * tau]]
        tris.append([base, base + 1, base + 2])
    verts, tris = np.array(verts), np.array(tris)
    zs = ZeroSet(3, np.array([[-1.5, 1.5]] * 3), np.full(3, 0.01), (301, 301, 301), vertices=verts, faces=tris)
    points = np.array([[0.89, 0.0, 0.9 * tau], [-0.5, 0.0, 0.5 * tau]])
    assert np.all(brute_triangles(points, verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]) <= tau)
    q = quality(zs, points, tau=tau, spacing=10.0)  # one sample per triangle
    assert q.recall == 1.0
    assert q.data_to_zero_set == pytest.approx(0.7 * tau, rel=1e-6)


# -- the compiled kernel against trimesh ---------------------------------------------------------

def test_kernel_matches_trimesh_closest_points(rng):
    from trimesh.triangles import closest_point

    from ipfit.geometry._distance_kernels import nearest_candidates

    tri = rng.normal(size=(400, 3, 3))
    tri[:40, 2] = tri[:40, 0] + 0.5 * (tri[:40, 1] - tri[:40, 0])  # collinear (zero-area) triangles
    tri[40:50, 1] = tri[40:50, 0]                                     # two equal corners
    points = rng.normal(size=(400, 3)) * 1.5
    idx = np.arange(400)[:, None]
    got = nearest_candidates(points, idx, 400, np.arange(400), tri[:, 0].copy(), tri[:, 1].copy(),
                             tri[:, 2].copy(), np.full(400, np.inf), True)
    want = np.linalg.norm(points[50:] - closest_point(tri[50:], points[50:]), axis=1)
    np.testing.assert_allclose(got[50:], want, rtol=1e-9, atol=1e-12)
    # degenerate triangles: the nearest point of their edges (a segment)
    seg = brute_segments(points[:50], tri[:50, 0], tri[:50, 1])[np.arange(50), np.arange(50)]
    seg2 = brute_segments(points[:50], tri[:50, 0], tri[:50, 2])[np.arange(50), np.arange(50)]
    np.testing.assert_allclose(got[:50], np.minimum(seg, seg2), rtol=1e-9, atol=1e-12)
    # segments, and the cap by the nearest-sample distance
    segs = nearest_candidates(points[:, :2].copy(), idx, 400, np.arange(400), tri[:, 0, :2].copy(),
                              tri[:, 1, :2].copy(), tri[:, 0, :2].copy(), np.full(400, 0.3), False)
    ref = brute_segments(points[:, :2], tri[:, 0, :2], tri[:, 1, :2])[np.arange(400), np.arange(400)]
    np.testing.assert_allclose(segs, np.minimum(ref, 0.3), rtol=1e-9, atol=1e-12)


# -- speed-ups that must not change a measurement ---------------------------------------------------

def test_threads_and_caches_do_not_change_a_measurement(monkeypatch):
    # A zero set of some 60,000 samples (above the threaded-query threshold) against a mesh: the
    # same Quality threaded or not, and on a new cloud (nothing kept) as on one that keeps its data
    # side; a cloud with faces is measured against them, one without against the bare points.
    import importlib

    import trimesh

    qmod = importlib.import_module("ipfit.zeroset.quality")
    from ipfit.geometry import distance as _distance

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    pts, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    wobbly = synthetic.from_terms(3, 4, {(2, 0, 0): 1 / 1.1 ** 2, (0, 2, 0): 1.0, (0, 0, 2): 1 / 0.9 ** 2,
                                         (2, 2, 0): 0.3, (0, 0, 0): -1.0})
    details = qmod._measure(wobbly, pts, faces=faces, details=True)
    assert len(details[2].points) > _distance._THREADED_QUERIES
    mesh_cloud = ipfit.Cloud(pts, faces=faces)
    threaded = quality(wobbly, mesh_cloud).to_dict()
    monkeypatch.setattr(_distance, "_THREADED_QUERIES", 10**12)
    assert quality(wobbly, pts, faces=faces).to_dict() == threaded
    assert quality(wobbly.with_coefficients(2 * wobbly.coefficients), mesh_cloud).to_dict() == threaded  # data side kept
    bare = quality(wobbly, pts)
    assert bare.reference == "points" and threaded["reference"] == "faces"
    assert quality(wobbly, ipfit.Cloud(pts)).to_dict() == bare.to_dict()
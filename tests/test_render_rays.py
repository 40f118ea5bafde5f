"""Ray-cast rendering against closed-form hits: a sphere (the quadratic formula), a torus (its
quartic along the ray, expanded by hand) and a degree-8 union of both and two spheres; and the
render's memory, which no longer grows with the degree."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from ipfit.analysis.rays import _box_interval, camera_rays, first_hits, intersect_rays, render
from ipfit.datasets.synthetic import from_terms

BOX = np.array([[-1.6, 1.6], [-1.6, 1.6], [-1.0, 1.0]])


def _product(*factors: dict) -> dict:
    """Coefficients of a product of polynomials given as {exponent tuple: coefficient}."""
    out = {(0, 0, 0): 1.0}
    for factor in factors:
        new: dict = {}
        for e1, c1 in out.items():
            for e2, c2 in factor.items():
                e = tuple(a + b for a, b in zip(e1, e2, strict=True))
                new[e] = new.get(e, 0.0) + c1 * c2
        out = new
    return out


def _sphere_terms(center, radius) -> dict:
    cx, cy, cz = center
    return {(2, 0, 0): 1.0, (0, 2, 0): 1.0, (0, 0, 2): 1.0, (1, 0, 0): -2 * cx, (0, 1, 0): -2 * cy,
            (0, 0, 1): -2 * cz, (0, 0, 0): cx * cx + cy * cy + cz * cz - radius * radius}


def _torus_terms(major, minor) -> dict:
    # (x² + y² + z² + R² − r²)² − 4R²(x² + y²)
    s = major * major - minor * minor
    return {(4, 0, 0): 1.0, (0, 4, 0): 1.0, (0, 0, 4): 1.0, (2, 2, 0): 2.0, (2, 0, 2): 2.0, (0, 2, 2): 2.0,
            (2, 0, 0): 2 * s - 4 * major * major, (0, 2, 0): 2 * s - 4 * major * major, (0, 0, 2): 2 * s,
            (0, 0, 0): s * s}


def _sphere_quadratic(o, d, center, radius):
    """Both roots of |o + t d − c|² = r² (the quadratic formula, NaN where the discriminant is
    negative) and the discriminant over a²."""
    a = np.sum(d * d, axis=1)
    oc = o - np.asarray(center)
    b = 2 * np.sum(d * oc, axis=1)
    c = np.sum(oc * oc, axis=1) - radius * radius
    disc = b * b - 4 * a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    t = np.column_stack([(-b - root) / (2 * a), (-b + root) / (2 * a)])
    t[disc < 0] = np.nan
    return t, disc / a**2


def _sphere_first(o, d, center, radius, lo, hi):
    """First t in [lo, hi] on the sphere; also how grazing (|disc| / a²)."""
    t, disc = _sphere_quadratic(o, d, center, radius)
    return _first_in(t, lo, hi), np.abs(disc)


def _torus_quartic_roots(o, d, major, minor):
    """The complex roots of the torus's quartic in t along o + t d (numpy's eigenvalues of the
    companion matrix of the hand-expanded coefficients)."""
    s = major * major - minor * minor
    # A(t) = |o + t d|² + R² − r², B(t) = (o_x + t d_x)² + (o_y + t d_y)², f = A² − 4R² B
    A = np.stack([np.sum(d * d, axis=1), 2 * np.sum(o * d, axis=1), np.sum(o * o, axis=1) + s], axis=1)
    B = np.stack([np.sum(d[:, :2] ** 2, axis=1), 2 * np.sum(o[:, :2] * d[:, :2], axis=1),
                  np.sum(o[:, :2] ** 2, axis=1)], axis=1)
    quartic = np.stack([A[:, 0] ** 2, 2 * A[:, 0] * A[:, 1], A[:, 1] ** 2 + 2 * A[:, 0] * A[:, 2],
                        2 * A[:, 1] * A[:, 2], A[:, 2] ** 2], axis=1)
    quartic[:, 2:] -= 4 * major * major * B
    companion = np.zeros((len(o), 4, 4))
    companion[:, 0, :] = -quartic[:, 1:] / quartic[:, :1]
    companion[:, np.arange(1, 4), np.arange(3)] = 1.0
    return np.linalg.eigvals(companion)


def _torus_first(o, d, major, minor, lo, hi):
    """First t in [lo, hi] on the torus; also how grazing (the smallest |imag| of a root pair)."""
    roots = _torus_quartic_roots(o, d, major, minor)
    real = np.abs(roots.imag) <= 1e-9 * (1 + np.abs(roots.real))
    t = np.where(real, roots.real, np.nan)
    pair = np.where(real, np.inf, np.abs(roots.imag)).min(axis=1)
    return _first_in(t, lo, hi), pair


def _first_in(t, lo, hi):
    inside = (t >= lo[:, None]) & (t <= hi[:, None])
    first = np.min(np.where(inside, t, np.inf), axis=1)
    return np.where(np.isfinite(first), first, np.nan)


def _camera(size, view=(25.0, -50.0)):
    origins, direction, _ = camera_rays(BOX, (size, size), view)
    d = np.broadcast_to(direction, origins.shape)
    lo, hi = _box_interval(origins, d, BOX)
    return origins, np.ascontiguousarray(d), lo, hi


def _compare(got, expected, grazing, size):
    """Hit masks agree except at grazing pixels (the reference is ambiguous there), depths to 1e-9."""
    differ = np.isfinite(got) != np.isfinite(expected)
    assert differ.sum() <= max(2, size * size // 5000), np.flatnonzero(differ)
    assert np.all(grazing[differ] < 1e-4)  # only rays that (nearly) touch the surface
    both = np.isfinite(got) & np.isfinite(expected)
    assert both.sum() > 0.05 * size * size  # the surface fills a fair part of the picture
    close = np.abs(got[both] - expected[both]) <= 1e-9 * (1 + np.abs(expected[both]))
    # a depth off by more is a double root (accurate to ~sqrt(eps)) at a grazing pixel
    assert np.all(close | (grazing[both] < 1e-6))
    assert close.mean() > 0.999


@pytest.mark.parametrize("center,radius", [((0.0, 0.0, 0.0), 0.9), ((0.3, -0.2, 0.1), 1.3)])
def test_render_depths_of_a_sphere_equal_the_quadratic_formula(center, radius):
    poly = from_terms(3, 2, _sphere_terms(center, radius))
    o, d, lo, hi = _camera(160)
    expected, grazing = _sphere_first(o, d, center, radius, lo, hi)
    _compare(first_hits(poly, o, d[0], BOX), expected, grazing, 160)


@pytest.mark.parametrize("view", [(25.0, -50.0), (70.0, 10.0), (0.0, 30.0)])
def test_render_depths_of_a_torus_equal_its_quartics_roots(view):
    poly = from_terms(3, 4, _torus_terms(1.0, 0.35))
    o, d, lo, hi = _camera(140, view)
    expected, grazing = _torus_first(o, d, 1.0, 0.35, lo, hi)
    _compare(first_hits(poly, o, d[0], BOX), expected, grazing, 140)


def _union_of_eight():
    """Degree 8: a torus and two spheres, one in its hole, one beside it (first hit: the nearest)."""
    parts = [("torus", (1.0, 0.35)), ("sphere", ((0.0, 0.0, 0.0), 0.3)), ("sphere", ((1.2, -0.9, 0.4), 0.35))]
    terms = _product(_torus_terms(1.0, 0.35), _sphere_terms(*parts[1][1]), _sphere_terms(*parts[2][1]))
    return from_terms(3, 8, terms), parts


def _union_first(parts, o, d, lo, hi):
    firsts, grazings = [], []
    for kind, args in parts:
        first, grazing = (_torus_first if kind == "torus" else _sphere_first)(o, d, *args, lo, hi)
        firsts.append(first)
        grazings.append(grazing)
    return np.fmin.reduce(firsts), np.minimum.reduce(grazings)


def test_render_of_a_degree_8_union_is_the_nearest_of_its_parts():
    poly, parts = _union_of_eight()
    size = 160
    o, d, lo, hi = _camera(size)
    expected, grazing = _union_first(parts, o, d, lo, hi)
    _compare(first_hits(poly, o, d[0], BOX), expected, grazing, size)
    # the picture draws exactly the pixels whose rays hit (white elsewhere)
    image = render(poly, BOX, size=size, view=(25.0, -50.0))
    drawn = (image < 255).any(axis=2).reshape(-1)
    differ = drawn != np.isfinite(expected)
    assert differ.sum() <= 5 and np.all(grazing[differ] < 1e-4)


def test_all_hits_of_the_union_along_lines_are_its_parts_hits(rng):
    poly, parts = _union_of_eight()
    o = rng.uniform(-2.5, 2.5, (400, 3))
    d = rng.standard_normal((400, 3))
    hits = intersect_rays(o, d, poly, tmin=-np.inf)
    expected = []
    for kind, args in parts:
        if kind == "sphere":
            t = _sphere_roots(o, d, *args)
        else:
            t = _torus_roots(o, d, *args)
        expected.append(t)
    expected = np.sort(np.concatenate(expected, axis=1), axis=1)
    count = np.isfinite(expected).sum(axis=1)
    clear = _separated(expected)  # no two hits closer than 1e-6 (tangent or touching parts)
    assert clear.mean() > 0.95
    assert np.array_equal(hits.count[clear], count[clear])
    for i in np.flatnonzero(clear & (count > 0)):
        np.testing.assert_allclose(hits.t[i, :count[i]], expected[i, :count[i]], rtol=1e-9, atol=1e-9)
    assert set(np.unique(hits.count)) >= {0, 2, 4}


def _sphere_roots(o, d, center, radius):
    """Both roots where the ray crosses the sphere (a tangent ray's double root counts as none)."""
    t, disc = _sphere_quadratic(o, d, center, radius)
    t[disc <= 0] = np.nan
    return t


def _torus_roots(o, d, major, minor):
    """Every real root of the torus's quartic (looser on the imaginary part than _torus_first)."""
    roots = _torus_quartic_roots(o, d, major, minor)
    real = np.abs(roots.imag) <= 1e-7 * (1 + np.abs(roots.real))
    return np.where(real, roots.real, np.nan)


def _separated(t):
    gaps = np.diff(t, axis=1)
    return ~np.any(np.isfinite(gaps) & (gaps < 1e-6), axis=1)


def test_render_memory_does_not_grow_with_the_degree():
    """A 480 x 480 picture of the degree-8 union: its arrays stay a few of the image's size
    (the eigenvalue method built a (rays, monomials, degree) table per block and the monomials'
    gradients of 65,536 hits at once: hundreds of MB)."""
    poly, _ = _union_of_eight()
    render(poly, BOX, size=8)  # loads the compiled kernel first: numba's own allocations are not the render's
    tracemalloc.start()
    try:
        image = render(poly, BOX, size=480)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert (image < 255).any(axis=2).mean() > 0.1
    # the rays' origins alone are 480² × 3 float64 = 5.5 MB; everything else is a few such arrays
    assert peak < 60e6, f"{peak / 1e6:.0f} MB"

"""Analytic shapes with known implicit polynomials, for tests, examples and benchmarks.

Each function returns a :class:`Shape`: points on the exact zero set, their outward unit
normals, and the exact polynomial (f > 0 outside, identity normalisation).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .. import basis
from .._utils.validation import check_rng
from ..polynomial import ImplicitPolynomial

__all__ = ["Shape", "circle", "ellipse", "sphere", "ellipsoid", "torus", "from_terms"]


class Shape(NamedTuple):
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    polynomial: ImplicitPolynomial


def from_terms(dim: int, degree: int, terms: dict[tuple[int, ...], float]) -> ImplicitPolynomial:
    """Polynomial from ``{exponent tuple: coefficient}`` (identity normalisation).

    >>> from_terms(2, 2, {(0, 0): -1, (2, 0): 1, (0, 2): 1})([[1.0, 0.0]]).tolist()
    [0.0]
    """
    exps = basis.exponents(dim, degree)
    index = {tuple(e): i for i, e in enumerate(exps.tolist())}
    coef = np.zeros(len(exps))
    for e, c in terms.items():
        coef[index[tuple(e)]] += c
    return ImplicitPolynomial(exps, coef)


def _unit(v: NDArray) -> NDArray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _place(points, normals, center):
    return points + np.asarray(center, dtype=float), normals


def ellipse(n: int = 200, a: float = 2.0, b: float = 1.0, center=(0.0, 0.0), *, rng=None,
            random: bool = False) -> Shape:
    """Axis-aligned ellipse (x/a)² + (y/b)² = 1 around ``center``."""
    t = check_rng(rng).uniform(0, 2 * np.pi, n) if random else np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.column_stack([a * np.cos(t), b * np.sin(t)])
    nrm = _unit(np.column_stack([np.cos(t) / a, np.sin(t) / b]))
    cx, cy = center
    poly = from_terms(2, 2, {(2, 0): 1 / a**2, (0, 2): 1 / b**2, (1, 0): -2 * cx / a**2, (0, 1): -2 * cy / b**2,
                             (0, 0): cx**2 / a**2 + cy**2 / b**2 - 1})
    pts, nrm = _place(pts, nrm, center)
    return Shape(pts, nrm, poly)


def circle(n: int = 200, radius: float = 1.0, center=(0.0, 0.0), *, rng=None, random: bool = False) -> Shape:
    """Circle of ``radius`` around ``center``."""
    return ellipse(n, radius, radius, center, rng=rng, random=random)


def _sphere_directions(n: int, rng) -> NDArray:
    if rng is None:
        i = np.arange(n) + 0.5
        z = 1 - 2 * i / n
        r = np.sqrt(1 - z * z)
        phi = np.pi * (1 + 5**0.5) * i
        return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    return _unit(check_rng(rng).standard_normal((n, 3)))


def ellipsoid(n: int = 500, axes=(2.0, 1.5, 1.0), center=(0.0, 0.0, 0.0), *, rng=None) -> Shape:
    """Axis-aligned ellipsoid Σ (x_j/axes_j)² = 1 (Fibonacci lattice unless ``rng`` is given)."""
    ax = np.asarray(axes, dtype=float)
    d = _sphere_directions(n, rng)
    pts = d * ax
    nrm = _unit(d / ax)
    c = np.asarray(center, dtype=float)
    terms: dict[tuple[int, ...], float] = {(0, 0, 0): float(np.sum(c**2 / ax**2)) - 1}
    for j in range(3):
        e2 = [0, 0, 0]
        e2[j] = 2
        e1 = [0, 0, 0]
        e1[j] = 1
        terms[tuple(e2)] = 1 / ax[j] ** 2
        terms[tuple(e1)] = -2 * c[j] / ax[j] ** 2
    pts, nrm = _place(pts, nrm, c)
    return Shape(pts, nrm, from_terms(3, 2, terms))


def sphere(n: int = 500, radius: float = 1.0, center=(0.0, 0.0, 0.0), *, rng=None) -> Shape:
    """Sphere of ``radius`` around ``center``."""
    return ellipsoid(n, (radius, radius, radius), center, rng=rng)


def torus(n: int = 1000, major: float = 1.0, minor: float = 0.4, *, rng=None) -> Shape:
    """Torus around the z axis: (x²+y²+z²+R²−r²)² − 4R²(x²+y²) = 0 (degree 4).

    Scaled by 1/(4R²) so that ||∇f|| is of order one on the surface.
    """
    R, r = float(major), float(minor)
    if rng is None:
        k = int(np.ceil(np.sqrt(n * R / r)))
        m = int(np.ceil(n / k))
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, k, endpoint=False),
                           np.linspace(0, 2 * np.pi, m, endpoint=False), indexing="ij")
        u, v = u.ravel()[:n], v.ravel()[:n]
    else:
        gen = check_rng(rng)
        u, v = gen.uniform(0, 2 * np.pi, n), gen.uniform(0, 2 * np.pi, n)
    ring = np.column_stack([np.cos(u), np.sin(u), np.zeros_like(u)])
    nrm = ring * np.cos(v)[:, None] + np.array([0.0, 0.0, 1.0]) * np.sin(v)[:, None]
    pts = R * ring + r * nrm
    s = R * R - r * r
    k4 = 1 / (4 * R * R)
    terms = {(4, 0, 0): 1, (0, 4, 0): 1, (0, 0, 4): 1, (2, 2, 0): 2, (2, 0, 2): 2, (0, 2, 2): 2,
             (2, 0, 0): 2 * s - 4 * R * R, (0, 2, 0): 2 * s - 4 * R * R, (0, 0, 2): 2 * s, (0, 0, 0): s * s}
    poly = from_terms(3, 4, {e: c * k4 for e, c in terms.items()})
    return Shape(pts, nrm, poly)

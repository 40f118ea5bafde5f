"""A generated collection of varied shapes, the same for the same seed (tests and benchmarks).

:func:`collection` cycles through five families — 2D star and blob contours, 3D
superquadrics, tori and ellipsoids — with sizes, proportions, poses and noise levels drawn
from one seeded generator per shape, so shape ``i`` of a collection is the same whatever N.
Normals are the exact outward normals of the noise-free shape; noise moves each point
along its normal by a Gaussian amount (``noise`` × the shape's mean radius).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._utils.numeric import unit_rows
from .._utils.validation import check_int
from . import synthetic

__all__ = ["GeneratedShape", "collection", "KINDS", "NOISE_LEVELS"]

KINDS = ("star", "blob", "superquadric", "torus", "ellipsoid")
#: Point noise along the normal, relative to the shape's mean radius.
NOISE_LEVELS = (0.0, 0.005, 0.02)


class GeneratedShape(NamedTuple):
    name: str
    kind: str
    noise: float
    points: NDArray[np.float64]
    normals: NDArray[np.float64]


def _radial_contour(n: int, radius, d_radius) -> tuple[NDArray, NDArray]:
    """A star-shaped contour r(t) and its outward normals (the rotated tangent)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r, dr = radius(t), d_radius(t)
    c, s = np.cos(t), np.sin(t)
    points = np.column_stack([r * c, r * s])
    tangent = np.column_stack([dr * c - r * s, dr * s + r * c])
    return points, unit_rows(np.column_stack([tangent[:, 1], -tangent[:, 0]]))


def _star(gen: np.random.Generator, n: int):
    arms, depth, phase = int(gen.integers(3, 7)), gen.uniform(0.1, 0.3), gen.uniform(0, 2 * np.pi)
    return _radial_contour(n, lambda t: 1 + depth * np.cos(arms * t + phase),
                           lambda t: -depth * arms * np.sin(arms * t + phase))


def _blob(gen: np.random.Generator, n: int):
    k = np.arange(2, 5)
    amp, phase = gen.uniform(0.0, 0.12, k.size) / k, gen.uniform(0, 2 * np.pi, k.size)
    return _radial_contour(n, lambda t: 1 + np.cos(np.outer(t, k) + phase) @ amp,
                           lambda t: -np.sin(np.outer(t, k) + phase) @ (amp * k))


def _superquadric(gen: np.random.Generator, n: int):
    # |x/a|^p + |y/b|^p + |z/c|^p = 1: the Fibonacci directions scaled onto the surface.
    axes, p = gen.uniform(0.6, 1.4, 3), gen.choice([2.5, 3.0, 4.0])
    d = synthetic.sphere(n).points
    scale = np.sum(np.abs(d / axes) ** p, axis=1) ** (-1 / p)
    points = d * scale[:, None]
    gradient = np.sign(points) * np.abs(points / axes) ** (p - 1) / axes
    return points, unit_rows(gradient)


def _torus(gen: np.random.Generator, n: int):
    shape = synthetic.torus(n, major=1.0, minor=gen.uniform(0.3, 0.5))
    return shape.points, shape.normals


def _ellipsoid(gen: np.random.Generator, n: int):
    shape = synthetic.ellipsoid(n, axes=tuple(gen.uniform(0.5, 1.5, 3)))
    return shape.points, shape.normals


_MAKERS = {"star": (_star, 2), "blob": (_blob, 2), "superquadric": (_superquadric, 3), "torus": (_torus, 3),
           "ellipsoid": (_ellipsoid, 3)}


def _rotation(gen: np.random.Generator, dim: int) -> NDArray:
    q, r = np.linalg.qr(gen.standard_normal((dim, dim)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q if dim == 3 else q[:, ::-1]


def collection(n: int, seed: int = 0, *, points_2d: int = 200, points_3d: int = 800) -> list[GeneratedShape]:
    """``n`` varied shapes, reproducible from ``seed`` (shape ``i`` does not depend on ``n``).

    Parameters
    ----------
    n : number of shapes; the families of :data:`KINDS` take turns.
    seed : the collection's seed; shape ``i`` uses ``SeedSequence([seed, i])``.
    points_2d, points_3d : points per contour / surface.

    Examples
    --------
    >>> shapes = collection(6, seed=1)
    >>> [s.kind for s in shapes]
    ['star', 'blob', 'superquadric', 'torus', 'ellipsoid', 'star']
    >>> shapes[2].name, shapes[2].points.shape
    ('superquadric-0002', (800, 3))
    >>> bool(np.array_equal(collection(3, seed=1)[2].points, shapes[2].points))
    True
    """
    n = check_int(n, "n", minimum=0)
    seed = check_int(seed, "seed", minimum=0)
    out = []
    for i in range(n):
        kind = KINDS[i % len(KINDS)]
        gen = np.random.default_rng(np.random.SeedSequence([seed, i]))
        make, dim = _MAKERS[kind]
        points, normals = make(gen, points_2d if dim == 2 else points_3d)
        noise = float(NOISE_LEVELS[int(gen.integers(len(NOISE_LEVELS)))])
        rotation, size, shift = _rotation(gen, dim), gen.uniform(0.5, 3.0), gen.uniform(-2, 2, dim)
        radius = float(np.linalg.norm(points - points.mean(axis=0), axis=1).mean())
        points = points + normals * (noise * radius * gen.standard_normal(len(points)))[:, None]
        out.append(GeneratedShape(f"{kind}-{i:04d}", kind, noise, size * points @ rotation.T + shift,
                                  normals @ rotation.T))
    return out

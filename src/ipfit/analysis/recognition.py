"""Shape retrieval with invariant descriptors: a generated benchmark and its precision.

:func:`demo_collection` draws 2D contours of a few classes (ellipses, stars with 3 and 5
arms, rounded squares) under random rotations, scales, translations and noise;
:func:`retrieval_precision` scores nearest-neighbour retrieval on descriptors of their fits.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.numeric import unit_rows
from .._utils.validation import check_int, check_nonnegative, check_rng, error

__all__ = ["CLASSES", "Contour", "demo_contour", "demo_collection", "retrieval_precision"]

CLASSES = ("ellipse", "star3", "star5", "square")


class Contour(NamedTuple):
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    label: str


def _radius(kind: str, theta: NDArray, rng: np.random.Generator) -> tuple[NDArray, NDArray]:
    """r(θ) and dr/dθ of a star-shaped class member (shape parameters drawn per shape)."""
    if kind == "ellipse":
        a, b = 1.0, rng.uniform(0.45, 0.6)
        r = a * b / np.sqrt((b * np.cos(theta)) ** 2 + (a * np.sin(theta)) ** 2)
        dr = -0.5 * a * b * ((a * a - b * b) * np.sin(2 * theta)) / np.sqrt(
            (b * np.cos(theta)) ** 2 + (a * np.sin(theta)) ** 2) ** 3
        return r, dr
    if kind in ("star3", "star5"):
        k, amp = int(kind[-1]), rng.uniform(0.22, 0.3)
        return 1 + amp * np.cos(k * theta), -amp * k * np.sin(k * theta)
    if kind == "square":  # superellipse |x|^p + |y|^p = 1, a square with rounded corners
        p = rng.uniform(3.5, 5.0)
        c, s = np.abs(np.cos(theta)), np.abs(np.sin(theta))
        base = c**p + s**p
        r = base ** (-1 / p)
        dbase = p * (-(c ** (p - 1)) * np.sign(np.cos(theta)) * np.sin(theta)
                     + s ** (p - 1) * np.sign(np.sin(theta)) * np.cos(theta))
        return r, -base ** (-1 / p - 1) / p * dbase
    raise error("kind", "one of " + ", ".join(CLASSES), repr(kind))


def demo_contour(kind: str, n: int = 200, noise: float = 0.01, rng=None) -> Contour:
    """One contour of class ``kind``, randomly rotated, scaled, moved and perturbed.

    ``noise`` is the standard deviation of Gaussian noise along the normals, relative to
    the shape's size.

    >>> c = demo_contour("star3", n=50, rng=0)
    >>> c.points.shape, c.label
    ((50, 2), 'star3')
    """
    gen = check_rng(rng)
    n = check_int(n, "n", minimum=8)
    noise = check_nonnegative(noise, "noise")
    theta = np.sort(gen.uniform(0, 2 * np.pi, n))
    r, dr = _radius(kind, theta, gen)
    radial = np.column_stack([np.cos(theta), np.sin(theta)])
    tangent = dr[:, None] * radial + r[:, None] * np.column_stack([-np.sin(theta), np.cos(theta)])
    normals = unit_rows(np.column_stack([tangent[:, 1], -tangent[:, 0]]))
    points = r[:, None] * radial + noise * gen.standard_normal(n)[:, None] * normals
    angle, size = gen.uniform(0, 2 * np.pi), gen.uniform(0.5, 3.0)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    shift = gen.uniform(-5, 5, 2)
    return Contour(size * points @ rot.T + shift, normals @ rot.T, kind)


def demo_collection(n_per_class: int = 10, n: int = 200, noise: float = 0.01, rng=None,
                    classes=CLASSES) -> list[Contour]:
    """``n_per_class`` random contours of each class, in class order."""
    gen = check_rng(rng)
    n_per_class = check_int(n_per_class, "n_per_class", minimum=1)
    return [demo_contour(kind, n, noise, gen) for kind in classes for _ in range(n_per_class)]


def retrieval_precision(descriptors: ArrayLike, labels, k: int | None = None) -> float:
    """Mean precision at k of nearest-neighbour retrieval on log-descriptors.

    Each item queries all others; precision at k is the fraction of its k nearest
    neighbours (Euclidean distance between ``log`` descriptors) with its own label;
    k defaults to the class size minus one.

    >>> retrieval_precision([[1.0], [1.1], [5.0], [5.2]], ["a", "a", "b", "b"])
    1.0
    """
    d = np.log(np.maximum(np.asarray(descriptors, dtype=np.float64), 1e-12))
    labels = np.asarray(labels)
    if d.ndim != 2 or len(d) != len(labels):
        raise error("labels", f"one label per descriptor row ({len(d)})", f"{len(labels)} labels")
    if k is None:
        k = int(min(np.unique(labels, return_counts=True)[1])) - 1
    k = check_int(k, "k", minimum=1, maximum=len(d) - 1)
    dist = np.linalg.norm(d[:, None, :] - d[None, :, :], axis=2)
    np.fill_diagonal(dist, np.inf)
    nearest = np.argsort(dist, axis=1)[:, :k]
    return float(np.mean(labels[nearest] == labels[:, None]))

"""The data of a reproduction run: bundled datasets as fitted and as scored, seeded streams, noisy copies.

A :class:`Data` is what one experiment fits (``points``, ``normals``: a subsample for 3D
clouds) together with the whole shape it is scored against (``ref_points``, ``ref_faces``).
Every random choice of a run comes from :func:`rng_for`, which derives a generator from the
run's seed and a label, so an experiment draws the same numbers whichever others ran before it.
:class:`Workspace` keeps the prepared datasets and every fitted polynomial of a run (the
figures need the polynomials; ``results.json`` keeps only their coefficients).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import unit_rows
from ..datasets import dataset_faces, load_dataset
from ..normals import DEFAULT_K, contour_normals, estimate_normals
from .config import Config

__all__ = ["Data", "Workspace", "rng_for", "prepare_data", "with_noise", "noise_neighbours", "noisy_normals",
           "NOISE_RADIUS"]

#: Normals of noisy data: neighbourhoods reach this many noise standard deviations.
NOISE_RADIUS = 4.0


@dataclass
class Data:
    """A dataset as fitted (``points``, ``normals``) and as scored (``ref_*``: the whole shape)."""

    name: str
    source: str
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    ref_points: NDArray[np.float64]
    ref_faces: NDArray[np.int64] | None
    ordered: bool
    n_total: int
    sampling: str

    @property
    def dim(self) -> int:
        return int(self.points.shape[1])

    @property
    def diagonal(self) -> float:
        """Length of the whole shape's bounding-box diagonal (the scale of relative errors and noise)."""
        return float(np.linalg.norm(np.ptp(self.ref_points, axis=0)))

    def describe(self) -> dict:
        return {"name": self.name, "source": self.source, "dim": self.dim, "n_points": len(self.points),
                "n_total": self.n_total, "sampling": self.sampling, "diagonal": self.diagonal,
                "reference": "faces" if self.ref_faces is not None else ("contour" if self.ordered else "points")}


def rng_for(seed: int, *labels: str) -> np.random.Generator:
    """A generator that depends on the run's seed and on what it is for (stable across runs).

    >>> rng_for(0, "noise", "boot").random() == rng_for(0, "noise", "boot").random()
    True
    >>> rng_for(0, "noise", "boot").random() == rng_for(0, "noise", "apple").random()
    False
    """
    return np.random.default_rng([int(seed), zlib.crc32("/".join(labels).encode())])


def prepare_data(name: str, cfg: Config, seed: int) -> Data:
    """Dataset ``name`` as the experiments fit it: 2D contours thinned in order, 3D clouds subsampled."""
    source = cfg.bunny_source if name == "bunny" else name
    points, normals = load_dataset(source)
    points = np.asarray(points, dtype=np.float64)
    normals = estimate_normals(points) if normals is None else np.asarray(normals, dtype=np.float64)
    n, dim = points.shape
    if dim == 2:
        step = 1 if cfg.points_2d is None else max(1, math.ceil(n / cfg.points_2d))
        idx = np.arange(0, n, step)
        sampling = "all points" if step == 1 else f"every {step}th point of the contour"
        return Data(name, source, points[idx], normals[idx], points, None, True, n, sampling)
    if cfg.points_3d < n:
        idx = np.sort(rng_for(seed, "subsample", name).choice(n, cfg.points_3d, replace=False))
        sampling = f"uniform random subset of {cfg.points_3d} points"
    else:
        idx = np.arange(n)
        sampling = "all points"
    faces = dataset_faces(source)
    faces = None if faces is None else np.asarray(faces, dtype=np.int64)
    return Data(name, source, points[idx], normals[idx], points, faces, False, n, sampling)


@dataclass
class Workspace:
    """What one run shares between its experiments: the prepared data and the fitted polynomials.

    ``polys`` is keyed by tuples that start with the experiment's name (e.g.
    ``("adaptive", "boot", "de", 4)``).
    """

    cfg: Config
    seed: int
    data: dict[str, Data] = field(default_factory=dict)
    polys: dict[tuple, Any] = field(default_factory=dict)

    def dataset(self, name: str) -> Data:
        """Dataset ``name``, prepared once per run."""
        if name not in self.data:
            self.data[name] = prepare_data(name, self.cfg, self.seed)
        return self.data[name]


def with_noise(clean: Data, sigma: float, seed: int) -> tuple[Data, int, float]:
    """``clean`` with Gaussian noise of std ``sigma`` × its diagonal and re-estimated normals.

    Returns the noisy data, the k of the normal estimation and the mean cosine between the
    re-estimated and the original normals.
    """
    scale = sigma * clean.diagonal
    noisy_points = clean.points + rng_for(seed, "noise", clean.name, repr(sigma)).normal(0.0, scale, clean.points.shape)
    k = noise_neighbours(noisy_points, scale)
    normals = noisy_normals(noisy_points, k, ordered=clean.ordered)
    agreement = float(np.mean(np.sum(normals * unit_rows(clean.normals), axis=1)))
    noisy = Data(clean.name, clean.source, noisy_points, normals, clean.ref_points, clean.ref_faces, clean.ordered,
                 clean.n_total, clean.sampling)
    return noisy, k, agreement


def noise_neighbours(points: NDArray, noise: float) -> int:
    """k for :func:`~ipfit.normals.estimate_normals` on data with Gaussian noise of std ``noise``.

    The library's default k (:data:`~ipfit.normals.DEFAULT_K`) spans a few point spacings; once the noise
    is larger than that, PCA fits the noise. k is raised to the median number of points
    within NOISE_RADIUS × ``noise`` of a point (at most a quarter of the points).

    >>> line = np.column_stack([np.linspace(0, 1, 101), np.zeros(101)])
    >>> noise_neighbours(line, 0.0), noise_neighbours(line, 0.05)
    (6, 25)
    """
    dim = points.shape[1]
    k = DEFAULT_K[dim]
    if noise > 0:
        counts = cKDTree(points).query_ball_point(points, NOISE_RADIUS * noise, return_length=True)
        k = max(k, int(np.median(counts)))
    return int(min(k, max(DEFAULT_K[dim], len(points) // 4)))


def noisy_normals(points: NDArray, k: int, *, ordered: bool) -> NDArray:
    """Normals re-estimated from noisy points: k-neighbour PCA (:func:`~ipfit.normals.estimate_normals`).

    The signs of an ordered 2D contour come from its order (the outward side of the contour
    traversed over ±k/2 points, :func:`~ipfit.normals.contour_normals`): the neighbour-graph
    orientation flips many normals of noisy contours. 3D clouds keep the library's orientation.
    """
    if not ordered:
        return estimate_normals(points, k=k)
    lines = estimate_normals(points, k=k, orient=False)
    outward = contour_normals(points, span=max(1, min(k // 2, (len(points) - 1) // 2)))
    return lines * np.where(np.sum(lines * outward, axis=1) < 0, -1.0, 1.0)[:, None]

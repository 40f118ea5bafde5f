"""Far-field information: what the zero set must *not* do away from the data.

The paper's objective only looks at the data points, so nothing stops a fit from growing
extra sheets or loops elsewhere in the box. Grid samples of the box away from the data
carry their signed distance to the data (sign from the nearest point's normal):

* the linear fits add them as weighted rows with target f ≈ signed distance
  (``far_weight`` of :func:`ipfit.fit_3l`, :func:`ipfit.fit_ridge`,
  :func:`ipfit.fit_gradient_one`);
* the metaheuristics and the polish add :class:`FarFieldTerm` to the objective: a penalty
  where f has the wrong sign, or where the zero set comes close to a sample (its Taubin
  distance is a small fraction of the sample's distance to the data).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from . import basis
from ._validation import check_nonnegative, check_positive

__all__ = ["far_field_samples", "FarFieldTerm", "DEFAULT_MARGIN", "DEFAULT_CLEARANCE", "DEFAULT_RATIO",
           "DEFAULT_TERM_WEIGHT"]

#: The sampled box is the data's box grown by this × its longest side: a little more than the
#: box in which zero sets are extracted and judged (0.25), so every part of that box is seen.
DEFAULT_MARGIN = 0.3
#: Samples nearer to the data than this × the 3L offset are dropped: there the data rows speak.
DEFAULT_CLEARANCE = 3.0
#: The zero set counts as "close" to a sample when its Taubin distance there is below this
#: fraction of the sample's true distance to the data. Far from a shape, a degree-g polynomial's
#: Taubin distance is about r/g while the true distance is about r, so the fraction must stay
#: below 1/g for a clean fit not to be penalised: 1/8 suits the degrees up to 8 used here, and
#: still sees small loops between grid nodes (1/16 missed one inside the boot at degree 8).
DEFAULT_RATIO = 1.0 / 8.0
#: Grid nodes along the longest side for the objective term: denser than the linear rows' grid
#: (40 / 16), since a loop smaller than a grid cell can hide between nodes (64 in 2D still caught
#: the loops inside the boot that 40 missed); 3D sheets are large, and the term costs M × d × P
#: per generation, so the 3D grid stays coarse.
TERM_GRID = {2: 64, 3: 14}
#: Recommended weight of the term in the objective (its values lie in [0, 2]; the paper's
#: distance of good fits is 0.005-0.2): 0.1 removed every spurious component of DE + polish
#: on the bundled contours at degrees 4-8, where 0.01 left some.
DEFAULT_TERM_WEIGHT = 0.1


def far_field_samples(u: NDArray[np.float64], normals: NDArray[np.float64], *, c: float = 0.05,
                      margin: float = DEFAULT_MARGIN, per_axis: int | None = None,
                      clearance: float = DEFAULT_CLEARANCE) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Grid samples of the data's box (plus ``margin``) away from the data, with signed distances.

    The grid is regular with the same step on every axis (``per_axis`` nodes along the
    longest side; 40 in 2D, 16 in 3D), so fits stay deterministic.

    Parameters
    ----------
    u : (N, dim) points (normalised coordinates in the fits).
    normals : (N, dim) unit normals at ``u``.
    c : the 3L offset; samples within ``clearance · c`` of the data are dropped.

    Returns
    -------
    samples : (M, dim) array in the coordinates of ``u``.
    targets : (M,) distances to the nearest data point, negative where that point's normal
        says the sample is inside.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(100)
    >>> samples, targets = far_field_samples(shape.points, shape.normals)
    >>> inside = np.linalg.norm(samples, axis=1) < 1
    >>> bool(np.all(targets[inside] < 0) and np.all(targets[~inside] > 0))
    True
    """
    dim = u.shape[1]
    lo, hi = u.min(axis=0), u.max(axis=0)
    pad = margin * float((hi - lo).max())
    lo, hi = lo - pad, hi + pad
    step = float((hi - lo).max()) / ((per_axis or (40 if dim == 2 else 16)) - 1)
    axes = [np.arange(a, b + 0.5 * step, step) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
    dist, nearest = cKDTree(u).query(grid, workers=-1)
    keep = dist > clearance * c
    grid, dist, nearest = grid[keep], dist[keep], nearest[keep]
    side = np.einsum("ij,ij->i", grid - u[nearest], normals[nearest])
    return grid, np.where(side < 0, -dist, dist)


class FarFieldTerm:
    r"""Objective term penalising zero-set pieces away from the data.

    For sample s_i with signed distance t_i and signed Taubin distance τ_i = f/||∇f||:

    .. math:: \text{term} = \frac{w}{M} \sum_i \min\left(2, \max\left(0, 1 - \frac{\operatorname{sign}(t_i)\,τ_i}{ρ |t_i|}\right)\right)

    It is 0 where f has the right sign and the zero set is not within ρ|t_i| of the sample,
    grows to 1 as the zero set reaches the sample, and up to 2 on the wrong side. It is
    invariant to positive scaling of the coefficients, like the paper's distance, and
    ``weight = 0`` leaves the paper's objective exactly.

    Parameters
    ----------
    samples, targets : from :func:`far_field_samples`, in the objective's coordinates.
    degree : polynomial degree of the coefficient vectors.
    weight : w.
    ratio : ρ (:data:`DEFAULT_RATIO`).
    """

    def __init__(self, samples: NDArray[np.float64], targets: NDArray[np.float64], degree: int, weight: float,
                 ratio: float = DEFAULT_RATIO) -> None:
        self.samples = np.asarray(samples, dtype=np.float64)
        self.targets = np.asarray(targets, dtype=np.float64)
        self.weight = check_nonnegative(weight, "far_weight")
        self.ratio = check_positive(ratio, "ratio")
        self.degree = degree
        dim = self.samples.shape[1]
        exps = basis.exponents(dim, degree)
        self.n_lower = basis.n_coefficients(dim, degree - 1)
        self.dim = dim
        self._m = basis.monomials(self.samples, exps)
        self._low = np.ascontiguousarray(self._m[:, : self.n_lower])
        maps = basis.derivative_maps(dim, degree)
        self._source = np.stack([dk.indices for dk in maps])
        self._factor = np.stack([dk.data for dk in maps])
        self._scale = 1.0 / (self.ratio * np.abs(self.targets))
        self._sign = np.sign(self.targets)

    @classmethod
    def from_data(cls, u: NDArray, normals: NDArray, degree: int, weight: float, *, ratio: float = DEFAULT_RATIO,
                  **kwargs) -> "FarFieldTerm":
        """Build the term from the data (samples from :func:`far_field_samples`, on a denser grid)."""
        kwargs.setdefault("per_axis", TERM_GRID[u.shape[1]])
        samples, targets = far_field_samples(u, normals, **kwargs)
        return cls(samples, targets, degree, weight, ratio=ratio)

    def _values_and_gradients(self, a: NDArray) -> tuple[NDArray, NDArray]:
        """f (M, P) and ∇f (M, dim·P; axis k of member p in column k·P + p) at the samples."""
        n_members = a.shape[0]
        at = np.ascontiguousarray(a.T)
        bt = np.empty((self.n_lower, self.dim * n_members))
        for k in range(self.dim):
            np.multiply(at[self._source[k]], self._factor[k][:, None], out=bt[:, k * n_members:(k + 1) * n_members])
        return self._m @ at, self._low @ bt

    def __call__(self, population: NDArray[np.float64]) -> NDArray[np.float64]:
        a = np.atleast_2d(np.asarray(population, dtype=np.float64))
        if self.weight == 0 or len(self.samples) == 0:
            return np.zeros(a.shape[0])
        n_members = a.shape[0]
        f, grads = self._values_and_gradients(a)
        grads *= grads
        sq = grads[:, :n_members]
        for k in range(1, self.dim):
            sq += grads[:, k * n_members:(k + 1) * n_members]
        np.maximum(sq, np.finfo(float).tiny, out=sq)
        np.sqrt(sq, out=sq)
        f /= sq
        f *= -(self._sign * self._scale)[:, None]
        f += 1.0
        np.clip(f, 0.0, 2.0, out=f)
        return self.weight * f.mean(axis=0)

    def value_and_grad(self, coefficients: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        a = np.asarray(coefficients, dtype=np.float64)
        if self.weight == 0 or len(self.samples) == 0:
            return 0.0, np.zeros_like(a)
        f, grads = self._values_and_gradients(a[None, :])
        f, g = f[:, 0], grads  # (M,), (M, dim)
        norm = np.sqrt(np.maximum(np.einsum("ij,ij->i", g, g), np.finfo(float).tiny))
        k = self._sign * self._scale
        shortfall = 1.0 - k * f / norm
        active = (shortfall > 0) & (shortfall < 2)
        value = self.weight * np.clip(shortfall, 0.0, 2.0).mean()
        # d(f/||g||) = dm/||g|| − f gᵀ dg / ||g||³, and the term is −w/M Σ_active k_i d(f/||g||)
        coef_f = np.where(active, -k / norm, 0.0)
        coef_g = np.where(active, k * f / norm**3, 0.0)[:, None] * g  # (M, dim)
        grad = self._m.T @ coef_f
        low_t = self._low.T @ coef_g  # (d_{g-1}, dim)
        for axis in range(g.shape[1]):
            grad[self._source[axis]] += self._factor[axis] * low_t[:, axis]
        return float(value), self.weight * grad / len(f)

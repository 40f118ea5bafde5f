"""Clouds with planted outliers, by issue 30's protocol, for the tests of outlier handling."""

from __future__ import annotations

import numpy as np


def with_outliers(points: np.ndarray, share: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``points`` plus ``share`` × N outliers uniform in their box grown by 20% on each side,
    shuffled; and the mask of the planted outliers."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    extra = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=(int(share * len(points)), points.shape[1]))
    cloud = np.vstack([points, extra])
    mask = np.r_[np.zeros(len(points), bool), np.ones(len(extra), bool)]
    order = rng.permutation(len(cloud))
    return cloud[order], mask[order]

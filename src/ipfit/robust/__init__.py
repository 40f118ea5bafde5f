"""Real scans: stray points and noise, judged from the points alone.

:func:`score_outliers` gives every point an outlier score and an inlier weight in [0, 1]
(soft, so that a fit can weight points rather than delete them), and estimates the noise scale
of the samples and their spacing. Normals that stray points must not spoil come from
:func:`ipfit.normals.estimate_normals` with ``inliers=`` the score's mask.

Modules:

* :mod:`.local` -- each point's offset from a quadric fitted to the samples around it;
* :mod:`.score` -- :func:`score_outliers`: the density seed, the rounds, the weights.
"""

from __future__ import annotations

from .score import DEFAULT_K, OutlierScore, score_outliers

__all__ = ["score_outliers", "OutlierScore", "DEFAULT_K"]

"""Comparing two sets of normals row by row: angles between their lines and flipped signs."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.numeric import unit_rows_mask
from .._utils.validation import error

__all__ = ["Agreement", "normal_agreement"]


class Agreement(NamedTuple):
    """How two sets of normals agree, row by row (rows with NaN in either are skipped).

    ``angles`` are between the normal lines in degrees (0-90, orientation ignored);
    ``flipped`` marks rows whose normals point to opposite sides (negative dot product).
    """

    angles: NDArray[np.float64]
    flipped: NDArray[np.bool_]
    median_angle: float
    flipped_fraction: float
    compared: int



def normal_agreement(estimated: ArrayLike, reference: ArrayLike) -> Agreement:
    """Compare two sets of normals row by row.

    Rows where either has NaN (e.g. mesh vertices without faces) are skipped.

    Returns
    -------
    Agreement
        Angles between the normal lines in degrees, which rows are flipped, the median
        angle, the fraction flipped and the number of rows compared.

    >>> a = normal_agreement([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, -1.0]])
    >>> a.median_angle, a.flipped_fraction
    (0.0, 0.5)
    """
    est = np.asarray(estimated, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.ndim != 2 or est.shape != ref.shape:
        raise error("reference", f"an array of the same shape as estimated {est.shape}", f"shape {ref.shape}",
                    "Pass one normal per row of the same points.")
    ok = np.isfinite(est).all(axis=1) & np.isfinite(ref).all(axis=1)
    e, r = est[ok], ref[ok]
    # Unit rows first (overflow-safe): a product of lengths of 1e200 would overflow. A zero row: cos 0, 90°.
    cos = np.einsum("ij,ij->i", unit_rows_mask(e)[0], unit_rows_mask(r)[0])
    angles = np.degrees(np.arccos(np.clip(np.abs(cos), 0.0, 1.0)))
    flipped = cos < 0
    m = int(ok.sum())
    if m == 0:
        return Agreement(angles, flipped, float("nan"), float("nan"), 0)
    return Agreement(angles, flipped, float(np.median(angles)), float(flipped.mean()), m)

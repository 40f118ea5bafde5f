"""The fields every ipfit result shares, in SciPy's vocabulary (one definition, one meaning)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Result"]


@dataclass(frozen=True, eq=False)
class Result:
    """Base of :class:`~ipfit.optimize.OptimizeResult`, :class:`~ipfit.RefineResult`,
    :class:`~ipfit.DegreeResult` and :class:`~ipfit.AdaptiveResult`.

    Attributes
    ----------
    x : the solution (coefficients, normalised coordinates, for the fits).
    fun : the value minimised at ``x``.
    nit : iterations (generations, or degrees tried).
    nfev : objective evaluations.
    success : whether the run reached what it set out to (each type says what that means).
    message : how it ended, in words.
    """

    x: NDArray[np.float64]
    fun: float
    nit: int
    nfev: int
    success: bool
    message: str

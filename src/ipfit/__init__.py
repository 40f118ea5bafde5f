"""ipfit: fit implicit polynomial curves and surfaces to 2D and 3D point clouds.

The method is Interian et al. (2017): linear fits (classic least squares, 3L, 3L + ridge),
the distance measure dissimilarity + δ(1 − smoothness), metaheuristic refinement and
adaptive degree selection.
"""

from __future__ import annotations

from . import basis
from .exceptions import ConditioningWarning, InvalidInputError, IpfitError, IpfitWarning, ReadError
from .linear import LINEAR_METHODS, fit_3l, fit_gradient_one, fit_linear, fit_lstsq, fit_ridge, fit_taubin
from .polynomial import ImplicitPolynomial, Normalization

__version__ = "0.1.0"

__all__ = [
    "ImplicitPolynomial",
    "Normalization",
    "fit_lstsq",
    "fit_taubin",
    "fit_3l",
    "fit_ridge",
    "fit_gradient_one",
    "fit_linear",
    "LINEAR_METHODS",
    "IpfitError",
    "InvalidInputError",
    "ReadError",
    "IpfitWarning",
    "ConditioningWarning",
    "basis",
]

"""ipfit: fit implicit polynomial curves and surfaces to 2D and 3D point clouds."""

from __future__ import annotations

from . import basis
from .exceptions import ConditioningWarning, InvalidInputError, IpfitError, IpfitWarning, ReadError
from .polynomial import ImplicitPolynomial, Normalization

__version__ = "0.1.0"

__all__ = [
    "ImplicitPolynomial",
    "Normalization",
    "IpfitError",
    "InvalidInputError",
    "ReadError",
    "IpfitWarning",
    "ConditioningWarning",
    "basis",
]

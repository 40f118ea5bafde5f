"""The zero set of a fitted polynomial: extraction by marching squares or cubes on a grid
(:mod:`~ipfit.zeroset.extract`), its quality against the data (:mod:`~ipfit.zeroset.quality`:
recall, precision, F-score, spurious components), trimming it to the data
(:mod:`~ipfit.zeroset.trim`) and writing it as a mesh or curves (:mod:`~ipfit.zeroset.export`).

The function :func:`ipfit.quality` is not re-exported here: ``ipfit.zeroset.quality`` is its module.
"""

from .export import save_zero_set
from .extract import ZeroSet, extract_zero_set, grid_values
from .quality import Quality
from .trim import Trim, trim_zero_set

__all__ = [
    "ZeroSet",
    "extract_zero_set",
    "grid_values",
    "Quality",
    "Trim",
    "trim_zero_set",
    "save_zero_set",
]

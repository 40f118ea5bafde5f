"""Fitting a polynomial of one degree: the linear fits and their one registry of methods
(:mod:`~ipfit.fitting.linear`), fits of clouds bigger than memory (:mod:`~ipfit.fitting.chunked`),
the paper's measures and objective (:mod:`~ipfit.fitting.objective`, compiled in
:mod:`~ipfit.fitting._objective_kernels`) with its far-field term (:mod:`~ipfit.fitting.farfield`),
every search setting (:mod:`~ipfit.fitting.options`: ``SearchOptions`` and the presets), the start
fits of a search (:mod:`~ipfit.fitting.starts`) and the search itself, start fits → DE/PSO →
polish (:mod:`~ipfit.fitting.refine`; the solvers are :mod:`ipfit.optimize`).

The function :func:`ipfit.refine` is not re-exported here: ``ipfit.fitting.refine`` is its module.
"""

from .chunked import fit_chunked
from .farfield import FarFieldTerm, far_field_samples
from .linear import LINEAR_METHODS, fit_3l, fit_gradient_one, fit_linear, fit_lstsq, fit_ridge, fit_taubin
from .objective import Measures, Objective, measures
from .options import PAPER, PAPER_METHOD, PAPER_RULE, RECOMMENDED, SearchOptions
from .refine import REFINE_METHODS, RefineResult

__all__ = [
    "fit_lstsq",
    "fit_taubin",
    "fit_3l",
    "fit_ridge",
    "fit_gradient_one",
    "fit_linear",
    "LINEAR_METHODS",
    "fit_chunked",
    "measures",
    "Measures",
    "Objective",
    "FarFieldTerm",
    "far_field_samples",
    "SearchOptions",
    "RECOMMENDED",
    "PAPER",
    "PAPER_METHOD",
    "PAPER_RULE",
    "RefineResult",
    "REFINE_METHODS",
]

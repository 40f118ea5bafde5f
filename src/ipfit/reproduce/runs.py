"""Every fit a reproduction run makes: the only module that calls the library's fitting functions.

The experiments ask for fits here and never call :func:`~ipfit.fitting.refine.refine`,
:func:`~ipfit.degree.adaptive.fit_adaptive` or :func:`~ipfit.fitting.linear.fit_linear` themselves, so a change
to those functions' signatures is adapted in this one file. :func:`search_options` turns a
:class:`~ipfit.reproduce.config.Config` into the search settings every refinement of the run
shares (the paper's objective: no far-field term).

>>> from ipfit.reproduce.config import CONFIGS
>>> opts = search_options(CONFIGS["full"])
>>> opts.iterations, opts.far_term_weight, opts.start_fits
(500, 0.0, ('lstsq', '3l'))
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from ..degree.adaptive import AdaptiveResult, fit_adaptive
from ..exceptions import ConditioningWarning
from ..fitting.linear import fit_linear
from ..fitting.options import RECOMMENDED, SearchOptions
from ..fitting.refine import RefineResult, refine
from ..polynomial import ImplicitPolynomial
from .config import PATH_EPSILON, Config
from .data import Data

__all__ = ["search_options", "refine_fit", "polish_fit", "adaptive_fit", "linear_fit", "ridge_fit"]


#: The reproduction's polish runs its full 1,000 L-BFGS iterations in 2D as in 3D (the
#: recommended pipeline's 2D default is shorter: ipfit.fitting.options.AUTO).
POLISH_ITERATIONS = 1000


def search_options(cfg: Config) -> SearchOptions:
    """The search settings shared by every DE/PSO run of ``cfg``: the paper's objective (no
    far-field term), every point and every iteration, the run's population and start fits."""
    changes: dict[str, Any] = {"iterations": cfg.iterations, "far_term_weight": 0.0,
                               "population_size": cfg.population, "search_points": None,
                               "stall_generations": None, "cleanup_weights": ()}
    if cfg.seeds is not None:
        changes["start_fits"] = tuple(cfg.seeds)
    return RECOMMENDED.replace(**changes)


def refine_fit(data: Data, degree: int, method: str, cfg: Config, *, delta: float,
               rng: np.random.Generator) -> RefineResult:
    """One DE or PSO refinement at a fixed degree with the run's search settings."""
    return refine(data.points, data.normals, degree, method=method, options=search_options(cfg), delta=delta, rng=rng)


def polish_fit(data: Data, degree: int, cfg: Config, start: ImplicitPolynomial | None = None) -> RefineResult:
    """The L-BFGS polish alone, from ``start`` or (None) from the best of the run's linear start fits."""
    opts = search_options(cfg).replace(polish_iterations=POLISH_ITERATIONS)
    if start is not None:
        return refine(data.points, data.normals, degree, method="polish", options=opts.replace(start_fits=()),
                      starts=[start], delta=cfg.delta, rng=0)
    return refine(data.points, data.normals, degree, method="polish", options=opts, delta=cfg.delta, rng=0)


class _Recorder:
    """A fixed-degree method for :func:`~ipfit.degree.adaptive.fit_adaptive` that keeps every RefineResult.

    It calls :func:`~ipfit.fitting.refine.refine` with the same generator for every degree, as
    ``fit_adaptive(method=...)`` does, so the run is the library's adaptive run; keeping the
    results gives the start fits' distances and the convergence histories.
    """

    def __init__(self, method: str, delta: float, rng: np.random.Generator, options: SearchOptions) -> None:
        self.method = method
        self.delta = delta
        self.rng = rng
        self.options = options
        self.records: dict[int, RefineResult] = {}
        self.__name__ = method

    def __call__(self, points, normals, degree):
        result = refine(points, normals, degree, method=self.method, options=self.options, delta=self.delta,
                        rng=self.rng)
        self.records[degree] = result
        return result.polynomial


def adaptive_fit(data: Data, method: str, cfg: Config, rng: np.random.Generator, *, epsilon: float = PATH_EPSILON,
                 max_degree: int | None = None) -> tuple[AdaptiveResult, dict[int, RefineResult]]:
    """One adaptive run (Algorithm 1, ``rule='paper'``) with DE or PSO at each degree.

    Returns the library's result and the refinement of every degree it fitted.
    """
    recorder = _Recorder(method, cfg.delta, rng, search_options(cfg))
    result = fit_adaptive(data.points, data.normals, method=recorder, epsilon=epsilon, delta=cfg.delta,
                          max_degree=max_degree or cfg.max_degree(data.dim), rule="paper")
    return result, recorder.records


def linear_fit(method: str, data: Data, degree: int) -> tuple[ImplicitPolynomial, float, list[str]]:
    """A linear fit ('lstsq', '3l', ...), its wall time and the conditioning warnings it raised."""
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConditioningWarning)
        poly = fit_linear(data.points, data.normals, degree, method)
    notes = [str(w.message) for w in caught if issubclass(w.category, ConditioningWarning)]
    return poly, time.perf_counter() - start, notes


def ridge_fit(data: Data, degree: int, kappa: float) -> tuple[ImplicitPolynomial, float]:
    """3L + ridge regression with weight ``kappa`` (κ = 0 is plain 3L) and its wall time."""
    start = time.perf_counter()
    poly = fit_linear(data.points, data.normals, degree, "ridge", kappa=kappa)
    return poly, time.perf_counter() - start

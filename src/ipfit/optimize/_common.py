"""Shared pieces of the population solvers: the result type and the generation loop."""

from __future__ import annotations

import abc
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.result import Result
from .._utils.validation import check_int, check_nonnegative, check_rng, error

__all__ = ["OptimizeResult", "PopulationSolver"]


@dataclass(frozen=True, eq=False)
class OptimizeResult(Result):
    """Outcome (or, passed to a callback, the current state) of a solver.

    Attributes
    ----------
    x : (d,) best point found.
    fun : its objective value.
    nit : iterations (generations) completed.
    nfev : objective evaluations, one per population member evaluated.
    success : False only when the run stopped on an error condition.
    message : why the run stopped.
    history : (nit + 1,) best value after each iteration, starting with the initial one.
    population, population_fun : the solver's memory of good points (DE: the population;
        PSO: the personal bests) and their values, best first in a final result. In a
        callback's snapshot these are the live arrays: read, do not keep or modify.
    """

    history: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    population: NDArray[np.float64] | None = None
    population_fun: NDArray[np.float64] | None = None

    def __repr__(self) -> str:
        return (f"OptimizeResult(fun={self.fun:.6g}, nit={self.nit}, nfev={self.nfev}, "
                f"success={self.success}, message={self.message!r})")


class PopulationSolver(abc.ABC):
    """Base of :class:`DifferentialEvolution` and :class:`ParticleSwarm`.

    Subclasses implement ``_step()`` (one generation, exactly one call of ``func``).
    Iterating over a solver runs one generation per item and yields the state snapshot;
    :meth:`solve` runs to ``maxiter`` generations (or until the callback stops it).
    """

    name = "population solver"

    # func(pop), or func(pop, bound) when a subclass screens (DifferentialEvolution(screen=True))
    def __init__(self, func: Callable[..., ArrayLike], init: ArrayLike, *, maxiter: int = 500,
                 rng=None, callback: Callable[[OptimizeResult], Any] | None = None,
                 project: Callable[[NDArray], NDArray] | None = None, min_population: int = 2,
                 stall_generations: int | None = None, stall_tolerance: float = 1e-4) -> None:
        try:
            pop = np.array(init, dtype=np.float64, copy=True)
        except (TypeError, ValueError):
            raise error("init", "a (P, d) array of numbers", type(init).__name__) from None
        if pop.ndim != 2 or pop.shape[0] < min_population or pop.shape[1] < 1:
            raise error("init", f"a (P, d) array with P >= {min_population}", f"shape {pop.shape}")
        if not np.isfinite(pop).all():
            raise error("init", "finite values", "NaN or inf")
        if callback is not None and not callable(callback):
            raise error("callback", "a callable or None", type(callback).__name__)
        self.func = func
        self.maxiter = check_int(maxiter, "maxiter", minimum=0)
        self.stall_generations = (None if stall_generations is None
                                  else check_int(stall_generations, "stall_generations", minimum=1))
        self.stall_tolerance = check_nonnegative(stall_tolerance, "stall_tolerance")
        self.rng = check_rng(rng)
        self.callback = callback
        self.project = project
        if project is not None:
            pop = project(pop)
        self.nfev = 0
        self.population = pop
        self.population_fun = self._evaluate(pop)
        self.nit = 0
        self._history = [float(self.population_fun.min())]
        self.message = ""
        self.stopped = False

    # -- helpers ---------------------------------------------------------------------------
    def _evaluate(self, pop: NDArray, bound: NDArray | None = None) -> NDArray[np.float64]:
        values = np.asarray(self.func(pop) if bound is None else self.func(pop, bound), dtype=np.float64)
        if values.shape != (pop.shape[0],):
            raise error("func", f"a ({pop.shape[0]},) array of values for a ({pop.shape[0]}, d) population",
                        f"shape {values.shape}")
        # A NaN would never be selected against; make it the worst value instead.
        values = np.where(np.isnan(values), np.inf, values)
        self.nfev += pop.shape[0]
        return values

    @property
    def best_index(self) -> int:
        return int(np.argmin(self.population_fun))

    @property
    def x(self) -> NDArray[np.float64]:
        return self.population[self.best_index].copy()

    @property
    def fun(self) -> float:
        return float(self.population_fun[self.best_index])

    @property
    def history(self) -> NDArray[np.float64]:
        return np.array(self._history)

    @abc.abstractmethod
    def _step(self) -> None:
        """Advance the population by one generation (DE and PSO define it)."""

    # -- public loop -----------------------------------------------------------------------
    def step(self) -> OptimizeResult:
        """Run one generation and return the state snapshot."""
        self._step()
        self.nit += 1
        self._history.append(self.fun)
        return self.snapshot()

    def snapshot(self) -> OptimizeResult:
        return OptimizeResult(x=self.x, fun=self.fun, nit=self.nit, nfev=self.nfev, success=True,
                              message=self.message, history=self.history, population=self.population,
                              population_fun=self.population_fun)

    def stalled(self) -> bool:
        """The best value improved by no more than ``stall_tolerance`` (relative) over the last
        ``stall_generations`` generations."""
        k = self.stall_generations
        if k is None or self.nit < k:
            return False
        before, now = self._history[-k - 1], self._history[-1]
        return before - now <= self.stall_tolerance * max(abs(before), np.finfo(float).tiny)

    def __iter__(self) -> Iterator[OptimizeResult]:
        while self.nit < self.maxiter and not self.stopped:
            yield self.step()
            if not self.stopped and self.stalled():
                self.stopped = True
                self.message = (f"stalled: the best value improved by no more than {self.stall_tolerance:g} "
                                f"(relative) over the last {self.stall_generations} generations")

    def solve(self) -> OptimizeResult:
        """Run up to ``maxiter`` generations; the callback sees every one.

        The callback receives the state snapshot; returning True or raising StopIteration
        stops the run (``message`` says so, ``success`` stays True).
        """
        self.message = f"maximum number of iterations ({self.maxiter}) reached"
        for state in self:
            if self.callback is not None:
                try:
                    stop = self.callback(state)
                except StopIteration:
                    stop = True
                if stop is True:
                    self.stopped = True
                    self.message = "stopped by the callback"
        return self.result()

    def result(self) -> OptimizeResult:
        """The final result, with the population sorted best first."""
        order = np.argsort(self.population_fun, kind="stable")
        return OptimizeResult(x=self.x, fun=self.fun, nit=self.nit, nfev=self.nfev, success=True,
                              message=self.message or "not run", history=self.history,
                              population=self.population[order].copy(),
                              population_fun=self.population_fun[order].copy())

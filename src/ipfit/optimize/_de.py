"""Differential evolution, DE/rand/1/bin (Storn & Price 1997), vectorised over the population."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import check_positive, check_probability, error
from ._common import OptimizeResult, PopulationSolver

__all__ = ["DifferentialEvolution", "distinct_indices", "trial_population", "select"]


def distinct_indices(rng: np.random.Generator, size: int, count: int = 3) -> NDArray[np.int64]:
    """For each member i of a population of ``size``, ``count`` indices distinct from each
    other and from i, uniformly among such choices; shape (count, size).

    Drawn without a per-member loop: the k-th index is drawn among ``size - 1 - k`` values and
    mapped past the already excluded indices in increasing order, a bijection onto the
    allowed set.
    """
    if size < count + 1:
        raise error("population", f"at least {count + 1} members for DE/rand/1", f"{size}")
    excluded = np.arange(size)[:, None]  # (size, k) sorted exclusions per member
    out = np.empty((count, size), dtype=np.int64)
    for k in range(count):
        pick = rng.integers(size - 1 - k, size=size)
        for j in range(k + 1):  # exclusions sorted ascending, so each shift is final
            pick += pick >= excluded[:, j]
        out[k] = pick
        excluded = np.sort(np.column_stack([excluded, pick]), axis=1)
    return out


def trial_population(population: NDArray, rng: np.random.Generator, mutation: float,
                     recombination: float) -> NDArray[np.float64]:
    """DE/rand/1/bin trial vectors: each member's components replaced, with probability CR =
    ``recombination`` and at one random position always, by those of the mutant
    x_r1 + F (x_r2 − x_r3), F = ``mutation`` (r1, r2, r3 distinct and other than the member).

    >>> pop = np.eye(4)
    >>> trial = trial_population(pop, np.random.default_rng(0), 0.5, 1.0)  # CR = 1: the mutants
    >>> sorted(np.round(trial.sum(axis=1), 12).tolist())  # x_r1 + 0.5 (x_r2 - x_r3) sums to 1
    [1.0, 1.0, 1.0, 1.0]
    """
    from ._kernels import rand1_bin

    size, dim = population.shape
    r1, r2, r3 = distinct_indices(rng, size)
    draws = rng.random((size, dim))
    forced = rng.integers(dim, size=size)
    out = np.empty((size, dim))
    rand1_bin(np.ascontiguousarray(population, dtype=np.float64), r1, r2, r3, float(mutation), draws,
              float(recombination), forced, out)
    return out


def select(population: NDArray, values: NDArray, trial: NDArray, trial_values: NDArray) -> NDArray[np.bool_]:
    """Greedy one-to-one selection in place: a trial replaces its parent when not worse.

    Returns the mask of replaced members. Accepting ties lets the population cross plateaus.
    """
    better = trial_values <= values
    population[better] = trial[better]
    values[better] = trial_values[better]
    return better


class DifferentialEvolution(PopulationSolver):
    """DE/rand/1/bin with one vectorised objective call per generation.

    Parameters
    ----------
    func : callable
        (P, d) array → (P,) values; called once per generation with all trial vectors.
    init : (P, d) array
        Initial population (P >= 4), e.g. started at good solutions.
    mutation : float, default 0.7
        Differential weight F (the paper's value, Section 5.2).
    recombination : float, default 0.9
        Crossover probability CR.
    maxiter : int, default 500
        Generations.
    rng : None, int or numpy.random.Generator
        Source of every random draw; a fixed seed makes runs bit-reproducible.
    callback : callable, optional
        Called with an :class:`OptimizeResult` snapshot after every generation; returning True
        (or raising StopIteration) stops the run.
    project : callable, optional
        Applied to the initial population and to every trial vector before evaluation, e.g.
        :func:`unit_rows` to keep candidates on the unit sphere.
    stall_generations, stall_tolerance : int or None, float
        Stop early when the best value has improved by no more than ``stall_tolerance``
        (relative) over the last ``stall_generations`` generations (None: never).
    screen : bool, default False
        Call ``func(trial, bound)`` with each trial's parent value as its bound. Selection only
        needs to know whether a trial beats its parent, so ``func`` may return, for a trial
        worse than its bound, any value above the bound (a cheaper lower bound, as
        :class:`~ipfit.fitting.objective.Objective` does); values at or below the bound must be exact.
        The run is then the same as with exact values. The initial population is evaluated
        with ``func(init)``.

    Notes
    -----
    Per generation the draws are, in this order: the three index rows of
    :func:`distinct_indices`, a (P, d) uniform array for the crossover mask (``< CR``) and P
    integers ``j_rand`` (the component always taken from the mutant). The names follow
    :func:`scipy.optimize.differential_evolution`. Selection is greedy, so the best value never
    increases.

    Examples
    --------
    >>> import numpy as np
    >>> sphere = lambda x: np.sum((x - 0.5) ** 2, axis=1)
    >>> start = np.random.default_rng(0).uniform(-1, 1, (20, 3))
    >>> res = DifferentialEvolution(sphere, start, maxiter=200, rng=1).solve()
    >>> bool(res.fun < 1e-10)
    True
    """

    name = "de"

    def __init__(self, func: Callable[..., ArrayLike], init: ArrayLike, *, mutation: float = 0.7,
                 recombination: float = 0.9, maxiter: int = 500, rng=None,
                 callback: Callable[[OptimizeResult], Any] | None = None,
                 project: Callable[[NDArray], NDArray] | None = None, stall_generations: int | None = None,
                 stall_tolerance: float = 1e-4, screen: bool = False) -> None:
        self.screen = bool(screen)
        self.mutation = check_positive(mutation, "mutation")
        if self.mutation > 2:
            raise error("mutation", "a differential weight in (0, 2]", repr(mutation), "The paper uses 0.7.")
        self.recombination = check_probability(recombination, "recombination")
        super().__init__(func, init, maxiter=maxiter, rng=rng, callback=callback, project=project,
                         min_population=4, stall_generations=stall_generations, stall_tolerance=stall_tolerance)

    def trial_vectors(self) -> NDArray[np.float64]:
        """Draw the next generation's trial vectors (mutation + crossover + projection)."""
        trial = trial_population(self.population, self.rng, self.mutation, self.recombination)
        return self.project(trial) if self.project is not None else trial

    def _step(self) -> None:
        trial = self.trial_vectors()
        bound = self.population_fun if self.screen else None
        select(self.population, self.population_fun, trial, self._evaluate(trial, bound))

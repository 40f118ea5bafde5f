"""Particle swarm optimisation with Clerc-Kennedy constriction, vectorised over the swarm."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import check_positive, error
from ._common import OptimizeResult, PopulationSolver

__all__ = ["ParticleSwarm", "velocity_update"]


def velocity_update(velocity: NDArray, position: NDArray, personal_best: NDArray, global_best: NDArray,
                    r1: NDArray, r2: NDArray, chi: float, c1: float, c2: float) -> NDArray:
    """Constricted velocity χ [v + c1 r1 (p − x) + c2 r2 (g − x)] (Clerc & Kennedy 2002)."""
    return chi * (velocity + c1 * r1 * (personal_best - position) + c2 * r2 * (global_best - position))


class ParticleSwarm(PopulationSolver):
    """Global-best PSO with constriction factor χ, one vectorised objective call per generation.

    Parameters
    ----------
    func : callable
        (P, d) array → (P,) values.
    init : (P, d) array
        Initial positions; initial velocities are zero, so a seeded particle starts where it
        was put and first moves towards the swarm's best.
    chi : float, default 0.729
        Constriction factor χ (the paper's value, after Clerc & Kennedy).
    c1, c2 : float, default 2.05
        Cognitive and social acceleration coefficients (χ = 0.729 corresponds to
        c1 + c2 = 4.1).
    maxiter, rng, callback
        As for :class:`DifferentialEvolution`.
    project : callable, optional
        Applied to new positions (e.g. :func:`unit_rows`). The velocity is then replaced by
        the displacement actually made, so that the component the projection removed does
        not build up in the velocity.

    Notes
    -----
    Per generation the draws are two (P, d) uniform arrays, r1 then r2. ``population`` and
    ``population_fun`` hold the personal bests (never worse than before), so the swarm's best
    value never increases; ``positions`` holds the current positions.

    Examples
    --------
    A swarm of 30 finds the minimum of an elongated bowl at (1, −2):

    >>> import numpy as np
    >>> bowl = lambda x: (x[:, 0] - 1) ** 2 + 10 * (x[:, 1] + 2) ** 2
    >>> swarm = ParticleSwarm(bowl, np.random.default_rng(0).normal(size=(30, 2)), maxiter=300, rng=1)
    >>> np.round(swarm.solve().x, 4).tolist()
    [1.0, -2.0]
    """

    name = "pso"

    def __init__(self, func: Callable[[NDArray], ArrayLike], init: ArrayLike, *, chi: float = 0.729,
                 c1: float = 2.05, c2: float = 2.05, maxiter: int = 500, rng=None,
                 callback: Callable[[OptimizeResult], Any] | None = None,
                 project: Callable[[NDArray], NDArray] | None = None, stall_generations: int | None = None,
                 stall_tolerance: float = 1e-4) -> None:
        self.chi = check_positive(chi, "chi")
        if self.chi >= 1:
            raise error("chi", "a constriction factor in (0, 1)", str(chi), "The paper uses chi = 0.729.")
        self.c1 = check_positive(c1, "c1")
        self.c2 = check_positive(c2, "c2")
        super().__init__(func, init, maxiter=maxiter, rng=rng, callback=callback, project=project,
                         min_population=2, stall_generations=stall_generations, stall_tolerance=stall_tolerance)
        self.positions = self.population.copy()
        self.positions_fun = self.population_fun.copy()
        self.velocities = np.zeros_like(self.positions)

    def _step(self) -> None:
        x = self.positions
        r1 = self.rng.random(x.shape)
        r2 = self.rng.random(x.shape)
        gbest = self.population[self.best_index]
        v = velocity_update(self.velocities, x, self.population, gbest, r1, r2, self.chi, self.c1, self.c2)
        moved = x + v
        if self.project is not None:
            moved = self.project(moved)
            v = moved - x
        self.positions, self.velocities = moved, v
        self.positions_fun = self._evaluate(moved)
        improved = self.positions_fun < self.population_fun
        self.population[improved] = moved[improved]
        self.population_fun[improved] = self.positions_fun[improved]

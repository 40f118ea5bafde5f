"""Solvers used by :func:`ipfit.refine`, written in SciPy's style.

* :class:`DifferentialEvolution` (DE/rand/1/bin) and :class:`ParticleSwarm` (constricted
  global-best PSO) evolve a population with one vectorised objective call per generation.
  Build one with a function and an initial population, then call :meth:`~PopulationSolver.solve`,
  call :meth:`~PopulationSolver.step` yourself, or iterate over the solver (one generation per
  item). All randomness comes from ``rng``.
* :func:`polish` runs L-BFGS from one point, with the analytic gradient and an optional
  triangular preconditioner.

Each returns an :class:`OptimizeResult` (``x``, ``fun``, ``nit``, ``nfev``, ``success``,
``message``, ``history``, ...).
"""

from .._utils.numeric import unit_rows
from ._common import OptimizeResult, PopulationSolver
from ._de import DifferentialEvolution
from ._polish import polish
from ._pso import ParticleSwarm

__all__ = ["OptimizeResult", "PopulationSolver", "DifferentialEvolution", "ParticleSwarm", "polish", "unit_rows"]

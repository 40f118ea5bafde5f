"""The compiled DE/rand/1/bin step, imported lazily (``import ipfit`` does not load numba).

At the population sizes of a 3D fit (P = 4d = 660 at degree 8) numpy's version of this step
made five full-size temporaries (three gathers, a difference, a product) and a ``where``, a
noticeable part of a generation outside the objective (the "DE loop overhead" of
``benchmarks/bench_objective.py``); this is one pass over the output. Every value is the one
numpy computed: the same operations in the same order, no fast-math.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True, boundscheck=False)
def rand1_bin(population, r1, r2, r3, mutation, draws, recombination, forced, out):  # pragma: no cover - compiled
    """``out[i] = x_i`` with components replaced by the mutant x_r1 + F (x_r2 − x_r3) where
    ``draws[i, j] < recombination`` or ``j == forced[i]`` (binomial crossover, at least one
    mutant component per member)."""
    size, dim = population.shape
    for i in range(size):
        a, b, c, keep = r1[i], r2[i], r3[i], forced[i]
        for j in range(dim):
            if draws[i, j] < recombination or j == keep:
                out[i, j] = population[a, j] + mutation * (population[b, j] - population[c, j])
            else:
                out[i, j] = population[i, j]

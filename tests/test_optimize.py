"""DE, PSO and the L-BFGS polish: operators checked by hand, then behaviour."""

from __future__ import annotations

import numpy as np
import pytest

from ipfit import InvalidInputError
from ipfit.optimize import DifferentialEvolution, OptimizeResult, ParticleSwarm, polish, unit_rows
from ipfit.optimize._de import distinct_indices, select
from ipfit.optimize._kernels import rand1_bin
from ipfit.optimize._pso import velocity_update


def sphere(x):
    return np.sum((x - 0.25) ** 2, axis=1)


# -- DE operators by hand -----------------------------------------------------------------------
def test_de_operators_by_hand():
    pop = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    r1, r2, r3 = np.array([1, 2, 3, 0]), np.array([2, 3, 0, 1]), np.array([3, 0, 1, 2])
    # mutants v_i = x_r1 + ½(x_r2 − x_r3):
    # v0 = x1 + ½(x2 − x3) = (1,0) + ½(−1,0) = (0.5, 0);   v1 = x2 + ½(x3 − x0) = (0.5, 1.5)
    # v2 = x3 + ½(x0 − x1) = (0.5, 1);                     v3 = x0 + ½(x1 − x2) = (0.5, −0.5)
    # crossover at CR = 0.5: draws below it take the mutant's component, and so does the forced
    # position (row 3 draws none, so it gets only its forced second component).
    draws = np.array([[0.1, 0.9], [0.9, 0.1], [0.1, 0.1], [0.9, 0.9]])
    forced = np.array([0, 1, 0, 1])
    trial = np.empty_like(pop)
    rand1_bin(pop, r1, r2, r3, 0.5, draws, 0.5, forced, trial)
    np.testing.assert_array_equal(trial, [[0.5, 0.0], [1.0, 1.5], [0.5, 1.0], [1.0, -0.5]])
    values = np.array([1.0, 2.0, 3.0, 4.0])
    replaced = select(pop, values, trial, np.array([0.5, 2.0, 5.0, 4.5]))
    np.testing.assert_array_equal(replaced, [True, True, False, False])  # ties are accepted
    np.testing.assert_array_equal(pop, [[0.5, 0.0], [1.0, 1.5], [0.0, 1.0], [1.0, 1.0]])
    np.testing.assert_array_equal(values, [0.5, 2.0, 3.0, 4.0])


def test_distinct_indices(rng):
    for size in (4, 5, 17):
        for _ in range(50):
            r = distinct_indices(rng, size)
            assert r.shape == (3, size)
            assert r.min() >= 0 and r.max() < size
            members = np.vstack([np.arange(size), r])
            assert all(len(set(col)) == 4 for col in members.T)
    # Uniform over the allowed choices: each other member equally likely as r1 of member 0.
    counts = np.bincount(np.concatenate([distinct_indices(rng, 5)[0] for _ in range(4000)]).reshape(-1, 5)[:, 0],
                         minlength=5)
    assert counts[0] == 0
    assert np.all(np.abs(counts[1:] / 4000 - 0.25) < 0.04)
    with pytest.raises(InvalidInputError, match="at least 4"):
        distinct_indices(rng, 3)


def test_one_de_step_replayed_by_hand(seed):
    pop = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.5, -0.5, 0.0]])
    de = DifferentialEvolution(sphere, pop, mutation=0.6, recombination=0.5, rng=seed, maxiter=1)
    de.step()
    # Replay the documented draws with an identical generator and apply DE/rand/1/bin by hand.
    ref = np.random.default_rng(seed)
    r = distinct_indices(ref, 5)
    u = ref.random((5, 3))
    jrand = ref.integers(3, size=5)
    expected = pop.copy()
    expected_fun = sphere(pop)
    for i in range(5):
        trial = []
        for j in range(3):
            if u[i, j] < 0.5 or j == jrand[i]:
                trial.append(pop[r[0, i], j] + 0.6 * (pop[r[1, i], j] - pop[r[2, i], j]))
            else:
                trial.append(pop[i, j])
        value = sum((t - 0.25) ** 2 for t in trial)
        if value <= expected_fun[i]:
            expected[i], expected_fun[i] = trial, value
    np.testing.assert_allclose(de.population, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(de.population_fun, expected_fun, rtol=1e-15)
    assert de.nit == 1 and de.nfev == 10


# -- PSO operators by hand ------------------------------------------------------------------------
def test_pso_velocity_by_hand():
    v = velocity_update(np.array([[1.0, -1.0]]), np.array([[0.0, 0.0]]), np.array([[1.0, 2.0]]),
                        np.array([2.0, 0.0]), np.array([[0.5, 0.5]]), np.array([[0.25, 1.0]]), 0.5, 2.0, 2.0)
    # ½ · [(1, −1) + 2·½·(1, 2) + 2·(¼, 1)·(2, 0)] = ½ · (1 + 1 + 1, −1 + 2 + 0) = (1.5, 0.5)
    np.testing.assert_array_equal(v, [[1.5, 0.5]])


def test_two_pso_steps_replayed_by_hand(seed):
    pop = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5], [-1.0, 2.0]])
    chi, c1, c2 = 0.729, 2.05, 2.05
    pso = ParticleSwarm(sphere, pop, chi=chi, c1=c1, c2=c2, rng=seed, maxiter=2)
    ref = np.random.default_rng(seed)
    x = pop.tolist()
    v = [[0.0, 0.0] for _ in x]
    pbest = [list(p) for p in x]
    pfun = [float(f) for f in sphere(pop)]
    for _ in range(2):
        pso.step()
        r1, r2 = ref.random((4, 2)), ref.random((4, 2))
        g = pbest[int(np.argmin(pfun))]
        for i in range(4):
            for j in range(2):
                v[i][j] = chi * (v[i][j] + c1 * r1[i, j] * (pbest[i][j] - x[i][j]) + c2 * r2[i, j] * (g[j] - x[i][j]))
                x[i][j] += v[i][j]
            value = (x[i][0] - 0.25) ** 2 + (x[i][1] - 0.25) ** 2
            if value < pfun[i]:
                pbest[i], pfun[i] = list(x[i]), value
        np.testing.assert_allclose(pso.positions, x, atol=1e-14)
        np.testing.assert_allclose(pso.velocities, v, atol=1e-14)
        np.testing.assert_allclose(pso.population, pbest, atol=1e-14)
        np.testing.assert_allclose(pso.population_fun, pfun, rtol=1e-13)
    assert pso.nfev == 12


def test_pso_projection_keeps_velocity_consistent(rng):
    start = unit_rows(rng.normal(size=(8, 5)))
    pso = ParticleSwarm(sphere, start, rng=rng, project=unit_rows, maxiter=3)
    before = pso.positions.copy()
    pso.step()
    np.testing.assert_allclose(np.linalg.norm(pso.positions, axis=1), 1.0)
    np.testing.assert_allclose(pso.velocities, pso.positions - before, atol=1e-15)


# -- behaviour -----------------------------------------------------------------------------------
@pytest.mark.parametrize("solver", [DifferentialEvolution, ParticleSwarm])
def test_converges_and_never_gets_worse(rng, solver):
    start = rng.uniform(-2, 2, size=(30, 4))
    res = solver(sphere, start, maxiter=300, rng=rng).solve()
    assert isinstance(res, OptimizeResult)
    assert res.fun < 1e-8
    np.testing.assert_allclose(res.x, 0.25, atol=1e-3)
    assert res.nit == 300 and res.nfev == 30 * 301 and len(res.history) == 301
    assert np.all(np.diff(res.history) <= 0)
    assert res.population_fun[0] == res.fun and np.all(np.diff(res.population_fun) >= 0)
    assert res.success and "maximum number" in res.message


@pytest.mark.parametrize("solver", [DifferentialEvolution, ParticleSwarm])
def test_reproducible_and_seed_dependent(solver):
    start = np.random.default_rng(5).normal(size=(12, 3))
    a = solver(sphere, start, maxiter=20, rng=3).solve()
    b = solver(sphere, start, maxiter=20, rng=np.random.default_rng(3)).solve()
    c = solver(sphere, start, maxiter=20, rng=4).solve()
    np.testing.assert_array_equal(a.population, b.population)
    np.testing.assert_array_equal(a.history, b.history)
    assert not np.array_equal(a.population, c.population)


@pytest.mark.parametrize("solver", [DifferentialEvolution, ParticleSwarm])
def test_callback_and_iteration(rng, solver):
    seen = []
    res = solver(sphere, rng.normal(size=(8, 2)), maxiter=7, rng=rng, callback=lambda s: seen.append(s.nit)).solve()
    assert seen == list(range(1, 8)) and res.nit == 7
    stopper = solver(sphere, rng.normal(size=(8, 2)), maxiter=50, rng=rng, callback=lambda s: s.nit >= 3).solve()
    assert stopper.nit == 3 and "callback" in stopper.message

    def raiser(state):
        raise StopIteration

    assert solver(sphere, rng.normal(size=(8, 2)), maxiter=50, rng=rng, callback=raiser).solve().nit == 1
    it = solver(sphere, rng.normal(size=(8, 2)), maxiter=4, rng=rng)
    assert [s.nit for s in it] == [1, 2, 3, 4]


def test_de_projection(rng):
    de = DifferentialEvolution(sphere, rng.normal(size=(10, 4)), rng=rng, project=unit_rows, maxiter=5)
    np.testing.assert_allclose(np.linalg.norm(de.population, axis=1), 1.0)
    res = de.solve()
    np.testing.assert_allclose(np.linalg.norm(res.population, axis=1), 1.0)


def test_nan_values_lose(rng):
    def nan_for_first_coordinate_positive(x):
        return np.where(x[:, 0] > 0, np.nan, sphere(x))

    res = DifferentialEvolution(nan_for_first_coordinate_positive, rng.normal(size=(10, 2)) - 3, maxiter=30,
                                rng=rng).solve()
    assert np.isfinite(res.fun) and res.x[0] <= 0


def test_solver_errors(rng):
    with pytest.raises(InvalidInputError, match="init"):
        DifferentialEvolution(sphere, np.zeros((3, 2)))
    with pytest.raises(InvalidInputError, match="mutation"):
        DifferentialEvolution(sphere, np.zeros((5, 2)), mutation=0.0)
    with pytest.raises(InvalidInputError, match="recombination"):
        DifferentialEvolution(sphere, np.zeros((5, 2)), recombination=1.5)
    with pytest.raises(InvalidInputError, match="chi"):
        ParticleSwarm(sphere, np.zeros((5, 2)), chi=1.2)
    with pytest.raises(InvalidInputError, match="func"):
        ParticleSwarm(lambda x: np.zeros(3), np.zeros((5, 2)))
    with pytest.raises(InvalidInputError, match="rng"):
        ParticleSwarm(sphere, np.zeros((5, 2)), rng="seed")


# -- polish --------------------------------------------------------------------------------------
def quadratic(x):
    scale = np.array([1.0, 100.0, 1e4])
    return float(np.sum(scale * (x - 1.0) ** 2)), 2 * scale * (x - 1.0)


def test_polish_minimises_and_reports():
    seen = []
    res = polish(quadratic, np.zeros(3), normalize=False, callback=lambda s: seen.append(s.fun))
    np.testing.assert_allclose(res.x, 1.0, atol=1e-6)
    assert res.history[0] == quadratic(np.zeros(3))[0] and len(res.history) == len(seen) + 1
    assert np.all(np.diff(res.history) <= 0) and res.nfev >= res.nit


def test_polish_with_preconditioner():
    r = np.diag(np.sqrt([1.0, 100.0, 1e4]))  # makes the quadratic isotropic
    res = polish(quadratic, np.zeros(3), normalize=False, precondition=r)
    np.testing.assert_allclose(res.x, 1.0, atol=1e-8)
    assert res.nit <= 3


def test_polish_never_worse_and_normalises():
    def bumpy(x):  # minimum at the start along the unit sphere: nothing to gain
        return 1.0, np.zeros_like(x)

    res = polish(bumpy, np.array([3.0, 4.0]))
    np.testing.assert_allclose(res.x, [0.6, 0.8])
    assert res.fun == 1.0 and "kept the start" in res.message
    assert polish(quadratic, np.zeros(3), maxiter=0, normalize=False).fun == quadratic(np.zeros(3))[0]
    with pytest.raises(InvalidInputError, match="precondition"):
        polish(quadratic, np.zeros(3), precondition=np.eye(2))


def test_de_screening_gives_the_same_run_as_exact_values(rng):
    # f = g + h with h >= 0: a screened objective may return g for a trial whose g already
    # exceeds its parent's value; selection, and so the whole seeded run, stays the same.
    def g(x):
        return np.sum((x - 0.3) ** 2, axis=1)

    def h(x):
        return 0.01 * np.abs(np.sin(5 * x)).sum(axis=1)

    calls = {"screened": 0}

    def screened(x, bound=None):  # the initial population is evaluated without bounds
        value = g(x)
        if bound is None:
            return value + h(x)
        contend = value <= bound
        calls["screened"] += int((~contend).sum())
        value[contend] += h(x[contend])
        return value

    start = rng.uniform(-1, 1, (24, 4))
    exact = DifferentialEvolution(lambda x: g(x) + h(x), start, maxiter=80, rng=5).solve()
    fast = DifferentialEvolution(screened, start, maxiter=80, rng=5, screen=True).solve()
    assert calls["screened"] > 80 * 24 // 10  # many trials never needed h
    assert fast.fun == exact.fun and fast.nit == exact.nit and fast.nfev == exact.nfev
    np.testing.assert_array_equal(fast.x, exact.x)
    np.testing.assert_array_equal(fast.history, exact.history)
    np.testing.assert_array_equal(fast.population_fun, exact.population_fun)

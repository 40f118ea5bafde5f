"""Metaheuristic refinement of linear fits at a fixed degree (paper, Section 4.1).

:func:`refine` minimises the paper's distance (Eq. 5) with differential evolution or particle
swarm optimisation, seeding the initial population with linear fits so that the metaheuristic
post-optimises them, and (in the recommended variants) polishes the best member with L-BFGS
on the analytic gradient.

Design notes:

* The distance ignores positive scaling of the coefficients, so candidates live on a unit
  sphere: every trial vector (DE) and new position (PSO) is projected back onto it.
* By default the population moves in whitened coordinates y = R a (R from the QR of the
  monomial matrix stacked with its derivatives, :meth:`~ipfit.objective.Objective.whitening`),
  in which every direction changes f and ∇f on the data alike. In raw coefficients the
  high-degree terms dominate and DE barely moves the seeds at degree ≥ 6 (the paper's
  observation); ``search_space="coefficients"`` restores that behaviour.
* The polish (L-BFGS, same whitening as preconditioner) starts from the metaheuristic's best
  member and from the best seed, and keeps the better result. On the bundled data it brings
  most of the improvement (see ``docs/refine-table.md``).
* The seeds, measured one at a time in float64, are candidates of the final choice, so the
  result is never worse than the best seed.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from . import basis
from ._validation import (as_normals, as_points, check_choice, check_degree, check_int, check_nonnegative,
                          check_probability, check_rng, error)
from .exceptions import IpfitError
from .farfield import FarFieldTerm
from .linear import DEFAULT_FAR_WEIGHT
from .objective import DEFAULT_DELTA, Measures, Objective, _check_dtype, single_threaded_blas
from .optimize import DifferentialEvolution, OptimizeResult, ParticleSwarm, polish as run_polish, unit_rows
from .polynomial import ImplicitPolynomial, Normalization

__all__ = ["refine", "RefineResult", "REFINE_METHODS", "DEFAULT_SEEDS"]

#: Accepted ``method`` names: a metaheuristic with or without the L-BFGS polish, or the
#: polish alone from the best seed. "de" and "pso" are the paper's pure variants.
REFINE_METHODS = ("de+polish", "pso+polish", "de", "pso", "polish")

#: The default seed pool: (label, linear method, parameters). Besides each linear method at
#: its default, a few parameter variants give the paper's N/10 seeded slots distinct members.
DEFAULT_SEEDS: tuple[tuple[str, str, dict], ...] = (
    ("3l", "3l", {}),
    ("ridge", "ridge", {}),
    ("gradient_one", "gradient_one", {}),
    ("taubin", "taubin", {}),
    ("lstsq", "lstsq", {}),
    ("3l(c=0.02)", "3l", {"c": 0.02}),
    ("3l(c=0.1)", "3l", {"c": 0.1}),
    ("ridge(kappa=1e-6)", "ridge", {"kappa": 1e-6}),
    ("ridge(kappa=1e-3)", "ridge", {"kappa": 1e-3}),
    ("gradient_one(mu=0.1)", "gradient_one", {"mu": 0.1}),
    ("gradient_one(mu=10)", "gradient_one", {"mu": 10.0}),
)

# Unseeded members start at seeds perturbed by a relative amount drawn log-uniformly in this
# range, measured in the whitened coordinates (see Objective.whitening), where 0.1 means
# "changes the values and gradients on the data by 10% of the seed's".
_SPREAD = (1e-3, 0.3)
# Two unit coefficient vectors closer than this count as the same solution.
_DISTINCT = 1e-3


@dataclass(frozen=True, eq=False)
class RefineResult:
    """Outcome of :func:`refine`.

    Attributes
    ----------
    polynomial : the best polynomial found (canonical: unit norm, f > 0 outside), with
        ``method`` set to the refine method and ``measures`` filled in.
    measures : its :class:`~ipfit.objective.Measures` (float64, normalised coordinates).
    history : best distance after each generation of the metaheuristic, starting with the
        initial population's (``nit + 1`` values; one value for ``method="polish"``).
    solutions : up to ``n_solutions`` best distinct polynomials found (the paper's "set of
        solutions"), best first; the first is ``polynomial``.
    nit : metaheuristic generations run.
    nfev : objective evaluations (one per coefficient vector: seeds, population members and
        polish evaluations).
    success : True when the run completed (or was stopped by the callback).
    message : how it ended.
    seconds : wall-clock time.
    seed_distances : distance of every seed, by label (float64).
    best_seed : label of the best seed.
    polish_history : the polish's value after each L-BFGS iteration (empty without polish).
    population_size : P.
    info : the parameters used and diagnostics.
    """

    polynomial: ImplicitPolynomial
    measures: Measures
    history: NDArray[np.float64]
    solutions: tuple[ImplicitPolynomial, ...]
    nit: int
    nfev: int
    success: bool
    message: str
    seconds: float
    seed_distances: Mapping[str, float]
    best_seed: str | None
    polish_history: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    population_size: int = 0
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def distance(self) -> float:
        return float(self.measures.distance)

    @property
    def x(self) -> NDArray[np.float64]:
        """The best coefficient vector (unit norm, normalised coordinates), as in SciPy's results."""
        return self.polynomial.coefficients

    @property
    def fun(self) -> float:
        """The objective's value at ``x``: the paper's distance plus any far-field term."""
        return float(self.info.get("objective", self.measures.distance))

    @property
    def best_seed_distance(self) -> float:
        return float(self.seed_distances[self.best_seed]) if self.best_seed is not None else float("inf")

    def __repr__(self) -> str:
        return (f"RefineResult(method={self.polynomial.method!r}, distance={self.distance:.6g}, "
                f"best_seed={self.best_seed!r} ({self.best_seed_distance:.6g}), nit={self.nit}, "
                f"nfev={self.nfev}, seconds={self.seconds:.2f})")


# -- seeds ----------------------------------------------------------------------------------------
def _linear_seeds(points, normals, degree, norm: Normalization, specs) -> tuple[list[str], list[NDArray], list[str]]:
    from .linear import fit_linear

    labels, coefs, notes = [], [], []
    for label, method, params in specs:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                poly = fit_linear(points, normals, degree, method, **params)
            except IpfitError as exc:
                notes.append(f"seed {label} failed: {exc}")
                continue
        notes.extend(f"seed {label}: {w.message}" for w in caught)
        if not np.allclose(poly.center, norm.center) or not np.isclose(poly.scale, norm.scale):
            # Linear fits normalise like Normalization.from_points; anything else is a bug.
            raise AssertionError(f"seed {label} uses another normalisation")
        labels.append(label)
        coefs.append(poly.coefficients)
    return labels, coefs, notes


def _user_seeds(seeds, points, normals, degree, norm: Normalization, d: int):
    from .linear import LINEAR_METHODS

    labels, coefs, specs = [], [], []
    for k, seed in enumerate(seeds):
        if isinstance(seed, str):
            method = check_choice(seed, f"seeds[{k}]", LINEAR_METHODS)
            specs.append((method, method, {}))
        elif isinstance(seed, ImplicitPolynomial):
            if seed.n_coefficients != d or seed.dim != points.shape[1]:
                raise error(f"seeds[{k}]", f"a degree-{degree} {points.shape[1]}D polynomial",
                            f"degree {seed.degree} in {seed.dim}D")
            if not (np.allclose(seed.center, norm.center, rtol=1e-12, atol=1e-12 * norm.scale)
                    and np.isclose(seed.scale, norm.scale, rtol=1e-12)):
                raise error(f"seeds[{k}]", "a polynomial fitted to the same points (same normalisation)",
                            "another normalisation", "Fit the seed with ipfit's linear fits on these points.")
            labels.append(seed.method or f"seed{k}")
            coefs.append(seed.coefficients)
        else:
            arr = np.asarray(seed, dtype=np.float64)
            if arr.shape != (d,) or not np.isfinite(arr).all() or not np.any(arr):
                raise error(f"seeds[{k}]", f"a method name, an ImplicitPolynomial or {d} finite coefficients "
                            "(not all zero) in the normalised coordinates", f"shape {arr.shape}")
            labels.append(f"seed{k}")
            coefs.append(arr)
    lin_labels, lin_coefs, notes = _linear_seeds(points, normals, degree, norm, specs) if specs else ([], [], [])
    labels = labels + lin_labels
    # Unique labels: seed_distances is keyed by them.
    unique = [label if labels.count(label) == 1 else f"{label}#{k}" for k, label in enumerate(labels)]
    return unique, coefs + lin_coefs, notes


def _initial_population(seed_y: NDArray, size: int, n_seeded: int, rng: np.random.Generator) -> NDArray:
    """Seeds first (the best ones exactly), the rest scattered around random seeds."""
    d = seed_y.shape[1]
    pop = np.empty((size, d))
    n_exact = min(n_seeded, seed_y.shape[0])
    pop[:n_exact] = seed_y[:n_exact]
    # Extra seeded slots (more slots than distinct seeds) repeat seeds with a tiny jitter, so
    # DE's difference vectors between them are not zero.
    n_jitter = n_seeded - n_exact
    base = np.concatenate([np.arange(n_jitter) % seed_y.shape[0],
                           rng.integers(seed_y.shape[0], size=size - n_seeded)]).astype(np.int64)
    lo, hi = np.log(_SPREAD[0]), np.log(_SPREAD[1])
    scale = np.concatenate([np.full(n_jitter, _SPREAD[0]), np.exp(rng.uniform(lo, hi, size - n_seeded))])
    noise = rng.standard_normal((size - n_exact, d)) / np.sqrt(d)
    pop[n_exact:] = seed_y[base] + scale[:, None] * noise
    return unit_rows(pop)


# -- the driver -------------------------------------------------------------------------------------
def refine(points: ArrayLike, normals: ArrayLike, degree: int, method: str = "de+polish", *,
           population: int | None = None, iterations: int = 500, seed_fraction: float = 0.1,
           seeds: Sequence[str | ImplicitPolynomial | ArrayLike] | None = None, chi: float = 0.729,
           c1: float = 2.05, c2: float = 2.05, F: float = 0.7, CR: float = 0.9, delta: float = DEFAULT_DELTA,
           polish: int = 1000, n_solutions: int = 5, rng=None,
           callback: Callable[[OptimizeResult], Any] | None = None, dtype=np.float64,
           search_space: str = "whitened", far_weight: float = 0.0) -> RefineResult:
    r"""Refine linear fits by minimising the paper's distance (Eq. 5) at a fixed degree.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array
    normals : (N, dim) array
        Normals at the points (any length but zero; normalised here).
    degree : int
        Polynomial degree.
    method : str, default "de+polish"
        ``"de+polish"`` (recommended) or ``"pso+polish"``: the metaheuristic, then an L-BFGS
        polish of its best member. ``"de"`` and ``"pso"``: the paper's pure variants.
        ``"polish"``: L-BFGS from the best seed only (fast; no population).
    population : int, optional
        Population (swarm) size P; default 4 × the number of coefficients (paper, Section 5.2).
    iterations : int, default 500
        Generations of the metaheuristic (paper: 500).
    seed_fraction : float, default 0.1
        Fraction of the population seeded with linear fits (paper: N/10; at least one seed).
        The other members are scattered around the seeds with relative perturbations
        log-uniform in [1e-3, 0.3] in the whitened coordinates.
    seeds : sequence, optional
        The seed pool. Default: :data:`DEFAULT_SEEDS` (least squares, Taubin, 3L, 3L + ridge,
        gradient-one and a few parameter variants). Items may be linear method names,
        :class:`~ipfit.ImplicitPolynomial` fitted to these points, or coefficient vectors in the
        normalised coordinates (``Normalization.from_points(points)``). An empty sequence
        means no seeds: the population starts at random directions.
    chi, c1, c2 : float
        PSO constriction factor χ = 0.729 and accelerations c1 = c2 = 2.05.
    F, CR : float
        DE differential weight 0.7 and crossover probability 0.9 (rand/1/bin).
    delta : float, default 0.25
        Penalty weight δ of the objective.
    polish : int, default 1000
        Maximum L-BFGS iterations of the polish (0 disables it).
    n_solutions : int, default 5
        How many best distinct solutions to return in ``solutions``.
    rng : None, int or numpy.random.Generator
        Source of all randomness: a fixed value makes the run bit-reproducible (on the same
        machine and BLAS).
    callback : callable, optional
        Called after every generation and every polish iteration with an
        :class:`~ipfit.optimize.OptimizeResult` whose ``x`` is the current best unit coefficient
        vector (normalised coordinates), ``fun`` its objective value, ``nit``, ``nfev``,
        ``history``, and ``message`` the stage ("de", "pso" or "polish"). Returning True
        stops that stage.
    far_weight : float, default 0
        Weight of the far-field term (:class:`~ipfit.farfield.FarFieldTerm`) added to the
        objective: it penalises zero-set pieces away from the data. 0 is the paper's
        objective exactly; with a positive weight, 3L with far-field rows joins the seeds.
        The reported ``measures`` stay the paper's (without the term).
    dtype : numpy.float64 or numpy.float32
        Precision of the population evaluations. float32 is about twice as fast; seeds,
        the polish and the returned measures always use float64.
    search_space : {"whitened", "coefficients"}
        Coordinates the population moves in. "whitened" (default): y = R a with R from
        :meth:`~ipfit.objective.Objective.whitening`, where all directions change f on the data
        alike. "coefficients": the raw coefficients, as in the paper. Candidates are kept on
        the unit sphere of that space either way: the objective ignores positive scaling.

    Returns
    -------
    RefineResult
        Its distance is never above the best seed's: the seeds are candidates too.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import ellipse
    >>> from ipfit.refine import refine
    >>> shape = ellipse(40)
    >>> res = refine(shape.points, shape.normals, 2, iterations=20, rng=0)
    >>> res.distance < 1e-8, res.polynomial.method
    (True, 'de+polish')
    """
    # One BLAS thread for the whole run: the population objective parallelises over blocks of
    # points itself, and everything else is many small products, for which BLAS worker
    # threads only cost synchronisation (badly so when other processes compete for the cores).
    with single_threaded_blas():
        return _refine(points, normals, degree, method, population, iterations, seed_fraction, seeds, chi, c1, c2,
                       F, CR, delta, polish, n_solutions, rng, callback, dtype, search_space, far_weight)


def _refine(points, normals, degree, method, population, iterations, seed_fraction, seeds, chi, c1, c2, F, CR,
            delta, polish, n_solutions, rng, callback, dtype, search_space, far_weight=0.0) -> RefineResult:
    started = time.perf_counter()
    pts = as_points(points)
    unit_normals = as_normals(normals, pts, required_by="refine")
    degree = check_degree(degree)
    method = check_choice(method, "method", REFINE_METHODS)
    dim = pts.shape[1]
    d = basis.n_coefficients(dim, degree)
    if pts.shape[0] < d:
        raise error("points", f"at least {d} points for a degree-{degree} {dim}D polynomial ({d} coefficients)",
                    f"{pts.shape[0]} points", "Pass more points or lower the degree.")
    metaheuristic = method.split("+")[0] if method != "polish" else None
    size = 4 * d if population is None else check_int(population, "population",
                                                       minimum=4 if metaheuristic == "de" else 2)
    iterations = check_int(iterations, "iterations", minimum=0)
    seed_fraction = check_probability(seed_fraction, "seed_fraction")
    delta = check_nonnegative(delta, "delta")
    polish_iterations = check_int(polish, "polish", minimum=0)
    n_solutions = check_int(n_solutions, "n_solutions", minimum=1)
    gen = check_rng(rng)
    dtype = _check_dtype(dtype)
    search_space = check_choice(search_space, "search_space", ("whitened", "coefficients"))
    if callback is not None and not callable(callback):
        raise error("callback", "a callable or None", type(callback).__name__)
    if metaheuristic == "de":  # validate before the (costly) seeds
        DifferentialEvolution(lambda x: np.zeros(len(x)), np.eye(4), F=F, CR=CR, maxiter=0)
    elif metaheuristic == "pso":
        ParticleSwarm(lambda x: np.zeros(len(x)), np.eye(2), chi=chi, c1=c1, c2=c2, maxiter=0)

    norm = Normalization.from_points(pts)
    u = norm.apply(pts)
    far_weight = check_nonnegative(far_weight, "far_weight")
    terms = [FarFieldTerm.from_data(u, unit_normals, degree, far_weight)] if far_weight > 0 else []
    obj64 = Objective(u, unit_normals, degree, delta, terms=terms)
    obj_pop = obj64 if dtype == np.float64 else Objective(u, unit_normals, degree, delta, dtype=dtype, terms=terms)

    # Seeds, best first.
    if seeds is None:
        pool = DEFAULT_SEEDS + ((("3l-far", "3l", {"far_weight": DEFAULT_FAR_WEIGHT}),) if far_weight > 0 else ())
        labels, coefs, notes = _linear_seeds(pts, unit_normals, degree, norm, pool)
    else:
        if isinstance(seeds, (str, ImplicitPolynomial)) or (isinstance(seeds, np.ndarray) and seeds.ndim == 1):
            raise error("seeds", "a sequence of seeds", type(seeds).__name__, "Wrap a single seed in a list.")
        labels, coefs, notes = _user_seeds(list(seeds), pts, unit_normals, degree, norm, d)
    nfev = 0
    if coefs:
        seed_a = unit_rows(np.array(coefs))
        # One vector at a time, exactly as the returned polynomial is measured below: the
        # comparison "never above the best seed" then holds to the last bit.
        seed_fun = np.array([obj64(a)[0] for a in seed_a])
        nfev += len(seed_a)
        order = np.argsort(seed_fun, kind="stable")
        seed_a, seed_fun, labels = seed_a[order], seed_fun[order], [labels[i] for i in order]
        seed_distances = dict(zip(labels, map(float, seed_fun)))
    else:
        seed_a, seed_fun, seed_distances = np.empty((0, d)), np.empty(0), {}
    if method == "polish" and not coefs:
        raise error("seeds", "at least one seed for method='polish'", "none", "Pass seeds or use 'de+polish'.")

    r = obj64.whitening()
    # Explicit inverse, applied with numpy: the hot loop then uses one BLAS library only (numpy
    # and SciPy bundle separate OpenBLAS copies whose spinning threads would compete). Its
    # rounding only reparametrises the search; seeds keep their exact coefficients below.
    r_inv = scipy.linalg.solve_triangular(r, np.eye(d), check_finite=False)
    if search_space == "whitened":
        def to_a(y):
            return y @ r_inv.T

        def to_space(a):
            return a @ r.T
    else:
        def to_a(y):
            return y

        def to_space(a):
            return a

    def stage_callback(stage, convert):
        if callback is None:
            return None

        def inner(state: OptimizeResult):
            a = unit_rows(convert(state.x))
            return callback(OptimizeResult(a, state.fun, state.nit, state.nfev, True, stage, state.history))
        return inner

    history = np.array([float(seed_fun[0])]) if coefs else np.empty(0)
    nit = 0
    messages = []
    candidates = [seed_a]
    if metaheuristic is not None:
        if coefs:
            n_seeded = max(1, int(round(seed_fraction * size)))
            start = _initial_population(unit_rows(to_space(seed_a)), size, min(n_seeded, size), gen)
        else:
            start = unit_rows(gen.standard_normal((size, d)))
        func = (lambda y: obj_pop(to_a(y))) if search_space == "whitened" else obj_pop
        common = dict(maxiter=iterations, rng=gen, callback=stage_callback(metaheuristic, to_a), project=unit_rows)
        if metaheuristic == "de":
            solver = DifferentialEvolution(func, start, F=F, CR=CR, **common)
        else:
            solver = ParticleSwarm(func, start, chi=chi, c1=c1, c2=c2, **common)
        meta = solver.solve()
        nit, nfev = meta.nit, nfev + meta.nfev
        history = meta.history
        messages.append(f"{metaheuristic}: {meta.message}")
        final = unit_rows(to_a(meta.population))
        candidates.append(final)

    pool = np.concatenate(candidates)
    if metaheuristic is not None:
        # Re-evaluated in float64 (the population may have been screened in float32), which
        # also puts the seeds and the final members on exactly the same footing.
        pool_fun = obj64(pool)
        nfev += len(final)
    else:
        pool_fun = seed_fun
    polish_history = np.empty(0)
    if "polish" in method and polish_iterations > 0:
        # Polish the best candidate and, when it is another one, the best seed: the local
        # optimum near the seed is sometimes the better one, and a polish costs little.
        starts = [int(np.argmin(pool_fun))]
        if coefs and starts[0] != 0:
            starts.append(0)
        polished = []
        for i in starts:
            pol = run_polish(obj64.value_and_grad, pool[i], maxiter=polish_iterations, precondition=r,
                             callback=stage_callback("polish", lambda x: x))
            nfev += pol.nfev
            polished.append(pol)
        pol = min(polished, key=lambda res: res.fun)
        polish_history = pol.history
        messages.append(f"polish: {pol.message}")
        pool = np.concatenate([np.array([res.x for res in polished]), pool])
        pool_fun = np.concatenate([[res.fun for res in polished], pool_fun])

    # The k best distinct candidates (float64), canonical sign.
    order = np.argsort(pool_fun, kind="stable")
    kept: list[int] = []
    for i in order:  # at most n_solutions hits, each checked against <= n_solutions kept ones
        if all(np.linalg.norm(pool[i] - pool[j]) > _DISTINCT for j in kept):
            kept.append(int(i))
            if len(kept) == n_solutions:
                break
    template = ImplicitPolynomial(basis.exponents(dim, degree), pool[kept[0]], norm, method=method)
    solutions = []
    for rank, i in enumerate(kept):
        poly = template.with_coefficients(pool[i]).canonical(pts, unit_normals)
        m = obj64.measures(poly.coefficients)[0]
        if m.distance > pool_fun[i] + 1e-12 * max(1.0, abs(pool_fun[i])):
            # canonical() chose the sign by the raw gradient agreement, which in rare cases
            # disagrees with the mean cosine; keep the orientation that was optimised.
            poly = template.with_coefficients(pool[i] / np.linalg.norm(pool[i]))
            m = obj64.measures(poly.coefficients)[0]
        if rank == 0 and coefs and m.distance > seed_fun[0]:
            # Only rounding (renormalisation, summation order) can put the winner above the
            # best seed: then it is the best seed, returned exactly as measured.
            poly = template.with_coefficients(seed_a[0])
            m = obj64.measures(seed_a[0])[0]
        solutions.append(poly.with_coefficients(poly.coefficients, measures=m.to_dict()))
    best_poly = solutions[0]
    best_measures = Measures(**{k: v for k, v in best_poly.measures.items()})
    used_seed = bool(coefs) and best_measures.distance >= seed_fun[0]
    if used_seed:
        messages.append("no candidate beat the best seed: returning it")
    info = {"population": size, "iterations": iterations, "seed_fraction": seed_fraction, "delta": delta,
            "dtype": dtype.name, "search_space": search_space, "notes": notes, "n_seeds": len(seed_distances),
            "far_weight": far_weight, "objective": float(obj64(best_poly.coefficients)[0])}
    if metaheuristic == "de":
        info.update(F=float(F), CR=float(CR))
    elif metaheuristic == "pso":
        info.update(chi=float(chi), c1=float(c1), c2=float(c2))
    best_poly = best_poly.with_coefficients(best_poly.coefficients, info=info)
    solutions[0] = best_poly
    return RefineResult(
        polynomial=best_poly, measures=best_measures, history=np.asarray(history, dtype=np.float64),
        solutions=tuple(solutions), nit=nit, nfev=int(nfev), success=True, message="; ".join(messages) or "done",
        seconds=time.perf_counter() - started, seed_distances=MappingProxyType(seed_distances),
        best_seed=labels[0] if coefs else None, polish_history=polish_history, population_size=size,
        info=MappingProxyType(info))

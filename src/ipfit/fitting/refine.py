"""Metaheuristic refinement of linear fits at a fixed degree (paper, Section 4.1).

:func:`refine` minimises the paper's distance (Eq. 5), plus the far-field term of the
recommended pipeline, with DE or PSO started from linear fits, and (in the "+polish" methods)
polishes the best member with L-BFGS on the analytic gradient. It runs in named steps:
:func:`_objectives` → :func:`~ipfit.fitting.starts.start_fits` → :func:`_search` → :func:`_polish` →
:func:`_best_distinct` → :class:`RefineResult`.

Design notes:

* The distance ignores positive scaling of the coefficients, so candidates live on a unit
  sphere: every trial vector (DE) and new position (PSO) is projected back onto it.
* By default the population moves in whitened coordinates y = R a (R from
  :meth:`~ipfit.fitting.objective.Objective.whitening`), in which every direction changes f and ∇f on
  the data alike. In raw coefficients the high-degree terms dominate and DE barely moves the
  start fits at degree ≥ 6 (the paper's observation); :data:`ipfit.PAPER` searches there.
* The polish (same whitening as preconditioner) starts from the search's best member and from
  the best start fit, and keeps the better result.
* The start fits are candidates of the final choice, so the result is never worse than the
  best of them.
* A cloud with ``weights`` (the inliers' weights when :func:`ipfit.fit_adaptive` found outliers)
  is fitted robustly: the start fits are reweighted by their own distances (IRLS, see
  :mod:`~ipfit.fitting.starts`), the objective of the search and of the polish weights each
  point and truncates its Taubin term at a few noise scales, at least 10 point spacings
  (:func:`robust_scale`, :data:`CAP_SCALES`), so that a stray point left in stops pulling the
  zero set, and the far-field term is judged robustly (:mod:`~ipfit.fitting.farfield`). Without
  weights nothing of this runs.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .. import basis
from .._utils.numeric import unit_rows
from .._utils.result import Result
from .._utils.validation import (
    as_points,
    check_degree,
    check_enough_points,
    check_nonnegative,
    check_rng,
    error,
)
from ..cloud import Cloud, as_cloud
from ..geometry.sampling import spread_subsample
from ..optimize import DifferentialEvolution, OptimizeResult, ParticleSwarm
from ..optimize import polish as lbfgs
from ..polynomial import ImplicitPolynomial, Normalization
from .farfield import VOTERS, FarFieldTerm, confident_cloud
from .objective import TAUBIN_CAP, Measures, Objective, single_threaded_blas
from .options import DEFAULT_DELTA, DEFAULT_METHOD, RECOMMENDED, REFINE_METHODS, MethodOptions, SearchOptions
from .starts import START_POINTS, StartFits, initial_population, start_fits

__all__ = ["refine", "RefineResult", "REFINE_METHODS", "robust_scale"]

# Full-cloud L-BFGS iterations after a subsampled polish (see _polish): FULL_POLISH_ITERATIONS up
# to FULL_POLISH_POINTS points, proportionally fewer beyond (at least FULL_POLISH_MIN). Measured:
# at 10⁶ points 100 full iterations took minutes per degree; half as many up to 50,000 points
# cost a hard dense cloud most of its fit (the Turk spider's 50,000 samples: F 0.96 -> 0.61).
FULL_POLISH_ITERATIONS = 100
FULL_POLISH_POINTS = 50_000
FULL_POLISH_MIN = 5
# Two unit coefficient vectors closer than this count as the same solution.
_DISTINCT = 1e-3
# Two distances of one polynomial computed along different paths (a sign or scale change, another
# BLAS kernel, another summation order) agree to about N·eps; a candidate must beat the best start
# fit by more than this share to count as better.
_SAME_DISTANCE = 1e-9
# Whitening diagonal entries below this share of the largest belong to directions that do not
# change f on the data at all (e.g. every monomial with y on points with y = 0): they are
# floored so that the map stays invertible; the search then moves freely along them.
_FLAT = 1e-12
# The robust loss's scale s (a weighted cloud, see robust_scale): the noise scale, but never below
# half the median spacing: clean synthetic data has a noise scale of 1e-6, and a shape sampled
# at some spacing is not known, between its samples, to better than about that.
SCALE_FLOOR_SPACINGS = 0.5
# The Taubin term's truncation: 3 scales hold 99.7 % of Gaussian offsets, and never below 10
# median spacings (about 2 % of the box diagonal on the contours of mpeg7-dev, the F-score's
# tolerance): a degree below the shape's misses its sharp parts by more than the noise, and a
# truncation there lets the fit drop them. Measured on apple, device1, face and heart of
# mpeg7-dev with 25 % strays: at 3 spacings the degree loop went on to degrees 12-14 for the
# same F-scores (2-6x the time), at 10 it took the path of the unweighted fit.
CAP_SCALES = 3.0
CAP_SPACINGS = 10.0


@dataclass(frozen=True, eq=False)
class RefineResult(Result):
    """Outcome of :func:`refine`, in SciPy's vocabulary.

    Attributes
    ----------
    x : the best coefficient vector (unit norm, normalised coordinates).
    fun : the objective's value at ``x`` (the paper's distance plus any far-field term).
    nit : metaheuristic generations run.
    nfev : objective evaluations (one per coefficient vector: start fits, population members
        and polish evaluations).
    success : True when a finite objective value was reached and no stage failed.
    message : how each stage ended.
    polynomial : the best polynomial (canonical: f > 0 outside), its measures filled in.
    measures : its :class:`~ipfit.fitting.objective.Measures` (the paper's, without any extra term).
    history : best objective value after each generation, starting with the initial
        population's (``nit + 1`` values; one value for ``method="polish"``).
    polish_history : the polish's value after each L-BFGS iteration (empty without polish).
    solutions : up to ``n_solutions`` best distinct polynomials, best first.
    start_distances : the objective at every start fit, by label.
    best_start : label of the best start fit (None without start fits).
    population_size : P.
    seconds : wall-clock time.
    options : the resolved settings, and diagnostics, as a read-only mapping.
    """

    polynomial: ImplicitPolynomial
    measures: Measures
    history: NDArray[np.float64]
    polish_history: NDArray[np.float64]
    solutions: tuple[ImplicitPolynomial, ...]
    start_distances: Mapping[str, float]
    best_start: str | None
    population_size: int
    seconds: float
    info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def distance(self) -> float:
        """The paper's distance at ``x`` (without the far-field term)."""
        return float(self.measures.distance)

    @property
    def best_start_value(self) -> float:
        return float(self.start_distances[self.best_start]) if self.best_start is not None else float("inf")

    def __repr__(self) -> str:
        return (f"RefineResult(method={self.polynomial.method!r}, fun={self.fun:.6g}, distance={self.distance:.6g}, "
                f"best_start={self.best_start!r}, nit={self.nit}, nfev={self.nfev}, success={self.success})")


def refine(points: ArrayLike | Cloud, normals: ArrayLike | None, degree: int, method: str = DEFAULT_METHOD, *,
           options: SearchOptions | None = None, delta: float = DEFAULT_DELTA,
           starts: Sequence[ImplicitPolynomial | ArrayLike] | None = None, keep_clear: ArrayLike | None = None,
           noise_scale: float | None = None, rng=None,
           callback: Callable[[OptimizeResult], Any] | None = None) -> RefineResult:
    r"""Refine linear fits by minimising the paper's distance (Eq. 5) at a fixed degree.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array, or a :class:`~ipfit.Cloud` with normals
        A cloud keeps what the next refinement on it reuses: the far-field term's samples, the
        search subsample, the start fits' big R factors. A cloud with ``weights`` is fitted
        robustly (module notes): reweighted start fits, weighted and truncated objective.
    normals : (N, dim) array
        Normals at the points (any length but zero; normalised here); None with a cloud.
    degree : int
        Polynomial degree.
    method : str, default "de+polish"
        ``"de+polish"`` (recommended) or ``"pso+polish"``: the metaheuristic, then an L-BFGS
        polish of its best member. ``"de"`` and ``"pso"``: the paper's pure variants.
        ``"polish"``: L-BFGS from the best start fit only (fast; no population).
    options : SearchOptions, default :data:`ipfit.RECOMMENDED`
        Population, iterations, DE/PSO parameters, start fits, search space, far-field term
        weight, precision. :data:`ipfit.PAPER` is the paper's search.
    delta : float, default 0.25
        Penalty weight δ of the paper's distance.
    starts : sequence, optional
        Extra starting polynomials: :class:`~ipfit.ImplicitPolynomial` fitted to these points,
        or coefficient vectors in the normalised coordinates (``Normalization.from_points``).
    keep_clear : (K, dim) array, optional
        Places (user coordinates) the zero set must stay away from, e.g. the samples of a
        spurious component: they join the far-field term's samples, each with the side of the
        data it lies on (from the nearest point's normal). Needs a positive far-field term weight.
    noise_scale : float, optional
        The points' noise scale (their units, e.g. :attr:`ipfit.robust.OutlierScore.noise_scale`),
        which sets the robust loss's scale on a cloud with weights (:func:`robust_scale`); None:
        from the points' spacing alone. Unused without weights.
    rng : None, int or numpy.random.Generator
        Source of all randomness: a fixed value makes the run bit-reproducible (on the same
        machine and BLAS).
    callback : callable, optional
        Called after every generation and every polish iteration with an
        :class:`~ipfit.optimize.OptimizeResult` whose ``x`` is the current best unit
        coefficient vector, ``fun`` the value of the objective being minimised, ``nit``,
        ``nfev``, and ``message`` the stage ("de", "pso" or "polish"). Returning True stops
        that stage. The polish from the best start fit, when it is not the best candidate,
        runs alongside the one from the best candidate (on a second thread when there are two
        cores) and reports nothing: the callback is always called from the caller's thread.

    Returns
    -------
    RefineResult
        Its objective value is never above the best start fit's.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import ellipse
    >>> from ipfit import refine, SearchOptions
    >>> shape = ellipse(40)
    >>> res = refine(shape.points, shape.normals, 2, options=SearchOptions(iterations=20), rng=0)
    >>> bool(res.distance < 1e-8), res.polynomial.method, res.success
    (True, 'de+polish', True)
    """
    cloud = as_cloud(points, normals, required_by="refine")
    pts = cloud.points
    degree = check_degree(degree)
    check_enough_points(len(pts), pts.shape[1], degree)
    options = RECOMMENDED if options is None else options
    if not isinstance(options, SearchOptions):
        raise error("options", "a SearchOptions (e.g. ipfit.RECOMMENDED or ipfit.PAPER)", type(options).__name__)
    settings = options.for_method(method, dim=pts.shape[1])  # the one resolution: read below as typed fields
    delta = check_nonnegative(delta, "delta")
    gen = check_rng(rng)
    if keep_clear is not None:
        keep_clear = as_points(keep_clear, "keep_clear", dims=(pts.shape[1],))
        if settings.far_term_weight <= 0:
            raise error("keep_clear", "a positive far_term_weight in the options", "far_term_weight=0",
                        "Set options=...replace(far_term_weight=...) or drop keep_clear.")
    if callback is not None and not callable(callback):
        raise error("callback", "a callable or None", type(callback).__name__)
    noise_scale = 0.0 if noise_scale is None else check_nonnegative(noise_scale, "noise_scale")
    # One BLAS thread for the whole run: the population objective parallelises over blocks of
    # points itself, and everything else is many small products, for which BLAS worker
    # threads only cost synchronisation (badly so when other processes compete for the cores).
    with single_threaded_blas():
        return _refine(cloud, degree, settings, delta, starts, keep_clear, noise_scale, gen, callback)


def _clear_targets(u: NDArray, unit_normals: NDArray, places: NDArray) -> NDArray:
    """Signed distance of each place to the data: the side given by the nearest point's normal."""
    dist, idx = cKDTree(u).query(places)
    side = np.einsum("ij,ij->i", places - u[idx], unit_normals[idx])
    return np.where(side < 0, -1.0, 1.0) * np.maximum(dist, 1e-12)


def _normalised(cloud: Cloud, n_search: int | None) -> tuple[Normalization, Cloud]:
    """The cloud in its normalised coordinates (all points, or the well-spread subsample of
    ``n_search``), kept by ``cloud`` for every refinement of the fit with the far-field term's
    samples it keeps in turn."""
    def compute() -> tuple[Normalization, Cloud]:
        if n_search is None:
            norm = Normalization.from_points(cloud.points)
            return norm, Cloud._checked(norm.apply(cloud.points), cloud.unit_normals, None, cloud.weights)
        norm, whole = _normalised(cloud, None)
        keep = spread_subsample(whole.points, n_search, rng=0)
        weights = None if whole.weights is None else whole.weights[keep]
        return norm, Cloud._checked(whole.points[keep], whole.oriented[keep], None, weights)

    return cloud.derived("normalised", n_search, compute)


def robust_scale(cloud: Cloud, noise_scale: float = 0.0) -> float:
    """The robust loss's scale s of ``cloud``, in its normalised coordinates: its noise scale
    (user units), floored at :data:`SCALE_FLOOR_SPACINGS` of the median spacing of its points.
    The start fits' reweighting (:mod:`~ipfit.fitting.starts`) and the Taubin term's truncation
    (:data:`CAP_SCALES`) are set in units of it."""
    def compute() -> float:
        spacing = float(np.median(cloud.spacing)) if len(cloud) > 1 else 0.0
        return max(noise_scale, SCALE_FLOOR_SPACINGS * spacing) / _normalised(cloud, None)[0].scale

    return cloud.derived("robust_scale", float(noise_scale), compute)


def _cap(cloud: Cloud, scale: float) -> float:
    """The Taubin term's truncation on a weighted cloud (normalised units)."""
    spacing = float(np.median(cloud.spacing)) / _normalised(cloud, None)[0].scale if len(cloud) > 1 else 0.0
    return max(CAP_SCALES * scale, CAP_SPACINGS * spacing)


def _objectives(cloud: Cloud, degree, delta, settings: MethodOptions, keep_clear=None, cap: float = TAUBIN_CAP):
    """The float64 objective on all points (start fits' ranking, final polish, measures), the
    search's (on a well-spread subsample of ``search_points`` points, maybe in float32) and, when
    subsampled, the float64 objective on that subsample (the first polish stage). A weighted
    cloud's objectives weight its points and truncate the Taubin term at ``cap``."""
    norm, whole = _normalised(cloud, None)
    weight = settings.far_term_weight

    extra = []
    if keep_clear is not None:
        places = norm.apply(keep_clear)
        data = confident_cloud(whole)
        extra = [FarFieldTerm(places, _clear_targets(data.points, data.oriented, places), degree, weight)]

    def build(part: Cloud, dtype=np.float64):
        robust = {} if part.weights is None else {"voters": VOTERS}  # see farfield's notes
        terms = [FarFieldTerm.from_data(confident_cloud(part), None, degree, weight, **robust)] if weight > 0 else []
        return Objective(part.points, part.oriented, degree, delta, dtype=dtype, terms=terms + extra,
                         weights=part.weights, cap=cap)

    obj64 = build(whole)
    dtype = np.dtype(settings.dtype)
    n_search = settings.search_points
    if n_search is not None and len(whole) > n_search:
        sub = _normalised(cloud, n_search)[1]
        sub64 = build(sub)
        obj_pop = sub64 if dtype == np.float64 else build(sub, dtype)
        return norm, obj64, obj_pop, sub64
    return norm, obj64, (obj64 if dtype == np.float64 else build(whole, dtype)), None


def _whitening(obj64: Objective) -> tuple[NDArray, NDArray]:
    r = obj64.whitening()
    diag = np.abs(np.diag(r))
    flat = diag <= _FLAT * diag.max()
    if flat.any():  # data on a line or a plane: some monomials vanish on every point
        r = r.copy()
        r[np.flatnonzero(flat), np.flatnonzero(flat)] = _FLAT * diag.max()
    # Explicit inverse, applied with numpy: the hot loop then uses one BLAS library only (numpy
    # and SciPy bundle separate OpenBLAS copies whose spinning threads would compete). Its
    # rounding only reparametrises the search; start fits keep their exact coefficients.
    return r, scipy.linalg.solve_triangular(r, np.eye(len(r)), check_finite=False)


def _staged(callback, stage: str, convert: Callable[[NDArray], NDArray]):
    if callback is None:
        return None

    def inner(state: OptimizeResult):
        return callback(OptimizeResult(x=unit_rows(convert(state.x)), fun=state.fun, nit=state.nit,
                                       nfev=state.nfev, success=True, message=stage, history=state.history))
    return inner


def _search(settings: MethodOptions, obj_pop, starts: StartFits, r, r_inv, size, gen, callback):
    """DE or PSO from the start fits; returns the final population (coefficients) and the result."""
    whitened = settings.search_space == "whitened"
    to_a = (lambda y: y @ r_inv.T) if whitened else (lambda y: y)
    d = r.shape[0]
    if len(starts):
        n_started = max(1, round(settings.start_fraction * size))
        start_y = unit_rows(starts.coefficients @ r.T if whitened else starts.coefficients)
        init = initial_population(start_y, size, min(n_started, size), gen)
    else:
        init = unit_rows(gen.standard_normal((size, d)))
    func = (lambda y, bound=None: obj_pop(to_a(y), bound)) if whitened else obj_pop
    stage = settings.method.split("+")[0]
    common = dict(maxiter=settings.iterations, rng=gen, callback=_staged(callback, stage, to_a), project=unit_rows,
                  stall_generations=settings.stall_generations, stall_tolerance=settings.stall_tolerance)
    solver: DifferentialEvolution | ParticleSwarm
    if stage == "de":
        solver = DifferentialEvolution(func, init, mutation=settings.mutation,
                                       recombination=settings.recombination, screen=True, **common)
    else:
        solver = ParticleSwarm(func, init, chi=settings.chi, c1=settings.c1, c2=settings.c2, **common)
    result = solver.solve()
    return unit_rows(to_a(result.population)), result


def _polish(obj64, sub64, pool, pool_fun, has_starts: bool, r, settings: MethodOptions, callback):
    """L-BFGS from the best candidate and, when it is another one, from the best start fit (index
    0 of the pool): the local optimum near it is sometimes the better one, and a polish is cheap.

    On a subsampled search the polish runs on the subsample first, then at most
    ``FULL_POLISH_ITERATIONS`` more iterations on all points from the better result: the
    subsample's optimum is close to the full one, and full-cloud iterations cost N/n times more.
    Returns (coefficient vectors, their float64 objective on all points, polish results)."""
    starts = [int(np.argmin(pool_fun))]
    if has_starts and starts[0] != 0:
        starts.append(0)
    first = obj64 if sub64 is None else sub64
    staged = _staged(callback, "polish", lambda x: x)
    polished = _polish_each(first, [pool[i] for i in starts], settings.polish_iterations, r, staged)
    xs = np.array([res.x for res in polished])
    if sub64 is None:
        return xs, np.array([res.fun for res in polished]), polished
    funs = obj64(xs)
    # alone on the machine: the pass over all points on every worker thread
    final = lbfgs(functools.partial(obj64.value_and_grad, split=True), xs[int(np.argmin(funs))],
                  maxiter=min(settings.polish_iterations, full_polish_budget(obj64.n_points)), precondition=r,
                  callback=staged)
    return np.vstack([xs, final.x]), np.append(funs, final.fun), [*polished, final]


def _polish_each(obj: Objective, x0s: list[NDArray], maxiter: int, r, callback) -> list[OptimizeResult]:
    """L-BFGS from each start, the first reporting to ``callback``; with two starts and two threads
    the second runs meanwhile on a worker thread, silent (a user's callback is only ever called
    from the caller's thread). The objective's pass is compiled and releases the GIL, and each
    run does exactly the arithmetic it does alone: the same results, in the time of the longer."""
    def run(x0, report=None):
        return lbfgs(obj.value_and_grad, x0, maxiter=maxiter, precondition=r, callback=report)

    if len(x0s) != 2 or obj.threads < 2:
        return [run(x0, callback if i == 0 else None) for i, x0 in enumerate(x0s)]
    obj.value_and_grad(x0s[0])  # the stacked rows the pass reuses, built once before the threads
    worker = ThreadPoolExecutor(1)
    try:
        other = worker.submit(run, x0s[1])
        return [run(x0s[0], callback), other.result()]
    finally:  # an interrupt does not wait for the other run: it ends on its own, its result unused
        worker.shutdown(wait=False, cancel_futures=True)


def full_polish_budget(n_points: int) -> int:
    """L-BFGS iterations on all of ``n_points`` points after a polish on a subsample. A full-cloud
    iteration costs N/n subsample ones (and rebuilds its design blocks beyond a few hundred
    thousand points): the budget shrinks with N, so a million points get a few steps."""
    return max(FULL_POLISH_MIN, int(FULL_POLISH_ITERATIONS * min(1.0, FULL_POLISH_POINTS / n_points)))


def _best_distinct(pool, pool_fun, n_solutions: int) -> list[int]:
    order = np.argsort(pool_fun, kind="stable")
    kept: list[int] = []
    for i in order:  # at most n_solutions hits, each checked against <= n_solutions kept ones
        if all(np.linalg.norm(pool[i] - pool[j]) > _DISTINCT for j in kept):
            kept.append(int(i))
            if len(kept) == n_solutions:
                break
    return kept


def _solutions(template, pool, pool_fun, kept, obj64, starts: StartFits):
    """Canonical-sign polynomials with their measures; the first is never above the best start."""
    out = []
    # canonical()'s sign (the gradients along the points' normals, as much as each point counts),
    # from one pass over the design matrix instead of the gradients at every point per solution
    agreement = obj64.normal_agreement()
    for rank, i in enumerate(kept):
        coef = pool[i] / np.linalg.norm(pool[i])
        poly = template.with_coefficients(-coef if float(agreement @ coef) < 0 else coef)
        m = obj64.measures(poly.coefficients)[0]
        if m.distance > pool_fun[i] + 1e-12 * max(1.0, abs(pool_fun[i])):
            # The raw gradient agreement in rare cases disagrees with the mean cosine: keep
            # the orientation that was optimised.
            poly = template.with_coefficients(coef)
            m = obj64.measures(poly.coefficients)[0]
        if rank == 0 and len(starts) and m.distance > starts.distances[0]:
            # Only rounding (renormalisation, summation order) can put the winner above the
            # best start fit: then it is that start fit, exactly as measured.
            poly = template.with_coefficients(starts.coefficients[0])
            m = obj64.measures(poly.coefficients)[0]
        out.append(poly.with_coefficients(poly.coefficients, measures=m.to_dict()))
    return out


def _refine(cloud: Cloud, degree, settings: MethodOptions, delta, given_starts, keep_clear, noise_scale, gen,
            callback) -> RefineResult:
    started = time.perf_counter()
    pts = cloud.points
    method, dim = settings.method, pts.shape[1]
    d = basis.n_coefficients(dim, degree)
    size = settings.population_size or 4 * d
    if method.startswith("de") and size < 4:
        raise error("population_size", "at least 4 members for DE/rand/1", str(size))
    # A weighted cloud is fitted robustly (module notes); without weights, exactly as ever.
    scale = None if cloud.weights is None else robust_scale(cloud, noise_scale)
    cap = TAUBIN_CAP if scale is None else _cap(cloud, scale)
    norm, obj64, obj_pop, sub64 = _objectives(cloud, degree, delta, settings, keep_clear, cap)
    n_search = len(pts) if sub64 is None else sub64.n_points
    # The linear start fits see what the search sees: a QR of the full cloud's 3N rows per start
    # fit would cost more than the whole search on big clouds (the bunny: 80 s of 12 QRs at degree 8).
    starts = start_fits(cloud, degree, norm, settings.start_fits, given_starts,
                        far_term=settings.far_term_weight > 0, max_points=min(n_search, START_POINTS),
                        scale=scale)
    if method == "polish" and not len(starts):
        raise error("starts", "at least one start fit or start polynomial for method='polish'", "none",
                    "Pass start fits in options, starts=[...], or use 'de+polish'.")
    nfev = starts.rank(obj64)
    r, r_inv = _whitening(obj64 if sub64 is None else sub64)

    history = starts.distances[:1].copy()
    nit, messages, success = 0, [], True
    pool, pool_fun = starts.coefficients, starts.distances
    if method != "polish":
        final, meta = _search(settings, obj_pop, starts, r, r_inv, size, gen, callback)
        nit, history = meta.nit, meta.history
        messages.append(f"{method.split('+')[0]}: {meta.message}")
        pool = np.concatenate([starts.coefficients, final])
        # Re-evaluated in float64 (the population may have been screened in float32), which
        # also puts the start fits and the final members on exactly the same footing.
        pool_fun = obj64(pool)
        nfev += meta.nfev + len(final)
    polish_history = np.empty(0)
    if method.endswith("polish") and settings.polish_iterations > 0:
        xs, funs, polished = _polish(obj64, sub64, pool, pool_fun, bool(len(starts)), r, settings, callback)
        nfev += sum(res.nfev for res in polished)
        best = polished[int(np.argmin(funs))]
        polish_history = best.history
        messages.append(f"polish: {best.message}")
        success = success and all(res.success for res in polished)
        pool = np.concatenate([xs, pool])
        pool_fun = np.concatenate([funs, pool_fun])

    kept = _best_distinct(pool, pool_fun, settings.n_solutions)
    template = ImplicitPolynomial(basis.exponents(dim, degree), pool[kept[0]], norm, method=method)
    solutions = _solutions(template, pool, pool_fun, kept, obj64, starts)
    best = solutions[0]
    fun = float(obj64(best.coefficients)[0])
    if len(starts) and best.measures["distance"] >= starts.distances[0] * (1 - _SAME_DISTANCE):
        messages.append("no candidate beat the best start fit: returning it")
    success = success and bool(np.isfinite(fun))
    if not np.isfinite(fun):
        messages.append("the objective is not finite at the best candidate")
    info = {**settings.to_dict(), "delta": delta, "notes": starts.notes, "n_starts": len(starts), "objective": fun,
            "search_points_used": n_search}
    if scale is not None:
        info.update(robust_scale=scale, taubin_cap=cap)
    best = best.with_coefficients(best.coefficients, info=info)
    solutions[0] = best
    return RefineResult(
        x=best.coefficients, fun=fun, nit=nit, nfev=int(nfev), success=success, message="; ".join(messages) or "done",
        polynomial=best, measures=Measures(**best.measures), history=np.asarray(history, dtype=np.float64),
        polish_history=polish_history, solutions=tuple(solutions),
        start_distances=MappingProxyType(starts.distance_by_label()),
        best_start=starts.labels[0] if len(starts) else None, population_size=size,
        seconds=time.perf_counter() - started, info=MappingProxyType(info))

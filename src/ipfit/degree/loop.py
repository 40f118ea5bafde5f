"""One degree loop: every degree fitted, measured and repaired, and the rule's choice among them.

:func:`degree_loop` fits g = min_degree, min_degree + 2, … with a fixed-degree method (a
refinement, a linear fit or the user's callable), measures each fit when the rule is geometric,
repairs what the rule asks to (:mod:`ipfit.degree.repair`), stops when the rule says so, and
lets the rule settle on a degree (:meth:`~ipfit.degree.rules.DegreeRule.settle`), with a degree
of the data's topology when the rule prefers one. A big cloud's degrees are fitted on an even
subsample and the selected one is measured on every point. :func:`ipfit.fit_adaptive` runs
this loop once, and again for each second look (:mod:`ipfit.degree.looks`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from .. import basis
from .._utils.result import Result
from .._utils.validation import as_normals, error
from ..cloud import Cloud
from ..fitting.linear import LINEAR_METHODS, fit_linear
from ..fitting.objective import Measures
from ..fitting.objective import measures as compute_measures
from ..fitting.options import REFINE_METHODS, SearchOptions
from ..fitting.refine import refine
from ..geometry.sampling import spread_subsample
from ..normals.rims import round_rims
from ..polynomial import ImplicitPolynomial, Normalization
from ..zeroset.quality import Quality, quality
from ..zeroset.topology import Topology, describe_mismatch
from .repair import fill_missing, other_solutions, repair
from .rules import TOLERANCE, TOPOLOGY, DegreeRule, TopologyRule, topology_differs

__all__ = ["DegreeResult", "FitFunction", "Loop", "LoopSettings", "another_loop", "degree_loop"]


@dataclass(frozen=True, eq=False)
class DegreeResult(Result):
    """What the adaptive loop found at one degree (SciPy's vocabulary, like every result).

    Attributes
    ----------
    x, fun : the coefficients (normalised coordinates) and the value the fixed-degree method
        minimised at them (SciPy's meaning: the paper's distance plus any far-field term; the
        paper's distance itself for a linear or custom fit, which minimise nothing of ours, and
        for another of the search's solutions put in place of a fit its repair left not clean,
        :func:`ipfit.degree.repair.other_solutions`).
    distance : the paper's distance at ``x`` (Eq. 4), without any extra term.
    nit, nfev : the fixed-degree method's iterations and objective evaluations (0 for a linear fit).
    success, message : whether the method reached a finite fit, and how it ended.
    degree, polynomial, measures : the fit and its :class:`~ipfit.fitting.objective.Measures`.
    quality : its :class:`~ipfit.zeroset.quality.Quality`, when the rule measured it.
    seconds : wall-clock time of this degree.
    solutions : the refinement's best distinct solutions (empty for a linear fit).
    """

    degree: int
    polynomial: ImplicitPolynomial
    measures: Measures
    seconds: float
    quality: Quality | None = None
    solutions: tuple[ImplicitPolynomial, ...] = ()
    cleanup: tuple[Mapping[str, Any], ...] = ()
    reason: str = ""

    @property
    def dissimilarity(self) -> float:
        return float(self.measures.dissimilarity)

    @property
    def smoothness(self) -> float:
        return float(self.measures.smoothness)

    @property
    def distance(self) -> float:
        return float(self.measures.distance)

    def to_dict(self) -> dict:
        """The entry of ``degrees`` in the JSON result (contract keys, plus nit/nfev/quality)."""
        out: dict[str, Any] = {
            "degree": self.degree, "dissimilarity": self.dissimilarity, "smoothness": self.smoothness,
            "distance": self.distance, "seconds": self.seconds, "method": self.polynomial.method,
            "coefficients": [float(c) for c in self.polynomial.coefficients], "nit": self.nit,
            "nfev": self.nfev, "success": self.success, "message": self.message}
        if self.quality is not None:
            out["quality"] = self.quality.to_dict()
        if self.cleanup:
            out["cleanup"] = [dict(attempt) for attempt in self.cleanup]
        if self.reason:
            out["reason"] = self.reason
        return out


FitFunction = Callable[..., ImplicitPolynomial]


class _Fitter:
    """Fits one degree with the chosen method; warm-starts each degree from the previous one."""

    def __init__(self, method, options: SearchOptions | None, delta: float, rng, progress,
                 noise_scale: float | None = None) -> None:
        self.method, self.delta, self.rng, self.progress = method, delta, rng, progress
        self.options, self.noise_scale = options, noise_scale
        self.previous: ImplicitPolynomial | None = None

    def __call__(self, cloud: Cloud, normals, degree, options: SearchOptions | None = None, extra_starts=(),
                 method: str | None = None, keep_clear=None):
        # ``normals`` as the fit was given them (made unit once); the cloud holds them normalised again.
        if callable(self.method):
            poly = self.method(cloud.points, normals, degree)
            if not isinstance(poly, ImplicitPolynomial):
                raise error("method", "a callable returning an ImplicitPolynomial", type(poly).__name__)
            return poly, (), 0, 0, True, "custom fit", None
        if self.method in LINEAR_METHODS:
            return fit_linear(cloud, None, degree, self.method), (), 0, 0, True, "linear fit", None
        options = cast(SearchOptions, options or self.options)  # a refinement method: check_settings gave options

        def report(state):
            self.progress({"event": "iteration", "degree": degree, "stage": state.message, "nit": state.nit,
                           "fun": state.fun})

        starts = list(extra_starts)
        if options.warm_start and self.previous is not None and self.previous.degree < degree:
            starts.append(_embed(self.previous, degree))
        result = refine(cloud, None, degree, method=method or self.method, options=options, delta=self.delta,
                        starts=starts or None, keep_clear=keep_clear, noise_scale=self.noise_scale, rng=self.rng,
                        callback=report if self.progress is not None else None)
        return (result.polynomial, tuple(result.solutions), result.nit, result.nfev, result.success,
                result.message, result.fun)


def _embed(poly: ImplicitPolynomial, degree: int) -> NDArray[np.float64]:
    """The coefficients of ``poly`` at a higher degree: graded order lists every lower-degree
    monomial first, so the same polynomial is its coefficients followed by zeros."""
    out = np.zeros(basis.n_coefficients(poly.dim, degree))
    out[: poly.n_coefficients] = poly.coefficients
    return out


@dataclass(frozen=True)
class LoopSettings:
    """What every degree loop of one :func:`fit_adaptive` call shares (checked there)."""

    method: Any
    options: SearchOptions | None
    rule: DegreeRule
    epsilon: float
    delta: float
    min_degree: int
    top: int
    progress: Callable[[dict], None] | None
    noise: float | None
    ordered_contour: bool | None
    rims: bool = False  # the loop turns the normals outward over thin rims (normals.rims)


@dataclass(frozen=True)
class Loop:
    """One degree loop's outcome: every degree's result, the selected one's index, why, and how."""

    results: list[DegreeResult]
    index: int
    reason: str
    message: str
    notes: tuple[str, ...] = ()  # what fit_adaptive decided around the loop, said after its message


def another_loop(cloud: Cloud, unit, settings: LoopSettings, generator, total: list[Loop]) -> Loop | None:
    """The degree loop run once more, on ``cloud``, appended to ``total``; None when interrupted
    before its first degree finished (the fit so far stands)."""
    try:
        again = degree_loop(cloud, unit, settings, generator)
    except KeyboardInterrupt:
        return None
    total.append(again)
    return again


def degree_loop(cloud: Cloud, unit, settings: LoopSettings, generator) -> Loop:
    """The degree loop on ``cloud`` (with ``unit``, its normals as given), the rule's selection,
    and the selected degree measured on every point when the loop fitted a subsample."""
    method, options, rule, epsilon, delta = (settings.method, settings.options, settings.rule, settings.epsilon,
                                             settings.delta)
    progress, ordered_contour, top, min_degree = (settings.progress, settings.ordered_contour, settings.top,
                                                  settings.min_degree)
    # A big cloud's degrees are fitted on an even subsample of it (SearchOptions.fit_points);
    # the selected one is measured on every point after the loop.
    work, work_unit = _working_cloud(cloud, unit, options if method in REFINE_METHODS else None)
    subsample = work is not cloud
    measured = rule.measured
    rims: tuple[str, ...] = ()  # what the message says of the normals' rims
    if settings.rims:
        # estimated normals are a dense scan's faces': they leave the zero set free to run on past
        # a thin part's rim (docs/rims.md)
        rounded, turn = round_rims(work.points, work.oriented, weights=work.weights, return_turn=True)
        if turn.any():
            work_unit = rounded
            work = Cloud._checked(work.points, as_normals(rounded, work.points), None, work.weights)
            turned = f"the normals of {np.count_nonzero(turn):,} points ({np.mean(turn > 0):.0%})"
            rims = (f"{turned} turned outward over thin rims",)
    fitter = _Fitter(method, options if method in REFINE_METHODS else None, delta, generator, progress,
                     settings.noise)
    degrees = list(range(min_degree, top + 1, 2)) if top > min_degree else [min_degree]
    results: list[DegreeResult] = []
    # per degree, for a topology variant after the loop: its fit before any repair, its refit, its
    # measure of another polynomial, its warm start
    unrepaired: list[tuple[DegreeResult, Callable[..., DegreeResult], Callable[..., DegreeResult],
                           ImplicitPolynomial | None]] = []
    reason = "max_degree"
    variant = _variants(results, unrepaired, rule, fitter, work, ordered_contour, progress) \
        if measured and fitter.options is not None and rule.prefers_topology else None
    beyond: int | None = None  # a degree tried after the rule's stop, for the data's topology
    aside: DegreeResult | None = None  # that degree, when it has another topology too
    for degree in degrees:
        if progress is not None:
            progress({"event": "degree_start", "degree": degree})
        try:
            entry = before_repair = _fit_degree(fitter, work, work_unit, degree, delta, measured, ordered_contour)
            best_f = rule.best_clean_f(results)

            def refit(options, start, keep_clear, degree=degree):
                return _fit_degree(fitter, work, work_unit, degree, delta, True, ordered_contour,
                                   options=options, extra_starts=[start], method="polish", keep_clear=keep_clear)

            if measured and fitter.options is not None and not rule.is_done(entry, best_f):
                entry = repair(entry, refit, fitter.options, work, ordered_contour, rule, best_f)
            if measured and fitter.options is not None and rule.fills_missing(entry, best_f):
                entry = fill_missing(entry, refit, fitter.options, work, ordered_contour, rule)

            def measure(poly, fitted=before_repair):
                return _measured_fit(fitted, poly, work, work_unit, delta, ordered_contour)

            if measured and fitter.options is not None and not rule.is_clean(entry.quality):
                entry = other_solutions(entry, before_repair.solutions, measure, fitter.options, rule)
            unrepaired.append((before_repair, refit, measure, fitter.previous))
        except KeyboardInterrupt:
            if not results:
                raise
            reason = "interrupted"
            break
        # A degree whose topology was repaired warm-starts the next one from its fit before the
        # repair, as without the topology check: holding a neck inside at degree 6 cost the fish the
        # shape its degree 8 grew from the unrepaired fit (F 0.96 for 1.0).
        topology_repaired = before_repair is not entry and rule.checks_topology and \
            topology_differs(before_repair.quality)
        fitter.previous = (before_repair if topology_repaired else entry).polynomial
        results.append(entry)
        if progress is not None:
            progress({"event": "degree_done", **entry.to_dict()})
        if degree == beyond:
            try:  # repaired at once, whatever its F-score as fitted: the repair is why it was tried
                if variant is not None and topology_differs(entry.quality):
                    tried, repaired = variant(len(results) - 1)
                    results[-1] = repaired or tried
            except KeyboardInterrupt:
                reason = "interrupted"
            if topology_differs(results[-1].quality):
                # tried for the data's topology alone, and it has another one too: the choice stays
                # among the degrees the rule fitted (the cow's degree 10 gains F-score with two parts)
                aside = results.pop()
                break
            if reason == "interrupted":
                break
        stop = rule.stop(results, epsilon)
        # Not trying a higher degree for want of a gain says nothing when there is none to try.
        if stop is not None and not (stop == "no_f_gain" and degree == degrees[-1]):
            # One degree more when the rule would keep another topology than the data's for want
            # of a degree of the data's within its tolerance: homer's degree 8 keeps a handle
            # across the narrow gap between its feet under every repair, its degree 10 closes it.
            reason = stop
            try:
                settled = None if variant is None or beyond is not None or degree == degrees[-1] else \
                    _settled_on_wrong_topology(results, rule, epsilon, stop, variant)
            except KeyboardInterrupt:  # the degrees fitted stand, as when a degree is interrupted
                reason, settled = "interrupted", None
            if settled is None:
                break
            results[:] = settled  # with the repair rounds tried on the way
            beyond = degree + 2
    results, index, reason, message = _select(results, rule, epsilon, reason, fixed=len(degrees) == 1,
                                              variant=variant if reason != "interrupted" else None)
    if beyond is not None and reason != "interrupted":
        outcome = "" if aside is None else \
            f", and it has another topology too ({_mismatch(aside)}): not selected"
        message = (f"{message}; degree {beyond} was tried after the rule had stopped at degree {beyond - 2}, as no "
                   f"degree up to it within {TOLERANCE:g} of the best clean F-score had the data's topology{outcome}")
    results = [dataclasses.replace(r, reason=rule.reason(results, i, index, message, epsilon))
               for i, r in enumerate(results)]
    if aside is not None:
        results.append(dataclasses.replace(aside, reason=f"tried after the rule's stop, for the data's topology: "
                                                         f"{_mismatch(aside)}"))
    if subsample and reason != "interrupted":
        sampled = f"degrees fitted on {len(work):,} of the {len(cloud):,} points spread evenly"
        try:
            if progress is not None:
                progress({"event": "every_point", "degree": results[index].degree, "n_points": len(cloud),
                          "fit_points": len(work)})
            results[index] = _on_every_point(cloud, unit, results[index], delta, measured, ordered_contour)
            message = f"{message}; {sampled}, degree {results[index].degree} measured on every point"
        except KeyboardInterrupt:  # the subsample's fit stands, as a degree finished in the loop does
            reason = "interrupted"
            message = f"{message}; {sampled}; interrupted while measuring degree {results[index].degree} on every point"
    return Loop(results, index, reason, "; ".join((message, *rims)))


def _variants(results: list[DegreeResult], unrepaired: list, rule: DegreeRule, fitter: _Fitter, work: Cloud,
              ordered_contour, progress) -> Callable[[int], tuple[DegreeResult, DegreeResult | None]]:
    """The ``variant`` a rule that prefers the data's topology settles with (see
    :meth:`~ipfit.degree.rules.DegreeRule.settle`): degree ``i`` of ``results`` (the loop's list,
    as it grows) repaired for the topology from its fit before any repair, each degree once."""
    done: dict[int, tuple[DegreeResult, DegreeResult | None]] = {}

    def variant(i: int) -> tuple[DegreeResult, DegreeResult | None]:
        if i in done:
            return done[i]
        previous = fitter.previous
        fit, refit, measure, fitter.previous = unrepaired[i]  # the polish starts as it did in the loop
        event = {"event": "topology_repair", "degree": results[i].degree, "mismatch": _mismatch(results[i])}
        if progress is not None:
            progress(event)
        try:
            entry, repaired = _topology_variant(results[i], fit, refit, measure, cast(SearchOptions, fitter.options),
                                                work, ordered_contour, rule.best_clean_f(results))
        finally:
            fitter.previous = previous  # a degree still to come starts from the loop's fit
        if progress is not None:
            done_q = cast(Quality, (repaired or entry).quality)
            progress({**event, "f_score": done_q.f_score, "matches": repaired is not None,
                      "seconds": entry.seconds - results[i].seconds})
        done[i] = entry, repaired
        return done[i]

    return variant


def _mismatch(entry: DegreeResult) -> str:
    q = cast(Quality, entry.quality)
    return describe_mismatch(cast(Topology, q.topology), cast(Topology, q.data_topology))


def _settled_on_wrong_topology(results: list[DegreeResult], rule: DegreeRule, epsilon: float, stop: str,
                               variant) -> list[DegreeResult] | None:
    """``results`` as ``rule`` settles them when it settles on a clean degree of another topology
    than the data's (known with confidence), else None."""
    settled, index, _ = rule.settle(results, epsilon, stop, variant, final=False)
    wrong = rule.is_clean(settled[index].quality) and topology_differs(settled[index].quality)
    return settled if wrong else None


def _working_cloud(cloud: Cloud, unit, options: SearchOptions | None):
    """The cloud the degree loop fits, and its normals as given: ``cloud`` itself, or an even
    subsample of ``options.fit_points`` of its points (fixed seed) when it has more. A mesh is
    fitted on every vertex: its faces describe the surface every degree is measured against
    (and its topology, known with confidence), which a subsample of its vertices would lose."""
    most = None if options is None else options.fit_points
    if most is None or len(cloud) <= most or cloud.faces is not None:
        return cloud, unit
    pick = spread_subsample(cloud, most)
    return (Cloud._checked(cloud.points[pick], as_normals(unit[pick], cloud.points[pick]), None,
                           None if cloud.weights is None else cloud.weights[pick]), unit[pick])


def _on_every_point(cloud: Cloud, unit, entry: DegreeResult, delta: float, measured: bool,
                    ordered_contour) -> DegreeResult:
    """``entry`` (a degree fitted on the working subsample) written in the normalisation of the
    whole ``cloud`` and measured on every point of it, its reason, repairs, evaluations and time
    carried over. It is not polished there again: on 50,000 points spread evenly the fit has
    settled, and a polish on every point, without the repairs' samples, can undo a repair."""
    start = time.perf_counter()
    norm = Normalization.from_points(cloud.points)
    moved = dataclasses.replace(entry.polynomial, coefficients=_renormalised(entry.polynomial, norm),
                                normalization=norm)
    poly, m, q = _measure(moved, cloud, unit, delta, measured, ordered_contour)
    # `fun` stays what the method minimised (on the subsample); the measures are every point's
    return dataclasses.replace(entry, x=poly.coefficients, polynomial=poly, measures=m, quality=q,
                               seconds=entry.seconds + time.perf_counter() - start)


def _renormalised(poly: ImplicitPolynomial, norm: Normalization) -> NDArray[np.float64]:
    """The unit coefficient vector of ``poly`` in the normalised coordinates of ``norm``: the
    same polynomial (a similarity keeps the degree), solved for at 4·d points of the unit box."""
    v = np.random.default_rng(0).uniform(-1.5, 1.5, size=(4 * poly.n_coefficients, poly.dim))
    coefficients = np.linalg.lstsq(basis.monomials(v, poly.exponents), poly(norm.invert(v)), rcond=None)[0]
    return coefficients / np.linalg.norm(coefficients)


class _WithinTolerance(TopologyRule):
    """The topology rule, its repair going on until a clean zero set of the data's topology is
    within the capture rule's tolerance of ``best_f`` (the variants :func:`_topology_variant` makes)."""

    def is_done(self, entry, best_f=0.0):
        return self.is_clean(entry.quality) and entry.quality.f_score >= best_f - TOLERANCE


def _topology_variant(entry: DegreeResult, unrepaired: DegreeResult, refit: Callable[..., DegreeResult],
                      measure: Callable[[ImplicitPolynomial], DegreeResult], options: SearchOptions, cloud: Cloud,
                      ordered_contour, best_f: float) -> tuple[DegreeResult, DegreeResult | None]:
    """``entry`` (a degree as its rule repaired it, of another topology than the data's) with what
    was tried for the data's topology recorded, and the best of it when that has a clean zero set
    of the data's topology (else None): first the search's other solutions of the degree (each
    measured by ``measure``), then, unless one of them is within the tolerance of ``best_f``, the
    topology rule's repair of its unrepaired fit, going on until a round is. Both carry every
    attempt, their evaluations and their time."""
    within = _WithinTolerance()
    other = other_solutions(unrepaired, unrepaired.solutions, measure, options, within)
    attempts = tuple(other.cleanup[len(unrepaired.cleanup):])
    nfev = 0
    best = other
    if not within.is_done(other, best_f):
        repaired = repair(unrepaired, refit, options, cloud, ordered_contour, within, best_f)
        attempts += tuple(repaired.cleanup)
        nfev = repaired.nfev - unrepaired.nfev
        if TOPOLOGY.is_clean(repaired.quality) and (not TOPOLOGY.is_clean(other.quality) or
                                                    repaired.quality.f_score >= other.quality.f_score):
            best = repaired
    totals = {"cleanup": tuple(entry.cleanup) + attempts, "nfev": entry.nfev + nfev,
              "seconds": entry.seconds + sum(a["seconds"] for a in attempts)}
    fixed = TOPOLOGY.is_clean(best.quality)
    return dataclasses.replace(entry, **totals), dataclasses.replace(best, **totals) if fixed else None


def _select(results, rule: DegreeRule, epsilon: float, reason: str, fixed: bool,
            variant=None) -> tuple[list[DegreeResult], int, str, str]:
    """``(results, index, reason, message)``: the results as the rule settles them (``variant``:
    see :meth:`~ipfit.degree.rules.DegreeRule.settle`), its choice among them and its explanation;
    a single degree asked for (``fixed``) leaves no choice to a rule."""
    if fixed and reason != "interrupted":
        return list(results), 0, "fixed", f"fixed degree {results[0].degree}"
    results, index, reason = rule.settle(results, epsilon, reason, variant)
    return results, index, reason, rule.explain(results, index, reason, epsilon)


def _measure(poly: ImplicitPolynomial, cloud: Cloud, unit, delta, measured: bool, ordered_contour
             ) -> tuple[ImplicitPolynomial, Measures, Quality | None]:
    """``poly`` with its paper's measures on ``cloud`` attached, those measures, and its quality
    when ``measured``: how every fit of the loop is measured."""
    m = compute_measures(poly, cloud.points, unit, delta=delta)
    poly = poly.with_coefficients(poly.coefficients, measures=m.to_dict())
    return poly, m, quality(poly, cloud, ordered_contour=ordered_contour) if measured else None


def _measured_fit(fitted: DegreeResult, poly: ImplicitPolynomial, cloud: Cloud, unit, delta, ordered_contour
                  ) -> DegreeResult:
    """``fitted`` (a degree's fit) with ``poly`` (another solution of the same search) in its
    place, measured as :func:`_fit_degree` measures a fit; its seconds are the measurement's."""
    t0 = time.perf_counter()
    poly, m, q = _measure(poly, cloud, unit, delta, True, ordered_contour)
    return dataclasses.replace(fitted, x=poly.coefficients, fun=float(m.distance), polynomial=poly, measures=m,
                               quality=q, seconds=time.perf_counter() - t0, cleanup=())


def _fit_degree(fitter: _Fitter, cloud: Cloud, unit, degree, delta, measured: bool, ordered_contour, *, options=None,
                extra_starts=(), method=None, keep_clear=None) -> DegreeResult:
    t0 = time.perf_counter()
    poly, solutions, nit, nfev, success, message, fun = fitter(cloud, unit, degree, options, extra_starts,
                                                               method, keep_clear)
    poly, m, q = _measure(poly, cloud, unit, delta, measured, ordered_contour)
    return DegreeResult(x=poly.coefficients, fun=float(m.distance if fun is None else fun), nit=nit, nfev=nfev,
                        success=success, message=message, degree=degree, polynomial=poly, measures=m,
                        seconds=time.perf_counter() - t0, quality=q, solutions=solutions)

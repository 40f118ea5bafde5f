"""Adaptive degree selection: the paper's Algorithm 1.

For g = 2, 4, …, G, fit at degree g with a fixed-degree method; stop as soon as the
smoothness improves by no more than ε over the previous degree and return that previous
degree; if the loop reaches G, return G. Every degree tried is kept, so a user can inspect
the whole path and take another degree.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import basis
from ._validation import (as_normals, as_points, check_choice, check_int, check_nonnegative, check_real,
                          check_rng, error)
from .linear import LINEAR_METHODS, fit_linear
from .polynomial import ImplicitPolynomial

__all__ = ["fit_adaptive", "AdaptiveResult", "DegreeResult", "select_degree", "select_degree_geometric",
           "fixed_degree_methods", "DEFAULT_METHOD", "DEFAULT_MAX_DEGREE", "RULES"]

#: Degree-selection rules: the paper's Algorithm 1, and the same rule restricted to degrees
#: whose zero set is clean (no spurious component, closed inside the box) when one exists.
RULES = ("paper", "geometric")

#: Maximum degree tried by default, per dimension (the paper: degrees 2 to 10 are the norm).
DEFAULT_MAX_DEGREE = {2: 10, 3: 8}
DEFAULT_METHOD = "de+polish"


def _refine_methods() -> tuple[str, ...]:
    from .refine import REFINE_METHODS

    return tuple(REFINE_METHODS)


def fixed_degree_methods() -> tuple[str, ...]:
    """Names accepted by ``fit_adaptive(method=...)``: the linear fits and the refinements."""
    return tuple(LINEAR_METHODS) + _refine_methods()



@dataclass(frozen=True, eq=False)
class DegreeResult:
    """What the adaptive loop found at one degree."""

    degree: int
    polynomial: ImplicitPolynomial
    dissimilarity: float
    smoothness: float
    distance: float
    seconds: float
    solutions: tuple[ImplicitPolynomial, ...] = ()
    details: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        out = {"degree": self.degree, "dissimilarity": self.dissimilarity, "smoothness": self.smoothness,
               "distance": self.distance, "seconds": self.seconds, "method": self.polynomial.method,
               "coefficients": [float(c) for c in self.polynomial.coefficients]}
        out.update({k: v for k, v in self.details.items() if k not in out})
        return out


def select_degree(degrees: Sequence[int], smoothness: Sequence[float], epsilon: float = 0.01,
                  complete: bool = True) -> tuple[int, str]:
    """Apply Algorithm 1's stopping rule to a smoothness path.

    Returns ``(index, reason)``: the index into ``degrees`` of the selected degree, and
    ``'criterion'`` (smoothness improved by ≤ ε at the next degree), ``'max_degree'`` (the
    loop reached its last degree) or ``'incomplete'`` (the path ended early, e.g. on Ctrl-C,
    before the rule fired: its last degree is returned).

    >>> select_degree([2, 4, 6, 8], [0.80, 0.90, 0.905, 0.95])
    (1, 'criterion')
    >>> select_degree([2, 4, 6], [0.8, 0.9, 0.95])
    (2, 'max_degree')
    """
    if len(degrees) != len(smoothness) or not degrees:
        raise error("smoothness", "one value per degree", f"{len(smoothness)} values for {len(degrees)} degrees")
    for i in range(1, len(degrees)):
        if smoothness[i] - smoothness[i - 1] <= epsilon:
            return i - 1, "criterion"
    return len(degrees) - 1, ("max_degree" if complete else "incomplete")


def select_degree_geometric(degrees: Sequence[int], smoothness: Sequence[float], clean: Sequence[bool],
                            f_scores: Sequence[float], epsilon: float = 0.01,
                            complete: bool = True) -> tuple[int, str]:
    """The paper's rule, but never a degree whose zero set is not clean when a clean one exists.

    ``clean[i]`` says degree i's zero set has no spurious component and closes inside the
    box. When the paper's choice is not clean, the clean degree with the highest F-score
    (the lowest such degree on ties) is taken, with reason ``'geometric'``.

    >>> select_degree_geometric([2, 4, 6], [0.8, 0.9, 0.905], [True, False, True], [0.7, 0.9, 0.95])
    (2, 'geometric')
    """
    index, reason = select_degree(degrees, smoothness, epsilon, complete)
    if clean[index] or not any(clean):
        return index, reason
    candidates = [i for i in range(len(degrees)) if clean[i]]
    best = max(candidates, key=lambda i: (f_scores[i], -degrees[i]))
    return best, "geometric"


@dataclass(frozen=True, eq=False)
class AdaptiveResult:
    """Result of :func:`fit_adaptive`.

    Attributes
    ----------
    polynomial : the fit at the selected degree (measures filled in).
    selected_degree : int
    degrees : one :class:`DegreeResult` per degree tried, in order.
    reason : why the loop stopped: 'criterion', 'max_degree' or 'interrupted'.
    epsilon, delta, method, seconds
    """

    polynomial: ImplicitPolynomial
    selected_degree: int
    degrees: tuple[DegreeResult, ...]
    reason: str
    epsilon: float
    delta: float
    method: str
    seconds: float
    rule: str = "paper"
    far_weight: float = 0.0

    @property
    def smoothness_path(self) -> NDArray[np.float64]:
        return np.array([d.smoothness for d in self.degrees])

    def at_degree(self, degree: int) -> DegreeResult:
        """The result kept for ``degree`` (so another degree than the selected one can be taken)."""
        for entry in self.degrees:
            if entry.degree == degree:
                return entry
        tried = ", ".join(str(d.degree) for d in self.degrees)
        raise error("degree", f"one of the degrees tried ({tried})", str(degree))

    def to_dict(self) -> dict:
        """The JSON result: the foundation format plus ``selected_degree`` and ``degrees``."""
        out = self.polynomial.to_dict()
        out["selected_degree"] = self.selected_degree
        out["degrees"] = [d.to_dict() for d in self.degrees]
        out["adaptive"] = {"epsilon": self.epsilon, "delta": self.delta, "method": self.method,
                           "reason": self.reason, "rule": self.rule, "far_weight": self.far_weight,
                           "seconds": self.seconds}
        chosen = self.at_degree(self.selected_degree)
        if "quality" in chosen.details:
            out["quality"] = chosen.details["quality"]
        return out


FitFunction = Callable[..., Any]


def _fit_one(method: str | FitFunction, points, normals, degree, delta, rng, params, progress, far_weight):
    """Fit one degree; returns (polynomial, solutions, details)."""
    if callable(method):
        poly = method(points, normals, degree)
        return poly, (), {}
    if method in LINEAR_METHODS:
        return fit_linear(points, normals, degree, method, **params), (), {}
    from .refine import refine

    def report(state):
        progress({"event": "iteration", "degree": degree, **_state_dict(state)})

    result = refine(points, normals, degree, method=method, delta=delta, rng=rng,
                    callback=report if progress is not None else None, far_weight=far_weight, **params)
    details = {"nit": int(result.nit), "nfev": int(result.nfev)}
    return result.polynomial, tuple(result.solutions), details


def _state_dict(state) -> dict:
    if isinstance(state, Mapping):
        return dict(state)
    out = {}
    for name in ("nit", "fun"):
        if hasattr(state, name):
            out[name] = getattr(state, name)
    return out


def fit_adaptive(points: ArrayLike, normals: ArrayLike | None = None, *, method: str | FitFunction = DEFAULT_METHOD,
                 max_degree: int | None = None, min_degree: int = 2, epsilon: float = 0.01, delta: float = 0.25,
                 rule: str = "geometric", far_weight: float | None = None, faces: ArrayLike | None = None,
                 ordered_contour: bool | None = None, rng=None, progress: Callable[[dict], None] | None = None, **params) -> AdaptiveResult:
    """Find the degree the data needs (Algorithm 1) and fit at it.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array.
    normals : (N, dim) array, or None to estimate them (:func:`ipfit.estimate_normals`).
    method : a fixed-degree method: a linear fit ('lstsq', 'taubin', '3l', 'ridge',
        'gradient_one'), a refinement ('de', 'pso', 'de+polish', 'pso+polish', 'polish'), or a
        callable ``(points, normals, degree) -> ImplicitPolynomial``.
    max_degree : G, the last degree tried (default 10 in 2D, 8 in 3D).
    min_degree : the first degree tried (even, default 2).
    epsilon : ε, the smallest smoothness gain that justifies a higher degree.
    delta : δ of the paper's distance.
    far_weight : weight of the far-field term in the refinement objective
        (:class:`ipfit.farfield.FarFieldTerm`); default
        :data:`ipfit.farfield.DEFAULT_TERM_WEIGHT` for the refinement methods; 0 gives the
        paper's objective. Not used by the linear methods ('3l-far' is 3L with far-field rows).
    rule : 'geometric' (default) or 'paper' (Algorithm 1 exactly). 'geometric': the geometric quality of every degree is
        measured (:func:`ipfit.quality.quality`: F-score, spurious components, closed) and
        a degree whose zero set is not clean is not selected when a clean one exists; the
        loop goes on past the paper's stop until a clean degree has been seen.
    faces, ordered_contour : describe the data's shape for the quality measures (mesh faces;
        a 2D contour in order, detected by :func:`ipfit.quality.looks_like_contour` when
        None), used with ``rule='geometric'``.
    rng : seed or Generator (SPEC 7), passed to the metaheuristics.
    progress : called with a dict per event ('degree_start', 'iteration', 'degree_done').
    **params : passed to the fixed-degree method (e.g. ``iterations``, ``population``).

    Returns
    -------
    AdaptiveResult

    Notes
    -----
    Ctrl-C (KeyboardInterrupt) during a degree ends the loop: the degrees already finished
    are kept and the rule is applied to them (``reason='interrupted'``). With none finished,
    the interrupt propagates.

    Examples
    --------
    >>> from ipfit import fit_adaptive
    >>> from ipfit.datasets import synthetic
    >>> shape = synthetic.ellipse(200)
    >>> result = fit_adaptive(shape.points, shape.normals, method="3l")
    >>> result.selected_degree
    2
    """
    from .objective import measures as compute_measures

    pts = as_points(points)
    dim = pts.shape[1]
    if normals is None:
        from .normals import estimate_normals

        unit = estimate_normals(pts)
    else:
        unit = as_normals(normals, pts)
    if not callable(method):
        method = check_choice(method, "method", fixed_degree_methods())
    rule = check_choice(rule, "rule", RULES)
    if far_weight is None:
        from .farfield import DEFAULT_TERM_WEIGHT

        far_weight = DEFAULT_TERM_WEIGHT
    far_weight = check_nonnegative(far_weight, "far_weight")
    epsilon = check_real(epsilon, "epsilon")
    delta = check_nonnegative(delta, "delta")
    min_degree = check_int(min_degree, "min_degree", minimum=1)
    top = DEFAULT_MAX_DEGREE[dim] if max_degree is None else check_int(max_degree, "max_degree", minimum=min_degree)
    largest_possible = max((g for g in range(1, top + 1) if basis.n_coefficients(dim, g) <= len(pts)), default=0)
    if largest_possible < min_degree:
        raise error("points", f"at least {basis.n_coefficients(dim, min_degree)} points for degree {min_degree}",
                    f"{len(pts)} points", "Pass more points.")
    if top > largest_possible:
        if max_degree is not None:
            raise error("max_degree", f"at most {largest_possible} for {len(pts)} points "
                        f"(degree {top} has {basis.n_coefficients(dim, top)} coefficients)", str(top),
                        "Lower --max-degree or pass more points.")
        top = largest_possible
    generator = check_rng(rng)
    degrees = list(range(min_degree, top + 1, 2))
    start = time.perf_counter()
    results: list[DegreeResult] = []
    reason = "max_degree"
    for degree in degrees:
        if progress is not None:
            progress({"event": "degree_start", "degree": degree})
        t0 = time.perf_counter()
        try:  # an interrupt anywhere in this degree's work drops only this degree
            poly, solutions, details = _fit_one(method, pts, unit, degree, delta, generator, params, progress,
                                                far_weight)
            m = compute_measures(poly, pts, unit, delta=delta)
            poly = poly.with_coefficients(poly.coefficients, measures=m.to_dict())
            if rule == "geometric":
                from .quality import looks_like_contour, quality

                if ordered_contour is None:
                    ordered_contour = dim == 2 and looks_like_contour(pts)
                q = quality(poly, pts, faces=faces, ordered_contour=ordered_contour)
                details = {**details, "quality": q.to_dict()}
        except KeyboardInterrupt:
            if not results:
                raise
            reason = "interrupted"
            break
        entry = DegreeResult(degree, poly, float(m.dissimilarity), float(m.smoothness), float(m.distance),
                             time.perf_counter() - t0, solutions, details)
        results.append(entry)
        if progress is not None:
            progress({"event": "degree_done", **entry.to_dict()})
        if len(results) >= 2 and results[-1].smoothness - results[-2].smoothness <= epsilon:
            if rule == "paper" or any(_is_clean(r) for r in results):
                reason = "criterion"
                break
    complete = reason != "interrupted"
    if rule == "geometric":
        index, rule_reason = select_degree_geometric(
            [r.degree for r in results], [r.smoothness for r in results], [_is_clean(r) for r in results],
            [r.details["quality"]["f_score"] for r in results], epsilon, complete)
    else:
        index, rule_reason = select_degree([r.degree for r in results], [r.smoothness for r in results], epsilon,
                                           complete=complete)
    if reason != "interrupted":
        reason = rule_reason
    chosen = results[index]
    name = method if isinstance(method, str) else getattr(method, "__name__", "custom")
    return AdaptiveResult(chosen.polynomial, chosen.degree, tuple(results), reason, epsilon, delta, name,
                          time.perf_counter() - start, rule, far_weight if name in _refine_methods() else 0.0)


def _is_clean(entry: DegreeResult) -> bool:
    q = entry.details.get("quality")
    return bool(q) and q["n_spurious"] == 0 and bool(q["closed"])

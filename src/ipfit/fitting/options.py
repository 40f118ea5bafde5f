"""Settings of the search that refines linear fits, as one immutable, checked object.

:class:`SearchOptions` holds everything DE, PSO and the L-BFGS polish need; it is checked once,
when it is built. :data:`RECOMMENDED` is the recommended pipeline's search (``ipfit fit``'s
default) and :data:`PAPER` the paper's exact one. A method-specific setting (DE's ``mutation``,
PSO's ``chi``, the polish's ``polish_iterations``...) left at ``None`` takes the method's
default; set explicitly for a method that does not use it, it is an error rather than being
silently dropped (:meth:`SearchOptions.check_method`). :meth:`SearchOptions.for_method` resolves
the options for one method and dimension into a :class:`MethodOptions`, which the search reads.

The paper's exact pipeline is::

    fit_adaptive(points, normals, method=PAPER_METHOD, options=PAPER, rule=PAPER_RULE)

which is what ``ipfit fit --paper`` runs.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from .._utils.validation import check_choice, check_int, check_nonnegative, check_positive, check_probability, error
from ..exceptions import InvalidInputError
from .farfield import DEFAULT_TERM_WEIGHT
from .linear import LINEAR_METHODS, check_params
from .objective import DEFAULT_DELTA

__all__ = ["SearchOptions", "RECOMMENDED", "PAPER", "PAPER_METHOD", "PAPER_RULE", "DEFAULT_METHOD",
           "DEFAULT_RULE", "DEFAULT_EPSILON", "DEFAULT_DELTA", "DEFAULT_ITERATIONS", "DEFAULT_START_FITS",
           "REFINE_METHODS", "METHOD_DEFAULTS", "AUTO", "MethodOptions", "StartFit",
           "parse_start_fit"]

#: Refinement methods: a metaheuristic with or without the L-BFGS polish stage, or the polish
#: alone from the best start fit. "de" and "pso" are the paper's pure variants.
REFINE_METHODS = ("de+polish", "pso+polish", "de", "pso", "polish")
DEFAULT_METHOD = "de+polish"
DEFAULT_RULE = "capture"
#: ε of Algorithm 1 and δ of the paper's distance (Eq. 5); the paper's values.
DEFAULT_EPSILON = 0.01
DEFAULT_ITERATIONS = 500
#: The paper's refinement: DE alone, without the polish (``fit_adaptive(method=PAPER_METHOD)``).
PAPER_METHOD = "de"
#: The paper's degree rule, Algorithm 1 (``fit_adaptive(rule=PAPER_RULE)``).
PAPER_RULE = "paper"

#: The linear fits that start the population by default: each linear method at its default,
#: and a few parameter variants so that the paper's N/10 start slots get distinct members.
#: Names are ``method`` or ``method(param=value)``; see :func:`parse_start_fit`.
DEFAULT_START_FITS = ("3l", "ridge", "gradient_one", "taubin", "lstsq", "3l(c=0.02)", "3l(c=0.1)",
                      "ridge(kappa=1e-6)", "ridge(kappa=1e-3)", "gradient_one(mu=0.1)", "gradient_one(mu=10)")

#: Defaults of the method-specific settings (the paper's DE and PSO parameters, Section 5.2).
METHOD_DEFAULTS: Mapping[str, float | int | str] = {"mutation": 0.7, "recombination": 0.9, "chi": 0.729,
                                                    "c1": 2.05, "c2": 2.05, "polish_iterations": "auto"}
#: What "auto" means for the settings whose best value depends on the dimension (measured in
#: ``benchmarks/bench_search_budget.py``). A contour's 1,000 spread points sample it about as
#: densely as 3,000 do a surface and halve the search's time on the larger contours; contours
#: also keep their F-scores with a 30-generation stall and 300 polish iterations (checked over
#: 143 contours, docs/degree-rule.md). Surfaces keep 1,000 polish iterations: 300 lost up to
#: 0.23 in F on the thin models of docs/quality-3d.md (docs/search-budget.md). Their stall is 30
#: generations too: with the polish kept, the whole pipeline kept its F-scores over 15 models
#: and two seeds (docs/budget-3d.md) in 0.7x the time.
#: Surfaces search in float32: a DE selection only compares values, which float32 ranks alike
#: except at near-ties (docs/budget-3d.md: the same selections on 15 of 15 models), and the
#: products run faster; the polish and every reported value stay float64. Contours keep float64:
#: their search runs on 1,000 points, a smaller share of a fit, where float32 gained no
#: measurable time.
AUTO: Mapping[str, Mapping[int, Any]] = {"search_points": {2: 1000, 3: 3000},
                                         "stall_generations": {2: 30, 3: 30},
                                         "polish_iterations": {2: 300, 3: 1000},
                                         "dtype": {2: "float64", 3: "float32"}}
_USED_BY = {"mutation": ("de",), "recombination": ("de",), "chi": ("pso",), "c1": ("pso",), "c2": ("pso",),
            "polish_iterations": ("polish",)}


class StartFit(NamedTuple):
    """One parsed start fit: its ``spec`` as written (``"ridge(kappa=1e-6)"``), the linear
    ``method`` and its checked ``params``."""

    spec: str
    method: str
    params: Mapping[str, float]


def parse_start_fit(spec: str, name: str = "start_fits") -> StartFit:
    """Split ``"ridge(kappa=1e-6)"`` into the method and its parameters, checking both with the
    method's entry in :data:`ipfit.fitting.linear.LINEAR_METHODS` (the one registry of linear fits).

    >>> parse_start_fit("3l(c=0.02)")
    StartFit(spec='3l(c=0.02)', method='3l', params={'c': 0.02})
    """
    if not isinstance(spec, str):
        raise error(name, "linear method names such as '3l' or 'ridge(kappa=1e-6)'", repr(spec))
    method, _, rest = spec.partition("(")
    method = check_choice(method.strip(), name, LINEAR_METHODS)
    params: dict[str, float] = {}
    if rest:
        if not rest.endswith(")"):
            raise error(name, "'method(param=value, ...)'", repr(spec))
        for item in filter(None, (part.strip() for part in rest[:-1].split(","))):
            key, _, value = item.partition("=")
            key = key.strip()
            if key not in LINEAR_METHODS[method].params:
                allowed = ", ".join(LINEAR_METHODS[method].params) or "no parameters"
                raise error(name, f"parameters of {method} ({allowed})", repr(key))
            try:
                params[key] = float(value)
            except ValueError:
                raise error(name, f"a number for {key}", repr(value)) from None
    try:
        return StartFit(spec, method, check_params(method, params))
    except InvalidInputError as exc:  # name the argument that holds the bad value
        raise error(name, f"valid parameters of {method}", repr(spec), str(exc)) from None


def _int_or_auto(value: Any, name: str, minimum: int) -> int | str:
    if isinstance(value, str):
        if value != "auto":
            raise error(name, f"an integer >= {minimum}, None or 'auto'", repr(value))
        return value
    return check_int(value, name, minimum=minimum)


@dataclass(frozen=True)
class SearchOptions:
    """How :func:`ipfit.refine` searches (and :func:`ipfit.fit_adaptive` at every degree).

    Parameters
    ----------
    population_size : int, optional
        Population (swarm) size P; default 4 × the number of coefficients (paper, Section 5.2).
    iterations : int, default 500
        Generations of DE/PSO (paper: 500).
    mutation, recombination : float, optional
        DE's differential weight F (default 0.7) and crossover probability CR (0.9), rand/1/bin.
    chi, c1, c2 : float, optional
        PSO's constriction factor χ (default 0.729) and accelerations (2.05, 2.05).
    polish_iterations : int, optional
        L-BFGS iterations of the polish stage (default 300 in 2D, 1,000 in 3D, :data:`AUTO`;
        0 skips it).
    start_fits : tuple of str
        The linear fits that start the population (:data:`DEFAULT_START_FITS`); ``()`` starts
        from random directions. With a far-field term, 3L with far-field rows joins them.
    start_fraction : float, default 0.1
        Share of the population that starts exactly at (or next to) the start fits (paper:
        N/10); the others are scattered around them.
    search_space : {"whitened", "coefficients"}
        Coordinates the population moves in: "whitened" (y = R a, where every direction changes
        f and ∇f on the data alike) or the raw coefficients (the paper).
    far_term_weight : float, default 0.1
        Weight of the far-field term added to the objective (:class:`ipfit.FarFieldTerm`),
        which keeps the zero set from growing sheets away from the data; 0 is the paper's
        objective exactly.
    dtype : {"auto", "float64", "float32"}, default "auto"
        Precision of the population evaluations (float32's products are up to twice as fast;
        start fits, the polish and the reported measures always use float64). "auto": float64
        in 2D, float32 in 3D (:data:`AUTO`).
    n_solutions : int, default 5
        How many best distinct solutions a refinement returns.
    search_points : int, None or "auto", default "auto"
        DE/PSO evaluate the population on a well-spread subsample of this many points
        (:func:`ipfit.geometry.sampling.spread_subsample`, fixed seed); the start fits' ranking, the
        polish and every reported measure use all points. None: all points (the paper).
        "auto": 1,000 in 2D, 3,000 in 3D (:data:`AUTO`).
    fit_points : int or None, default 50,000
        :func:`ipfit.fit_adaptive` on a cloud of more points runs its degree loop (every
        degree's search, polish, measurement and repair) on this many of them spread evenly
        (:func:`ipfit.geometry.sampling.spread_subsample`, fixed seed), then measures the
        selected degree on every point (a mesh, whose faces every degree is measured against,
        always on every vertex). None: every degree on every point (the
        paper). 50,000 points sample a shape far more densely than a polynomial of
        the maximum degree resolves (165 coefficients in 3D), and a degree's full-cloud passes
        (ranking, measures, quality) were most of a million-point fit's time (docs/peers.md).
    mesh_points : int or None, default 2,000
        :func:`ipfit.fit_adaptive` on a 3D mesh (with vertex normals) whose vertices are too few for
        the highest degree it may try (the rule's points per coefficient: 910 for degree 12) also
        fits points spread evenly over its faces, this many points in all (at least as many as that
        degree asks for), each with its face's vertex normals interpolated at it
        (:func:`ipfit.geometry.sampling.surface_points`, fixed seed): its faces are the surface
        every degree is measured against, and its few vertices would stop the degrees early and
        leave thin parts with hardly a point. A mesh whose first fit measures poorly (best clean
        F-score below 0.95) is fitted again on its vertices and this many points spread over its
        faces, kept when it measures better against them, and a sparse bare cloud whose fit measures
        poorly on its points and this many spread over the triangles between them
        (:func:`ipfit.fit_adaptive`, Notes).
        None: the vertices only (the paper). Measured in docs/mesh-points.md and
        docs/quality-3d.md.
    stall_generations : int, None or "auto", default "auto"
        End DE/PSO when the best objective value has not improved by more than
        ``stall_tolerance`` (relative) over this many generations. None: always run
        ``iterations`` generations (the paper). "auto": 30 (:data:`AUTO`).
    stall_tolerance : float, default 1e-4
    warm_start : bool, default False
        :func:`ipfit.fit_adaptive` starts each degree also from the previous degree's solution
        (exactly representable, with zero higher-degree coefficients). Off by default: measured
        on the bundled contours it traps the search near the lower degree's shape (airplane:
        degree 6 selected with F = 0.88 instead of degree 10 with F = 0.99;
        ``benchmarks/bench_warm_start.py``).
    cleanup_weights : tuple of float, default (1.0, 10.0)
        When a degree's zero set has spurious components, the geometric rule of
        :func:`ipfit.fit_adaptive` polishes that degree's fit again with a far-field term that
        also holds samples of those components (``refine(keep_clear=...)``), at these weights
        in turn (stopping at the first that does not improve the fit), before rejecting the
        degree; every attempt is recorded.

    Examples
    --------
    >>> from ipfit import SearchOptions, PAPER
    >>> SearchOptions(iterations=100).iterations
    100
    >>> PAPER.search_space, PAPER.far_term_weight
    ('coefficients', 0.0)
    >>> SearchOptions(chi=0.7).check_method("de")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipfit.exceptions.InvalidInputError: chi: expected a setting used by method 'de' (chi is used by pso), got chi=0.7...
    """

    population_size: int | None = None
    iterations: int = DEFAULT_ITERATIONS
    mutation: float | None = None
    recombination: float | None = None
    chi: float | None = None
    c1: float | None = None
    c2: float | None = None
    polish_iterations: int | None = None
    start_fits: tuple[str, ...] = DEFAULT_START_FITS
    start_fraction: float = 0.1
    search_space: str = "whitened"
    far_term_weight: float = DEFAULT_TERM_WEIGHT
    dtype: str = "auto"
    n_solutions: int = 5
    search_points: int | str | None = "auto"
    fit_points: int | None = 50_000
    mesh_points: int | None = 2_000
    stall_generations: int | str | None = "auto"
    stall_tolerance: float = 1e-4
    warm_start: bool = False
    cleanup_weights: tuple[float, ...] = (1.0, 10.0)

    def __post_init__(self) -> None:
        set_ = functools.partial(object.__setattr__, self)
        if self.population_size is not None:
            set_("population_size", check_int(self.population_size, "population_size", minimum=2))
        set_("iterations", check_int(self.iterations, "iterations", minimum=0))
        if self.mutation is not None:
            value = check_positive(self.mutation, "mutation")
            if value > 2:
                raise error("mutation", "a differential weight in (0, 2]", str(value), "The paper uses 0.7.")
            set_("mutation", value)
        if self.recombination is not None:
            set_("recombination", check_probability(self.recombination, "recombination"))
        if self.chi is not None:
            value = check_positive(self.chi, "chi")
            if value >= 1:
                raise error("chi", "a constriction factor in (0, 1)", str(value), "The paper uses 0.729.")
            set_("chi", value)
        for name in ("c1", "c2"):
            if getattr(self, name) is not None:
                set_(name, check_positive(getattr(self, name), name))
        if self.polish_iterations is not None:
            set_("polish_iterations", _int_or_auto(self.polish_iterations, "polish_iterations", 0))
        fits = self.start_fits
        if isinstance(fits, str) or not isinstance(fits, (tuple, list)):
            raise error("start_fits", "a tuple of linear method names", repr(fits), "Wrap one name in a tuple.")
        for spec in fits:
            parse_start_fit(spec)
        set_("start_fits", tuple(fits))
        set_("start_fraction", check_probability(self.start_fraction, "start_fraction"))
        set_("search_space", check_choice(self.search_space, "search_space", ("whitened", "coefficients")))
        set_("far_term_weight", check_nonnegative(self.far_term_weight, "far_term_weight"))
        dtype = self.dtype
        if not (isinstance(dtype, str) and dtype == "auto"):
            try:
                dtype = np.dtype(dtype).name
            except TypeError:
                dtype = repr(dtype)
        set_("dtype", check_choice(dtype, "dtype", ("auto", "float64", "float32")))
        set_("n_solutions", check_int(self.n_solutions, "n_solutions", minimum=1))
        if self.search_points is not None:
            set_("search_points", _int_or_auto(self.search_points, "search_points", 10))
        if self.fit_points is not None:
            set_("fit_points", check_int(self.fit_points, "fit_points", minimum=1000))
        if self.mesh_points is not None:
            set_("mesh_points", check_int(self.mesh_points, "mesh_points", minimum=1))
        if self.stall_generations is not None:
            set_("stall_generations", _int_or_auto(self.stall_generations, "stall_generations", 1))
        set_("stall_tolerance", check_nonnegative(self.stall_tolerance, "stall_tolerance"))
        if not isinstance(self.warm_start, (bool, np.bool_)):
            raise error("warm_start", "True or False", repr(self.warm_start))
        weights = self.cleanup_weights
        if isinstance(weights, (str, bytes)) or not isinstance(weights, (tuple, list)):
            raise error("cleanup_weights", "a tuple of far-field term weights", repr(weights))
        set_("cleanup_weights", tuple(check_positive(w, "cleanup_weights") for w in weights))

    def replace(self, **changes: Any) -> SearchOptions:
        """A copy with ``changes`` applied (and checked).

        >>> RECOMMENDED.replace(iterations=50).iterations
        50
        """
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            raise error(unknown[0], "a SearchOptions field (" + ", ".join(f.name for f in dataclasses.fields(self))
                        + ")", "an unknown name")
        return dataclasses.replace(self, **changes)

    def check_method(self, method: str) -> str:
        """``method`` (one of :data:`REFINE_METHODS`), checked against these settings: a
        method-specific setting given explicitly for a method that does not use it raises
        :class:`~ipfit.InvalidInputError`.

        >>> RECOMMENDED.check_method("pso")
        'pso'
        """
        method = check_choice(method, "method", REFINE_METHODS)
        stages = set(method.split("+"))
        for name, users in _USED_BY.items():
            value = getattr(self, name)
            if value is not None and not stages.intersection(users):
                raise error(name, f"a setting used by method {method!r} ({name} is used by {', '.join(users)})",
                            f"{name}={value!r}", "Leave it unset or pick a method that uses it.")
        return method

    def for_method(self, method: str, dim: int) -> MethodOptions:
        """Every setting resolved for ``method`` (one of :data:`REFINE_METHODS`) on data of
        dimension ``dim``: method defaults filled in, "auto" values decided, start fits parsed.
        Checked as :meth:`check_method` does.

        >>> RECOMMENDED.for_method("de+polish", dim=2).search_points
        1000
        """
        method = self.check_method(method)
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        for name in _USED_BY:
            if values[name] is None:
                values[name] = METHOD_DEFAULTS[name]
        for name, by_dim in AUTO.items():
            if values[name] == "auto":
                values[name] = by_dim[dim]
        values["start_fits"] = tuple(parse_start_fit(spec) for spec in self.start_fits)
        return MethodOptions(method=method, dim=dim, **values)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready settings (tuples as lists)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in dataclasses.fields(self)}


@dataclass(frozen=True)
class MethodOptions:
    """A :class:`SearchOptions` resolved for one method and dimension
    (:meth:`SearchOptions.for_method`): what :func:`ipfit.refine` and the start fits read, every
    field a plain value (method defaults filled in, no "auto", start fits parsed). Built from
    checked options, so not checked again.
    """

    method: str
    dim: int
    population_size: int | None
    iterations: int
    mutation: float
    recombination: float
    chi: float
    c1: float
    c2: float
    polish_iterations: int
    start_fits: tuple[StartFit, ...]
    start_fraction: float
    search_space: str
    far_term_weight: float
    dtype: str
    n_solutions: int
    search_points: int | None
    fit_points: int | None
    mesh_points: int | None
    stall_generations: int | None
    stall_tolerance: float
    warm_start: bool
    cleanup_weights: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """The settings by name (start fits as written), as :attr:`ipfit.RefineResult.info` records them."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in ("method", "dim")}
        out["start_fits"] = tuple(fit.spec for fit in self.start_fits)
        return out


#: The recommended pipeline's search: DE + polish in whitened coordinates, all start fits,
#: with the far-field term.
RECOMMENDED = SearchOptions()
#: The paper's exact search: DE (F = 0.7, CR = 0.9, 500 iterations, population 4·d, N/10 started)
#: in the raw coefficients, started from the classic and 3L fits, on the paper's distance.
PAPER = SearchOptions(start_fits=("lstsq", "3l"), search_space="coefficients", far_term_weight=0.0, search_points=None,
                      fit_points=None, mesh_points=None, stall_generations=None, cleanup_weights=(),
                      dtype="float64")

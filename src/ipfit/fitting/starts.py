"""Where a refinement starts: the linear fits (and user polynomials) that seed the population.

The paper seeds N/10 of the population with linear fits so that the metaheuristic
post-optimises them. Here the start fits are evaluated one at a time in float64, sorted best
first, and the population is built around them.

On a cloud with weights (stray points left in, see :func:`ipfit.refine`) every linear start fit
is reweighted by its own distances, iteratively (IRLS): a point's weight is the cloud's times
the Cauchy weight 1 / (1 + (d/(c·s))²) of its Taubin distance d = |f|/||∇f|| to the current
fit, s the robust scale (:func:`ipfit.fitting.refine.robust_scale`), and the fit is solved
again, until it stops moving or after :data:`IRLS_ROUNDS` rounds. A linear fit is a least
squares fit, which a few strays bend at will; the reweighted one follows the points near its
zero set. The Cauchy weight never reaches 0, so no round drops the shape's own points for good
even when the first fit passes far from them: far out it falls like (c·s/d)², so it is the
ratio of distances that ranks the points, and the shape's points, the many near the fit, win.
The scale is the larger of s and the spread of the current distances (their median as a
Gaussian σ): at a degree too low for the shape the fit misses it by more than the noise, and
a scale of the noise alone then weights the shape's own points by how badly the polynomial
can follow them (measured on the apple of mpeg7-dev with 25 % strays: the coefficients kept
jumping by up to 0.8 per round at degree 4).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.numeric import unit_rows
from .._utils.validation import error
from ..cloud import Cloud, as_cloud
from ..exceptions import IpfitError
from ..geometry.sampling import spread_subsample
from ..polynomial import ImplicitPolynomial, Normalization
from .linear import DEFAULT_FAR_ROW_WEIGHT, fit_linear
from .options import StartFit

__all__ = ["StartFits", "start_fits", "initial_population", "IRLS_ROUNDS", "CAUCHY_C"]

# Unstarted members begin at start fits perturbed by a relative amount drawn log-uniformly in
# this range, measured in the whitened coordinates (see Objective.whitening), where 0.1 means
# "changes the values and gradients on the data by 10% of the start fit's".
_SPREAD = (1e-3, 0.3)
_TINY = float(np.finfo(np.float64).tiny)
FAR_START = "3l-far"
#: Linear start fits on bigger clouds use a well-spread subsample of this many points (in the
#: whole cloud's coordinates): each fit's QR costs N·d², and a dozen of them run per degree.
START_POINTS = 50_000
#: Reweighting rounds of a start fit on a weighted cloud, at most. Each is a QR per start fit, a
#: dozen per degree, and the starts only seed the search: the first rounds move a fit most (the
#: apple of mpeg7-dev with 25 % strays, degree 2: by 0.026, 0.011, 0.007, 0.005, 0.003; unit
#: coefficient vectors), so 3 rounds (48 linear fits per degree instead of 72) suffice.
IRLS_ROUNDS = 3
#: Cauchy's constant in units of the scale: 2.385 makes the weighted fit 95 % as efficient as
#: least squares on Gaussian offsets (Holland & Welsch 1977), so on clean parts of the shape the
#: reweighting costs next to nothing, while a point 10 scales away counts 1/18.
CAUCHY_C = 2.385
# The reweighting stops when the unit coefficient vector moves less than this.
_IRLS_TOLERANCE = 1e-6
# The spread of the current distances as a Gaussian σ: their median over this (MAD-type), which
# holds while fewer than half the points are strays.
_MEDIAN_TO_SIGMA = 0.6745


class StartFits:
    """Start fits in the normalised coordinates, best first once :meth:`rank` has run."""

    def __init__(self, labels: list[str], coefficients: NDArray, notes: list[str]) -> None:
        # Unique labels: distances are reported by label.
        self.labels = [lab if labels.count(lab) == 1 else f"{lab}#{k}" for k, lab in enumerate(labels)]
        self.coefficients = unit_rows(coefficients) if len(coefficients) else coefficients
        self.notes = notes
        self.distances = np.empty(0)

    def __len__(self) -> int:
        return len(self.labels)

    def rank(self, objective) -> int:
        """Evaluate each start fit exactly as the returned polynomial is measured (one vector at
        a time, float64), so "never above the best start fit" holds to the last bit; sort best
        first. Returns the number of evaluations."""
        if not len(self):
            return 0
        values = np.array([objective(a)[0] for a in self.coefficients])
        order = np.argsort(values, kind="stable")
        self.coefficients, self.distances = self.coefficients[order], values[order]
        self.labels = [self.labels[i] for i in order]
        return len(values)

    def distance_by_label(self) -> dict[str, float]:
        # not strict: before rank() there are labels but no distances (an empty dict)
        return dict(zip(self.labels, map(float, self.distances), strict=False))


def _fitted_cloud(cloud: Cloud, max_points: int) -> Cloud:
    """The cloud the start fits solve on: a spread subsample of ``max_points`` points of a bigger
    one. The linear fits check and normalise the unit normals they are given once more (they
    always have: its last bits are part of every fit's coefficients)."""
    keep = spread_subsample(cloud.points, max_points, rng=0) if len(cloud) > max_points else slice(None)
    return as_cloud(cloud.points[keep], cloud.oriented[keep], weights=None if cloud.weights is None
                    else cloud.weights[keep])


def _distances(design: tuple[NDArray, NDArray], coefficients: NDArray) -> NDArray[np.float64]:
    """Taubin distances |f|/||∇f|| at the rows of ``design`` (monomials, their gradients)."""
    m, dm = design
    grads = dm @ coefficients  # (dim, N)
    return np.abs(m @ coefficients) / np.maximum(np.sqrt(np.einsum("kn,kn->n", grads, grads)), _TINY)


def _reweighted(fitted: Cloud, poly: ImplicitPolynomial, degree: int, method: str, params, norm: Normalization,
                scale: float, design: tuple[NDArray, NDArray]) -> ImplicitPolynomial:
    """``poly`` (a linear fit on the weighted cloud ``fitted``) refitted by IRLS with Cauchy
    weights of width ``CAUCHY_C`` times the larger of ``scale`` and the spread of the current
    distances (module notes): the last fit."""
    base = cast(NDArray[np.float64], fitted.weights)
    a = poly.coefficients
    for _ in range(IRLS_ROUNDS):
        dist = _distances(design, a)
        width = CAUCHY_C * max(scale, float(np.median(dist[base > 0])) / _MEDIAN_TO_SIGMA)
        weights = base / (1.0 + (dist / width) ** 2)
        if not width > 0 or not np.isfinite(weights).all() or not weights.any():
            break
        try:
            new = fit_linear(Cloud._checked(fitted.points, fitted.unit_normals, None, weights), None, degree, method,
                             normalization=norm, **params)
        except IpfitError:  # a degenerate reweighted system: keep the last fit
            break
        moved = min(np.linalg.norm(new.coefficients - a), np.linalg.norm(new.coefficients + a))
        poly, a = new, new.coefficients
        if moved < _IRLS_TOLERANCE:
            break
    return poly


def _linear(cloud: Cloud, degree, norm: Normalization, fits: Sequence[StartFit], max_points: int,
            scale: float | None = None):
    labels, coefs, notes = [], [], []
    if len(cloud) > max_points:
        notes.append(f"start fits on a spread subsample of {max_points} of the {len(cloud)} points")
    # One cloud for every degree's start fits: it keeps the R factors they share.
    fitted = cloud.derived("start_fit_cloud", min(max_points, len(cloud)), lambda: _fitted_cloud(cloud, max_points))
    design = None
    if scale is not None and fitted.weights is not None:
        design = basis.monomials_and_gradients(norm.apply(fitted.points), degree)
        notes.append(f"start fits reweighted (Cauchy IRLS, scale {scale:.3g}, at most {IRLS_ROUNDS} rounds)")
    for spec, method, params in fits:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                poly = fit_linear(fitted, None, degree, method, normalization=norm, **params)
            except IpfitError as exc:
                notes.append(f"start fit {spec} failed: {exc}")
                continue
            if design is not None:
                poly = _reweighted(fitted, poly, degree, method, params, norm, cast(float, scale), design)
        notes.extend(f"start fit {spec}: {w.message}" for w in caught)
        if not np.allclose(poly.center, norm.center) or not np.isclose(poly.scale, norm.scale):
            # Linear fits normalise like Normalization.from_points; anything else is a bug.
            raise AssertionError(f"start fit {spec} uses another normalisation")
        labels.append(spec)
        coefs.append(poly.coefficients)
    return labels, coefs, notes


def _given(starts, dim: int, degree: int, norm: Normalization, d: int):
    labels, coefs = [], []
    if isinstance(starts, (str, ImplicitPolynomial)) or (isinstance(starts, np.ndarray) and starts.ndim == 1):
        raise error("starts", "a sequence of start polynomials", type(starts).__name__, "Wrap one start in a list.")
    for k, start in enumerate(starts):
        if isinstance(start, ImplicitPolynomial):
            if start.n_coefficients != d or start.dim != dim:
                raise error(f"starts[{k}]", f"a degree-{degree} {dim}D polynomial",
                            f"degree {start.degree} in {start.dim}D")
            if not (np.allclose(start.center, norm.center, rtol=1e-12, atol=1e-12 * norm.scale)
                    and np.isclose(start.scale, norm.scale, rtol=1e-12)):
                raise error(f"starts[{k}]", "a polynomial fitted to the same points (same normalisation)",
                            "another normalisation", "Fit it with ipfit's linear fits on these points.")
            labels.append(start.method or f"start{k}")
            coefs.append(start.coefficients)
        else:
            try:
                arr = np.asarray(start, dtype=np.float64)
            except (TypeError, ValueError):
                arr = np.empty(0)
            if arr.shape != (d,) or not np.isfinite(arr).all() or not np.any(arr):
                raise error(f"starts[{k}]", f"an ImplicitPolynomial or {d} finite coefficients (not all zero) in "
                            "the normalised coordinates", f"shape {arr.shape}")
            labels.append(f"start{k}")
            coefs.append(arr)
    return labels, coefs


def start_fits(cloud: Cloud, degree: int, norm: Normalization, fits: Sequence[StartFit],
               starts: Sequence[ImplicitPolynomial | ArrayLike] | None, far_term: bool,
               max_points: int = START_POINTS, scale: float | None = None) -> StartFits:
    """The user's polynomials first, then the linear start fits (parsed and checked by
    :meth:`ipfit.SearchOptions.for_method`) (3L with far-field rows added
    when the objective has a far-field term: it starts the search nearer clean zero sets),
    fitted on a well-spread subsample of at most ``max_points`` points of ``cloud`` (which
    needs unit normals). On a cloud with weights and a robust ``scale`` (normalised units),
    each linear fit is reweighted by its distances (module notes)."""
    d = basis.n_coefficients(cloud.dim, degree)
    labels, coefs = _given(starts, cloud.dim, degree, norm, d) if starts is not None else ([], [])
    fits = list(fits)
    if far_term and fits and FAR_START not in (fit.spec for fit in fits):
        fits.append(StartFit(f"{FAR_START}(far_row_weight={DEFAULT_FAR_ROW_WEIGHT:g})", FAR_START,
                             {"far_row_weight": DEFAULT_FAR_ROW_WEIGHT}))
    lin_labels, lin_coefs, notes = _linear(cloud, degree, norm, fits, max_points, scale)
    labels = [*labels, *(FAR_START if lab.startswith(FAR_START + "(") else lab for lab in lin_labels)]
    return StartFits(labels, np.array(coefs + lin_coefs).reshape(-1, d), notes)


def initial_population(start_y: NDArray, size: int, n_started: int, rng: np.random.Generator) -> NDArray:
    """Start fits first (the best ones exactly), the rest scattered around random start fits."""
    d = start_y.shape[1]
    pop = np.empty((size, d))
    n_exact = min(n_started, start_y.shape[0])
    pop[:n_exact] = start_y[:n_exact]
    # Extra started slots (more slots than distinct start fits) repeat them with a tiny jitter,
    # so DE's difference vectors between them are not zero.
    n_jitter = n_started - n_exact
    base = np.concatenate([np.arange(n_jitter) % start_y.shape[0],
                           rng.integers(start_y.shape[0], size=size - n_started)]).astype(np.int64)
    lo, hi = np.log(_SPREAD[0]), np.log(_SPREAD[1])
    scale = np.concatenate([np.full(n_jitter, _SPREAD[0]), np.exp(rng.uniform(lo, hi, size - n_started))])
    noise = rng.standard_normal((size - n_exact, d)) / np.sqrt(d)
    pop[n_exact:] = start_y[base] + scale[:, None] * noise
    return unit_rows(pop)

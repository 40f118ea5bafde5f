"""Linear implicit-polynomial fits: classic least squares, Taubin, 3L, 3L + ridge, gradient-one.

Every public ``fit_*`` function normalises the data (:class:`~ipfit.Normalization`),
builds its linear system in normalised coordinates, and hands it to a private solver with
the common signature ``_solve_<name>(problem, **params) -> (coefficients, info)``. The
result is a canonical :class:`~ipfit.ImplicitPolynomial` (unit coefficient norm, f > 0
outside) carrying the normalisation and the solver's diagnostics in ``info``.

Systems are solved by QR of the stacked (augmented) matrix and a small triangular solve,
never through the normal equations, whose condition number is the square of the system's.

Every fit takes arrays or a :class:`~ipfit.Cloud` as its points (then ``normals`` is None: the
cloud's own are used). A cloud keeps the R factors of the big row blocks, so the fits on one
cloud (the dozen start fits of a search) factor each block once. A cloud with ``weights`` is
fitted by weighted least squares: each point's rows (its level rows, its offset or gradient
rows) are scaled by the square root of its weight, so that a weight of 2 counts as the point
twice, a weight of 0 as no point; without weights the arithmetic is the unweighted one.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from math import factorial
from typing import cast

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.validation import (
    check_choice,
    check_degree,
    check_enough_points,
    check_nonnegative,
    check_positive,
    error,
)
from ..cloud import Cloud, as_cloud
from ..exceptions import ConditioningWarning
from ..polynomial import ImplicitPolynomial, Normalization
from .farfield import VOTERS, confident_mask, far_field_samples

__all__ = [
    "fit_lstsq",
    "fit_taubin",
    "fit_3l",
    "fit_ridge",
    "fit_gradient_one",
    "fit_linear",
    "LINEAR_METHODS",
    "LinearMethod",
    "check_params",
    "ridge_penalty",
    "DEFAULT_OFFSET",
    "DEFAULT_KAPPA",
    "DEFAULT_MU",
    "DEFAULT_FAR_ROW_WEIGHT",
    "far_field_samples",
]

#: 3L offset in normalised units (the data's mean distance to its centre is 1): small
#: enough that the offset sets do not fold over on the bundled shapes' tightest features.
DEFAULT_OFFSET = 0.05
#: Ridge weight κ relative to the per-row scale of the 3L system (see :func:`fit_ridge`).
DEFAULT_KAPPA = 1e-4
#: Gradient-one weight μ (Tasdizen et al. 2000). The gradient rows alone fix the scale of a,
#: so μ only trades zero-set accuracy against unit gradients: on an exact 3:1.2 ellipse at
#: degree 2 the largest zero-set error is 0.11 for μ = 1, 0.06 for 0.1 and 0.012 for 0.01.
DEFAULT_MU = 0.01
#: Default far-field row weight of the "3l-far" method: the far-field rows' share of the
#: system's total weight (see :func:`_with_far_field`). Not the objective's far-field *term*
#: weight (:attr:`ipfit.SearchOptions.far_term_weight`).
DEFAULT_FAR_ROW_WEIGHT = 1e-3
_RCOND = 1e-13  # relative singular-value cut-off of the triangular solves


def _r_factor(a: NDArray, overwrite: bool = False) -> NDArray:
    """The (n, n) triangular factor of A's QR (scipy returns it padded to A's row count)."""
    r = scipy.linalg.qr(a, mode="r", overwrite_a=overwrite, check_finite=False)[0]
    return r[: min(a.shape)].copy()  # a copy: a view would keep the padded (rows × n) array alive


@dataclass(frozen=True)
class _Problem:
    u: NDArray[np.float64]  # normalised points (N, dim)
    normals: NDArray[np.float64] | None  # unit normals (N, dim)
    normalization: Normalization
    degree: int
    cloud: Cloud | None = None  # the data in user coordinates, which keeps the R factors of its rows
    weights: NDArray[np.float64] | None = None  # per point, in [0, 1]; None: every point counts fully

    @property
    def dim(self) -> int:
        return self.u.shape[1]

    @property
    def exponents(self) -> NDArray[np.int64]:
        return basis.exponents(self.dim, self.degree)

    def design(self, pts: NDArray | None = None) -> NDArray[np.float64]:
        return basis.monomials(self.u if pts is None else pts, self.exponents)

    # What the solvers read of the cloud; a chunked cloud (ipfit.fitting.chunked) overrides them.
    @property
    def n_points(self) -> int:
        return len(self.u)

    @property
    def total_weight(self) -> float:
        """The data rows' weight per row family: the number of points, or the sum of their weights."""
        return self.n_points if self.weights is None else float(np.sum(self.weights))

    def root_weights(self, sl: slice) -> NDArray[np.float64] | None:
        """√w of the points ``sl`` (what their rows are scaled by), or None without weights."""
        return None if self.weights is None else np.sqrt(self.weights[sl])

    def blocks(self, make: Callable[..., Iterable[NDArray]], *args) -> Iterable[NDArray]:
        """The row blocks ``make(problem, *args)`` of the whole cloud (or blocks with the same R)."""
        return make(self, *args)

    def r_of(self, make: Callable[..., Iterable[NDArray]], *args) -> NDArray:
        """R of the rows ``make(problem, *args)``, kept by the cloud for the next fits on it: the
        start fits of a search solve a dozen systems that share their big blocks (3L and its
        ridge variants one, gradient-one's variants and least squares two), so each big QR is
        done once and each fit adds only its own small rows."""
        if self.cloud is None:
            return _r_of_blocks(self.blocks(make, *args))
        # The rows depend on the cloud, the coordinates it is fitted in, the degree and the blocks.
        key = (self.normalization.center.tobytes(), self.normalization.scale, self.degree, make.__name__, args)
        return self.cloud.derived("r_factor", key, lambda: _r_of_blocks(self.blocks(make, *args)))

    def power_sums(self, top: int) -> NDArray[np.float64]:
        """γ_t = Σ_i ||u_i||^{2t} for t = 0..top (the ridge penalty's weights)."""
        sq = np.einsum("ij,ij->i", self.u, self.u)
        if self.weights is not None:  # weighted like the rows the penalty is relative to
            return np.array([np.sum(self.weights * sq**t) for t in range(top + 1)])
        return np.array([np.sum(sq**t) for t in range(top + 1)])


def _prepare(points: ArrayLike | Cloud, normals: ArrayLike | None, degree, *, method: str,
             needs_normals: bool, normalization: Normalization | None = None) -> _Problem:
    degree = check_degree(degree)
    cloud = as_cloud(points, normals, required_by=method if needs_normals else None)
    pts = cloud.points
    check_enough_points(pts.shape[0], pts.shape[1], degree)
    if normalization is not None and (not isinstance(normalization, Normalization)
                                      or normalization.dim != pts.shape[1]):
        raise error("normalization", f"a {pts.shape[1]}D Normalization", repr(normalization))
    norm = Normalization.from_points(pts) if normalization is None else normalization
    return _Problem(norm.apply(pts), cloud.unit_normals, norm, degree, cloud, cloud.weights)


def _triangular_lstsq(r: NDArray, z: NDArray, method: str) -> tuple[NDArray, dict]:
    """Minimum-norm solution of R a = z for a small square R, with diagnostics (gelsd's own
    singular values: a second SVD for them cost as much as the solve)."""
    a, _, rank, sv = scipy.linalg.lstsq(r, z, cond=_RCOND, lapack_driver="gelsd")
    rank = int(rank)
    cond = float(sv[0] / sv[-1]) if sv.size and sv[-1] > 0 else float("inf")
    if rank < r.shape[1]:
        warnings.warn(f"{method}: the linear system is rank deficient (rank {rank} of {r.shape[1]}); "
                      "the solution is the minimum-norm one. Use more points, a lower degree or fit_ridge.",
                      ConditioningWarning, stacklevel=4)
    return a, {"condition_number": cond, "rank": rank}


# Rows per QR step on big systems: [R; next rows] is factorised in turn (a tall-skinny QR), so
# the full design matrix never exists. Systems with fewer rows take one QR, as before.
_BLOCK_ROWS = 1 << 17
_SIGN_POINTS = 50_000


def _r_of_blocks(blocks: Iterable[NDArray]) -> NDArray:
    """R of the row-stacked ``blocks``: one QR when they fit in ``_BLOCK_ROWS`` rows, else a
    running QR of [R; next blocks]."""
    pending, rows, r = [], 0, None
    for block in blocks:
        pending.append(block)
        rows += len(block)
        if rows >= _BLOCK_ROWS:
            r = _r_factor(np.concatenate(([] if r is None else [r]) + pending), overwrite=True)
            pending, rows = [], 0
    if pending or r is None:
        r = _r_factor(np.concatenate(([] if r is None else [r]) + pending), overwrite=True)
    return r


def _point_chunks(problem: _Problem, rows_per_point: int) -> Iterator[slice]:
    n = len(problem.u)
    step = max(1, _BLOCK_ROWS // rows_per_point)
    return (slice(start, min(start + step, n)) for start in range(0, n, step))


def _augmented(a_mat: NDArray, b: NDArray) -> NDArray:
    aug = np.empty((a_mat.shape[0], a_mat.shape[1] + 1))
    aug[:, :-1] = a_mat
    aug[:, -1] = b
    return aug


def _qr_solve(r_aug: NDArray, d: int, method: str, more: Iterable[NDArray] = (),
              extra_rows: NDArray | None = None) -> tuple[NDArray, dict]:
    """Least squares min ||A a − b||² (+ ||E a||²) from R of [A | b], R of [R; ``more``] when
    more rows of [A | b] are given (the R of stacked rows is that of their R's); Q is never formed."""
    more = list(more)
    if more:
        r_aug = _r_factor(np.concatenate([r_aug, *more]))
    r, z = r_aug[:d, :d], r_aug[:d, d]
    residual = float(abs(r_aug[d, d])) if r_aug.shape[0] > d else 0.0
    if extra_rows is not None:
        r = np.vstack([r, extra_rows])
        z = np.concatenate([z, np.zeros(extra_rows.shape[0])])
    coef, info = _triangular_lstsq(r, z, method)
    info["residual"] = residual
    return coef, info


# -- solvers (one signature) -----------------------------------------------------------
def _weighted(rows: NDArray, root: NDArray | None) -> NDArray:
    """``rows`` (one per point, or ``k`` per point in k consecutive runs of the points) scaled by
    the points' √w: weighted least squares as an ordinary one."""
    if root is None:
        return rows
    return rows * np.tile(root, len(rows) // len(root))[:, None]


def _lstsq_blocks(problem: _Problem) -> Iterator[NDArray]:
    return (_weighted(problem.design(problem.u[sl]), problem.root_weights(sl)) for sl in _point_chunks(problem, 1))


def _solve_lstsq(problem: _Problem) -> tuple[NDArray, dict]:
    # Minimise ||M a|| with ||a|| = 1: the right singular vector of the smallest singular value.
    _, sv, vt = np.linalg.svd(problem.r_of(_lstsq_blocks))
    info = {"condition_number": float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf"),
            "smallest_singular_value": float(sv[-1]),
            "singular_gap": float(sv[-1] / sv[-2]) if sv.size > 1 and sv[-2] > 0 else 0.0}
    return vt[-1], info


def _taubin_factors(problem: _Problem) -> tuple[NDArray, NDArray, NDArray]:
    """(mean of the non-constant monomials, them centred (or their R, for big clouds), R of their
    gradient rows)."""
    if len(problem.u) * (1 + problem.dim) <= _BLOCK_ROWS:
        m, dm = basis.monomials_and_gradients(problem.u, problem.degree)
        root = problem.root_weights(slice(None))
        if root is None:
            mean = m[:, 1:].mean(axis=0)
            return mean, m[:, 1:] - mean, _r_factor(dm[:, :, 1:].reshape(-1, m.shape[1] - 1))
        # weighted: the constant's optimum centres the columns on their weighted mean
        mean = problem.weights @ m[:, 1:] / problem.total_weight
        return mean, _weighted(m[:, 1:] - mean, root), _r_factor(_weighted(dm[:, :, 1:].reshape(-1, m.shape[1] - 1),
                                                                           root))

    # Big clouds: R of [1 | M₁] holds the column sums in its first row and the centred R below
    # (weighted: R of √w [1 | M₁] holds √Σw and the weighted sums over it, the weighted centring below).
    def blocks(gradients: bool):
        for sl in _point_chunks(problem, 1 + problem.dim):
            m, dm = basis.monomials_and_gradients(problem.u[sl], problem.degree)
            root = problem.root_weights(sl)
            yield _weighted(dm[:, :, 1:].reshape(-1, m.shape[1] - 1) if gradients else m, root)

    r1 = _r_of_blocks(blocks(False))
    return r1[0, 1:] / r1[0, 0], r1[1:, 1:], _r_of_blocks(blocks(True))


def _solve_taubin(problem: _Problem) -> tuple[NDArray, dict]:
    # Minimise Σ f² / Σ ||∇f||². The constant term has no gradient, so eliminate it first
    # (its optimum centres the other columns). Then whiten by the gradient rows' SVD,
    # restricted to the directions whose gradient on the data is not zero (on exact data a
    # square such as (x²+y²−1)² has none), which leaves an ordinary smallest-singular-vector
    # problem. R of (centred · W) is R of (R_centred · W), Q drops out, so big clouds pass R.
    mean, r_centred, r_grads = _taubin_factors(problem)
    _, sv_g, vt_g = np.linalg.svd(r_grads)
    keep = sv_g > 1e-10 * sv_g[0]
    whiten = vt_g[keep].T / sv_g[keep]
    _, sv, vt = np.linalg.svd(_r_factor(r_centred @ whiten))
    a1 = whiten @ vt[-1]
    coef = np.concatenate([[-mean @ a1], a1])
    info = {"condition_number": float(sv_g[0] / sv_g[keep][-1]), "eigenvalue": float(sv[-1] ** 2),
            "gradient_rank": int(keep.sum())}
    return coef, info


def _three_level_blocks(problem: _Problem, c: float) -> Iterator[NDArray]:
    normals = cast(NDArray[np.float64], problem.normals)  # 3L requires normals (_prepare checked them)
    for sl in _point_chunks(problem, 3):
        u, n = problem.u[sl], normals[sl]
        stacked = np.concatenate([u, u + c * n, u - c * n])
        targets = np.concatenate([np.zeros(len(u)), np.full(len(u), c), np.full(len(u), -c)])
        yield _weighted(_augmented(problem.design(stacked), targets), problem.root_weights(sl))


def _far_field_block(problem: _Problem, n_rows: float, far_row_weight: float, c: float) -> tuple[list, int]:
    """Far-field rows whose total weight is ``far_row_weight`` times the data rows' weight ``n_rows``."""
    if far_row_weight <= 0:
        return [], 0
    keep = confident_mask(problem.weights, problem.n_points)  # every point without weights
    robust = {} if problem.weights is None else {"voters": VOTERS}  # see farfield's notes
    samples, targets = far_field_samples(problem.u[keep], cast(NDArray, problem.normals)[keep], c=c, **robust)
    if len(samples) == 0:
        return [], 0
    root = np.sqrt(far_row_weight * n_rows / len(samples))
    return [_augmented(root * problem.design(samples), root * targets)], len(samples)


def _solve_3l(problem: _Problem, c: float = DEFAULT_OFFSET, far_row_weight: float = 0.0) -> tuple[NDArray, dict]:
    far, n_far = _far_field_block(problem, 3 * problem.total_weight, far_row_weight, c)
    d = basis.n_coefficients(problem.dim, problem.degree)
    coef, info = _qr_solve(problem.r_of(_three_level_blocks, c), d, "fit_3l", far)
    info.update(far_row_weight=far_row_weight, far_samples=n_far)
    return coef, info


def ridge_penalty(u: NDArray[np.float64], exps: NDArray[np.int64]) -> NDArray[np.float64]:
    """Diagonal D of the rotation-invariant ridge penalty aᵀDa (Tasdizen 2000; Sahin & Unel 2008).

    ``D_α = γ_{|α|} · α! / |α|!`` with ``γ_t = Σ_i ||u_i||^{2t}``: within each total degree
    this is the Bombieri norm, which no rotation changes.
    """
    sq = np.einsum("ij,ij->i", u, u)
    return _ridge_diagonal(np.array([np.sum(sq**t) for t in range(int(exps.sum(axis=1).max()) + 1)]), exps)


def _ridge_diagonal(gamma: NDArray, exps: NDArray[np.int64]) -> NDArray[np.float64]:
    total = exps.sum(axis=1)
    fact = np.array([factorial(int(k)) for k in range(int(total.max()) + 1)], dtype=float)
    multinomial_inverse = np.prod(fact[exps], axis=1) / fact[total]
    return gamma[total] * multinomial_inverse


def _solve_ridge(problem: _Problem, c: float = DEFAULT_OFFSET, kappa: float = DEFAULT_KAPPA,
                 far_row_weight: float = 0.0) -> tuple[NDArray, dict]:
    far, n_far = _far_field_block(problem, 3 * problem.total_weight, far_row_weight, c)
    penalty = _ridge_diagonal(problem.power_sums(problem.degree), problem.exponents)
    coef, info = _qr_solve(problem.r_of(_three_level_blocks, c), len(penalty), "fit_ridge", far,
                           extra_rows=np.diag(np.sqrt(kappa * penalty)))
    info.update(kappa=kappa, far_row_weight=far_row_weight, far_samples=n_far)
    return coef, info


def _gradient_blocks(problem: _Problem) -> Iterator[NDArray]:
    """Rows [∂M/∂x_k | n_k]: the gradient-one rows before their weight √μ."""
    normals = cast(NDArray[np.float64], problem.normals)  # gradient-one requires normals (_prepare checked them)
    for sl in _point_chunks(problem, problem.dim):
        m, dm = basis.monomials_and_gradients(problem.u[sl], problem.degree)
        # dm is (dim, n, d): the rows run over the points once per coordinate
        yield _weighted(_augmented(dm.reshape(-1, m.shape[1]), normals[sl].T.ravel()), problem.root_weights(sl))


def _solve_gradient_one(problem: _Problem, mu: float = DEFAULT_MU, far_row_weight: float = 0.0,
                        c: float = DEFAULT_OFFSET) -> tuple[NDArray, dict]:
    n_rows = problem.total_weight * (1 + problem.dim)
    far, n_far = _far_field_block(problem, n_rows, far_row_weight, c)
    d = basis.n_coefficients(problem.dim, problem.degree)
    # R of [M | 0; √μ ∂M | √μ n] is R of [R_M | 0; √μ R_∂]: every μ reuses the two big factors.
    values = problem.r_of(_lstsq_blocks)
    values = np.hstack([values, np.zeros((len(values), 1))])
    coef, info = _qr_solve(values, d, "fit_gradient_one", [np.sqrt(mu) * problem.r_of(_gradient_blocks), *far])
    info.update(mu=mu, far_row_weight=far_row_weight, far_samples=n_far)
    return coef, info


def _offset(c: float) -> float:
    c = check_positive(c, "c")
    if c > _MAX_OFFSET:
        raise error("c", f"an offset in (0, {_MAX_OFFSET:g}] normalised units (the data's mean distance to its "
                    "centre is 1)", f"{c:g}", f"The default is {DEFAULT_OFFSET}.")
    return c


def _bounded(value: float, name: str, largest: float) -> float:
    value = check_nonnegative(value, name)
    if value > largest:
        raise error(name, f"a number in [0, {largest:g}]", f"{value:g}")
    return value


# Offsets larger than the shape put the 3L levels on the other side of it.
_MAX_OFFSET = 10.0


def _far_row_weight(value: float) -> float:
    return _bounded(value, "far_row_weight", 1e6)


@dataclass(frozen=True)
class LinearMethod:
    """One linear fit method: its solver, whether it needs normals, and its parameters (name →
    check returning the checked value), the one list of what ``fit_linear``, the start fits
    (``"ridge(kappa=1e-6)"``) and ``fit_chunked`` accept."""

    solve: Callable[..., tuple[NDArray, dict]]
    needs_normals: bool
    params: Mapping[str, Callable[[float], float]] = field(default_factory=dict)
    defaults: tuple[tuple[str, float], ...] = ()


_3L_PARAMS = {"c": _offset, "far_row_weight": _far_row_weight}
#: The linear fit methods by name: the one registry (see docs/architecture.md, "A linear fit method").
LINEAR_METHODS: dict[str, LinearMethod] = {
    "lstsq": LinearMethod(_solve_lstsq, needs_normals=False),
    "taubin": LinearMethod(_solve_taubin, needs_normals=False),
    "3l": LinearMethod(_solve_3l, needs_normals=True, params=_3L_PARAMS),
    "ridge": LinearMethod(_solve_ridge, needs_normals=True,
                          params={"c": _offset, "kappa": lambda v: _bounded(v, "kappa", 1e12),
                                  "far_row_weight": _far_row_weight}),
    "gradient_one": LinearMethod(_solve_gradient_one, needs_normals=True,
                                 params={"mu": lambda v: check_positive(_bounded(v, "mu", 1e12), "mu"), "c": _offset,
                                         "far_row_weight": _far_row_weight}),
    "3l-far": LinearMethod(_solve_3l, needs_normals=True, params=_3L_PARAMS,
                           defaults=(("far_row_weight", DEFAULT_FAR_ROW_WEIGHT),)),
}


def check_params(method: str, params: Mapping[str, float]) -> dict[str, float]:
    """``params`` of the registered linear ``method``, each checked by the method's own check."""
    checks = LINEAR_METHODS[method].params
    for name in params:
        if name not in checks:
            allowed = ", ".join(checks) or "no parameters"
            raise error(name, f"a parameter of the {method!r} fit ({allowed})", "an unknown name")
    return {name: checks[name](value) for name, value in params.items()}


def _fit(method: str, points, normals, degree, normalization=None, **params) -> ImplicitPolynomial:
    params = check_params(method, params)
    spec = LINEAR_METHODS[method]
    problem = _prepare(points, normals, degree, method=f"fit_{method}", needs_normals=spec.needs_normals,
                       normalization=normalization)
    return _fit_problem(method, problem, params)


def _fit_problem(method: str, problem: _Problem, params: dict, **extra_info) -> ImplicitPolynomial:
    """Solve a prepared problem with checked parameters (also used by :mod:`ipfit.fitting.chunked`)."""
    spec = LINEAR_METHODS[method]
    try:
        with np.errstate(all="ignore"):
            coef, info = spec.solve(problem, **{**dict(spec.defaults), **params})
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError, ValueError) as exc:
        raise error("points", "data whose linear system can be solved", f"a {method} system that failed ({exc})",
                    "Check the points, the normals, the degree and the method's parameters.") from None
    if not np.isfinite(coef).all() or not np.any(coef):
        raise error("points", "data that determine a polynomial", f"a degenerate {method} system",
                    "Check the points, the normals and the degree.")
    poly = ImplicitPolynomial(problem.exponents, coef, problem.normalization, method=method,
                              info={**info, **extra_info})
    if problem.normals is not None:
        # The sign only needs the normals' overall agreement: every k-th point of a big cloud
        # (all points up to _SIGN_POINTS) keeps the gradients' memory bounded.
        every = slice(None, None, max(1, len(problem.u) // _SIGN_POINTS))
        normals = problem.normals[every]
        if problem.weights is not None:  # the agreement of the points that count, as much as they count
            normals = normals * problem.weights[every, None]
        return poly.canonical(problem.normalization.invert(problem.u[every]), normals)
    return poly.canonical()


def fit_lstsq(points: ArrayLike, normals: ArrayLike | None = None, degree: int | None = None) -> ImplicitPolynomial:
    """Classic linear fit (paper, Section 2.2): minimise ||M a|| subject to ||a|| = 1.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array
    normals : optional (N, dim) array, only used to choose the sign (f > 0 outside).
    degree : int >= 1

    Returns
    -------
    ImplicitPolynomial
        ``info`` holds the condition number and the smallest singular value.

    Examples
    --------
    >>> from ipfit import fit_lstsq
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(50, radius=2.0, center=(1.0, -1.0))
    >>> poly = fit_lstsq(shape.points, degree=2)
    >>> bool(abs(poly([[3.0, -1.0]])[0]) < 1e-9)
    True
    """
    return _fit("lstsq", points, normals, degree)


def fit_taubin(points: ArrayLike, normals: ArrayLike | None = None, degree: int | None = None) -> ImplicitPolynomial:
    """Taubin's fit: the generalised eigenproblem MᵀM a = λ (Σ_k M_kᵀ M_k) a (Taubin 1991).

    The constant term has zero gradient, making the right-hand matrix singular; it is
    eliminated analytically, which leaves a regular problem in the other coefficients.

    >>> from ipfit import fit_taubin
    >>> from ipfit.datasets.synthetic import ellipse
    >>> poly = fit_taubin(ellipse(60).points, degree=2)
    >>> bool(abs(poly([[2.0, 0.0]])[0]) < 1e-9)
    True
    """
    return _fit("taubin", points, normals, degree)


def fit_3l(points: ArrayLike, normals: ArrayLike, degree: int, c: float = DEFAULT_OFFSET,
           far_row_weight: float = 0.0) -> ImplicitPolynomial:
    """The 3L algorithm (Blane et al. 2000).

    Each point is offset by ±c along its unit normal (c in normalised units, where the
    data's mean distance to its centre is 1); the targets are +c outside, 0 on the data and
    −c inside, and the 3N×d system is solved by QR.

    ``far_row_weight > 0`` adds far-field rows (:func:`far_field_samples`): grid samples of
    the box away from the data whose target is their signed distance to the data, with that
    share of the system's total weight. They keep the zero set from growing extra sheets
    away from the data; 0 (the default) is the paper's 3L.

    >>> from ipfit import fit_3l
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(80)
    >>> poly = fit_3l(shape.points, shape.normals, degree=2)
    >>> # 3L is close, not exact: level sets ±c of x²+y²−1 are not at distance c
    >>> bool(abs(poly([[1.0, 0.0]])[0]) < 1e-2)
    True
    """
    return _fit("3l", points, normals, degree, c=c, far_row_weight=far_row_weight)


def fit_ridge(points: ArrayLike, normals: ArrayLike, degree: int, kappa: float = DEFAULT_KAPPA,
              c: float = DEFAULT_OFFSET, far_row_weight: float = 0.0) -> ImplicitPolynomial:
    """3L with ridge regression: a = argmin ||A a − b||² + κ aᵀDa (paper, Section 5.5).

    ``D`` is :func:`ridge_penalty` (rotation invariant). Because γ_t sums over the N data
    points like the 3N rows of A do, κ is relative to the per-point scale of the system:
    κ = 0 is plain 3L.

    >>> from ipfit import fit_ridge
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(80)
    >>> poly = fit_ridge(shape.points, shape.normals, degree=4, kappa=1e-6)
    >>> bool(abs(poly([[0.0, 1.0]])[0]) < 1e-3)
    True
    """
    return _fit("ridge", points, normals, degree, c=c, kappa=kappa, far_row_weight=far_row_weight)


def fit_gradient_one(points: ArrayLike, normals: ArrayLike, degree: int, mu: float = DEFAULT_MU,
                     far_row_weight: float = 0.0) -> ImplicitPolynomial:
    """Tasdizen's gradient-one fit: minimise Σ f(x_i)² + μ Σ ||∇f(x_i) − n_i||².

    Asking ∇f to equal the unit normal on the data makes f close to a signed distance there.

    >>> from ipfit import fit_gradient_one
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(80, radius=3.0)
    >>> poly = fit_gradient_one(shape.points, shape.normals, degree=2)
    >>> bool(abs(poly([[3.0, 0.0]])[0]) < 1e-9)
    True
    """
    return _fit("gradient_one", points, normals, degree, mu=mu, far_row_weight=far_row_weight)


def fit_linear(points: ArrayLike | Cloud, normals: ArrayLike | None, degree: int, method: str = "3l", *,
               normalization: Normalization | None = None, **params: float) -> ImplicitPolynomial:
    """Dispatch to one of :data:`LINEAR_METHODS` by name (``'lstsq'``, ``'taubin'``, ``'3l'``,
    ``'ridge'``, ``'gradient_one'``, or ``'3l-far'``: 3L with far-field rows at the default
    row weight), with that method's parameters (``c``, ``kappa``, ``mu``, ``far_row_weight``).

    ``normalization`` fits in given normalised coordinates instead of the points' own (e.g.
    on a subsample, in the coordinates of the whole cloud). ``points`` may be a
    :class:`~ipfit.Cloud` (with ``normals`` None), which keeps the big R factors for the next fit.

    >>> from ipfit import fit_linear
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(40)
    >>> fit_linear(shape.points, shape.normals, 2, "ridge", kappa=0.0).method
    'ridge'
    """
    method = check_choice(method, "method", LINEAR_METHODS)
    return _fit(method, points, normals, degree, normalization, **params)

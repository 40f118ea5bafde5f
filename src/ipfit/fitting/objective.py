"""The paper's measures (Eq. 2-4) and the objective minimised by :func:`ipfit.refine` (Eq. 5).

For coefficients ``a`` and points x_i with unit normals n_i:

* dissimilarity  = (1/N) Σ |f(x_i)| / ||∇f(x_i)||            (mean Taubin distance, Eq. 2)
* smoothness     = (1/N) Σ ∇f(x_i)·n_i / ||∇f(x_i)||          (mean cosine, Eq. 3)
* distance       = dissimilarity + δ (1 − smoothness)          (Eq. 4, the objective of Eq. 5)

All three are unchanged when ``a`` is multiplied by a positive constant.

A whole population A (P × d) is evaluated at once. With M the N × d monomial matrix, f = M Aᵀ,
and because ∂f/∂x_k = m_{g−1}(x)ᵀ (D_k a), the gradients are products with the narrower
N × d_{g−1} matrix L (the first d_{g−1} columns of M in the graded order) after a gather
D_k Aᵀ. Points are processed in blocks: two BLAS products per block, then a compiled
per-point reduction while the block is still in cache (:mod:`ipfit.fitting._objective_kernels`).
The samples of a :class:`~ipfit.fitting.farfield.FarFieldTerm` passed in ``terms`` are extra rows of
the same pass (their own reduction), so the term costs what as many data points cost.

Memory: the design matrix is kept between evaluations only while it is small
(:data:`CACHE_BYTES`); beyond that every block builds its rows from the points when it needs
them, so a million points never need the N × d matrix, in the population pass, the measures,
the analytic gradient or the whitening.

Threads: with :mod:`threadpoolctl` installed, the blocks are shared between ``threads``
worker threads (default: the usable cores) that each run single-threaded BLAS and the
reduction (which releases the GIL). Multithreaded BLAS on small blocks was measured to stall
badly as soon as another process competes for the cores (its threads spin-wait for each
other), and numpy and SciPy each bundle their own OpenBLAS whose idle threads compete too.
Without threadpoolctl the blocks run one after the other with BLAS's own threads. The
single-member pass of the polish (:meth:`Objective.value_and_grad`, no BLAS) runs on the calling
thread while the design is kept, and shares its blocks between the worker threads when the
design is rebuilt at every evaluation (a cloud of more than a few hundred thousand points
fitted on all of them, as ``SearchOptions(fit_points=None)`` asks).

Points where ∇f = 0: the cosine is 0 there and the Taubin term is :data:`TAUBIN_CAP` (0 if
f = 0 too, a singular point on the curve). Each point's Taubin term is capped at
:data:`TAUBIN_CAP` so that the mean stays finite; the cap is far beyond any distance that
matters for data normalised to unit mean radius.

Robust loss: with per-point ``weights`` w_i the measures are weighted means, Σ w_i t_i / Σ w_i,
and a smaller ``cap`` truncates the Taubin term, min(|f|/||∇f||, cap): a point farther from
the zero set than the cap adds a constant, so it stops pulling the zero set towards it (a
truncated L1 loss; the cosine term stays, bounded by 2δ per point). Weights all 1 and the
default cap are the paper's measures, to the bit.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Protocol, cast, runtime_checkable

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.threads import default_threads
from .._utils.validation import (
    as_normals,
    as_points,
    as_weights,
    check_degree,
    check_nonnegative,
    check_positive,
    error,
)
from ..polynomial import ImplicitPolynomial
from .farfield import FarFieldTerm, fused_rows

if TYPE_CHECKING:
    from ..polynomial import Normalization

__all__ = ["Measures", "measures", "Objective", "ObjectiveTerm", "TAUBIN_CAP", "DEFAULT_DELTA",
           "single_threaded_blas", "default_threads"]

#: The paper's penalty weight δ (Section 5.3).
DEFAULT_DELTA = 0.25
#: Upper bound of one point's Taubin term |f|/||∇f||, in the evaluation coordinates.
TAUBIN_CAP = 1e10
# Squared-gradient floor: below it ∇f counts as zero (scale-free in practice: a unit-norm
# coefficient vector never produces such gradients except where they vanish exactly).
_TINY = float(np.finfo(np.float64).tiny)
# Below this squared gradient norm a point contributes nothing to the analytic gradient: its
# terms scale like 1/||∇f||³ and would overflow (the value itself stays well defined).
_GRAD_FLOOR = 1e-100
# Block size target in bytes for the (rows × (1 + dim)·P) products: keeps a block's products
# in L2/L3 between the BLAS call and the reduction, while blocks stay tall enough for BLAS.
_BLOCK_BYTES = 4 << 20
_MIN_ROWS, _MAX_ROWS = 256, 4096
# Smallest block when a small evaluation is split between the worker threads (a population of
# hundreds of members keeps the products efficient on such blocks).
_MIN_SPLIT_ROWS = 64
# Below this many multiply-adds per evaluation (about a millisecond) the worker threads' hand-off
# costs more than it saves: small evaluations run on the calling thread.
_THREAD_WORK = 4_000_000
#: Design matrices up to this size (bytes) are kept between evaluations; bigger ones are
#: rebuilt block by block on every evaluation (from the power table: a few percent of a pass).
CACHE_BYTES = 256 << 20
# Points per block of the single-member gradient pass: 2^13 rows of a degree-8
# 3D matrix are 11 MB, tall enough for BLAS to run at speed.
_SINGLE_ROWS = 1 << 13


@lru_cache(maxsize=1)
def _controller():
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # optional: without it, evaluation stays serial (see the module notes)
        return None
    return ThreadpoolController()


def single_threaded_blas():
    """Context manager limiting every loaded BLAS to one thread (no-op without threadpoolctl).

    Used around code that alternates many small BLAS calls (the polish, the population loop)
    or that parallelises over blocks itself.
    """
    ctl = _controller()
    return ctl.limit(limits=1, user_api="blas") if ctl is not None else contextlib.nullcontext()


_POOLS: dict[tuple[int, int], ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    # Keyed by process id too: a forked child inherits the pool object but not its threads.
    key = (os.getpid(), workers)
    with _POOLS_LOCK:
        if key not in _POOLS:
            _POOLS[key] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="ipfit-objective")
        return _POOLS[key]


@dataclass(frozen=True, eq=False)
class Measures:
    """The paper's measures of one polynomial (floats) or of a population ((P,) arrays).

    Attributes
    ----------
    dissimilarity : mean Taubin distance |f|/||∇f|| (Eq. 2), in the evaluation coordinates
        (a polynomial's own normalised coordinates for :func:`measures` on an
        :class:`~ipfit.ImplicitPolynomial`).
    smoothness : mean cosine between ∇f and the unit normals (Eq. 3), in [−1, 1].
    distance : ``dissimilarity + delta * (1 - smoothness)`` (Eq. 4).
    delta : the penalty weight δ used.
    """

    dissimilarity: float | NDArray[np.float64]
    smoothness: float | NDArray[np.float64]
    distance: float | NDArray[np.float64]
    delta: float

    def to_dict(self) -> dict:
        """``{"dissimilarity", "smoothness", "distance", "delta"}`` as JSON-ready numbers (lists
        for a population)."""
        def plain(value):
            return value.tolist() if isinstance(value, np.ndarray) else float(value)

        return {"dissimilarity": plain(self.dissimilarity), "smoothness": plain(self.smoothness),
                "distance": plain(self.distance), "delta": float(self.delta)}

    def __getitem__(self, index) -> Measures:
        """The measures of population member(s) ``index``."""
        pick = (lambda v: v[index]) if np.ndim(self.distance) else (lambda v: v)
        out = Measures(pick(self.dissimilarity), pick(self.smoothness), pick(self.distance), self.delta)
        if np.ndim(out.distance) == 0:
            return Measures(float(out.dissimilarity), float(out.smoothness), float(out.distance), self.delta)
        return out


@runtime_checkable
class ObjectiveTerm(Protocol):
    """An extra term added to the paper's distance (for example a far-field penalty).

    A term must be invariant to positive scaling of the coefficients, like the distance, and
    vectorised over a population. With no terms, :class:`Objective` is the paper's Eq. 5.
    """

    def __call__(self, population: NDArray[np.float64]) -> NDArray[np.float64]:
        """(P, d) coefficients → (P,) values."""

    def value_and_grad(self, coefficients: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        """Value and gradient (d,) for one coefficient vector."""


def _check_dtype(dtype) -> np.dtype:
    try:
        dt = np.dtype(dtype)
    except TypeError:
        dt = None
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise error("dtype", "numpy.float64 or numpy.float32", repr(dtype),
                    "Use float32 only for fast population screening; final measures use float64.")
    return dt


class Objective:
    r"""The paper's distance (Eq. 5) on fixed data, for whole populations of coefficients.

    Build it once per (points, normals, degree, δ, dtype); the monomial matrix is computed
    once and reused by every evaluation while it fits in :data:`CACHE_BYTES`, and otherwise
    rebuilt block by block (bounded memory for any number of points).

    Parameters
    ----------
    u : (N, dim) array
        Points in the coordinates of the coefficients (for fits: normalised coordinates,
        see :meth:`from_data`).
    normals : (N, dim) array
        Normals at the points; normalised to unit length here.
    degree : int
        Polynomial degree g; coefficient vectors have d = C(g + dim, dim) entries.
    delta : float, default 0.25
        Penalty weight δ of the smoothness term.
    dtype : numpy.float64 or numpy.float32
        Precision of the products. float32 about doubles the throughput; on the bundled bunny
        and butterfly, populations around a 3L fit had distances within 5e-5 (relative) of
        float64 up to degree 10 and the same ranking (Spearman ≥ 0.9999), which is what a
        metaheuristic needs. Sums are accumulated in float64 either way, and
        :meth:`value_and_grad` always works in float64.
    terms : sequence of :class:`ObjectiveTerm`
        Extra terms added to the distance in :meth:`__call__` and :meth:`value_and_grad`;
        empty (default) gives exactly the paper's objective, and so does a
        :class:`~ipfit.fitting.farfield.FarFieldTerm` of weight 0. Far-field terms (same degree) are
        evaluated as extra rows of the compiled pass; :meth:`measures` never includes terms.
    threads : int, optional
        Worker threads for population evaluation (default: the usable cores); used only when
        :mod:`threadpoolctl` is installed and an evaluation spans several blocks and about a
        millisecond of work. Results are reproducible for a given value (fixed partition,
        fixed summation order).
    weights : (N,) array in [0, 1], optional
        Per-point weights: the dissimilarity and smoothness become weighted means
        Σ w_i t_i / Σ w_i (in :meth:`__call__`, :meth:`measures` and :meth:`value_and_grad`).
        None (default): every point counts fully, the paper's means.
    cap : float, default :data:`TAUBIN_CAP`
        Truncation of each point's Taubin term |f|/||∇f|| (evaluation coordinates): a point
        beyond it adds ``cap`` whatever the fit does (a robust loss). The default truncates
        nothing that matters (the paper's measures).

    Examples
    --------
    >>> import numpy as np
    >>> from ipfit.datasets.synthetic import circle
    >>> shape = circle(16)
    >>> obj = Objective(shape.points, shape.normals, degree=2)
    >>> exact = shape.polynomial.coefficients
    >>> np.round(obj(np.stack([exact, 3.0 * exact, -exact])), 12).tolist()
    [0.0, 0.0, 0.5]
    """

    def __init__(self, u: ArrayLike, normals: ArrayLike, degree: int, delta: float = DEFAULT_DELTA, *,
                 dtype=np.float64, terms: Sequence[ObjectiveTerm] = (), threads: int | None = None,
                 weights: ArrayLike | None = None, cap: float = TAUBIN_CAP) -> None:
        pts = as_points(u, "points")
        self.normals64 = as_normals(normals, pts, required_by="the smoothness measure")
        self.degree = check_degree(degree)
        self.delta = check_nonnegative(delta, "delta")
        self.dtype = _check_dtype(dtype)
        self.terms = tuple(terms)
        if threads is None:
            threads = default_threads()
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise error("threads", "an integer >= 1 or None", repr(threads))
        self.threads = int(threads)
        for term in self.terms:
            if not isinstance(term, ObjectiveTerm):
                raise error("terms", "objects with __call__(population) and value_and_grad(a)",
                            type(term).__name__)
        self.cap = check_positive(cap, "cap")
        if self.cap > TAUBIN_CAP:
            raise error("cap", f"a number in (0, {TAUBIN_CAP:g}]", f"{self.cap:g}")
        self.weights = None if weights is None else as_weights(weights, len(pts))
        # Kernels take an array either way; ones leave every sum as it is (x · 1.0 is exact), and
        # their sum is N exactly, so unweighted measures are the paper's to the bit.
        self._weights = np.ones(len(pts)) if self.weights is None else self.weights
        self._total = float(len(pts)) if self.weights is None else float(np.sum(self.weights))
        self.u = pts
        self.dim = pts.shape[1]
        self.n_points = pts.shape[0]
        self.n_coefficients = basis.n_coefficients(self.dim, self.degree)
        self.n_lower = basis.n_coefficients(self.dim, self.degree - 1)
        self._exps = basis.exponents(self.dim, self.degree)
        # The graded order puts every monomial of degree <= g-1 first, so the derivative
        # design matrix L is a column slice of M: no second matrix to build or store.
        cached = self.n_points * self.n_coefficients * self.dtype.itemsize <= CACHE_BYTES
        self._m = basis.monomials(pts, self._exps).astype(self.dtype, copy=False) if cached else None
        self._normals = np.ascontiguousarray(self.normals64, dtype=self.dtype)
        self._far = fused_rows(self.terms, self.dim, self.degree, self.dtype)
        # Terms outside the compiled pass; a far-field term of weight 0 is dropped altogether,
        # so that the objective is then the paper's, bit for bit.
        self._extra = tuple(t for t in self.terms if not isinstance(t, FarFieldTerm))
        # The far rows of the polish's float64 pass (none: empty, so that the pass needs no branch).
        far64 = self._far if self.dtype == np.float64 else fused_rows(self.terms, self.dim, self.degree, np.float64)
        self._far64 = far64 or (np.empty((0, self.n_coefficients)), np.empty(0), np.empty(0))
        self._member_rows: NDArray[np.float64] | None = None
        self._whitening: NDArray[np.float64] | None = None
        self._agreement: NDArray[np.float64] | None = None

    # -- construction from raw data ---------------------------------------------------------
    @classmethod
    def from_data(cls, points: ArrayLike, normals: ArrayLike, degree: int, delta: float = DEFAULT_DELTA,
                  **kwargs) -> Objective:
        """Normalise ``points`` with :meth:`Normalization.from_points` (as the linear fits do)
        and build the objective in those coordinates; ``.normalization`` records the map."""
        from ..polynomial import Normalization

        pts = as_points(points)
        norm = Normalization.from_points(pts)
        obj = cls(norm.apply(pts), as_normals(normals, pts, required_by="the smoothness measure"), degree,
                  delta, **kwargs)
        obj.normalization = norm
        return obj

    normalization: Normalization | None = None  #: set by :meth:`from_data`

    # -- population evaluation ----------------------------------------------------------------
    def _population(self, population: ArrayLike) -> NDArray:
        arr = np.asarray(population, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != self.n_coefficients:
            raise error("population", f"a (P, {self.n_coefficients}) array of coefficient vectors",
                        f"shape {np.shape(population)}",
                        f"Degree {self.degree} in {self.dim}D has {self.n_coefficients} coefficients.")
        if not np.isfinite(arr).all():
            raise error("population", "finite coefficients", "NaN or inf")
        return arr

    def block_rows(self, n_members: int) -> int:
        """Points per block for a population of ``n_members``."""
        per_row = (1 + self.dim) * n_members * self.dtype.itemsize
        return int(min(max(_BLOCK_BYTES // max(per_row, 1), _MIN_ROWS), _MAX_ROWS))

    def sums(self, population: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Per-member Σ_i w_i Taubin term and Σ_i w_i cosine over the points (the fused kernel)."""
        sums = self._sums(self._population(population))
        return sums[0], sums[1]

    def _design(self, lo: int, hi: int, dtype) -> NDArray:
        """Rows lo:hi of the design matrix M, from the cache or built from the points."""
        if self._m is not None and self._m.dtype == dtype:
            return self._m[lo:hi]
        return basis.monomials(self.u[lo:hi], self._exps).astype(dtype, copy=False)

    def _sums(self, a: NDArray, data: bool = True, far: bool = False) -> NDArray[np.float64]:
        """(3, P): Σ Taubin, Σ cosine over the data, and the far-field term, in one pass (the
        parts not asked for stay 0)."""
        n_members = a.shape[0]
        at = np.ascontiguousarray(a.T, dtype=self.dtype)  # (d, P)
        bt = basis.gradient_coefficients(at, self.dim, self.degree)  # (d_{g-1}, dim·P)
        spans = [(False, self.n_points)] if data else []
        if far and self._far is not None:
            spans.append((True, len(self._far[0])))
        n_rows = sum(n for _, n in spans)
        workers = self.threads if _controller() is not None else 1
        if n_rows * n_members * (self.n_coefficients + self.dim * self.n_lower) < _THREAD_WORK:
            workers = 1
        rows = self.block_rows(n_members)
        if workers > 1:  # every part in at least as many blocks as workers, so each keeps them all busy
            rows = min(rows, max(_MIN_SPLIT_ROWS, -(-max(n for _, n in spans) // workers)))
        jobs = [(is_far, lo, hi) for is_far, n in spans for lo, hi in basis.point_blocks(n, rows)]
        workers = min(workers, len(jobs))
        if workers == 1:
            return self._partial_sums(at, bt, jobs, rows)
        # Every workers-th block per worker (data and far-field blocks shared alike), summed in a
        # fixed order: reproducible.
        with single_threaded_blas():
            futures = [_pool(workers).submit(self._partial_sums, at, bt, jobs[k::workers], rows)
                       for k in range(workers)]
            parts = [f.result() for f in futures]
        total = parts[0]
        for part in parts[1:]:
            total += part
        return total

    def _partial_sums(self, at: NDArray, bt: NDArray, jobs, rows: int) -> NDArray[np.float64]:
        from ._objective_kernels import reduce_far_field, reduce_population

        n_members = at.shape[1]
        values = np.empty((rows, n_members), dtype=self.dtype)
        grads = np.empty((rows, self.dim * n_members), dtype=self.dtype)
        sums = np.zeros((3, n_members))
        # far-field jobs exist only when there are far-field rows (_sums)
        far = cast(tuple[NDArray, NDArray, NDArray], self._far)
        for is_far, lo, hi in jobs:
            n = hi - lo
            m = far[0][lo:hi] if is_far else self._design(lo, hi, self.dtype)
            np.matmul(m, at, out=values[:n])
            np.matmul(m[:, : self.n_lower], bt, out=grads[:n])
            if is_far:
                reduce_far_field(values[:n], grads[:n], far[1][lo:hi], far[2][lo:hi], _TINY, sums[2])
            else:
                reduce_population(values[:n], grads[:n], self._normals[lo:hi], self._weights[lo:hi], _TINY, self.cap,
                                  sums[0], sums[1])
        return sums

    def measures(self, population: ArrayLike) -> Measures:
        """:class:`Measures` of every member, as (P,) float64 arrays (the data only, no terms)."""
        sums = self._sums(self._population(population))
        return self._measures(sums)

    def _measures(self, sums: NDArray[np.float64]) -> Measures:
        dissim = sums[0] / self._total
        smooth = sums[1] / self._total
        return Measures(dissim, smooth, dissim + self.delta * (1.0 - smooth), self.delta)

    def __call__(self, population: ArrayLike, bound: ArrayLike | None = None) -> NDArray[np.float64]:
        """(P, d) coefficients → (P,) objective values (the distance plus any extra terms).

        ``bound`` ((P,), optional) are values the caller only needs to know whether each member
        beats, as a DE selection does with the parents' values. A member whose distance (plus
        the terms outside the compiled pass) already exceeds its bound then gets that value, a
        lower bound of its objective since the far-field term is >= 0, and the far-field rows
        are evaluated for the other members only. Most trials of a search lose to their
        parents on the data alone, so the term then costs a fraction of its full price; every
        value at or below its bound is exact.
        """
        a = self._population(population)
        if bound is None or self._far is None:
            sums = self._sums(a, far=True)
            # a population's measures: (P,) arrays
            value = cast(NDArray[np.float64], self._measures(sums).distance)
            if self._far is not None:
                value = value + sums[2]
            return self._plus_extra(a, value)
        bound = np.asarray(bound, dtype=np.float64)
        if bound.shape != (a.shape[0],):
            raise error("bound", f"a ({a.shape[0]},) array, one value per member", f"shape {bound.shape}")
        value = self._plus_extra(a, cast(NDArray[np.float64], self._measures(self._sums(a)).distance))
        contenders = np.flatnonzero(value <= bound)
        if contenders.size:
            value[contenders] += self._sums(a[contenders], data=False, far=True)[2]
        return value

    def _plus_extra(self, a: NDArray, value: NDArray[np.float64]) -> NDArray[np.float64]:
        for term in self._extra:
            value = value + np.asarray(term(a), dtype=np.float64)
        return value

    # -- conditioning ------------------------------------------------------------------------------
    def whitening(self) -> NDArray[np.float64]:
        r"""Upper-triangular R (d × d) with RᵀR = MᵀM + Σ_k M_kᵀM_k (M_k = ∂M/∂x_k).

        In y = R a, ||y||² = Σ_i f(x_i)² + ||∇f(x_i)||², so every direction of y changes the
        values and gradients on the data by the same amount: the natural coordinates for a
        search over polynomials (the raw coefficients of high-degree terms are orders of
        magnitude more sensitive than the others). Computed once, by a blockwise QR.
        """
        if self._whitening is None:
            d = self.n_coefficients
            r = np.zeros((0, d))
            rows = max(_MIN_ROWS, (1 << 22) // (8 * d * (1 + self.dim)))
            for start in range(0, self.n_points, rows):
                m, dm = basis.monomials_and_gradients(self.u[start:start + rows], self.degree)
                block = np.concatenate([r, m, dm.reshape(-1, d)])
                r = scipy.linalg.qr(block, mode="r", overwrite_a=True, check_finite=False)[0][:d]
            # A positive diagonal makes R unique (and the map orientation-preserving).
            sign = np.where(np.diag(r) < 0, -1.0, 1.0)
            self._whitening = sign[:, None] * r
        return self._whitening

    def normal_agreement(self) -> NDArray[np.float64]:
        r"""Vector v with v · a = Σ_i w_i ∇f(u_i) · n_i for any coefficients a (float64).

        How much the gradients agree with the normals is linear in the coefficients, so one pass
        over the design matrix gives it for every polynomial of this degree: the sign that makes
        f > 0 outside (:meth:`~ipfit.ImplicitPolynomial.canonical`) without evaluating gradients
        at every point once per polynomial.
        """
        if self._agreement is None:
            moments = np.zeros((self.n_lower, self.dim))
            pulled = self.normals64 * self._weights[:, None]
            for lo, hi in basis.point_blocks(self.n_points, _SINGLE_ROWS):
                moments += self._design(lo, hi, np.float64)[:, : self.n_lower].T @ pulled[lo:hi]
            agreement = np.zeros(self.n_coefficients)
            basis.add_gradient_adjoint(agreement, moments, self.degree)
            self._agreement = agreement
        return self._agreement

    # -- single member with gradient -------------------------------------------------------------
    def value_and_grad(self, coefficients: ArrayLike, *, split: bool = False) -> tuple[float, NDArray[np.float64]]:
        """Objective value and its analytic gradient with respect to ``coefficients`` (float64).

        The gradient exists wherever no f(x_i) is exactly 0 and no ∇f(x_i) vanishes, i.e.
        almost everywhere; at f(x_i) = 0 the sign function's value 0 is used (a subgradient).
        It is orthogonal to ``coefficients`` (the objective is scale invariant).

        ``split=True`` shares the blocks of rows between the worker threads even when the design
        is kept (it always is shared when the design is rebuilt at every evaluation): for a
        caller that runs nothing else meanwhile. The sums are then added in another order, so
        the value differs from the one-thread pass by rounding (reproducibly, for a given
        number of threads).
        """
        # One compiled pass, no BLAS call (an L-BFGS step runs in a fraction of a millisecond,
        # so even entering a BLAS thread limit here would be a noticeable share of it).
        return self._value_and_grad(self._population(coefficients)[0], split)

    def _value_and_grad(self, a: NDArray[np.float64], split: bool = False) -> tuple[float, NDArray[np.float64]]:
        from ._objective_kernels import member_pass

        source, factor = basis.derivative_gather(self.dim, self.degree)
        n = self._total

        def part(blocks) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
            sums, grad = np.zeros(3), np.zeros(self.n_coefficients)
            for rows, normals, weights, n_data in blocks:
                sums += member_pass(rows, a, source, factor, normals, weights, self._far64[1], self._far64[2],
                                    n_data, 1.0 / n, self.delta, _TINY, self.cap, TAUBIN_CAP, _GRAD_FLOOR, grad)
            return sums, grad

        jobs = self._member_jobs()
        # A design too big to keep is rebuilt at every evaluation, and building its rows is most
        # of the pass: the blocks are then shared between the worker threads (both kernels
        # release the GIL), every workers-th block each, summed in a fixed order: reproducible.
        # (A million points: 0.28 s an evaluation on one thread.) A kept design's pass stays on
        # the calling thread unless asked to split: a polish's passes may run two side by side.
        workers = min(self.threads, len(jobs)) if (self._m is None or split) else 1
        if workers == 1:
            sums, grad = part(self._member_block(job) for job in jobs)
        else:
            futures = [_pool(workers).submit(part, (self._member_block(job) for job in jobs[k::workers]))
                       for k in range(workers)]
            parts = [f.result() for f in futures]
            sums, grad = parts[0]
            for more_sums, more_grad in parts[1:]:
                sums, grad = sums + more_sums, grad + more_grad
        value = sums[0] / n + self.delta * (1.0 - sums[1] / n) + sums[2]
        for term in self._extra:
            tv, tg = term.value_and_grad(a)
            value += float(tv)
            grad = grad + np.asarray(tg, dtype=np.float64)
        return float(value), grad

    def _member_jobs(self) -> list[tuple[str, int, int]]:
        """The single-member pass's blocks of rows, in order: the data then the far-field samples,
        stacked into one block (kept) when they fit in one, so that a polish step is one
        compiled call; bigger clouds in blocks of points, then the far-field rows."""
        if self.n_points + len(self._far64[0]) <= _SINGLE_ROWS:
            return [("stacked", 0, self.n_points)]
        jobs = [("points", lo, hi) for lo, hi in basis.point_blocks(self.n_points, _SINGLE_ROWS)]
        return jobs + [("far", 0, 0)] if len(self._far64[0]) else jobs

    def _member_block(self, job: tuple[str, int, int]):
        """(float64 rows, their normals and weights, how many are data rows) of a job of
        :meth:`_member_jobs`."""
        kind, lo, hi = job
        if kind == "points":
            return self._design(lo, hi, np.float64), self.normals64[lo:hi], self._weights[lo:hi], hi - lo
        if kind == "far":
            return self._far64[0], self.normals64[:0], self._weights[:0], 0
        if self._member_rows is None:
            self._member_rows = np.vstack([self._design(0, self.n_points, np.float64), self._far64[0]])
        return self._member_rows, self.normals64, self._weights, self.n_points


def measures(poly_or_population: ImplicitPolynomial | ArrayLike, points: ArrayLike, normals: ArrayLike,
             delta: float = DEFAULT_DELTA) -> Measures:
    """The paper's dissimilarity, smoothness and distance (Eq. 2-4) of a polynomial or a population.

    Parameters
    ----------
    poly_or_population : ImplicitPolynomial, (d,) array or (P, d) array
        An :class:`~ipfit.ImplicitPolynomial` is evaluated in its own normalised coordinates
        u = (x − center)/scale: the dissimilarity is then in normalised units (the data's mean
        radius is 1 for fitted polynomials), so it does not change when the user rescales the
        data. Raw coefficient vectors are evaluated with ``points`` taken in the coefficients'
        own coordinates; the degree follows from d.
    points : (N, dim) array
    normals : (N, dim) array
        Normals at the points (normalised to unit length here).
    delta : float, default 0.25
        Penalty weight δ.

    Returns
    -------
    Measures
        Floats for a polynomial or a (d,) vector, (P,) arrays for a (P, d) population.

    Examples
    --------
    The circle x² + y² − 1 at (1, 0) with normal (1, 0) and at (2, 0) with normal (0, 1):
    Taubin terms 0 and 3/4, cosines 1 and 0.

    >>> from ipfit import ImplicitPolynomial
    >>> from ipfit.fitting.objective import measures
    >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    >>> m = measures(circle, [[1.0, 0.0], [2.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]])
    >>> m.dissimilarity, m.smoothness, m.distance
    (0.375, 0.5, 0.5)
    """
    if isinstance(poly_or_population, ImplicitPolynomial):
        poly = poly_or_population
        pts = as_points(points, dims=(poly.dim,))
        u = poly.normalization.apply(pts)
        obj = Objective(u, as_normals(normals, pts, required_by="measures"), poly.degree, delta)
        return obj.measures(poly.coefficients)[0]
    pts = as_points(points)
    try:
        coef = np.asarray(poly_or_population, dtype=np.float64)
    except (TypeError, ValueError):
        raise error("poly_or_population", "an ImplicitPolynomial or a (d,) or (P, d) coefficient array",
                    type(poly_or_population).__name__) from None
    if coef.ndim not in (1, 2) or coef.shape[-1] == 0:
        raise error("poly_or_population", "an ImplicitPolynomial or a (d,) or (P, d) coefficient array",
                    f"shape {coef.shape}")
    dim = pts.shape[1]
    try:
        degree = basis.degree_from_n_coefficients(dim, coef.shape[-1])
    except ValueError:
        raise error("poly_or_population", f"coefficient vectors of length C(g+{dim}, {dim}) for some degree g",
                    f"length {coef.shape[-1]}") from None
    if degree == 0:
        raise error("poly_or_population", "a polynomial of degree >= 1", "a constant")
    obj = Objective(pts, as_normals(normals, pts, required_by="measures"), degree, delta)
    result = obj.measures(coef)
    return result[0] if coef.ndim == 1 else result

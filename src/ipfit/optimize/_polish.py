"""Local polish of one candidate: L-BFGS on the objective with its analytic gradient."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.linalg
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import check_int, error
from ._common import OptimizeResult

__all__ = ["polish"]


def polish(fun_and_grad: Callable[[NDArray], tuple[float, NDArray]], x0: ArrayLike, *, maxiter: int = 300,
           precondition: ArrayLike | None = None, normalize: bool = True, ftol: float = 1e-12,
           gtol: float = 1e-10, callback: Callable[[OptimizeResult], Any] | None = None) -> OptimizeResult:
    """Minimise a smooth-almost-everywhere function from ``x0`` with L-BFGS (SciPy's L-BFGS-B).

    Parameters
    ----------
    fun_and_grad : callable
        x (d,) → (value, gradient (d,)), e.g. :meth:`ipfit.fitting.objective.Objective.value_and_grad`.
    x0 : (d,) array
        Starting point (the best member of a metaheuristic, or a linear fit).
    maxiter : int, default 300
        L-BFGS iterations.
    precondition : (d, d) upper-triangular array, optional
        R such that the search runs in y = R x. With R from the QR factorisation of the
        monomial matrix M, every direction in y changes the values f(x_i) by the same amount,
        which removes most of the ill-conditioning of the monomial basis (the raw coefficients
        of high-degree terms are orders of magnitude more sensitive than the others).
    normalize : bool, default True
        Return x scaled to unit norm (for scale-invariant objectives such as the paper's).
    ftol, gtol : float
        L-BFGS-B's relative-decrease and projected-gradient tolerances.
    callback : callable, optional
        Receives an :class:`OptimizeResult` snapshot (``x`` in the original variables) after
        every iteration; returning True or raising StopIteration stops the polish.

    Returns
    -------
    OptimizeResult
        Never worse than ``x0``: when L-BFGS does not improve, ``x`` is ``x0`` (normalised).
        ``history`` holds the value after each iteration, starting with f(x0).

    Examples
    --------
    >>> import numpy as np
    >>> quad = lambda x: (float(np.sum((x - 1.0) ** 2)), 2 * (x - 1.0))
    >>> res = polish(quad, np.zeros(3), normalize=False)
    >>> np.round(res.x, 6).tolist()
    [1.0, 1.0, 1.0]
    """
    x_start = np.array(x0, dtype=np.float64).ravel()
    if x_start.size == 0 or not np.isfinite(x_start).all():
        raise error("x0", "a finite non-empty vector", f"shape {np.shape(x0)}")
    maxiter = check_int(maxiter, "maxiter", minimum=0)
    if precondition is not None:
        r = np.asarray(precondition, dtype=np.float64)
        if r.shape != (x_start.size, x_start.size) or not np.isfinite(r).all():
            raise error("precondition", f"a finite ({x_start.size}, {x_start.size}) upper-triangular matrix",
                        f"shape {r.shape}")
        # One triangular inversion, then only numpy products in the loop: numpy and SciPy link
        # separate OpenBLAS copies, and alternating between them makes their idle threads spin
        # against each other on a small machine.
        r_inv = scipy.linalg.solve_triangular(r, np.eye(x_start.size), check_finite=False)

        def to_x(y):
            return r_inv @ y

        def fg(y):
            value, grad = fun_and_grad(r_inv @ y)
            return value, r_inv.T @ grad  # d/dy f(R⁻¹ y) = R⁻ᵀ ∇f

        y0 = r @ x_start
    else:
        def to_x(y):
            return y

        fg = fun_and_grad
        y0 = x_start

    def finish(x):
        if normalize:
            norm = np.linalg.norm(x)
            return x / norm if norm > 0 else x
        return x

    f0 = float(fun_and_grad(x_start)[0])
    history = [f0]
    nfev = [1]

    def counted(y):
        nfev[0] += 1
        value, grad = fg(y)
        return float(value), np.asarray(grad, dtype=np.float64)

    stopped = [False]

    def on_iteration(intermediate_result):
        history.append(float(intermediate_result.fun))
        if callback is not None:
            snap = OptimizeResult(x=finish(to_x(intermediate_result.x)), fun=float(intermediate_result.fun),
                                  nit=len(history) - 1, nfev=nfev[0], success=True, message="",
                                  history=np.array(history))
            try:
                stop = callback(snap)
            except StopIteration:
                stop = True
            if stop is True:
                stopped[0] = True
                raise StopIteration

    if maxiter == 0:
        return OptimizeResult(x=finish(x_start), fun=f0, nit=0, nfev=1, success=bool(np.isfinite(f0)),
                              message="maxiter is 0", history=np.array(history))
    res = scipy.optimize.minimize(counted, y0, jac=True, method="L-BFGS-B", callback=on_iteration,
                                  options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol, "maxcor": 20})
    x = to_x(res.x)
    fun = float(res.fun)
    message = "stopped by the callback" if stopped[0] else str(res.message)
    if not fun < f0 or not np.isfinite(x).all():
        x, fun = x_start, f0
        message += " (no improvement: kept the start)"
    # success: a finite value was reached. L-BFGS's own flag is in the message: on these
    # objectives (|f| is not smooth where f = 0) its line search often ends "abnormally" at a
    # perfectly good point.
    return OptimizeResult(x=finish(x), fun=fun, nit=int(res.nit), nfev=nfev[0], success=bool(np.isfinite(fun)),
                          message=message, history=np.array(history))

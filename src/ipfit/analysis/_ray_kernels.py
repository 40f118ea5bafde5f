"""Compiled real roots of a polynomial along rays for :mod:`ipfit.analysis.rays`, imported lazily.

Kept apart so that ``import ipfit`` does not pay numba's import time. The kernel is serial and
releases the GIL (``nogil``); :mod:`ipfit.analysis.rays` runs blocks of rays on worker threads
(numba's ``prange`` is not used, for the reason given in :mod:`ipfit.fitting._objective_kernels`).

For each ray u(τ) = p + τ e (normalised coordinates) the kernel builds the univariate
coefficients of f(u(τ)) by the exact binomial expansion of the monomials (each monomial is a
lower one times one factor (p_j + τ e_j): a shift-and-add on its row of coefficients), then
isolates its real roots in the interval [lo, hi] without eigenvalues: the roots of a
polynomial are separated by those of its derivative, so the roots of the derivatives are found
from the highest (linear) one down, each from the intervals between the roots of the next one,
on which it is monotone. A sign change on such an interval brackets exactly one root, found by
safeguarded Newton-bisection to full precision; a root of even multiplicity (a tangent ray)
changes no sign and is found at the derivative's root where f is at rounding level. Every root
is then checked, after a Newton step on f itself (not the expansion), against the same rule the
eigenvalue method used: |f| at most ``residual`` × Σ|terms|.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)

_MAX_BRACKET_STEPS = 200  # safeguarded Newton-bisection halves the bracket at least every 2 steps
_NEWTON_STEPS = 3  # on f itself, after the expansion's root: rounding-level corrections only
_SAME_ROOT = 1e-7  # relative distance under which two roots are one (a double root found twice)
_FLAT = 1e-14  # f vanishes on the ray: the expansion's coefficients below this × Σ|a|
_NEGLIGIBLE = 1e-13  # coefficients below this × the largest drop out of the root bound (|τ| ~ 1e13)


@njit(**_JIT)
def _horner(q, m, x):  # pragma: no cover - compiled
    """q(x) and q'(x) for q of degree m, ascending coefficients."""
    f = q[m]
    df = 0.0
    for t in range(m - 1, -1, -1):
        df = df * x + f
        f = f * x + q[t]
    return f, df


@njit(**_JIT)
def _bracketed_root(q, m, lo, hi, f_lo):  # pragma: no cover - compiled
    """The root of q in [lo, hi] where q(lo) = f_lo and q(hi) have opposite signs (rtsafe)."""
    if f_lo > 0:  # orient so that q(neg) < 0 < q(pos)
        neg, pos = hi, lo
    else:
        neg, pos = lo, hi
    x = 0.5 * (lo + hi)
    dx_old = abs(hi - lo)
    dx = dx_old
    f, df = _horner(q, m, x)
    for _ in range(_MAX_BRACKET_STEPS):
        if f == 0.0:
            return x
        if f < 0:
            neg = x
        else:
            pos = x
        a, b = min(neg, pos), max(neg, pos)
        newton = x - f / df if df != 0.0 else np.nan
        # Bisect when Newton leaves the bracket or would not halve the step of two steps ago.
        if not (a < newton < b) or abs(2.0 * f) > abs(dx_old * df):
            dx_old = dx
            dx = 0.5 * (b - a)
            x = a + dx
        else:
            dx_old = dx
            dx = x - newton
            x = newton
        if abs(dx) <= 4e-16 * (1.0 + abs(x)) or b - a <= 4e-16 * (1.0 + abs(x)):
            return x
        f, df = _horner(q, m, x)
    return x


@njit(**_JIT)
def _on_ray(coefficients, parent, axis, p, e, tau, m, dm):  # pragma: no cover - compiled
    """f, df/dτ and Σ|terms| at u = p + τ e, from the monomials built one factor at a time."""
    m[0] = 1.0
    dm[0] = 0.0
    f = coefficients[0]
    df = 0.0
    size = abs(coefficients[0])
    for k in range(1, coefficients.shape[0]):
        src = parent[k]
        j = axis[k]
        u = p[j] + tau * e[j]
        m[k] = m[src] * u
        dm[k] = dm[src] * u + m[src] * e[j]
        f += coefficients[k] * m[k]
        df += coefficients[k] * dm[k]
        size += abs(coefficients[k] * m[k])
    return f, df, size


@njit(**_JIT)
def _accept(coefficients, parent, axis, p, e, tau, residual, newton, m, dm):  # pragma: no cover - compiled
    """τ after up to ``newton`` Newton steps on f along the ray (each kept only if |f| drops),
    or NaN when |f| there is above ``residual`` × Σ|terms|."""
    f, df, size = _on_ray(coefficients, parent, axis, p, e, tau, m, dm)
    for _ in range(newton):
        if f == 0.0 or df == 0.0:
            break
        step = f / df
        if not abs(step) < 0.1 * (1.0 + abs(tau)):  # not in Newton's basin (or NaN): keep τ
            break
        f2, df2, size2 = _on_ray(coefficients, parent, axis, p, e, tau - step, m, dm)
        if not abs(f2) < abs(f):
            break
        tau, f, df, size = tau - step, f2, df2, size2
        if abs(step) <= 1e-15 * (1.0 + abs(tau)):
            break
    if abs(f) <= residual * size:
        return tau
    return np.nan


@njit(**_JIT)
def _gradient(coefficients, parent, axis, u, m, gm):  # pragma: no cover - compiled
    """∇_u f at u (normalised coordinates) into ``gm[0]``; ``m``, ``gm`` are scratch (M,), (M, dim)."""
    dim = u.shape[0]
    m[0] = 1.0
    for j in range(dim):
        gm[0, j] = 0.0
    for k in range(1, coefficients.shape[0]):
        src = parent[k]
        a = axis[k]
        m[k] = m[src] * u[a]
        for j in range(dim):
            gm[k, j] = gm[src, j] * u[a]
        gm[k, a] += m[src]
    out = np.zeros(dim)
    for k in range(1, coefficients.shape[0]):
        for j in range(dim):
            out[j] += coefficients[k] * gm[k, j]
    return out


@njit(**_JIT)
def ray_roots(coefficients, parent, axis, order, degree, p, e, lo, hi, residual, first_only, out, flat,
              gradient):  # pragma: no cover - compiled
    """Real roots of f along each ray u(τ) = p[i] + τ e[i] with lo[i] <= τ <= hi[i], ascending.

    ``coefficients`` (M,) are f's in graded order, ``parent``/``axis`` (M,) say that monomial k
    is monomial ``parent[k]`` times u_axis[k], ``order`` (M,) its degree; ``degree`` is f's. ``p``, ``e`` (n, dim)
    are the rays (normalised coordinates), ``lo``, ``hi`` (n,) the interval of τ searched (±inf
    allowed). Writes the roots into ``out`` (n, ≥ 1), NaN-padded (the caller fills it with NaN);
    with ``first_only``, only the first root (``out`` (n, 1)) and, into ``gradient`` (n, dim),
    ∇_u f there. ``flat[i]`` is set where f vanishes on the whole ray (no roots reported).
    """
    n, dim = p.shape
    nc = coefficients.shape[0]
    g = degree
    width = out.shape[1]
    total = 0.0
    for k in range(nc):
        total += abs(coefficients[k])
    table = np.zeros((nc, g + 1))
    c = np.zeros(g + 1)
    q = np.zeros(g + 1)
    points = np.zeros(g + 2)  # interval ends: lo, the next derivative's roots, hi
    crit = np.zeros(g + 1)
    found = np.zeros(g + 1)
    roots = np.zeros(2 * g + 2)
    mm = np.zeros(nc)
    dmm = np.zeros(nc)
    gm = np.zeros((nc, dim))
    u = np.zeros(dim)
    for i in range(n):
        pi = p[i]
        ei = e[i]
        # -- the univariate coefficients c[t] of f(p + τ e), exactly expanded
        for t in range(g + 1):
            table[0, t] = 0.0
            c[t] = 0.0
        table[0, 0] = 1.0
        c[0] = coefficients[0]
        for k in range(1, nc):
            src = parent[k]
            j = axis[k]
            a = pi[j]
            b = ei[j]
            ak = coefficients[k]
            top = order[k]  # the monomial's degree: its row ends there (the parent's one before)
            v = table[src, 0] * a
            table[k, 0] = v
            c[0] += ak * v
            for t in range(1, top):
                v = table[src, t] * a + table[src, t - 1] * b
                table[k, t] = v
                c[t] += ak * v
            v = table[src, top - 1] * b
            table[k, top] = v
            c[top] += ak * v
        largest = 0.0
        for t in range(g + 1):
            largest = max(largest, abs(c[t]))
        if largest <= _FLAT * total:
            flat[i] = True
            continue
        # -- the interval: [lo, hi] within the bound of the roots of the significant coefficients
        top = g
        while top > 0 and abs(c[top]) <= _NEGLIGIBLE * largest:
            top -= 1
        if top == 0:
            continue  # a non-zero constant along the ray
        # Fujiwara's bound on the roots' size: far tighter than Cauchy's at high degree, and the
        # bisection's first steps halve it
        bound = 0.0
        for k in range(1, top + 1):
            ratio = abs(c[top - k] / c[top])
            if k == top:
                ratio *= 0.5
            bound = max(bound, ratio ** (1.0 / k))
        bound = 2.0 * bound * (1.0 + 1e-12)
        a_end = max(lo[i], -bound)
        b_end = min(hi[i], bound)
        if not a_end <= b_end:
            continue
        # -- roots of the derivatives of order g-1 (linear) down to 0 (f), each level's
        #    intervals cut at the roots of the level above, on which it is monotone
        n_crit = 0
        n_roots = 0
        for level in range(g - 1, -1, -1):
            mdeg = g - level
            for t in range(mdeg + 1):  # q = the level-th derivative of c (falling factorials)
                factor = 1.0
                for r in range(level):
                    factor *= t + level - r
                q[t] = c[t + level] * factor
            points[0] = a_end
            for r in range(n_crit):
                points[r + 1] = crit[r]
            points[n_crit + 1] = b_end
            n_points = n_crit + 2
            n_new = 0
            last = level == 0
            f_left, _ = _horner(q, mdeg, points[0])
            done = False
            for r in range(n_points - 1):
                x0 = points[r]
                x1 = points[r + 1]
                f_right, _ = _horner(q, mdeg, x1)
                root = np.nan
                if f_left == 0.0:
                    root = x0
                elif (f_left < 0.0) != (f_right < 0.0) and f_right != 0.0:
                    root = _bracketed_root(q, mdeg, x0, x1, f_left)
                elif r == n_points - 2 and f_right == 0.0:
                    root = x1
                if not last:
                    if root == root:
                        crit[n_new] = root  # crit's old entries were copied into points above
                        n_new += 1
                else:
                    # A tangent root at the interval's left end (a root of f'): no sign change on
                    # the interval before it, and f at rounding level there. A sign change just
                    # after it is the same root found twice, merged below.
                    if r >= 1 and found[r - 1] == 0.0:
                        tau = _accept(coefficients, parent, axis, pi, ei, x0, residual, 0, mm, dmm)
                        if tau == tau:
                            roots[n_roots] = tau
                            n_roots += 1
                    found[r] = 0.0
                    if root == root:
                        tau = _accept(coefficients, parent, axis, pi, ei, root, residual, _NEWTON_STEPS, mm, dmm)
                        if tau == tau:
                            found[r] = 1.0
                            roots[n_roots] = tau
                            n_roots += 1
                    if first_only and n_roots > 0:
                        done = True
                        break
                f_left = f_right
            if done:
                break
            if not last:
                n_crit = n_new
        # -- sort, merge double roots found twice, write
        for r in range(1, n_roots):
            x = roots[r]
            s = r - 1
            while s >= 0 and roots[s] > x:
                roots[s + 1] = roots[s]
                s -= 1
            roots[s + 1] = x
        kept = 0
        for r in range(n_roots):
            x = roots[r]
            if kept > 0 and abs(x - out[i, kept - 1]) <= _SAME_ROOT * (1.0 + abs(x)):
                continue
            if kept == width:
                break
            out[i, kept] = x
            kept += 1
        if first_only and kept > 0:
            for j in range(dim):
                u[j] = pi[j] + out[i, 0] * ei[j]
            grad = _gradient(coefficients, parent, axis, u, mm, gm)
            for j in range(dim):
                gradient[i, j] = grad[j]

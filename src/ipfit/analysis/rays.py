"""Every intersection of rays with the zero set, and ray-cast images of surfaces.

Restricting f to a ray gives a univariate polynomial of the same degree. Its coefficients are
computed by exact binomial expansion of the monomial form: each monomial of u(τ) = p + τ e
is built from a lower one times one factor (p_j + τ e_j), a shift-and-add on coefficient
rows, so the whole table costs one pass over the basis per ray and involves no
interpolation or linear solve (sampling at Chebyshev nodes would need a solve whose error
grows with the degree). To keep the coefficients well scaled, the ray is re-parametrised in
normalised coordinates around its point nearest the data's centre, with a unit direction:
the roots of interest then have |τ| of order one.

Real roots are isolated in compiled code (:mod:`ipfit.analysis._ray_kernels`): the roots of
the derivatives, from the linear one down, cut the search interval into pieces on which the
next derivative is monotone, so every sign change of f brackets exactly one root, found by
safeguarded Newton-bisection; each root is then checked on the original f along the ray (a
Newton step undoes the rounding of the expansion) and accepted only where |f| is at rounding
level. Double roots (tangent rays) come out as one hit. Rays are processed in blocks, on the
package's worker threads, with nothing per ray kept but its hits: memory stays a few arrays of
the rays' size whatever the degree. (Companion-matrix eigenvalues, used before, cost a
(rays, monomials, degree) table and a batched eigenvalue solve per block, and ∇f of every hit
at once: 50 s and 484 MB for ``ipfit render`` of a degree-8 fit at 480 × 480 pixels; the
compiled kernel takes about 1.3 CPU seconds and 40 MB for such an image,
benchmarks/bench_render.py.)
"""

from __future__ import annotations

import math
import numbers
import os
from functools import lru_cache
from typing import NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._result_schema import MAX_COORDINATE
from .._utils.numeric import unit_rows_mask
from .._utils.validation import as_points, check_int, check_real, error

__all__ = ["RayHits", "intersect_rays", "render", "camera_rays", "first_hits"]

_BLOCK = 16384  # rays per block and per thread: bounds the block's arrays (a few per ray)
_RESIDUAL_TOL = 1e-9  # accepted roots: |f| below this fraction of Σ|terms|


class RayHits(NamedTuple):
    """Intersections of N rays with a zero set.

    Attributes
    ----------
    t : (N, K) ray parameters of the hits, ascending, NaN-padded (K >= 1 is the largest
        count, at most the degree): the hit k of ray i is
        ``origins[i] + t[i, k] * directions[i]``.
    points : (N, degree, dim) the hit points, NaN-padded.
    count : (N,) number of hits of each ray.
    on_zero_set : (N,) True where f vanishes on the whole ray (the ray lies in the zero set);
        such rays report no hits.
    """

    t: NDArray[np.float64]
    points: NDArray[np.float64]
    # the field shadows tuple.count, as mypy says; it is the public name of the field
    count: NDArray[np.int64]  # type: ignore[assignment]
    on_zero_set: NDArray[np.bool_]

    @property
    def first(self) -> NDArray[np.float64]:
        """Parameter of the first hit of each ray (NaN for a miss)."""
        return self.t[:, 0] if self.t.shape[1] else np.full(len(self.t), np.nan)


@lru_cache(maxsize=64)
def _parents(dim: int, degree: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    # Monomial k = monomial parent[k] times u_axis[k]; parents come earlier in graded order.
    exps = basis.exponents(dim, degree)
    index = {tuple(e): i for i, e in enumerate(exps.tolist())}
    parent = np.zeros(len(exps), dtype=np.int64)
    axis = np.zeros(len(exps), dtype=np.int64)
    for k, e in enumerate(exps.tolist()[1:], start=1):
        j = next(i for i, v in enumerate(e) if v > 0)
        lowered = list(e)
        lowered[j] -= 1
        parent[k], axis[k] = index[tuple(lowered)], j
    return parent, axis


def _rows(value: ArrayLike, name: str, dim: int) -> NDArray[np.float64]:
    # one ray may come as a single point; anything else goes to as_points as given, so that
    # masks, dtypes and DataFrames are checked there
    if isinstance(value, np.ndarray) and value.ndim == 1:
        value = value[np.newaxis]
    elif isinstance(value, (list, tuple)) and value and all(isinstance(v, numbers.Number) for v in value):
        value = [value]
    return as_points(value, name, dims=(dim,))


def _as_rays(poly, origins: ArrayLike, directions: ArrayLike) -> tuple[NDArray, NDArray]:
    o, d = _rows(origins, "origins", poly.dim), _rows(directions, "directions", poly.dim)
    if len(o) != len(d) and 1 not in (len(o), len(d)):
        raise error("directions", f"one direction per origin ({len(o)}) or a single one", f"{len(d)} directions",
                    "Pass arrays of the same length, or one origin or one direction for all rays.")
    o, d = np.broadcast_arrays(o, d)
    _, ok = unit_rows_mask(d)
    if not ok.all():
        first = int(np.flatnonzero(~ok)[0])
        raise error("directions", "non-zero direction vectors", f"{int((~ok).sum())} zero-length directions "
                    f"(first at row {first})", "A ray needs a direction; remove those rows.")
    return np.ascontiguousarray(o), np.ascontiguousarray(d)


def intersect_rays(origins: ArrayLike, directions: ArrayLike, poly, tmin: float | ArrayLike = 0.0,
                   tmax: float | ArrayLike = math.inf) -> RayHits:
    """All real intersections of the rays ``origins + t · directions`` (tmin <= t <= tmax) with f = 0.

    Parameters
    ----------
    origins, directions : (N, dim) arrays (or one row, shared by all rays). Directions need
        not be unit vectors (t is in units of their length) but must not be zero.
    poly : ImplicitPolynomial
    tmin, tmax : the part of each ray to search: numbers, or (N,) arrays (one interval per ray);
        ``-inf`` and ``inf`` are allowed.

    Returns
    -------
    RayHits
        ``t``, ``points`` and ``count`` per ray (tangent contacts count once).

    Examples
    --------
    A ray along x through the unit circle, as a line (t from −inf):

    >>> from ipfit import ImplicitPolynomial
    >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    >>> hits = intersect_rays([[-3.0, 0.0]], [[1.0, 0.0]], circle, tmin=-math.inf)
    >>> hits.count.tolist(), hits.t.round(12).tolist()
    ([2], [[2.0, 4.0]])
    """
    o, d = _as_rays(poly, origins, directions)
    n = len(o)
    lo, hi = _limits(tmin, "tmin", n, -math.inf), _limits(tmax, "tmax", n, math.inf)
    if np.any(lo > hi):
        first = int(np.flatnonzero(lo > hi)[0])
        raise error("tmax", f"a value >= tmin ({lo[first]})", str(hi[first]) if np.ndim(tmax) == 0
                    else f"{hi[first]} at ray {first}")
    t_all, flat, _ = _ray_hits(poly, o, d, lo, hi, first_only=False)
    count = np.isfinite(t_all).sum(axis=1)
    width = int(count.max(initial=0))
    t_all = t_all[:, :max(width, 1)]
    points = o[:, None, :] + t_all[:, :, None] * d[:, None, :]
    return RayHits(t_all, points, count, flat)


def _limits(value, name: str, n: int, infinite: float) -> NDArray[np.float64]:
    """``tmin`` or ``tmax`` as one value per ray: a real number (``infinite``, ±inf, allowed) or
    an (n,) array of them."""
    if np.ndim(value) == 0:
        number = infinite if value == infinite else check_real(value, name)
        return np.full(n, number)
    limits = np.asarray(value, dtype=np.float64) if np.asarray(value).dtype.kind in "iuf" else None
    if limits is None or limits.shape != (n,):
        raise error(name, f"a real number or one per ray ({n})", f"an array of shape {np.shape(value)}")
    if not np.all(np.isfinite(limits) | (limits == infinite)):
        raise error(name, f"finite numbers or {infinite}", f"{int(np.sum(~np.isfinite(limits)))} other values")
    return limits


def _ray_hits(poly, o: NDArray, d: NDArray, tmin: NDArray, tmax: NDArray, first_only: bool
              ) -> tuple[NDArray, NDArray, NDArray | None]:
    """Hits of the rays ``o + t d`` with tmin <= t <= tmax (per ray), ascending and NaN-padded
    (n, degree), or the first hit alone (n, 1) and ∇f there (n, dim) with ``first_only``;
    and which rays lie in the zero set. Blocks of rays run on the worker threads."""
    from concurrent.futures import ThreadPoolExecutor

    from .._utils.threads import default_threads
    from ._ray_kernels import ray_roots

    n, dim = o.shape
    parent, axis = _parents(dim, poly.degree)
    order = basis.exponents(dim, poly.degree).sum(axis=1)
    coefficients = np.ascontiguousarray(poly.coefficients, dtype=np.float64)
    t_all = np.full((n, 1 if first_only else poly.degree), np.nan)
    flat = np.zeros(n, dtype=bool)
    gradient = np.full((n, dim), np.nan) if first_only else np.zeros((0, dim))
    s = poly.scale

    def block(start: int) -> None:
        sl = slice(start, min(start + _BLOCK, n))
        p, q = poly.normalization.apply(o[sl]), d[sl] / s
        qn = np.linalg.norm(q, axis=1)
        e = q / qn[:, None]
        t0 = -np.einsum("nd,nd->n", p, e) / qn
        p0 = p + t0[:, None] * q  # the ray's point nearest the centre: roots have |τ| ~ 1
        tau = np.full((len(p0), t_all.shape[1]), np.nan)
        grad = np.zeros((len(p0), dim)) if first_only else gradient
        # the interval in τ; inf stays inf (t0 and qn are finite)
        ray_roots(coefficients, parent, axis, order, poly.degree, p0, e, (tmin[sl] - t0) * qn, (tmax[sl] - t0) * qn,
                  _RESIDUAL_TOL, first_only, tau, flat[sl], grad)
        t = t0[:, None] + tau / qn[:, None]
        with np.errstate(invalid="ignore"):  # rounding may put a root at an end just outside
            t[(t < tmin[sl, None]) | (t > tmax[sl, None])] = np.nan
        t_all[sl] = t
        if first_only:
            gradient[sl] = np.where(np.isfinite(t), grad / s, np.nan)  # ∇_x f = ∇_u f / s

    starts = range(0, n, _BLOCK)
    threads = min(default_threads(), len(starts))
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(block, starts))  # list(): re-raises a block's exception here
    else:
        for start in starts:
            block(start)
    return t_all, flat, gradient if first_only else None


# -- ray-cast rendering -----------------------------------------------------------------

def camera_rays(bounds: ArrayLike, size: tuple[int, int], view: tuple[float, float] = (20.0, -60.0),
                up: str = "z") -> tuple[NDArray, NDArray, NDArray]:
    """Orthographic camera framing the box ``bounds`` (3, 2): origins, direction, light.

    ``view`` is (elevation, azimuth) in degrees as in matplotlib; ``up`` the vertical axis.
    Origins are one per pixel (row-major, top row first), on a plane outside the box.
    """
    box = np.asarray(bounds, dtype=np.float64).reshape(3, 2)
    centre, radius = box.mean(axis=1), 0.5 * float(np.linalg.norm(box[:, 1] - box[:, 0]))
    order = {"z": (0, 1, 2), "y": (2, 0, 1), "x": (1, 2, 0)}[up]
    elev, azim = np.radians(view[0]), np.radians(view[1])
    local = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    to_eye = np.zeros(3)
    to_eye[list(order)] = local
    vertical = np.zeros(3)
    vertical[order[2]] = 1.0
    right = np.cross(vertical, to_eye)
    right /= np.linalg.norm(right)
    upward = np.cross(to_eye, right)
    # Frame the box's projection (its corners seen along the view), not its bounding sphere.
    corners = np.array(np.meshgrid(*box, indexing="ij")).reshape(3, -1).T - centre
    extent = max(np.abs(corners @ right).max(), np.abs(corners @ upward).max()) * 1.02
    width, height = size
    half_w = extent * max(1.0, width / height)
    half_h = extent * max(1.0, height / width)
    xs = np.linspace(-half_w, half_w, width)
    ys = np.linspace(half_h, -half_h, height)
    gx, gy = np.meshgrid(xs, ys)
    origins = centre + 2.0 * radius * to_eye + gx.reshape(-1, 1) * right + gy.reshape(-1, 1) * upward
    light = to_eye + 0.6 * upward - 0.4 * right
    return origins, -to_eye, light / np.linalg.norm(light)


def _box_interval(o: NDArray, d: NDArray, box: NDArray) -> tuple[NDArray, NDArray]:
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (box[:, 0] - o) / d
        b = (box[:, 1] - o) / d
    # fmax/fmin skip the NaN of a zero direction component on a box face, without a warning.
    lo = np.fmax.reduce(np.minimum(a, b), axis=1)
    hi = np.fmin.reduce(np.maximum(a, b), axis=1)
    return np.maximum(lo, 0.0), hi


def first_hits(poly, origins: NDArray, direction: NDArray, bounds: NDArray) -> NDArray[np.float64]:
    """Parameter of each ray's first hit inside the box ``bounds`` (NaN for none), as drawn by :func:`render`."""
    return _first_hits(poly, origins, direction, bounds)[0]


def _first_hits(poly, origins: NDArray, direction: NDArray, bounds: NDArray) -> tuple[NDArray, NDArray]:
    """First hits inside the box (NaN for none) and ∇f there, (n,) and (n, dim)."""
    box = np.asarray(bounds, dtype=np.float64)
    directions = np.broadcast_to(direction, origins.shape)
    lo, hi = _box_interval(origins, directions, box)
    first = np.full(len(origins), np.nan)
    gradient = np.full(origins.shape, np.nan)
    live = np.flatnonzero(lo <= hi)  # rays that cross the box
    if live.size:
        t, _, grad = _ray_hits(poly, np.ascontiguousarray(origins[live]), np.ascontiguousarray(directions[live]),
                               lo[live], hi[live], first_only=True)
        first[live], gradient[live] = t[:, 0], grad
    return first, gradient


def render(poly, bounds: ArrayLike, path: str | os.PathLike | None = None, *, size: int | tuple[int, int] = 480,
           view: tuple[float, float] = (20.0, -60.0), up: str = "z",
           color: tuple[float, float, float] = (0.85, 0.72, 0.55)) -> NDArray[np.uint8]:
    """Ray-cast image of a 3D zero set inside the box ``bounds``: the exact surface, shaded by ∇f.

    Each pixel's ray is clipped to the box and its first intersection with f = 0 is shaded
    with a Lambert term plus a small specular highlight from the unit normal ∇f / |∇f|.

    Parameters
    ----------
    poly : 3D ImplicitPolynomial.
    bounds : (3, 2) box [[xmin, xmax], [ymin, ymax], [zmin, zmax]].
    path : if given, the image is written there as PNG (atomically).
    size : width (square image) or (width, height) in pixels.
    view, up : camera elevation and azimuth in degrees, and the vertical axis.

    Returns
    -------
    (height, width, 3) uint8 RGB image; background white.

    Examples
    --------
    >>> from ipfit.datasets.synthetic import sphere
    >>> img = render(sphere().polynomial, [[-1.5, 1.5]] * 3, size=16)
    >>> img.shape, bool((img[8, 8] < 255).any()), img[0, 0].tolist()
    ((16, 16, 3), True, [255, 255, 255])
    """
    if poly.dim != 3:
        raise error("poly", "a 3D surface to ray-cast", f"a {poly.dim}D curve", "Draw 2D fits with ipfit plot.")
    box = np.asarray(bounds, dtype=np.float64)
    if box.shape != (3, 2) or not np.all(np.isfinite(box)) or not np.all(box[:, 1] > box[:, 0]):
        raise error("bounds", "a (3, 2) box with min < max on every axis", f"{box.tolist()}")
    if np.abs(box).max() > MAX_COORDINATE:  # the camera's rays would start beyond float64's range
        raise error("bounds", f"a box within ±{MAX_COORDINATE:.0e}", f"{box.tolist()}",
                    "Render the polynomial in smaller units.")
    # np.isscalar does not narrow for mypy: the other case is the (width, height) pair
    width, height = (size, size) if np.isscalar(size) else cast("tuple[int, int]", size)
    width, height = check_int(width, "size", minimum=1), check_int(height, "size", minimum=1)
    if up not in ("x", "y", "z"):
        raise error("up", "'x', 'y' or 'z'", repr(up))
    origins, direction, light = camera_rays(box, (width, height), view, up)
    first, gradient = _first_hits(poly, origins, direction, box)
    hit = np.isfinite(first)
    image = np.ones((len(origins), 3))
    if hit.any():
        normal, _ = unit_rows_mask(gradient[hit])
        facing = np.sign(normal @ -direction)
        normal *= np.where(facing == 0, 1.0, facing)[:, None]  # two-sided: light the side we see
        lambert = np.clip(normal @ light, 0.0, 1.0)
        half = (light - direction) / np.linalg.norm(light - direction)
        spec = np.clip(normal @ half, 0.0, 1.0) ** 40
        image[hit] = np.clip(np.asarray(color) * (0.22 + 0.78 * lambert)[:, None] + 0.25 * spec[:, None], 0, 1)
    out = (image.reshape(height, width, 3) * 255 + 0.5).astype(np.uint8)
    if path is not None:
        from PIL import Image

        from .._utils.atomic import atomic_path

        with atomic_path(path) as tmp:
            Image.fromarray(out).save(tmp, format="PNG")
    return out

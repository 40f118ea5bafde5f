"""The fitted model: :class:`ImplicitPolynomial` and the data :class:`Normalization`.

A polynomial keeps the normalisation of the data it was fitted on and evaluates
f((x − center) / scale): expanding the coefficients back into user coordinates would be
badly conditioned at high degree, so that is never done.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import basis
from ._result_schema import FORMAT_NAME, FORMAT_VERSION, parse_result_text, read_result_json, validate_result
from ._utils.numeric import row_norms
from ._utils.validation import as_matching, as_points, error
from .exceptions import InvalidInputError, ReadError

__all__ = ["Normalization", "ImplicitPolynomial", "FORMAT_NAME", "FORMAT_VERSION"]

_CHUNK = 1 << 16  # rows per evaluation block: bounds the temporary design matrix


def _readonly(values: ArrayLike, dtype) -> NDArray:
    arr = np.array(values, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Normalization:
    """Similarity map u = (x − center) / scale used to condition the fit (paper, Section 5).

    >>> norm = Normalization.from_points([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [1.0, -1.0]])
    >>> norm.center.tolist(), norm.scale
    ([1.0, 0.0], 1.0)
    """

    center: NDArray[np.float64]
    scale: float

    def __post_init__(self) -> None:
        try:
            center = _readonly(self.center, np.float64)
        except (TypeError, ValueError):
            raise error("center", "2 or 3 finite numbers", repr(self.center)[:60]) from None
        if center.ndim != 1 or center.size not in (2, 3) or not np.isfinite(center).all():
            raise error("center", "2 or 3 finite numbers", repr(center.tolist())[:60],
                        "A NaN or infinite centre would make every value NaN.")
        object.__setattr__(self, "center", center)
        try:
            scale = float(self.scale)
        except (TypeError, ValueError):
            raise error("scale", "a finite number > 0", repr(self.scale)[:60]) from None
        if not (math.isfinite(scale) and scale > 0):
            raise error("scale", "a finite number > 0", repr(self.scale))
        object.__setattr__(self, "scale", scale)

    @classmethod
    def from_points(cls, points: ArrayLike) -> Normalization:
        """Centre at the mean and divide by the mean distance to it."""
        pts = as_points(points)
        center = pts.mean(axis=0)
        scale = float(row_norms(pts - center).mean())  # no underflow for coordinates of 1e-200
        if not scale > 0:
            raise error("points", "points that are not all identical", "one repeated point",
                        "Pass a point cloud with some extent.")
        return cls(center, scale)

    @classmethod
    def identity(cls, dim: int) -> Normalization:
        return cls(np.zeros(dim), 1.0)

    @property
    def dim(self) -> int:
        return int(self.center.shape[0])

    def apply(self, points: NDArray) -> NDArray[np.float64]:
        """User coordinates → normalised coordinates."""
        return (np.asarray(points, dtype=np.float64) - self.center) / self.scale

    def invert(self, points: NDArray) -> NDArray[np.float64]:
        """Normalised coordinates → user coordinates."""
        return np.asarray(points, dtype=np.float64) * self.scale + self.center

    def to_dict(self) -> dict:
        return {"center": self.center.tolist(), "scale": self.scale}


@dataclass(frozen=True, eq=False)
class ImplicitPolynomial:
    r"""An implicit polynomial curve (2D) or surface (3D): the zero set of f.

    ``f(x) = Σ_k coefficients[k] · Π_j ((x_j − center_j) / scale) ** exponents[k, j]``.

    Instances are immutable; fitting functions such as :func:`ipfit.fit_3l` build them.
    Fitted polynomials are in canonical form: unit coefficient norm and f > 0 outside the
    shape, so ``contains`` is the sign test of the paper's introduction.

    Parameters
    ----------
    exponents : (d, dim) int array in the graded order of :func:`ipfit.basis.exponents`.
    coefficients : (d,) float array.
    normalization : :class:`Normalization`, default identity.
    method : name of the fit that produced it, if any.
    measures : the paper's measures on the fitting data, if known.
    info : diagnostics of the fit (condition number, rank, ...).

    Examples
    --------
    The unit circle x² + y² − 1:

    >>> import numpy as np
    >>> from ipfit import ImplicitPolynomial
    >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    >>> circle([[1.0, 0.0], [0.0, 2.0]]).tolist()
    [0.0, 3.0]
    >>> circle.gradient([[1.0, 0.0]]).tolist()
    [[2.0, 0.0]]
    >>> circle.contains([[0.0, 0.0], [3.0, 0.0]]).tolist()
    [True, False]
    """

    exponents: NDArray[np.int64]
    coefficients: NDArray[np.float64]
    normalization: Normalization = field(default=None)  # type: ignore[assignment]
    method: str | None = None
    measures: Mapping[str, float] | None = None
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        raw = np.asarray(self.exponents)
        if raw.dtype.kind not in "iub" and not (raw.dtype.kind == "f" and np.all(np.mod(raw, 1) == 0)):
            raise error("exponents", "whole numbers", f"an array of dtype {raw.dtype}"
                        + (" with fractions" if raw.dtype.kind == "f" else ""))
        exps = _readonly(raw, np.int64)
        coef = _readonly(self.coefficients, np.float64)
        if exps.ndim != 2 or exps.shape[1] not in (2, 3):
            raise error("exponents", "an integer array of shape (d, 2) or (d, 3)", f"shape {exps.shape}")
        if coef.shape != (exps.shape[0],):
            raise error("coefficients", f"{exps.shape[0]} values, one per exponent row", f"shape {coef.shape}")
        if not np.isfinite(coef).all():
            raise error("coefficients", "finite values", "NaN or inf")
        degree = int(exps.sum(axis=1).max())
        if not np.array_equal(exps, basis.exponents(exps.shape[1], degree)):
            raise error("exponents", "the graded exponent table of ipfit.basis.exponents(dim, degree)",
                        "another ordering or an incomplete table",
                        "Build the polynomial with ImplicitPolynomial.from_coefficients.")
        norm = self.normalization or Normalization.identity(exps.shape[1])
        if norm.dim != exps.shape[1]:
            raise error("normalization", f"a {exps.shape[1]}D centre", f"a {norm.dim}D centre")
        object.__setattr__(self, "exponents", exps)
        object.__setattr__(self, "coefficients", coef)
        object.__setattr__(self, "normalization", norm)
        if self.measures is not None:
            measures = {k: float(v) for k, v in dict(self.measures).items()}
            object.__setattr__(self, "measures", MappingProxyType(measures))
        object.__setattr__(self, "info", MappingProxyType(dict(self.info)))

    # -- construction -------------------------------------------------------------------
    @classmethod
    def from_coefficients(cls, coefficients: ArrayLike, dim: int, normalization: Normalization | None = None,
                          **kwargs) -> ImplicitPolynomial:
        """Build from a coefficient vector in graded order; the degree follows from its length."""
        coef = np.asarray(coefficients, dtype=np.float64).ravel()
        try:
            degree = basis.degree_from_n_coefficients(dim, coef.size)
        except ValueError:
            raise error("coefficients", f"a length C(g+{dim}, {dim}) for some degree g (e.g. "
                        + ", ".join(str(basis.n_coefficients(dim, g)) for g in (1, 2, 4, 6)) + ")",
                        f"length {coef.size}") from None
        # None is the identity (__post_init__); mypy's __init__ takes the field's type, Normalization
        return cls(basis.exponents(dim, degree), coef, normalization, **kwargs)  # type: ignore[arg-type]

    def with_coefficients(self, coefficients: ArrayLike, **changes) -> ImplicitPolynomial:
        """A copy with other coefficients (same basis and normalisation)."""
        return replace(self, coefficients=np.asarray(coefficients, dtype=np.float64), **changes)

    # -- properties ---------------------------------------------------------------------
    @property
    def dim(self) -> int:
        return int(self.exponents.shape[1])

    @property
    def degree(self) -> int:
        return int(self.exponents.sum(axis=1).max())

    @property
    def n_coefficients(self) -> int:
        return int(self.exponents.shape[0])

    @property
    def center(self) -> NDArray[np.float64]:
        return self.normalization.center

    @property
    def scale(self) -> float:
        return self.normalization.scale

    # -- evaluation ---------------------------------------------------------------------
    def _normalised(self, points: ArrayLike) -> NDArray[np.float64]:
        pts = as_points(points, "points", dims=(self.dim,))
        return self.normalization.apply(pts)

    def evaluate_normalized(self, u: NDArray[np.float64], gradient: bool = False):
        """f (and ∇_u f) at points already in normalised coordinates, block by block."""
        n = u.shape[0]
        values = np.empty(n)
        grads = np.empty((n, self.dim)) if gradient else None
        degree = self.degree
        for start in range(0, n, _CHUNK):
            block = u[start:start + _CHUNK]
            if grads is not None:  # gradient
                m, dm = basis.monomials_and_gradients(block, degree)
                grads[start:start + _CHUNK] = (dm @ self.coefficients).T
            else:
                m = basis.monomials(block, self.exponents)
            values[start:start + _CHUNK] = m @ self.coefficients
        return (values, grads) if gradient else values

    def __call__(self, points: ArrayLike) -> NDArray[np.float64]:
        """f at ``points`` (N, dim) in user coordinates."""
        return self.evaluate_normalized(self._normalised(points))

    def gradient(self, points: ArrayLike) -> NDArray[np.float64]:
        """∇f at ``points`` in user coordinates (chain rule through the scale), shape (N, dim)."""
        _, grads = self.evaluate_normalized(self._normalised(points), gradient=True)
        return grads / self.scale

    def value_and_gradient(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        values, grads = self.evaluate_normalized(self._normalised(points), gradient=True)
        return values, grads / self.scale

    def taubin_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """First-order distance |f| / ||∇f|| in user units (Taubin 1994; Sampson's distance).

        The distance to the zero set to first order: exact on a line or plane, close to the true
        distance near the zero set, and the residual of :meth:`residuals`.

        It is computed in normalised coordinates (the scale times |f| / ||∇_u f||), where f and
        ∇f are of order one on the data. Where the gradient is zero it is 0 if f = 0 too (a
        singular point of the zero set) and inf otherwise. Far from the data, where f and ∇f
        overflow but their ratio does not, every term is divided by the largest power of the
        point's coordinates first, so points of 1e200 give finite distances; no warnings.

        >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
        >>> circle.taubin_distance([[2.0, 0.0], [0.0, 0.0], [1e200, 0.0]]).tolist()  # |x² − 1| / |2x|
        [0.75, inf, 5e+199]
        """
        u = self._normalised(points)
        with np.errstate(over="ignore", invalid="ignore"):
            values, grads = self.evaluate_normalized(u, gradient=True)
        stretch = np.ones(len(u))
        far = ~(np.isfinite(values) & np.isfinite(grads).all(axis=1))
        if far.any():
            values[far], grads[far], stretch[far] = self._rescaled_value_and_gradient(u[far])
        length = row_norms(grads)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            ratio = np.where(length > 0, np.abs(values) / np.where(length > 0, length, 1.0),
                             np.where(values == 0, 0.0, np.inf))
            return ratio * stretch * self.scale

    def residuals(self, points: ArrayLike) -> NDArray[np.float64]:
        """Per-point residuals: the first-order distance :meth:`taubin_distance`, shape (N,).

        The name scikit-image's model protocol uses (``skimage.measure.ransac`` compares these
        to its ``residual_threshold``), in the data's own units; see
        :class:`ipfit.ImplicitPolynomialModel`.

        >>> circle = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
        >>> circle.residuals([[2.0, 0.0], [0.0, 0.5]]).tolist()  # |4 − 1| / 4, |0.25 − 1| / 1
        [0.75, 0.75]
        """
        return self.taubin_distance(points)

    def _rescaled_value_and_gradient(self, u: NDArray[np.float64]):
        """f / (c t^g) and ∇_u f / (c t^(g−1)) at u = t v, and t, for points where f or ∇f overflow.

        t = max(max_j |u_j|, 1) and c the largest |coefficient|: the term of degree k becomes
        (a_k / c) t^(k − g) v^k with |v| <= 1, none larger than one, and the ratio |f| / ||∇f||
        is t times that of the two returned values.
        """
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            t = np.maximum(np.max(np.abs(u), axis=1), 1.0)
            t = np.where(np.isfinite(t), t, np.inf)
            biggest = float(np.max(np.abs(self.coefficients)))
            coef = self.coefficients / biggest if biggest > 0 else self.coefficients
            lowered = self.exponents.sum(axis=1) - self.degree  # <= 0
            values = np.empty(len(u))
            grads = np.empty((len(u), self.dim))
            for start in range(0, len(u), _CHUNK):
                stop = start + _CHUNK
                v = u[start:stop] / t[start:stop, None]
                m, dm = basis.monomials_and_gradients(v, self.degree)
                weighted = coef * t[start:stop, None] ** lowered
                values[start:stop] = np.einsum("nk,nk->n", m, weighted)
                grads[start:stop] = np.einsum("dnk,nk->nd", dm, weighted)
        # a coordinate beyond float range (u of inf) has no direction left: it is infinitely far
        lost = ~np.isfinite(t) | ~np.isfinite(values) | ~np.isfinite(grads).all(axis=1)
        values[lost], grads[lost] = np.inf, 1.0
        return values, grads, np.where(lost, 1.0, t)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """True where f < 0: inside the shape for a canonical polynomial (f > 0 outside)."""
        return self(points) < 0

    # -- canonical form -----------------------------------------------------------------
    def canonical(self, points: ArrayLike | None = None, normals: ArrayLike | None = None) -> ImplicitPolynomial:
        """Unit-norm coefficients with the sign that makes f > 0 outside.

        With ``normals`` (and their ``points``) the sign makes ∇f agree with the normals on
        average; without them, f is made positive on most of a sphere far from the data.
        """
        coef = self.coefficients
        norm = float(np.linalg.norm(coef))
        if norm == 0:
            return self
        coef = coef / norm
        probe = self.with_coefficients(coef)
        if normals is not None and points is not None:
            pts = as_points(points, "points", dims=(self.dim,))
            agreement = float(np.sum(probe.gradient(pts) * as_matching(normals, pts)))
            sign = -1.0 if agreement < 0 else 1.0
        else:
            directions = _sphere_directions(self.dim)
            values = probe.evaluate_normalized(4.0 * directions)
            sign = -1.0 if np.sum(np.sign(values)) < 0 else 1.0
        return probe.with_coefficients(sign * coef)

    # -- JSON ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        out: dict[str, Any] = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "dim": self.dim,
            "degree": self.degree,
            "exponents": self.exponents.tolist(),
            "coefficients": [float(c) for c in self.coefficients],
            "normalization": self.normalization.to_dict(),
            "method": self.method,
        }
        if self.measures is not None:
            out["measures"] = dict(self.measures)
        if self.info:
            out["info"] = to_jsonable(dict(self.info))
        return out

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def save(self, path: str | os.PathLike) -> None:
        """Write the JSON result atomically (temporary file, then rename)."""
        from ._utils.atomic import write_text_atomic

        validate_result(self.to_dict(), "polynomial")  # never write a file that cannot be read back
        write_text_atomic(path, self.to_json())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "result") -> ImplicitPolynomial:
        """The final polynomial of a result's JSON object, validated completely first.

        Every key of ``docs/result-format.md`` is checked (see :mod:`ipfit.degree.results`), so a
        corrupt file gives one :class:`~ipfit.InvalidInputError` naming the bad key.
        """
        data = validate_result(data, source)
        if isinstance(data.get("objects"), list):  # a scene (ipfit fit --objects): one result per object
            raise InvalidInputError(f"{source}: a scene of {len(data['objects'])} objects, not one polynomial. Read "
                                    "it with ipfit.load_scene, or pick one of its \"objects\".")
        norm = data.get("normalization")
        normalization = Normalization(norm["center"], norm["scale"]) if norm else None
        measures = data.get("measures")
        if measures is not None:
            measures = {k: v for k, v in measures.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        # None is the identity (__post_init__); mypy's __init__ takes the field's type, Normalization
        return cls(data["exponents"], data["coefficients"], normalization,  # type: ignore[arg-type]
                   method=data.get("method"), measures=measures, info=data.get("info") or {})

    @classmethod
    def from_json(cls, text: str | bytes) -> ImplicitPolynomial:
        """The final polynomial of a result's JSON text."""
        if isinstance(text, bytes):
            text = text.decode("utf-8", errors="replace")
        if not isinstance(text, str):
            raise error("text", "the JSON text of an ipfit result (str or bytes)", type(text).__name__,
                        "Use ImplicitPolynomial.load(path) for a file.")
        return cls.from_dict(parse_result_text(text, "JSON"), source="JSON")

    @classmethod
    def load(cls, path: str | os.PathLike) -> ImplicitPolynomial:
        """Read a JSON result written by :meth:`save` or ``ipfit fit`` (extra keys are ignored)."""
        if not isinstance(path, (str, os.PathLike)):
            raise error("path", "a path to a result JSON", type(path).__name__)
        data = read_result_json(path)
        try:
            return cls.from_dict(data, source=str(path))
        except InvalidInputError as exc:
            raise ReadError(str(exc)) from None

    def __repr__(self) -> str:
        return (f"ImplicitPolynomial(dim={self.dim}, degree={self.degree}, "
                f"n_coefficients={self.n_coefficients}, method={self.method!r})")

    # -- using the polynomial (ipfit.codegen, rays, projection, curvature) -----------------
    def to_source(self, language: str) -> str:
        """Standalone source of f and ∇f: see :func:`ipfit.to_source`."""
        from .analysis.codegen import to_source

        return to_source(self, language)

    def intersect_rays(self, origins: ArrayLike, directions: ArrayLike, tmin: float = 0.0, tmax: float = math.inf):
        """Every intersection of rays with the zero set: see :func:`ipfit.intersect_rays`."""
        from .analysis.rays import intersect_rays

        return intersect_rays(origins, directions, self, tmin, tmax)

    def project(self, points: ArrayLike):
        """Closest points on the zero set and true distances: see :func:`ipfit.project`."""
        from .analysis.projection import project

        return project(self, points)

    def curvature(self, points: ArrayLike):
        """Curvatures of the level set through ``points``: see :func:`ipfit.analysis.curvature.curvature`."""
        from .analysis.curvature import curvature

        return curvature(self, points)

    def hessian(self, points: ArrayLike) -> NDArray[np.float64]:
        """Hessian of f at ``points``, shape (N, dim, dim): see :func:`ipfit.hessian`."""
        from .analysis.curvature import hessian

        return hessian(self, points)


def _sphere_directions(dim: int, n: int = 64) -> NDArray[np.float64]:
    if dim == 2:
        t = 2 * np.pi * (np.arange(n) + 0.5) / n
        return np.column_stack([np.cos(t), np.sin(t)])
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5 ** 0.5) * i
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def to_jsonable(value):
    """JSON-ready copy: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [to_jsonable(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value

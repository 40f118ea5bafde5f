"""scikit-image's model protocol: an implicit polynomial that ``skimage.measure.ransac`` can fit.

:class:`ImplicitPolynomialModel` fits a polynomial of a fixed degree to a sample of points by a
linear fit that needs no normals (Taubin's by default) and gives every point its first-order
distance to the zero set as residual (:meth:`ipfit.ImplicitPolynomial.residuals`). It speaks
both dialects of ``ransac``: scikit-image 0.26's class method ``from_estimate(data)``, whose
result is truthy when the fit succeeded, and the older ``model = cls(); model.estimate(data)``.

``ransac`` takes a class, not an instance, so the degree and the method are class attributes:
:meth:`ImplicitPolynomialModel.for_degree` makes the class of another degree or method.

>>> import numpy as np
>>> from skimage.measure import ransac
>>> from ipfit.fitting.model import ImplicitPolynomialModel
>>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
>>> points = np.vstack([np.column_stack([3 + 2 * np.cos(t), 1 + 2 * np.sin(t)]), [[9.0, 9.0], [0.0, 7.0]]])
>>> model, inliers = ransac(points, ImplicitPolynomialModel, ImplicitPolynomialModel.min_samples(2),
...                         residual_threshold=0.01, rng=0)
>>> int(inliers.sum()), model.polynomial.degree
(40, 2)
>>> model.residuals([[5.0, 1.0], [6.0, 1.0]]).round(6).tolist()  # on the circle; (3² − 2²) / (2·3)
[0.0, 0.833333]
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.validation import as_points, check_choice, check_degree, error
from ..exceptions import InvalidInputError
from ..polynomial import ImplicitPolynomial, Normalization
from .linear import LINEAR_METHODS, _fit_problem, _lstsq_blocks, _Problem

__all__ = ["ImplicitPolynomialModel", "MODEL_METHODS"]

#: The linear fits a model can use: those that need no normals (a sample of bare points has none).
MODEL_METHODS = tuple(name for name, spec in LINEAR_METHODS.items() if not spec.needs_normals)

# A sample determines its polynomial when the monomials on it have rank d − 1 (a one-dimensional
# null space: the polynomial up to its scale). On exactly degenerate samples (collinear points for
# a conic, even 100,000 of them; exact circle points for a quartic) the (d − 1)-th singular value
# is rounding, below 4e-16 of the largest; on minimal samples of random points it stayed above
# 7e-4 for conics, 1e-6 for quartic curves and 4e-8 for quartic surfaces (200 samples each).
# Only degree 8 and above curves come near the cut-off, on samples too ill-conditioned to use.
_RANK_TOL = 1e-12


class ImplicitPolynomialModel:
    """An implicit polynomial curve or surface as a scikit-image model, for ``ransac``.

    The class attributes ``degree`` (default 2: conics and quadrics) and ``method`` (default
    ``"taubin"``, or ``"lstsq"``) set the fit; :meth:`for_degree` makes the class of another.

    ``from_estimate(data)`` fits the (N, 2) or (N, 3) points ``data`` and returns a model that
    is truthy, with the fitted :class:`~ipfit.ImplicitPolynomial` as ``polynomial``; a sample
    that does not determine one polynomial (too few points, all on a line or a lower-degree
    curve, repeated points) gives a falsy model whose ``message`` says why, never an error, so
    ``ransac`` draws another sample. ``residuals(data)`` is every point's first-order distance
    |f| / ||∇f|| to the zero set, in the data's units (``ransac``'s ``residual_threshold`` is
    one of them).

    The minimal sample, ``min_samples(dim)``, is the number of coefficients minus one (the
    polynomial is defined up to its scale): 5 points for a conic, 9 for a quadric, 14 for a
    quartic curve, 34 for a quartic surface. Exact points of a lower-degree shape (a circle for
    a degree-4 model) do not determine the polynomial either (any multiple of the circle's
    polynomial fits them) and fail too; noisy ones fit.

    Parameters
    ----------
    polynomial : ImplicitPolynomial or None
        The fitted polynomial; None for a model not fitted yet (``cls()`` then ``estimate``, the
        protocol of scikit-image before 0.26) or a failed estimate.
    message : str
        Why the estimate failed (empty otherwise).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> model = ImplicitPolynomialModel.from_estimate(np.column_stack([np.cos(t), np.sin(t)]))
    >>> bool(model), model.residuals([[2.0, 0.0]]).round(12).tolist()  # |4 − 1| / ||(4, 0)||
    (True, [0.75])
    >>> failed = ImplicitPolynomialModel.from_estimate(np.column_stack([t, 2 * t]))  # on a line
    >>> bool(failed), failed.message
    (False, '12 points that do not determine a degree-2 polynomial (on a curve of lower degree, or repeated)')
    >>> Quartic = ImplicitPolynomialModel.for_degree(4)
    >>> Quartic.degree, Quartic.min_samples(2), Quartic.min_samples(3)
    (4, 14, 34)
    """

    degree: ClassVar[int] = 2
    method: ClassVar[str] = "taubin"

    def __init__(self, polynomial: ImplicitPolynomial | None = None, message: str = "") -> None:
        if polynomial is not None and not isinstance(polynomial, ImplicitPolynomial):
            raise error("polynomial", "an ImplicitPolynomial or None", type(polynomial).__name__)
        self.polynomial = polynomial
        self.message = str(message)

    # -- the classes of other degrees and methods --------------------------------------------
    @classmethod
    def for_degree(cls, degree: int, method: str = "taubin") -> type[ImplicitPolynomialModel]:
        """The model class that fits polynomials of ``degree`` by the linear fit ``method``.

        ``method`` is one of :data:`MODEL_METHODS` (``"taubin"``, ``"lstsq"``).

        >>> Model = ImplicitPolynomialModel.for_degree(4, method="lstsq")
        >>> Model.__name__, Model.degree, Model.method, issubclass(Model, ImplicitPolynomialModel)
        ('ImplicitPolynomialModel4Lstsq', 4, 'lstsq', True)
        """
        degree = check_degree(degree)
        top = max(basis.MAX_DEGREE.values())
        if degree > top:
            raise error("degree", f"at most {top} (ipfit's limit)", str(degree), "Lower the degree.")
        method = check_choice(method, "method", MODEL_METHODS)
        name = f"ImplicitPolynomialModel{degree}{method.title()}"
        return type(name, (cls,), {"degree": degree, "method": method, "__module__": cls.__module__,
                                   "__qualname__": name, "__doc__": cls.__doc__})

    @classmethod
    def min_samples(cls, dim: int) -> int:
        """The smallest sample that determines a polynomial: its number of coefficients minus one."""
        if isinstance(dim, bool) or dim not in (2, 3):
            raise error("dim", "2 or 3", repr(dim))
        return basis.n_coefficients(dim, cls.degree) - 1

    # -- scikit-image's protocol ----------------------------------------------------------------
    @classmethod
    def from_estimate(cls, data: ArrayLike) -> ImplicitPolynomialModel:
        """Fit ``data`` (N, dim): a truthy model, or a falsy one with the ``message`` why not."""
        polynomial, message = cls._fit(data)
        return cls(polynomial, message)

    def estimate(self, data: ArrayLike) -> bool:
        """Fit ``data`` in place and say whether it succeeded (scikit-image before 0.26)."""
        self.polynomial, self.message = self._fit(data)
        return self.polynomial is not None

    def residuals(self, data: ArrayLike) -> NDArray[np.float64]:
        """First-order distance |f| / ||∇f|| of every point of ``data`` to the zero set, shape (N,)."""
        if self.polynomial is None:
            raise error("model", "a fitted model", f"a failed or missing estimate ({self.message or 'not fitted'})",
                        "Check bool(model) before using it.")
        return self.polynomial.residuals(data)

    def __bool__(self) -> bool:
        return self.polynomial is not None

    def __repr__(self) -> str:
        what = repr(self.polynomial) if self.polynomial is not None else f"failed: {self.message or 'not fitted'}"
        return f"{type(self).__name__}(degree={self.degree}, method={self.method!r}, {what})"

    # -- the fit -----------------------------------------------------------------------------
    @classmethod
    def _fit(cls, data: ArrayLike) -> tuple[ImplicitPolynomial | None, str]:
        """(polynomial, "") or (None, why not). Bad arguments raise; bad samples do not."""
        pts = as_points(data, "data", min_points=0)
        dim, degree = pts.shape[1], cls.degree
        if degree > basis.MAX_DEGREE[dim]:
            raise error("degree", f"at most {basis.MAX_DEGREE[dim]} in {dim}D (ipfit's limit)", str(degree),
                        "Use ImplicitPolynomialModel.for_degree with a lower degree.")
        need = cls.min_samples(dim)
        if len(pts) < need:
            return None, f"{len(pts)} points for a degree-{degree} {dim}D polynomial (at least {need} needed)"
        try:
            norm = Normalization.from_points(pts)
        except InvalidInputError:
            return None, f"{len(pts)} copies of one point"
        problem = _Problem(norm.apply(pts), None, norm, degree)
        # Checked before the fit, which would return one of the many polynomials through such a
        # sample (a line times any other line, for a conic through collinear points).
        with np.errstate(all="ignore"):
            singular = np.linalg.svd(problem.r_of(_lstsq_blocks), compute_uv=False)
        if not (singular.size >= need and np.isfinite(singular).all() and singular[need - 1] > _RANK_TOL * singular[0]):
            return None, (f"{len(pts)} points that do not determine a degree-{degree} polynomial "
                          "(on a curve of lower degree, or repeated)")
        try:
            return _fit_problem(cls.method, problem, {}), ""
        except InvalidInputError as exc:  # a degenerate system the rank test let through
            return None, str(exc)

"""Result JSON: read, validate and write it, and get at the polynomials it holds.

A result is the JSON object ``ipfit fit`` writes (``ImplicitPolynomial.save`` writes its
first keys). Its keys are one written schema, :data:`SCHEMA`, documented in
``docs/result-format.md``; every reader of results (``ImplicitPolynomial.load``, the
``mesh``, ``plot`` and ``score`` commands, :func:`ipfit.viz.plotting.plot_result`) goes
through :func:`validate_result`, so a corrupt file gives one line naming the bad key.

* :func:`load_result` — a path, JSON text, dict or polynomial → the validated dict;
* :func:`result_view` — the same → a :class:`ResultView` holding the final polynomial,
  the fit of every degree tried, the comparison fits and the data's box;
* :func:`dumps_result` / :func:`write_result` — a dict → validated JSON text / file.

A view also reads the points a fit treated as outliers (:attr:`ResultView.outlier_indices`)
and matches them to the data drawn with it (:meth:`ResultView.outlier_mask`).

>>> from ipfit.datasets import synthetic
>>> data = synthetic.circle().polynomial.to_dict()
>>> data["degrees"] = [{"degree": 2, "smoothness": 1.0, "coefficients": data["coefficients"]}]
>>> view = result_view(data)
>>> view.polynomial.degree, [d.degree for d in view.degrees], view.fixed_degree
(2, [2], True)
>>> load_result({**data, "selected_degree": "x"})  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
ipfit.exceptions.InvalidInputError: result: "selected_degree": expected a whole number >= 1, got the string "x". ...
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._result_schema import (
    FORMAT_NAME,
    FORMAT_VERSION,
    MAX_COORDINATE,
    MAX_DEGREE,
    MAX_DEPTH,
    SCHEMA,
    Key,
    parse_result_text,
    read_result_json,
    schema_markdown,
    validate_result,
)
from .._utils.atomic import write_text_atomic
from .._utils.validation import error
from ..exceptions import InvalidInputError, IpfitWarning, ReadError
from ..polynomial import ImplicitPolynomial, Normalization, to_jsonable

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "MAX_DEGREE", "MAX_COORDINATE", "MAX_DEPTH", "SCHEMA", "Key",
           "validate_result", "load_result", "result_view",
           "ResultView", "DegreeFit", "dumps_result", "write_result", "read_result_json", "schema_markdown"]


def _is_path(result: Any) -> bool:
    return isinstance(result, os.PathLike) or (isinstance(result, str) and not result.lstrip().startswith("{"))


def _source_of(result: Any) -> str:
    return str(result) if _is_path(result) else "result"


def load_result(result: Any, source: str | None = None) -> dict:
    """A result as its validated JSON object.

    Parameters
    ----------
    result : path (str or PathLike) to a result JSON, JSON text (a str starting with
        ``{``), a dict, or an object with ``to_dict()`` (an ImplicitPolynomial or an
        AdaptiveResult).
    source : the name used in error messages (default: the path, or "result").

    Returns
    -------
    dict
        The JSON object, checked against :data:`SCHEMA` (a dict passed in is returned
        as a plain dict, not copied deeply).

    Raises
    ------
    ReadError
        When a file cannot be read or is not a valid result (the message starts with its path).
    InvalidInputError
        When text or a dict is not a valid result.
    """
    source = source or _source_of(result)
    if _is_path(result):
        data = read_result_json(result)
        try:
            return validate_result(data, source)
        except InvalidInputError as exc:
            raise ReadError(str(exc)) from None
    if isinstance(result, (str, bytes)):
        text = result.decode("utf-8", errors="replace") if isinstance(result, bytes) else result
        return validate_result(parse_result_text(text, source), source)
    if isinstance(result, Mapping):
        return validate_result(dict(result), source)
    if callable(getattr(result, "to_dict", None)):
        return validate_result(result.to_dict(), source)
    raise error("result", "a path to a result JSON, JSON text, a dict or an ImplicitPolynomial",
                "None" if result is None else type(result).__name__)


def dumps_result(data: Mapping[str, Any], indent: int | None = 1) -> str:
    """Validated JSON text of a result (standard JSON: non-finite numbers become null)."""
    data = to_jsonable(data)
    validate_result(data, "result")
    return json.dumps(data, indent=indent, allow_nan=False)


def write_result(path: str | os.PathLike, data: Mapping[str, Any]) -> None:
    """Validate ``data`` and write it to ``path`` atomically (nothing is written when invalid)."""
    write_text_atomic(path, dumps_result(data))


@dataclass(frozen=True)
class DegreeFit:
    """One entry of a result's ``degrees``: its polynomial (None without coefficients) and the raw entry."""

    degree: int
    polynomial: ImplicitPolynomial | None
    entry: Mapping[str, Any]


@dataclass(frozen=True)
class ResultView:
    """The polynomials of a validated result, whether a plain polynomial or an adaptive run.

    Attributes
    ----------
    data : the validated JSON object (read-only view).
    source : the name used in messages (the file's path, or "result").
    polynomial : the final (selected) polynomial.
    degrees : one :class:`DegreeFit` per degree tried, in order (empty for a plain polynomial).
    selected_degree : the degree chosen, or None.
    comparisons : name → polynomial of the comparison fits (classic linear, 3L, ...).
    bounds : (dim, 2) box of the data, or None.
    """

    data: Mapping[str, Any]
    source: str
    polynomial: ImplicitPolynomial
    degrees: tuple[DegreeFit, ...] = ()
    selected_degree: int | None = None
    comparisons: Mapping[str, ImplicitPolynomial] = field(default_factory=dict)
    bounds: NDArray[np.float64] | None = None

    @property
    def dim(self) -> int:
        return self.polynomial.dim

    @property
    def fixed_degree(self) -> bool:
        """True when the degree was fixed (``ipfit fit --degree``), or the result holds one
        polynomial and no search: there is no degree search to show. A search that stopped
        after its first degree is not fixed (its degree was selected)."""
        adaptive = self.data.get("adaptive")
        if isinstance(adaptive, Mapping) and "reason" in adaptive:
            return adaptive["reason"] == "fixed"
        return len(self.degrees) <= 1

    @property
    def input(self) -> Mapping[str, Any]:
        """The ``input`` record (source, path, n_points, normals); empty when absent."""
        return self.data.get("input") or {}

    @property
    def outliers(self) -> Mapping[str, Any]:
        """The ``outliers`` record (mode, count, share, noise_scale, indices); empty when absent."""
        return self.data.get("outliers") or {}

    @property
    def outlier_indices(self) -> NDArray[np.int64] | None:
        """The points the fit treated as outliers (0-based, into the fitted points, sorted), or
        None when the result records no indices (no ``outliers`` section, or one without them)."""
        indices = self.outliers.get("indices")
        if indices is None:
            return None
        # The schema has checked them: whole numbers >= 0 (2.0 included) that float64 holds. Clipped
        # so that 1e300 stays a huge index (beyond any cloud) instead of overflowing int64.
        return np.unique(np.clip(np.asarray(indices, dtype=np.float64), 0, 2.0 ** 62).astype(np.int64))

    def outlier_mask(self, n_points: int) -> NDArray[np.bool_] | None:
        """Which of ``n_points`` rows of data are the recorded outliers, or None.

        None when the result records no outliers (no section, count 0 or no indices), and
        when the rows cannot be the fitted points: then an :class:`IpfitWarning` says why
        (the caller draws every point as data). The indices count the *fitted* points, so
        the rows must be exactly those: ``input.n_points`` of them when the result records
        it; without it (a dict from :meth:`AdaptiveResult.to_dict`), every index must fall
        among the rows and, when the result records the share, ``count / n_points`` must be
        that share (to float rounding: one row more or less changes it by 1/n). A subsample
        or another file fails one of these.
        """
        record = self.outliers
        indices = self.outlier_indices
        if indices is None or not len(indices) or record.get("count", len(indices)) == 0:
            return None
        n_points = int(n_points)
        count = int(record.get("count", len(indices)))
        fitted = self.input.get("n_points")
        share = record.get("share")
        why = None
        if fitted is not None and int(fitted) != n_points:
            why = f"it fitted {int(fitted)} points"
        elif indices[-1] >= n_points:
            why = f"its outlier indices run up to {int(indices[-1])}"
        elif fitted is None and isinstance(share, (int, float)) and not math.isclose(share, count / n_points,
                                                                                   rel_tol=1e-9):
            # share = count / n exactly (to float rounding): one row more or less changes it by 1/n
            why = f"its {count} outliers are a share of {share:.6g} of the points it fitted"
        if why is not None:
            warnings.warn(f"{self.source}: outliers not marked: {why}, but {n_points} points were given, so "
                          "they cannot be the fitted points; every point is drawn as data. Pass the points "
                          "that were fitted to see the outliers.", IpfitWarning, stacklevel=3)
            return None
        mask = np.zeros(n_points, dtype=bool)
        mask[indices] = True
        return mask

    def fit(self, degree: int | None = None, name: str = "degree") -> ImplicitPolynomial:
        """The final polynomial, or the fit of ``degree`` from the per-degree table.

        ``name`` is the parameter named in the error when there is no such fit.
        """
        if degree is None or (degree == self.polynomial.degree and not self.degrees):
            return self.polynomial
        for entry in self.degrees:
            if entry.degree == degree and entry.polynomial is not None:
                return entry.polynomial
        tried = ", ".join(str(d.degree) for d in self.degrees if d.polynomial is not None) or "none"
        raise error(name, f"a degree with coefficients in {self.source} ({tried})", str(degree),
                    "Pick one of those.")


def result_view(result: Any, source: str | None = None) -> ResultView:
    """Read a result (see :func:`load_result` for what it accepts) into a :class:`ResultView`.

    A :class:`ResultView` is returned as it is: its messages keep naming its file.
    """
    if isinstance(result, ResultView):
        return result
    source = source or _source_of(result)
    data = load_result(result, source)
    kind = ReadError if _is_path(result) else InvalidInputError
    if isinstance(data.get("objects"), list):  # a scene holds one result per object, no polynomial of its own
        raise kind(f"{source}: a scene of {len(data['objects'])} objects, not one polynomial. Read it with "
                   "ipfit.load_scene, or pick one of its \"objects\".")
    poly = ImplicitPolynomial.from_dict(data, source)

    def build(coefficients, own_norm) -> ImplicitPolynomial:
        # Entries share the top-level normalisation unless they carry their own.
        norm = Normalization(own_norm["center"], own_norm["scale"]) if own_norm else poly.normalization
        return ImplicitPolynomial.from_coefficients(coefficients, poly.dim, normalization=norm)

    try:
        degrees = tuple(DegreeFit(int(e["degree"]), build(e["coefficients"], e.get("normalization"))
                                  if e.get("coefficients") is not None else None, MappingProxyType(dict(e)))
                        for e in data.get("degrees") or ())
        comparisons = {str(name): build(e["coefficients"], e.get("normalization"))
                       for name, e in (data.get("comparisons") or {}).items()}
    except InvalidInputError as exc:  # the schema has checked them; this only guards the constructors
        raise kind(f"{source}: {exc}") from None
    bounds = data.get("bounds")
    selected = data.get("selected_degree")
    return ResultView(MappingProxyType(data), source, poly, degrees, int(selected) if selected is not None else None,
                      MappingProxyType(comparisons),
                      np.asarray(bounds, dtype=np.float64) if bounds is not None else None)

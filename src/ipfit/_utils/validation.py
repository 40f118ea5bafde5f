"""Argument checking shared by every public function: one module, one message template.

Messages follow ``"{name}: expected {expected}, got {got}. {fix}"`` so that every error
names the parameter, what was expected, what came and what to do.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Mapping
from collections.abc import Set as AbstractSet
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..exceptions import error  # the one message template; imported from here throughout
from .foreign import foreign_parts

__all__ = [
    "error",
    "as_points",
    "as_normals",
    "as_matching",
    "check_real_dtype",
    "as_faces",
    "as_weights",
    "check_degree",
    "check_real",
    "check_positive",
    "check_nonnegative",
    "check_probability",
    "check_int",
    "check_choice",
    "check_rng",
    "check_enough_points",
]


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    text = " ".join(repr(value).split())  # one line: a DataFrame's repr spans many
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" if count == 1 else f"{count} {word}s"


# Dtype kinds refused by as_points, as a user would name them, and the fix: float64 conversion
# would silently turn each of them into numbers that were never coordinates.
_AS_NUMBERS = "Pass the coordinates as numbers (e.g. converted with .astype(float))."
_REFUSED_KINDS = {"b": ("booleans", "Pass coordinates, not a mask: e.g. points[mask]."),
                  "c": ("complex numbers", "Pass the real parts (or np.abs) explicitly."),
                  "O": ("Python objects", _AS_NUMBERS), "U": ("text", _AS_NUMBERS), "S": ("bytes", _AS_NUMBERS),
                  "M": ("dates", _AS_NUMBERS), "m": ("durations", _AS_NUMBERS),
                  "V": ("structured records", _AS_NUMBERS)}


def as_points(points: ArrayLike, name: str = "points", *, dims=(2, 3), min_points: int = 1) -> NDArray[np.float64]:
    """Return ``points`` as a C-contiguous float64 array of shape (N, D), D in ``dims``.

    Accepted: arrays and nested lists of real numbers (integers or floats of any width, also
    ``np.matrix``, without a warning); masked arrays with no element masked; pandas DataFrames
    with columns named x, y[, z] (nx, ny[, nz] when ``name`` is "normals"), in any case, the
    other columns ignored; the points of trimesh, Open3D and PyVista objects
    (:mod:`ipfit._utils.foreign`). Refused, each with one :class:`InvalidInputError` line naming
    ``name``: booleans, complex numbers, text, dates, Python objects and ragged lists; other
    DataFrames; masked arrays with masked elements (drop those rows first with
    ``np.ma.compress_rows``: a masked coordinate has no value to fit); generators and iterators
    (they can be read only once); None; scalars, 1-D or 3-D arrays, a column count not in
    ``dims``; fewer than ``min_points`` rows; NaN or infinite coordinates.
    """
    arr = _real_array(points, name, dims)
    if arr.ndim != 2 or arr.shape[1] not in dims:
        dim_text = " or ".join(f"(N, {d})" for d in dims)
        raise error(name, f"an array of shape {dim_text}", f"shape {arr.shape}",
                    "Pass one point per row with its coordinates as columns.")
    if arr.shape[0] < min_points:
        raise error(name, f"at least {_plural(min_points, 'point')}", f"{arr.shape[0]}", "Pass more points.")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise error(name, "finite coordinates", f"{int(bad.sum())} rows with NaN or inf (first at row {first})",
                    "Remove or repair those rows.")
    return np.ascontiguousarray(arr)


def _real_array(value: Any, name: str, dims) -> NDArray[np.float64]:
    """``value`` as a float64 array of any shape, or the error saying why it holds no coordinates."""
    expected = " or ".join(f"(N, {d})" for d in dims)
    expected = f"an {expected} array of numbers"
    if value is None:
        raise error(name, expected, "None", "Pass the points.")
    if isinstance(value, (str, bytes)):
        raise error(name, expected, _describe(value), "To read a file of points, use ipfit.read_points(path).")
    if isinstance(value, Iterator):  # consumed by a first pass, it would be empty at the next
        raise error(name, expected, f"an iterator ({type(value).__name__})",
                    "Materialise it first: np.array(list(points)).")
    if isinstance(value, (Mapping, AbstractSet)):
        raise error(name, expected, f"a {type(value).__name__}", "Pass a list or an array with one point per row.")
    if hasattr(value, "columns") and hasattr(value, "to_numpy"):
        return _frame_coordinates(value, name)
    parts = foreign_parts(value, name)  # a trimesh, Open3D or PyVista object: its points
    if parts is not None:
        value = parts.points
    if isinstance(value, np.ma.MaskedArray):
        masked = np.ma.getmaskarray(value)
        rows = masked.reshape(len(masked), -1).any(axis=1) if masked.ndim else masked.reshape(1)
        if rows.any():
            first = int(np.flatnonzero(rows)[0])
            raise error(name, "a masked array with no masked values",
                        f"{_plural(int(rows.sum()), 'row')} with masked values (first at row {first})",
                        "Drop them first: np.ma.compress_rows(points).")
        value = np.ma.getdata(value)
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nested lists
        raise error(name, expected, _describe(value), "Pass a numeric array with one point per row.") from None
    check_real_dtype(arr, name, expected)
    return arr.astype(np.float64, copy=False)


def check_real_dtype(arr: Any, name: str, expected: str = "an array of numbers") -> None:
    """Refuse an array (numpy, Dask...) whose dtype holds no real numbers: booleans, text..."""
    if arr.dtype.kind in _REFUSED_KINDS:
        what, fix = _REFUSED_KINDS[arr.dtype.kind]
        expected = "real coordinates" if arr.dtype.kind == "c" else expected  # numbers, but not real ones
        raise error(name, expected, f"{what} (an array of shape {arr.shape} and dtype {arr.dtype})", fix)


def _frame_coordinates(frame: Any, name: str) -> NDArray[np.float64]:
    """The x, y[, z] columns of a DataFrame (nx, ny[, nz] for normals), matched in any case."""
    axes = [("n" if name == "normals" else "") + a for a in "xyz"]
    labels: dict[str, list] = {}
    for label in frame.columns:
        labels.setdefault(str(label).strip().lower(), []).append(label)
    wanted = axes if axes[2] in labels else axes[:2]
    shown = ", ".join(str(label) for label in frame.columns)
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    needed = f"a DataFrame with columns {axes[0]}, {axes[1]}[, {axes[2]}]"
    missing = [axis for axis in wanted if axis not in labels]
    if missing:
        raise error(name, needed, f"columns {shown or '(none)'}",
                    "Rename the coordinate columns, or pass frame[[...]].to_numpy().")
    twice = [axis for axis in wanted if len(labels[axis]) > 1]
    if twice:
        raise error(name, needed, f"{len(labels[twice[0]])} columns named {twice[0]} (in some case)",
                    "Keep one column per coordinate.")
    columns = [frame[labels[axis][0]] for axis in wanted]
    for axis, column in zip(wanted, columns, strict=True):
        if getattr(column.dtype, "kind", "O") not in "iuf":  # pandas' nullable dtypes have a kind too
            raise error(name, f"numeric columns {', '.join(wanted)}", f"column {axis} of dtype {column.dtype}",
                        "Convert it, e.g. with pandas.to_numeric.")
    return np.column_stack([column.to_numpy(dtype=np.float64, na_value=np.nan) for column in columns])


@overload
def as_normals(normals: None, points: NDArray[np.float64], name: str = ..., *,
               required_by: str | None = ...) -> None: ...
@overload
def as_normals(normals: ArrayLike, points: NDArray[np.float64], name: str = ..., *,
               required_by: str | None = ...) -> NDArray[np.float64]: ...
@overload
def as_normals(normals: ArrayLike | None, points: NDArray[np.float64], name: str = ..., *,
               required_by: str | None = ...) -> NDArray[np.float64] | None: ...
def as_normals(normals: ArrayLike | None, points: NDArray[np.float64], name: str = "normals",
               *, required_by: str | None = None) -> NDArray[np.float64] | None:
    """Return unit normals of the same shape as ``points`` (or None when allowed).

    Zero-length normals are an error: their direction is what the methods use.
    """
    if normals is None:
        if required_by is not None:
            raise error(name, f"an {points.shape} array of normals (required by {required_by})", "None",
                        "Pass the file's normals or ipfit.estimate_normals(points).")
        return None
    arr = as_matching(normals, points, name)
    length = np.linalg.norm(arr, axis=1)
    tiny = length <= 1e-12 * max(1.0, float(length.max(initial=0.0)))
    if tiny.any():
        first = int(np.flatnonzero(tiny)[0])
        raise error(name, "non-zero normal vectors", f"{int(tiny.sum())} zero-length normals (first at row {first})",
                    "Remove those points or estimate normals with ipfit.estimate_normals.")
    return arr / length[:, None]


def as_matching(values: ArrayLike, points: NDArray[np.float64], name: str = "normals") -> NDArray[np.float64]:
    """``values`` checked as :func:`as_points` and of the same shape as ``points``: one vector per point."""
    arr = as_points(values, name, dims=(points.shape[1],))
    if arr.shape != points.shape:
        raise error(name, f"shape {points.shape} to match the points", f"shape {arr.shape}",
                    "Pass one normal per point.")
    return arr


def as_weights(weights: ArrayLike, n_points: int, name: str = "weights") -> NDArray[np.float64]:
    """Per-point weights as a float64 (N,) array in [0, 1], not all zero: one weight per point."""
    try:
        arr = np.asarray(weights)
    except (TypeError, ValueError):
        raise error(name, f"an ({n_points},) array of numbers in [0, 1]", _describe(weights)) from None
    if arr.ndim != 1 or len(arr) != n_points or (arr.size and arr.dtype.kind not in "iuf"):
        raise error(name, f"an ({n_points},) array of numbers in [0, 1], one per point", _describe(arr))
    arr = arr.astype(np.float64)
    if not np.isfinite(arr).all():
        raise error(name, "numbers in [0, 1]", "NaN or inf")
    if arr.size and (arr.min() < 0.0 or arr.max() > 1.0):
        raise error(name, "numbers in [0, 1]", f"values in [{arr.min():g}, {arr.max():g}]",
                    "Scale the weights so that the largest is 1.")
    if arr.size and not arr.any():
        raise error(name, "at least one positive weight", "all zeros", "Weight the points that should be fitted.")
    return arr


def as_faces(faces: ArrayLike, n_points: int, dim: int = 3) -> NDArray[np.int64]:
    """Triangles as an (F, 3) integer array of row indices into ``n_points`` points."""
    if dim != 3:
        raise error("faces", "None for 2D data", "faces", "Faces describe 3D meshes; pass ordered_contour for 2D.")
    try:
        arr = np.asarray(faces)
    except (TypeError, ValueError):
        raise error("faces", "an (F, 3) integer array", type(faces).__name__) from None
    if arr.ndim != 2 or arr.shape[1] != 3 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        raise error("faces", "an (F, 3) integer array of point indices", f"shape {arr.shape}, dtype {arr.dtype}",
                    "Pass triangles; split polygons first.")
    if arr.size and (arr.min() < 0 or arr.max() >= n_points):
        raise error("faces", f"indices in [0, {n_points})", f"indices in [{arr.min()}, {arr.max()}]",
                    "Faces must index the rows of points.")
    return arr.astype(np.int64)


def check_int(value: Any, name: str, *, minimum: int | None = None, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise error(name, "an integer", _describe(value))
    value = int(value)
    if minimum is not None and value < minimum:
        raise error(name, f"an integer >= {minimum}", str(value))
    if maximum is not None and value > maximum:
        raise error(name, f"an integer <= {maximum}", str(value))
    return value


def check_degree(degree: Any, name: str = "degree") -> int:
    """A polynomial degree: an integer >= 1."""
    if isinstance(degree, bool) or not isinstance(degree, numbers.Integral):
        raise error(name, "an integer >= 1", _describe(degree), "Pass a whole number such as 4.")
    if degree < 1:
        raise error(name, "an integer >= 1", str(int(degree)), "Use degree 2, 4, 6... for closed shapes.")
    return int(degree)


def check_real(value: Any, name: str) -> float:
    # float() first: any numbers.Real converts (fractions.Fraction, decimal-backed types), while
    # numpy's isfinite refuses what it cannot cast.
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(name, "a finite real number", _describe(value))
    try:
        result = float(value)
    except (OverflowError, ValueError):  # a Real too big for a float (Fraction(10**400))
        result = math.inf
    if not math.isfinite(result):
        raise error(name, "a finite real number", _describe(value))
    return result


def check_positive(value: Any, name: str) -> float:
    value = check_real(value, name)
    if value <= 0:
        raise error(name, "a number > 0", str(value))
    return value


def check_nonnegative(value: Any, name: str) -> float:
    value = check_real(value, name)
    if value < 0:
        raise error(name, "a number >= 0", str(value))
    return value


def check_probability(value: Any, name: str) -> float:
    value = check_real(value, name)
    if not 0.0 <= value <= 1.0:
        raise error(name, "a number in [0, 1]", str(value))
    return value


def check_choice(value: Any, name: str, choices) -> str:
    choices = list(choices)
    if not isinstance(value, str) or value.lower() not in choices:
        raise error(name, "one of " + ", ".join(repr(c) for c in choices), _describe(value))
    return value.lower()


def check_rng(rng: Any) -> np.random.Generator:
    """SPEC 7: ``None``, an int seed, a SeedSequence or a Generator."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (numbers.Integral, np.random.SeedSequence)) and not isinstance(rng, bool)):
        try:
            # numpy's stubs do not know numbers.Integral; default_rng accepts any Integral it can index
            return np.random.default_rng(rng)  # type: ignore[arg-type]
        except ValueError:
            raise error("rng", "None, a non-negative int seed or a numpy Generator", _describe(rng)) from None
    raise error("rng", "None, a non-negative int seed or a numpy Generator", _describe(rng))


def check_enough_points(n_points: int, dim: int, degree: int, name: str = "points") -> None:
    """Refuse a degree above ipfit's limit, or whose polynomial has more coefficients than there are points."""
    from ..basis import MAX_DEGREE, n_coefficients

    if degree > MAX_DEGREE[dim]:
        raise error("degree", f"at most {MAX_DEGREE[dim]} in {dim}D (ipfit's limit)", str(degree),
                    "Lower the degree.")
    d = n_coefficients(dim, degree)
    if n_points < d:
        raise error(name, f"at least {d} points for a degree-{degree} {dim}D polynomial ({d} coefficients)",
                    f"{n_points} points", "Pass more points or lower the degree.")

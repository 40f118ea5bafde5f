"""Argument checking shared by every public function: one module, one message template.

Messages follow ``"{name}: expected {expected}, got {got}. {fix}"`` so that every error
names the parameter, what was expected, what came and what to do.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .exceptions import InvalidInputError

__all__ = [
    "error",
    "as_points",
    "as_normals",
    "as_faces",
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


def error(name: str, expected: str, got: str, fix: str = "") -> InvalidInputError:
    """Build the library's standard caller error (returned, so callers write ``raise``)."""
    message = f"{name}: expected {expected}, got {got}."
    if fix:
        message += f" {fix}"
    return InvalidInputError(message)


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{type(value).__name__} {text}"


def as_points(points: ArrayLike, name: str = "points", *, dims=(2, 3), min_points: int = 1) -> NDArray[np.float64]:
    """Return ``points`` as a C-contiguous float64 array of shape (N, D), D in ``dims``."""
    if np.iscomplexobj(points):  # float64 conversion would drop the imaginary parts
        raise error(name, "real coordinates", _describe(np.asarray(points)), "Pass the real parts (or np.abs) explicitly.")
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise error(name, "an (N, 2) or (N, 3) array of numbers", _describe(points),
                    "Pass a numeric array with one point per row.") from None
    if arr.ndim != 2 or arr.shape[1] not in dims:
        dim_text = " or ".join(f"(N, {d})" for d in dims)
        raise error(name, f"an array of shape {dim_text}", f"shape {arr.shape}",
                    "Pass one point per row with its coordinates as columns.")
    if arr.shape[0] < min_points:
        raise error(name, f"at least {min_points} points", f"{arr.shape[0]}",
                    "Pass more points.")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise error(name, "finite coordinates", f"{int(bad.sum())} rows with NaN or inf (first at row {first})",
                    "Remove or repair those rows.")
    return np.ascontiguousarray(arr)


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
    arr = as_points(normals, name, dims=(points.shape[1],))
    if arr.shape != points.shape:
        raise error(name, f"shape {points.shape} to match the points", f"shape {arr.shape}",
                    "Pass one normal per point.")
    length = np.linalg.norm(arr, axis=1)
    tiny = length <= 1e-12 * max(1.0, float(length.max(initial=0.0)))
    if tiny.any():
        first = int(np.flatnonzero(tiny)[0])
        raise error(name, "non-zero normal vectors", f"{int(tiny.sum())} zero-length normals (first at row {first})",
                    "Remove those points or estimate normals with ipfit.estimate_normals.")
    return arr / length[:, None]


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
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise error(name, "a finite real number", _describe(value))
    return float(value)


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
    if rng is None or isinstance(rng, (numbers.Integral, np.random.SeedSequence)) and not isinstance(rng, bool):
        try:
            return np.random.default_rng(rng)
        except ValueError:
            raise error("rng", "None, a non-negative int seed or a numpy Generator", _describe(rng)) from None
    raise error("rng", "None, a non-negative int seed or a numpy Generator", _describe(rng))


def check_enough_points(n_points: int, dim: int, degree: int, name: str = "points") -> None:
    """Refuse a degree whose polynomial has more coefficients than there are points."""
    from .basis import n_coefficients

    d = n_coefficients(dim, degree)
    if n_points < d:
        raise error(name, f"at least {d} points for a degree-{degree} {dim}D polynomial ({d} coefficients)",
                    f"{n_points} points", "Pass more points or lower the degree.")

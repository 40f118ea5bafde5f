"""The result JSON's schema and its validator (the public face is :mod:`ipfit.degree.results`).

This module sits below :mod:`ipfit.polynomial` so that ``ImplicitPolynomial.from_dict``
can validate a whole file; :mod:`ipfit.degree.results` adds the reading of its polynomials.

The schema is one table, :data:`SCHEMA`: every documented key with its type, whether it
is required, and its meaning. ``docs/result-format.md`` is generated from it
(:func:`schema_markdown`). Keys are a contract: later versions add keys; a renamed key bumps
:data:`FORMAT_VERSION` and the old name is still read; keys the table does not know are kept and
not checked.
"""

from __future__ import annotations

import contextlib
import json
import math
import numbers
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple, TypeVar

import numpy as np

from . import basis
from ._utils.validation import error
from .exceptions import InvalidInputError, ReadError

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "Key", "SCHEMA", "MAX_DEGREE", "MAX_COORDINATE", "MAX_DEPTH",
           "validate_result", "read_result_json", "check_coordinates", "schema_markdown"]

FORMAT_NAME = "ipfit"
#: 2: ``adaptive.far_weight`` renamed ``adaptive.far_term_weight`` (version-1 files are still
#: read: :func:`parse_result_text` renames the key).
FORMAT_VERSION = 2
_FIX = "Regenerate the result with ipfit, or repair that key."
#: The normalisation's scale must be at least this times the centre's size (and 1e-12):
#: (x − center) / scale then keeps 4 of float64's 16 significant digits.
RELATIVE_SCALE = 1e-12
#: Largest coordinate (centre, scale, bounds, data): squared distances between points this
#: far apart, summed over 3 axes, stay below float64's 1.8e308.
MAX_COORDINATE = 1e150
#: Highest degree a result may hold, per dimension: the highest ipfit fits.
MAX_DEGREE = basis.MAX_DEGREE
#: Deepest nesting of objects and lists; ipfit writes 5 levels.
MAX_DEPTH = 64


# -- value types: (text for the docs and the messages, test) ----------------------------------

def _is_int(v) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _is_whole(v) -> bool:
    # 2.0 is a whole number too (some JSON writers print every number as a float)
    return _is_int(v) or (_is_number(v) and math.isfinite(v) and float(v).is_integer())


def _is_finite(v) -> bool:
    """A number float64 holds: an integer of 400 digits is "finite" to Python, not to NumPy."""
    try:
        return _is_number(v) and math.isfinite(float(v))
    except OverflowError:
        return False


def _is_float(v) -> bool:
    """A number float64 holds, or ±Infinity / NaN (see "number" in docs/result-format.md)."""
    return _is_number(v) and (not _is_int(v) or _is_finite(v))


class _Type(NamedTuple):
    text: str
    test: Callable[[Any], bool]


_TYPES = {
    "object": _Type("an object", lambda v: isinstance(v, Mapping)),
    "list of objects": _Type("a list of objects", lambda v: isinstance(v, list)
                             and all(isinstance(e, Mapping) for e in v)),
    "object of objects": _Type("an object whose values are objects", lambda v: isinstance(v, Mapping)
                               and all(isinstance(e, Mapping) for e in v.values())),
    "string": _Type("a string", lambda v: isinstance(v, str)),
    "boolean": _Type("true or false", lambda v: isinstance(v, bool)),
    "integer >= 0": _Type("a whole number >= 0", lambda v: _is_whole(v) and _is_finite(v) and v >= 0),
    "integer >= 1": _Type("a whole number >= 1", lambda v: _is_whole(v) and _is_finite(v) and v >= 1),
    "number": _Type("a number", _is_float),
    "number > 0": _Type("a finite number > 0", lambda v: _is_finite(v) and v > 0),
    "numbers": _Type("a list of finite numbers", lambda v: isinstance(v, list) and all(map(_is_finite, v))),
    "indices": _Type("a list of whole numbers >= 0",
                     lambda v: isinstance(v, list) and all(_is_whole(i) and _is_finite(i) and i >= 0 for i in v)),
    "whole numbers or nulls": _Type("a list of whole numbers or nulls",
                                    lambda v: isinstance(v, list) and all(i is None or (_is_whole(i) and _is_finite(i))
                                                                          for i in v)),
    "outlier mode": _Type('"auto", "none" or a number from 0 to 0.9',
                          lambda v: v in ("auto", "none") or (_is_finite(v) and not isinstance(v, (bool, str))
                                                              and 0 <= v < 0.9)),
    "number >= 0 or null": _Type("a finite number >= 0, or null", lambda v: v is None or (_is_finite(v) and v >= 0)),
    "exponent rows": _Type("a list of rows of whole numbers >= 0, all of length 2 or all of length 3",
                           lambda v: isinstance(v, list) and bool(v) and all(isinstance(r, list) for r in v)
                           and len({len(r) for r in v}) == 1 and len(v[0]) in (2, 3)
                           and all(_is_whole(e) and _is_finite(e) and e >= 0 for r in v for e in r)),
    "integers": _Type("a list of whole numbers", lambda v: isinstance(v, list) and all(
        _is_whole(i) and _is_finite(i) for i in v)),
    "box": _Type("[[min...], [max...]]: two lists of finite numbers of one length, min <= max",
                 lambda v: isinstance(v, list) and len(v) == 2 and all(
                     isinstance(r, list) and all(map(_is_finite, r)) for r in v) and len(v[0]) == len(v[1])
                 and all(a <= b for a, b in zip(v[0], v[1], strict=True))),
    "bounds": _Type("a list of [low, high] pairs of finite numbers, one per axis, low <= high",
                    lambda v: isinstance(v, list) and all(
                        isinstance(r, list) and len(r) == 2 and all(map(_is_finite, r)) and r[0] <= r[1] for r in v)),
    '"ipfit"': _Type(f'the string "{FORMAT_NAME}"', lambda v: v == FORMAT_NAME),
    "version": _Type(f"a whole number from 1 to {FORMAT_VERSION} (the newest format this ipfit reads)",
                     lambda v: _is_int(v) and 1 <= v <= FORMAT_VERSION),
    "2 or 3": _Type("2 or 3", lambda v: _is_int(v) and v in (2, 3)),
}


class Key(NamedTuple):
    """One documented key. ``path`` uses ``a.b`` for nesting, ``a[].b`` for the entries
    of a list and ``a.*.b`` for the values of an object with free names."""

    path: str
    type: str
    required: bool
    meaning: str


def _k(path: str, type_: str, meaning: str, required: bool = False) -> Key:
    return Key(path, type_, required, meaning)


_QUALITY = (
    ("recall", "number", "fraction of data points within tau of the zero set"),
    ("precision", "number", "fraction of the zero set within tau of the data's shape"),
    ("f_score", "number", "harmonic mean of recall and precision"),
    ("chamfer", "number", "symmetric Chamfer distance, user units"),
    ("n_components", "integer >= 0", "pieces of the zero set in the box"),
    ("n_spurious", "integer >= 0", "pieces with no part within tau of the data"),
    ("closed", "boolean", "the zero set closes inside the box"),
    ("n_open", "integer >= 0", "pieces near the data that leave the box (not closed)"),
    ("tau", "number", "the tolerance, user units"),
    ("data_to_zero_set", "number", "mean distance from the data to the zero set"),
    ("zero_set_to_data", "number", "mean distance from the zero set to the data"),
    ("grid_step", "number", "step of the extraction grid"),
    ("reference", "string", 'what precision was measured against: "faces", "contour" or "points"'),
    ("spurious", "list of objects", "one entry per spurious component"),
    ("spurious[].size", "number", "its length (2D) or area (3D), user units"),
    ("spurious[].share", "number", "its share of the zero set's total size"),
    ("spurious[].center", "numbers", "its mean position, user units"),
    ("spurious[].distance", "number", "its nearest approach to the data, user units"),
    ("topology", "object", "the zero set's topology, specks left out (docs/topology.md)"),
    ("topology.dim", "2 or 3", "its dimension"),
    ("topology.components", "integer >= 0", "pieces counted (2D loops and arcs; 3D surfaces)"),
    ("topology.open", "integer >= 0", "those that are open (2D arcs; 3D surfaces with a border)"),
    ("topology.loops", "integer >= 0", "those that are closed (2D loops; 3D closed surfaces)"),
    ("topology.nesting", "indices", "2D: each loop's depth (how many loops enclose it), sorted"),
    ("topology.euler", "whole numbers or nulls", "3D: Euler characteristic V - E + F of each closed surface"),
    ("topology.genus", "whole numbers or nulls", "3D: genus of each closed surface (null: not orientable)"),
    ("topology.ignored", "integer >= 0", "specks (or an estimate's stray pieces) left out"),
    ("topology.source", "string", '"zero set", or the data\'s: "contour", "mesh", "points"'),
    ("topology.confidence", "string", '"high", "medium", "low" or "unknown"'),
    ("data_topology", "object", "the data's topology, as far as the data tells it"),
    ("data_topology.dim", "2 or 3", "its dimension"),
    ("data_topology.components", "integer >= 0", "pieces counted (2D loops and arcs; 3D surfaces)"),
    ("data_topology.open", "integer >= 0", "those that are open (2D arcs; 3D surfaces with a border)"),
    ("data_topology.loops", "integer >= 0", "those that are closed (2D loops; 3D closed surfaces)"),
    ("data_topology.nesting", "indices", "2D: each loop's depth (how many loops enclose it), sorted"),
    ("data_topology.euler", "whole numbers or nulls", "3D: Euler characteristic V - E + F of each closed surface"),
    ("data_topology.genus", "whole numbers or nulls", "3D: genus of each closed surface (null: not orientable)"),
    ("data_topology.ignored", "integer >= 0", "specks (or an estimate's stray pieces) left out"),
    ("data_topology.source", "string", '"zero set", or the data\'s: "contour", "mesh", "points"'),
    ("data_topology.confidence", "string", '"high", "medium", "low" or "unknown"'),
    ("topology_matches", "boolean", "the zero set has the data's topology; null when the data's is not known"),
)


def _normalization(prefix: str, meaning: str) -> tuple[Key, ...]:
    return (_k(prefix, "object", meaning),
            _k(f"{prefix}.center", "numbers", "centre c, one value per axis", required=True),
            _k(f"{prefix}.scale", "number > 0", "scale s", required=True))


SCHEMA: tuple[Key, ...] = (
    _k("format", '"ipfit"', "marks the file as an ipfit result", required=True),
    _k("version", "version", "format version; a newer file is refused with a message", required=True),
    _k("dim", "2 or 3", "2 for a curve, 3 for a surface; must agree with the exponents"),
    _k("degree", "integer >= 1", "total degree; must agree with the exponents"),
    _k("exponents", "exponent rows", "one row per monomial, in the graded order of ipfit.basis.exponents "
       "(1, x, y, z, x², xy, ...)", required=True),
    _k("coefficients", "numbers", "one per exponent row, not all zero", required=True),
    *_normalization("normalization", "f is evaluated at (x − center) / scale; absent means center 0, scale 1"),
    _k("method", "string", "the fit that produced the polynomial"),
    _k("measures", "object", "the paper's measures on the fitting data"),
    _k("measures.dissimilarity", "number", "mean absolute value of f on the data (paper, Eq. 9)"),
    _k("measures.smoothness", "number", "mean agreement of ∇f with the normals (Eq. 10)"),
    _k("measures.distance", "number", "dissimilarity + delta (1 − smoothness)"),
    _k("measures.delta", "number", "the delta used"),
    _k("info", "object", "free-form diagnostics of the fit (condition number, rank, ...)"),
    _k("selected_degree", "integer >= 1", "the degree chosen; one of degrees[].degree"),
    _k("degrees", "list of objects", "one entry per degree tried, in order"),
    _k("degrees[].degree", "integer >= 1", "the degree", required=True),
    _k("degrees[].dissimilarity", "number", "its dissimilarity"),
    _k("degrees[].smoothness", "number", "its smoothness"),
    _k("degrees[].distance", "number", "its distance"),
    _k("degrees[].seconds", "number", "time spent on it"),
    _k("degrees[].coefficients", "numbers", "its polynomial, C(degree + dim, dim) values in graded order"),
    _k("degrees[].method", "string", "the fit used at that degree"),
    *_normalization("degrees[].normalization", "its own normalisation; absent means the top-level one"),
    _k("degrees[].nit", "integer >= 0", "iterations (generations) of the fixed-degree method; 0 for a linear fit"),
    _k("degrees[].nfev", "integer >= 0", "objective evaluations at that degree"),
    _k("degrees[].success", "boolean", "the method reached a finite fit"),
    _k("degrees[].message", "string", "how the method ended (each stage)"),
    _k("degrees[].reason", "string", "why the degree was selected, rejected or not needed (or, tried after the rule's "
       "stop for the data's topology, set aside), in one line"),
    _k("degrees[].cleanup", "list of objects", "refits with stronger far-field terms of a degree that was not clean "
       "or not precise, or that missed part of the data; then, if still not clean, the search's other solutions "
       "measured"),
    _k("degrees[].cleanup[].target", "string", '"spurious components", "topology", "precision" or "missing surface": '
       'what the refit removed or fixed; "another solution": one of the search\'s other distinct solutions'),
    _k("degrees[].cleanup[].solution", "integer >= 1", 'target "another solution": its rank among the search\'s '
       "distinct solutions (0 is the one fitted)"),
    _k("degrees[].cleanup[].far_term_weight", "number", "the far-field term weight of that refit"),
    _k("degrees[].cleanup[].precision", "number", "its precision"),
    _k("degrees[].cleanup[].clean", "boolean", "the refit's zero set is clean"),
    _k("degrees[].cleanup[].f_score", "number", "its F-score"),
    _k("degrees[].cleanup[].n_spurious", "integer >= 0", "its spurious components"),
    _k("degrees[].cleanup[].closed", "boolean", "its zero set closes inside the box"),
    _k("degrees[].cleanup[].topology_matches", "boolean", "its zero set has the data's topology (null: not known)"),
    _k("degrees[].cleanup[].seconds", "number", "time of the refit"),
    _k("degrees[].quality", "object", "geometric quality of that degree, keys as in quality"),
    *(_k(f"degrees[].quality.{name}", t, m) for name, t, m in _QUALITY),
    _k("adaptive", "object", "settings and outcome of the degree search"),
    _k("adaptive.epsilon", "number", "stopping threshold on the smoothness gain"),
    _k("adaptive.delta", "number", "the distance's delta"),
    _k("adaptive.method", "string", "fixed-degree method"),
    _k("adaptive.reason", "string", "why the search stopped where it did"),
    _k("adaptive.rule", "string", '"capture", "geometric" or "paper"'),
    _k("adaptive.far_term_weight", "number",
       "weight of the far-field term (version 1 wrote it as `adaptive.far_weight`, read as this key)"),
    _k("adaptive.seconds", "number", "total time"),
    _k("adaptive.success", "boolean", "a degree was selected on a complete run (false when interrupted, or when "
       "the geometric rule found no clean degree)"),
    _k("adaptive.message", "string", "which degree was selected and why"),
    _k("adaptive.options", "object", "the search settings (ipfit.SearchOptions) of a refinement method; null for a "
       "linear fit"),
    _k("outliers", "object", "the points the fit treated as outliers (fit_adaptive's outliers=, ipfit fit --outliers)"),
    _k("outliers.mode", "outlier mode", '"auto" (found from the data), "none" (every point fitted) or the forced '
       "share"),
    _k("outliers.count", "integer >= 0", "points treated as outliers"),
    _k("outliers.share", "number", "count / the points fitted (input.n_points)"),
    _k("outliers.noise_scale", "number >= 0 or null", "the inliers' estimated noise (Gaussian sigma of their "
       "offsets from the shape, data units); null when not estimated"),
    _k("outliers.indices", "indices", "which points (0-based, in the input's order) were treated as outliers"),
    _k("quality", "object", "geometric quality of the final polynomial (ipfit score --write)"),
    *(_k(f"quality.{name}", t, m) for name, t, m in _QUALITY),
    _k("distance_to_zero_set", "object", "true distances from the data to the zero set of the final polynomial "
       "(ipfit score --write)"),
    _k("distance_to_zero_set.projected_mean", "number", "mean distance from the data points to their closest points "
       "on the zero set, user units"),
    _k("distance_to_zero_set.projected_max", "number", "the largest of those distances"),
    _k("distance_to_zero_set.taubin_mean", "number", "mean of Taubin's estimate |f| / |∇f| at the same points"),
    _k("distance_to_zero_set.taubin_max", "number", "the largest of those estimates"),
    _k("distance_to_zero_set.n_points", "integer >= 0", "data points measured (all, or at most 4000 evenly "
       "strided)"),
    _k("input", "object", "the data that was fitted"),
    _k("input.source", "string", "INPUT as typed (a path or a bundled dataset name)"),
    _k("input.path", "string", "absolute path of INPUT when it was a file"),
    _k("input.n_points", "integer >= 0", "number of points"),
    _k("input.normals", "string", '"file" or "estimated"'),
    _k("batch", "object", "written by ipfit batch / ipfit.fit_many"),
    _k("batch.settings_hash", "string",
       "hash of the fit settings; a result with the current hash is skipped on resume"),
    _k("batch.name", "string", "the shape's name in the batch (its seed is made from it and the batch seed)"),
    _k("batch.seed", "integer >= 0", "the batch seed"),
    _k("batch.shape_seed", "integer >= 0", "the shape's own seed: ipfit fit --seed with it gives this result"),
    _k("bounds", "bounds", "the data's bounding box, one [low, high] per axis"),
    _k("comparisons", "object of objects", "other fits for comparison, by name (e.g. classic linear, 3L)"),
    _k("comparisons.*.coefficients", "numbers", "its polynomial in graded order", required=True),
    _k("comparisons.*.degree", "integer >= 1", "its degree; must agree with the number of coefficients"),
    _k("comparisons.*.method", "string", "the fit"),
    *_normalization("comparisons.*.normalization", "its own normalisation; absent means the top-level one"),
    # A scene (ipfit fit --objects, ipfit.fit_scene): no polynomial of its own (exponents and
    # coefficients are then not required), one complete result per object.
    _k("objects", "list of objects", "a scene: one complete result per object (every key above; each readable "
       "alone by ipfit.load_result); a scene has no top-level polynomial"),
    _k("objects[].bounding_box", "box", "the object's points' box, [[min...], [max...]] in the input's coordinates"),
    _k("objects[].n_points", "integer >= 0", "the object's points"),
    _k("objects[].touching", "boolean", "the object may be two objects that touch (a narrow neck), fitted as one"),
    _k("objects[].note", "string", "what the segmentation says of it, in words (e.g. why touching)"),
    _k("planes", "list of objects", "a scene: the dominant planes removed before the objects were split"),
    _k("planes[].normal", "numbers", "its unit normal n (the plane is n · x = offset)", required=True),
    _k("planes[].offset", "number", "its offset", required=True),
    _k("planes[].n_points", "integer >= 0", "points on it (within threshold)"),
    _k("planes[].threshold", "number", "the distance within which a point was on it"),
    _k("planes[].polynomial", "object", "the plane as a degree-1 result (fit_scene(keep_planes=True), "
       "ipfit fit --objects --keep-planes)"),
    _k("segmentation", "object", "a scene: how the scan was split"),
    _k("segmentation.n_points", "integer >= 0", "points in the scan"),
    _k("segmentation.n_objects", "integer >= 0", "objects found (the entries of objects)"),
    _k("segmentation.n_planes", "integer >= 0", "planes removed"),
    _k("segmentation.n_clutter", "integer >= 0", "pieces too small to fit (clutter)"),
    _k("segmentation.n_clutter_points", "integer >= 0", "points in them"),
    _k("segmentation.n_outliers", "integer >= 0", "stray returns set aside before the split"),
    _k("segmentation.spacing", "number", "median distance of a point to its nearest neighbour"),
    _k("segmentation.link", "number", "the median of the points' link distances (0: labels given)"),
    _k("segmentation.noise_scale", "number", "the scan's noise scale"),
    _k("segmentation.labels", "integers", "each point's object (0, 1, ...) or -1, in the input's order"),
    _k("segmentation.kinds", "integers", "each point's kind: 0 object, 1 plane, 2 clutter, 3 outlier"),
    _k("segmentation.message", "string", "what was found, in words"),
)

_BY_PARENT: dict[str, list[Key]] = {}
for _key in SCHEMA:
    _parent = _key.path.rsplit(".", 1)[0] if "." in _key.path else ""
    _BY_PARENT.setdefault(_parent, []).append(_key)


# -- validation ----------------------------------------------------------------------------

def _got(value) -> str:
    """A JSON reader's description of a value."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return "the string " + json.dumps(value if len(value) <= 40 else value[:37] + "...")
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, list):
        return f"a list of {len(value)} item{'s' if len(value) != 1 else ''}" if value else "an empty list"
    if _is_int(value) and not _is_finite(value):
        return f"a whole number beyond float64's range (about {int(value.bit_length() * math.log10(2)) + 1} digits)"
    if _is_number(value):
        return "NaN" if value != value else repr(value).replace("inf", "Infinity")
    return type(value).__name__


def _fail(source: str, where: str, expected: str, got: str, fix: str = _FIX) -> InvalidInputError:
    return error(f'{source}: "{where}"', expected, got, fix)


def _expected(key: Key) -> str:
    text = _TYPES[key.type].text
    required = [k.path.rsplit(".", 1)[1] for k in _BY_PARENT.get(key.path, ()) if k.required]
    if required:
        text += " with " + " and ".join(f'"{name}"' for name in required)
    return text


def _walk(obj: Mapping, parent: str, where: str, source: str, optional: tuple[str, ...] = ()) -> None:
    for key in _BY_PARENT.get(parent, ()):
        name = key.path.rsplit(".", 1)[-1]
        shown = f"{where}.{name}" if where else name
        value = obj.get(name)
        if value is None:
            if key.required and key.path not in optional:
                raise _fail(source, shown, _expected(key), "nothing" if name not in obj else "null")
            continue
        if not _TYPES[key.type].test(value):
            raise _fail(source, shown, _expected(key), _got(value))
        if key.type == "object":
            _walk(value, key.path, shown, source)
        elif key.type == "list of objects":
            for i, entry in enumerate(value):
                _walk(entry, key.path + "[]", f"{shown}[{i}]", source)
        elif key.type == "object of objects":
            for entry_name, entry in value.items():
                _walk(entry, key.path + ".*", f"{shown}.{entry_name}", source)


def _check_polynomial(coefficients: list, dim: int, degree: int, where: str, source: str) -> None:
    expected = basis.n_coefficients(dim, degree)
    if len(coefficients) != expected:
        raise _fail(source, where, f"{expected} values for a degree-{degree} {dim}D polynomial",
                    f"{len(coefficients)} values")
    if not any(coefficients):
        raise _fail(source, where, "at least one non-zero value", "all zeros",
                    "An all-zero polynomial has no zero set; regenerate the result with ipfit.")


def _check_normalization(norm: Mapping | None, dim: int, where: str, source: str) -> None:
    if norm is None:
        return
    if len(norm["center"]) != dim:
        raise _fail(source, f"{where}.center", f"{dim} values, one per axis", f"{len(norm['center'])} values")
    _check_magnitude(norm["center"], f"{where}.center", source)
    _check_magnitude([norm["scale"]], f"{where}.scale", source)
    smallest = _smallest_scale(norm["center"])
    if norm["scale"] < smallest:
        raise _fail(source, f"{where}.scale", f"at least {smallest:.3g} ({RELATIVE_SCALE:g} × the centre's size, "
                    "below which coordinates keep fewer than 4 digits)", _got(norm["scale"]))


def _smallest_scale(center) -> float:
    # Below this, (x − center) / scale keeps fewer than 4 of float64's 16 digits.
    return RELATIVE_SCALE * max(1.0, *(abs(float(c)) for c in center))


def _check_magnitude(values, where: str, source: str) -> None:
    largest = max((abs(float(v)) for v in values), default=0.0)
    if largest > MAX_COORDINATE:
        raise _fail(source, where, f"values of magnitude at most {MAX_COORDINATE:g} (beyond it squared distances "
                    "overflow float64)", f"{largest:.3g}")


def _check_degree(degree: int, dim: int, where: str, source: str) -> None:
    """Refuse a degree whose work (tables, grids) could not end in reasonable time, before any of it."""
    if degree > MAX_DEGREE[dim]:
        raise _fail(source, where, f"a degree of at most {MAX_DEGREE[dim]} in {dim}D (ipfit's limit for results)",
                    f"degree {degree}" if degree < 10**6 else "a degree above a million")


def _check_depth(data: Mapping, source: str) -> None:
    """Refuse nesting deeper than :data:`MAX_DEPTH` (checked without recursion: that is what fails)."""
    stack: list[tuple[Mapping | list, int]] = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise InvalidInputError(f"{source}: nested more than {MAX_DEPTH} levels deep (ipfit writes 5). "
                                    "Pass a result written by ipfit.")
        children = value.values() if isinstance(value, Mapping) else value if isinstance(value, list) else ()
        stack.extend((child, depth + 1) for child in children if isinstance(child, (Mapping, list)))


def check_coordinates(points: np.ndarray, name: str = "points") -> None:
    """Refuse data whose coordinates no result could record: beyond :data:`MAX_COORDINATE`, or
    an extent too small for its offset from the origin (the normalisation's scale limit).

    ``fit`` calls it before fitting and the result commands on their data, so both fail up
    front with a message about the data, not about a result written afterwards.
    """
    from ._utils.validation import error

    largest = float(np.abs(points).max(initial=0.0))
    if largest > MAX_COORDINATE:
        raise error(name, f"coordinates of magnitude at most {MAX_COORDINATE:g} (beyond it squared distances "
                    "overflow float64)", f"coordinates up to {largest:.3g}", "Rescale the data (other units).")
    center = points.mean(axis=0)
    spread = float(np.linalg.norm(points - center, axis=1).mean()) if len(points) else 0.0
    smallest = _smallest_scale(center)
    if 0 < spread < smallest:  # identical points have their own message where the extent is used
        raise error(name, f"an extent of at least {RELATIVE_SCALE:g} × the data's offset from the origin (below "
                    "that float64 keeps fewer than 4 digits of the shape)",
                    f"points spread over {spread:.3g} around {np.abs(center).max():.3g}",
                    "Subtract the offset first (move the data near the origin).")


# validate_result returns the object it was given (a Mapping once checked)
_Data = TypeVar("_Data")


def validate_result(data: _Data, source: str = "result") -> _Data:
    """Check a result's JSON object against :data:`SCHEMA` and its internal consistency.

    Returns ``data`` itself (unchanged) when it is valid; otherwise raises
    :class:`~ipfit.InvalidInputError` with one line naming the first bad key.

    >>> line = {"format": "ipfit", "version": 1, "exponents": [[0, 0], [1, 0], [0, 1]],
    ...         "coefficients": [0.0, 1.0, -1.0]}
    >>> validate_result(line) is line
    True
    >>> validate_result({**line, "normalization": [0, 0, 1]})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipfit.exceptions.InvalidInputError: result: "normalization": expected an object with "center" and "scale", ...
    """
    if not isinstance(data, Mapping):
        raise error(source, "a JSON object written by ipfit (a result)", _got(data), "Pass a result written by ipfit.")
    if data.get("format") != FORMAT_NAME:
        raise InvalidInputError(f'{source}: not an ipfit result (expected "format": "{FORMAT_NAME}", got '
                                f'{_got(data.get("format")) if "format" in data else "no format"}). '
                                "Pass a result written by ipfit.")
    _check_depth(data, source)
    if isinstance(data.get("objects"), list):
        return _validate_scene(data, source)
    _walk(data, "", "", source)
    rows = [[int(e) for e in row] for row in data["exponents"]]
    dim = len(rows[0])
    degree = max(sum(row) for row in rows)
    _check_degree(degree, dim, "exponents", source)
    if data.get("dim") is not None and data["dim"] != dim:
        raise _fail(source, "dim", f"{dim}, the number of columns of the exponents", _got(data["dim"]))
    if data.get("degree") is not None and data["degree"] != degree:
        raise _fail(source, "degree", f"{degree}, the highest total degree in the exponents", _got(data["degree"]))
    # Count first: a corrupt exponent (say 10**9) must not build a table that large.
    if len(rows) != basis.n_coefficients(dim, degree) or not np.array_equal(rows, basis.exponents(dim, degree)):
        raise _fail(source, "exponents", f"the graded order of ipfit.basis.exponents({dim}, {degree}) "
                    "(1, x, y, ..., every monomial up to the degree)", "another order or an incomplete table")
    if len(data["coefficients"]) != len(rows):
        raise _fail(source, "coefficients", f"{len(rows)} values, one per exponent row",
                    f"{len(data['coefficients'])} values")
    _check_polynomial(data["coefficients"], dim, degree, "coefficients", source)
    _check_normalization(data.get("normalization"), dim, "normalization", source)
    if data.get("bounds") is not None:
        if len(data["bounds"]) != dim:
            raise _fail(source, "bounds", f"{dim} [low, high] pairs, one per axis", f"{len(data['bounds'])} pairs")
        _check_magnitude([e for pair in data["bounds"] for e in pair], "bounds", source)
    tried = []
    for i, entry in enumerate(data.get("degrees") or ()):
        g = int(entry["degree"])
        _check_degree(g, dim, f"degrees[{i}].degree", source)
        tried.append(g)
        if entry.get("coefficients") is not None:
            _check_polynomial(entry["coefficients"], dim, g, f"degrees[{i}].coefficients", source)
        _check_normalization(entry.get("normalization"), dim, f"degrees[{i}].normalization", source)
    selected = data.get("selected_degree")
    if selected is not None and tried and selected not in tried:
        raise _fail(source, "selected_degree", "one of the degrees tried (" + ", ".join(map(str, tried)) + ")",
                    _got(selected))
    for name, entry in (data.get("comparisons") or {}).items():
        where = f"comparisons.{name}"
        coef = entry["coefficients"]
        try:
            g = basis.degree_from_n_coefficients(dim, len(coef))
        except ValueError:
            raise _fail(source, f"{where}.coefficients", f"C(g + {dim}, {dim}) values for some degree g",
                        f"{len(coef)} values") from None
        _check_degree(g, dim, f"{where}.coefficients", source)
        if entry.get("degree") is not None and entry["degree"] != g:
            raise _fail(source, f"{where}.degree", f"{g}, the degree of its {len(coef)} coefficients",
                        _got(entry["degree"]))
        _check_polynomial(coef, dim, g, f"{where}.coefficients", source)
        _check_normalization(entry.get("normalization"), dim, f"{where}.normalization", source)
    return data


def _validate_scene(data, source: str):
    """A scene: its own keys, then every object as a complete result of one dimension."""
    _walk(data, "", "", source, optional=("exponents", "coefficients"))
    dims = set()
    for i, entry in enumerate(data["objects"]):
        validate_result(entry, f"{source}: objects[{i}]")
        dim = len(entry["exponents"][0])
        dims.add(dim)
        box = entry.get("bounding_box")
        if box is not None and len(box[0]) != dim:
            raise _fail(source, f"objects[{i}].bounding_box", f"{dim} values per corner, one per axis",
                        f"{len(box[0])} values")
    for i, plane in enumerate(data.get("planes") or ()):
        if isinstance(plane.get("polynomial"), Mapping):
            validate_result(plane["polynomial"], f"{source}: planes[{i}].polynomial")
    if len(dims) > 1 or (dims and data.get("dim") is not None and data["dim"] not in dims):
        raise _fail(source, "objects", "objects of one dimension, the scene's", "objects of "
                    + " and ".join(f"{d}D" for d in sorted(dims | ({data["dim"]} if data.get("dim") else set()))))
    return data


def read_result_json(path: str | os.PathLike) -> dict:
    """The JSON object of a result file (not yet validated), or a :class:`~ipfit.ReadError`."""
    from ._utils import atomic as _atomic

    path = Path(path)
    kind = _atomic.special_kind(path)
    if kind is not None:  # reading a FIFO would wait forever for a writer
        raise ReadError(f"{path}: is a {kind}, not a result file. Pass the .json written by ipfit fit.")
    if _atomic.unfinished(path):  # a fit killed while publishing: its set is completed first
        with contextlib.suppress(OSError, InvalidInputError):
            _atomic.settle(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file. Check the path.") from None
    except IsADirectoryError:
        raise ReadError(f"{path}: is a folder, not a result file. Pass the .json written by ipfit fit.") from None
    except UnicodeDecodeError as exc:  # an image or a binary point file, given where a result belongs
        raise ReadError(f"{path}: not a result JSON: it is not text (byte {exc.start} is not UTF-8). Pass the .json "
                        f"written by ipfit fit (`ipfit fit {path}` would write {path.with_suffix('.json').name}).") \
            from None
    except OSError as exc:
        raise ReadError(f"{path}: cannot be read ({exc.__class__.__name__}). Check the file.") from None
    return parse_result_text(text, str(path), ReadError)


def parse_result_text(text: str, source: str, kind: type[InvalidInputError] = InvalidInputError) -> dict:
    """The JSON object in ``text`` (not yet validated); ``kind`` is the error type raised."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise kind(f"{source}: not valid JSON ({exc.msg} at line {exc.lineno}). Pass a result written by ipfit.") \
            from None
    except RecursionError:
        raise kind(f"{source}: JSON nested too deeply. Pass a result written by ipfit.") from None
    except ValueError:  # an integer of more digits than Python converts
        raise kind(f"{source}: a number in it has more than {sys.get_int_max_str_digits()} digits. "
                   "Pass a result written by ipfit.") from None
    if not isinstance(data, dict):
        raise kind(f"{source}: not an ipfit result (a JSON object was expected, got {_got(data)}). "
                   "Pass a result written by ipfit.")
    return _from_version_1(data)


def _from_version_1(data: dict) -> dict:
    """A version-1 result read as version 2: its one renamed key (``adaptive.far_weight``)
    under the new name, so that every reader sees one spelling."""
    adaptive = data.get("adaptive")
    if data.get("version") == 1 and isinstance(adaptive, dict) and "far_weight" in adaptive \
            and "far_term_weight" not in adaptive:
        data["adaptive"] = {("far_term_weight" if key == "far_weight" else key): value
                            for key, value in adaptive.items()}
        data["version"] = 2
    return data


# -- documentation ---------------------------------------------------------------------------

def schema_markdown() -> str:
    """The schema table of ``docs/result-format.md`` (Markdown), generated from :data:`SCHEMA`."""
    lines = ["| key | type | required | meaning |", "|---|---|---|---|"]
    for key in SCHEMA:
        required = "yes" if key.required else ""
        if key.required and "." in key.path:
            required = "yes, when its parent is present"
        cells = (f"`{key.path}`", _TYPES[key.type].text, required, key.meaning)
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines) + "\n"

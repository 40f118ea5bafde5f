"""The result JSON: one schema, one validator, used by every reader (library side).

Each corruption of issue 13 is refused with one line naming the key, by ``load_result``,
``ImplicitPolynomial.from_dict``, ``from_json`` and ``load``; the CLI side is in
test_cli_mesh_plot_score.py. The schema table in docs/result-format.md is checked against
the validator's table, and the README's contract keys against both.
"""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

import ipfit

from ipfit import ImplicitPolynomial, InvalidInputError, Normalization, ReadError, basis, fit_adaptive
from ipfit.datasets import synthetic
from ipfit.degree.results import (SCHEMA, dumps_result, load_result, result_view, schema_markdown, validate_result,
                           write_result)

REPO = Path(__file__).resolve().parents[1]


def padded(poly, degree: int) -> list[float]:
    """Coefficients of ``poly`` in the basis of a higher ``degree`` (graded order is nested)."""
    coef = np.zeros(basis.n_coefficients(poly.dim, degree))
    coef[: poly.n_coefficients] = poly.coefficients
    return coef.tolist()


@pytest.fixture(scope="module")
def fitted() -> dict:
    """A result as ``fit_adaptive`` writes it (ellipse, 3L, degrees 2 and 4), plus CLI keys."""
    shape = synthetic.ellipse(120)
    data = fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4, rule="geometric").to_dict()
    data["input"] = {"source": "ellipse.csv", "path": "/nowhere/ellipse.csv", "n_points": 120, "normals": "file"}
    data["bounds"] = np.column_stack([shape.points.min(axis=0), shape.points.max(axis=0)]).tolist()
    circle = synthetic.circle().polynomial
    data["comparisons"] = {"lstsq": {"degree": 2, "coefficients": padded(circle, 2)},
                           "3l": {"coefficients": padded(circle, 4), "method": "3l"}}
    return json.loads(json.dumps(data))  # as read back from a file


def _set(key, value):
    def mutate(d):
        d[key] = value
    return mutate


def _nested(outer, key, value):
    def mutate(d):
        d[outer][key] = value
    return mutate


def _exponent(row, col, value):
    def mutate(d):
        d["exponents"][row][col] = value
    return mutate


def _swap_exponent_rows(d):
    d["exponents"][1], d["exponents"][2] = d["exponents"][2], d["exponents"][1]


# (mutation, the key the one-line message must name, a phrase it must contain)
CORRUPTIONS = {
    "normalization-list": (_set("normalization", [0, 0, 1]), '"normalization"',
                           'expected an object with "center" and "scale", got a list'),
    "measures-list": (_set("measures", [1, 2]), '"measures"', "expected an object, got a list"),
    "info-list": (_set("info", [1, 2]), '"info"', "expected an object, got a list"),
    "degrees-number": (_set("degrees", 5), '"degrees"', "expected a list of objects, got 5"),
    "degree-word": (_set("degrees", [{"degree": "two"}]), '"degrees[0].degree"', 'got the string "two"'),
    "selected-word": (_set("selected_degree", "x"), '"selected_degree"', 'got the string "x"'),
    "comparisons-list": (_set("comparisons", [1, 2]), '"comparisons"', "got a list"),
    "center-nan": (_nested("normalization", "center", [math.nan, 0.0]), '"normalization.center"',
                   "finite numbers"),
    "center-inf": (_nested("normalization", "center", [0.0, math.inf]), '"normalization.center"',
                   "finite numbers"),
    "dim-contradicts": (_set("dim", 3), '"dim"', "expected 2, the number of columns of the exponents"),
    "degree-contradicts": (_set("degree", 6), '"degree"', "expected 2, the highest total degree"),
    "exponent-fraction": (_exponent(3, 0, 1.5), '"exponents"', "whole numbers"),
    "coefficients-zero": (lambda d: d.update(coefficients=[0.0] * len(d["coefficients"])), '"coefficients"',
                          "all zeros"),
    "coefficients-count": (lambda d: d["coefficients"].pop(), '"coefficients"', "6 values, one per exponent row"),
    "exponents-order": (_swap_exponent_rows, '"exponents"', "graded order"),
    # beyond the list: the consistency of the per-degree table, comparisons and bounds
    "degree-entry-count": (lambda d: d["degrees"][0]["coefficients"].pop(), '"degrees[0].coefficients"',
                           "6 values for a degree-2 2D polynomial"),
    "selected-not-tried": (_set("selected_degree", 8), '"selected_degree"', "one of the degrees tried (2, 4)"),
    "comparison-count": (lambda d: d["comparisons"]["lstsq"]["coefficients"].pop(),
                         '"comparisons.lstsq.coefficients"', "for some degree g"),
    "comparison-degree": (lambda d: d["comparisons"]["3l"].update(degree=2), '"comparisons.3l.degree"',
                          "expected 4"),
    "bounds-axes": (lambda d: d["bounds"].append([0, 1]), '"bounds"', "2 [low, high] pairs"),
    "quality-closed": (lambda d: d["degrees"][1]["quality"].update(closed="yes"), '"degrees[1].quality.closed"',
                       "true or false"),
    "scale-zero": (_nested("normalization", "scale", 0), '"normalization.scale"', "a finite number > 0"),
    "scale-below-precision": (lambda d: d["normalization"].update(center=[1e100, 0.0], scale=1.0),
                              '"normalization.scale"', "at least 1e+88"),
    "exponents-missing": (lambda d: d.pop("exponents"), '"exponents"', "got nothing"),
    "version-newer": (_set("version", 3), '"version"', "got 3"),
}


def corrupted(base: dict, case: str) -> dict:
    data = copy.deepcopy(base)
    CORRUPTIONS[case][0](data)
    return data


def one_line(exc: BaseException) -> str:
    text = str(exc)
    assert "\n" not in text
    return text


def test_a_real_result_is_valid_and_unchanged(fitted):
    before = copy.deepcopy(fitted)
    assert validate_result(fitted) is fitted
    assert fitted == before
    assert [d["degree"] for d in fitted["degrees"]] == [2, 4] and fitted["degree"] == fitted["selected_degree"] == 2


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corruption_is_one_line_naming_the_key(fitted, case, tmp_path):
    _, key, phrase = CORRUPTIONS[case]
    data = corrupted(fitted, case)
    for read in (load_result, ImplicitPolynomial.from_dict, result_view):
        with pytest.raises(InvalidInputError) as info:
            read(data)
        text = one_line(info.value)
        assert text.startswith(f"result: {key}: ") and phrase in text, text
    with pytest.raises(InvalidInputError, match=re.escape(key)):
        ImplicitPolynomial.from_json(json.dumps(data))
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    for read in (ImplicitPolynomial.load, load_result, result_view):
        with pytest.raises(ReadError) as info:
            read(path)
        assert one_line(info.value).startswith(f"{path}: {key}: ")


@pytest.mark.parametrize("bad", [None, 5, ["{}"]])
def test_from_json_refuses_what_is_not_text(bad):
    with pytest.raises(InvalidInputError, match=r"^text: expected the JSON text of an ipfit result"):
        ImplicitPolynomial.from_json(bad)


@pytest.mark.parametrize("text, match", [
    ("{oops", "not valid JSON"),
    ("[1, 2]", "a JSON object was expected, got a list"),
    ('{"format": "other"}', "not an ipfit result"),
    ("[" * 100000 + "]" * 100000, "JSON"),
])
def test_from_json_refuses_what_is_not_a_result(text, match):
    with pytest.raises(InvalidInputError, match=match) as info:
        ImplicitPolynomial.from_json(text)
    one_line(info.value)


def test_load_result_errors(tmp_path):
    with pytest.raises(ReadError, match="no such file"):
        load_result(tmp_path / "missing.json")
    with pytest.raises(ReadError, match="is a folder"):
        load_result(tmp_path)
    with pytest.raises(InvalidInputError, match="^result: expected a path to a result JSON"):
        load_result(None)


@pytest.mark.parametrize("center", [[math.nan, 0.0], [0.0, math.inf], [[0.0, 0.0]], [0.0], "ab"])
def test_normalization_refuses_bad_centres(center):
    with pytest.raises(InvalidInputError, match="^center: expected 2 or 3 finite numbers"):
        Normalization(center, 1.0)


def test_polynomial_refuses_fractional_exponents():
    exps = basis.exponents(2, 2).astype(float)
    ImplicitPolynomial(exps, np.ones(6))  # whole floats are whole numbers
    exps[3, 0] = 1.5
    with pytest.raises(InvalidInputError, match="^exponents: expected whole numbers"):
        ImplicitPolynomial(exps, np.ones(6))


def test_nan_centre_through_the_api_never_evaluates():
    poly = synthetic.circle().polynomial
    with pytest.raises(InvalidInputError):
        ImplicitPolynomial(poly.exponents, poly.coefficients, Normalization([math.nan, 0.0], 1.0))


def test_extra_keys_are_allowed_and_kept(fitted, tmp_path):
    data = copy.deepcopy(fitted)
    data["future_key"] = {"anything": [1, "two"]}
    data["degrees"][0]["reason"] = "accepted: closed, no spurious piece"
    data["measures"]["new_measure"] = "text is fine in a key the schema does not know"
    assert validate_result(data) is data
    write_result(tmp_path / "r.json", data)
    back = json.loads((tmp_path / "r.json").read_text())
    assert back["future_key"] == data["future_key"] and back["degrees"][0]["reason"].startswith("accepted")


def test_write_result_round_trip_and_refusal(fitted, tmp_path):
    data = copy.deepcopy(fitted)
    data["measures"]["distance"] = math.inf  # standard JSON: written as null, read back as "not recorded"
    write_result(tmp_path / "r.json", data)
    text = (tmp_path / "r.json").read_text()
    assert "Infinity" not in text and json.loads(text)["measures"]["distance"] is None
    poly = ImplicitPolynomial.load(tmp_path / "r.json")
    np.testing.assert_array_equal(poly.coefficients, fitted["coefficients"])
    assert "distance" not in poly.measures
    with pytest.raises(InvalidInputError, match='"selected_degree"'):
        write_result(tmp_path / "bad.json", corrupted(fitted, "selected-word"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]  # nothing half-written
    assert json.loads(dumps_result(fitted)) == fitted


def test_save_refuses_a_polynomial_that_cannot_be_read_back(tmp_path):
    zero = ImplicitPolynomial(basis.exponents(2, 2), np.zeros(6))
    with pytest.raises(InvalidInputError, match="all zeros"):
        zero.save(tmp_path / "z.json")
    assert list(tmp_path.iterdir()) == []


def test_load_result_accepts_text_dict_path_and_objects(fitted, tmp_path):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(fitted))
    poly = synthetic.circle().polynomial
    assert load_result(str(path)) == load_result(path) == load_result(json.dumps(fitted)) == load_result(fitted)
    assert load_result(poly)["coefficients"] == poly.coefficients.tolist()


def test_view_polynomials_evaluate_like_the_stored_ones(fitted):
    view = result_view(fitted)
    assert view.dim == 2 and view.selected_degree == fitted["selected_degree"] and not view.fixed_degree
    assert [d.degree for d in view.degrees] == [2, 4]
    probe = np.array([[0.3, -0.2], [1.5, 0.4]])
    for entry in view.degrees:
        # an independent evaluation of the stored coefficients in the stored normalisation
        norm = fitted["normalization"]
        u = (probe - np.asarray(norm["center"])) / norm["scale"]
        exps = basis.exponents(2, entry.degree)
        expected = np.array([sum(c * np.prod(p ** e) for c, e in zip(entry.entry["coefficients"], exps))
                             for p in u])
        np.testing.assert_allclose(entry.polynomial(probe), expected, atol=1e-12)
        assert view.fit(entry.degree) is entry.polynomial
    assert view.fit() is view.polynomial
    assert view.comparisons["lstsq"].degree == 2 and view.comparisons["3l"].degree == 4
    with pytest.raises(InvalidInputError, match=r"^--degree: expected a degree with coefficients in result \(2, 4\)"):
        view.fit(6, name="--degree")
    assert view.input["source"] == "ellipse.csv"


def test_entries_with_their_own_normalization(fitted):
    data = copy.deepcopy(fitted)
    data["comparisons"]["3l"]["normalization"] = {"center": [0.5, 0.0], "scale": 2.0}
    view = result_view(data)
    assert view.comparisons["3l"].normalization.scale == 2.0
    assert view.comparisons["lstsq"].normalization.scale == fitted["normalization"]["scale"]


def test_plain_polynomial_is_a_fixed_degree_view():
    view = result_view(synthetic.sphere().polynomial)
    assert view.fixed_degree and view.degrees == () and view.selected_degree is None and view.bounds is None
    assert view.input == {}


# -- one written schema ---------------------------------------------------------------------

def _documented_keys(markdown: str) -> list[str]:
    return re.findall(r"^\| `([^`]+)` \|", markdown, flags=re.M)


def test_docs_table_is_the_validators_table():
    doc = (REPO / "docs" / "result-format.md").read_text(encoding="utf-8")
    assert schema_markdown() in doc, "docs/result-format.md is stale: paste ipfit.degree.results.schema_markdown() in"
    assert _documented_keys(doc) == [key.path for key in SCHEMA]


# The contract keys of the README's "JSON result format" section (issue 12: never renamed).
README_CONTRACT = ["format", "version", "dim", "degree", "exponents", "coefficients", "normalization",
                   "normalization.center", "normalization.scale", "method", "measures", "measures.dissimilarity",
                   "measures.smoothness", "measures.distance", "measures.delta", "selected_degree", "degrees",
                   "degrees[].degree", "degrees[].dissimilarity", "degrees[].smoothness", "degrees[].distance",
                   "degrees[].seconds", "degrees[].coefficients", "degrees[].method", "degrees[].quality",
                   "adaptive", "quality", "input", "bounds", "info", "comparisons"]


def test_every_contract_key_is_in_the_schema():
    paths = {key.path for key in SCHEMA}
    assert set(README_CONTRACT) <= paths
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("## JSON result format"):]
    example = json.loads(re.search(r"```json\n(.*?)```", section, flags=re.S).group(1))
    assert set(example) <= paths and set(example["normalization"]) <= {"center", "scale"}


def test_every_key_the_library_writes_is_documented(fitted):
    paths = {key.path for key in SCHEMA}

    def walk(obj, prefix):
        for name, value in obj.items():
            path = f"{prefix}{name}"
            if path in ("info", "adaptive") or path.startswith(("info.", "adaptive.")):
                assert path in paths or path.count(".") == 1, path  # free-form sub-keys are fine
                continue
            assert path in paths, path
            if isinstance(value, dict) and path not in ("comparisons",):
                walk(value, path + ".")
            elif isinstance(value, list) and value and isinstance(value[0], dict):
                walk(value[0], path + "[].")

    data = {k: v for k, v in fitted.items() if k != "comparisons"}
    walk(data, "")


def test_docs_example_is_valid():
    doc = (REPO / "docs" / "result-format.md").read_text(encoding="utf-8")
    example = json.loads(re.search(r"## Example\n\n```json\n(.*?)```", doc, flags=re.S).group(1))
    view = result_view(example)
    assert view.polynomial([[1.0, 0.0]])[0] == pytest.approx(0.0, abs=1e-12)  # the unit circle


def test_far_term_weight_has_one_json_key_and_version_1_files_still_read(tmp_path):
    # Version 2 writes adaptive.far_term_weight only; a version-1 file's adaptive.far_weight is
    # read as that key (from a file and from JSON text), its value kept.
    shape = synthetic.ellipse(120)
    options = ipfit.RECOMMENDED.replace(iterations=2, far_term_weight=0.3)
    written = fit_adaptive(shape.points, shape.normals, method="polish", options=options, max_degree=2).to_dict()
    assert written["version"] == 2 == ipfit.degree.results.FORMAT_VERSION
    assert written["adaptive"]["far_term_weight"] == 0.3 and "far_weight" not in written["adaptive"]
    old = json.loads(json.dumps(written))
    old["version"] = 1
    old["adaptive"] = {("far_weight" if k == "far_term_weight" else k): v for k, v in old["adaptive"].items()}
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(old))
    for source in (path, json.dumps(old)):
        read = load_result(source)
        assert read["version"] == 2 and read["adaptive"]["far_term_weight"] == 0.3
        assert "far_weight" not in read["adaptive"]
        assert read["coefficients"] == written["coefficients"]
    assert list(read["adaptive"]) == list(written["adaptive"])  # the key keeps its place


# -- the outliers section ---------------------------------------------------------------------

def _with_outliers(fitted: dict, indices, n_points: int | None = 120, **extra) -> dict:
    data = copy.deepcopy(fitted)
    if n_points is None:
        data.pop("input")
    else:
        data["input"]["n_points"] = n_points
    data["outliers"] = {"mode": "auto", "count": len(set(indices)), "share": len(set(indices)) / (n_points or 120),
                        "noise_scale": 0.01, "indices": list(indices), **extra}
    return data


def test_view_reads_the_outliers(fitted):
    view = result_view(fitted)  # a clean cloud: nothing left out, nothing to mark
    assert view.outliers.get("count", 0) == 0 and view.outlier_mask(120) is None
    assert view.outlier_indices is None or view.outlier_indices.size == 0
    bare = result_view({k: v for k, v in fitted.items() if k != "outliers"})  # outliers="none" writes no section
    assert bare.outliers == {} and bare.outlier_indices is None and bare.outlier_mask(120) is None
    view = result_view(json.dumps(_with_outliers(fitted, [17, 3.0, 99])))  # 3.0: a whole number written as a float
    assert result_view(view) is view  # a view passes through, keeping its source
    assert view.outliers["mode"] == "auto" and view.outliers["noise_scale"] == 0.01
    assert view.outlier_indices.dtype == np.int64 and view.outlier_indices.tolist() == [3, 17, 99]
    mask = view.outlier_mask(120)
    assert mask.shape == (120,) and np.flatnonzero(mask).tolist() == [3, 17, 99]


def test_outlier_mask_without_input_checks_indices_and_share(fitted, recwarn):
    view = result_view(_with_outliers(fitted, [0, 5, 119], n_points=None))
    assert np.flatnonzero(view.outlier_mask(120)).tolist() == [0, 5, 119]  # share 3/120: the rows match
    for rows, why in [(121, "a share of 0.025 of the points it fitted"), (119, "indices run up to 119")]:
        with pytest.warns(ipfit.IpfitWarning, match=f"result: outliers not marked: its .*{why}.*, but {rows} points"):
            assert view.outlier_mask(rows) is None
    no_share = {k: v for k, v in view.outliers.items() if k != "share"}
    view = result_view({**_with_outliers(fitted, [0, 5, 119], n_points=None), "outliers": no_share})
    assert view.outlier_mask(500) is not None  # nothing but the indices to go by: they fit
    assert not [w for w in recwarn if issubclass(w.category, ipfit.IpfitWarning)]


def test_outlier_mask_refuses_rows_that_are_not_the_fitted_ones(fitted, tmp_path):
    data = _with_outliers(fitted, [1, 2])
    path = tmp_path / "r.json"
    write_result(path, data)
    with pytest.warns(ipfit.IpfitWarning, match=rf"^{re.escape(str(path))}: outliers not marked: it fitted 120 "
                                                 r"points, but 100 points were given"):
        assert result_view(path).outlier_mask(100) is None
    huge = _with_outliers(fitted, [1, 1e300])  # a whole number float64 holds: beyond any cloud, not an overflow
    with pytest.warns(ipfit.IpfitWarning, match="indices run up to"):
        assert result_view(huge).outlier_mask(120) is None


def test_outlier_mask_is_none_without_outliers(fitted, recwarn):
    for record in ({"mode": "none", "count": 0, "share": 0.0, "noise_scale": None, "indices": []},
                   {"mode": "auto", "count": 0, "share": 0.0, "noise_scale": 0.02},  # no indices written
                   {"mode": 0.1, "count": 12, "share": 0.1, "noise_scale": 0.02}):
        view = result_view({**fitted, "outliers": record})
        assert view.outlier_mask(7) is None  # whatever the rows: nothing to place
    assert not [w for w in recwarn if issubclass(w.category, ipfit.IpfitWarning)]

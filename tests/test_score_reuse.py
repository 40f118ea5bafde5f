"""``ipfit score``: the fit's stored quality is reused exactly when the measurement would be the
same (data, tau, grid), and ``--write`` adds what was measured, schema-valid, saying so in one line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from running import quick_fit

from ipfit.cli import main
from ipfit.datasets import synthetic
from ipfit.degree.results import load_result, result_view
from ipfit.zeroset.quality import quality


def run(capsys, argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def write_points(path: Path, points: np.ndarray) -> Path:
    np.savetxt(path, points, delimiter=",", header="x,y,z", comments="")
    return path


@pytest.fixture
def torus_fit(tmp_path):
    """A real degree-4 fit (3L) of 600 torus points: its JSON path and the data file."""
    data = write_points(tmp_path / "torus.csv", synthetic.torus(600).points)
    quick_fit(tmp_path, data, "--degree", "4")
    return tmp_path / "out" / "fit.json", data


def test_the_stored_quality_is_the_measurement_score_would_make(torus_fit):
    path, data = torus_fit
    stored = json.loads(path.read_text())["quality"]
    points = np.loadtxt(data, delimiter=",", skiprows=1)
    measured = quality(result_view(path).polynomial, points).to_dict()
    assert stored.keys() == measured.keys()
    for key, value in measured.items():
        if isinstance(value, float):
            assert math.isclose(stored[key], value, rel_tol=1e-9, abs_tol=1e-12), key
        else:
            assert stored[key] == value, key


def test_score_reuses_the_fits_quality_only_for_the_same_data_tau_and_grid(torus_fit, tmp_path, capsys):
    path, data = torus_fit
    result = json.loads(path.read_text())
    true_precision = result["quality"]["precision"]
    # A marker no measurement gives: seen in the output only when the stored record is used.
    result["quality"]["precision"] = 0.123
    path.write_text(json.dumps(result))

    def precision(*options) -> tuple[float, list]:
        code, out, _ = run(capsys, ["score", path, "--json", *options])
        assert code == 0
        report = json.loads(out)
        return report["precision"], report["from_result"]

    assert precision() == (0.123, ["quality"])
    assert precision("--resolution", "128", "--tau-fraction", "0.02") == (0.123, ["quality"])  # the defaults, spelt out
    assert precision("--points", data) == (0.123, ["quality"])  # the recorded file, named
    for other in (["--margin", "0.3"], ["--resolution", "100"], ["--tau-fraction", "0.03"],
                  ["--tau", str(result["quality"]["tau"] * 1.01)]):
        value, reused = precision(*other)
        assert reused == [] and abs(value - true_precision) < 0.05, other
    fewer = write_points(tmp_path / "fewer.csv", np.loadtxt(data, delimiter=",", skiprows=1)[::2])
    value, reused = precision("--points", fewer)
    assert reused == [] and value != 0.123
    code, out, _ = run(capsys, ["score", path])
    assert code == 0 and "precision         0.123" in out
    assert f"(quality as {path} stores it: the fit measured the same data with the same tau and grid)" in out


def _torus_distance(points: np.ndarray, major: float, minor: float) -> np.ndarray:
    """Exact distance to the torus around z: | ‖(ρ − R, z)‖ − r | with ρ = √(x² + y²)."""
    rho = np.hypot(points[:, 0], points[:, 1])
    return np.abs(np.hypot(rho - major, points[:, 2]) - minor)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_write_adds_the_true_distance_and_says_what_it_wrote(tmp_path, capsys, seed):
    rng = np.random.default_rng(seed)
    shape = synthetic.torus(400, major=1.0, minor=0.4, rng=rng)
    # points moved off the surface along the normals by known amounts: their exact distances
    offsets = rng.uniform(-0.05, 0.05, len(shape.points))  # within tau (0.08) of the surface
    points = shape.points + offsets[:, None] * shape.normals
    data = write_points(tmp_path / "off.csv", points)
    path = tmp_path / "torus.json"
    shape.polynomial.save(path)
    before = json.loads(path.read_text())

    code, out, _ = run(capsys, ["score", path, "--points", data, "--write", "--resolution", "48"])
    assert code == 0
    wrote = [line for line in out.splitlines() if line.startswith("wrote ")]
    assert wrote == [(f'wrote {path}: "quality" (recall, precision, F-score, Chamfer, spurious components) and '
                      '"distance_to_zero_set" (true and Taubin distances)')]
    after = load_result(path)  # schema-valid, or this raises
    assert list(after)[: len(before)] == list(before) and {k: after[k] for k in before} == before
    distance = after["distance_to_zero_set"]
    exact = _torus_distance(points, 1.0, 0.4)
    assert distance["n_points"] == 400
    assert distance["projected_mean"] == pytest.approx(exact.mean(), abs=1e-9)
    assert distance["projected_max"] == pytest.approx(exact.max(), abs=1e-9)
    assert np.isclose(exact.max(), np.abs(offsets).max())  # the reference itself: the offsets
    assert after["quality"]["reference"] == "points" and after["quality"]["recall"] == 1.0

    # Again: the quality is measured again (the data is not the fit's), the distance is stored.
    code, out, _ = run(capsys, ["score", path, "--points", data, "--write", "--resolution", "48"])
    assert code == 0
    assert [line for line in out.splitlines() if line.startswith("wrote ")] == [
        f"wrote {path}: nothing new (it already held these measures)"]
    assert load_result(path) == after
    assert sorted(p.name for p in tmp_path.iterdir()) == ["off.csv", "torus.json"]  # no temporary files left


def test_write_on_a_fit_adds_only_the_distance(torus_fit, capsys):
    path, _ = torus_fit
    before = path.read_bytes()
    code, out, _ = run(capsys, ["score", path, "--write"])
    assert code == 0
    assert out.splitlines()[-1] == f'wrote {path}: "distance_to_zero_set" (true and Taubin distances)'
    after = load_result(path)
    assert after["quality"] == json.loads(before)["quality"]
    assert set(after) - set(json.loads(before)) == {"distance_to_zero_set"}
    # the next score reads both from the file
    code, out, _ = run(capsys, ["score", path, "--json"])
    assert code == 0 and json.loads(out)["from_result"] == ["quality", "distance_to_zero_set"]

"""``ipfit mesh``, ``ipfit plot`` and ``ipfit score`` end to end (in-process, real files)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ipfit.cli import build_parser, main
from ipfit.datasets import synthetic

from test_plotting import adaptive_result, nonblank
from test_results import CORRUPTIONS, corrupted, fitted  # noqa: F401  fitted: a real fit_adaptive result


def write_points(path: Path, points: np.ndarray) -> str:
    header = "x,y,z" if points.shape[1] == 3 else "x,y"
    np.savetxt(path, points, delimiter=",", header=header, comments="")
    return str(path)


def image(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("L"), dtype=float) / 255


def run(capsys, argv) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_error_line(code: int, err: str, command: str, *phrases: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith(f"ipfit {command}: error: "), err
    assert "Traceback" not in err
    for phrase in phrases:
        assert phrase in err, err


@pytest.fixture
def torus_json(tmp_path):
    shape = synthetic.torus(800)
    sphere = synthetic.ellipsoid(axes=(1.4, 1.4, 0.5)).polynomial
    path = tmp_path / "torus.json"
    path.write_text(json.dumps(adaptive_result(shape.polynomial, {2: sphere, 4: shape.polynomial}, 4), indent=1))
    return shape, path


@pytest.fixture
def circle_json(tmp_path):
    shape = synthetic.circle(100)
    path = tmp_path / "circle.json"
    shape.polynomial.save(path)
    return shape, path


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl"])
def test_mesh_3d(torus_json, tmp_path, capsys, suffix):
    import trimesh

    _, path = torus_json
    out = tmp_path / f"t{suffix}"
    code, stdout, _ = run(capsys, ["mesh", path, "-o", out, "--resolution", "40"])
    assert code == 0
    mesh = trimesh.load(out, force="mesh")
    assert len(mesh.faces) > 100
    assert "1 component(s)" in stdout and "closed" in stdout


def test_mesh_selected_degree_and_points(torus_json, tmp_path, capsys):
    import trimesh

    shape, path = torus_json
    data = write_points(tmp_path / "torus.csv", shape.points)
    out = tmp_path / "d2.ply"
    code, stdout, _ = run(capsys, ["mesh", path, "-o", out, "--degree", "2", "--points", data, "--resolution", "40"])
    assert code == 0 and "degree 2" in stdout
    radii = np.linalg.norm(trimesh.load(out, force="mesh").vertices[:, :2], axis=1)
    assert radii.max() == pytest.approx(1.4, abs=0.1)  # the degree-2 ellipsoid, not the torus


def test_mesh_2d_svg_csv_agree_in_data_coordinates(circle_json, tmp_path):
    import xml.etree.ElementTree as ET

    _, path = circle_json
    assert main(["mesh", str(path), "-o", str(tmp_path / "c.svg")]) == 0
    assert main(["mesh", str(path), "-o", str(tmp_path / "c.csv")]) == 0
    rows = np.loadtxt(tmp_path / "c.csv", delimiter=",", comments="#", skiprows=3)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 1:], axis=1), 1.0, atol=0.01)
    root = ET.parse(tmp_path / "c.svg").getroot()
    ns = "{http://www.w3.org/2000/svg}"
    assert "data coordinates" in root.find(f"{ns}desc").text
    group = root.find(f"{ns}g")
    (_, _, _, _, _, shift) = map(float, group.get("transform")[len("matrix("):-1].split())
    (path_el,) = group.findall(f"{ns}path")
    numbers = [float(t) for t in path_el.get("d").replace("M", " ").replace("L", " ").replace("Z", " ").split()]
    svg = np.reshape(numbers, (-1, 2))
    # the SVG's numbers are the CSV's (to 6 significant digits), without the closing repeat
    np.testing.assert_allclose(svg, rows[:-1, 1:], rtol=1e-5, atol=1e-6)
    viewbox = [float(v) for v in root.get("viewBox").split()]
    assert shift == pytest.approx(2 * viewbox[1] + viewbox[3])  # y ↦ (y0 + y1) − y inside the box


@pytest.mark.parametrize("argv, phrases", [
    (["mesh", "{circle}", "-o", "{tmp}/c.ply"], ["-o/--output: expected a file name ending in .svg or .csv",
                                                "got '.ply'"]),
    (["mesh", "{circle}", "-o", "{tmp}/c.xyz"], ["ending in .svg or .csv", "got '.xyz'"]),
    (["mesh", "{circle}", "-o", "{tmp}/c"], ["with no extension"]),
    (["mesh", "{tmp}/missing.json", "-o", "{tmp}/c.svg"], ["no such file"]),
    (["mesh", "{circle}", "-o", "{tmp}/c.svg", "--degree", "6"], ["--degree: expected a degree"]),
    (["mesh", "{circle}", "-o", "{tmp}/nofolder/c.svg"], ["does not exist"]),
])
def test_mesh_errors_one_line(circle_json, tmp_path, capsys, argv, phrases):
    _, path = circle_json
    code, _, err = run(capsys, [a.format(circle=path, tmp=tmp_path) for a in argv])
    assert_one_error_line(code, err, "mesh", *phrases)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["circle.json"]


def test_mesh_3d_refuses_curve_suffix_before_work(torus_json, tmp_path, capsys):
    _, path = torus_json
    code, _, err = run(capsys, ["mesh", path, "-o", tmp_path / "t.svg"])
    assert_one_error_line(code, err, "mesh", "ending in .ply or .obj or .stl for a 3D result")


# -- corrupted results: every reader refuses them with one line ------------------------------

@pytest.mark.parametrize("command", ["mesh", "score", "plot"])
@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corrupted_result_one_line_exit_2(fitted, case, command, tmp_path, capsys):
    _, key, phrase = CORRUPTIONS[case]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(corrupted(fitted, case)))
    data = write_points(tmp_path / "data.csv", synthetic.ellipse(120).points)
    argv = {"mesh": ["mesh", path, "-o", tmp_path / "z.svg"],
            "score": ["score", path, "--points", data],
            "plot": ["plot", path, "-o", tmp_path / "p.png"]}[command]
    code, out, err = run(capsys, argv)
    assert_one_error_line(code, err, command, f"{path}: {key}: ", phrase)
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json", "data.csv"]


# -- plot -----------------------------------------------------------------------------------

def test_plot(torus_json, circle_json, tmp_path, capsys):
    shape, path = torus_json
    data = write_points(tmp_path / "torus.csv", shape.points)
    out = tmp_path / "t.png"
    code, stdout, err = run(capsys, ["plot", path, "--points", data, "-o", out, "--resolution", "28"])
    assert code == 0 and err == ""
    assert nonblank(out) > 0
    assert "5 panel(s)" in stdout  # 2 degrees, smoothness, 2 comparisons: the points are on the surfaces
    _, cpath = circle_json
    code, stdout, err = run(capsys, ["plot", cpath, "-o", tmp_path / "c.png"])
    assert code == 0 and err == ""  # a plain polynomial records no data: nothing to warn about
    assert nonblank(tmp_path / "c.png") > 0


@pytest.mark.parametrize("output, phrase", [
    ("p.xyz", "got '.xyz'"),
    ("p", "with no extension"),
])
def test_plot_refuses_unknown_suffix(circle_json, tmp_path, capsys, output, phrase):
    _, path = circle_json
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / output])
    assert_one_error_line(code, err, "plot", "-o/--output: expected a figure file name ending in .png, .pdf, .svg",
                          phrase)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["circle.json"]


def test_plot_bounds_the_dpi(torus_json, tmp_path, capsys):
    _, path = torus_json
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "t.png", "--dpi", "100000"])
    assert code == 2 and err.count("\n") == 1 and "--dpi" in err and "from 1 to 2400" in err
    # within the option's range, but too many pixels for a five-panel figure
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "t.png", "--dpi", "2400"])
    assert_one_error_line(code, err, "plot", "dpi: expected at most", "million pixels", "got 2400")
    assert not (tmp_path / "t.png").exists()


def _with_input(path: Path, record: dict) -> None:
    data = json.loads(path.read_text())
    data["input"] = record
    path.write_text(json.dumps(data))


def test_plot_finds_the_recorded_data_by_absolute_path(circle_json, tmp_path, capsys, monkeypatch):
    shape, path = circle_json
    data = write_points(tmp_path / "circle.csv", shape.points)
    _with_input(path, {"source": "circle.csv", "path": str(Path(data).resolve()), "n_points": 100})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # "circle.csv" means nothing here; the absolute path does
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "c.png"])
    assert code == 0 and err == ""
    code, _, err = run(capsys, ["plot", path, "--no-points", "-o", tmp_path / "bare.png"])
    assert code == 0 and err == ""
    with_points = image(tmp_path / "c.png")
    bare = image(tmp_path / "bare.png")
    assert with_points.shape == bare.shape and np.sum(with_points < bare - 0.1) > 50  # the grey points


def test_plot_finds_a_bundled_dataset_by_name(tmp_path, capsys):
    from ipfit import load_dataset

    cloud = load_dataset("airplane")
    poly = synthetic.ellipse(a=1.0, b=1.0).polynomial
    result = poly.to_dict()
    result["normalization"] = {"center": np.mean(cloud.points, axis=0).tolist(),
                               "scale": float(np.ptp(cloud.points, axis=0).max() / 2)}
    result["input"] = {"source": "airplane", "n_points": len(cloud.points)}
    path = tmp_path / "a.json"
    path.write_text(json.dumps(result))
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "a.png", "--resolution", "60"])
    assert code == 0 and err == ""
    code, out, err = run(capsys, ["score", path, "--json", "--resolution", "60"])
    assert code == 0 and json.loads(out)["tau"] > 0


@pytest.mark.parametrize("record, phrase", [
    ({"source": "gone.csv", "path": "/nowhere/gone.csv", "n_points": 100}, "/nowhere/gone.csv does not exist"),
    ({"source": "gone.csv", "n_points": 100}, "gone.csv does not exist (here)"),
    ({"n_points": 100}, "does not record its data"),
])
def test_plot_warns_once_when_the_data_cannot_be_found(circle_json, tmp_path, capsys, monkeypatch, record, phrase):
    _, path = circle_json
    _with_input(path, record)
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "c.png"])
    assert code == 0 and nonblank(tmp_path / "c.png") > 0
    assert err.count("\n") == 1 and err.startswith("ipfit plot: warning: ") and phrase in err
    assert "without the points" in err and "--points DATA" in err
    code, _, err = run(capsys, ["plot", path, "--no-points", "-o", tmp_path / "c.png"])
    assert code == 0 and err == ""  # asked not to look


def test_plot_warns_when_the_recorded_file_is_other_data(circle_json, tmp_path, capsys):
    shape, path = circle_json
    data = write_points(tmp_path / "c.csv", shape.points[:50])  # the file changed since the fit
    _with_input(path, {"source": data, "path": data, "n_points": 100})
    code, _, err = run(capsys, ["plot", path, "-o", tmp_path / "c.png"])
    assert code == 0 and err.count("\n") == 1 and "has 50 2D points, the result was fitted to 100" in err


def test_mesh_frames_by_bounds_without_looking_for_data(torus_json, tmp_path, capsys):
    import trimesh

    _, path = torus_json
    data = json.loads(path.read_text())
    data["bounds"] = [[-1.4, 1.4], [-1.4, 1.4], [-0.4, 0.4]]
    data["input"] = {"source": "gone.csv", "path": "/nowhere/gone.csv"}
    path.write_text(json.dumps(data))
    code, _, err = run(capsys, ["mesh", path, "-o", tmp_path / "t.ply", "--resolution", "40", "--margin", "0.1"])
    assert code == 0 and err == ""
    vertices = trimesh.load(tmp_path / "t.ply", force="mesh").vertices
    assert np.abs(vertices[:, 2]).max() == pytest.approx(0.4, abs=0.05)  # the torus, inside the recorded box
    del data["bounds"]
    path.write_text(json.dumps(data))
    code, _, err = run(capsys, ["mesh", path, "-o", tmp_path / "t.ply", "--resolution", "40"])
    assert code == 0 and err.count("\n") == 1 and "framing the box by the result's normalisation" in err


# -- score ----------------------------------------------------------------------------------

def test_score_prints_and_writes(torus_json, tmp_path, capsys):
    shape, path = torus_json
    data = write_points(tmp_path / "torus.csv", shape.points)
    before = json.loads(path.read_text())
    code, out, _ = run(capsys, ["score", path, "--points", data, "--json", "--resolution", "48"])
    assert code == 0
    q = json.loads(out)
    assert q["recall"] == 1.0 and q["n_spurious"] == 0 and q["closed"] is True
    assert json.loads(path.read_text()) == before  # without --write the result is untouched
    code, out, _ = run(capsys, ["score", path, "--points", data, "--write", "--resolution", "48"])
    assert code == 0 and "f_score" in out
    after = json.loads(path.read_text())
    assert list(after)[: len(before)] == list(before)  # existing keys kept, in order
    assert {k: after[k] for k in before} == before
    assert after["quality"]["recall"] == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["torus.csv", "torus.json"]


def test_score_takes_the_data_as_points_only(circle_json, tmp_path, capsys):
    shape, path = circle_json
    data = write_points(tmp_path / "c.csv", shape.points)
    code, new, err = run(capsys, ["score", path, "--points", data, "--json"])
    assert code == 0 and err == "" and json.loads(new)["recall"] == 1.0
    with pytest.raises(SystemExit) as exc:  # the old positional DATA is gone: argparse refuses it
        build_parser().parse_args(["score", str(path), str(data)])
    assert exc.value.code == 2


def test_score_finds_recorded_data_or_says_how_to_pass_it(circle_json, tmp_path, capsys):
    shape, path = circle_json
    data = write_points(tmp_path / "c.csv", shape.points)
    _with_input(path, {"source": "c.csv", "path": data, "n_points": 100})
    code, out, err = run(capsys, ["score", path])
    assert code == 0 and err == "" and "against c.csv" in out
    _with_input(path, {"source": "c.csv", "path": str(tmp_path / "moved.csv"), "n_points": 100})
    code, _, err = run(capsys, ["score", path])
    assert_one_error_line(code, err, "score", "moved.csv does not exist", "Pass the data with --points DATA")


def test_score_degree_tau_and_contour(torus_json, circle_json, tmp_path, capsys):
    shape, path = torus_json
    data = write_points(tmp_path / "torus.csv", shape.points)
    code, out, _ = run(capsys, ["score", path, "--points", data, "--degree", "2", "--json", "--resolution", "32"])
    assert code == 0 and json.loads(out)["f_score"] < 0.9  # the ellipsoid misses the hole
    cshape, cpath = circle_json
    sparse = write_points(tmp_path / "sparse.csv", cshape.points[::4])  # 25 ordered points
    code, out, _ = run(capsys, ["score", cpath, "--points", sparse, "--json"])
    q = json.loads(out)
    assert q["reference"] == "contour" and q["f_score"] == 1.0
    code, out, _ = run(capsys, ["score", cpath, "--points", sparse, "--json", "--contour", "no", "--tau", "0.01"])
    q = json.loads(out)
    # the bare points: τ is honoured, and the circle between them is within their gaps (0.25 apart)
    assert q["reference"] == "points" and q["tau"] == 0.01 and q["recall"] == 1.0 and q["precision"] == 1.0


def test_score_with_mesh_faces(tmp_path, capsys):
    import trimesh

    trimesh.creation.icosphere(subdivisions=2).export(tmp_path / "ico.ply")
    synthetic.sphere().polynomial.save(tmp_path / "s.json")
    code, out, _ = run(capsys, ["score", tmp_path / "s.json", "--points", tmp_path / "ico.ply", "--json",
                                "--resolution", "48"])
    q = json.loads(out)
    assert code == 0 and q["reference"] == "faces" and q["f_score"] == 1.0


def test_score_errors(torus_json, tmp_path, capsys):
    shape, path = torus_json
    flat = write_points(tmp_path / "flat.csv", synthetic.circle(30).points)
    code, _, err = run(capsys, ["score", path, "--points", flat])
    assert_one_error_line(code, err, "score", "--points: expected 3D points")
    data = write_points(tmp_path / "torus.csv", shape.points)
    code, _, err = run(capsys, ["score", path, "--points", data, "--write", "--degree", "2"])
    assert_one_error_line(code, err, "score", "--write")
    code, _, err = run(capsys, ["score", path, "--points", data, "--tau", "0"])
    assert_one_error_line(code, err, "score", "--tau")

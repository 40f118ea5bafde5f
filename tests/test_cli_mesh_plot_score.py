"""``ipfit mesh``, ``ipfit plot`` and ``ipfit score`` end to end (in-process)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipfit.cli import main
from ipfit.datasets import synthetic

from test_plotting import adaptive_result, nonblank


@pytest.fixture
def inputs(monkeypatch):
    """Serve INPUT names from memory, so these tests do not depend on the file readers."""
    from ipfit.cli import _common

    table = {}
    original = _common.load_input

    def fake(spec):
        if spec in table:
            points, faces = table[spec]
            return _common.Input(points, None, spec, faces)
        return original(spec)

    monkeypatch.setattr(_common, "load_input", fake)
    return table


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
    assert main(["mesh", str(path), "-o", str(out), "--resolution", "40"]) == 0
    mesh = trimesh.load(out, force="mesh")
    assert len(mesh.faces) > 100
    line = capsys.readouterr().out
    assert "1 component(s)" in line and "closed" in line


def test_mesh_selected_degree_and_points(torus_json, tmp_path, inputs, capsys):
    import trimesh

    shape, path = torus_json
    inputs["torus-data"] = (shape.points, None)
    out = tmp_path / "d2.ply"
    assert main(["mesh", str(path), "-o", str(out), "--degree", "2", "--points", "torus-data",
                 "--resolution", "40"]) == 0
    assert "degree 2" in capsys.readouterr().out
    radii = np.linalg.norm(trimesh.load(out, force="mesh").vertices[:, :2], axis=1)
    assert radii.max() == pytest.approx(1.4, abs=0.1)  # the degree-2 ellipsoid, not the torus


def test_mesh_2d_svg_csv(circle_json, tmp_path):
    _, path = circle_json
    assert main(["mesh", str(path), "-o", str(tmp_path / "c.svg")]) == 0
    assert main(["mesh", str(path), "-o", str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.svg").read_text().count("<path") == 1
    rows = np.loadtxt(tmp_path / "c.csv", delimiter=",", comments="#", skiprows=3)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 1:], axis=1), 1.0, atol=0.01)


@pytest.mark.parametrize("argv, match", [
    (["mesh", "{circle}", "-o", "{tmp}/c.ply"], "expected an extension in .svg, .csv"),
    (["mesh", "{tmp}/missing.json", "-o", "{tmp}/c.svg"], "no such file"),
    (["mesh", "{circle}", "-o", "{tmp}/c.svg", "--degree", "6"], "--degree"),
    (["mesh", "{circle}", "-o", "{tmp}/nofolder/c.svg"], "does not exist"),
])
def test_mesh_errors_one_line(circle_json, tmp_path, capsys, argv, match):
    _, path = circle_json
    argv = [a.format(circle=path, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1 and err.startswith("ipfit mesh: error:")


def test_plot(torus_json, circle_json, tmp_path, inputs, capsys):
    shape, path = torus_json
    inputs["torus-data"] = (shape.points, None)
    out = tmp_path / "t.png"
    assert main(["plot", str(path), "--points", "torus-data", "-o", str(out), "--resolution", "28"]) == 0
    assert nonblank(out) > 0
    assert "6 panel(s)" in capsys.readouterr().out
    _, cpath = circle_json
    assert main(["plot", str(cpath), "-o", str(tmp_path / "c.png")]) == 0
    assert nonblank(tmp_path / "c.png") > 0


def test_plot_uses_recorded_input(circle_json, tmp_path, inputs):
    shape, path = circle_json
    data = json.loads(path.read_text())
    data["input"] = {"source": "circle-data", "n_points": 100}
    path.write_text(json.dumps(data))
    inputs["circle-data"] = (shape.points, None)
    assert main(["plot", str(path), "-o", str(tmp_path / "c.png")]) == 0
    data["input"]["source"] = "gone"  # an unreadable recorded input only drops the points
    path.write_text(json.dumps(data))
    assert main(["plot", str(path), "-o", str(tmp_path / "c2.png")]) == 0


def test_score_prints_and_writes(torus_json, tmp_path, inputs, capsys):
    shape, path = torus_json
    inputs["torus-data"] = (shape.points, None)
    before = json.loads(path.read_text())
    assert main(["score", str(path), "torus-data", "--json", "--resolution", "48"]) == 0
    q = json.loads(capsys.readouterr().out)
    assert q["recall"] == 1.0 and q["n_spurious"] == 0 and q["closed"] is True
    assert json.loads(path.read_text()) == before  # without --write the result is untouched
    assert main(["score", str(path), "torus-data", "--write", "--resolution", "48"]) == 0
    assert "f_score" in capsys.readouterr().out
    after = json.loads(path.read_text())
    assert list(after)[: len(before)] == list(before)  # existing keys kept, in order
    assert {k: after[k] for k in before} == before
    assert after["quality"]["recall"] == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["torus.json"]


def test_score_degree_tau_and_contour(torus_json, circle_json, inputs, capsys):
    shape, path = torus_json
    inputs["torus-data"] = (shape.points, None)
    assert main(["score", str(path), "torus-data", "--degree", "2", "--json", "--resolution", "32"]) == 0
    assert json.loads(capsys.readouterr().out)["f_score"] < 0.9  # the ellipsoid misses the hole
    cshape, cpath = circle_json
    inputs["circle-sparse"] = (cshape.points[::4], None)  # 25 ordered points
    assert main(["score", str(cpath), "circle-sparse", "--json"]) == 0
    q = json.loads(capsys.readouterr().out)
    assert q["reference"] == "contour" and q["f_score"] == 1.0
    assert main(["score", str(cpath), "circle-sparse", "--json", "--contour", "no", "--tau", "0.01"]) == 0
    q = json.loads(capsys.readouterr().out)
    assert q["reference"] == "points" and q["tau"] == 0.01 and q["precision"] < 0.5


def test_score_with_mesh_faces(tmp_path, inputs, capsys):
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2)
    inputs["ico"] = (np.asarray(mesh.vertices), np.asarray(mesh.faces))
    synthetic.sphere().polynomial.save(tmp_path / "s.json")
    assert main(["score", str(tmp_path / "s.json"), "ico", "--json", "--resolution", "48"]) == 0
    q = json.loads(capsys.readouterr().out)
    assert q["reference"] == "faces" and q["f_score"] == 1.0


def test_score_errors(torus_json, circle_json, inputs, capsys):
    shape, path = torus_json
    inputs["flat"] = (synthetic.circle(30).points, None)
    assert main(["score", str(path), "flat"]) == 2
    assert "3D points" in capsys.readouterr().err
    inputs["torus-data"] = (shape.points, None)
    assert main(["score", str(path), "torus-data", "--write", "--degree", "2"]) == 2
    assert main(["score", str(path), "torus-data", "--tau", "0"]) == 2
    assert capsys.readouterr().err.count("\n") == 2


def test_score_reads_a_real_file(tmp_path, capsys):
    io = pytest.importorskip("ipfit.io")
    shape = synthetic.circle(100)
    shape.polynomial.save(tmp_path / "c.json")
    np.savetxt(tmp_path / "c.csv", shape.points, delimiter=",", header="x,y", comments="")
    assert io.read_points(tmp_path / "c.csv").points.shape == (100, 2)
    assert main(["score", str(tmp_path / "c.json"), str(tmp_path / "c.csv"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["f_score"] == 1.0

"""``ipfit export`` and ``ipfit render`` end to end (in-process), and the true distance of ``ipfit score``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipfit.cli import main
from ipfit.datasets import synthetic
from ipfit.analysis.invariants import similarity


@pytest.fixture
def sphere_json(tmp_path):
    poly = similarity(synthetic.sphere(radius=1.0).polynomial, translation=[0.5, 0.0, -0.5], scale=2.0)
    path = tmp_path / "sphere.json"
    poly.save(path)
    return poly, path


@pytest.fixture
def circle_json(tmp_path):
    poly = synthetic.circle(radius=2.0, center=(1.0, -1.0)).polynomial
    path = tmp_path / "circle.json"
    poly.save(path)
    return poly, path


def test_export_python_to_stdout_runs(sphere_json, capsys, rng):
    poly, path = sphere_json
    assert main(["export", str(path), "--to", "python"]) == 0
    namespace: dict = {}
    exec(capsys.readouterr().out, namespace)
    pts = rng.uniform(-3, 3, (20, 3))
    np.testing.assert_allclose(namespace["f"](*pts.T), poly(pts), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("language,marker", [("c", "double ipfit_f(double x, double y, double z)"),
                                             ("glsl", "float ipfit_sdf(vec3 p)"),
                                             ("latex", r"\begin{aligned}"), ("sympy", "import sympy")])
def test_export_to_file(sphere_json, tmp_path, capsys, language, marker):
    poly, path = sphere_json
    out = tmp_path / f"f.{language}"
    assert main(["export", str(path), "--to", language, "-o", str(out)]) == 0
    assert marker in out.read_text()
    assert out.read_text() == poly.to_source(language)
    assert str(out) in capsys.readouterr().out


def test_export_errors_are_one_line(sphere_json, tmp_path, capsys):
    _, path = sphere_json
    with pytest.raises(SystemExit) as exc:
        main(["export", str(path), "--to", "fortran"])
    assert exc.value.code == 2
    assert main(["export", str(tmp_path / "missing.json"), "--to", "c"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no such file" in err[-1]
    assert main(["export", str(path), "--to", "c", "-o", str(tmp_path / "nodir" / "f.c")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_render_writes_a_png_of_the_surface(sphere_json, tmp_path, capsys):
    from PIL import Image

    _, path = sphere_json
    out = tmp_path / "sphere.png"
    assert main(["render", str(path), "-o", str(out), "--size", "40", "30", "--points", "sphere"]) == 2  # wrong INPUT
    capsys.readouterr()
    assert main(["render", str(path), "-o", str(out), "--size", "40", "30"]) == 0
    img = np.asarray(Image.open(out))
    assert img.shape == (30, 40, 3)
    covered = (img < 255).any(axis=2)
    assert covered[15, 20] and 0.03 < covered.mean() < 0.9  # the default box contains the sphere
    assert "ray-cast image" in capsys.readouterr().out


def test_render_refuses_curves_and_other_formats(circle_json, sphere_json, tmp_path, capsys):
    _, circle_path = circle_json
    _, sphere_path = sphere_json
    assert main(["render", str(circle_path), "-o", str(tmp_path / "c.png")]) == 2
    assert "2D curve" in capsys.readouterr().err
    assert main(["render", str(sphere_path), "-o", str(tmp_path / "s.jpg")]) == 2
    assert ".png" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.png")) and not list(tmp_path.glob("*.jpg"))


def test_score_reports_true_distance_beside_taubin(circle_json, tmp_path, capsys):
    poly, path = circle_json
    data = tmp_path / "pts.txt"
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    radii = 2.0 + np.where(np.arange(60) % 2, 0.3, -0.2)  # data off the circle by 0.3 and 0.2
    np.savetxt(data, np.column_stack([1 + radii * np.cos(t), -1 + radii * np.sin(t)]))
    assert main(["score", str(path), "--points", str(data), "--json"]) == 0
    dist = json.loads(capsys.readouterr().out)["distance_to_zero_set"]
    assert dist["projected_mean"] == pytest.approx(0.25, abs=1e-9)
    assert dist["projected_max"] == pytest.approx(0.3, abs=1e-9)
    # Taubin's |f|/|∇f| = |ρ² − 4| / (2ρ): 0.2804 and 0.2111 here, not the true 0.3 and 0.2.
    assert dist["taubin_mean"] == pytest.approx(np.mean(np.abs(radii**2 - 4) / (2 * radii)), rel=1e-9)
    assert main(["score", str(path), "--points", str(data)]) == 0
    out = capsys.readouterr().out
    assert "distance_true     mean 0.25, max 0.3" in out and "distance_taubin" in out

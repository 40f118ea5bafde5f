"""Hostile result files against the one loader and the six commands that read results.

Every case is a real file on disk run through ``ipfit.cli.main`` (or a real subprocess): one
error line and exit 2, or the work done; never a traceback, a hang or a file left behind.
"""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ipfit import basis
from ipfit.degree.adaptive import fit_adaptive
from ipfit.exceptions import InvalidInputError, ReadError
from ipfit.degree.results import load_result, result_view

from test_cli_mesh_plot_score import assert_one_error_line, run

COMMANDS = {  # each command's cheapest complete run of RESULT (written into the test's folder)
    "mesh": lambda out: ["-o", out / "m.{ext}", "--resolution", "24"],
    "plot": lambda out: ["-o", out / "p.png", "--resolution", "24", "--no-points", "--dpi", "30"],
    "score": lambda out: ["--points", out / "pts.csv", "--resolution", "24"],
    "export": lambda out: ["--to", "python", "-o", out / "f.py"],
    "view": lambda out: ["-o", out / "v.html", "--no-points"],
    "render": lambda out: ["-o", out / "r.png", "--size", "12", "12"],
}


def quadric(dim: int, scale: float = 1.0, constant: float = -1.0) -> dict:
    """The unit circle or sphere (or, with constant +1, no zero set), scaled by ``scale``."""
    rows = basis.exponents(dim, 2).tolist()
    coefficients = [constant if sum(r) == 0 else 1.0 if max(r) == 2 else 0.0 for r in rows]
    return {"format": "ipfit", "version": 1, "dim": dim, "degree": 2, "exponents": rows,
            "coefficients": coefficients, "normalization": {"center": [0.0] * dim, "scale": scale}}


def with_key(data: dict, path: str, value) -> dict:
    doc = copy.deepcopy(data)
    *parents, last = path.split(".")
    target = doc
    for part in parents:
        target = target[part]
    target[last] = value
    return doc


def nested(depth: int) -> str:
    return "[" * depth + "]" * depth


def degree_30_surface() -> dict:
    rows = basis.exponents(3, 30).tolist()
    return {"format": "ipfit", "version": 1, "dim": 3, "degree": 30, "exponents": rows,
            "coefficients": [-1.0] + [1.0] * (len(rows) - 1)}


SPHERE = quadric(3)
SPHERE_TEXT = json.dumps(SPHERE)
# name -> (JSON text of the file, a phrase its one error line must hold)
CORRUPTED = {
    "5000-digit coefficient": (SPHERE_TEXT.replace('"coefficients": [-1.0', '"coefficients": [' + "7" * 5000),
                               "more than 4300 digits"),
    "5000-digit degree": (SPHERE_TEXT.replace('"degree": 2', '"degree": ' + "9" * 5000), "more than 4300 digits"),
    "400-digit coefficient": (SPHERE_TEXT.replace('"coefficients": [-1.0', '"coefficients": [' + "7" * 400),
                              '"coefficients": expected a list of finite numbers'),
    "400-digit exponent": (SPHERE_TEXT.replace("[[0, 0, 0]", "[[" + "3" * 400 + ", 0, 0]"), '"exponents"'),
    "nested 100,000 deep": ('{"format": "ipfit", "version": 1, "info": ' + nested(100_000) + "}",
                            "nested too deeply"),
    "nested 200 deep (under the parser's limit)": (SPHERE_TEXT[:-1] + ', "info": {"x": ' + nested(200) + "}}",
                                                    "nested more than 64 levels"),
    "a list instead of the result": ("[1, 2]", "a JSON object was expected"),
    "normalization a list": (json.dumps(with_key(SPHERE, "normalization", [0, 1])), '"normalization": expected an object'),
    "input a list": (json.dumps({**SPHERE, "input": ["a"]}), '"input": expected an object'),
    "degrees a string": (json.dumps({**SPHERE, "degrees": "abc"}), '"degrees": expected a list of objects'),
    "missing coefficients": (json.dumps({k: v for k, v in SPHERE.items() if k != "coefficients"}),
                             '"coefficients": expected'),
    "NaN coefficient": (SPHERE_TEXT.replace('"coefficients": [-1.0', '"coefficients": [NaN'),
                        '"coefficients": expected a list of finite numbers'),
    "one coefficient short": (json.dumps({**SPHERE, "coefficients": SPHERE["coefficients"][:-1]}),
                              "10 values, one per exponent row"),
    "degree 30 in 3D": (json.dumps(degree_30_surface()), "at most 20 in 3D"),
    "centre 1e300": (json.dumps(with_key(SPHERE, "normalization.center", [1e300] * 3)), "at most 1e+150"),
    "centre and scale 1e300": (json.dumps(with_key(with_key(SPHERE, "normalization.center", [1e300] * 3),
                                                   "normalization.scale", 1e300)), "at most 1e+150"),
    "scale 1e308": (json.dumps(with_key(SPHERE, "normalization.scale", 1e308)), '"normalization.scale"'),
    "bounds 1e200": (json.dumps({**SPHERE, "bounds": [[-1e200, 1e200]] * 3}), '"bounds"'),
}


@pytest.fixture
def folder(tmp_path):
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(300, 3))
    np.savetxt(tmp_path / "pts.csv", sphere / np.linalg.norm(sphere, axis=1)[:, None], delimiter=",")
    np.savetxt(tmp_path / "circle.csv", np.c_[np.cos(t), np.sin(t)], delimiter=",")
    return tmp_path


def argv(command: str, result: Path, folder: Path, dim: int = 3) -> list:
    rest = [str(a).replace("{ext}", "ply" if dim == 3 else "svg") for a in COMMANDS[command](folder)]
    return [command, result, *rest]


@pytest.mark.parametrize("case", sorted(CORRUPTED))
def test_load_result_refuses_each_corruption_in_one_line(tmp_path, case):
    """The one loader (what batch and every command call) raises ReadError, one line, quickly."""
    text, phrase = CORRUPTED[case]
    path = tmp_path / "bad.json"
    path.write_text(text)
    start = time.perf_counter()
    with pytest.raises(ReadError) as info:
        load_result(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and phrase in message, message
    assert time.perf_counter() - start < 2


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_refuses_every_corruption_in_one_line(capsys, folder, command):
    """mesh, plot, score, export, view and render: exit 2 and one line naming the file, nothing written."""
    before = set(os.listdir(folder))
    for case, (text, phrase) in CORRUPTED.items():
        path = folder / "bad.json"
        path.write_text(text)
        code, _, err = run(capsys, argv(command, path, folder))
        assert_one_error_line(code, err, command, str(path), phrase)
        assert set(os.listdir(folder)) == before | {"bad.json"}, case


def test_a_5000_digit_integer_is_one_line_in_a_real_process(folder):
    """As the user meets it: a separate interpreter, its stderr and exit code."""
    path = folder / "bad.json"
    path.write_text(CORRUPTED["5000-digit coefficient"][0])
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src")}
    done = subprocess.run([sys.executable, "-m", "ipfit.cli", "mesh", str(path), "-o", str(folder / "m.ply")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "more than 4300 digits" in done.stderr and "Traceback" not in done.stderr
    assert not (folder / "m.ply").exists()


def test_api_dicts_with_python_only_values_are_refused_in_one_line():
    """A dict built in Python can hold what JSON text cannot: an int of 5000 digits, deep nesting."""
    deep: list = []
    for _ in range(5000):
        deep = [deep]
    for bad in (with_key(SPHERE, "coefficients", [10 ** 5000] + SPHERE["coefficients"][1:]),
                with_key(SPHERE, "degree", 10 ** 5000), {**SPHERE, "info": {"x": deep}}):
        with pytest.raises(InvalidInputError) as info:
            load_result(bad)
        assert "\n" not in str(info.value) and len(str(info.value)) < 400


@pytest.mark.parametrize("dim", [2, 3])
def test_null_normalization_means_identity_in_every_command(capsys, folder, dim):
    """``"normalization": null`` (documented: not recorded, identity) works everywhere, also without "dim"."""
    data = {k: v for k, v in quadric(dim).items() if k != "dim"}
    data["normalization"] = None
    path = folder / "null.json"
    path.write_text(json.dumps(data))
    assert result_view(path).polynomial.scale == 1.0
    for command in COMMANDS:
        if command == "render" and dim == 2:
            continue
        if command == "score" and dim == 2:
            code, _, err = run(capsys, ["score", path, "--points", folder / "circle.csv", "--resolution", "24"])
        else:
            code, _, err = run(capsys, argv(command, path, folder, dim))
        assert code == 0, (command, err)
    assert (folder / "v.html").stat().st_size > 0


def test_view_names_the_dimension_of_a_minimal_result(capsys, folder):
    """No "dim", no normalisation: the dimension comes from the exponents (it said "0D")."""
    data = {k: v for k, v in quadric(2).items() if k not in ("dim", "normalization")}
    path = folder / "minimal.json"
    path.write_text(json.dumps(data))
    code, _, err = run(capsys, ["view", path, "-o", folder / "v.html", "--points", folder / "pts.csv"])
    assert_one_error_line(code, err, "view", "expected 2D points", "got 3D")


def test_surfaces_at_the_largest_scale_are_meshed_and_rendered(capsys, folder):
    """A sphere of radius 1e140 (the schema allows up to 1e150): mesh keeps its faces (skimage's float32
    scaling used to overflow them away) and render draws it like the unit sphere."""
    counts = {}
    for scale in (1.0, 1e140):
        path = folder / f"s{scale:g}.json"
        path.write_text(json.dumps(quadric(3, scale)))
        code, out, err = run(capsys, ["mesh", path, "-o", folder / f"s{scale:g}.ply", "--resolution", "24"])
        assert code == 0, err
        counts[scale] = out.split("vertices, ")[1].split(" faces")[0]
        code, out, err = run(capsys, ["render", path, "-o", folder / f"s{scale:g}.png", "--size", "24", "24"])
        assert code == 0 and "warning" not in err, err
        assert "surface on 0%" not in out
    assert counts[1.0] == counts[1e140] != "0"


def test_render_of_a_blank_image_says_why(capsys, folder):
    path = folder / "none.json"
    path.write_text(json.dumps(quadric(3, constant=1.0)))  # x² + y² + z² + 1 has no real zero
    code, _, err = run(capsys, ["render", path, "-o", folder / "r.png", "--size", "12", "12"])
    assert code == 0 and err.startswith("ipfit render: warning: no ray meets") and err.count("\n") == 1, err


def test_mesh_of_an_empty_zero_set_names_the_output_not_its_temporary(capsys, folder):
    path = folder / "none.json"
    path.write_text(json.dumps(quadric(3, constant=1.0)))
    code, _, err = run(capsys, ["mesh", path, "-o", folder / "m.ply", "--resolution", "24"])
    assert_one_error_line(code, err, "mesh", f"{folder / 'm.ply'}: ", "empty", "--margin")
    assert ".partial" not in err and sorted(os.listdir(folder)) == ["circle.csv", "none.json", "pts.csv"]


@pytest.mark.parametrize("command", ["plot", "score", "view", "mesh"])
def test_data_beyond_float64s_reach_is_refused_by_the_commands(capsys, folder, command):
    """A valid result with --points at 1e300 (it used to end in LinAlgError or "tau: ... inf")."""
    path = folder / "circle.json"
    path.write_text(json.dumps(quadric(2)))
    np.savetxt(folder / "far.csv", np.loadtxt(folder / "circle.csv", delimiter=",") * 1e300 + 1e300, delimiter=",")
    extra = {"plot": ["-o", folder / "p.png"], "view": ["-o", folder / "v.html"], "mesh": ["-o", folder / "m.svg"],
             "score": []}[command]
    code, _, err = run(capsys, [command, path, "--points", folder / "far.csv", *extra])
    assert_one_error_line(code, err, command, "--points: expected coordinates of magnitude at most 1e+150")


def ellipse(offset: float) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    return np.c_[2 * np.cos(t), np.sin(t)] + offset


def test_fit_refuses_data_its_result_could_not_record_before_fitting():
    """Offset 1e15 with extent ~1.5: refused up front about the data (it used to fit, then blame
    "normalization.scale" of its own result); at 1e9 the same shape fits and its result loads."""
    start = time.perf_counter()
    with pytest.raises(InvalidInputError) as info:
        fit_adaptive(ellipse(1e15), method="3l", min_degree=2, max_degree=2)
    assert time.perf_counter() - start < 1
    assert str(info.value).startswith("points: expected an extent") and "offset" in str(info.value)
    result = fit_adaptive(ellipse(1e9), method="3l", min_degree=2, max_degree=2)
    assert load_result(result.to_dict())["normalization"]["scale"] > 1e-12 * 1e9
    with pytest.raises(InvalidInputError, match="at most 1e\\+150"):
        fit_adaptive(ellipse(0) * 1e200, method="3l", min_degree=2, max_degree=2)


def test_fit_command_refuses_offset_data_and_writes_nothing(capsys, tmp_path):
    np.savetxt(tmp_path / "far.csv", ellipse(1e15), delimiter=",")
    code, _, err = run(capsys, ["fit", tmp_path / "far.csv", "-o", tmp_path / "out", "--degree", "2",
                                "--method", "3l"])
    assert_one_error_line(code, err, "fit", "offset", "Subtract the offset")
    assert sorted(os.listdir(tmp_path)) == ["far.csv"]


def test_quality_without_extent_names_what_the_caller_can_pass():
    from ipfit.zeroset.quality import quality

    poly = result_view(quadric(2)).polynomial
    with pytest.raises(InvalidInputError) as info:
        quality(poly, np.ones((5, 2)))
    assert "tau=" in str(info.value) and "--tau" in str(info.value) and "explicitly" not in str(info.value)


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS is how the test runs out of memory")
def test_out_of_memory_names_the_input_and_the_commands_option(folder):
    """A real process under a 2 GB address-space limit asked for a 20000 x 20000 image."""
    path = folder / "s.json"
    path.write_text(json.dumps(SPHERE))
    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30)); "
            "from ipfit.cli import main; sys.exit(main(sys.argv[1:]))")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src"), "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code, "render", str(path), "-o", str(folder / "r.png"),
                           "--size", "20000", "20000"], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr == f"ipfit render: error: out of memory on {path}. Try a smaller --size, or smaller data.\n"
    assert not (folder / "r.png").exists()

"""`ipfit fit` end to end, in-process and as a subprocess, including every bad input."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ipfit

from ipfit.degree.adaptive import select_degree, select_degree_geometric
from ipfit.zeroset.quality import Quality
from ipfit.degree.rules import get_rule, select_degree_capture
from ipfit.cli import main


def _outputs(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_fit_bundled_2d_dataset_in_process(tmp_path, capsys):
    prefix = tmp_path / "out" / "airplane"
    code = main(["fit", "airplane", "-o", str(prefix), "--method", "3l", "--quiet"])
    assert code == 0
    assert _outputs(prefix.parent) == ["airplane.csv", "airplane.json", "airplane.png", "airplane.svg"]
    data = json.loads((prefix.parent / "airplane.json").read_text())
    for key in ("format", "version", "dim", "degree", "exponents", "coefficients", "normalization", "method",
                "measures", "selected_degree", "degrees"):
        assert key in data
    assert_obeys_its_rule(data)
    assert set(data["measures"]) == {"dissimilarity", "smoothness", "distance", "delta"}


def assert_obeys_its_rule(data):
    """Every written JSON's selected_degree follows its own rule applied to its own degrees."""
    degrees = [d["degree"] for d in data["degrees"]]
    smooth = [d["smoothness"] for d in data["degrees"]]
    epsilon = data["adaptive"]["epsilon"]
    complete = data["adaptive"]["reason"] != "interrupted"
    if data["adaptive"]["rule"] == "paper":
        index, _ = select_degree(degrees, smooth, epsilon, complete)
    elif data["adaptive"]["rule"] in ("capture", "topology"):
        rule = get_rule(data["adaptive"]["rule"])  # "topology" also holds the data's topology
        quality = [Quality.from_dict(d["quality"]) for d in data["degrees"]]
        index = select_degree_capture(degrees, [q.f_score for q in quality], [rule.is_clean(q) for q in quality])
    else:
        quality = [d["quality"] for d in data["degrees"]]
        clean = [q["n_spurious"] == 0 and q["closed"] for q in quality]
        index, _ = select_degree_geometric(degrees, smooth, clean, [q["f_score"] for q in quality], epsilon, complete)
    assert data["selected_degree"] == degrees[index] == data["degree"]


def test_fit_3d_file_with_refinement_writes_a_mesh(tmp_path):
    prefix = tmp_path / "bunny"
    code = main(["fit", "bunny_res4", "-o", str(prefix), "--method", "de+polish",
                 "--max-degree", "4", "--iterations", "5", "--population", "40", "--quiet", "--seed", "3"])
    assert code == 0
    assert _outputs(tmp_path) == ["bunny.json", "bunny.ply", "bunny.png"]
    data = json.loads((tmp_path / "bunny.json").read_text())
    assert data["dim"] == 3 and data["selected_degree"] in (2, 4)
    assert_obeys_its_rule(data)
    assert all(len(d["coefficients"]) in (10, 35) for d in data["degrees"])


def test_fixed_degree(tmp_path):
    code = main(["fit", "boot", "-o", str(tmp_path / "b"), "--degree", "4", "--method", "3l", "--quiet",
                 "--no-picture", "--no-zero-set"])
    assert code == 0
    data = json.loads((tmp_path / "b.json").read_text())
    assert data["selected_degree"] == 4 and [d["degree"] for d in data["degrees"]] == [4]


def test_paper_flag_is_the_paper_preset_bit_for_bit(tmp_path):
    code = main(["fit", "airplane", "-o", str(tmp_path / "p"), "--paper", "--quiet", "--no-picture", "--no-zero-set"])
    assert code == 0
    data = json.loads((tmp_path / "p.json").read_text())
    assert data["adaptive"]["rule"] == "paper" and data["adaptive"]["far_term_weight"] == 0.0
    assert data["method"] == "de"
    assert_obeys_its_rule(data)
    points, normals = ipfit.load_dataset("airplane")
    same = ipfit.fit_adaptive(points, normals, method=ipfit.PAPER_METHOD, options=ipfit.PAPER, rule=ipfit.PAPER_RULE,
                              rng=0)
    assert [d["coefficients"] for d in data["degrees"]] == [d.x.tolist() for d in same.degrees]
    # Pinned: the per-degree coefficients of the paper's pipeline before the options refactor.
    golden = json.loads((Path(__file__).parent / "data" / "paper_airplane_golden.json").read_text())
    assert [d["degree"] for d in data["degrees"]] == golden["degrees"]
    assert data["selected_degree"] == golden["selected_degree"]
    for ours, pinned in zip(data["degrees"], golden["coefficients"]):
        assert ours["coefficients"] == pytest.approx(pinned, rel=1e-9, abs=1e-12)


def test_paper_flag_refuses_the_options_it_fixes(tmp_path, capsys):
    code = main(["fit", "airplane", "-o", str(tmp_path / "p"), "--paper", "--method", "pso", "--quiet"])
    assert code == 2 and "--paper: it fixes --method" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv,message", [
    (["fit", "no-such-file.ply"], "no-such-file.ply: no such file, nor a bundled dataset name"),
    (["fit", "boot", "--degree", "x"], "--degree: expected 'auto' or a whole number"),
    (["fit", "boot", "--epsilon", "abc"], "argument --epsilon: expected a number"),
    (["fit", "boot", "--delta", "-1"], "argument --delta: expected a number >= 0"),
    (["fit", "boot", "--method", "annealing"], "argument --method: invalid choice"),
    (["fit", "boot", "--iterations", "0"], "argument --iterations: expected a whole number >= 1"),
    (["fit", "airplane", "--degree", "30"], "--degree: degree 30 needs at least 496 points, the input has 200"),
    (["fit", "airplane", "--max-degree", "24", "--method", "3l"], "--max-degree: expected at most 18 for 200 points"),
    (["fit", "airplane", "--method", "3l", "--far-term-weight", "0.5"], "--far-term-weight: method '3l' is a linear fit"),
])
def test_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys, argv, message):
    prefix = tmp_path / "o" / "x"
    code = None
    try:
        code = main(argv + ["-o", str(prefix), "--quiet"])
    except SystemExit as exc:  # argparse errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert not prefix.parent.exists() or _outputs(prefix.parent) == []


def test_unreadable_file_exits_2(tmp_path, capsys):
    bad = tmp_path / "points.xyz"
    bad.write_text("1 2 3\nfoo bar baz\n")
    code = main(["fit", str(bad), "-o", str(tmp_path / "r"), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert str(bad) in err and len(err.strip().splitlines()) == 1
    assert _outputs(tmp_path) == ["points.xyz"]


def _run(args, cwd):
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-m", "ipfit.cli", *args], cwd=cwd, capture_output=True, text=True,
                          env=env, timeout=300)


def test_subprocess_success_and_failure(tmp_path):
    ok = _run(["fit", "airplane", "-o", "a", "--method", "3l"], tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "selected degree" in ok.stdout
    assert (tmp_path / "a.json").exists()
    bad = _run(["fit", "missing.csv", "-o", "m"], tmp_path)
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "Traceback" not in bad.stderr
    assert not (tmp_path / "m.json").exists()


def test_help_lists_every_option():
    out = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for option in ("--degree", "--max-degree", "--method", "--epsilon", "--delta", "--iterations", "--population",
                   "--seed", "--normals", "--output", "--quiet"):
        assert option in out.stdout
    top = subprocess.run([sys.executable, "-m", "ipfit.cli", "--help"], capture_output=True, text=True)
    assert top.returncode == 0 and "fit" in top.stdout


def test_ctrl_c_keeps_every_finished_degree(tmp_path, monkeypatch):
    import ipfit.degree.loop as loop

    real = loop.fit_linear

    def interrupting(points, normals, degree, method, **params):
        if degree == 6:
            raise KeyboardInterrupt
        return real(points, normals, degree, method, **params)

    monkeypatch.setattr(loop, "fit_linear", interrupting)
    code = main(["fit", "boot", "-o", str(tmp_path / "boot"), "--method", "3l", "--epsilon", "-1", "--rule", "paper",
                 "--quiet"])
    assert code == 130
    data = json.loads((tmp_path / "boot.json").read_text())
    assert [d["degree"] for d in data["degrees"]] == [2, 4]
    assert data["adaptive"]["reason"] == "interrupted"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_dataset_names_ignore_case_and_near_misses_get_a_suggestion(tmp_path, capsys):
    assert main(["fit", "Boot", "-o", str(tmp_path / "b"), "--method", "3l", "--degree", "2", "--quiet"]) == 0
    assert json.loads((tmp_path / "b.json").read_text())["input"]["source"] == "Boot"
    assert main(["fit", "bot", "-o", str(tmp_path / "c"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Did you mean 'boot'?" in err and err.count("\n") == 1
    assert not (tmp_path / "c.json").exists()


def test_fixed_and_odd_degrees_say_what_they_are(tmp_path, capsys):
    assert main(["fit", "boot", "-o", str(tmp_path / "b"), "--method", "3l", "--degree", "3", "--no-picture",
                 "--no-zero-set"]) == 0
    captured = capsys.readouterr()
    assert "--degree 3 is odd: an odd-degree zero set is never bounded" in captured.err
    assert "fixed degree 3" in captured.out
    data = json.loads((tmp_path / "b.json").read_text())
    assert data["adaptive"]["reason"] == "fixed" and data["degrees"][0]["reason"].startswith("selected")


def test_messages_name_the_options_typed(tmp_path, capsys):
    assert main(["fit", "airplane", "-o", str(tmp_path / "a"), "--method", "3l", "--max-degree", "30"]) == 2
    assert capsys.readouterr().err.startswith("ipfit fit: error: --max-degree: expected at most 18")
    with pytest.raises(SystemExit) as stop:
        main(["fit", "airplane", "-o", str(tmp_path / "a"), "--seed", "-1"])
    assert stop.value.code == 2 and "argument --seed: expected a whole number >= 0" in capsys.readouterr().err


def test_progress_shows_each_stage_when_piped(tmp_path):
    out = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", "boot", "-o", str(tmp_path / "b"), "--degree", "4",
                          "--iterations", "20", "--no-picture", "--no-zero-set"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert lines[:3] == ["degree 4: fitting", "degree 4: DE", "degree 4: L-BFGS polish"]
    assert lines[-1].startswith("degree 4: distance ")
    quiet = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", "boot", "-o", str(tmp_path / "q"), "--degree",
                            "2", "--method", "3l", "--quiet", "--no-picture"], capture_output=True, text=True)
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == ""


def test_a_degrees_line_counts_its_repair_polishes_and_the_other_solutions_measured():
    import io

    from ipfit.cli._progress import Progress

    stream = io.StringIO()
    progress = Progress("lines", stream=stream)
    done = {"event": "degree_done", "degree": 6, "distance": 0.01, "smoothness": 0.9, "dissimilarity": 0.02,
            "seconds": 1.5, "quality": {"f_score": 0.744, "precision": 0.8, "recall": 0.7}}
    progress({**done, "cleanup": [{"target": "spurious components"}, {"target": "another solution"},
                                  {"target": "another solution"}]})
    progress({**done, "degree": 8, "cleanup": [{"target": "another solution"}]})
    progress({**done, "degree": 10})
    first, second, third = stream.getvalue().splitlines()
    assert first.endswith("recall 0.700), 1 repair polish(es), 2 other solution(s) of the search measured (1.5 s)")
    assert second.endswith("recall 0.700), 1 other solution(s) of the search measured (1.5 s)")
    assert third.endswith("recall 0.700) (1.5 s)")


def test_progress_bar_on_a_terminal(tmp_path):
    # A real pseudo-terminal: rich draws its bar there, with the stage and the quantity minimised.
    import pty

    pid, fd = pty.fork()
    if pid == 0:  # the child runs the command on the terminal
        os.execv(sys.executable, [sys.executable, "-m", "ipfit.cli", "fit", "boot", "-o", str(tmp_path / "b"),
                                  "--degree", "4", "--iterations", "200", "--no-picture", "--no-zero-set"])
    chunks = []
    while True:
        try:
            data = os.read(fd, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    os.waitpid(pid, 0)
    screen = b"".join(chunks).decode("utf-8", "replace")
    assert "degree 4: DE" in screen and "objective" in screen and "fixed degree 4" in screen


@pytest.mark.parametrize("kind", ["line", "plane", "flat-circle"])
def test_axis_aligned_lines_and_planes_are_fitted(tmp_path, kind):
    x = np.linspace(-1, 1, 40)
    if kind == "line":
        pts = np.column_stack([x, 0 * x])
    elif kind == "plane":
        gx, gy = np.meshgrid(x[::3], x[::3])
        pts = np.column_stack([gx.ravel(), gy.ravel(), 0 * gx.ravel()])
    else:  # 2D points saved with a z = 0 column
        t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
        pts = np.column_stack([np.cos(t), np.sin(t), 0 * t])
    path = tmp_path / f"{kind}.csv"
    np.savetxt(path, pts, delimiter=",")
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--iterations", "20", "--max-degree", "4",
                 "--quiet", "--no-picture", "--no-zero-set"]) == 0
    poly = ipfit.ImplicitPolynomial.load(tmp_path / "out.json")
    off = np.zeros(pts.shape[1])
    off[-1] = 0.5  # half a unit off the line/plane
    scale = np.abs(poly(pts + off)).max()
    assert np.abs(poly(pts)).max() < 1e-2 * scale  # the data lie on (or within 1% of) the zero set


def test_a_big_cloud_says_it_fitted_the_degrees_on_a_subsample(tmp_path):
    # More than SearchOptions.fit_points (50,000) points: the degrees on 50,000 spread evenly,
    # the selected one measured on every point, and the terminal and the result say so.
    from ipfit.datasets import synthetic

    torus = synthetic.torus(60_000, rng=np.random.default_rng(0))
    src = tmp_path / "torus.xyz"
    np.savetxt(src, np.hstack([torus.points, torus.normals]), fmt="%.9g")
    out = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", str(src), "-o", str(tmp_path / "t"),
                          "--no-picture", "--no-zero-set"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert ("degree 4: measuring on all 60,000 points (the degrees were fitted on 50,000 of them "
            "spread evenly)") in out.stderr.splitlines()
    result = json.loads((tmp_path / "t.json").read_text())
    assert result["selected_degree"] == 4 and result["quality"]["f_score"] > 0.999
    assert "degrees fitted on 50,000 of the 60,000 points spread evenly" in result["adaptive"]["message"]


def test_the_second_fits_of_a_weighted_or_noisy_surface_are_announced():
    import io

    from ipfit.cli._progress import Progress

    stream = io.StringIO()
    Progress("lines", stream=stream)({"event": "weights_variant",
                                      "message": "fitting again, weighted by the outlier score alone"})
    Progress("lines", stream=stream)({"event": "normals_variant", "message": "fitting again with the normals "
                                      "estimated without the noise's σ"})
    Progress("lines", stream=stream)({"event": "reorient",
                                      "message": "1,234 normals turned to the fit's gradient, fitting again"})
    assert stream.getvalue().splitlines() == ["fitting again, weighted by the outlier score alone",
                                              "fitting again with the normals estimated without the noise's σ",
                                              "1,234 normals turned to the fit's gradient, fitting again"]


def test_every_event_of_a_fit_that_carries_a_message_is_printed():
    # the events fit_adaptive sends with a 'message' (found in the degree package's sources), each printed as it is
    import io
    import re
    from pathlib import Path

    import ipfit.degree.adaptive as adaptive
    from ipfit.cli._progress import Progress

    source = "".join(path.read_text() for path in Path(adaptive.__file__).parent.glob("*.py"))
    kinds = set(re.findall(r'\{"event": "(\w+)", "message"', source))
    kinds |= set(re.findall(r'_with_spread\([^"]*"(\w+)"', source))  # the looks that spread points announce themselves
    assert {"mesh_points", "local_surface"} <= kinds
    assert {"mesh_points", "weights_variant", "normals_variant", "layers", "reorient"} <= kinds
    for kind in sorted(kinds):
        stream = io.StringIO()
        Progress("lines", stream=stream)({"event": kind, "message": f"the {kind} line"})
        assert stream.getvalue().splitlines() == [f"the {kind} line"], kind


def test_the_topology_line_says_when_a_repair_reached_the_data_topology_but_was_not_kept():
    # The progress said "repaired to the data's topology, F-score 0.912" while the rule kept the
    # degree's own fit (below its band): the summary's line for that degree says so too, instead
    # of a bare mismatch that reads as if the repair had failed.
    from types import SimpleNamespace

    from ipfit.cli.fit import _topology_line
    from ipfit.zeroset.topology import Topology

    q = Quality(recall=0.95, precision=0.95, f_score=0.95, chamfer=0.01, n_components=3, n_spurious=0, closed=True,
                tau=0.05, data_to_zero_set=0.01, zero_set_to_data=0.01, grid_step=0.01, reference="contour",
                topology=Topology(2, 3, nesting=(0, 0, 0)), data_topology=Topology(2, 1, nesting=(0,), source="contour"))
    assert q.topology_matches is False

    def rounds(*rows):
        return tuple({"target": "topology", "far_term_weight": w, "clean": clean, "f_score": f, "topology_matches": m}
                     for w, clean, f, m in rows)

    entry = SimpleNamespace(degree=14, quality=q, cleanup=())
    assert _topology_line(entry) == "degree 14: 3 loops where the data has 1"
    entry = SimpleNamespace(degree=14, quality=q, cleanup=rounds(
        (1.0, True, 0.93, False), (3.2, True, 0.912, True), (10.0, False, 0.95, True)))
    assert _topology_line(entry) == ("degree 14: 3 loops where the data has 1; a repair reached the data's "
                                     "topology at F-score 0.912, not kept")
    entry = SimpleNamespace(degree=14, quality=q, cleanup=rounds((10.0, False, 0.88, True)))
    assert _topology_line(entry).endswith("at F-score 0.880 with a zero set not clean, not kept")

"""The command line's messages that left things out (issue 34, point 5): one test per message."""

from __future__ import annotations

import importlib.resources
import json

import numpy as np
import pytest

from ipfit import io
from ipfit.cli import build_parser, main
from ipfit.datasets import synthetic
from ipfit.degree.adaptive import fit_adaptive
from ipfit.degree.rules import CAPTURE_MAX_DEGREE, select_degree_capture
from ipfit.exceptions import ReadError

HORSE = importlib.resources.files("skimage.data") / "horse.png"


def _fit(tmp_path, capsys, *options, spec="boot"):
    """``ipfit fit SPEC -o tmp/fit OPTIONS`` with 3L: (exit code, stdout, stderr, the JSON or None)."""
    prefix = tmp_path / "fit"
    code = main(["fit", str(spec), "-o", str(prefix), "--method", "3l", *options])
    out, err = capsys.readouterr()
    path = prefix.with_suffix(".json")
    return code, out, err, json.loads(path.read_text()) if path.exists() else None


def test_fixed_degree_reports_its_spurious_pieces_on_the_terminal(tmp_path, capsys):
    code, out, _, data = _fit(tmp_path, capsys, "--degree", "6", "--no-zero-set")
    assert code == 0
    count = data["quality"]["n_spurious"]
    assert count >= 1  # 3L's degree 6 of the boot has stray ovals: the case the figure showed alone
    line = next(line for line in out.splitlines() if line.startswith("fixed degree 6"))
    assert f"{count} spurious piece" in line and "red in the figure" in line
    assert f"F-score {data['quality']['f_score']:.3f}" in line


def test_fixed_degree_without_spurious_pieces_says_none(tmp_path, capsys):
    shape = synthetic.ellipse(120)
    np.savetxt(tmp_path / "ellipse.xyz", np.hstack([shape.points, shape.normals]))
    code, out, _, data = _fit(tmp_path, capsys, "--degree", "2", "--no-picture", spec=tmp_path / "ellipse.xyz")
    assert code == 0 and data["quality"]["n_spurious"] == 0
    assert "spurious" not in out and "red in the figure" not in out


def test_a_degree_above_the_documented_maximum_warns_in_one_line(tmp_path, capsys):
    top = CAPTURE_MAX_DEGREE[2]
    code, _, err, _ = _fit(tmp_path, capsys, "--degree", str(top + 2), "--no-picture", "--no-zero-set", "-q")
    assert code == 0
    warnings = [line for line in err.splitlines() if f"--degree {top + 2} is above {top}" in line]
    assert len(warnings) == 1 and warnings[0].startswith("ipfit fit: warning:") and "2D" in warnings[0]
    code, _, err, _ = _fit(tmp_path, capsys, "--degree", str(top), "--no-picture", "--no-zero-set", "-q")
    assert code == 0 and "above" not in err  # the maximum itself is documented, hence silent


def test_a_max_degree_above_the_maximum_warns_when_the_loop_gets_there(tmp_path, capsys):
    top = CAPTURE_MAX_DEGREE[2]
    # the paper's rule with a negative epsilon never stops early: it climbs to the last degree
    code, _, err, data = _fit(tmp_path, capsys, "--max-degree", str(top + 2), "--rule", "paper", "--epsilon", "-1",
                              "--no-picture", "--no-zero-set", "-q")
    assert code == 0 and max(d["degree"] for d in data["degrees"]) == top + 2
    warned = [line for line in err.splitlines() if "above" in line]
    assert warned == [(f"ipfit fit: warning: --max-degree {top + 2}: the fit went to degree {top + 2}, above {top}, "
                      "the highest degree ipfit tries and is tested at in 2D: expect slow fits, poor conditioning "
                      "and spurious pieces.")]
    code, _, err, data = _fit(tmp_path, capsys, "--max-degree", str(top + 2), "--no-picture", "--no-zero-set", "-q")
    assert code == 0 and max(d["degree"] for d in data["degrees"]) <= top and "above" not in err


def test_the_wrote_line_lists_every_output_html_included(tmp_path, capsys):
    code, out, _, _ = _fit(tmp_path, capsys, "--degree", "4", "--html")
    assert code == 0
    wrote = next(line for line in out.splitlines() if line.startswith("wrote "))
    listed = wrote.removeprefix("wrote ").split(", ")
    assert sorted(listed) == sorted(str(p) for p in tmp_path.iterdir())  # everything written, nothing else
    assert any(name.endswith(".html") for name in listed)


def test_the_figure_says_fixed_only_for_a_fixed_degree(tmp_path, capsys):
    from ipfit.viz.plotting import plot_result

    shape = synthetic.ellipse(200)
    np.savetxt(tmp_path / "ellipse.xyz", np.hstack([shape.points, shape.normals]))
    code, _, _, data = _fit(tmp_path, capsys, "--no-picture", "--no-zero-set", "-q", spec=tmp_path / "ellipse.xyz")
    assert code == 0 and [d["degree"] for d in data["degrees"]] == [2] and data["adaptive"]["reason"] != "fixed"
    titles = [ax.get_title() for ax in plot_result(data, shape.points).axes]
    assert not any("(fixed)" in t for t in titles), titles


def test_a_bare_cloud_says_its_normals_are_estimated(tmp_path, capsys):
    shape = synthetic.ellipse(150)
    np.savetxt(tmp_path / "bare.xyz", shape.points)
    code, _, err, data = _fit(tmp_path, capsys, "--degree", "2", "--no-picture", "--no-zero-set",
                              spec=tmp_path / "bare.xyz")
    assert code == 0 and data["input"]["normals"] == "estimated"
    lines = [line for line in err.splitlines() if "normals" in line]
    assert len(lines) == 1 and "has no normals: estimating them from its 150 points" in lines[0]
    # with the file's normals: not a word
    np.savetxt(tmp_path / "full.xyz", np.hstack([shape.points, shape.normals]))
    _, _, err, data = _fit(tmp_path, capsys, "--degree", "2", "--no-picture", "--no-zero-set",
                           spec=tmp_path / "full.xyz")
    assert data["input"]["normals"] == "file" and "estimating" not in err


@pytest.mark.parametrize("text", ["name city country age job pet\nalice paris france thirty cook cat\n",
                                  "hello world\nthis is a text file here\nand another line\n",
                                  "a;b\nc;d\n"])
def test_a_text_without_numbers_says_nothing_in_it_is_a_number(tmp_path, text):
    path = tmp_path / "words.txt"
    path.write_text(text)
    with pytest.raises(ReadError) as info:
        io.read_points(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: nothing in it is a number")
    assert "expected 2 like the first row" not in message


def test_a_table_with_one_bad_value_still_names_its_line(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("x,y\n1,2\n3,abc\n5,6\n")
    with pytest.raises(ReadError, match=r"line 3: 'abc' is not a number"):
        io.read_points(path)


def test_view_of_an_image_says_it_is_not_a_result_json(tmp_path, capsys):
    assert main(["view", str(HORSE), "-o", str(tmp_path / "horse.html")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{HORSE}: not a result JSON" in err
    assert "UnicodeDecodeError" not in err and "ipfit fit" in err
    assert not list(tmp_path.iterdir())


def test_with_no_clean_degree_the_message_says_what_is_taken():
    # the open dome: degree 2 (F 0.841) was taken over degree 8 (F 0.849), the message
    # said "the best F-score": it is the lowest degree within the tolerance, and says so
    assert select_degree_capture([2, 4, 6, 8], [0.841, 0.80, 0.83, 0.849], [False] * 4) == 0
    assert select_degree_capture([2, 4, 6, 8], [0.82, 0.80, 0.83, 0.849], [False] * 4) == 3
    from ipfit.degree.rules import CAPTURE

    dome = synthetic.sphere(400, rng=0).points
    dome = dome[dome[:, 2] > 0.2]  # an open cap: no zero set is closed inside the box
    result = fit_adaptive(dome, max_degree=4, rng=0)
    assert not any(CAPTURE.is_clean(d.quality) for d in result.degrees)
    assert "no degree tried is clean, so the lowest degree within 0.01 of the best F-score was taken" in result.message


def test_the_lazy_method_choices_are_the_registry():
    from ipfit.cli.fit import _method_names
    from ipfit.degree.adaptive import fixed_degree_methods

    assert _method_names() == fixed_degree_methods()
    parser = build_parser("fit")
    assert parser.parse_args(["fit", "boot", "--method", "pso"]).method == "pso"
    with pytest.raises(SystemExit):
        parser.parse_args(["fit", "boot", "--rule", "nonsense"])
    help_text = parser._subparsers._group_actions[0].choices["fit"].format_help()
    assert all(name in help_text for name in fixed_degree_methods())


def test_the_full_parser_still_builds_every_command():
    # main() builds only the command it runs (build_parser(command)); build_parser() builds them all
    assert build_parser().parse_args(["reproduce", "-o", "x", "--quick"]).config == "quick"
    assert build_parser("reproduce").parse_args(["reproduce", "-o", "x"]).config == "full"

"""``ipfit reproduce --quick``: the report, its figures and its numbers all come from one run."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ipfit import reproduce as rep
from ipfit.cli import main

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def data_source():
    pytest.importorskip("ipfit.datasets.bundled")
    return "bundled"


@pytest.fixture(scope="module")
def quick_run(data_source, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduction")
    assert main(["reproduce", "--out", str(out), "--quick", "-q"]) == 0
    return out


def test_report_is_rendered_from_results_json(quick_run):
    results = rep.load_results(quick_run)
    text = (quick_run / "README.md").read_text(encoding="utf-8")
    assert text == rep.render_report(results)
    assert results["run"]["experiments"] == list(rep.EXPERIMENTS)
    assert results["config"]["name"] == "quick"
    assert "--quick" in results["run"]["command"]
    json.dumps(results, allow_nan=False)  # plain JSON: no NaN, no numpy


def test_every_referenced_figure_exists_and_is_not_blank(quick_run):
    from PIL import Image

    text = (quick_run / "README.md").read_text(encoding="utf-8")
    referenced = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    results = rep.load_results(quick_run)
    assert sorted(referenced) == sorted(results["figures"].values())
    # one figure per experiment part: δ, 6 datasets × 2 methods, 2 ridge, noise, convergence
    assert len(referenced) == 1 + 12 + 2 + 1 + 1
    for name in referenced:
        with Image.open(quick_run / name) as im:
            assert im.format == "PNG"
            grey = np.asarray(im.convert("L"), dtype=float)
        assert grey.std() > 5, name
        assert (grey < 128).mean() > 0.002, f"{name} is nearly blank"
    assert not list(quick_run.glob(".*partial*"))


def test_summary_table_matches_the_json_and_its_verdicts_are_computed(quick_run):
    results = rep.load_results(quick_run)
    text = (quick_run / "README.md").read_text(encoding="utf-8")
    summary = results["summary"]
    assert rep.summarize(results) == summary  # verdicts follow from the numbers in the file
    table = text.split("## Summary")[1].split("\n\n")[1].splitlines()[2:]
    assert len(table) == len(summary)
    for line, row in zip(table, summary):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells == [row["claim"], row["paper"], row["ours"], f"**{row['verdict']}**"]
        for number in re.findall(r"\d+\.\d+|\d+", row["ours"]):
            assert number in json.dumps(row["values"], ensure_ascii=False) or _in_results(number, results), number
    claims = {row["claim"] for row in summary}
    for name in rep.DATASETS:
        assert f"{name}: selected degree" in claims
    assert any(c.startswith("δ: small") for c in claims) and any(c.startswith("noise") for c in claims)
    assert any(c.startswith("3L+RRR") for c in claims) and any("linear seeds" in c for c in claims)


def _in_results(number: str, results) -> bool:
    """A number printed in the summary text is one of the run's numbers (rounded as printed)."""
    decimals = len(number.split(".")[1]) if "." in number else 0
    target = float(number)
    stack = [results]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, (int, float)) and not isinstance(item, bool):
            for scale in (1, 100):  # percentages are printed ×100
                if round(item * scale, decimals) == target:
                    return True
    return False


def test_selected_degrees_follow_the_rule_on_the_saved_paths(quick_run):
    from ipfit.adaptive import select_degree

    results = rep.load_results(quick_run)
    for name, ds in results["adaptive"]["datasets"].items():
        for method, run in ds["runs"].items():
            degrees = [p["degree"] for p in run["path"]]
            assert degrees == list(range(2, run["max_degree"] + 1, 2))
            smooth = [p["smoothness"] for p in run["path"]]
            for key, sel in run["selection"].items():
                index, reason = select_degree(degrees, smooth, sel["epsilon"])
                assert (degrees[index], reason) == (sel["degree"], sel["reason"]), (name, method, key)


def test_saved_numbers_are_the_measures_of_the_saved_fits(quick_run):
    from ipfit import ImplicitPolynomial, Normalization
    from ipfit.objective import measures

    results = rep.load_results(quick_run)
    cfg = rep.CONFIGS["quick"]
    data = rep.prepare_data("airplane", cfg, results["run"]["seed"])
    entry = results["adaptive"]["datasets"]["airplane"]["runs"]["de"]["path"][1]
    poly = ImplicitPolynomial.from_coefficients(entry["coefficients"], 2,
                                                normalization=Normalization.from_points(data.points))
    m = measures(poly, data.points, data.normals, delta=cfg.delta)
    assert m.smoothness == pytest.approx(entry["smoothness"], rel=1e-9)
    assert m.distance == pytest.approx(entry["distance"], rel=1e-9)


def test_same_seed_same_numbers(data_source, tmp_path):
    def numbers(out):
        results = rep.reproduce(out, "quick", only=["delta"], seed=3)
        return _without_times(results["delta"])

    assert numbers(tmp_path / "a") == numbers(tmp_path / "b")


def _without_times(value):
    if isinstance(value, dict):
        return {k: _without_times(v) for k, v in value.items() if "seconds" not in k}
    if isinstance(value, list):
        return [_without_times(v) for v in value]
    return value


def test_only_and_errors(data_source, tmp_path, capsys):
    out = tmp_path / "only"
    assert main(["reproduce", "--out", str(out), "--quick", "--only", "ridge", "-q"]) == 0
    results = rep.load_results(out)
    assert results["run"]["experiments"] == ["ridge"]
    assert "adaptive" not in results  # ridge ran its own adaptive DE path
    assert results["ridge"]["datasets"]["airplane"]["ours_source"].startswith("adaptive DE run")
    assert sorted(results["figures"]) == ["ridge/airplane", "ridge/butterfly"]
    assert sorted(p.name for p in out.glob("fig_*.png")) == ["fig_ridge_airplane.png", "fig_ridge_butterfly.png"]

    blocker = tmp_path / "file"
    blocker.write_text("x")
    capsys.readouterr()
    assert main(["reproduce", "--out", str(blocker), "--quick", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "not a folder" in err
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "--out", str(out), "--only", "figures"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit):
        main(["reproduce", "--out", str(out), "--quick", "--full"])


def test_adaptive_runs_are_the_library_adaptive_runs(quick_run):
    """The recorded paths equal fit_adaptive(method='de') with the same seed: the runner only keeps records."""
    from ipfit.adaptive import fit_adaptive

    results = rep.load_results(quick_run)
    cfg = rep.CONFIGS["quick"]
    seed = results["run"]["seed"]
    data = rep.prepare_data("airplane", cfg, seed)
    params = cfg.refine_params()
    assert params.pop("far_weight") == 0.0  # the paper's objective
    direct = fit_adaptive(data.points, data.normals, method="de", epsilon=rep.PATH_EPSILON, delta=cfg.delta,
                          max_degree=4, rng=rep._rng(seed, "adaptive", "airplane", "de"), rule="paper",
                          far_weight=0.0, **params)
    saved = results["adaptive"]["datasets"]["airplane"]["runs"]["de"]["path"]
    assert [d.smoothness for d in direct.degrees] == [p["smoothness"] for p in saved[:2]]
    assert [d.distance for d in direct.degrees] == [p["distance"] for p in saved[:2]]


def test_committed_report_is_the_rendering_of_its_results():
    """docs/reproduction: not edited by hand (the page is its results.json rendered) and complete."""
    folder = Path(__file__).resolve().parents[1] / "docs" / "reproduction"
    if not (folder / "results.json").is_file():
        pytest.skip("no committed report")
    results = rep.load_results(folder)
    text = (folder / "README.md").read_text(encoding="utf-8")
    assert text == rep.render_report(results)
    assert rep.summarize(results) == results["summary"]
    assert results["config"]["name"] == rep.DEFAULT_CONFIG and results["run"]["experiments"] == list(rep.EXPERIMENTS)
    for name in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text):
        assert (folder / name).is_file(), name

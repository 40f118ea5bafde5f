"""``ipfit batch`` / ``ipfit.fit_many`` against hostile inputs: names, foreign files in OUTDIR,
damaged results on resume, signals, a missing dask, and inputs or options that would hang."""

from __future__ import annotations

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from ipfit.batch import MANIFEST, MAX_GENERATED, expand_inputs, fit_many, local_cluster, max_workers  # noqa: E402
from ipfit.cli import main  # noqa: E402
from ipfit.datasets import collection  # noqa: E402
from ipfit.exceptions import InvalidInputError  # noqa: E402
from ipfit.io import write_points  # noqa: E402
from ipfit.degree.results import load_result  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FAST = dict(method="3l", max_degree=2)
FAST_CLI = ["--method", "3l", "--degree", "2"]


@pytest.fixture(scope="module")
def client():
    with local_cluster(1) as c:
        yield c


def _write(path: Path, shape) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_points(path, shape.points, shape.normals)
    return path


def _summary(folder: Path) -> list[dict]:
    with open(folder / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _one_error_line(err: str) -> str:
    assert err.count("\n") == 1 and err.startswith("ipfit batch: error: "), err
    assert "Traceback" not in err
    return err


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(REPO / "src")}


# -- names -------------------------------------------------------------------------------------------
def test_names_are_unique_and_independent_of_the_input_order(tmp_path):
    shapes = collection(2)
    files = [_write(tmp_path / name, shapes[i % 2]) for i, name in
             enumerate(["a.ply", "a.xyz", "b.xyz", "summary.xyz", "sub/index.xyz", "B.ply"])]
    forward = {t.source: t.name for t in expand_inputs([str(f) for f in files])}
    backward = {t.source: t.name for t in expand_inputs([str(f) for f in files[::-1]])}
    assert forward == backward
    assert sorted(forward.values()) == ["B-ply", "a-ply", "a-xyz", "b-xyz", "index-xyz", "summary-xyz"]
    twice = expand_inputs([str(tmp_path / "a.xyz"), str(tmp_path / "*.xyz")])  # one file, reached twice
    assert sorted(t.name for t in twice) == ["a", "b", "summary-xyz"]


def test_same_file_names_in_two_folders_get_a_hash_of_their_path(tmp_path):
    shape = collection(1)[0]
    names = [t.name for t in expand_inputs([str(_write(tmp_path / d / "a.xyz", shape)) for d in ("x", "y")])]
    assert len(set(names)) == 2 and all(n.startswith("a-xyz-") and len(n) == len("a-xyz-") + 6 for n in names)
    mapped = expand_inputs([{"index": (shape.points, shape.normals)}])
    assert mapped[0].name.startswith("index-")


@pytest.mark.parametrize("name", ["../escaped", "", "a/b", ".hidden", "..", "a\\b", "x" * 201])
def test_fit_many_refuses_a_name_that_is_not_a_plain_file_name(tmp_path, name):
    shape = collection(1)[0]
    with pytest.raises(InvalidInputError, match=r"^inputs: expected shape names that are plain file names"):
        fit_many({name: (shape.points, shape.normals)}, output=tmp_path / "out", workers=1, **FAST)
    assert not (tmp_path / "out").exists() and not (tmp_path / "escaped.json").exists()


def test_two_inputs_of_one_stem_keep_both_rows_and_resume_in_any_order(client, tmp_path):
    shapes = collection(2, seed=4)
    inputs = [str(_write(tmp_path / "in" / "a.ply", shapes[0])), str(_write(tmp_path / "in" / "a.xyz", shapes[1]))]
    out = tmp_path / "out"
    first = fit_many(inputs, client=client, output=out, **FAST)
    assert [(r["name"], r["status"]) for r in first.rows] == [("a-ply", "ok"), ("a-xyz", "ok")]
    assert [r["name"] for r in _summary(out)] == ["a-ply", "a-xyz"]
    stamps = {p.name: p.stat().st_mtime_ns for p in out.glob("a-*.json")}
    again = fit_many(inputs[::-1], client=client, output=out, **FAST)
    assert [(r["name"], r["status"]) for r in again.rows] == [("a-xyz", "skipped"), ("a-ply", "skipped")]
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("a-*.json")} == stamps  # nothing rewritten
    assert load_result(out / "a-ply.json")["input"]["path"] == str(Path(inputs[0]).resolve())


# -- files in OUTDIR that ipfit did not write ---------------------------------------------------------
@pytest.mark.parametrize("case", ["summary.csv", "summary.parquet", "index.html", "shape.png", "shape.html",
                                  "manifest", "input_in_outdir"])
def test_a_file_ipfit_did_not_write_is_never_replaced(tmp_path, capsys, case):
    pytest.importorskip("pyarrow")
    shape = collection(1)[0]
    folder = tmp_path / "in"
    _write(folder / "shape.xyz", shape)
    out = tmp_path / "out"
    out.mkdir()
    args = ["batch", str(folder), "-o", str(out), *FAST_CLI, "--html"]
    victim = {"manifest": out / MANIFEST, "input_in_outdir": folder / "summary.csv"}.get(case, out / case)
    if case == "input_in_outdir":  # OUTDIR is the input folder, which holds a point file named summary.csv
        _write(victim, shape)
        args[3] = str(folder)
    else:
        victim.write_text("the user's own file\n")
    before = victim.read_bytes()
    assert main(args) == 2
    err = _one_error_line(capsys.readouterr().err)
    assert str(victim) in err and ("ipfit did not write it" in err or "is an input file" in err or
                                   "not ipfit's record" in err)
    assert victim.read_bytes() == before
    assert not list(out.glob("[!.]*.json")) and not (folder / "shape.json").exists()  # refused before the work


def test_outputs_of_a_previous_batch_are_its_own(client, tmp_path):
    shape = collection(1)[0]
    _write(tmp_path / "in" / "index.xyz", shape)  # a shape named like the batch's index page
    out = tmp_path / "out"
    args = ["batch", str(tmp_path / "in"), "-o", str(out), "--scheduler", client.scheduler.address, *FAST_CLI,
            "--html", "-q"]
    assert main(args) == 0
    assert {p.name for p in out.iterdir()} >= {"index-xyz.json", "index-xyz.html", "index-xyz.png", "index.html",
                                               "summary.csv", MANIFEST}
    assert main(args + ["--epsilon", "0.02"]) == 0  # other settings: every file replaced, none refused
    assert [r["status"] for r in _summary(out)] == ["ok"]


# -- resume over damaged results -----------------------------------------------------------------------
def _deep(depth: int) -> str:
    return '{"format": "ipfit", "x": ' + "[" * depth + "]" * depth + "}"


DAMAGE = {
    "wrong_types": lambda d: {**d, "measures": [1, 2], "input": "a string", "batch": ["x"]},
    "no_coefficients": lambda d: {k: v for k, v in d.items() if k != "coefficients"},
    "nan_coefficient": lambda d: {**d, "coefficients": [float("nan"), *d["coefficients"][1:]]},
}


def test_resume_fits_damaged_results_again(client, tmp_path):
    shapes = collection(5, seed=6)
    out = tmp_path / "out"
    fit_many(shapes, client=client, output=out, **FAST)
    damaged = {}
    for shape, (kind, damage) in zip(shapes, DAMAGE.items()):
        path = out / f"{shape.name}.json"
        path.write_text(json.dumps(damage(json.loads(path.read_text()))))  # NaN written as the token NaN
        damaged[shape.name] = kind
    path = out / f"{shapes[3].name}.json"
    path.write_text(_deep(100_000))  # json.loads: RecursionError
    damaged[shapes[3].name] = "deep"
    path = out / f"{shapes[4].name}.json"
    path.write_text('{"format": "ipfit", "version": ' + "9" * 100_000 + "}")  # int(): ValueError (digit limit)
    damaged[shapes[4].name] = "huge_int"
    again = fit_many(shapes, client=client, output=out, **FAST)
    assert {r["name"]: r["status"] for r in again.rows} == dict.fromkeys(damaged, "ok")
    for name in damaged:
        load_result(out / f"{name}.json")  # replaced by a valid result
    assert {r["status"] for r in fit_many(shapes, client=client, output=out, **FAST).rows} == {"skipped"}


def test_a_failed_shape_names_its_input_never_a_temporary_file(client, tmp_path):
    folder = tmp_path / "in"
    _write(folder / "good.xyz", collection(1)[0])
    (folder / "broken.xyz").write_text("1 2 oops\n")
    batch = fit_many([folder], client=client, output=tmp_path / "out", **FAST)
    error = {r["name"]: r["error"] for r in batch.rows}["broken"]
    assert "broken.xyz" in error and ".partial" not in error and "\n" not in error


# -- signals -------------------------------------------------------------------------------------------
def _alive(pids) -> list[int]:
    psutil = pytest.importorskip("psutil")
    return [p for p in pids if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]


def _interrupt_batch(out, n_shapes: int, started, signals: int = 1) -> list[int]:
    """``ipfit batch generated:N`` interrupted like a terminal's Ctrl-C (SIGINT to the process group,
    workers included) once ``started(proc)`` holds; it must exit 130 quietly and leave no worker
    process behind. The processes it had when signalled."""
    psutil = pytest.importorskip("psutil")
    cmd = [sys.executable, "-m", "ipfit.cli", "batch", f"generated:{n_shapes}", "-o", str(out), "--workers", "2",
           "--max-degree", "6", "--iterations", "300" if n_shapes > 6 else "30"]
    proc = subprocess.Popen(cmd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while proc.poll() is None and not started(proc) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, proc.communicate()
    children = [c.pid for c in psutil.Process(proc.pid).children(recursive=True)]
    for _ in range(signals):
        os.killpg(proc.pid, signal.SIGINT)
        time.sleep(0.3)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Exception ignored" not in err and "KeyboardInterrupt" not in err, err
    deadline = time.monotonic() + 10
    while _alive(children) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _alive(children)
    return children


@pytest.mark.slow
@pytest.mark.parametrize("signals", [1, 2])
def test_ctrl_c_is_quiet_keeps_finished_results_and_stops_the_workers(tmp_path, signals):
    out = tmp_path / "out"
    workers = _interrupt_batch(out, 6, lambda proc: bool(list(out.glob("[!.]*.json"))), signals)
    assert workers
    rows = _summary(out)
    finished = {p.stem for p in out.glob("[!.]*.json")}
    assert len(rows) == 6 and finished == {r["name"] for r in rows if r["status"] == "ok"}
    for name in finished:
        load_result(out / f"{name}.json")


def test_ctrl_c_while_the_cluster_starts_kills_no_worker(tmp_path):
    """A Ctrl-C as the first worker processes start reaches them too: they start with SIGINT
    ignored, so none dies with a traceback; the batch process ignores that one as well (the
    documented price) and runs on."""
    psutil = pytest.importorskip("psutil")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ipfit.cli", "batch", "generated:2", "-o", str(out), "--workers", "2",
           "--max-degree", "2", "--method", "3l"]
    proc = subprocess.Popen(cmd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while proc.poll() is None and not psutil.Process(proc.pid).children() and time.monotonic() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, proc.communicate()
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err and "Exception ignored" not in err and "KeyboardInterrupt" not in err, err
    assert proc.returncode in (0, 130), err
    if proc.returncode == 0:  # the signal came while the cluster started: the batch ran on, whole
        assert {r["status"] for r in _summary(out)} == {"ok"}


# -- a core install --------------------------------------------------------------------------------------
BLOCK_DASK = """
import sys
class NoDask:
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in ("dask", "distributed"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, NoDask())
from ipfit.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_without_dask_batch_says_which_extra_to_install(tmp_path):
    proc = subprocess.run([sys.executable, "-c", BLOCK_DASK, "batch", "generated:2", "-o", str(tmp_path / "out")],
                          env=_env(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "pip install 'ipfit[dask]'" in _one_error_line(proc.stderr)
    assert not (tmp_path / "out").exists()


# -- what would hang or flood the machine ------------------------------------------------------------------
def test_a_fifo_is_refused_at_once_and_skipped_in_folders_and_globs(tmp_path):
    folder = tmp_path / "in"
    _write(folder / "a.xyz", collection(1)[0])
    fifo = folder / "pipe.xyz"
    os.mkfifo(fifo)
    proc = subprocess.run([sys.executable, "-m", "ipfit.cli", "batch", str(fifo), "-o", str(tmp_path / "out")],
                          env=_env(), capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and "not a regular file" in _one_error_line(proc.stderr)
    assert [t.name for t in expand_inputs([str(folder)])] == ["a"]
    assert [t.name for t in expand_inputs([str(folder / "*.xyz")])] == ["a"]


def test_a_scheduler_that_never_answers_is_one_line_within_the_timeout(tmp_path, capsys, monkeypatch):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    accepted = []
    threading.Thread(target=lambda: accepted.append(server.accept()), daemon=True).start()
    monkeypatch.setenv("IPFIT_BATCH_CONNECT_TIMEOUT", "1")
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    start = time.monotonic()
    try:
        assert main(["batch", "generated:1", "-o", str(tmp_path / "out"), "--scheduler", address, *FAST_CLI]) == 2
    finally:
        server.close()
    assert time.monotonic() - start < 8 and accepted  # it connected, and gave up
    assert not (tmp_path / "out").exists()
    assert f"cannot connect to {address} (no answer within 1 s)" in _one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("args", [["generated:1000000000000"], [f"generated:{MAX_GENERATED + 1}:3"],
                                  ["generated:2", "--workers", "1000"]])
def test_limits_are_checked_before_the_work(tmp_path, capsys, args):
    start = time.monotonic()
    assert main(["batch", *args, "-o", str(tmp_path / "out"), *FAST_CLI]) == 2
    err = _one_error_line(capsys.readouterr().err)
    assert time.monotonic() - start < 10 and not (tmp_path / "out").exists()
    assert ("--workers: expected at most" in err) if "--workers" in args else (f"N <= {MAX_GENERATED:,}" in err)
    assert 1 <= max_workers() <= 4 * (os.cpu_count() or 1)


@pytest.mark.parametrize("value", ["abc", "0", "inf"])
def test_a_bad_connect_timeout_setting_is_one_line(tmp_path, capsys, monkeypatch, value):
    monkeypatch.setenv("IPFIT_BATCH_CONNECT_TIMEOUT", value)
    assert main(["batch", "generated:1", "-o", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "IPFIT_BATCH_CONNECT_TIMEOUT: expected a number of seconds > 0" in _one_error_line(capsys.readouterr().err)

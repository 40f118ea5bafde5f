"""ipfit.fit_many and ``ipfit batch`` on real dask.distributed clusters of worker processes."""

from __future__ import annotations

import csv
import re
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from ipfit import RECOMMENDED, fit_3l, fit_adaptive  # noqa: E402
from ipfit.batch import COLUMNS, THREAD_ENV, fit_many, local_cluster, shape_rng  # noqa: E402
from ipfit.cli import main  # noqa: E402
from ipfit.datasets import collection, synthetic  # noqa: E402
from ipfit.io import write_points  # noqa: E402
from ipfit.degree.results import load_result  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
FAST = RECOMMENDED.replace(iterations=5, population_size=12, polish_iterations=10)
CRASH_POINTS = 77  # a shape with this many points kills its worker (crashing_3l)


def crashing_3l(points, normals, degree):
    """3L, except that it kills the worker process on a shape of CRASH_POINTS points."""
    if len(points) == CRASH_POINTS:
        os._exit(13)
    return fit_3l(points, normals, degree)


@pytest.fixture(scope="module")
def client():
    with local_cluster(2) as c:
        yield c


def _sequential(shape, seed=0, **settings):
    threadpoolctl = pytest.importorskip("threadpoolctl")
    with threadpoolctl.threadpool_limits(1):  # the workers' thread count, so BLAS sums in the same order
        return fit_adaptive(shape.points, shape.normals, rng=shape_rng(seed, shape.name), **settings).to_dict()


def _same_fit(batch_result: dict, alone: dict) -> None:
    assert batch_result["coefficients"] == alone["coefficients"]  # bit for bit
    assert batch_result["selected_degree"] == alone["selected_degree"]
    assert [d["coefficients"] for d in batch_result["degrees"]] == [d["coefficients"] for d in alone["degrees"]]


def test_workers_are_processes_with_one_thread_each(client):
    info = client.scheduler_info()["workers"]
    assert len(info) == 2 and all(w["nthreads"] == 1 for w in info.values())
    pids = client.run(os.getpid)
    assert len(set(pids.values())) == 2 and os.getpid() not in pids.values()
    envs = client.run(lambda: {k: os.environ.get(k) for k in THREAD_ENV})
    assert all(env == THREAD_ENV for env in envs.values())

    def blas_threads():
        import threadpoolctl

        return [p["num_threads"] for p in threadpoolctl.threadpool_info()]

    assert all(set(n) <= {1} for n in client.run(blas_threads).values())


def test_same_seed_gives_the_sequential_result_bit_for_bit(client, tmp_path):
    shapes = collection(5, seed=3)
    settings = dict(method="de+polish", options=FAST, max_degree=4)
    batch = fit_many(shapes[::-1], client=client, seed=7, output=tmp_path, **settings)  # reversed: order is no input
    assert batch.counts() == {"ok": 5}
    for shape in shapes:
        _same_fit(batch.results[shape.name], _sequential(shape, 7, **settings))
        on_disk = load_result(tmp_path / f"{shape.name}.json")
        assert on_disk["coefficients"] == batch.results[shape.name]["coefficients"]
        assert on_disk["batch"]["name"] == shape.name and on_disk["batch"]["seed"] == 7


@pytest.mark.slow
def test_twenty_shapes_on_two_worker_processes_equal_sequential_fits(client):
    shapes = collection(20, seed=0)
    settings = dict(method="de+polish", options=FAST, max_degree=4)
    batch = fit_many(shapes, client=client, **settings)
    assert batch.counts() == {"ok": 20}
    for shape in shapes:
        _same_fit(batch.results[shape.name], _sequential(shape, **settings))


def test_resume_skips_shapes_fitted_with_the_same_settings(client, tmp_path):
    shapes = collection(4, seed=1)
    first = fit_many(shapes[:2], client=client, output=tmp_path, method="3l", max_degree=4)
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("[!.]*.json")}
    again = fit_many(shapes, client=client, output=tmp_path, method="3l", max_degree=4)
    assert [r["status"] for r in again.rows] == ["skipped", "skipped", "ok", "ok"]
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("[!.]*.json") if p.name in stamps} == stamps
    assert again.results[shapes[0].name]["coefficients"] == first.results[shapes[0].name]["coefficients"]
    assert again.rows[0]["selected_degree"] == first.rows[0]["selected_degree"]
    changed = fit_many(shapes, client=client, output=tmp_path, method="3l", max_degree=4, epsilon=0.02)
    assert {r["status"] for r in changed.rows} == {"ok"}  # other settings: fitted again
    with open(tmp_path / "summary.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert tuple(table[0]) == COLUMNS and [r["name"] for r in table] == [s.name for s in shapes]
    pq = pytest.importorskip("pyarrow.parquet")
    parquet = pq.read_table(tmp_path / "summary.parquet").to_pylist()
    assert parquet == [{k: row[k] for k in COLUMNS} for row in changed.rows]


def test_a_corrupt_file_and_a_killed_worker_are_failed_rows(client, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    shapes = collection(4, seed=2)
    for shape in shapes:
        write_points(folder / f"{shape.name}.xyz", shape.points, shape.normals)
    (folder / "corrupt.xyz").write_text("1.0 2.0 oops\n3 4\n")
    crash = synthetic.circle(CRASH_POINTS)
    pids = set(client.run(os.getpid).values())
    batch = fit_many([folder, {"crash": (crash.points, crash.normals)}], client=client, method=crashing_3l,
                     max_degree=4)
    rows = {r["name"]: r for r in batch.rows}
    assert rows["corrupt"]["status"] == "failed" and "corrupt.xyz" in rows["corrupt"]["error"]
    assert rows["crash"]["status"] == "failed" and "worker" in rows["crash"]["error"]
    assert all("\n" not in r["error"] for r in rows.values() if r["error"])
    assert all(rows[s.name]["status"] == "ok" for s in shapes)
    alone = fit_adaptive(shapes[0].points, shapes[0].normals, method=crashing_3l, max_degree=4)
    np.testing.assert_allclose(batch.results[shapes[0].name]["coefficients"], alone.x, rtol=1e-9, atol=1e-12)
    client.wait_for_workers(2, timeout=60)
    assert set(client.run(os.getpid).values()) != pids  # the worker really died and was replaced


def _write_shapes(folder: Path, n: int, seed: int = 0) -> list:
    folder.mkdir(parents=True, exist_ok=True)
    shapes = collection(n, seed=seed)
    for shape in shapes:
        write_points(folder / f"{shape.name}.xyz", shape.points, shape.normals)
    return shapes


def test_cli_batch_on_an_existing_scheduler(client, tmp_path, capsys):
    shapes = _write_shapes(tmp_path / "in", 3)
    out = tmp_path / "out"
    args = ["batch", str(tmp_path / "in" / "*.xyz"), "-o", str(out), "--scheduler", client.scheduler.address,
            "--method", "3l", "--max-degree", "4"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "[3/3]" in err and "0 failed" in err  # plain lines when piped
    for shape in shapes:
        result = load_result(out / f"{shape.name}.json")
        alone = fit_adaptive(shape.points, shape.normals, method="3l", max_degree=4)
        np.testing.assert_allclose(result["coefficients"], alone.x, rtol=1e-9, atol=1e-12)
        assert result["input"]["n_points"] == len(shape.points)
    with open(out / "summary.csv", newline="") as fh:
        assert {r["status"] for r in csv.DictReader(fh)} == {"ok"}
    assert main(args + ["-q"]) == 0  # resumed: nothing to do, nothing printed
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    with open(out / "summary.csv", newline="") as fh:
        assert {r["status"] for r in csv.DictReader(fh)} == {"skipped"}


@pytest.mark.parametrize("case", ["missing", "output_is_file", "foreign_json", "bad_option"])
def test_cli_batch_caller_errors_are_one_line_before_any_work(tmp_path, capsys, case):
    _write_shapes(tmp_path / "in", 1)
    out = tmp_path / "out"
    args = ["batch", str(tmp_path / "in"), "-o", str(out), "--method", "3l"]
    if case == "missing":
        args[1] = str(tmp_path / "nothing.xyz")
    elif case == "output_is_file":
        out.write_text("mine")
    elif case == "foreign_json":
        out.mkdir()
        (out / "star-0000.json").write_text('{"mine": 1}')
    else:
        args += ["--iterations", "5"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ipfit batch: error: ")
    if case == "foreign_json":
        assert json.loads((out / "star-0000.json").read_text()) == {"mine": 1}
    elif case != "output_is_file":
        assert not (out / "summary.csv").exists()


@pytest.mark.slow
def test_ctrl_c_cancels_pending_shapes_keeps_finished_ones_and_writes_the_summary(tmp_path):
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    cmd = [sys.executable, "-m", "ipfit.cli", "batch", "generated:40", "-o", str(out), "--max-degree", "6",
           "--iterations", "40", "--workers", "2"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 240
    while not list(out.glob("[!.]*.json")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole process group
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    statuses = [r["status"] for r in rows]
    assert len(rows) == 40 and "cancelled" in statuses and "ok" in statuses
    finished = {p.stem for p in out.glob("[!.]*.json")}
    assert finished == {r["name"] for r in rows if r["status"] == "ok"}
    for name in finished:
        load_result(out / f"{name}.json")  # complete, valid files only
    assert not [p for p in out.iterdir() if p.suffix not in (".json", ".csv", ".parquet")]  # no temporaries


def _events(total=3):
    counts = [("a", "ok", None), ("b", "failed", "ReadError: b.xyz: not a point file."), ("c", "ok", None)]
    done = failed = 0
    for i, (name, status, err) in enumerate(counts[:total]):
        done, failed = done + (status == "ok"), failed + (status == "failed")
        yield {"event": "shape", "name": name, "status": status, "error": err, "done": done, "failed": failed,
               "skipped": 0, "running": min(2, total - i - 1), "total": total, "elapsed": 1.0 + i,
               "eta": None if i == 0 else 2.0 * (total - i - 1)}


@pytest.mark.parametrize("mode", ["off", "lines", "bar"])
def test_batch_progress_modes(mode):
    import io

    from ipfit.cli.batch import BatchProgress

    stream = io.StringIO()
    shown = BatchProgress(mode, stream)
    for event in _events():
        shown(event)
    shown.close()
    text = stream.getvalue()
    if mode == "off":
        assert text == ""
    elif mode == "lines":
        lines = text.splitlines()
        assert len(lines) == 3 and lines[1].startswith("[2/3] b: failed: ReadError: b.xyz")
        assert "1 done, 1 failed, 1 running, ETA 2 s" in lines[1] and "ETA ?" in lines[0]
    else:
        assert "b: failed: ReadError" in text  # failures are printed above the bar


@pytest.mark.slow
def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys):
    _write_shapes(tmp_path / "in", 1)
    assert main(["batch", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9",
                 "--method", "3l"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler: cannot connect to tcp://127.0.0.1:9" in err


def test_cli_batch_html_writes_an_index_of_viewers_with_thumbnails(client, tmp_path):
    shapes = _write_shapes(tmp_path / "in", 2)
    out = tmp_path / "out"
    assert main(["batch", str(tmp_path / "in" / "*.xyz"), "-o", str(out), "--scheduler", client.scheduler.address,
                 "--method", "3l", "--max-degree", "2", "--html", "-q"]) == 0
    index = (out / "index.html").read_text(encoding="utf-8")
    for shape in shapes:
        assert f'<a href="{shape.name}.html"><img src="{shape.name}.png"' in index
        page = (out / f"{shape.name}.html").read_text(encoding="utf-8")
        assert "plotly" in page.lower() and not re.search(r"<script[^>]+src=[\"']https?:", page)
        assert (out / f"{shape.name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

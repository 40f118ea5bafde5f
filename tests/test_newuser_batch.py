"""``ipfit batch`` as a new user runs it (issue 34, point 3), through the real command line in
subprocesses: each shape's seed in summary.csv gives its result again with ``ipfit fit --seed``;
a batch with nothing to do answers at once without Dask; Dask's warnings stay off the terminal;
the HTML pages share one plotly script and stay small; the thumbnails show the selected degree."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("distributed")

from ipfit.batch import shape_seed

# small bundled shapes, one 2D and one 3D; a short search, which still draws random numbers
SHAPES = ["airplane", "bunny_res4"]
FIT_OPTIONS = ["--max-degree", "4", "--iterations", "10", "--population", "16"]


def _ipfit(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ipfit.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env=os.environ.copy())


def _summary(folder: Path) -> list[dict]:
    with open(folder / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@contextlib.contextmanager
def _port_8787_taken(wait: float = 60.0):
    """A socket of ours listening on port 8787 (Dask's HTTP port). Another process holding it
    (a second test run's cluster) may let it go at any moment, and the batch would then find it
    free: the port is asked for again until it is ours, for up to ``wait`` seconds."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    deadline = time.monotonic() + wait
    while True:
        try:
            sock.bind(("", 8787))
            sock.listen()
            break
        except OSError:
            if time.monotonic() > deadline:  # held all along by another: taken, as the test needs
                break
            time.sleep(0.5)
    try:
        yield
    finally:
        sock.close()


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """One real batch on an embedded LocalCluster while port 8787 is taken: (folder, process)."""
    out = tmp_path_factory.mktemp("batch") / "out"
    with _port_8787_taken():
        done = _ipfit("batch", *SHAPES, "-o", str(out), "--workers", "1", *FIT_OPTIONS)
    assert done.returncode == 0, done.stderr
    return out, done


def test_each_shape_has_its_own_seed_in_the_summary_and_the_result(batch):
    out, _ = batch
    rows = _summary(out)
    assert [r["name"] for r in rows] == SHAPES and {r["status"] for r in rows} == {"ok"}
    seeds = [int(r["seed"]) for r in rows]
    assert seeds == [shape_seed(0, name) for name in SHAPES] and len(set(seeds)) == 2
    for row in rows:
        assert json.loads((out / f"{row['name']}.json").read_text())["batch"]["shape_seed"] == int(row["seed"])


@pytest.mark.parametrize("name", SHAPES)
def test_ipfit_fit_with_the_summary_seed_gives_the_batch_result_bit_for_bit(batch, tmp_path, name):
    out, _ = batch
    seed = next(r["seed"] for r in _summary(out) if r["name"] == name)
    done = _ipfit("fit", name, "--seed", seed, *FIT_OPTIONS, "-o", str(tmp_path / name), "--no-picture",
                  "--no-zero-set", "-q")
    assert done.returncode == 0, done.stderr
    alone = json.loads((tmp_path / f"{name}.json").read_text())
    batched = json.loads((out / f"{name}.json").read_text())
    assert alone["coefficients"] == batched["coefficients"]  # bit for bit
    assert [d["coefficients"] for d in alone["degrees"]] == [d["coefficients"] for d in batched["degrees"]]
    # and the seed is what made it: the batch seed itself gives another search (the searches land on a
    # few optima, so some degree, not every one, differs)
    other = _ipfit("fit", name, "--seed", "0", *FIT_OPTIONS, "-o", str(tmp_path / "other"), "--no-picture",
                   "--no-zero-set", "-q")
    assert other.returncode == 0
    assert [d["coefficients"] for d in json.loads((tmp_path / "other.json").read_text())["degrees"]] != \
        [d["coefficients"] for d in batched["degrees"]]


def test_dask_warnings_go_to_the_log_not_the_terminal(batch):
    out, done = batch
    assert "8787" not in done.stderr and "already in use" not in done.stderr.lower()
    assert "UserWarning" not in done.stderr
    log = (out / "batch.log").read_text()
    assert "Port 8787 is already in use" in log and all("\n" not in line for line in log.splitlines())
    assert str(out / "batch.log") in done.stdout  # the last line says where they went


def test_a_batch_with_nothing_to_do_answers_at_once_without_dask(batch):
    out, _ = batch
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("[!.]*.json")}
    code = ("import json, sys, time\n"
            "from ipfit.cli import main\n"
            "start = time.perf_counter()\n"
            f"code = main({['batch', *SHAPES, '-o', str(out), '--workers', '1', *FIT_OPTIONS]!r})\n"
            "print(json.dumps({'code': code, 'seconds': time.perf_counter() - start,\n"
            "                  'dask': sorted(m for m in ('distributed', 'dask') if m in sys.modules)}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    report = json.loads(done.stdout.splitlines()[-1])
    assert report["code"] == 0 and report["dask"] == []  # no cluster: Dask not even imported
    assert report["seconds"] < 5.0  # about 1 s on an idle machine, imports included
    assert {r["status"] for r in _summary(out)} == {"skipped"}
    assert [int(r["seed"]) for r in _summary(out)] == [shape_seed(0, name) for name in SHAPES]
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("[!.]*.json")} == before


# -- --html ----------------------------------------------------------------------------------------

HTML_SHAPES = ["airplane", "boot", "butterfly", "apple", "bunny_res4", "bunny_res3", "generated:1"]


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    out = tmp_path_factory.mktemp("pages") / "out"
    done = _ipfit("batch", *HTML_SHAPES, "-o", str(out), "--method", "3l", "--workers", "2", "--html")
    assert done.returncode == 0, done.stderr
    return out


def test_seven_pages_share_one_plotly_script_and_stay_under_a_megabyte(pages):
    names = [r["name"] for r in _summary(pages)]
    assert len(names) == 7
    script = pages / "plotly.min.js"
    assert script.stat().st_size > 1_000_000  # plotly itself, once
    for name in names:
        page = pages / f"{name}.html"
        text = page.read_text()
        assert page.stat().st_size <= 1_000_000, (name, page.stat().st_size)
        assert text.count('src="plotly.min.js"') == 1 and "Plotly.newPlot" in text
    index = (pages / "index.html").read_text()
    assert all(f'href="{name}.html"' in index and f'src="{name}.png"' in index for name in names)


def _blue_extent(path: Path) -> tuple[float, float]:
    """Width and height, as shares of the picture, of its zero-set blue (curve or surface)."""
    rgb = np.asarray(Image.open(path).convert("RGB")).astype(int)
    blue = (rgb[..., 2] > rgb[..., 0] + 40) & (rgb[..., 2] > 120)
    rows, cols = np.nonzero(blue)
    return np.ptp(cols) / rgb.shape[1], np.ptp(rows) / rgb.shape[0]


def test_thumbnails_show_the_selected_degree_large_with_the_data(pages):
    for row in _summary(pages):
        path = pages / f"{row['name']}.png"
        with Image.open(path) as im:
            assert min(im.size) >= 300
        width, height = _blue_extent(path)
        assert max(width, height) > 0.4, (row["name"], width, height)  # one panel, not one of many
        grey = np.asarray(Image.open(path).convert("RGB")).astype(int)
        dark = (np.ptp(grey, axis=2) < 20) & (grey.mean(axis=2) < 150)  # the data points (grey)
        if not row["input"].startswith("generated:"):  # a generated shape's page has no file to read
            assert dark.sum() > 100, row["name"]


def test_pages_of_a_batch_with_nothing_to_do_are_kept(pages):
    stamps = {p.name: p.stat().st_mtime_ns for p in pages.glob("*.html") if p.name != "index.html"}
    done = _ipfit("batch", *HTML_SHAPES, "-o", str(pages), "--method", "3l", "--workers", "2", "--html")
    assert done.returncode == 0
    assert {r["status"] for r in _summary(pages)} == {"skipped"}
    assert {p.name: p.stat().st_mtime_ns for p in pages.glob("*.html") if p.name != "index.html"} == stamps

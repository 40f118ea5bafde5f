"""The command line's promise: one line and exit 2 on bad input or an unwritable output, no
input ever replaced, no partial or hidden file left, and finished work kept on SIGINT/SIGTERM.

Signal tests run the real command in a subprocess and send real signals; the write phase is
made observable with the test-only ``IPFIT_TEST_WRITE_DELAY`` hook (inert when unset).
"""

from __future__ import annotations

import errno
import json
import os
import pty
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ipfit
from ipfit.cli import main
from running import wait_for

SRC = str(Path(ipfit.__file__).resolve().parents[1])
FAST = ["--degree", "2", "--method", "3l", "-q"]


def heart(n: int = 60) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([16 * np.sin(t) ** 3, 13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)])


@pytest.fixture
def heart_csv(tmp_path) -> Path:
    path = tmp_path / "heart.csv"
    np.savetxt(path, heart(), delimiter=",", header="x,y", comments="")
    return path


@pytest.fixture
def result_json(tmp_path, heart_csv) -> Path:
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "r"), *FAST]) == 0
    return tmp_path / "r.json"


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def hidden(folder: Path) -> list[str]:
    """Temporary files (all start with a dot) anywhere below ``folder``."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(".*"))


def one_error_line(err: str, command: str) -> None:
    assert err.startswith(f"ipfit {command}: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and "Warning" not in err


# -- inputs are never written ----------------------------------------------------------------

def test_default_prefix_keeps_the_input_csv(tmp_path, heart_csv, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    before = heart_csv.read_bytes()
    assert main(["fit", "heart.csv", *FAST]) == 0
    assert heart_csv.read_bytes() == before
    assert listing(tmp_path) == ["heart-fit.csv", "heart-fit.json", "heart-fit.png", "heart-fit.svg", "heart.csv"]
    assert json.loads((tmp_path / "heart-fit.json").read_text())["format"] == "ipfit"
    # a second run replaces its own previous result, still not the data
    (tmp_path / "heart-fit.svg").write_text("old")
    assert main(["fit", "heart.csv", *FAST]) == 0
    assert (tmp_path / "heart-fit.svg").read_text().startswith("<?xml")
    assert heart_csv.read_bytes() == before


def test_default_prefix_keeps_the_input_mesh(tmp_path, monkeypatch):
    import trimesh

    monkeypatch.chdir(tmp_path)
    trimesh.creation.capsule(height=1.0, radius=0.5, count=[12, 12]).export(tmp_path / "capsule.ply")
    before = (tmp_path / "capsule.ply").read_bytes()
    assert main(["fit", "capsule.ply", *FAST]) == 0
    assert (tmp_path / "capsule.ply").read_bytes() == before
    assert listing(tmp_path) == ["capsule-fit.json", "capsule-fit.ply", "capsule-fit.png", "capsule.ply"]


def test_default_prefix_refuses_when_both_names_hold_user_files(tmp_path, heart_csv, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "heart-fit.png").write_bytes(b"a user's picture")
    assert main(["fit", "heart.csv", *FAST]) == 2
    one_error_line(capsys.readouterr().err, "fit")
    assert listing(tmp_path) == ["heart-fit.png", "heart.csv"]
    assert (tmp_path / "heart-fit.png").read_bytes() == b"a user's picture"


def test_default_prefix_does_not_replace_an_unrelated_json(tmp_path, heart_csv, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "heart.json").write_text('{"mine": 1}')
    assert main(["fit", "heart.csv", *FAST]) == 0
    assert (tmp_path / "heart.json").read_text() == '{"mine": 1}'
    assert (tmp_path / "heart-fit.json").exists()


@pytest.mark.parametrize("link", ["same", "symlink", "hardlink", "suffix"])
def test_explicit_output_equal_to_an_input_is_refused(tmp_path, heart_csv, capsys, link):
    before = heart_csv.read_bytes()
    target = {"same": heart_csv.with_suffix(""), "suffix": heart_csv,
              "symlink": tmp_path / "alias", "hardlink": tmp_path / "twin"}[link]
    if link == "symlink":
        (tmp_path / "alias.csv").symlink_to(heart_csv)
    if link == "hardlink":
        os.link(heart_csv, tmp_path / "twin.csv")
    assert main(["fit", str(heart_csv), "-o", str(target), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert "is the input file" in err
    assert heart_csv.read_bytes() == before
    assert not list(tmp_path.glob("*.json")) and not hidden(tmp_path)


@pytest.mark.parametrize("command", ["normals", "mesh", "plot"])
def test_other_commands_refuse_to_write_their_input(tmp_path, heart_csv, result_json, capsys, command):
    before = heart_csv.read_bytes(), result_json.read_bytes()
    argv = {"normals": ["normals", str(heart_csv), "-o", str(heart_csv)],
            # the data recorded in the result is an input too
            "mesh": ["mesh", str(result_json), "-o", str(heart_csv)],
            "plot": ["plot", str(result_json), "-o", str(result_json.with_suffix(".svg")),
                     "--points", str(result_json.with_suffix(".svg"))]}[command]
    if command == "plot":
        np.savetxt(result_json.with_suffix(".svg"), heart())  # a (strangely named) data file
        before = before + (result_json.with_suffix(".svg").read_bytes(),)
    assert main(argv) == 2
    one_error_line(capsys.readouterr().err, command)
    after = heart_csv.read_bytes(), result_json.read_bytes()
    assert after == before[:2]
    assert not hidden(tmp_path)


# -- output paths -----------------------------------------------------------------------------

def test_fit_output_folder_named_like_the_json_leaves_nothing(tmp_path, heart_csv, capsys):
    (tmp_path / "pfx.json").mkdir()
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "pfx"), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert "is a folder" in err
    assert listing(tmp_path) == ["heart.csv", "pfx.json"] and not hidden(tmp_path)


@pytest.mark.parametrize("command", ["fit", "normals", "mesh", "plot"])
def test_every_command_refuses_a_folder_as_output(tmp_path, heart_csv, result_json, capsys, command):
    folder = tmp_path / {"fit": "f.json", "normals": "n.ply", "mesh": "m.svg", "plot": "p.png"}[command]
    folder.mkdir()
    source = str(heart_csv) if command in ("fit", "normals") else str(result_json)
    out = str(folder.with_suffix("")) if command == "fit" else str(folder)
    before = listing(tmp_path)
    assert main([command, source, "-o", out] + (FAST if command == "fit" else [])) == 2
    err = capsys.readouterr().err
    one_error_line(err, command)
    assert "is a folder" in err
    assert listing(tmp_path) == before and not hidden(tmp_path) and not list(folder.iterdir())


@pytest.mark.parametrize("command", ["fit", "normals", "mesh", "plot"])
@pytest.mark.parametrize("where, reason", [
    ("{file}/sub/out", "Not a directory"),  # a file where a folder is needed
    ("/proc/ipfit-test", "No such file or directory"),  # a kernel file system takes no new files
])
def test_unwritable_output_is_one_line_naming_the_path(tmp_path, heart_csv, result_json, capsys, command, where,
                                                       reason):
    suffix = {"fit": "", "normals": ".ply", "mesh": ".svg", "plot": ".png"}[command]
    out = where.format(file=heart_csv) + suffix
    source = str(heart_csv) if command in ("fit", "normals") else str(result_json)
    before = listing(tmp_path)
    assert main([command, source, "-o", out] + (FAST if command == "fit" else [])) == 2
    err = capsys.readouterr().err
    one_error_line(err, command)
    assert reason in err and ("heart.csv" in err or "/proc/ipfit-test" in err)
    assert listing(tmp_path) == before and not hidden(tmp_path)


def test_plot_refuses_an_unknown_figure_format_before_drawing(tmp_path, result_json, capsys):
    for name in ("p.xyz", "p"):
        assert main(["plot", str(result_json), "-o", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err
        one_error_line(err, "plot")
        assert "expected a figure file name" in err and ".png" in err
    assert not hidden(tmp_path)


def test_fit_output_with_a_known_suffix_names_the_prefix(tmp_path, heart_csv):
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "res.json"), *FAST]) == 0
    assert {"res.json", "res.png", "res.svg", "res.csv"} <= set(listing(tmp_path))


def test_fit_makes_missing_folders_and_removes_them_on_failure(tmp_path, heart_csv, capsys):
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "a" / "b" / "r"), "--degree", "x"]) == 2
    capsys.readouterr()
    assert not (tmp_path / "a").exists()
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "a" / "b" / "r"), *FAST]) == 0
    assert (tmp_path / "a" / "b" / "r.json").exists()


# -- write faults (in-process fault injection) ---------------------------------------------

FAULTS = [(errno.ENOSPC, "No space left on device"), (errno.EROFS, "Read-only file system"),
          (errno.EACCES, "Permission denied")]


@pytest.mark.parametrize("code, reason", FAULTS)
def test_write_fault_found_before_the_fit(tmp_path, heart_csv, capsys, monkeypatch, code, reason):
    """The disk is full (read-only, forbidden) when the outputs are reserved: no fit runs."""
    import ipfit._utils.atomic as atomic
    import ipfit.degree.adaptive

    def fsync(fd):
        raise OSError(code, os.strerror(code))

    fits = []
    monkeypatch.setattr(atomic.os, "fsync", fsync)
    monkeypatch.setattr(ipfit.degree.adaptive, "fit_adaptive", lambda *a, **k: fits.append(1))
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "out" / "r"), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert reason in err and str(tmp_path / "out" / "r.json") in err
    assert fits == [] and listing(tmp_path) == ["heart.csv"]


@pytest.mark.parametrize("code, reason", FAULTS)
@pytest.mark.parametrize("failing", [".svg", ".png"])
def test_write_fault_during_the_write_is_all_or_nothing(tmp_path, heart_csv, capsys, monkeypatch, code, reason,
                                                        failing):
    """A write fails half-way: one line naming that output, and no output at all remains."""
    import ipfit._utils.atomic as atomic

    real = atomic.publish

    def publish(tmp, target):
        if Path(tmp).name.endswith(failing) and Path(target).name.startswith("."):  # the writer's own rename
            raise OSError(code, os.strerror(code), str(tmp))
        real(tmp, target)

    monkeypatch.setattr(atomic, "publish", publish)
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "r"), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert reason in err and f"r{failing}" in err
    assert listing(tmp_path) == ["heart.csv"]


def test_score_write_fault_keeps_the_result(tmp_path, heart_csv, result_json, capsys, monkeypatch):
    import ipfit._utils.atomic as atomic

    before = result_json.read_bytes()

    def replace(src, dst):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic.os, "replace", replace)
    assert main(["score", str(result_json), "--points", str(heart_csv), "--write"]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "score")
    assert str(result_json) in err and "No space left" in err
    assert result_json.read_bytes() == before and not hidden(tmp_path)


# -- the boundary -------------------------------------------------------------------------

def test_numpy_warnings_never_reach_the_terminal(tmp_path, capsys):
    """Normals near the float limit (which used to overflow numpy while read): no warning text."""
    path = tmp_path / "huge.csv"
    points = heart()
    np.savetxt(path, np.hstack([points, points * 1e200]), delimiter=",", header="x,y,nx,ny", comments="")
    code = main(["fit", str(path), "-o", str(tmp_path / "h"), *FAST])
    err = capsys.readouterr().err
    assert "RuntimeWarning" not in err and "overflow" not in err
    assert code in (0, 2)
    assert not hidden(tmp_path)


def test_keyboard_interrupt_in_process_says_nothing_was_written(tmp_path, heart_csv, capsys, monkeypatch):
    import ipfit.degree.adaptive

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(ipfit.degree.adaptive, "fit_adaptive", interrupted)
    assert main(["fit", str(heart_csv), "-o", str(tmp_path / "r"), *FAST]) == 130
    assert capsys.readouterr().err == "ipfit fit: interrupted; nothing was written\n"
    assert listing(tmp_path) == ["heart.csv"]


# -- real processes, real signals ------------------------------------------------------------

def _env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": SRC, "PYTHONWARNINGS": "", **extra}


def _start(args, cwd, *, tty=False, **env):
    """The command in a subprocess; with ``tty`` its stderr is a terminal (progress lines on)."""
    master = None
    stderr = subprocess.PIPE
    if tty:
        master, stderr = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "ipfit.cli", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=stderr, env=_env(**env), text=True)
    if tty:
        os.close(stderr)
    return proc, master


def _read_tty(master, buffer: list[str]) -> str:
    while select.select([master], [], [], 0)[0]:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        buffer.append(chunk.decode(errors="replace"))
    return "".join(buffer)


def _writing(folder: Path, outputs: int = 4) -> bool:
    """The write phase has begun: a writer's own temporary file beside the reserved ones."""
    return len(list(folder.glob(".ipfit-*.partial*"))) > outputs


def _finish(proc, master=None, buffer=None):
    out, err = proc.communicate(timeout=300)
    if master is not None:
        err = _read_tty(master, buffer)
        os.close(master)
    return proc.returncode, out, err


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_during_the_final_write_keeps_every_output(tmp_path, heart_csv, sig):
    proc, _ = _start(["fit", str(heart_csv), "-o", "r", "--degree", "2", "--method", "3l"], tmp_path,
                     IPFIT_TEST_WRITE_DELAY="0.5")
    assert wait_for(lambda: _writing(tmp_path))
    proc.send_signal(sig)
    code, out, err = _finish(proc)
    assert code == 128 + sig
    assert listing(tmp_path) == ["heart.csv", "r.csv", "r.json", "r.png", "r.svg"], err
    assert "finishing writing the outputs" in err and "Traceback" not in err
    assert json.loads((tmp_path / "r.json").read_text())["selected_degree"] == 2


@pytest.mark.slow
def test_second_signal_during_the_write_abandons_it_cleanly(tmp_path, heart_csv):
    proc, _ = _start(["fit", str(heart_csv), "-o", "r", *FAST], tmp_path, IPFIT_TEST_WRITE_DELAY="1")
    assert wait_for(lambda: _writing(tmp_path))
    proc.send_signal(signal.SIGINT)
    time.sleep(0.1)
    proc.send_signal(signal.SIGTERM)
    code, _, err = _finish(proc)
    assert code == 128 + signal.SIGTERM
    assert err.rstrip().endswith("nothing was written"), err
    assert listing(tmp_path) == ["heart.csv"]


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_after_the_first_degree_keeps_it(tmp_path, heart_csv, sig):
    proc, master = _start(["fit", str(heart_csv), "-o", "r", "--method", "de", "--iterations", "400",
                           "--max-degree", "8", "--rule", "paper", "--epsilon", "-1"], tmp_path, tty=True)
    buffer: list[str] = []
    assert wait_for(lambda: "degree 2: distance" in _read_tty(master, buffer), timeout=240)
    proc.send_signal(sig)
    code, out, err = _finish(proc, master, buffer)
    assert code == 128 + sig, err
    assert "Traceback" not in err
    assert listing(tmp_path) == ["heart.csv", "r.csv", "r.json", "r.png", "r.svg"]
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["adaptive"]["reason"] == "interrupted" and data["degrees"][0]["degree"] == 2


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_before_the_first_degree_writes_nothing(tmp_path, heart_csv, sig):
    proc, master = _start(["fit", str(heart_csv), "-o", "r", "--method", "de", "--iterations", "100000"],
                          tmp_path, tty=True)
    buffer: list[str] = []
    assert wait_for(lambda: "objective" in _read_tty(master, buffer), timeout=240)  # the DE stage is running
    proc.send_signal(sig)
    code, _, err = _finish(proc, master, buffer)
    assert code == 128 + sig
    last = err.replace("\r", "\n").strip().splitlines()[-1]
    assert last.startswith("ipfit fit: interrupted") and last.endswith("nothing was written")
    assert "Traceback" not in err and listing(tmp_path) == ["heart.csv"]


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.05, 0.15, 0.3, 0.6, 1.0])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_at_any_moment_leaves_no_traceback_and_no_partial_file(tmp_path, heart_csv, sig, delay):
    proc, _ = _start(["fit", str(heart_csv), "-o", "r", *FAST], tmp_path)
    time.sleep(delay)
    proc.send_signal(sig)
    code, out, err = _finish(proc)
    if "Traceback" in err:  # only Python's own start-up (site, before any ipfit module runs) may show one
        assert "ipfit" not in err and code != 0, err
    else:
        assert code in (0, 128 + sig, -sig), err  # -sig: SIGTERM before Python could install any handler
    assert not hidden(tmp_path)
    assert listing(tmp_path) in (["heart.csv"], ["heart.csv", "r.csv", "r.json", "r.png", "r.svg"])


def test_closed_stdout_is_not_an_error(tmp_path):
    proc = subprocess.Popen(f"{sys.executable} -m ipfit.cli datasets | head -c 10", shell=True, cwd=tmp_path,
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=120)
    assert len(out) == 10 and err == ""


def test_the_command_line_owns_ctrl_c_before_numpy_loads():
    """`import ipfit.cli` (what the console script runs before main) loads no numpy, scipy or
    matplotlib, so a Ctrl-C during their import happens inside main's boundary."""
    code = "import sys, ipfit.cli; print(sorted({'numpy', 'scipy', 'matplotlib'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "[]", out.stderr


def test_lazy_package_keeps_functions_named_like_their_modules():
    import ipfit.zeroset.quality
    import ipfit.fitting.refine

    assert callable(ipfit.quality) and callable(ipfit.refine) and callable(ipfit.fit_adaptive)
    assert set(ipfit.__all__) <= set(dir(ipfit))

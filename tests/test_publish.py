"""Outputs published as a set, and paths that are not regular files.

- a command's outputs appear together, also when two runs write the same prefix at once and when
  the writer is killed (SIGKILL) half-way: the next writer finishes or clears what it left;
- hidden temporary files have short names (a legal 255-byte output name works) and no error
  ever names one;
- devices, FIFOs and sockets are refused as outputs (never replaced) and as inputs (never read:
  reading a FIFO waits forever), including the files a glTF scene refers to.

Everything runs for real: subprocesses, SIGKILL, os.mkfifo, os.mknod. A test reading a FIFO
cannot hang if the refusal regresses: a thread then opens the FIFO's other end and closes it.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import ipfit
from ipfit._utils import atomic as _atomic
from ipfit.cli import main
from ipfit.exceptions import InvalidInputError, ReadError
from running import wait_for

SRC = str(Path(ipfit.__file__).resolve().parents[1])
FAST = ["--degree", "2", "--method", "3l", "-q"]
OUTPUTS = ("csv", "json", "png", "svg")
DELAY = "0.15"  # IPFIT_TEST_WRITE_DELAY: seconds per write and per rename, so a kill can land in them


def heart(n: int = 60) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([16 * np.sin(t) ** 3,
                                    13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)])


def save_csv(path: Path, points: np.ndarray) -> Path:
    np.savetxt(path, points, delimiter=",", header="x,y", comments="")
    return path


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def one_error_line(err: str, command: str) -> None:
    assert err.startswith(f"ipfit {command}: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and ".partial" not in err and ".ipfit-" not in err, err


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two inputs that make different outputs (a heart, and one upside down), and the outputs of
    one undisturbed run of each, to tell which run a file comes from."""
    folder = tmp_path_factory.mktemp("runs")
    inputs = {"a": save_csv(folder / "a.csv", heart()), "b": save_csv(folder / "b.csv", heart() * [1, -1])}
    for name, path in inputs.items():
        assert main(["fit", str(path), "-o", str(folder / name / "r"), *FAST]) == 0
    return inputs, {name: {s: (folder / name / f"r.{s}").read_bytes() for s in OUTPUTS} for name in inputs}


def run_of(folder: Path, runs) -> str:
    """Which input made the output set ``folder/r.*``; fails when the files come from different runs."""
    inputs, reference = runs
    source = json.loads((folder / "r.json").read_text())["input"]["source"]
    name = next(n for n, p in inputs.items() if source == str(p))
    for suffix in ("csv", "png", "svg"):  # deterministic for a given input (the JSON holds timings)
        made_by = [n for n in reference if reference[n][suffix] == (folder / f"r.{suffix}").read_bytes()]
        assert made_by == [name], f"r.json comes from {name}.csv, r.{suffix} from {made_by or 'neither'}"
    return name


def _env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": SRC, "PYTHONWARNINGS": "", **extra}


def _start(args, cwd, **env) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "ipfit.cli", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=_env(**env), text=True)


def _writing(folder: Path) -> bool:
    """The write phase has begun: a writer's own temporary beside the reserved ones, or the journal."""
    return len(list(folder.glob(".ipfit-*.partial*"))) > len(OUTPUTS) or any(folder.glob(".ipfit-*.journal"))


# -- two runs on one prefix ------------------------------------------------------------------

def test_concurrent_runs_on_one_prefix_never_mix(tmp_path, runs):
    inputs, _ = runs
    procs = [_start(["fit", str(inputs[name]), "-o", "r", *FAST], tmp_path, IPFIT_TEST_WRITE_DELAY=DELAY)
             for name in ("a", "b")]
    results = [(p.wait(timeout=120), p.stderr.read()) for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes in ([0, 0], [0, 2]), results
    for code, err in results:
        if code == 2:  # the later one waited for the lock, then refused
            one_error_line(err, "fit")
            assert "another ipfit process (pid " in err and "is writing r.*" in err
    run_of(tmp_path, runs)
    assert hidden(tmp_path) == []


def test_a_prefix_being_written_is_refused_with_one_line(tmp_path, runs, capsys):
    """Another process holds the prefix (its outputs reserved): fit waits briefly, then says so."""
    inputs, _ = runs
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from ipfit._utils import atomic as _atomic; "
                               "_atomic.reserve(sys.argv[1]); print('held', flush=True); time.sleep(60)",
                               str(tmp_path / "r.png")], stdout=subprocess.PIPE, env=_env(), text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        started = time.monotonic()
        assert main(["fit", str(inputs["a"]), "-o", str(tmp_path / "r"), *FAST]) == 2
        waited = time.monotonic() - started
        err = capsys.readouterr().err
        one_error_line(err, "fit")
        assert f"another ipfit process (pid {holder.pid}) is writing r.*" in err
        assert waited >= _atomic.LOCK_WAIT
        assert [p.name for p in tmp_path.iterdir() if not p.name.startswith(".")] == []
    finally:
        holder.kill()
        holder.wait()
    # the holder died without cleaning up: the next run removes what it left and writes
    assert main(["fit", str(inputs["a"]), "-o", str(tmp_path / "r"), *FAST]) == 0
    assert run_of(tmp_path, runs) == "a" and hidden(tmp_path) == []


# -- SIGKILL -------------------------------------------------------------------------------

def _kill_while_writing(folder: Path, runs, moment, pause: float) -> None:
    """An older set from input a, then a run on input b killed by SIGKILL once ``moment(folder)`` holds."""
    inputs, _ = runs
    assert main(["fit", str(inputs["a"]), "-o", str(folder / "r"), *FAST]) == 0
    proc = _start(["fit", str(inputs["b"]), "-o", "r", *FAST], folder, IPFIT_TEST_WRITE_DELAY=DELAY)
    try:
        assert wait_for(lambda: moment(folder) or proc.poll() is not None), proc.communicate()
        time.sleep(pause)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)


def _settled(folder: Path, runs) -> str:
    """What the next writer of the prefix finds, after it finished or cleared the killed run's files."""
    journal = any(folder.glob(".ipfit-*.journal"))
    _atomic.settle(folder / "r.json")
    assert hidden(folder) == []
    made_by = run_of(folder, runs)
    if journal:  # the killed run had committed its set: it is finished, all new
        assert made_by == "b"
    return made_by


def test_sigkill_while_publishing_is_finished_by_the_next_writer(tmp_path, runs):
    _kill_while_writing(tmp_path, runs, lambda f: any(f.glob(".ipfit-*.journal")), pause=0.0)
    assert any(tmp_path.glob(".ipfit-*.journal")), "the kill came too late to test the roll-forward"
    assert _settled(tmp_path, runs) == "b"


def test_a_result_read_after_a_killed_publication_is_the_completed_set(tmp_path, runs):
    """A reader of PREFIX.json (mesh, score, plot...) finishes the killed run's renames first, so it
    never reads the old JSON beside the new pictures."""
    from ipfit.degree.results import load_result

    _kill_while_writing(tmp_path, runs, lambda f: any(f.glob(".ipfit-*.journal")), pause=0.0)
    assert _atomic.unfinished(tmp_path / "r.json"), "the kill came too late to test the roll-forward"
    load_result(tmp_path / "r.json")
    assert not _atomic.unfinished(tmp_path / "r.json") and hidden(tmp_path) == []
    assert run_of(tmp_path, runs) == "b"


def test_sigkill_while_writing_leaves_the_old_set_and_the_next_run_cleans_up(tmp_path, runs, capsys):
    _kill_while_writing(tmp_path, runs, _writing, pause=0.0)
    assert hidden(tmp_path), "the kill came too late: nothing was left to clean"
    inputs, _ = runs
    assert run_of(tmp_path, runs) == "a"  # nothing of b published yet
    assert main(["fit", str(inputs["a"]), "-o", str(tmp_path / "r"), *FAST]) == 0
    assert hidden(tmp_path) == [] and run_of(tmp_path, runs) == "a"


@pytest.mark.slow
@pytest.mark.parametrize("attempt", range(12))
def test_sigkill_at_a_random_moment_of_the_write_phase(tmp_path, runs, attempt):
    pause = random.Random(attempt).uniform(0.0, 8 * float(DELAY))  # 4 writes, then 4 renames
    _kill_while_writing(tmp_path, runs, _writing, pause)
    _settled(tmp_path, runs)
    inputs, _ = runs
    assert main(["fit", str(inputs["b"]), "-o", str(tmp_path / "r"), *FAST]) == 0
    assert hidden(tmp_path) == [] and run_of(tmp_path, runs) == "b"


def test_a_damaged_journal_is_not_followed(tmp_path):
    """A journal names only temporaries of its own set, renamed onto files of that set."""
    victim = tmp_path / "keep.txt"
    victim.write_text("mine")
    key = _atomic._key(tmp_path / "r.json")
    (tmp_path / f".ipfit-{key}.lock").write_text("999999\n")  # what a killed writer leaves
    (tmp_path / f".ipfit-{key}-x.partial").write_text("stale")
    (tmp_path / f".ipfit-{key}.journal").write_text(json.dumps(
        {"renames": [[f".ipfit-{key}-x.partial", "keep.txt"], [f".ipfit-{key}-x.partial", "../r.json"], "junk"]}))
    _atomic.settle(tmp_path / "r.json")
    assert victim.read_text() == "mine" and sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


# -- names ---------------------------------------------------------------------------------------

def test_a_255_byte_output_name_is_written(tmp_path, runs):
    inputs, _ = runs
    prefix = "p" * (255 - len(".json"))
    assert main(["fit", str(inputs["a"]), "-o", str(tmp_path / prefix), *FAST]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{prefix}.{s}" for s in OUTPUTS)
    _atomic.write_text_atomic(tmp_path / ("q" * 255), "text")
    assert (tmp_path / ("q" * 255)).read_text() == "text" and hidden(tmp_path) == []


def test_an_error_while_writing_names_the_output_not_its_temporary(tmp_path, capsys):
    """An empty zero set is found by the mesh writer, which only sees the staged temporary file."""
    t = np.linspace(0, 2 * np.pi, 16)
    ball = np.array([[np.cos(a) * np.sin(b), np.sin(a) * np.sin(b), np.cos(b)]
                     for a in t[:-1] for b in np.linspace(0.2, np.pi - 0.2, 8)])
    np.savetxt(tmp_path / "ball.xyz", ball)
    np.savetxt(tmp_path / "far.xyz", ball + 100)
    assert main(["fit", str(tmp_path / "ball.xyz"), "-o", str(tmp_path / "b"), "--no-picture", *FAST]) == 0
    assert main(["mesh", str(tmp_path / "b.json"), "-o", str(tmp_path / "m.ply"),
                 "--points", str(tmp_path / "far.xyz")]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "mesh")
    assert err.startswith(f"ipfit mesh: error: {tmp_path / 'm.ply'}: the ") and "zero set is empty" in err
    assert not (tmp_path / "m.ply").exists() and hidden(tmp_path) == []


# -- special files as outputs ------------------------------------------------------------------

def _make_special(path: Path, kind: str) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":  # a /dev/null of our own, never the system's
        if os.geteuid() != 0:
            pytest.skip("making a device node needs root")
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    elif kind == "socket":
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(path))
        server.close()
    else:
        path.symlink_to("/dev/null")


SPECIAL = [("fifo", "named pipe (FIFO)"), ("device", "character device"), ("socket", "socket"),
           ("link to /dev/null", "character device")]


@pytest.mark.parametrize("kind, said", SPECIAL)
def test_fit_refuses_a_special_file_as_output(tmp_path, runs, capsys, kind, said):
    inputs, _ = runs
    _make_special(tmp_path / "r.svg", kind)
    before = os.lstat(tmp_path / "r.svg")
    null = os.stat("/dev/null")
    assert main(["fit", str(inputs["a"]), "-o", str(tmp_path / "r"), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert f"got {tmp_path / 'r.svg'}, a {said}" in err
    after = os.lstat(tmp_path / "r.svg")
    assert (after.st_ino, after.st_mode) == (before.st_ino, before.st_mode)
    assert os.stat("/dev/null").st_ino == null.st_ino and stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.svg"]


@pytest.mark.parametrize("command", ["mesh", "plot", "normals", "export"])
def test_every_command_refuses_a_fifo_as_output(tmp_path, runs, capsys, command):
    inputs, _ = runs
    result = inputs["a"].parent / "a" / "r.json"
    out = tmp_path / {"mesh": "m.svg", "plot": "p.png", "normals": "n.ply", "export": "e.py"}[command]
    os.mkfifo(out)
    argv = {"normals": ["normals", str(inputs["a"])], "export": ["export", str(result), "--to", "python"]}
    assert main([*argv.get(command, [command, str(result)]), "-o", str(out)]) == 2
    one_error_line(capsys.readouterr().err, command)
    assert stat.S_ISFIFO(os.lstat(out).st_mode) and sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def test_the_library_refuses_to_replace_a_special_file(tmp_path):
    os.mkfifo(tmp_path / "f.json")
    (tmp_path / "null.json").symlink_to("/dev/null")
    for name in ("f.json", "null.json"):
        with pytest.raises(InvalidInputError, match="expected a regular file or a new file name"):
            _atomic.write_text_atomic(tmp_path / name, "{}")
    assert stat.S_ISFIFO(os.lstat(tmp_path / "f.json").st_mode) and (tmp_path / "null.json").is_symlink()
    assert hidden(tmp_path) == []


# -- special files as inputs -------------------------------------------------------------------

@contextlib.contextmanager
def unblocking(fifo: Path):
    """Should a reader open ``fifo`` after all, open its write end and close it (the reader then
    sees an empty file), so a regression fails the test instead of hanging it."""
    done = threading.Event()

    def unblock() -> None:
        while not done.wait(0.05):
            try:
                fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)  # fails (ENXIO) until someone reads
            except OSError:
                continue
            os.close(fd)

    thread = threading.Thread(target=unblock, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


@pytest.mark.parametrize("command", ["fit", "mesh --points", "normals"])
def test_a_fifo_as_input_is_refused_not_waited_on(tmp_path, runs, capsys, command):
    inputs, _ = runs
    fifo = tmp_path / "data.csv"
    os.mkfifo(fifo)
    result = str(inputs["a"].parent / "a" / "r.json")
    argv = {"fit": ["fit", str(fifo), "-o", str(tmp_path / "r"), *FAST],
            "mesh --points": ["mesh", result, "--points", str(fifo), "-o", str(tmp_path / "m.svg")],
            "normals": ["normals", str(fifo), "-o", str(tmp_path / "n.ply")]}[command]
    with unblocking(fifo):
        assert main(argv) == 2
    err = capsys.readouterr().err
    one_error_line(err, command.split()[0])
    assert f"{fifo}: is a named pipe (FIFO), not a regular file" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.csv"]


@pytest.mark.parametrize("command", ["mesh", "plot", "score", "export", "view", "render"])
def test_a_fifo_as_result_is_refused_not_waited_on(tmp_path, capsys, command):
    fifo = tmp_path / "r.json"
    os.mkfifo(fifo)
    out = {"mesh": ["-o", str(tmp_path / "m.svg")], "plot": ["-o", str(tmp_path / "p.png")], "score": [],
           "export": ["--to", "c"], "view": ["-o", str(tmp_path / "v.html")], "render": ["-o", str(tmp_path / "i.png")]}
    with unblocking(fifo):
        assert main([command, str(fifo), *out[command]]) == 2
    err = capsys.readouterr().err
    one_error_line(err, command)
    assert f"{fifo}: is a named pipe (FIFO), not a result file" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_stdin_as_input_is_refused(tmp_path):
    """``/dev/stdin`` is a pipe here (kept open: a reader would wait for it to close)."""
    proc = subprocess.Popen([sys.executable, "-m", "ipfit.cli", "fit", "/dev/stdin", *FAST], cwd=tmp_path,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env(),
                            text=True)
    try:
        code = proc.wait(timeout=60)
    finally:
        proc.kill()
        proc.stdin.close()
    err = proc.stderr.read()
    assert code == 2, err
    one_error_line(err, "fit")
    assert "/dev/stdin: is a named pipe (FIFO), not a regular file" in err and list(tmp_path.iterdir()) == []


def test_the_readers_refuse_sockets_devices_and_folders(tmp_path):
    sock = tmp_path / "s.xyz"
    _make_special(sock, "socket")
    (tmp_path / "d.ply").mkdir()
    for path, said in ((sock, "is a socket"), ("/dev/zero", "is a character device"), (tmp_path / "d.ply", "folder")):
        for read in (ipfit.io.read_points, ipfit.io.read_mesh):
            with pytest.raises(ReadError, match=said):
                read(path)


def _gltf_referring_to(folder: Path, uri: str) -> Path:
    import trimesh

    files = trimesh.creation.box().export(file_type="gltf")
    scene = json.loads(files["model.gltf"])
    for name, data in files.items():
        if name != "model.gltf":
            (folder / name).write_bytes(data)
    scene["buffers"][0]["uri"] = uri
    path = folder / "scene.gltf"
    path.write_text(json.dumps(scene))
    return path


@pytest.mark.parametrize("uri, said", [("pipe.bin", "a named pipe (FIFO), not a regular file"),
                                       ("../gltf_buffer_0.bin", "outside its folder"),
                                       ("/dev/zero", "outside its folder"),
                                       ("link.bin", "outside its folder")])
def test_a_gltf_buffer_that_is_not_a_file_beside_it_is_refused(tmp_path, capsys, uri, said):
    folder = tmp_path / "scene"
    folder.mkdir()
    path = _gltf_referring_to(folder, uri)
    (tmp_path / "gltf_buffer_0.bin").write_bytes((folder / "gltf_buffer_0.bin").read_bytes())
    (folder / "link.bin").symlink_to(tmp_path / "gltf_buffer_0.bin")
    os.mkfifo(folder / "pipe.bin")
    with unblocking(folder / "pipe.bin"):
        assert main(["fit", str(path), "-o", str(tmp_path / "r"), *FAST]) == 2
    err = capsys.readouterr().err
    one_error_line(err, "fit")
    assert f"{path}: it refers to '{uri}', {said}" in err


def test_a_gltf_with_its_buffers_beside_it_still_reads(tmp_path):
    path = _gltf_referring_to(tmp_path, "gltf_buffer_0.bin")
    assert ipfit.io.read_points(path).points.shape == (8, 3)

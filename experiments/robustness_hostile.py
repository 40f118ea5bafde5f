"""The second campaign of experiments/robustness.py: ipfit tried as a hostile user would.

Batch outputs (same stems, user files in OUTDIR, names that escape, corrupted results on
resume, Ctrl-C), concurrent and killed runs on one prefix, special files (FIFOs, character
devices, sockets) as inputs and outputs, resource bombs (huge shape counts, worker counts,
degrees, images), result-JSON edge cases in every command that reads one, unusual API inputs
(masked arrays, pandas frames, bool arrays, generators, matrices) and missing optional
packages. Every command-line case runs in a real subprocess with a time limit, so a hang is
counted, not suffered; each case also counts data lost (a shape without its row or result)
and mixed output sets (files of one prefix from different runs).
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [sys.path[0], os.environ.get("PYTHONPATH")]))  # its child processes too

import ipfit
from ipfit.batch import MANIFEST
from ipfit.exceptions import IpfitError

SRC = str(Path(ipfit.__file__).resolve().parents[1])
FAST = ["--degree", "2", "--method", "3l", "-q"]
LIMIT = 90  # seconds before a case counts as a hang
BATCH = ["batch", "--workers", "1"]


def _env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": SRC, "PYTHONWARNINGS": "", **extra}


def ellipse(n: int = 60, a: float = 3.0, b: float = 1.0, shift=(0.0, 0.0)) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([a * np.cos(t) + shift[0], b * np.sin(t) + shift[1]])


def save_csv(path: Path, pts: np.ndarray) -> Path:
    np.savetxt(path, pts, delimiter=",", header="x,y" if pts.shape[1] == 2 else "x,y,z", comments="")
    return path


# -- running a case ---------------------------------------------------------------------------

def spawn(argv: list[str], cwd: Path, **env) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "ipfit.cli", *argv], cwd=cwd, env=_env(**env),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def finish(proc: subprocess.Popen, limit: float = LIMIT) -> tuple[int | None, str]:
    """(exit code, stderr), or (None, stderr so far) after killing a process that hung."""
    try:
        _, err = proc.communicate(timeout=limit)
        return proc.returncode, err
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
        return None, err


def verdict(code: int | None, err: str, *, allow_success: bool = True, command: str = "") -> str | None:
    """What broke the promise (None when the case ended as promised)."""
    if code is None:
        return f"no answer within {LIMIT} s"
    if "Traceback" in err or "Exception ignored" in err:
        return "traceback: " + (err.strip().splitlines() or [""])[-1][:140]
    lines = [line for line in err.strip().splitlines() if line]
    if code == 2:
        if len(lines) != 1 or not lines[0].startswith(f"ipfit {command}".strip()) or "error:" not in lines[0]:
            return "not one error line: " + " | ".join(lines)[:160]
        if ".partial" in lines[0]:
            return "names a temporary file: " + lines[0][:160]
        return None
    if code == 0 and allow_success:
        return None
    return f"exit {code}: {' | '.join(lines)[-160:]}"


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if ".partial" in p.name]


def snapshot(paths) -> dict[str, bytes]:
    return {str(p): Path(p).read_bytes() for p in paths if Path(p).is_file()}


def changed(before: dict[str, bytes]) -> int:
    return sum(not Path(p).is_file() or Path(p).read_bytes() != content for p, content in before.items())


def cli_case(tally, category: str, argv: list[str], cwd: Path, *, protect=(), allow_success=True, note="",
             limit: float = LIMIT, env: dict | None = None, check=None) -> tuple[int | None, str]:
    """One subprocess case: its verdict, temporaries left, protected files changed, and ``check(cwd)``'s
    extra counts ({"lost": n, "mixed": n, "problem": text})."""
    before = snapshot(protect)
    code, err = finish(spawn(argv, cwd, **(env or {})), limit)
    problem = verdict(code, err, allow_success=allow_success, command=argv[0] if argv else "")
    extra = check(cwd, code) if check is not None else {}
    problem = problem or extra.pop("problem", None)
    tally.add(category, clean=True, foreign=problem, reproducer=note + "ipfit " + " ".join(argv),
              leftovers=len(temporaries(cwd)), modified=changed(before), hang=code is None,
              lost=extra.get("lost", 0), mixed=extra.get("mixed", 0))
    return code, err


def api_case(tally, category: str, label: str, call, *, accept_warnings: bool = False) -> None:
    """An API call ends in success or an IpfitError with one line, and leaks no foreign warning."""
    problem = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            call()
        except IpfitError as exc:
            if len(str(exc).splitlines()) != 1:
                problem = f"{type(exc).__name__} of {len(str(exc).splitlines())} lines"
        except Exception as exc:  # noqa: BLE001 - what escapes is exactly what is counted
            problem = f"{type(exc).__name__}: {str(exc).splitlines()[0][:120] if str(exc) else ''}"
    foreign = [w for w in caught if not issubclass(w.category, ipfit.exceptions.IpfitWarning)
               and not issubclass(w.category, (DeprecationWarning, RuntimeWarning))]
    pending = [w for w in caught if issubclass(w.category, PendingDeprecationWarning)]
    if problem is None and (pending or foreign and not accept_warnings):
        w = (pending or foreign)[0]
        problem = f"leaked {w.category.__name__}: {str(w.message)[:100]}"
    tally.add(category, clean=True, foreign=problem, reproducer=label)


# -- batch outputs ------------------------------------------------------------------------------

def _summary(folder: Path) -> list[dict]:
    path = folder / "summary.csv"
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _rows_lost(folder: Path, expected: int) -> dict:
    rows = _summary(folder)
    names = {r.get("name") for r in rows}
    results = [r for r in rows if r.get("status") in ("ok", "skipped")]
    missing_json = [r for r in results if not (folder / f"{r['name']}.json").is_file()]
    return {"lost": max(0, expected - len(names)) + len(missing_json)}


def batch_outputs(tally, work: Path) -> None:
    cat = "batch outputs"
    a, b = ellipse(), ellipse(a=2.0, shift=(1.0, 0.0))
    # Two inputs of one stem, then a resume: two rows, two results, nothing refitted.
    case = work / "stems"
    case.mkdir()
    save_csv(case / "a.csv", a)
    np.savetxt(case / "a.xyz", b)
    inputs = [case / "a.csv", case / "a.xyz"]
    argv = [*BATCH, "a.csv", "a.xyz", "-o", "out", *FAST]
    cli_case(tally, cat, argv, case, protect=inputs, check=lambda cwd, code: _rows_lost(cwd / "out", 2),
             note="(a.csv and a.xyz) ")
    stamps = {p.name: p.stat().st_mtime_ns for p in (case / "out").glob("[!.]*.json")}

    def refitted(cwd, code):
        now = {p.name: p.stat().st_mtime_ns for p in (cwd / "out").glob("[!.]*.json")}
        again = [r for r in _summary(cwd / "out") if r.get("status") != "skipped"]
        out = _rows_lost(cwd / "out", 2)
        if again or now != stamps:
            out["problem"] = f"resume refitted {[r['name'] for r in again]} or rewrote a finished result"
        return out

    cli_case(tally, cat, argv, case, protect=inputs, check=refitted, note="(resume of a.csv and a.xyz) ")

    # User files in OUTDIR: summary.csv, summary.parquet, index.html and NAME.png/NAME.html are not ipfit's.
    for user_file in ("summary.csv", "summary.parquet", "index.html", "a.png", "a.html", "a.json"):
        case = work / f"user-{user_file}"
        (case / "out").mkdir(parents=True)
        save_csv(case / "a.csv", a)
        (case / "out" / user_file).write_text("the user's own file\n")
        cli_case(tally, cat, [*BATCH, "a.csv", "-o", "out", "--html", *FAST], case,
                 protect=[case / "a.csv", case / "out" / user_file], note=f"(out/{user_file} is the user's) ")
    # OUTDIR is the input folder, and an input is called summary.csv.
    case = work / "input-summary"
    case.mkdir()
    save_csv(case / "summary.csv", a)
    save_csv(case / "b.csv", b)
    cli_case(tally, cat, [*BATCH, ".", "-o", ".", *FAST], case, protect=[case / "summary.csv", case / "b.csv"],
             note="(input folder = OUTDIR, an input named summary.csv) ")
    # A shape called index, with --html (the batch index is index.html too).
    case = work / "index-shape"
    case.mkdir()
    save_csv(case / "index.csv", a)
    save_csv(case / "b.csv", b)

    def index_kept(cwd, code):
        out = _rows_lost(cwd / "out", 2)
        if code == 0:
            page = (cwd / "out" / "index.html").read_text(encoding="utf-8", errors="replace")
            views = [r for r in _summary(cwd / "out") if not (cwd / "out" / f"{r['name']}.html").is_file()]
            if "b" not in page or views:
                out["problem"] = "the batch index and a shape's viewer collide"
        return out

    cli_case(tally, cat, [*BATCH, "index.csv", "b.csv", "-o", "out", "--html", *FAST], case,
             protect=[case / "index.csv", case / "b.csv"], check=index_kept, note="(a shape named index) ")
    _corrupted_resume(tally, work, a)
    _batch_names(tally, work, a)


def _corrupted_resume(tally, work: Path, pts: np.ndarray) -> None:
    cat = "batch resume over corrupted results"
    case = work / "resume"
    case.mkdir()
    save_csv(case / "a.csv", pts)
    argv = [*BATCH, "a.csv", "-o", "out", *FAST]
    code, _ = finish(spawn(argv, case))
    good = json.loads((case / "out" / "a.json").read_text())
    deep = "[" * 100_000 + "]" * 100_000
    corruptions = {
        "input is a list": {**good, "input": [1, 2]}, "batch is a string": {**good, "batch": "x"},
        "measures is a list": {**good, "measures": [1]}, "adaptive is a string": {**good, "adaptive": "x"},
        "coefficients removed": {k: v for k, v in good.items() if k != "coefficients"},
        "coefficients NaN": {**good, "coefficients": [float("nan")] * len(good["coefficients"])},
        "degrees is a string": {**good, "degrees": "x"},
        "a 5000-digit coefficient": {**good, "coefficients": ["@"] + good["coefficients"][1:]},
        "normalization a list": {**good, "normalization": [0, 1]}, "quality is a list": {**good, "quality": [0]},
    }
    texts = {label: json.dumps(doc).replace('"@"', "1" + "0" * 4999) for label, doc in corruptions.items()}
    texts["nested 100,000 deep"] = json.dumps({**good, "measures": "@"}).replace('"@"', deep)
    texts["truncated"] = json.dumps(good)[:200]
    for label, text in texts.items():
        (case / "out" / "a.json").write_text(text)

        def refit(cwd, code, label=label):
            rows = _summary(cwd / "out")
            out = {"lost": int(not rows)}
            if code == 0 and (not rows or rows[0].get("status") != "ok"):
                out["problem"] = f"a resume took a corrupted result ({label}) as finished: {rows[:1]}"
            return out

        cli_case(tally, cat, argv, case, protect=[case / "a.csv"], check=refit, note=f"(out/a.json: {label}) ")


def _batch_names(tally, work: Path, pts: np.ndarray) -> None:
    """fit_many names: nothing is ever written outside the output folder, nor as a hidden file."""
    cat = "batch names (API)"
    script = textwrap.dedent("""
        import json, sys
        import numpy as np
        from ipfit.batch import fit_many
        from ipfit.exceptions import IpfitError
        name, folder = json.loads(sys.argv[1]), sys.argv[2]
        t = 2 * np.pi * np.arange(60) / 60
        pts = np.column_stack([3 * np.cos(t), np.sin(t)])
        try:
            fit_many({name: pts}, output=folder, method="3l", max_degree=2, workers=1)
        except IpfitError as exc:
            print(exc, file=sys.stderr)
            sys.exit(2)
        """)
    for name in ("../escaped", "", ".", "..", "a/b", "/tmp/abs", ".hidden", "a\\b", "x" * 300, "nul\0byte",
                 "summary", "index"):
        case = work / f"names-{len(list(work.iterdir()))}"
        (case / "box").mkdir(parents=True)
        proc = subprocess.Popen([sys.executable, "-c", script, json.dumps(name), str(case / "box" / "out")], cwd=case,
                                env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        code, err = finish(proc)
        problem = None if code == 2 and len(err.strip().splitlines()) == 1 else verdict(code, err)
        outside = [p for p in case.rglob("*") if p.is_file() and (case / "box" / "out") not in p.parents]
        hidden = [p for p in (case / "box" / "out").rglob(".*") if p.name != MANIFEST] \
            if (case / "box" / "out").exists() else []
        if outside or hidden:
            problem = f"wrote {[str(p.relative_to(case)) for p in outside + hidden]}"
        tally.add(cat, clean=True, foreign=problem, reproducer=f"fit_many({{{name!r}: pts}}, output='out')",
                  hang=code is None)


# -- interrupted batches ------------------------------------------------------------------------

def batch_signals(tally, work: Path, n: int) -> None:
    cat = "batch Ctrl-C"
    for case_no in range(n):
        case = work / f"bsig{case_no}"
        case.mkdir()
        argv = [*BATCH[:1], "generated:6", "-o", "out", "--workers", "2", "--max-degree", "6", "-q"]
        proc = spawn(argv, case)
        time.sleep(4.0 + case_no)
        twice = case_no % 2 == 1
        os.kill(proc.pid, signal.SIGINT)
        if twice:
            time.sleep(0.3)
            os.kill(proc.pid, signal.SIGINT)
        code, err = finish(proc)
        problem = None
        if code is None:
            problem = f"no answer within {LIMIT} s"
        elif "Traceback" in err or "Exception ignored" in err:
            problem = "traceback: " + err.strip().splitlines()[-1][:140]
        elif code not in (0, 130):
            problem = f"exit {code}: {err.strip()[-140:]}"
        rows = _summary(case / "out")
        lost = 0 if code in (0, 130) and len(rows) == 6 else int(code is not None)
        done = [r for r in rows if r.get("status") == "ok" and not (case / "out" / f"{r['name']}.json").is_file()]
        tally.add(cat, clean=True, foreign=problem, hang=code is None, lost=lost + len(done),
                  leftovers=len(temporaries(case)),
                  reproducer=f"ipfit {' '.join(argv)} & sleep {4 + case_no}; kill -INT $!" + ("; sleep 0.3; kill -INT $!"
                                                                                            if twice else ""))
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # stray workers, if any


# -- one prefix, several runs -------------------------------------------------------------------

def _set_consistent(cwd: Path, prefix: str) -> bool:
    """Whether PREFIX.json and PREFIX.csv come from one run: the zero set's vertices lie on the
    JSON's polynomial (a mixed set's lie on another curve)."""
    files = [cwd / f"{prefix}{s}" for s in (".json", ".csv")]
    if not all(p.is_file() for p in files):
        return not any(p.is_file() for p in files)
    poly = ipfit.ImplicitPolynomial.load(files[0])
    xy = np.loadtxt(files[1], delimiter=",", comments="#", skiprows=3, usecols=(1, 2), ndmin=2)
    values = np.abs(poly(xy)) / np.maximum(np.linalg.norm(poly.gradient(xy), axis=1), 1e-300)
    return bool(np.median(values) < 1e-2)


def publishing(tally, work: Path, kills: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    cat = "one prefix, concurrent runs"
    for case_no in range(4):
        case = work / f"conc{case_no}"
        case.mkdir()
        save_csv(case / "a.csv", ellipse())
        save_csv(case / "b.csv", ellipse(a=1.0, b=2.0, shift=(5.0, 0.0)))
        delay = {"IPFIT_TEST_WRITE_DELAY": f"{0.1 + 0.1 * case_no:.1f}"}
        procs = [spawn(["fit", name, "-o", "r", *FAST], case, **delay) for name in ("a.csv", "b.csv")]
        time.sleep(rng.uniform(0, 0.5))
        outcomes = [finish(p) for p in procs]
        problems = [verdict(code, err, command="fit") for code, err in outcomes]
        mixed = int(not _set_consistent(case, "r"))
        ok = [code for code, _ in outcomes if code == 0]
        tally.add(cat, clean=True, foreign=next((p for p in problems if p), None) or
                  (None if ok else "neither run wrote its outputs"), mixed=mixed,
                  hang=any(code is None for code, _ in outcomes), leftovers=len(temporaries(case)),
                  reproducer=f"IPFIT_TEST_WRITE_DELAY={delay['IPFIT_TEST_WRITE_DELAY']} ipfit fit a.csv -o r & "
                             "ipfit fit b.csv -o r")
    cat = "SIGKILL while publishing, then a rerun"
    for case_no in range(kills):
        case = work / f"kill{case_no}"
        case.mkdir()
        save_csv(case / "a.csv", ellipse())
        save_csv(case / "b.csv", ellipse(a=1.0, b=2.0, shift=(5.0, 0.0)))
        finish(spawn(["fit", "a.csv", "-o", "r", *FAST], case))  # an older result
        proc = spawn(["fit", "b.csv", "-o", "r", *FAST], case, IPFIT_TEST_WRITE_DELAY="0.3")
        moment = rng.uniform(0.5, 3.5)
        time.sleep(moment)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        finish(proc)
        code, err = finish(spawn(["fit", "a.csv", "-o", "r", *FAST, "--degree", "4"], case))  # the next run
        problem = verdict(code, err, command="fit")
        tally.add(cat, clean=True, foreign=problem, hang=code is None, mixed=int(not _set_consistent(case, "r")),
                  leftovers=len(temporaries(case)) + len(list(case.glob(".*"))),
                  reproducer=f"IPFIT_TEST_WRITE_DELAY=0.3 ipfit fit b.csv -o r & sleep {moment:.2f}; kill -KILL $!; "
                             "ipfit fit a.csv -o r --degree 4")


# -- special files --------------------------------------------------------------------------------

def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _char_device(path: Path) -> Path | None:
    """A character device like /dev/null, made in the case's own folder (root only)."""
    try:
        os.mknod(path, 0o666 | 0o020000, os.makedev(1, 3))
    except (PermissionError, AttributeError, OSError):
        return None
    return path


def special_files(tally, work: Path, result: Path) -> None:
    cat = "special files as inputs"
    case = work / "special-in"
    case.mkdir()
    fifo = _fifo(case / "pipe.csv")
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(str(case / "sock.csv"))
    device = _char_device(case / "dev.csv")
    names = ["pipe.csv", "sock.csv"] + ([device.name] if device else []) + ["/dev/stdin"]
    r = str(result)
    for name in names:
        for argv in (["fit", name, "-o", "o", *FAST], ["normals", name, "-o", "n.ply"],
                     ["mesh", r, "--points", name, "-o", "m.svg"], ["score", r, "--points", name],
                     ["plot", r, "--points", name, "-o", "p.png", "--dpi", "20"],
                     [*BATCH, name, "-o", "out", *FAST]):
            cli_case(tally, cat, argv, case, protect=[result])
    # A glTF whose buffer is a FIFO.
    gltf = {"asset": {"version": "2.0"}, "buffers": [{"uri": "pipe.bin", "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}], "scene": 0}
    _fifo(case / "pipe.bin")
    (case / "scene.gltf").write_text(json.dumps(gltf))
    cli_case(tally, cat, ["fit", "scene.gltf", "-o", "g", *FAST], case, protect=[case / "scene.gltf"],
             note="(scene.gltf's buffer is a FIFO) ")
    listener.close()

    cat = "special files as outputs"
    case = work / "special-out"
    case.mkdir()
    save_csv(case / "a.csv", ellipse())
    specials = [_fifo(case / "f.json"), _fifo(case / "f2.svg"), _fifo(case / "f3.ply")]
    outputs = [["fit", "a.csv", "-o", "f", *FAST], ["fit", "a.csv", "-o", "f.json", *FAST],
               ["mesh", r, "-o", "f2.svg"], ["normals", "a.csv", "-o", "f3.ply"]]
    devices = [_char_device(case / "null.json"), _char_device(case / "null.png")]
    if all(devices):
        (case / "link.svg").symlink_to(devices[0])
        specials += [*devices, case / "link.svg"]
        outputs += [["fit", "a.csv", "-o", "null", *FAST], ["mesh", r, "-o", "link.svg"],
                    ["plot", r, "-o", "null.png", "--dpi", "20"], ["view", r, "-o", "link.svg"]]
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(case / "s.json"))
    specials.append(case / "s.json")
    outputs.append(["fit", "a.csv", "-o", "s", *FAST])
    for argv in outputs:
        def still_special(cwd, code):
            kinds = [p for p in specials if p.exists() or p.is_symlink()]
            regular = [p.name for p in kinds if p.is_file()]
            return {"problem": f"replaced the special file(s) {regular}"} if regular else {}

        cli_case(tally, cat, argv, case, protect=[case / "a.csv"], check=still_special, allow_success=False)
    sock.close()


# -- resource bombs -------------------------------------------------------------------------------

def _silent_server() -> tuple[socket.socket, int]:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted = []

    def accept():
        with contextlib.suppress(OSError):
            while True:
                accepted.append(server.accept()[0])  # accepted, never answered

    threading.Thread(target=accept, daemon=True).start()
    return server, server.getsockname()[1]


def resources(tally, work: Path, result: Path) -> None:
    cat = "resource bombs"
    case = work / "bombs"
    case.mkdir()
    save_csv(case / "a.csv", ellipse())
    server, port = _silent_server()
    cases = [
        [*BATCH[:1], "generated:1000000000000", "-o", "out", *FAST],
        [*BATCH[:1], "generated:99999999999999999999", "-o", "out", *FAST],
        [*BATCH[:1], "a.csv", "-o", "out", "--workers", "1000", *FAST],
        [*BATCH[:1], "a.csv", "-o", "out", "--scheduler", f"tcp://127.0.0.1:{port}", *FAST],
        [*BATCH[:1], "a.csv", "-o", "out", "--scheduler", "tcp://127.0.0.1:1", *FAST],
    ]
    for argv in cases:
        cli_case(tally, cat, argv, case, protect=[case / "a.csv"], allow_success=False, limit=60)
    server.close()
    # A result claiming degree 30 in 3D, scored; a sphere scaled by 1e308, rendered.
    sphere = _sphere_result(case)
    big = json.loads(sphere.read_text())
    big["normalization"]["scale"] = 1e308
    (case / "huge.json").write_text(json.dumps(big))
    d30 = json.loads(sphere.read_text())
    from ipfit.basis import exponents

    e = exponents(3, 30)
    d30.update(degree=30, exponents=e.tolist(), coefficients=[0.0] * (len(e) - 1) + [1.0])
    d30.pop("degrees", None)
    d30.pop("selected_degree", None)
    (case / "d30.json").write_text(json.dumps(d30))
    for argv in (["score", "d30.json", "--points", "sphere.csv"], ["mesh", "d30.json", "-o", "d.ply"],
                 ["render", "d30.json", "-o", "d.png", "--size", "64"], ["render", "huge.json", "-o", "h.png",
                                                                          "--size", "64"],
                 ["mesh", "huge.json", "-o", "h.ply"], ["plot", "huge.json", "-o", "h.png", "--dpi", "20"]):
        cli_case(tally, cat, argv, case, limit=120)
    # A 12,000 x 12,000 silhouette: refused or read within a memory bound (peak RSS counted).
    from PIL import Image

    image = Image.new("1", (12_000, 12_000), 0)
    image.paste(1, (3000, 3000, 9000, 9000))
    image.save(case / "big.png")
    del image
    script = ("import resource, sys\nfrom ipfit.cli import main\ncode = main(['fit', 'big.png', '-o', 'b', "
              "'--degree', '2', '--method', '3l', '-q'])\n"
              "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024, file=sys.stderr)\nsys.exit(code)")
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=case, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    code, err = finish(proc)
    lines = err.strip().splitlines()
    peak = int(lines[-1]) if lines and lines[-1].isdigit() else None
    problem = verdict(code, "\n".join(lines[:-1]), command="fit") if peak is not None else f"crashed: {err[-140:]}"
    if problem is None and peak is not None and peak > 1500:
        problem = f"read with a {peak} MB peak"
    tally.add(cat, clean=True, foreign=problem, hang=code is None, reproducer="ipfit fit big.png (12,000² pixels)")


def _sphere_result(case: Path) -> Path:
    u = np.random.default_rng(0).normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    save_csv(case / "sphere.csv", u)
    finish(spawn(["fit", "sphere.csv", "-o", "sphere", *FAST, "--no-picture", "--no-zero-set"], case))
    return case / "sphere.json"


# -- result JSON edge cases -----------------------------------------------------------------------

def result_edges(tally, work: Path, result: Path, data: Path) -> None:
    cat = "result JSON edge cases"
    case = work / "edges"
    case.mkdir()
    shutil.copy(data, case / data.name)
    good = json.loads(result.read_text())
    deep = "[" * 100_000 + "]" * 100_000
    docs = {
        "normalization null": {**good, "normalization": None},
        "a 5000-digit coefficient": {**good, "coefficients": ["@"] + good["coefficients"][1:]},
        "centre and scale 1e300": {**good, "normalization": {"center": [1e300, 1e300], "scale": 1e300}},
        "input is a list": {**good, "input": [1]}, "measures is a string": {**good, "measures": "x"},
        "degrees is a dict": {**good, "degrees": {"a": 1}}, "degrees hold strings": {**good, "degrees": ["x"]},
        "quality is a list": {**good, "quality": [1]}, "exponents are strings": {**good, "exponents": "x"},
        "minimal": {k: good[k] for k in ("format", "version", "dim", "degree", "exponents", "coefficients",
                                         "normalization")},
        "a 400-digit degree": {**good, "degree": "@400"}, "bool coefficients": {**good, "coefficients":
                                                                                  [True] * len(good["coefficients"])},
    }
    texts = {label: json.dumps(doc).replace('"@"', "1" + "0" * 4999).replace('"@400"', "1" + "0" * 400)
             for label, doc in docs.items()}
    texts["nested 100,000 deep"] = json.dumps({**good, "info": "@"}).replace('"@"', deep)
    d = data.name
    for label, text in texts.items():
        (case / "r.json").write_text(text)
        for argv in (["mesh", "r.json", "--points", d, "-o", "m.svg"], ["plot", "r.json", "--points", d, "-o", "p.png",
                                                                        "--dpi", "20"],
                     ["score", "r.json", "--points", d], ["export", "r.json", "--to", "c"],
                     ["view", "r.json", "--points", d, "-o", "v.html"]):
            cli_case(tally, cat, argv, case, protect=[case / "r.json", case / d], note=f"(r.json: {label}) ")
            for p in case.iterdir():
                if p.name not in ("r.json", d):
                    p.unlink()


# -- API inputs -----------------------------------------------------------------------------------

def api_inputs(tally) -> None:
    import pandas as pd

    cat = "API inputs"
    pts = ellipse()
    nrm = ipfit.estimate_normals(pts)
    poly = ipfit.fit_3l(pts, nrm, 2)
    masked_nan = np.ma.masked_invalid(np.vstack([pts, [np.nan, np.nan]]))
    inputs = {
        "a masked array with NaN under the mask": masked_nan,
        "a masked array without masked rows": np.ma.asarray(pts),
        "a DataFrame with x, y": pd.DataFrame(pts, columns=["x", "y"]),
        "a DataFrame with extra columns": pd.DataFrame({"x": pts[:, 0], "y": pts[:, 1], "label": "a", "w": 1.0}),
        "a DataFrame with object columns": pd.DataFrame({"x": pts[:, 0].astype(object), "y": list(map(str, pts[:, 1]))}),
        "a DataFrame without x, y": pd.DataFrame(pts, columns=["a", "b"]),
        "a bool array": pts > 0, "a generator": (row for row in pts.tolist()), "an np.matrix": np.asmatrix(pts),
        "a list of strings": [["1", "2"]] * 10, "a complex array": pts.astype(complex), "an object array":
            np.array([object()] * 20).reshape(10, 2), "a 3-d array": pts[None], "a scalar": 3.0, "None": None,
        "a dict": {"x": pts[:, 0], "y": pts[:, 1]}, "a pandas Series": pd.Series(pts[:, 0]),
    }
    calls = {
        "fit_3l(X, None, 2)": lambda x: ipfit.fit_3l(x, None, 2),
        "fit_lstsq(X, None, 2)": lambda x: ipfit.fit_lstsq(x, None, 2),
        "fit_adaptive(X, method='3l', max_degree=2)": lambda x: ipfit.fit_adaptive(x, method="3l", max_degree=2),
        "estimate_normals(X)": lambda x: ipfit.estimate_normals(x),
        "poly(X)": lambda x: poly(x), "poly.gradient(X)": lambda x: poly.gradient(x),
        "poly.contains(X)": lambda x: poly.contains(x),
        "quality(poly, X)": lambda x: ipfit.quality(poly, x),
    }
    for what, value in inputs.items():
        for label, call in calls.items():
            api_case(tally, cat, label.replace("X", f"<{what}>"), lambda call=call, value=value: call(value))


# -- optional packages ------------------------------------------------------------------------------

_BLOCKER = textwrap.dedent("""
    import sys
    blocked = set(sys.argv.pop(1).split(","))

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in blocked:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    sys.meta_path.insert(0, Blocker())
    from ipfit.cli import main
    sys.exit(main(sys.argv[1:]))
    """)


def optional_packages(tally, work: Path, result: Path) -> None:
    cat = "optional packages missing"
    case = work / "optional"
    case.mkdir()
    save_csv(case / "a.csv", ellipse())
    (case / "a.las").write_bytes(b"LASF" + bytes(400))
    (case / "a.pcd").write_text("VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                                "POINTS 1\nDATA ascii\n0 0 0\n")
    r = str(result)
    cases = [("dask,distributed", [*BATCH[:1], "a.csv", "-o", "out", *FAST]), ("plotly", ["view", r, "-o", "v.html"]),
             ("plotly", ["fit", "a.csv", "-o", "x", *FAST, "--html"]), ("laspy,lazrs", ["fit", "a.las", "-o", "l"]),
             ("pypcd4", ["fit", "a.pcd", "-o", "p"]), ("pyarrow", [*BATCH[:1], "a.csv", "-o", "out2", *FAST])]
    for blocked, argv in cases:
        proc = subprocess.Popen([sys.executable, "-c", _BLOCKER, blocked, *argv], cwd=case, env=_env(),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        code, err = finish(proc)
        problem = verdict(code, err, command=argv[0])
        needs_line = blocked != "pyarrow" and code == 2
        if problem is None and needs_line and "pip install 'ipfit[" not in err:
            problem = "no pip install 'ipfit[EXTRA]' line: " + err.strip()[:140]
        tally.add(cat, clean=True, foreign=problem, hang=code is None,
                  reproducer=f"without {blocked}: ipfit {' '.join(argv)}")

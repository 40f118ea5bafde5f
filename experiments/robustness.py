"""Try ipfit on bad input and faults, and write docs/robustness.md.

    PYTHONPATH=src python experiments/robustness.py [--fuzz 200] [--signals 12] [--json-values 12]
        [--kills 8] [--batch-signals 4] [--only STEP] [--out docs/robustness.md]

Categories: bad files x commands, bad options, output paths, corrupted result JSON (CLI and
API), API calls with bad arguments, fuzzing of every reader (truncations, bit flips, random
bytes, huge numbers, out-of-range indices), signals (real SIGINT/SIGTERM to real processes)
and write faults (ENOSPC/EROFS/EACCES injected into the atomic writer, plus real unwritable
paths); then the second, hostile-user campaign of ``robustness_hostile.py`` (batch outputs,
corrupted results on resume, batch Ctrl-C, concurrent and SIGKILLed runs on one prefix,
special files, resource bombs, result-JSON edge cases, API inputs, missing optional packages).
Per category it counts: cases, clean outcomes (success, or one line + exit 2 on the command
line / an IpfitError in the API), foreign exceptions or tracebacks, hangs, data lost, mixed
output sets, leftover temporary or partial files, and input or user files modified. The first
campaign's command-line cases run in-process through ``ipfit.cli.main`` (the same boundary as
the console script) except the signal cases; the second's run in subprocesses.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import errno
import hashlib
import io
import json
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [sys.path[0], os.environ.get("PYTHONPATH")]))  # its child processes too

import ipfit
from ipfit._utils import atomic as _atomic
from ipfit.cli import main
from ipfit.exceptions import IpfitError

import robustness_hostile as hostile

ROOT = Path(__file__).resolve().parents[1]
SRC = str(Path(ipfit.__file__).resolve().parents[1])
FAST = ["--degree", "2", "--method", "3l", "-q"]

def promise() -> str:
    """The README's "What every command promises" paragraph: the page quotes it, so one copy."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("### What every command promises", 1)[1].split("\n#", 1)[0]
    return section.split("[`docs/robustness.md`]", 1)[0].strip() + "\n"


# -- bookkeeping -------------------------------------------------------------------------------

class Tally:
    def __init__(self) -> None:
        self.rows: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
        self.foreign: dict[str, dict[str, list[str]]] = collections.defaultdict(dict)

    def add(self, category: str, *, clean: bool, foreign: str | None = None, reproducer: str = "",
            leftovers: int = 0, modified: int = 0, hang: bool = False, lost: int = 0, mixed: int = 0) -> None:
        row = self.rows[category]
        row["cases"] += 1
        row["clean"] += bool(clean and not foreign and not hang and not lost and not mixed)
        row["foreign"] += bool(foreign) and not hang
        row["hangs"] += bool(hang)
        row["lost"] += lost
        row["mixed"] += mixed
        row["leftovers"] += leftovers
        row["modified"] += modified
        if foreign:
            self.foreign[category].setdefault(foreign, []).append(reproducer)


def digest(paths) -> dict[str, str]:
    return {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths if Path(p).is_file()}


def hidden_files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*")]


def where(exc: BaseException) -> str:
    """``Type: message`` and the innermost ipfit frame (or the innermost frame)."""
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if "ipfit" in f.filename] or frames
    place = f" at {Path(ours[-1].filename).name}:{ours[-1].lineno}" if ours else ""
    return f"{type(exc).__name__}{place}: {str(exc).splitlines()[0][:120] if str(exc) else ''}"


def run_cli(argv: list[str], cwd: Path) -> tuple[int | None, str, BaseException | None]:
    """``main(argv)`` in ``cwd``: (exit code, stderr, exception that escaped main)."""
    err = io.StringIO()
    old = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 2
            except BaseException as exc:  # noqa: BLE001  an escape is exactly what is counted
                return None, err.getvalue(), exc
    finally:
        os.chdir(old)
    return code, err.getvalue(), None


def judge_cli(tally: Tally, category: str, argv: list[str], cwd: Path, inputs=(), allow_success=True,
              note: str = "") -> None:
    """Run one command-line case and count it."""
    before = digest(inputs)
    listing = set(os.listdir(cwd))
    code, err, exc = run_cli(argv, cwd)
    foreign = None
    if exc is not None:
        foreign = where(exc)
    elif "Traceback" in err or "Warning" in err and "warning:" not in err:
        foreign = "traceback or warning text: " + err.strip().splitlines()[-1][:120]
    elif code == 2:
        lines = err.strip().splitlines()
        command = argv[0] if argv and argv[0] in {"fit", "normals", "mesh", "plot", "score"} else ""
        ok = len([l for l in lines if "error:" in l]) == 1 and lines[-1].startswith(f"ipfit {command}".strip())
        if not ok:
            foreign = "not one error line: " + " | ".join(lines)[:160]
    elif code != 0 or not allow_success:
        foreign = f"exit {code}: {err.strip()[:120]}"
    leftovers = len(hidden_files(cwd))
    for p in hidden_files(cwd):
        with contextlib.suppress(OSError):
            p.unlink() if p.is_file() else shutil.rmtree(p)
    modified = sum(digest([k]).get(k) != v for k, v in before.items())
    tally.add(category, clean=True, foreign=foreign, reproducer=note + "ipfit " + " ".join(argv), leftovers=leftovers,
              modified=modified)
    for name in set(os.listdir(cwd)) - listing:  # keep the folder as it was for the next case
        p = cwd / name
        shutil.rmtree(p) if p.is_dir() else p.unlink()


def judge_api(tally: Tally, category: str, label: str, call) -> None:
    foreign = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            call()
    except IpfitError:
        pass
    except BaseException as exc:  # noqa: BLE001
        if isinstance(exc, KeyboardInterrupt):
            raise
        foreign = where(exc)
    tally.add(category, clean=True, foreign=foreign, reproducer=label)


# -- fixtures ----------------------------------------------------------------------------------

def heart(n: int = 60) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([16 * np.sin(t) ** 3, 13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)])


def make_seed_files(folder: Path) -> dict[str, Path]:
    """One small valid file per reader suffix."""
    import trimesh
    from PIL import Image, ImageDraw

    pts = heart()
    normals = ipfit.estimate_normals(pts)
    capsule = trimesh.creation.capsule(height=1.0, radius=0.5, count=[8, 8])
    files = {}
    for suffix in (".csv", ".xyz", ".txt", ".npy", ".npz"):
        files[suffix] = ipfit.write_points(folder / f"seed{suffix}", pts, normals)
    files[".ply"] = ipfit.write_points(folder / "seed.ply", capsule.vertices, capsule.vertex_normals, binary=False)
    files[".ply (binary)"] = ipfit.write_points(folder / "seedb.ply", capsule.vertices, capsule.vertex_normals)
    for suffix in (".obj", ".off", ".stl"):
        capsule.export(folder / f"seed{suffix}")
        files[suffix] = folder / f"seed{suffix}"
    image = Image.new("L", (64, 64), 0)
    ImageDraw.Draw(image).ellipse((12, 16, 52, 48), fill=255)
    image.save(folder / "seed.png")
    files[".png"] = folder / "seed.png"
    return files


# -- categories --------------------------------------------------------------------------------

def bad_files(tally: Tally, work: Path, result: Path) -> None:
    cases = {
        "empty.csv": b"", "text.csv": b"hello,world\nfoo,bar\n", "one.csv": b"1,2\n", "nan.csv": b"1,2\nnan,3\n4,5\n",
        "inf.xyz": b"1 2 3\ninf 1 1\n0 0 1\n1 1 1\n", "ragged.csv": b"1,2\n3\n4,5,6,7\n",
        "binary.ply": os.urandom(300), "header.ply": b"ply\nformat ascii 1.0\nelement vertex 5\nend_header\n1 2 3\n",
        "off6.off": b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 1e308 0\n3 0 1 2\n",
        "badidx.off": b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
        "garbage.obj": os.urandom(200), "garbage.stl": os.urandom(200), "garbage.png": os.urandom(200),
        "line.csv": "\n".join(f"{i},0" for i in range(40)).encode(),
        "big.csv": "\n".join(f"{1e200 * np.cos(t)},{1e200 * np.sin(t)}" for t in np.linspace(0, 6, 40)).encode(),
        "tiny.csv": "\n".join(f"{1e-200 * np.cos(t)},{1e-200 * np.sin(t)}" for t in np.linspace(0, 6, 40)).encode(),
        "complex.npy": None, "zeros.npy": None, "unknown.abc": b"1 2\n3 4\n", "missing.csv": None,
    }
    for name, content in cases.items():
        if name == "complex.npy":
            np.save(work / name, heart().astype(complex) * (1 + 1j))
        elif name == "zeros.npy":
            np.save(work / name, np.zeros((30, 2)))
        elif content is not None:
            (work / name).write_bytes(content)
    (work / "folder.csv").mkdir(exist_ok=True)
    names = list(cases) + ["folder.csv"]
    for name in names:
        inputs = [work / name]
        judge_cli(tally, "bad files × commands", ["fit", name, "-o", "o", *FAST, "--no-picture"], work, inputs)
        judge_cli(tally, "bad files × commands", ["normals", name, "-o", "o.ply"], work, inputs)
        judge_cli(tally, "bad files × commands", ["mesh", str(result), "--points", name, "-o", "o.svg"], work, inputs)
        judge_cli(tally, "bad files × commands", ["score", str(result), name], work, inputs)
        judge_cli(tally, "bad files × commands", ["plot", str(result), "--points", name, "-o", "o.png", "--dpi", "20",
                                                   "--resolution", "40"], work, inputs)
        judge_cli(tally, "bad files × commands", ["mesh", name, "-o", "o.svg"], work, inputs)


def bad_options(tally: Tally, work: Path, data: Path, result: Path) -> None:
    d, r = str(data), str(result)
    cases = [
        ["fit", d, "--degree", "x"], ["fit", d, "--degree", "-2"], ["fit", d, "--degree", "0"],
        ["fit", d, "--degree", "40"], ["fit", d, "--max-degree", "0"], ["fit", d, "--max-degree", "30"],
        ["fit", d, "--epsilon", "nan"], ["fit", d, "--epsilon", "inf"], ["fit", d, "--delta", "-1"],
        ["fit", d, "--far-weight", "-1"], ["fit", d, "--seed", "-1"], ["fit", d, "--seed", "x"],
        ["fit", d, "--iterations", "0"], ["fit", d, "--population", "0"], ["fit", d, "--method", "nope"],
        ["fit", d, "--rule", "nope"], ["fit", d, "--normals", "nope"], ["fit", d, "--bogus"], ["fit"],
        ["fit", d, "--method", "3l", "--iterations", "5"], ["fit", "nosuchdataset"], ["fit", "Boot"],
        ["normals", d, "-o", "n.ply", "--k", "0"], ["normals", d, "-o", "n.ply", "--k", "100000"],
        ["normals", d], ["normals", d, "-o", "n.abc"],
        ["mesh", r, "-o", "m.svg", "--degree", "7"], ["mesh", r, "-o", "m.svg", "--resolution", "0"],
        ["mesh", r, "-o", "m.svg", "--margin", "-1"], ["mesh", r, "-o", "m.svg", "--resolution", "1"],
        ["mesh", r, "-o", "m.ply"], ["plot", r, "-o", "p.png", "--dpi", "0"], ["plot", r, "-o", "p.xyz"],
        ["plot", r, "-o", "p"], ["plot", r, "-o", "p.png", "--view", "a", "b"], ["plot", r, "-o", "p.png", "--up", "w"],
        ["score", r, d, "--tau", "0"], ["score", r, d, "--tau", "-1"], ["score", r, d, "--tau-fraction", "0"],
        ["score", r, d, "--tau", "1", "--tau-fraction", "0.1"], ["score", r, d, "--write", "--degree", "2"],
        ["score", r, d, "--contour", "maybe"], ["datasets", "--bogus"], ["reproduce", "--bogus"], ["nosuchcommand"],
        ["--bogus"],
    ]
    for argv in cases:
        judge_cli(tally, "bad options", argv, work, [data, result])


def output_paths(tally: Tally, work: Path, data: Path, result: Path) -> None:
    (work / "dir.json").mkdir(exist_ok=True)
    for name in ("dir.ply", "dir.svg", "dir.png"):
        (work / name).mkdir(exist_ok=True)
    d, r = data.name, str(result)
    cases = [
        ["fit", d, "-o", "dir", *FAST], ["fit", d, "-o", "dir.json", *FAST], ["fit", d, "-o", d, *FAST],
        ["fit", d, "-o", data.stem, *FAST], ["fit", d, "-o", f"{d}/x", *FAST], ["fit", d, "-o", "/proc/x", *FAST],
        ["fit", d, "-o", "/proc/self/x/y", *FAST], ["fit", d, "-o", "/sys/x", *FAST], ["fit", d, *FAST],
        ["normals", d, "-o", "dir.ply"], ["normals", d, "-o", d], ["normals", d, "-o", f"{d}/x.ply"],
        ["normals", d, "-o", "/proc/x.ply"], ["normals", d, "-o", "nofolder/x.ply"],
        ["mesh", r, "-o", "dir.svg"], ["mesh", r, "-o", d], ["mesh", r, "-o", f"{d}/x.svg"], ["mesh", r, "-o", "/proc/x.svg"],
        ["mesh", r, "-o", r.replace(".json", ".csv")],
        ["plot", r, "-o", "dir.png"], ["plot", r, "-o", f"{d}/x.png"], ["plot", r, "-o", "/proc/x.png"],
        ["plot", r, "-o", "p.xyz"], ["score", r, d, "--write"],
    ]
    for argv in cases:
        judge_cli(tally, "output paths", argv, work, [data, result])


def corrupted_results(tally: Tally, work: Path, data: Path, result: Path, n_values: int) -> None:
    base = json.loads(result.read_text())
    values = [None, 5, -1, "x", [1, 2], {}, [], float("nan"), float("inf"), 1e308, [[1e308, 1]], True][:n_values]
    keys = sorted(base) + ["normalization.center", "normalization.scale", "degrees.0.degree", "degrees.0.coefficients",
                           "input.source"]

    def mutate(key: str, value):
        doc = json.loads(json.dumps(base))
        target, parts = doc, key.split(".")
        for part in parts[:-1]:
            target = target[int(part)] if isinstance(target, list) else target.get(part, {})
        if isinstance(target, list):
            target[int(parts[-1])] = value
        elif isinstance(target, dict):
            target[parts[-1]] = value
        return doc

    for key in keys:
        for value in values + ["<deleted>"]:
            doc = mutate(key, value) if value != "<deleted>" else {k: v for k, v in base.items() if k != key}
            path = work / "bad.json"
            path.write_text(json.dumps(doc))
            label = f"{key} = {value!r}"
            judge_api(tally, "corrupted result JSON (API)", f"ImplicitPolynomial.from_dict(<result with {label}>)",
                      lambda: ipfit.ImplicitPolynomial.from_dict(json.loads(path.read_text())))
            note = f"bad.json = a result with {label}: "
            judge_cli(tally, "corrupted result JSON (CLI)", ["mesh", "bad.json", "-o", "m.svg", "--resolution", "64"],
                      work, [path, data], note=note)
            judge_cli(tally, "corrupted result JSON (CLI)", ["score", "bad.json", data.name, "--resolution", "64"],
                      work, [path, data], note=note)
    judge_api(tally, "corrupted result JSON (API)", "ImplicitPolynomial.from_json(None)",
              lambda: ipfit.ImplicitPolynomial.from_json(None))


def api_calls(tally: Tally, work: Path) -> None:
    pts = heart()
    nrm = ipfit.estimate_normals(pts)
    poly = ipfit.fit_3l(pts, nrm, 2)
    cases = {
        "read_points(None)": lambda: ipfit.read_points(None),
        "read_points(5)": lambda: ipfit.read_points(5),
        "read_points('')": lambda: ipfit.read_points(""),
        "read_points(<folder>)": lambda: ipfit.read_points(work),
        "estimate_normals(pts, workers=0)": lambda: ipfit.estimate_normals(pts, workers=0),
        "estimate_normals(pts, k=0)": lambda: ipfit.estimate_normals(pts, k=0),
        "estimate_normals(pts, k=10**6)": lambda: ipfit.estimate_normals(pts, k=10 ** 6),
        "estimate_normals('x')": lambda: ipfit.estimate_normals("x"),
        "estimate_normals(pts * 1e200)": lambda: ipfit.estimate_normals(pts * 1e200),
        "fit_3l(pts, nrm, 2, c=1e300)": lambda: ipfit.fit_3l(pts, nrm, 2, c=1e300),
        "fit_3l(pts, nrm, -2)": lambda: ipfit.fit_3l(pts, nrm, -2),
        "fit_3l(pts, nrm[:5], 2)": lambda: ipfit.fit_3l(pts, nrm[:5], 2),
        "fit_3l(pts[:3], nrm[:3], 8)": lambda: ipfit.fit_3l(pts[:3], nrm[:3], 8),
        "fit_adaptive(pts, nrm, options=RECOMMENDED.replace(dtype='x'))":
            lambda: ipfit.fit_adaptive(pts, nrm, options=ipfit.RECOMMENDED.replace(dtype="x")),
        "fit_adaptive(pts, nrm, progress=5)": lambda: ipfit.fit_adaptive(pts, nrm, method="3l", progress=5),
        "fit_adaptive(pts, nrm, method='x')": lambda: ipfit.fit_adaptive(pts, nrm, method="x"),
        "fit_adaptive(pts, nrm, rng=-1)": lambda: ipfit.fit_adaptive(pts, nrm, method="3l", rng=-1),
        "fit_lstsq(pts, degree=2.5)": lambda: ipfit.fit_lstsq(pts, degree=2.5),
        "extract_zero_set(poly, resolution=0)": lambda: ipfit.extract_zero_set(poly, resolution=0),
        "extract_zero_set(poly, bounds='x')": lambda: ipfit.extract_zero_set(poly, bounds="x"),
        "extract_zero_set('x')": lambda: ipfit.extract_zero_set("x"),
        "quality(poly, pts, tau=-1)": lambda: ipfit.quality(poly, pts, tau=-1),
        "quality(poly, pts[:, :1])": lambda: ipfit.quality(poly, pts[:, :1]),
        "write_points(<folder>, pts)": lambda: ipfit.write_points(work, pts),
        "write_points('x.abc', pts)": lambda: ipfit.write_points(work / "x.abc", pts),
        "ImplicitPolynomial.from_json('{')": lambda: ipfit.ImplicitPolynomial.from_json("{"),
        "ImplicitPolynomial.load(<missing>)": lambda: ipfit.ImplicitPolynomial.load(work / "missing.json"),
        "poly(pts[:, :1])": lambda: poly(pts[:, :1]),
        "load_dataset('nope')": lambda: ipfit.load_dataset("nope"),
        "refine(pts, nrm, degree=2, method='x')": lambda: ipfit.refine(pts, nrm, degree=2, method="x"),
    }
    for label, call in cases.items():
        judge_api(tally, "API calls", label, call)
    for p in work.glob("x.*"):
        p.unlink()


def _mutations(data: bytes, rng: random.Random) -> tuple[str, bytes]:
    kind = rng.choice(["truncate", "bitflip", "random", "huge", "index", "dupline", "dropline"])
    b = bytearray(data)
    if kind == "truncate":
        return kind, bytes(b[:rng.randrange(len(b) + 1)])
    if kind == "bitflip":
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
        return kind, bytes(b)
    if kind == "random":
        return kind, bytes(rng.randrange(256) for _ in range(rng.randint(0, 400)))
    lines = bytes(b).split(b"\n")
    i = rng.randrange(len(lines))
    if kind in ("huge", "index"):
        words = lines[i].split()
        token = (rng.choice([b"1e308", b"-1e308", b"1e400", b"nan", b"inf", b"1e-320", b"1e155"]) if kind == "huge"
                 else rng.choice([b"99999999", b"-1", b"4294967296", b"3", b"0"]))
        if words:
            words[rng.randrange(len(words))] = token
            lines[i] = b" ".join(words)
        return kind, b"\n".join(lines)
    if kind == "dupline":
        lines.insert(i, lines[i])
    else:
        del lines[i]
    return kind, b"\n".join(lines)


class _Timeout(Exception):
    pass


def fuzz(tally: Tally, work: Path, seeds: dict[str, Path], per_format: int, seed: int) -> None:
    rng = random.Random(seed)

    def alarm(signum, frame):
        raise _Timeout

    previous = signal.signal(signal.SIGALRM, alarm)
    try:
        for label, path in seeds.items():
            data = path.read_bytes()
            target = work / f"fuzz{path.suffix}"
            for case in range(per_format):
                kind, mutated = _mutations(data, rng)
                target.write_bytes(mutated)
                foreign = None
                signal.alarm(10)
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        ipfit.read_points(target)
                        ipfit.read_mesh(target)
                except IpfitError:
                    pass
                except _Timeout:
                    foreign = "no answer within 10 s"
                except BaseException as exc:  # noqa: BLE001
                    if isinstance(exc, KeyboardInterrupt):
                        raise
                    foreign = where(exc)
                finally:
                    signal.alarm(0)
                keep = None
                if foreign:
                    keep = work / "fuzz-found" / f"{label.replace(' ', '_').strip('.')}-{case}{path.suffix}"
                    keep.parent.mkdir(exist_ok=True)
                    keep.write_bytes(mutated)
                tally.add(f"fuzzing {label}", clean=True, foreign=foreign,
                          reproducer=f"read_points/read_mesh({keep}) ({kind} of {path.name})" if keep else "")
    finally:
        signal.signal(signal.SIGALRM, previous)


def signals(tally: Tally, work: Path, data: Path, n: int, seed: int) -> None:
    rng = random.Random(seed)
    env = {**os.environ, "PYTHONPATH": SRC}
    expected = {"r.csv", "r.json", "r.png", "r.svg"}
    for case in range(n):
        folder = work / f"sig{case}"
        folder.mkdir()
        shutil.copy(data, folder / data.name)
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        slow_write, long_fit = case % 4 == 2, case % 4 == 3
        delay = rng.uniform(0.0, 8.0 if long_fit else 4.0)
        extra = {"IPFIT_TEST_WRITE_DELAY": "0.4"} if slow_write else {}
        argv = (["fit", data.name, "-o", "r", "--method", "de", "--iterations", "300", "--max-degree", "4"] if long_fit
                else ["fit", data.name, "-o", "r", "--degree", "2", "--method", "3l"])
        proc = subprocess.Popen([sys.executable, "-m", "ipfit.cli", *argv], cwd=folder, env={**env, **extra},
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=300)
        code = proc.returncode
        names = {p.name for p in folder.iterdir()} - {data.name}
        hidden = {n for n in names if n.startswith(".")}
        foreign = None
        if "Traceback" in err and "ipfit" in err:
            foreign = "traceback: " + err.strip().splitlines()[-1]
        elif code not in (0, 128 + sig, -sig) and not ("Traceback" in err and "ipfit" not in err):
            foreign = f"exit {code}: {err.strip()[-120:]}"
        elif names - hidden not in (set(), expected):
            foreign = f"partial output {sorted(names)}"
        repro = (f"{'IPFIT_TEST_WRITE_DELAY=0.4 ' if slow_write else ''}ipfit {' '.join(argv)} & sleep {delay:.2f}; "
                 f"kill -{signal.Signals(sig).name[3:]} $!")
        tally.add("signals", clean=True, foreign=foreign, reproducer=repro, leftovers=len(hidden),
                  modified=int((folder / data.name).read_bytes() != data.read_bytes()))
        shutil.rmtree(folder)


def write_faults(tally: Tally, work: Path, data: Path, result: Path) -> None:
    real_fsync, real_publish = _atomic.os.fsync, _atomic.publish
    commands = [["fit", data.name, "-o", "w", *FAST], ["normals", data.name, "-o", "w.ply"],
                ["mesh", str(result), "-o", "w.svg"], ["plot", str(result), "-o", "w.png", "--dpi", "20"],
                ["score", str(result), data.name, "--write"]]
    for code in (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EIO):
        for phase in ("reserve", "write"):
            for argv in commands:
                def fsync(fd, code=code):
                    raise OSError(code, os.strerror(code))

                def publish(tmp, target, code=code):
                    if Path(target).name.startswith("."):  # a writer's own rename onto the staged file
                        raise OSError(code, os.strerror(code), str(tmp))
                    real_publish(tmp, target)

                if phase == "reserve":
                    _atomic.os.fsync = fsync
                else:
                    _atomic.publish = publish
                try:
                    judge_cli(tally, "write faults", argv, work, [data, result], allow_success=argv[0] == "score"
                              and phase == "write")
                finally:
                    _atomic.os.fsync, _atomic.publish = real_fsync, real_publish


# -- report -----------------------------------------------------------------------------------

def processor() -> str:
    """The processor's model name (BLAS kernels, and so the last bits of results, depend on it)."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.machine()


def render(tally: Tally, seconds: float, args) -> str:
    columns = ("cases", "clean", "foreign", "hangs", "lost", "mixed", "leftovers", "modified")
    header = ("| category | cases | clean | foreign exceptions / tracebacks | hangs | data lost | mixed output sets | "
              "leftover or partial files | inputs or user files modified |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    rows, total = [], collections.Counter()
    for category, row in tally.rows.items():
        rows.append(f"| {category} | " + " | ".join(f"{row[c]:,}" for c in columns) + " |")
        total.update(row)
    rows.append("| **total** | " + " | ".join(f"**{total[c]:,}**" for c in columns) + " |")
    found = []
    for category, groups in tally.foreign.items():
        for what, repros in sorted(groups.items(), key=lambda kv: -len(kv[1])):
            found.append(f"- **{category}** ({len(repros)}×) `{what}`  \n  e.g. `{repros[0]}`")
    return "\n".join([
        "# Robustness", "", promise(),
        f"Generated by `experiments/robustness.py --fuzz {args.fuzz} --signals {args.signals} "
        f"--json-values {args.json_values} --kills {args.kills} --batch-signals {args.batch_signals} "
        f"--seed {args.seed}` in {seconds:.0f} s on {processor()}; rerun it after "
        "changes.",
        "", "*Clean* means the case ended as promised: success, or one line + exit 2 on the command line "
        "(an `IpfitError` in the API, with no foreign warning). The categories from *batch outputs* on are "
        "the second campaign (`experiments/robustness_hostile.py`): each runs in a real subprocess with a "
        f"{hostile.LIMIT} s limit, so a *hang* is counted and killed; *data lost* counts shapes without their "
        "summary row or finished result; *mixed output sets* counts a prefix whose JSON and zero-set CSV "
        "come from different runs (after the next run, for the killed ones). Leftovers are temporary files "
        "found after the case; inputs or user files modified compares their bytes before and after.",
        "", header, *rows, "",
        "## Foreign exceptions, tracebacks and hangs found", "",
        *(found or ["None."]), "",
    ])


def cli() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fuzz", type=int, default=200, help="mutated files per reader format (default 200)")
    parser.add_argument("--signals", type=int, default=12, help="signal cases (real processes; default 12)")
    parser.add_argument("--json-values", type=int, default=12, help="bad values tried per result-JSON key (max 12)")
    parser.add_argument("--kills", type=int, default=8, help="SIGKILLs while publishing (default 8)")
    parser.add_argument("--batch-signals", type=int, default=4, help="Ctrl-C cases of a batch (default 4)")
    parser.add_argument("--only", help="run only the steps whose name contains this (a quick look)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "robustness.md")
    args = parser.parse_args()
    start = time.perf_counter()
    tally = Tally()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        data = work / "heart.csv"
        np.savetxt(data, heart(), delimiter=",", header="x,y", comments="")
        assert main(["fit", str(data), "-o", str(work / "res"), *FAST, "--no-picture", "--no-zero-set"]) == 0
        result = work / "res.json"
        seeds_dir = work / "seeds"
        seeds_dir.mkdir()
        steps = [
            ("bad files", lambda: bad_files(tally, work, result)),
            ("bad options", lambda: bad_options(tally, work, data, result)),
            ("output paths", lambda: output_paths(tally, work, data, result)),
            ("corrupted results", lambda: corrupted_results(tally, work, data, result, args.json_values)),
            ("API calls", lambda: api_calls(tally, work)),
            ("fuzzing", lambda: fuzz(tally, work, make_seed_files(seeds_dir), args.fuzz, args.seed)),
            ("write faults", lambda: write_faults(tally, work, data, result)),
            ("signals", lambda: signals(tally, work, data, args.signals, args.seed)),
            ("batch outputs", lambda: hostile.batch_outputs(tally, work)),
            ("batch Ctrl-C", lambda: hostile.batch_signals(tally, work, args.batch_signals)),
            ("one prefix", lambda: hostile.publishing(tally, work, args.kills, args.seed)),
            ("special files", lambda: hostile.special_files(tally, work, result)),
            ("resource bombs", lambda: hostile.resources(tally, work, result)),
            ("result JSON edge cases", lambda: hostile.result_edges(tally, work, result, data)),
            ("API inputs", lambda: hostile.api_inputs(tally)),
            ("optional packages", lambda: hostile.optional_packages(tally, work, result)),
        ]
        for name, step in steps:
            if args.only and args.only not in name:
                continue
            t0 = time.perf_counter()
            step()
            print(f"{name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        found = work / "fuzz-found"
        if found.exists():
            keep = ROOT / "experiments" / "robustness-found"
            shutil.rmtree(keep, ignore_errors=True)
            shutil.copytree(found, keep)
    text = render(tally, time.perf_counter() - start, args)
    args.out.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    cli()

"""Real clouds (issue 30): today's pipeline, outlier removal then fit, and the robust fit, on corrupted shapes.

Usage::

    python experiments/robust.py [--shapes DIR|FILE|NAME|bundled ...] [--every K] [--limit N]
                                 [--pipelines today sor robust mesh] [--conditions clean noise-1 ...]
                                 [--samples N] [--jobs 2] [--seed 0] [--out docs/robust.md]
                                 [--resume [--redo]] [--page-only]

Every shape (a 2D contour CSV or a 3D mesh in a folder of ``--shapes``, a file, a bundled
dataset's name, or ``bundled`` for the six bundled datasets) is turned into a real-cloud version
by the protocol of issue 30, exactly as ``../shared/tools/corrupt.py`` does (same reader, same
seed from the file name and the settings, same points: checked against that script at the start
of each run): points only, no normals, shuffled; Gaussian noise of σ = 0.5% or 1% of the box
diagonal, or 10%, 25% or 40% of the point count as outliers uniform in the box grown by 20% on each
side. Each pipeline fits the corrupted cloud:

* **today**: ``fit_adaptive(points)``, normals estimated (``outliers="none"`` once the API has it);
* **sor**: Open3D's statistical outlier removal (k = 20 neighbours, mean + 2 standard deviations),
  then ``fit_adaptive`` on the points kept;
* **robust**: ``fit_adaptive(points, outliers="auto")``, skipped while the API has no ``outliers=``;
* **mesh**, the reference the issue measures bare clouds against ("as good as meshes"): a 3D shape's
  clean mesh itself, ``fit_adaptive(ipfit.load(FILE))`` (``ipfit fit MESH``: its vertices with their
  normals and faces), under the clean condition only.

Each fit is scored against the *clean* shape with :func:`ipfit.zeroset.quality.quality` (τ = 2% of the
box diagonal; a 2D contour's segments, a mesh's faces): F-score, spurious components, selected
degree; with the fit's seconds and the share of points each pipeline treated as outliers against
the planted share. ``--samples N`` draws each 3D mesh's surface at N points
(``trimesh.sample.sample_surface``, seed 0) in place of its vertices before the same corruption, a
dense scan of the object (scored against the same faces; 2D shapes keep their points).
Worker processes (``--jobs``) with one thread each run the cases; each first
fits a small circle and sphere, so that no timed fit pays for numba's compilation. The rows go to
``--out``'s ``.json`` twin as they finish (``--resume`` keeps those and runs the rest);
``--resume --redo`` fits the command's cases (its shapes under its conditions, by its pipelines)
again and replaces their stored rows (after a change that affects only them); ``--page-only``
rewrites the Markdown from that JSON alone.

The default run (140 + 12 + 6 shapes, 6 conditions, 3 pipelines and the meshes' own fits: about 2,800 fits of 5-40 s)
takes hours on 2 cores; ``--every 5`` takes a fifth of each folder, for a quicker look.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from datetime import date
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# this checkout's ipfit, in the spawned workers too (they import this module first): an ipfit
# installed from another checkout would otherwise be measured under this one's commit
sys.path.insert(0, str(ROOT / "src"))
SHARED = ROOT.parent / "shared"
DEFAULT_SHAPES = (str(SHARED / "data" / "mpeg7-dev"), str(SHARED / "data" / "turk-dev"), "bundled")
CORRUPT_PY = SHARED / "tools" / "corrupt.py"
BUNDLED = ("boot", "airplane", "butterfly", "bunny", "apple", "duck")
MESH_SUFFIXES = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")

# name -> (noise σ as a fraction of the box diagonal, outliers as a fraction of the point count);
# the floats are written into the seed exactly as corrupt.py's argparse floats are.
CONDITIONS = {
    "clean": (0.0, 0.0),
    "noise-0.5": (0.005, 0.0),
    "noise-1": (0.01, 0.0),
    "outliers-10": (0.0, 0.1),
    "outliers-25": (0.0, 0.25),
    "outliers-40": (0.0, 0.4),
}
LABELS = {"clean": "clean", "noise-0.5": "noise σ 0.5%", "noise-1": "noise σ 1%", "outliers-10": "10% outliers",
          "outliers-25": "25% outliers", "outliers-40": "40% outliers"}
PIPELINES = ("today", "sor", "robust", "mesh")
# a bare cloud is as good as its mesh when its F-score is at most this much below the mesh fit's
AS_GOOD = 0.03
SOR_NEIGHBOURS, SOR_STD_RATIO = 20, 2.0


# --- the shapes and their corruption (corrupt.py's rule) ---------------------------------------------------------

def shape_specs(entries: list[str], every: int = 1, limit: int | None = None) -> list[tuple[str, str]]:
    """(id, path) of every shape ``entries`` name; a folder's files sorted, then every ``every``-th,
    then the first ``limit`` (and the same for ``bundled``'s list). The id is "folder/stem"
    (turk-dev's airplane is not the bundled airplane)."""
    from ipfit.datasets import bundled

    specs = []
    for entry in entries:
        path = Path(entry)
        if path.is_dir():
            files = sorted(p for p in path.iterdir() if p.suffix.lower() in (".csv", *MESH_SUFFIXES))
            found = [(f"{path.name}/{p.stem}", str(p)) for p in files]
        elif path.is_file():
            found = [(f"{path.parent.name}/{path.stem}", str(path))]
        else:
            names = BUNDLED if entry == "bundled" else [entry]
            found = []
            for name in names:
                key = bundled.resolve_name(name)
                if key is None:
                    raise SystemExit(f"--shapes: {entry!r} is neither a folder, a file, 'bundled' nor a dataset "
                                     f"name ({', '.join(bundled.dataset_names())})")
                # the bundled file itself: corrupt.py can be run on it and gives the same cloud
                found.append((f"bundled/{key}", str(bundled.dataset_path(key))))
        specs += found[::every][:limit]
    return specs


def read_clean(path: str):
    """(points, faces or None) read as corrupt.py reads them: a CSV's x,y rows, or trimesh's
    processed vertices (``ipfit.load`` merges duplicated positions and keeps unreferenced
    vertices, so its points differ on some meshes; the clouds must be corrupt.py's)."""
    if path.endswith(".csv"):
        with open(path) as handle:
            rows = [line.split(",")[:2] for line in handle
                    if line.strip() and not line.startswith("#") and not line.startswith("x")]
        return np.array(rows, float), None
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=True)
    faces = np.asarray(mesh.faces, np.int64) if len(mesh.faces) else None
    return np.asarray(mesh.vertices, float), faces


def corrupt(points, file_name: str, noise: float, outliers: float):
    """corrupt.py's cloud of ``points`` (read from ``file_name``) and which of its points are planted
    outliers. The coordinates go through corrupt.py's ``%.9g`` text, so that they are the very
    floats a reader of its output file gets."""
    x = np.asarray(points, float)
    rng = np.random.default_rng([ord(c) for c in f"{os.path.basename(file_name)}|{noise}|{outliers}"])
    diag = np.linalg.norm(x.max(0) - x.min(0))
    # drawn even for σ = 0: the draw advances the generator, and the outliers and the order depend on it
    y = x + rng.normal(scale=noise * diag, size=x.shape)
    planted = np.zeros(len(y), bool)
    if outliers:
        lo, hi = x.min(0), x.max(0)
        ext = hi - lo
        far = rng.uniform(lo - 0.2 * ext, hi + 0.2 * ext, size=(int(outliers * len(x)), x.shape[1]))
        y = np.vstack([y, far])
        planted = np.concatenate([planted, np.ones(len(far), bool)])
    order = rng.permutation(len(y))
    return np.char.mod("%.9g", y[order]).astype(float), planted[order]


def check_corrupt_py(specs: list[tuple[str, str]], script: Path = CORRUPT_PY) -> str:
    """Run corrupt.py on the first 2D and the first 3D shape (noise 1%, then 25% outliers) and
    require the very points :func:`corrupt` gives; returns the sentence the page prints."""
    if not script.exists():
        return f"not checked against corrupt.py ({script} not found)"
    picks = {}
    for _, path in specs:
        picks.setdefault(path.endswith(".csv"), path)
    checked = []
    with tempfile.TemporaryDirectory() as folder:
        for path in picks.values():
            for noise, outliers in (CONDITIONS["noise-1"], CONDITIONS["outliers-25"]):
                out = Path(folder) / "cloud.xyz"
                subprocess.run([sys.executable, str(script), path, str(out), "--noise", str(noise),
                                "--outliers", str(outliers)], check=True)
                theirs = np.loadtxt(out)
                mine = corrupt(read_clean(path)[0], path, noise, outliers)[0]
                if mine.shape != theirs.shape or not np.array_equal(mine, theirs):
                    raise SystemExit(f"corrupt.py and experiments/robust.py give different points for {path} "
                                     f"(noise {noise}, outliers {outliers})")
                checked.append(f"{Path(path).name} ({noise}, {outliers})")
    return "the same points as `corrupt.py` on " + ", ".join(checked)


# --- the pipelines -----------------------------------------------------------------------------------------------

def statistical_outlier_removal(points, neighbours: int = SOR_NEIGHBOURS, std_ratio: float = SOR_STD_RATIO):
    """Which points Open3D's ``remove_statistical_outlier(neighbours, std_ratio)`` keeps.

    Open3D's definition (``PointCloud::RemoveStatisticalOutliers``): a point's mean distance to its
    ``neighbours`` nearest points, the point itself among them; kept when that mean is positive
    and below the mean of the positive means + ``std_ratio`` × their standard deviation (Bessel's
    correction). In 2D the same on the plane (Open3D's points would have z = 0).
    """
    from scipy.spatial import cKDTree

    x = np.asarray(points, float)
    d, _ = cKDTree(x).query(x, k=min(neighbours, len(x)))
    mean = d.mean(axis=1)
    positive = mean > 0
    # Open3D sums the positive means but divides by the count of all points that have neighbours
    centre = mean[positive].sum() / len(mean)
    spread = np.sqrt(np.sum((mean[positive] - centre) ** 2) / (len(mean) - 1))
    return positive & (mean < centre + std_ratio * spread)


def check_open3d(points) -> str:
    """Compare :func:`statistical_outlier_removal` with Open3D's on one cloud, when Open3D is installed."""
    try:
        import open3d
    except ImportError:
        return "Open3D is not installed here: not compared with its remove_statistical_outlier"
    x = np.asarray(points, float)
    cloud = open3d.geometry.PointCloud()
    cloud.points = open3d.utility.Vector3dVector(np.column_stack([x, np.zeros((len(x), 3 - x.shape[1]))]))
    _, kept = cloud.remove_statistical_outlier(nb_neighbors=SOR_NEIGHBOURS, std_ratio=SOR_STD_RATIO)
    theirs = np.zeros(len(x), bool)
    theirs[np.asarray(kept, int)] = True
    mine = statistical_outlier_removal(x)
    differ = int(np.sum(mine != theirs))
    if differ:
        raise SystemExit(f"statistical_outlier_removal differs from Open3D's on {differ} of {len(x)} points")
    return f"the same points kept as Open3D {open3d.__version__}'s remove_statistical_outlier on a {len(x)}-point cloud"


def _outlier_keyword() -> bool:
    from ipfit import fit_adaptive

    return "outliers" in inspect.signature(fit_adaptive).parameters


def today(points, dim: int, seed: int = 0):
    """``ipfit fit FILE`` on a bare cloud: the recommended pipeline, normals estimated."""
    from ipfit import fit_adaptive

    return fit_adaptive(points, rng=seed, **({"outliers": "none"} if _outlier_keyword() else {}))


def sor(points, dim: int, seed: int = 0):
    """The usual work-around: statistical outlier removal, then today's pipeline on what is kept."""
    return today(np.asarray(points)[statistical_outlier_removal(points)], dim, seed)


def robust(points, dim: int, seed: int = 0):
    """The robust pipeline of issue 30: ``fit_adaptive(points, outliers="auto")``."""
    from ipfit import fit_adaptive

    return fit_adaptive(points, rng=seed, outliers="auto")


def treated_as_outliers(pipeline: str, points, result):
    """(mask of the points the pipeline set aside or None, noise scale or None): the robust fit
    records them in ``result.outliers`` (an :class:`ipfit.OutlierScore`)."""
    if pipeline == "sor":
        return ~statistical_outlier_removal(points), None
    found = getattr(result, "outliers", None)
    if pipeline != "robust" or found is None:
        return None, None
    return ~np.asarray(found.inliers), float(found.noise_scale)


def mesh(path: str, seed: int = 0):
    """``ipfit fit MESH`` on the clean mesh: its vertices, their normals and its faces."""
    from ipfit import fit_adaptive, load

    return fit_adaptive(load(path), rng=seed)


def runs(pipeline: str, path: str, condition: str) -> bool:
    """Whether ``pipeline`` has a row for the shape at ``path`` under ``condition``: the mesh
    reference only for a clean 3D mesh."""
    return pipeline != "mesh" or (condition == "clean" and Path(path).suffix.lower() in MESH_SUFFIXES)


# the pipelines of a corrupted cloud; the mesh reference fits the file (run_case)
FUNCTIONS = {"today": today, "sor": sor, "robust": robust}


# --- one case: a shape under one condition, every pipeline -------------------------------------------------------

def surface_samples(vertices, faces, count: int):
    """``count`` points uniform on the mesh's surface (trimesh's sampler, seed 0)."""
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return np.asarray(trimesh.sample.sample_surface(mesh, count, seed=0)[0], float)


def run_case(shape: str, path: str, condition: str, pipelines: tuple[str, ...], seed: int,
             samples: int | None = None) -> list[dict]:
    """The rows of every pipeline on ``shape`` corrupted by ``condition``, scored on the clean shape
    (a 3D mesh's surface drawn at ``samples`` points first, when given)."""
    from _versions import spurious_record

    from ipfit.zeroset.quality import looks_like_contour, quality

    clean, faces = read_clean(path)
    noise, outliers = CONDITIONS[condition]
    drawn = surface_samples(clean, faces, samples) if samples and faces is not None else clean
    points, planted = corrupt(drawn, path, noise, outliers)
    dim = clean.shape[1]
    contour = dim == 2 and looks_like_contour(clean)
    rows = []
    for pipeline in (p for p in pipelines if runs(p, path, condition) and (p != "mesh" or faces is not None)):
        row = {"shape": shape, "dim": dim, "condition": condition, "noise": noise, "outliers": outliers,
               "pipeline": pipeline, "n_clean": len(drawn), "n": len(points), "n_planted": int(planted.sum()),
               "reference": "faces" if faces is not None else "contour" if contour else "points"}
        start = time.perf_counter()
        try:
            result = mesh(path, seed) if pipeline == "mesh" else FUNCTIONS[pipeline](points, dim, seed)
        except Exception as exc:  # noqa: BLE001 - a failed fit is a result of the experiment, kept in its row
            rows.append({**row, "status": "error", "error": f"{type(exc).__name__}: {exc}"[:300],
                         "seconds": time.perf_counter() - start})
            continue
        seconds = time.perf_counter() - start
        start = time.perf_counter()
        q = quality(result.polynomial, clean, faces=faces, ordered_contour=contour)
        flagged, noise_scale = treated_as_outliers(pipeline, points, result)
        row.update({"status": "ok", "degree": result.selected_degree, "reason": result.reason,
                    "degrees_tried": [d.degree for d in result.degrees], "f_score": q.f_score,
                    "precision": q.precision, "recall": q.recall, "n_spurious": q.n_spurious,
                    "closed": bool(q.closed), **spurious_record(q), "seconds": seconds,
                    "seconds_score": time.perf_counter() - start, "noise_scale": noise_scale})
        if flagged is None and pipeline == "robust" and getattr(result, "outlier_share", None) is not None:
            row["share_found"] = float(result.outlier_share)  # a share without a per-point mask
        elif flagged is not None:
            row.update({"share_found": float(flagged.mean()),
                        "detected": float(flagged[planted].mean()) if planted.any() else None,
                        "false_alarms": float(flagged[~planted].mean())})
        rows.append(row)
    return rows


def _start_worker() -> None:
    from _versions import start_worker

    start_worker(None)


def run(specs, conditions, pipelines, seed: int, jobs: int, json_path: Path, meta: dict, done: list[dict],
        samples: int | None = None) -> list:
    """Every case not in ``done``, largest shapes first (so that the workers end together); the
    JSON is rewritten after each case, so that an interrupted run can ``--resume``."""
    import multiprocessing

    have = {(r["shape"], r["condition"], r["pipeline"]) for r in done}
    cases = [(shape, path, c, tuple(p for p in pipelines if (shape, c, p) not in have and runs(p, path, c)))
             for shape, path in specs for c in conditions]
    cases = sorted((case for case in cases if case[3]), key=lambda case: -os.path.getsize(case[1]))
    rows = list(done)
    # inherited by the spawned workers before they import numpy: one BLAS and numba thread each
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[name] = "1"
    with ProcessPoolExecutor(jobs, multiprocessing.get_context("spawn"), initializer=_start_worker) as pool:
        futures = [pool.submit(run_case, *case, seed, samples) for case in cases]
        for k, future in enumerate(as_completed(futures), 1):
            for row in future.result():
                rows.append(row)
                print(f"[{k}/{len(cases)}] " + json.dumps({key: row.get(key) for key in (
                    "shape", "condition", "pipeline", "status", "degree", "f_score", "n_spurious", "seconds")}),
                      flush=True)
            write_json(json_path, meta, rows)
    return rows


def write_json(path: Path, meta: dict, rows: list[dict]) -> None:
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1), encoding="utf-8")
    tmp.replace(path)


# --- the page, from the JSON alone -------------------------------------------------------------------------------

def _f(row: dict) -> float:
    """A failed fit recovered nothing of the shape: F = 0 in the summaries."""
    return row["f_score"] if row.get("status") == "ok" else 0.0


def _beyond_specks(row: dict) -> int:
    from _versions import n_beyond_specks

    return n_beyond_specks(row) if row.get("status") == "ok" else 0


def _summary(rows: list[dict]) -> dict | None:
    if not rows:
        return None
    f = np.array([_f(r) for r in rows])
    worst = min(rows, key=_f)
    ok = [r for r in rows if r.get("status") == "ok"]
    spurious = [_beyond_specks(r) for r in rows]
    found = [r for r in ok if "share_found" in r]
    detected = [r["detected"] for r in found if r.get("detected") is not None]
    alarms = [r["false_alarms"] for r in found if "false_alarms" in r]
    return {"n": len(rows), "median": float(np.median(f)), "worst": float(f.min()), "worst_shape": worst["shape"],
            "spurious_shapes": sum(s > 0 for s in spurious), "spurious_total": sum(spurious),
            "failed": len(rows) - len(ok),
            "degree": float(np.median([r["degree"] for r in ok])) if ok else None,
            "seconds": float(np.median([r["seconds"] for r in ok])) if ok else None,
            "share_true": float(np.median([r["n_planted"] / r["n"] for r in rows])),
            "share_found": float(np.median([r["share_found"] for r in found])) if found else None,
            "detected": float(np.median(detected)) if detected else None,
            "false_alarms": float(np.median(alarms)) if alarms else None}


def _pct(value) -> str:
    return "—" if value is None else f"{100 * value:.1f}%"


def summary_table(rows: list[dict], conditions, pipelines) -> list[str]:
    lines = [("| condition | pipeline | shapes | median F | worst F (shape) | shapes with spurious components "
             "(components) | median degree | median seconds | outliers true / found | planted found | "
             "false alarms |"), "|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in conditions:
        for p in pipelines:
            s = _summary([r for r in rows if r["condition"] == c and r["pipeline"] == p])
            if s is None:
                continue
            failed = f", {s['failed']} failed" if s["failed"] else ""
            degree = "—" if s["degree"] is None else f"{s['degree']:g}"
            seconds = "—" if s["seconds"] is None else f"{s['seconds']:.1f}"
            lines.append(
                f"| {LABELS.get(c, c)} | {p} | {s['n']}{failed} | {s['median']:.3f} | {s['worst']:.3f} "
                f"({s['worst_shape']}) | {s['spurious_shapes']} ({s['spurious_total']}) | {degree} | {seconds} | "
                f"{_pct(s['share_true'])} / {_pct(s['share_found'])} | {_pct(s['detected'])} | "
                f"{_pct(s['false_alarms'])} |")
    return lines


def must_show(rows: list[dict], pipelines) -> list[str]:
    """Issue 30's criteria on these shapes, per pipeline."""
    lines = ["| criterion (issue 30) | " + " | ".join(pipelines) + " |", "|---|" + "---|" * len(pipelines)]
    checks = []
    for p in pipelines:
        s = {c: _summary([r for r in rows if r["condition"] == c and r["pipeline"] == p]) for c in CONDITIONS}
        checks.append(s)

    def cell(ok: bool, text: str) -> str:
        return f"{'✓' if ok else '✗'} {text}"

    criteria = [
        ("25% outliers: median F within 0.03 of the clean fit's",
         lambda s: cell(s["outliers-25"]["median"] >= s["clean"]["median"] - 0.03,
                        f"{s['outliers-25']['median']:.3f} vs {s['clean']['median']:.3f}")),
        ("25% outliers: no spurious component",
         lambda s: cell(s["outliers-25"]["spurious_shapes"] == 0, f"{s['outliers-25']['spurious_shapes']} shapes")),
        ("40% outliers: median F ≥ 0.90",
         lambda s: cell(s["outliers-40"]["median"] >= 0.90, f"{s['outliers-40']['median']:.3f}")),
        ("1% noise: median F within 0.03 of the clean fit's",
         lambda s: cell(s["noise-1"]["median"] >= s["clean"]["median"] - 0.03,
                        f"{s['noise-1']['median']:.3f} vs {s['clean']['median']:.3f}")),
        ("clean bare cloud: every shape F ≥ 0.90",
         lambda s: cell(s["clean"]["worst"] >= 0.90, f"worst {s['clean']['worst']:.3f}")),
    ]
    for text, judge in criteria:
        cells = []
        for s in checks:
            try:
                cells.append(judge(s))
            except TypeError:  # a condition this run did not include
                cells.append("—")
        lines.append(f"| {text} | " + " | ".join(cells) + " |")
    references = {r["shape"]: _f(r) for r in rows if r["pipeline"] == "mesh" and r["condition"] == "clean"}
    if references:
        cells = []
        for p in pipelines:
            pairs = [(r["shape"], _f(r) - references[r["shape"]]) for r in rows
                     if r["pipeline"] == p != "mesh" and r["condition"] == "clean" and r["shape"] in references]
            if not pairs:
                cells.append("—")
                continue
            below = [shape for shape, gap in pairs if gap < -AS_GOOD]
            worst = min(pairs, key=lambda pair: pair[1])
            cells.append(cell(not below, f"{len(below)} of {len(pairs)} below"
                                         + (f", worst {worst[1]:+.3f} ({worst[0]})" if below else "")))
        lines.append(f"| clean bare cloud as good as its mesh (`mesh`): every shape's F at most {AS_GOOD:g} below "
                     "the mesh fit's | " + " | ".join(cells) + " |")
    return lines


def per_shape(rows: list[dict], conditions, pipelines) -> list[str]:
    by = {(r["shape"], r["condition"], r["pipeline"]): r for r in rows}
    shapes = sorted({(r["dim"], r["shape"], r["n_clean"]) for r in rows})
    reference = "mesh" in pipelines  # its clean fit in a column of its own
    pipelines = [p for p in pipelines if p != "mesh"]

    def text(r: dict | None) -> str:
        return "·" if r is None else "fail" if r.get("status") != "ok" else \
            f"{r['f_score']:.2f}" + ("*" if _beyond_specks(r) else "")

    lines = [f"*F-score per pipeline ({' / '.join(pipelines)}), against the clean shape*"
             + ("; *mesh*: the clean mesh's own fit" if reference else ""), "",
             "| shape | dim | N | " + " | ".join(LABELS.get(c, c) for c in conditions) + " |" + " mesh |" * reference,
             "|---|---|---|" + "---|" * (len(conditions) + reference)]
    for dim, shape, n in shapes:
        cells = [" / ".join(text(by.get((shape, c, p))) for p in pipelines) for c in conditions]
        if reference:
            cells.append(text(by.get((shape, "clean", "mesh"))))
        lines.append(f"| {shape} | {dim}D | {n} | " + " | ".join(cells) + " |")
    return lines + ["", "`*`: spurious components beyond specks; `fail`: the pipeline raised (the JSON has the error)."]


def markdown(meta: dict, rows: list[dict]) -> str:
    # every condition and pipeline the rows hold, not only the last (resumed) run's
    conditions = [c for c in CONDITIONS if any(r["condition"] == c for r in rows)]
    pipelines = [p for p in PIPELINES if any(r["pipeline"] == p for r in rows)]
    dims = sorted({r["dim"] for r in rows})
    n_shapes = {d: len({r["shape"] for r in rows if r["dim"] == d}) for d in dims}
    shapes_text = " and ".join(f"{n_shapes[d]} {'2D contours' if d == 2 else '3D meshes'}" for d in dims)
    # the pipelines run (and the robust one's note when it was skipped)
    described = {
        "today": "* **today**: `fit_adaptive(points)` (`ipfit fit FILE`), normals estimated"
                 + (", `outliers=\"none\"`" if meta.get("outlier_keyword") else "") + ";",
        "sor": f"* **sor**: statistical outlier removal as Open3D's `remove_statistical_outlier(nb_neighbors="
               f"{SOR_NEIGHBOURS}, std_ratio={SOR_STD_RATIO:g})` ({meta['open3d_check']}), then today's pipeline;",
        "robust": "* **robust**: `fit_adaptive(points, outliers=\"auto\")`"
                  + (";" if "mesh" in pipelines else "." if "robust" in pipelines
                     else f" — {meta.get('robust_note', 'not run')}."),
        "mesh": "* **mesh**, for reference: the clean mesh itself, `fit_adaptive(ipfit.load(FILE))` (`ipfit fit MESH`: "
                "its vertices with their normals and faces; not the drawn points), the fit a bare cloud is "
                "measured against (\"as good as meshes\"), clean 3D shapes only; its column of the criteria applies "
                "them to the mesh fits, for reference.",
    }
    # a page resumed by later runs names each of them, in order, at its end (their commands are long)
    runs, run_commits = meta["command"].split("` then `"), meta["commit"].split(" then ")
    if len(runs) == 1:
        made, commits = f"`{meta['command']}`", meta["commit"]
    else:
        made = f"{len(runs)} runs of `experiments/robust.py` (listed at the end of this page)"
        commits = f"{run_commits[0]} to {run_commits[-1]}" if len(run_commits) > 1 else run_commits[0]
    lines = [
        "# Real clouds: outliers, noise and no normals",
        "",
        (f"Generated by {made} on {meta['date']} ({meta['machine']}; ipfit {commits}; "
        f"{meta['jobs']} worker process{'es' if meta['jobs'] > 1 else ''} with one thread each, side by side; "
        f"{meta['wall_seconds'] / 60:.0f} minutes), seed {meta['seed']}, on {shapes_text} "
        f"({', '.join(meta['shapes'])}). "
        + (f"Each 3D mesh's surface drawn at {meta['samples']:,} points (`trimesh.sample.sample_surface`, seed 0) "
           "in place of its vertices: a dense scan of it. " if meta.get("samples") else "")
        + "The protocol of issue 30: each shape's points only (no normals), shuffled, "
        "with Gaussian noise of σ = 0.5% or 1% of the box diagonal, or 10%, 25% or 40% of the point count added as "
        "outliers uniform in the bounding box grown by 20% on each side; the seed fixed by the file name and the "
        f"settings ({meta['corrupt_check']}). Each fit is scored against the *clean* shape by "
        "`ipfit.zeroset.quality.quality` (τ = 2% of the box diagonal; a contour's segments, a mesh's faces); "
        "spurious components are counted beyond specks (`ipfit.degree.rules.is_speck`). A pipeline that raised "
        "counts as F = 0."),
        "",
        *([f"Where the shapes come from: {meta['source']}", ""] if meta.get("source") else []),
        *[text for name, text in described.items()
          if name in pipelines or (name == "robust" and meta.get("robust_note"))],
        "",
        ("*Outliers true / found*: the median planted share of the cloud, and of the points the pipeline set aside; "
        "*planted found*: the median share of the planted outliers among them; *false alarms*: the median share "
        "of the shape's own points among them. Seconds are the fit's (outlier removal included), not the scoring's."),
        "",
        "## Issue 30's criteria on these shapes",
        "",
        *must_show(rows, pipelines),
        "",
    ]
    for d in dims:
        lines += [f"## {d}D ({n_shapes[d]} {'contours' if d == 2 else 'meshes'})", "",
                  *summary_table([r for r in rows if r["dim"] == d], conditions, pipelines), ""]
    if len(dims) > 1:
        lines += ["## All shapes", "", *summary_table(rows, conditions, pipelines), ""]
    lines += ["## Per shape", "", *per_shape(rows, conditions, pipelines), ""]
    errors = [r for r in rows if r.get("status") != "ok"]
    if errors:
        lines += ["## Failures", "", "| shape | condition | pipeline | error |", "|---|---|---|---|"]
        lines += [f"| {r['shape']} | {r['condition']} | {r['pipeline']} | {r['error']} |" for r in errors]
        lines.append("")
    if len(runs) == 1:
        lines += ["Regenerate: `" + meta["command"] + "`; `" + meta["command_page"] + "` rewrites this page from "
                  f"`{meta['json']}` alone.", ""]
    else:
        lines += ["## How this page was made", "",
                  "The runs, in order; each after the first (`--resume`) kept the stored rows and fitted its own "
                  "cases, replacing the stored ones of those cases when given `--redo`. Running the same commands "
                  "in the same order regenerates the page; `" + meta["command_page"] + "` rewrites it from "
                  f"`{meta['json']}` alone.", ""]
        lines += [f"{i}. `{run}`" + (f" (ipfit {run_commits[i - 1]})" if len(run_commits) == len(runs) else "")
                  for i, run in enumerate(runs, 1)]
        lines.append("")
    return "\n".join(lines)


# --- the command -------------------------------------------------------------------------------------------------

def _machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{platform.machine()}, {cpu}, {os.cpu_count()} cores shared with other jobs"


def _machines(stored: str | None, current: str) -> str:
    """The processors a resumed page's rows were fitted on, in order: their last bits differ (BLAS
    kernels), and with them a knife-edge fit's result."""
    if not stored:
        return current
    arch, cpus, cores = stored.split(", ", 2)
    cpu = current.split(", ", 2)[1]
    return stored if cpu in cpus.split(" then ") else f"{arch}, {cpus} then {cpu}, {cores}"


def _commit() -> str:
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "src"], capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown commit"
    return head + (" with local changes to src/" if dirty else "")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=list(DEFAULT_SHAPES),
                        help="folders of 2D contour CSVs and 3D meshes, files, bundled dataset names, or 'bundled'")
    parser.add_argument("--every", type=int, default=1, help="every K-th shape of each --shapes entry")
    parser.add_argument("--limit", type=int, help="at most N shapes of each --shapes entry (after --every)")
    parser.add_argument("--conditions", nargs="+", choices=list(CONDITIONS), default=list(CONDITIONS))
    parser.add_argument("--pipelines", nargs="+", choices=PIPELINES, default=list(PIPELINES))
    parser.add_argument("--seed", type=int, default=0, help="the fits' seed (the clouds' are fixed by corrupt.py)")
    parser.add_argument("--samples", type=int, help="draw each 3D mesh's surface at N points instead of its vertices")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (one thread each)")
    parser.add_argument("--out", default="docs/robust.md")
    parser.add_argument("--resume", action="store_true", help="keep the rows of the JSON and run the missing cases")
    parser.add_argument("--page-only", action="store_true", help="rewrite the Markdown from the JSON alone")
    parser.add_argument("--source", help="where the shapes come from, a sentence for the page (with --page-only: "
                                         "replaces the stored one)")
    parser.add_argument("--redo", action="store_true",
                        help="with --resume: fit this command's cases (its shapes, conditions and pipelines) "
                             "again, replacing their stored rows")
    args = parser.parse_args(argv)
    out = Path(args.out)
    json_path = out.with_suffix(".json")
    if args.page_only:
        stored = json.loads(json_path.read_text(encoding="utf-8"))
        if args.source is not None:  # page text only: the run's command with it gives this very page
            meta = stored["meta"]
            meta["source"] = args.source
            # a resumed page's command is its runs' commands joined by "` then `": the first run's takes it
            first, *rest = meta["command"].split("` then `")
            words = shlex.split(first)
            if "--source" in words:
                at = words.index("--source")
                del words[at:at + 2]
            meta["command"] = "` then `".join([shlex.join([*words, "--source", args.source]), *rest])
            write_json(json_path, meta, stored["rows"])
        out.write_text(markdown(stored["meta"], stored["rows"]), encoding="utf-8")
        print(f"wrote {out}")
        return 0

    specs = shape_specs(args.shapes, args.every, args.limit)
    if not specs:
        raise SystemExit("--shapes: no shapes found")
    pipelines = list(args.pipelines)
    has_keyword = _outlier_keyword()
    note = None
    if "robust" in pipelines and not has_keyword:
        pipelines.remove("robust")
        note = "skipped: this checkout's `fit_adaptive` has no `outliers=` keyword yet"
        print(f"robust pipeline {note}")
    argv_text = shlex.join(sys.argv[1:] if argv is None else argv)
    command = f"python experiments/robust.py {argv_text}".strip()
    page_args = shlex.join(["--out", args.out, "--page-only"])
    print(f"{len(specs)} shapes x {len(args.conditions)} conditions x {len(pipelines)} pipelines")
    check = check_corrupt_py(specs)
    first, _ = read_clean(specs[0][1])
    meta = {"command": command.replace(" --resume", ""), "command_page": f"python experiments/robust.py {page_args}",
            "json": str(json_path), "date": date.today().isoformat(), "machine": _machine(), "commit": _commit(),
            "python": platform.python_version(), "numpy": np.__version__, "jobs": args.jobs, "seed": args.seed,
            "shapes": [Path(s).name if Path(s).exists() else s for s in args.shapes]
            + [f"every {args.every}"] * (args.every > 1) + [f"at most {args.limit} each"] * (args.limit is not None),
            "conditions": args.conditions, "pipelines": pipelines, "outlier_keyword": has_keyword,
            "robust_note": note, "corrupt_check": check, "source": args.source, "samples": args.samples,
            "open3d_check": check_open3d(corrupt(first, specs[0][1], *CONDITIONS["outliers-25"])[0])}
    done, before = [], 0.0
    if args.resume and json_path.exists():
        stored = json.loads(json_path.read_text(encoding="utf-8"))
        done, before = stored["rows"], stored["meta"].get("wall_seconds", 0.0)
        if args.source is None:  # the shapes still come from where the page says
            meta["source"] = stored["meta"].get("source")
        if args.redo:  # the page's command line says so (--redo)
            again = {name for name, _ in specs}
            done = [r for r in done if not (r["shape"] in again and r["condition"] in args.conditions
                                            and r["pipeline"] in pipelines)]
        # the page names every run its rows come from: the earlier command(s), then this one
        if stored["meta"].get("command") and stored["meta"]["command"] != meta["command"]:
            meta["command"] = f"{stored['meta']['command']}` then `{meta['command']} --resume"
        if stored["meta"].get("commit") and stored["meta"]["commit"] != meta["commit"]:
            meta["commit"] = f"{stored['meta']['commit']} then {meta['commit']}"
        meta["machine"] = _machines(stored["meta"].get("machine"), meta["machine"])
        meta["shapes"] = [*stored["meta"].get("shapes", []), *(s for s in meta["shapes"]
                                                             if s not in stored["meta"].get("shapes", []))]
    start = time.perf_counter()
    json_path.parent.mkdir(parents=True, exist_ok=True)
    meta["wall_seconds"] = before
    if args.resume and done and stored["meta"].get("samples") != args.samples:
        raise SystemExit(f"--samples {args.samples}: the stored rows were drawn with --samples "
                         f"{stored['meta'].get('samples')}; write another --out")
    rows = run(specs, args.conditions, pipelines, args.seed, args.jobs, json_path, meta, done, args.samples)
    meta["wall_seconds"] = before + time.perf_counter() - start
    write_json(json_path, meta, rows)
    out.write_text(markdown(meta, rows), encoding="utf-8")
    print(f"wrote {out} and {json_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

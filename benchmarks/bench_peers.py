"""ipfit against the reconstruction people use instead: Open3D's screened Poisson (issue 33).

Usage::

    python benchmarks/bench_peers.py [--shapes bunny apple duck] [--million] [--repeats 3]
                                     [--out docs/peers.md]

``make bench-peers`` runs it with ``--million``. Open3D is a benchmark extra (``pip install
open3d``), not a dependency of ipfit.

Each cloud is given to both sides with the same points and normals: a bundled 3D dataset as
:func:`ipfit.load` reads it (a mesh's vertices with their face normals), and with ``--million``
the bunny's surface sampled to 10⁶ points with its face normals (fixed seed). Per cloud, in one
run, interleaved (every tool once, then again, ``--repeats`` times), each run in a fresh Python
process:

* **ipfit**: ``ipfit.fit_adaptive(points, normals, rng=0)``, the recommended pipeline;
* **ipfit fit (command)**: ``ipfit fit NAME -o PREFIX`` as a user runs it, figure and files
  written (bundled datasets only: the command reads them by name);
* **Poisson d6 / d8**: ``open3d.geometry.TriangleMesh.create_from_point_cloud_poisson`` at depth
  6 and 8 (its other settings at their defaults, all cores), then the vertices of the lowest 1 %
  of densities removed (the density trimming of Open3D's tutorial).

Reported per run: wall seconds of the process up to the end of its work (interpreter, imports,
reading, the reconstruction, writing; not the scoring after it, which would add the same seconds to
both sides and flatter the slower one; the median of the repeats), seconds of the reconstruction
call alone,
peak resident memory of the process (``VmHWM``, read right after the reconstruction, before
the scoring), and the size of the result (coefficients, or vertices and triangles, as bytes of
float64 coordinates and int32 indices). Every surface is scored the same way, outside the timed
part: its triangles (ipfit's zero set extracted by marching cubes on a 128-cell grid over the
data's box grown by 25 % on each side, as ``ipfit.zeroset.quality`` judges it) sampled at 200,000
points, against the data's surface (a mesh's triangles sampled alike; a bare cloud's points):
F-score at τ = 2 % of the data's box diagonal, and spurious components, connected pieces of the
surface whose samples lie at a median distance beyond τ from the data.
The ratio column divides by Poisson depth 8's wall seconds of the same repeat, taking the median
over the repeats (the machines are shared: only ratios measured side by side mean anything).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

REPO = Path(__file__).resolve().parents[1]
TOOLS = ("ipfit", "ipfit fit (command)", "Poisson d6", "Poisson d8")
TRIM_QUANTILE = 0.01
SAMPLES = 200_000
GRID = 128
MARGIN = 0.25
MILLION = 1_000_000


# --- the clouds ------------------------------------------------------------------------------------------------------

def bundled_cloud(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A bundled dataset's points, unit normals and faces (none: a (0, 3) array)."""
    import ipfit

    cloud = ipfit.load(name)
    faces = np.zeros((0, 3), np.int64) if cloud.faces is None else np.asarray(cloud.faces)
    return np.asarray(cloud.points), np.asarray(cloud.unit_normals), faces


def million_cloud() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bunny's surface sampled to 10⁶ points, each with its face's outward normal."""
    import ipfit

    cloud = ipfit.load("bunny")
    vertices, faces = np.asarray(cloud.points), np.asarray(cloud.faces)
    points, face = surface_samples(vertices, faces, MILLION)
    corners = vertices[faces[face]]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # the faces' winding is the mesh's; orient them as ipfit's vertex normals are (outward)
    vertex_normals = np.asarray(cloud.unit_normals)[faces[face]].sum(axis=1)
    normals *= np.where(np.einsum("ij,ij->i", normals, vertex_normals) < 0, -1.0, 1.0)[:, None]
    return points, normals, np.zeros((0, 3), np.int64)


def surface_samples(vertices: np.ndarray, faces: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points uniform on the triangles (seed 0), and the triangle of each."""
    corners = vertices[faces]
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    rng = np.random.default_rng(0)
    face = rng.choice(len(faces), size=count, p=area / area.sum()) if area.sum() > 0 else \
        rng.integers(len(faces), size=count)
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    c = corners[face]
    return c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0]), face


# --- one run, in a fresh process -------------------------------------------------------------------------------------

def _peak_mb() -> float:
    """This process's peak resident memory. ``VmHWM`` is the process image's own (reset by exec);
    ``ru_maxrss`` also keeps the forking parent's size, which here holds a million points."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def child(tool: str, data: str, out: str, name: str) -> None:
    """Run ``tool`` on the cloud saved in ``data``; write the timings and the surface to ``out``."""
    with np.load(data) as saved:
        points, normals, data_faces = saved["points"], saved["normals"], saved["faces"]
    record: dict = {"tool": tool}
    if tool == "ipfit":
        import ipfit

        start = time.perf_counter()
        result = ipfit.fit_adaptive(points, normals, rng=0)
        record["seconds_call"] = time.perf_counter() - start
        record["peak_mb"] = _peak_mb()
        record["finished"] = time.time()
        poly = result.polynomial
        record.update(degree=int(result.selected_degree), size=f"{poly.n_coefficients} coefficients",
                      bytes=8 * poly.n_coefficients)
        vertices, faces = _zero_set(poly, points)
    elif tool == "ipfit fit (command)":
        import ipfit
        from ipfit.cli import main

        start = time.perf_counter()
        code = main(["fit", name, "-o", str(Path(out).with_suffix("")) + "-fit"])
        record["seconds_call"] = time.perf_counter() - start
        record["peak_mb"] = _peak_mb()
        record["finished"] = time.time()
        if code not in (0, None):
            raise SystemExit(f"ipfit fit {name} exited with {code}")
        prefix = Path(str(Path(out).with_suffix("")) + "-fit")
        poly = ipfit.ImplicitPolynomial.load(prefix.with_suffix(".json"))
        record.update(size=f"{poly.n_coefficients} coefficients", bytes=8 * poly.n_coefficients)
        vertices, faces = _zero_set(poly, points)
    else:
        import open3d

        depth = int(tool.split("d")[-1])
        start = time.perf_counter()
        cloud = open3d.geometry.PointCloud()
        cloud.points = open3d.utility.Vector3dVector(points)
        cloud.normals = open3d.utility.Vector3dVector(normals)
        mesh, densities = open3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=depth)
        densities = np.asarray(densities)
        mesh.remove_vertices_by_mask(densities < np.quantile(densities, TRIM_QUANTILE))
        record["seconds_call"] = time.perf_counter() - start
        record["peak_mb"] = _peak_mb()
        record["finished"] = time.time()
        vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
        record.update(size=f"{len(vertices):,} vertices, {len(faces):,} triangles",
                      bytes=24 * len(vertices) + 12 * len(faces))
    # the data's surface: a mesh's triangles sampled as densely as the result's, or the points
    reference = surface_samples(points, data_faces, SAMPLES)[0] if len(data_faces) else points
    record.update(_score(vertices, faces, reference))
    Path(out).write_text(json.dumps(record))


def _zero_set(poly, points) -> tuple[np.ndarray, np.ndarray]:
    import ipfit

    lo, hi = points.min(axis=0), points.max(axis=0)
    grow = MARGIN * (hi - lo).max()
    zs = ipfit.extract_zero_set(poly, bounds=np.column_stack([lo - grow, hi + grow]), resolution=GRID)
    if zs.vertices is None or zs.faces is None:  # no zero set in the box
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.asarray(zs.vertices, float), np.asarray(zs.faces, np.int64)


def _score(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> dict:
    """F-score of the surface against the data's surface samples ``points`` at τ, and its pieces
    far from them (module notes)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    from ipfit.geometry.distance import DEFAULT_TAU_FRACTION  # quality()'s τ

    tau = DEFAULT_TAU_FRACTION * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    if len(faces) == 0:
        return {"f_score": 0.0, "precision": 0.0, "recall": 0.0, "spurious": 0, "tau": tau}
    samples, face = surface_samples(vertices, faces, SAMPLES)
    to_data = cKDTree(points).query(samples, workers=-1)[0]
    to_surface = cKDTree(samples).query(points, workers=-1)[0]
    precision, recall = float(np.mean(to_data <= tau)), float(np.mean(to_surface <= tau))
    f = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(vertices),) * 2)
    _, label = connected_components(graph, directed=False)
    piece = label[faces[face, 0]]
    spurious = 0
    for p in np.unique(piece):
        if np.median(to_data[piece == p]) > tau:
            spurious += 1
    return {"f_score": f, "precision": precision, "recall": recall, "spurious": spurious, "tau": tau}


# --- the run ---------------------------------------------------------------------------------------------------------

def run(clouds: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, bool]], repeats: int, folder: Path) -> list[dict]:
    rows = []
    for label, (points, normals, faces, by_name) in clouds.items():
        data = folder / f"{label.split(',')[0].replace(' ', '_')}.npz"
        np.savez(data, points=points, normals=normals, faces=faces)
        tools = [t for t in TOOLS if by_name or t != "ipfit fit (command)"]
        for repeat in range(repeats):
            for tool in tools:
                slug = tool.replace(" ", "_").replace("(", "").replace(")", "")
                out = data.with_name(f"{data.stem}-{slug}-{repeat}.json")
                start = time.time()  # the wall clock, which the child's end stamp shares
                done = subprocess.run([sys.executable, __file__, "--child", tool, str(data), str(out), label],
                                      capture_output=True, text=True)
                if done.returncode:
                    raise SystemExit(f"{tool} on {label} failed:\n{done.stderr[-2000:]}")
                record = json.loads(out.read_text())
                finished = record.pop("finished")
                row = {**record, "cloud": label, "n": len(points), "repeat": repeat, "seconds": finished - start}
                rows.append(row)
                print(json.dumps({k: row[k] for k in ("cloud", "tool", "repeat", "seconds", "seconds_call",
                                                       "peak_mb", "f_score", "spurious")}), flush=True)
    return rows


def _median(values) -> float:
    return float(np.median(np.asarray(list(values), float)))


def summary(rows: list[dict]) -> list[dict]:
    out = []
    for cloud in dict.fromkeys(r["cloud"] for r in rows):
        mine = [r for r in rows if r["cloud"] == cloud]
        reference = {r["repeat"]: r["seconds"] for r in mine if r["tool"] == "Poisson d8"}
        ratios = {tool: [r["seconds"] / reference[r["repeat"]] for r in mine if r["tool"] == tool and r["repeat"]
                         in reference] for tool in TOOLS}
        for tool in TOOLS:
            runs = [r for r in mine if r["tool"] == tool]
            if not runs:
                continue
            out.append({"cloud": cloud, "n": runs[0]["n"], "tool": tool, "repeats": len(runs),
                        "seconds": _median(r["seconds"] for r in runs),
                        "seconds_call": _median(r["seconds_call"] for r in runs),
                        "ratio": _median(ratios[tool]) if ratios[tool] else None,
                        "peak_mb": _median(r["peak_mb"] for r in runs), "f_score": _median(r["f_score"] for r in runs),
                        "spurious": int(max(r["spurious"] for r in runs)), "size": runs[0]["size"],
                        "bytes": runs[0]["bytes"], "degree": runs[0].get("degree")})
    return out


def markdown(meta: dict, table: list[dict]) -> str:
    lines = ["# ipfit against screened Poisson", "",
             (f"Generated by `{meta['command']}` on {meta['date']} ({meta['machine']}; ipfit {meta['commit']}, "
             f"Open3D {meta['open3d']}; {meta['minutes']:.0f} minutes). Each run is a fresh process; every tool "
             f"once, then again, {meta['repeats']} times in turn. The protocol is in the script's docstring: the "
             "same points and normals for both sides, Poisson's mesh trimmed of its 1 % lowest-density vertices, "
             "every surface scored by one scorer (F-score against the data's surface at τ = 2 % of its box diagonal; "
             "spurious: pieces of surface at a median distance beyond τ from the data). *Seconds*: the process "
             "up to the end of its work (interpreter, imports, reading, the reconstruction, writing; not the "
             "scoring), the median of the repeats; "
             "*call*: the reconstruction alone; *ratio*: seconds over Poisson depth 8's in the same repeat, the "
             "median of the repeats."), "",
             "| cloud | N | tool | seconds | call s | ratio to Poisson d8 | peak MB | F-score | spurious | size |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in table:
        ratio = "—" if r["ratio"] is None else f"{r['ratio']:.2f}"
        size = r["size"] + (f" (degree {r['degree']})" if r["degree"] else "") + f", {r['bytes'] / 1024:,.1f} KiB"
        lines.append(f"| {r['cloud']} | {r['n']:,} | {r['tool']} | {r['seconds']:.1f} | {r['seconds_call']:.1f} | "
                     f"{ratio} | {r['peak_mb']:.0f} | {r['f_score']:.3f} | {r['spurious']} | {size} |")
    lines += ["", ("Issue 33's targets: the bunny's whole `ipfit fit` command within 2× of Poisson depth 8, "
                   "10⁶ points within 3× and under 1 GB; the rows above say where it stands."), ""]
    return "\n".join(lines)


def _machine() -> str:
    cpu = platform.processor() or "unknown processor"
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                   if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{platform.machine()}, {cpu}, {os.cpu_count()} cores shared with other jobs"


def _commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=["bunny", "apple", "duck"])
    parser.add_argument("--million", action="store_true", help="add the bunny's surface sampled to 10⁶ points")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "peers.md")
    parser.add_argument("--child", nargs=4, metavar=("TOOL", "DATA", "OUT", "NAME"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    try:
        import open3d
    except ImportError:
        print("bench_peers: Open3D is needed for the comparison; pip install open3d", file=sys.stderr)
        return 2
    started = time.perf_counter()
    clouds = {name: (*bundled_cloud(name), True) for name in args.shapes}
    if args.million:
        clouds["bunny surface, 10⁶ points"] = (*million_cloud(), False)
    with tempfile.TemporaryDirectory() as folder:
        rows = run(clouds, args.repeats, Path(folder))
    table = summary(rows)
    command = "python benchmarks/bench_peers.py" + (" --million" if args.million else "") + \
        ("" if args.shapes == ["bunny", "apple", "duck"] else " --shapes " + " ".join(args.shapes)) + \
        ("" if args.repeats == 3 else f" --repeats {args.repeats}")
    meta = {"command": command, "date": date.today().isoformat(), "commit": _commit(), "open3d": open3d.__version__,
            "machine": _machine(),
            "repeats": args.repeats, "minutes": (time.perf_counter() - started) / 60}
    args.out.write_text(markdown(meta, table))
    args.out.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows, "table": table}, indent=1))
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

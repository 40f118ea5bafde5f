"""Dense scans of thin shapes: the fit with the normals rounded over rims, and without (issue 30).

Usage::

    python experiments/rims.py [--only NAME ...] [--meshes FILE ...] [--samples N] [--jobs 2]
                               [--out docs/rims.md] [--page-only]

Each shape (the 12 meshes of ``../shared/data/turk-dev``, the bundled apple and duck, and the
mesh files of ``--meshes``) is drawn as a dense scan: N points uniform on its surface (seed 0,
``experiments/normals_bare.py``'s ``surface_samples``; meshes without an outward side are left
out and named). Each scan is fitted by ``ipfit.fit_adaptive(points, normals, rng=0)`` (the
recommended pipeline, outliers 'auto'), in three conditions:

* **faces**: with each point's face normal (a scanner's normals: sideways up to a thin part's rim);
* **bare**: without normals (estimated by ``ipfit.estimate_normals``);
* **noisy**: without normals, with Gaussian noise of σ = 0.5 % of the box diagonal (issue 30's
  protocol, ``experiments/robust.py``'s ``corrupt``);

The bare and noisy scans are fitted twice: **on**, the pipeline as it is (the normals it estimates
turned outward near rims by ``ipfit.normals.rims.round_rims`` before the degree loop), and **off**,
with ``round_rims`` replaced by one that turns nothing (the pipeline before it). Given normals are
kept as given (**given**, the pipeline as it is); for comparison the faces condition is also fitted
with the face normals rounded by ``round_rims`` before they are given (**rounded**), and with each
point's normal interpolated from its triangle's vertex normals (trimesh's, area-weighted: the
rounding a mesh gives; **mesh**). Every fit is scored against the mesh's faces by
``ipfit.zeroset.quality.quality`` (F-score at τ = 2 % of the box diagonal).

Columns *spread*: the spacing's spread that ``round_rims`` requires to be at most 2 (p90 / p10 of
the distance to the 8th nearest point, on the standardised points), on the scan and on the mesh's
vertices; *turned*: the share of the scan's points whose face normal ``round_rims`` turns.
The rows go to ``--out`` with a ``.json`` twin; ``--page-only`` rewrites the page from it.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from _versions import page_meta, regenerate, write_page

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
# this checkout's ipfit, in the spawned workers too (they import this module first)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

TURK = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "turk-dev"
CONDITIONS = {"faces": ("given", "rounded", "mesh"), "bare": ("off", "on"), "noisy": ("off", "on")}
NOISE = 0.005


def _no_rims(points, normals, **_):
    return np.asarray(normals, float), np.zeros(len(normals))


def spacing_spread(points) -> float:
    from scipy.spatial import cKDTree

    from ipfit.normals.local import standardise

    p = standardise(np.unique(np.asarray(points, float), axis=0))
    d = cKDTree(p).query(p, k=[9])[0][:, 0]
    low, high = np.percentile(d, [10, 90])
    return float(high / low)


def _shape(name: str, meshes: list[str], turk: Path):
    from normals_bare import shapes

    return next(shapes([name], turk, meshes))


def run(job: tuple) -> dict:
    """One fit: (name, condition, variant, samples, meshes, turk) -> its row."""
    name, condition, variant, samples, meshes, turk = job
    warnings.simplefilter("ignore")
    import trimesh
    from normals_bare import surface_samples
    from robust import corrupt

    import ipfit
    from ipfit.degree import adaptive
    from ipfit.normals.rims import round_rims
    from ipfit.zeroset.quality import quality

    _, path, vertices, _, faces = _shape(name, meshes, Path(turk))
    points, normals = surface_samples(vertices, faces, samples)
    row = {"shape": name, "condition": condition, "variant": variant, "N": len(points)}
    if condition == "faces" and variant == "rounded":
        normals, turn = round_rims(points, normals, return_turn=True)
        row["turned"] = float(np.mean(turn > 0))
        row["spread scan"] = spacing_spread(points)
        row["spread vertices"] = spacing_spread(vertices)
    if condition == "faces" and variant == "mesh":
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        again, face = trimesh.sample.sample_surface(mesh, samples, seed=0)  # surface_samples' own draw
        assert np.array_equal(again, points)
        bary = trimesh.triangles.points_to_barycentric(mesh.triangles[face], points)
        corner = np.asarray(mesh.vertex_normals)[mesh.faces[face]] * np.sign(mesh.volume)
        normals = np.einsum("ij,ijk->ik", bary, corner)
    if condition != "faces":
        normals = None
    if condition == "noisy":
        points, _ = corrupt(points, f"{path or name}#{samples}", NOISE, 0.0)
    if variant == "off":
        adaptive.round_rims = _no_rims
    start = time.perf_counter()
    result = ipfit.fit_adaptive(points, normals, rng=0)
    row["seconds"] = time.perf_counter() - start
    q = quality(result.polynomial, ipfit.Cloud(vertices, faces=faces))
    row.update(F=q.f_score, spurious=len(q.spurious), degree=int(result.selected_degree))
    return row


def _median(values):
    return float(np.median(values)) if values else float("nan")


def _listed(names: list[str], baseline: bool) -> str:
    if baseline:
        return "—"
    return f"{len(names)} ({', '.join(names)})" if names else "0"


def page(rows: list[dict], meta: dict) -> str:
    by = {(r["shape"], r["condition"], r["variant"]): r for r in rows}
    names = list(dict.fromkeys(r["shape"] for r in rows))
    out = ["# Dense scans of thin shapes: normals rounded over rims (issue 30)\n",
           (f"Generated by `{meta['command']}` on {meta['date']} ({meta['machine']}; ipfit {meta['commit']}; "
           f"{meta['minutes']:.0f} minutes), {meta['samples']:,} points per scan. Every shape is a mesh "
           "drawn as a dense scan and fitted by the recommended pipeline: without normals, with the normals "
           "it estimates turned outward over thin rims (*on*, `ipfit.normals.rims.round_rims` before the "
           "degree loop) and without that (*off*); with the faces' normals as given (*given*: kept), "
           "rounded before they are given (*rounded*), or interpolated from the mesh's vertex normals "
           "(*mesh*). The protocol is in the script's docstring. F-scores against the mesh's faces (τ = 2 % of the "
           "box diagonal); `*`: spurious components.\n"),
           "## Summary\n",
           ("| condition | fit | shapes | median F | worst F | higher by > 0.01 than the first | lower by > 0.01 | "
           "with spurious components |"),
           "|---|---|---|---|---|---|---|---|"]
    for condition, variants in CONDITIONS.items():
        for variant in variants:
            fs = [(n, by[(n, condition, variant)]) for n in names if (n, condition, variant) in by]
            if not fs:
                continue
            first = variants[0]
            base = {n: by[(n, condition, first)]["F"] for n in names if (n, condition, first) in by}
            higher = [n for n, r in fs if variant != first and n in base and r["F"] > base[n] + 0.01]
            lower = [n for n, r in fs if variant != first and n in base and r["F"] < base[n] - 0.01]
            worst = min(fs, key=lambda item: item[1]["F"])
            out.append(f"| {condition} | {variant} | {len(fs)} | {_median([r['F'] for _, r in fs]):.3f} | "
                       f"{worst[1]['F']:.3f} ({worst[0]}) | {_listed(higher, variant == first)} | "
                       f"{_listed(lower, variant == first)} | "
                       f"{sum(r['spurious'] > 0 for _, r in fs)} |")
    out += ["", "## Per shape\n",
            ("*F (degree)* per condition and fit; *turned*: share of the scan's points whose face normal "
            "`round_rims` turns; *spread*: p90 / p10 of the spacing on the scan and on the mesh's vertices (rims are "
            "rounded only where it is at most 2).\n"),
            ("| shape | N | spread scan / vertices | turned | faces given | faces rounded | faces mesh | bare off | "
            "bare on | noisy off | noisy on |"),
            "|---|---|---|---|---|---|---|---|---|---|---|"]

    def cell(n, c, v):
        r = by.get((n, c, v))
        return "—" if r is None else f"{r['F']:.3f}{'*' if r['spurious'] else ''} ({r['degree']})"

    for n in names:
        on = by.get((n, "faces", "rounded"), {})
        spread = f"{on['spread scan']:.1f} / {on['spread vertices']:.1f}" if "spread scan" in on else "—"
        turned = f"{on['turned']:.1%}" if "turned" in on else "—"
        count = next(r["N"] for r in rows if r["shape"] == n)
        out.append(f"| {n} | {count:,} | {spread} | {turned} | " +
                   " | ".join(cell(n, c, v) for c, vs in CONDITIONS.items() for v in vs) + " |")
    if meta.get("left_out"):
        out.append(f"\nLeft out (faces not consistently wound, no outward side): {', '.join(meta['left_out'])}.")
    out.append(regenerate(meta, "rims.py"))
    return "\n".join(out) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--meshes", nargs="*", default=[])
    parser.add_argument("--turk", type=Path, default=TURK)
    parser.add_argument("--samples", type=int, default=5000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("docs/rims.md"))
    parser.add_argument("--page-only", action="store_true")
    args = parser.parse_args(argv)
    if args.page_only:
        write_page(args.out, page)
        return
    from normals_bare import shapes, surface_samples

    names, left_out = [], []
    for name, _, vertices, _, faces in shapes(args.only, args.turk, args.meshes):
        (names if surface_samples(vertices, faces, 10) is not None else left_out).append(name)
    jobs = [(n, c, v, args.samples, list(args.meshes), str(args.turk)) for n in names
            for c, vs in CONDITIONS.items() for v in vs]
    start = time.perf_counter()
    rows = []
    # one fit per process: each job sets its own pipeline variant
    with ProcessPoolExecutor(args.jobs, max_tasks_per_child=1) as pool:
        for row in pool.map(run, jobs):
            rows.append(row)
            print(json.dumps(row), flush=True)
    meta = page_meta("rims.py", argv, args.out, start, samples=args.samples, left_out=left_out)
    write_page(args.out, page, rows, meta)


if __name__ == "__main__":
    main()

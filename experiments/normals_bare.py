"""Normals of bare 3D clouds against their meshes' vertex normals, and what they cost a fit (issue 30).

Usage::

    python experiments/normals_bare.py [--only NAME ...] [--fit] [--out FILE.md] [--turk DIR]

For the 12 meshes of ``../shared/data/turk-dev`` (vertices as ``trimesh.load(f, force='mesh',
process=True)`` merges them) and the bundled apple and duck (``ipfit.load``): per shape,
:func:`ipfit.estimate_normals` on the bare vertices against the mesh's vertex normals:

* ``cos10 … cos75``: quantiles 10/25/50/75 % of |cos| between the estimated and the mesh's
  normal *lines* (1 = same line);
* ``off60``: share of points whose line is more than 60° off (|cos| < 0.5);
* ``flip``: share of opposite signs among the points whose line is right (|cos| > 0.7);
* ``s``: seconds of ``estimate_normals``.

The last rows are the medians over the shapes. No fits by default. ``--fit`` also fits each
shape twice (``ipfit.fit_adaptive(X, normals, rng=0, outliers="none")``, with the mesh's normals
and with the estimated ones) and scores both against the mesh
(``ipfit.zeroset.quality.quality(poly, ipfit.Cloud(X, faces=F))``): F, precision, recall, the
degree. A fit takes 20-50 s on two busy cores: pass ``--only`` with a few names.

The reference's signs are outward wherever a ray along them escapes the mesh and one against
them does not (checked: at most 0.5 % inward, 5 % on walkman); walkman's vertices repeat with
the normals of different faces (6,672 rows, 2,106 positions), so its |cos| cannot reach 1.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import ipfit
from ipfit.zeroset.quality import quality

TURK = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "turk-dev"
BUNDLED = ("apple", "duck")


def shapes(only, turk: Path):
    """(name, points, mesh normals, faces) of every shape, or of those named in ``only``."""
    import trimesh

    names = [p.stem for p in sorted(turk.glob("*.ply"))] + list(BUNDLED)
    for name in names:
        if only and name not in only:
            continue
        if name in BUNDLED:
            cloud = ipfit.load(name)
            yield name, np.asarray(cloud.points), np.asarray(cloud.normals), np.asarray(cloud.faces)
        else:
            mesh = trimesh.load(turk / f"{name}.ply", force="mesh", process=True)
            yield name, np.asarray(mesh.vertices, float), np.asarray(mesh.vertex_normals, float), np.asarray(mesh.faces)


def compare(estimated, reference) -> dict:
    est = estimated / np.linalg.norm(estimated, axis=1, keepdims=True)
    ref = reference / np.linalg.norm(reference, axis=1, keepdims=True)
    cos = np.einsum("ij,ij->i", est, ref)
    ok = np.isfinite(cos)
    cos = cos[ok]
    lines = np.abs(cos)
    right = lines > 0.7
    q = np.quantile(lines, [0.10, 0.25, 0.50, 0.75])
    return {"cos10": q[0], "cos25": q[1], "cos50": q[2], "cos75": q[3], "off60": float(np.mean(lines < 0.5)),
            "flip": float(np.mean(cos[right] < 0)) if right.any() else float("nan")}


def fit_scores(points, normals, faces) -> dict:
    result = ipfit.fit_adaptive(points, normals, rng=0, outliers="none")
    q = quality(result.polynomial, ipfit.Cloud(points, faces=faces))
    return {"F": q.f_score, "P": q.precision, "R": q.recall, "deg": result.polynomial.degree}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--fit", action="store_true")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--turk", type=Path, default=TURK, help="the turk-dev folder (default: ../shared/...)")
    args = parser.parse_args(argv)
    cols = ["cos10", "cos25", "cos50", "cos75", "off60", "flip", "s"]
    fit_cols = ["F mesh", "P mesh", "R mesh", "deg mesh", "F est", "P est", "R est", "deg est"]
    header = ["shape", "N"] + cols + (fit_cols if args.fit else [])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    rows = []
    for name, points, mesh_normals, faces in shapes(args.only, args.turk):
        start = time.perf_counter()
        estimated = ipfit.estimate_normals(points)
        row = compare(estimated, mesh_normals)
        row["s"] = time.perf_counter() - start
        if args.fit:
            for label, nrm in (("mesh", mesh_normals), ("est", estimated)):
                start = time.perf_counter()
                scores = fit_scores(points, nrm, faces)
                row.update({f"{key} {label}": value for key, value in scores.items()})
                row[f"fit s {label}"] = time.perf_counter() - start
        rows.append(row)
        cells = [name, str(len(points))] + [f"{row[c]:.3f}" if c != "s" else f"{row[c]:.2f}" for c in cols]
        if args.fit:
            cells += [f"{row[c]:.3f}" if not c.startswith("deg") else str(row[c]) for c in fit_cols]
        lines.append("| " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    if rows:
        med = ["median", ""] + [f"{np.nanmedian([r[c] for r in rows]):.3f}" for c in cols]
        if args.fit:
            med += [f"{np.nanmedian([r[c] for r in rows]):.3f}" for c in fit_cols]
        lines.append("| " + " | ".join(med) + " |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

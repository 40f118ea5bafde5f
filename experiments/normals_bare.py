"""Normals of bare 3D clouds against their meshes' vertex normals, and what they cost a fit (issue 30).

Usage::

    python experiments/normals_bare.py [--only NAME ...] [--fit] [--out FILE.md] [--turk DIR]
                                       [--meshes FILE ...] [--noise SIGMA] [--wide] [--known-noise]
                                       [--samples N ...] [--signs]

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

``--meshes`` adds mesh files (their vertices and vertex normals, read as the Turk meshes are).
``--noise SIGMA`` corrupts each shape's vertices as issue 30's protocol does (Gaussian noise of
SIGMA × the box diagonal, shuffled: ``experiments/robust.py``'s ``corrupt``, the very points of
``../shared/tools/corrupt.py``); a noisy point's reference is the normal of its nearest clean
vertex, and ``--fit`` scores the fits of the noisy points against the clean mesh. ``--wide``
adds the estimate with the noisy-data path forced in 3D (``ipfit.normals.scale._GAIN`` set to
infinity: every point's neighbourhood grown to its flattest local scale and the signs propagated
on the denoised coarse sample, even where no wider neighbourhood is flatter): columns ``flip
wide`` and, with ``--fit``, ``F wide`` (docs/normals-noise.md). ``--known-noise`` adds the estimate
that ``fit_adaptive`` makes of a noisy cloud, given the noise's σ the outlier score finds
(``ipfit.estimate_normals(points, noise=ipfit.robust.score_outliers(points).noise_scale)``):
columns ``off60 σ`` and ``flip σ``, and with ``--fit``, ``F σ``. ``--signs`` (with ``--fit``) also fits
the estimated normals with each sign made the reference's (``F signs``): what the signs alone cost
a fit, against what the lines cost (``F signs`` against ``F mesh``).

``--samples N ...`` replaces each shape's vertices by N points drawn uniformly on its surface
(``trimesh.sample.sample_surface``, seed 0), a row per shape and N: a dense scan of the object,
each point's reference the outward normal of its face. Only meshes with consistently wound faces
have an outward side to compare with (their face normals times the sign of their signed volume,
which small holes do not change); the others are left out and named (docs/normals-dense.md).

The reference's signs are outward wherever a ray along them escapes the mesh and one against
them does not (checked: at most 0.5 % inward, 5 % on walkman); walkman's vertices repeat with
the normals of different faces (6,672 rows, 2,106 positions), so its |cos| cannot reach 1.
"""

from __future__ import annotations

import argparse
import platform
import shlex
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

import ipfit
from ipfit.zeroset.quality import quality

TURK = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "turk-dev"
BUNDLED = ("apple", "duck")


def shapes(only, turk: Path, meshes=(), noisy: bool = False):
    """(name, file, points, mesh normals, faces) of every shape, or of those named in ``only``
    (``noisy``: every shape read as ``corrupt.py`` reads it, the bundled ones too)."""
    import trimesh

    from ipfit.datasets.bundled import dataset_path

    files = {p.stem: p for p in sorted(turk.glob("*.ply"))} | {Path(m).stem: Path(m) for m in meshes}
    for name in [*files, *BUNDLED]:
        if only and name not in only:
            continue
        if name in BUNDLED and not noisy:
            cloud = ipfit.load(name)
            yield name, None, np.asarray(cloud.points), np.asarray(cloud.normals), np.asarray(cloud.faces)
        else:
            path = dataset_path(name) if name in BUNDLED else files[name]
            mesh = trimesh.load(path, force="mesh", process=True)
            yield (name, path, np.asarray(mesh.vertices, float), np.asarray(mesh.vertex_normals, float),
                   np.asarray(mesh.faces))


def surface_samples(clean, faces, count: int):
    """``count`` points uniform on the mesh (seed 0) and their faces' outward normals, or None when
    the mesh has no outward side to compare with (inconsistently wound faces). The outward side
    is that of the faces' signed volume (a mesh with small holes has one too)."""
    import trimesh

    mesh = trimesh.Trimesh(clean, faces, process=False)
    if not mesh.is_winding_consistent or mesh.volume == 0:
        return None
    points, face = trimesh.sample.sample_surface(mesh, count, seed=0)
    return np.asarray(points, float), np.asarray(mesh.face_normals)[face] * np.sign(mesh.volume)


def corrupted(points, normals, path: Path, noise: float):
    """issue 30's noisy cloud of ``points`` (robust.corrupt) and each noisy point's reference normal."""
    from scipy.spatial import cKDTree

    from robust import corrupt

    noisy, _ = corrupt(points, str(path), noise, 0.0)
    return noisy, normals[cKDTree(points).query(noisy)[1]]


def wide_estimate(points):
    """estimate_normals with the noisy-data path forced in 3D (see --wide)."""
    from ipfit.normals import scale

    kept = scale._GAIN
    scale._GAIN = float("inf")
    try:
        return ipfit.estimate_normals(points)
    finally:
        scale._GAIN = kept


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


def _clouds(args):
    """(name, file, clean points, their normals, faces, N or None) per row: each shape once, or
    once per ``--samples`` N."""
    for name, path, clean, clean_normals, faces in shapes(args.only, args.turk, args.meshes, args.noise > 0):
        for count in args.samples or [None]:
            yield name, path, clean, clean_normals, faces, count


def fit_scores(points, normals, reference) -> dict:
    result = ipfit.fit_adaptive(points, normals, rng=0, outliers="none")
    q = quality(result.polynomial, reference)
    return {"F": q.f_score, "P": q.precision, "R": q.recall, "deg": result.polynomial.degree}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--fit", action="store_true")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--turk", type=Path, default=TURK, help="the turk-dev folder (default: ../shared/...)")
    parser.add_argument("--meshes", nargs="*", default=[], help="more mesh files")
    parser.add_argument("--noise", type=float, default=0.0, help="issue 30's noise, a share of the box diagonal")
    parser.add_argument("--wide", action="store_true", help="also the estimate with the noisy-data path forced")
    parser.add_argument("--known-noise", action="store_true",
                        help="also the estimate given the outlier score's noise scale, as fit_adaptive makes it")
    parser.add_argument("--signs", action="store_true",
                        help="with --fit: also the estimated lines with the reference's signs")
    parser.add_argument("--samples", type=int, nargs="*", default=[],
                        help="N points drawn on each mesh's surface instead of its vertices (a row per N)")
    args = parser.parse_args(argv)
    if args.samples and args.noise:
        parser.error("--samples draws clean points on the surface: not with --noise")
    cols = ["cos10", "cos25", "cos50", "cos75", "off60", "flip", "s"] + (["flip wide"] if args.wide else []) + \
        (["off60 σ", "flip σ"] if args.known_noise else [])
    if args.signs and not args.fit:
        parser.error("--signs is a fit's column: add --fit")
    fits = ("mesh", "est") + (("signs",) if args.signs else ()) + (("wide",) if args.wide else ()) + \
        (("σ",) if args.known_noise else ())
    fit_cols = [f"{key} {label}" for label in fits for key in ("F", "P", "R", "deg")]
    header = ["shape", "N"] + cols + (fit_cols if args.fit else [])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    rows, skipped = [], []
    for name, path, clean, clean_normals, faces, count in _clouds(args):
        if count is None:
            points, mesh_normals = (clean, clean_normals) if args.noise == 0 else \
                corrupted(clean, clean_normals, path, args.noise)
        else:
            drawn = surface_samples(clean, faces, count)
            if drawn is None:
                if name not in skipped:
                    skipped.append(name)
                    print(f"{name}: faces not consistently wound: left out", flush=True)
                continue
            points, mesh_normals = drawn
        # an unreferenced vertex has no normal: no reference for it (or for a noisy point nearest it)
        referenced = np.linalg.norm(mesh_normals, axis=1) > 1e-9
        points, mesh_normals = points[referenced], mesh_normals[referenced]
        start = time.perf_counter()
        estimated = ipfit.estimate_normals(points)
        row = compare(estimated, mesh_normals)
        row["s"] = time.perf_counter() - start
        normals = {"mesh": mesh_normals, "est": estimated}
        if args.signs:
            turned = np.einsum("ij,ij->i", estimated, mesh_normals) < 0
            normals["signs"] = estimated * np.where(turned, -1.0, 1.0)[:, None]
        if args.wide:
            normals["wide"] = wide_estimate(points)
            row["flip wide"] = compare(normals["wide"], mesh_normals)["flip"]
        if args.known_noise:
            from ipfit.robust import score_outliers

            normals["σ"] = ipfit.estimate_normals(points, noise=score_outliers(points).noise_scale)
            known = compare(normals["σ"], mesh_normals)
            row["off60 σ"], row["flip σ"] = known["off60"], known["flip"]
        if args.fit:
            for label in fits:
                start = time.perf_counter()
                scores = fit_scores(points, normals[label], ipfit.Cloud(clean, faces=faces))
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
        command = shlex.join(["python", "experiments/normals_bare.py", *(sys.argv[1:] if argv is None else argv)])
        legend = ("Columns: *cos10 … cos75*, quantiles of |cos| between the estimated and the mesh's normal lines; "
                  "*off60*, the share of lines more than 60° off; *flip*, the share of opposite signs among the "
                  "points whose line is right (|cos| > 0.7); *flip wide*, the same for the estimate with the "
                  "noisy-data path forced in 3D (`ipfit.normals.scale._GAIN` infinite); *off60 σ, flip σ*, the "
                  "same for the estimate given the noise's σ that the outlier score finds, as `fit_adaptive` makes "
                  "it (`estimate_normals(points, noise=score_outliers(points).noise_scale)`); *s*, seconds of "
                  "`estimate_normals`; with `--fit`, *F, P, R, deg* of `fit_adaptive(points, normals, rng=0, outliers=\"none\")` "
                  "with the mesh's (*mesh*), the estimated (*est*), the estimated lines with the mesh's signs "
                  "(*signs*), the forced path's (*wide*) and the σ-given "
                  "(*σ*) normals, scored "
                  "against the clean mesh. A noisy point's reference normal is its nearest clean vertex's; points "
                  "whose reference normal is zero (unreferenced vertices) are left out. Shapes: "
                  "`../shared/data/turk-dev` and the meshes named (for `../common-3d-test-models`, see "
                  "docs/robust-external.md).")
        what = ("Each row: one shape's surface drawn at N points (the reference: each point's face's outward "
                "normal), their estimated normals against the mesh's." if args.samples else
                "Each row: one shape's bare vertices" + (f" with issue 30's noise of σ = {args.noise:g} × the "
                "box diagonal" if args.noise else "") + ", their estimated normals against the mesh's.")
        left = f" Left out (faces not consistently wound): {', '.join(skipped)}." if skipped else ""
        from robust import _machine  # the processor's name: platform.processor() is empty on Linux

        head = ["# Estimated normals against the meshes' (issue 30)", "",
                f"Generated by `{command}` on {date.today().isoformat()} ({_machine()}; "
                f"Python {platform.python_version()}); fits with seed 0. "
                + what + left, "", legend, ""]
        args.out.write_text("\n".join(head) + "\n" + text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

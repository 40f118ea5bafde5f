"""Outlier scores on the development data: strays found, false alarms, noise scale (issue 30).

Usage::

    python experiments/outlier_scores.py [--out FILE.md] [--quick]

Scores (no fits) every shape of ``../shared/data/mpeg7-dev`` (the first 40 contours),
``../shared/data/turk-dev`` (mesh vertices, as trimesh reads them) and the bundled boot,
airplane, butterfly, apple, duck and bunny, corrupted by the protocol of
``../shared/tools/corrupt.py`` (reimplemented here to keep the truth: Gaussian noise of
σ = NOISE × the box diagonal, int(OUTLIERS × N) points uniform in the box grown by 20 % on each
side, shuffled, the seed fixed by the file name and the settings; a bundled set's file name is
its dataset name), at outliers 0, 0.1, 0.25, 0.4 and noise 0, 0.005, 0.01.

Per collection and condition, the median and the worst shape of: the share of planted strays
found (score above 1), the share of those farther than max(6σ, 2 % of the diagonal) from the
clean shape found (closer ones are samples as far as the points can tell), the share of samples
flagged (false alarms), and the estimated noise over the true σ (for noise 0, the estimate in
1/1000 of the box diagonal: the shape's own roughness). ``--quick`` takes every other contour
and leaves the bunny out.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import sys
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

import ipfit
from ipfit.robust import score_outliers

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
NOISES = (0.0, 0.005, 0.01)
OUTLIERS = (0.0, 0.1, 0.25, 0.4)
BUNDLED = ("boot", "airplane", "butterfly", "apple", "duck", "bunny")


def read_contour(path: Path) -> np.ndarray:
    """corrupt.py's reader: x,y rows, '#' comments and the 'x,y' header skipped."""
    with open(path, encoding="utf-8") as f:
        rows = [line.split(",")[:2] for line in f
                if line.strip() and not line.startswith("#") and not line.startswith("x")]
    return np.array(rows, float)


def surface(points: np.ndarray, faces) -> cKDTree:
    """Dense samples of the clean shape, for the strays' distance to it."""
    if faces is None:  # a closed contour: 5 samples per segment
        t = np.linspace(0.0, 1.0, 5, endpoint=False)[None, :, None]
        step = np.roll(points, -1, axis=0) - points
        return cKDTree((points[:, None, :] + t * step[:, None, :]).reshape(-1, 2))
    import trimesh

    samples, _ = trimesh.sample.sample_surface(trimesh.Trimesh(points, faces, process=False), 200_000, seed=0)
    return cKDTree(np.vstack([points, samples]))


def shapes(quick: bool):
    """(collection, name, file name for the seed, clean points, faces or None)."""
    import trimesh

    contours = sorted((SHARED / "mpeg7-dev").glob("*.csv"))[:40]
    for path in contours[::2] if quick else contours:
        yield "mpeg7-dev", path.stem, path.name, read_contour(path), None
    for path in sorted((SHARED / "turk-dev").glob("*.ply")):
        mesh = trimesh.load(path, force="mesh", process=True)
        yield "turk-dev", path.stem, path.name, np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    for name in BUNDLED:
        if quick and name == "bunny":
            continue
        cloud = ipfit.load(name)
        yield "bundled", name, name, np.asarray(cloud.points), cloud.faces


def corrupt(file_name: str, points: np.ndarray, noise: float, outliers: float):
    """corrupt.py's protocol, with the truth kept: (cloud, stray mask, σ)."""
    rng = np.random.default_rng([ord(c) for c in f"{file_name}|{float(noise)}|{float(outliers)}"])
    lo, hi = points.min(axis=0), points.max(axis=0)
    sigma = noise * float(np.linalg.norm(hi - lo))
    cloud = points + rng.normal(scale=sigma, size=points.shape)
    n_out = int(outliers * len(points)) if outliers else 0
    if n_out:
        box = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=(n_out, points.shape[1]))
        cloud = np.vstack([cloud, box])
    order = rng.permutation(len(cloud))
    stray = np.r_[np.zeros(len(points), bool), np.ones(n_out, bool)][order]
    return cloud[order], stray, sigma


def measure(quick: bool):
    rows = []
    for collection, name, file_name, points, faces in shapes(quick):
        clean = surface(points, faces)
        diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
        for noise in NOISES:
            for outliers in OUTLIERS:
                cloud, stray, sigma = corrupt(file_name, points, noise, outliers)
                start = time.perf_counter()
                result = score_outliers(cloud)
                seconds = time.perf_counter() - start
                flagged = ~result.inliers
                far = stray & (clean.query(cloud)[0] > max(6 * sigma, 0.02 * diagonal))
                rows.append({
                    "collection": collection, "shape": name, "noise": noise, "outliers": outliers,
                    "n": len(cloud), "seconds": seconds,
                    "found": float(flagged[stray].mean()) if stray.any() else np.nan,
                    "found_far": float(flagged[far].mean()) if far.any() else np.nan,
                    "false_alarms": float(flagged[~stray].mean()),
                    "noise_ratio": result.noise_scale / sigma if sigma else 1000 * result.noise_scale / diagonal,
                })
    return rows


def _median_worst(rows, key, worst):
    values = np.array([r[key] for r in rows], float)
    if np.isnan(values).all():
        return "-"
    i = int(worst(np.where(np.isnan(values), np.nan, values)))
    return f"{np.nanmedian(values):.3f} / {values[i]:.3f} ({rows[i]['shape']})"


def table(rows) -> str:
    lines = [("| collection | noise | strays | found: median / worst | far strays found "
              "| false alarms: median / worst | noise estimate / true σ: median / farthest |"),
             "|---|---|---|---|---|---|---|"]
    for collection in dict.fromkeys(r["collection"] for r in rows):
        for noise in NOISES:
            for outliers in OUTLIERS:
                sel = [r for r in rows if r["collection"] == collection and r["noise"] == noise
                       and r["outliers"] == outliers]
                ratio = np.array([r["noise_ratio"] for r in sel])
                off = np.abs(np.log(np.maximum(ratio, 1e-12))) if noise else ratio
                far_from_one = int(np.argmax(off))
                noise_text = (f"{np.median(ratio):.2f} / {ratio[far_from_one]:.2f} ({sel[far_from_one]['shape']})"
                              if noise else f"({np.median(ratio):.2f} / {ratio[far_from_one]:.2f} ‰ of the diagonal)")
                lines.append(
                    f"| {collection} | {noise:g} | {outliers:g} | {_median_worst(sel, 'found', np.nanargmin)} "
                    f"| {_median_worst(sel, 'found_far', np.nanargmin)} "
                    f"| {_median_worst(sel, 'false_alarms', np.nanargmax)} | {noise_text} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="also write the Markdown table here")
    parser.add_argument("--quick", action="store_true", help="every other contour, no bunny")
    args = parser.parse_args(argv)
    if not SHARED.is_dir():
        parser.error(f"development data not found at {SHARED}")
    start = time.perf_counter()
    rows = measure(args.quick)
    seconds = sum(r["seconds"] for r in rows)
    slowest = max(rows, key=lambda r: r["seconds"])
    text = (f"{len({(r['collection'], r['shape']) for r in rows})} shapes x {len(NOISES) * len(OUTLIERS)} conditions; "
            f"scoring took {seconds:.0f} s in all, the slowest {slowest['seconds']:.1f} s "
            f"({slowest['shape']}, {slowest['n']} points); whole run {time.perf_counter() - start:.0f} s "
            f"on {os.cpu_count()} cores.\n\n" + table(rows) + "\n")
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Old vs new :func:`ipfit.zeroset.quality.quality`, in one run: ``python benchmarks/bench_quality.py``.

For every bundled dataset given (default: apple and bunny_res3 in 3D, boot, airplane and
butterfly in 2D), degree (default 4, 6, 8) and fit (``fit_3l``, ``fit_taubin`` and
``fit_adaptive`` at that fixed degree with ``rng=0``), the zero set is extracted once and
measured by the previous implementation (kept below, only here, as the reference: samples at
τ/3 of both shapes, numpy exact distances to the elements of the 6 nearest samples, far
probes on the dense samples) and by the current one, alternately, best of ``--repeat``.
Prints one row per case (times, ratio, F-score and the new − old differences of F, precision
and recall, spurious counts old/new, closed) and a summary: total and per-dimension time
ratios, the same ratios for whole ``quality(polynomial, ...)`` calls (the shared extraction
added to both), the max |ΔF|, |ΔP|, |ΔR|, and whether every n_spurious and closed agree.
``--no-adaptive`` skips the slow fits (about a minute in 3D). The numba kernels are
compiled (or loaded from cache) before timing.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

# -- the previous implementation (reference for the comparison only) --------------------------


def _old_point_segment(p, a, b):
    ab = b - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    t = np.einsum("ij,ij->i", p - a, ab) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(np.where(length2 > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - a - t[:, None] * ab, axis=1)


def _old_point_triangle(p, a, b, c):
    e0, e1, w = b - a, c - a, p - a
    d00, d01, d11 = (np.einsum("ij,ij->i", x, y) for x, y in ((e0, e0), (e0, e1), (e1, e1)))
    d20, d21 = np.einsum("ij,ij->i", w, e0), np.einsum("ij,ij->i", w, e1)
    denom = d00 * d11 - d01 * d01
    ok = denom > 1e-300
    safe = np.where(ok, denom, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    t = (d00 * d21 - d01 * d20) / safe
    inside = ok & (v >= 0) & (t >= 0) & (v + t <= 1)
    plane = np.abs(np.einsum("ij,ij->i", w, np.cross(e0, e1))) / np.sqrt(safe)
    edges = np.minimum(np.minimum(_old_point_segment(p, a, b), _old_point_segment(p, b, c)),
                       _old_point_segment(p, c, a))
    return np.where(inside, plane, edges)


class _OldTarget:
    def __init__(self, samples, kind, corners=(), band=np.inf, far_budget=5000):
        from scipy.spatial import cKDTree

        self.samples, self.kind, self.corners, self.band, self.far_budget = samples, kind, corners, band, far_budget
        self.tree = cKDTree(samples.points)
        dim = samples.points.shape[1]
        keys = np.floor(samples.points / band).astype(np.int64)
        self._lo = keys.min(axis=0) - 1
        self._extent = keys.max(axis=0) - self._lo + 2
        codes = np.unique(self._encode(keys))
        offsets = np.stack(np.meshgrid(*[[-1, 0, 1]] * dim, indexing="ij"), axis=-1).reshape(-1, dim)
        self._cells = np.unique((codes[:, None] + self._encode(offsets - self._lo)[None, :]
                                 - self._encode(np.zeros((1, dim), dtype=np.int64) - self._lo)).ravel())

    def _encode(self, keys):
        code = np.zeros(len(keys), dtype=np.int64)
        for j in range(keys.shape[1]):
            code = code * self._extent[j] + (keys[:, j] - self._lo[j])
        return code

    def distance(self, query, k=6):
        from scipy.spatial import cKDTree

        n = len(self.samples.points)
        k = 1 if self.kind == "points" else min(k, n)
        out = np.full(len(query), np.inf)
        keys = np.floor(query / self.band).astype(np.int64)
        inside = np.all((keys >= self._lo) & (keys < self._lo + self._extent), axis=1)
        maybe = np.zeros(len(query), dtype=bool)
        maybe[inside] = np.isin(self._encode(keys[inside]), self._cells)
        candidates = np.flatnonzero(maybe)
        d, idx = self.tree.query(query[candidates], k=[1] if k == 1 else k, distance_upper_bound=self.band,
                                 workers=-1)
        d, idx = d.reshape(len(candidates), k), idx.reshape(len(candidates), k)
        out[candidates] = d[:, 0]
        if self.kind != "points":
            rows_near = np.flatnonzero(np.isfinite(d[:, 0]))
            for start in range(0, rows_near.size, 1 << 15):
                rows = rows_near[start:start + (1 << 15)]
                missing = idx[rows] >= n
                elements = self.samples.elements[np.where(missing, 0, idx[rows])].ravel()
                p = np.repeat(query[candidates[rows]], k, axis=0)
                corners = [c[elements] for c in self.corners]
                dist = _old_point_segment(p, *corners) if self.kind == "segments" else _old_point_triangle(p, *corners)
                exact = np.where(missing, np.inf, dist.reshape(len(rows), k))
                out[candidates[rows]] = np.minimum(exact.min(axis=1), d[rows, 0])
        far = np.flatnonzero(~np.isfinite(out))
        if far.size:
            probe = far[:: -(-far.size // self.far_budget)]
            out[probe] = self.tree.query(query[probe], workers=-1)[0]
            rest = far[np.isin(far, probe, assume_unique=True, invert=True)]
            if rest.size:
                out[rest] = out[probe][cKDTree(query[probe]).query(query[rest], workers=-1)[1]]
        return out


def old_quality(zs, pts, faces=None, ordered_contour=False, tau_fraction=0.02, max_samples=2_000_000):
    """The previous ``quality`` on an extracted zero set: F, P, R, Chamfer, n_spurious, closed."""
    from ipfit.zeroset.extract import Samples, sample_segments, sample_triangles

    tau = tau_fraction * float(np.linalg.norm(np.ptp(pts, axis=0)))
    spacing = tau / 3
    band = 2 * tau + 2 * spacing
    if faces is not None and len(faces):
        tri = [pts[faces[:, i]] for i in range(3)]
        ref = _OldTarget(sample_triangles(pts, faces, spacing, max_samples=max_samples), "triangles", tri, band)
    elif ordered_contour:
        starts, ends = pts[:-1], pts[1:]
        closing = float(np.linalg.norm(pts[0] - pts[-1]))
        if closing > 0 and closing <= 10 * float(np.median(np.linalg.norm(ends - starts, axis=1))):
            starts, ends = np.vstack([starts, pts[-1:]]), np.vstack([ends, pts[:1]])
        ref = _OldTarget(sample_segments(starts, ends, spacing, max_samples=max_samples), "segments",
                         (starts, ends), band)
    else:
        n = len(pts)
        ref = _OldTarget(Samples(pts, np.ones(n), np.full(n, -1), np.arange(n)), "points", band=band)
    if zs.is_empty:
        return dict(f_score=0.0, precision=0.0, recall=0.0, chamfer=math.inf, n_spurious=0, closed=False)
    samples = zs.sample(spacing, max_samples=max_samples)
    if zs.dim == 2:
        starts, ends, _ = zs.segments()
        target = _OldTarget(samples, "segments", (starts, ends), band)
    else:
        f = zs.faces
        target = _OldTarget(samples, "triangles", tuple(zs.vertices[f[:, i]] for i in range(3)), band)
    d_data = target.distance(pts)
    d_zero = ref.distance(samples.points)
    recall = float(np.mean(d_data <= tau))
    w = samples.weights
    precision = float(w[d_zero <= tau].sum() / w.sum())
    f_score = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    nearest = np.full(zs.n_components, np.inf)
    np.minimum.at(nearest, samples.labels, d_zero)
    return dict(f_score=f_score, precision=precision, recall=recall,
                chamfer=0.5 * (float(d_data.mean()) + float(np.dot(w, d_zero) / w.sum())),
                n_spurious=int((nearest > tau).sum()), closed=zs.closed)


# -- the comparison ---------------------------------------------------------------------------

def _fits(data, degree, methods):
    import ipfit

    for method in methods:
        if method == "3l":
            yield method, ipfit.fit_3l(data.points, data.normals, degree)
        elif method == "taubin":
            yield method, ipfit.fit_taubin(data.points, data.normals, degree)
        else:
            yield method, ipfit.fit_adaptive(data.points, data.normals, faces=data.faces, max_degree=degree,
                                             min_degree=degree, rng=0).polynomial


def _best(repeat, fn):
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+", default=["apple", "bunny_res3", "boot", "airplane", "butterfly"])
    parser.add_argument("--degrees", nargs="+", type=int, default=[4, 6, 8])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-adaptive", action="store_true")
    args = parser.parse_args()

    from ipfit import load
    from ipfit.datasets import synthetic
    from ipfit.zeroset.quality import looks_like_contour, quality
    from ipfit.zeroset.extract import extract_zero_set

    warm = synthetic.sphere(200)
    quality(warm.polynomial, warm.points, resolution=24)  # compile or load the numba kernels
    quality(synthetic.circle(50).polynomial, synthetic.circle(50).points, ordered_contour=True)
    methods = ["3l", "taubin"] + ([] if args.no_adaptive else ["adaptive"])
    print(f"| dataset | deg | fit | old s | new s | ratio | F old | ΔF | ΔP | ΔR | spurious old/new | closed |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for name in args.datasets:
        data = load(name)
        ordered = data.points.shape[1] == 2 and looks_like_contour(data.points)
        for degree in args.degrees:
            for method, poly in _fits(data, degree, methods):
                extract, zs = _best(1, lambda: extract_zero_set(poly, points=data.points))
                t_old = t_new = math.inf
                for _ in range(args.repeat):  # alternate, so that both see the same machine load
                    t, old = _best(1, lambda: old_quality(zs, data.points, data.faces, ordered))
                    t_old = min(t_old, t)
                    t, new = _best(1, lambda: quality(zs, data.points, faces=data.faces, ordered_contour=ordered))
                    t_new = min(t_new, t)
                delta = [new.f_score - old["f_score"], new.precision - old["precision"], new.recall - old["recall"]]
                same = new.n_spurious == old["n_spurious"] and new.closed == old["closed"]
                rows.append(dict(dim=data.points.shape[1], old=t_old, new=t_new, extract=extract, delta=delta,
                                 same=same))
                print(f"| {name} | {degree} | {method} | {t_old:.3f} | {t_new:.3f} | {t_old / t_new:.1f} | "
                      f"{old['f_score']:.4f} | {delta[0]:+.4f} | {delta[1]:+.4f} | {delta[2]:+.4f} | "
                      f"{old['n_spurious']}/{new.n_spurious} | {old['closed']}/{new.closed} |", flush=True)
    print()
    for label, sel in (("all", rows), ("3D", [r for r in rows if r["dim"] == 3]),
                       ("2D", [r for r in rows if r["dim"] == 2])):
        if not sel:
            continue
        old, new, ext = (sum(r[key] for r in sel) for key in ("old", "new", "extract"))
        worst = min(r["old"] / r["new"] for r in sel)
        print(f"{label}: {len(sel)} cases, measuring {old:.2f} s -> {new:.2f} s (x{old / new:.1f}, worst case "
              f"x{worst:.1f}); with the extraction {old + ext:.2f} s -> {new + ext:.2f} s (x{(old + ext) / (new + ext):.1f})")
    worst = np.max(np.abs([r["delta"] for r in rows]), axis=0)
    print(f"max |ΔF| = {worst[0]:.4f}, max |ΔP| = {worst[1]:.4f}, max |ΔR| = {worst[2]:.4f}; "
          f"n_spurious and closed identical in {sum(r['same'] for r in rows)} of {len(rows)} cases")
    if worst.max() > 0.005 or not all(r["same"] for r in rows):
        sys.exit(1)


if __name__ == "__main__":
    main()

"""The five experiments of Section 5: each runs its fits (through :mod:`.runs`) and returns plain records.

Every ``run_*`` function takes the run's :class:`~ipfit.reproduce.data.Workspace` (data,
seed, configuration; it also keeps the fitted polynomials for the figures) and a ``log``
callable, and returns the experiment's part of ``results.json``:

1. :func:`run_delta`: the δ sweep at degree 4 on the boot (Fig. 7);
2. :func:`run_adaptive`: the adaptive degree search on the six datasets with DE and with PSO
   (Figs. 8–13), beside the classic linear and 3L fits at the selected degrees;
3. :func:`run_ridge`: 3L + ridge regression for several κ against our fit (Figs. 14–15);
4. :func:`run_noise`: Gaussian noise with re-estimated normals (Fig. 16);
5. :func:`run_convergence`: distance per iteration of PSO, DE and the L-BFGS polish.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..degree.adaptive import select_degree
from .config import METHODS, eps_key, selected_degree
from .data import Data, Workspace, rng_for, with_noise
from .formatting import fmt
from .measure import (
    contour_roundness,
    fit_entry,
    history_entry,
    quality_entry,
    refine_summary,
    ridge_scale,
    zero_set_geometry,
)
from .runs import adaptive_fit, linear_fit, polish_fit, refine_fit, ridge_fit

__all__ = ["run_delta", "run_adaptive", "run_adaptive_one", "run_ridge", "run_noise", "run_convergence",
           "EXPERIMENT_RUNNERS"]

Log = Callable[[str], None]


# -- 1: δ -----------------------------------------------------------------------------------------

def run_delta(ws: Workspace, log: Log, results: Mapping) -> dict:
    """Fig. 7: DE at degree 4 on the boot for each δ (several seeds: instability shows across them)."""
    cfg = ws.cfg
    data = ws.dataset(cfg.delta_dataset)
    runs = []
    for delta in cfg.delta_values:
        for k in range(cfg.delta_seeds):
            res = refine_fit(data, cfg.delta_degree, "de", cfg, delta=delta,
                             rng=rng_for(ws.seed, "delta", repr(delta), str(k)))
            entry = fit_entry(res.polynomial, data, cfg, res.seconds, delta=delta, delta_value=delta, seed_index=k,
                              **refine_summary(res))
            runs.append(entry)
            ws.polys[("delta", delta, k)] = res.polynomial
            log(f"delta {delta:g} seed {k}: distance {entry['distance']:.4g}, smoothness {entry['smoothness']:.4f}, "
                f"F {fmt(entry['f_score'], 3)}, spurious {entry['n_spurious']}")
    per_delta = [aggregate(delta, [r for r in runs if r["delta_value"] == delta]) for delta in cfg.delta_values]
    return {"dataset": data.describe(), "degree": cfg.delta_degree, "method": "de", "seeds": cfg.delta_seeds,
            "runs": runs, "per_delta": per_delta}


def aggregate(delta: float, runs: Sequence[dict]) -> dict:
    """The runs at one δ summed up: F-score range, means, spurious components, clean runs."""
    def values(key):
        return [r[key] for r in runs if r[key] is not None]

    f = values("f_score")
    return {"delta": delta, "n": len(runs),
            "f_min": min(f) if f else None, "f_mean": float(np.mean(f)) if f else None, "f_max": max(f) if f else None,
            "smoothness_mean": float(np.mean(values("smoothness"))),
            "dissimilarity_mean": float(np.mean(values("dissimilarity"))),
            "spurious_max": max(values("n_spurious"), default=None),
            "all_closed": all(bool(r["closed"]) for r in runs),
            "n_clean": sum(bool(r["closed"]) and r["n_spurious"] == 0 for r in runs)}


# -- 2: adaptive --------------------------------------------------------------------------------

def run_adaptive_one(data: Data, method: str, ws: Workspace) -> dict:
    """One whole adaptive path with ``method`` and the degree Algorithm 1 selects on it for each ε."""
    cfg = ws.cfg
    result, records = adaptive_fit(data, method, cfg, rng_for(ws.seed, "adaptive", data.name, method))
    path: list[dict[str, Any]] = []
    for d in result.degrees:
        entry: dict[str, Any] = {"degree": d.degree, "distance": d.distance, "dissimilarity": d.dissimilarity,
                 "smoothness": d.smoothness, "seconds": d.seconds, "method": d.polynomial.method}
        entry.update(quality_entry(d.polynomial, data, cfg))
        entry.update(refine_summary(records[d.degree]))
        entry["coefficients"] = [float(c) for c in d.polynomial.coefficients]
        path.append(entry)
        ws.polys[("adaptive", data.name, method, d.degree)] = d.polynomial
    degrees = [p["degree"] for p in path]
    smooth = [p["smoothness"] for p in path]
    selection = {}
    for eps in cfg.epsilons:
        index, reason = select_degree(degrees, smooth, eps)
        selection[eps_key(eps)] = {"epsilon": eps, "degree": degrees[index], "reason": reason}
    return {"dataset": data.name, "method": method, "max_degree": cfg.max_degree(data.dim),
            "path_seconds": result.seconds, "path": path, "selection": selection}


def run_adaptive(ws: Workspace, log: Log, results: Mapping) -> dict:
    """Figs. 8–13: one adaptive path per dataset and method; classic and 3L at the selected degrees."""
    out: dict[str, Any] = {"datasets": {}}
    for name in ws.cfg.datasets:
        data = ws.dataset(name)
        entry: dict[str, Any] = {"data": data.describe(), "runs": {}, "linear": {}}
        for method in METHODS:
            run = run_adaptive_one(data, method, ws)
            entry["runs"][method] = run
            sel = ", ".join(f"ε={k}: {v['degree']}" for k, v in run["selection"].items())
            log(f"adaptive {name} {method}: smoothness "
                + " ".join(f"{p['degree']}:{p['smoothness']:.4f}" for p in run["path"])
                + f" -> {sel} ({run['path_seconds']:.0f} s)")
        wanted = sorted({s["degree"] for run in entry["runs"].values() for s in run["selection"].values()})
        for degree in wanted:
            for lin in ("lstsq", "3l"):
                poly, seconds, notes = linear_fit(lin, data, degree)
                ws.polys[("linear", name, lin, degree)] = poly
                entry["linear"][f"{lin}@{degree}"] = fit_entry(poly, data, ws.cfg, seconds, warnings=notes)
        out["datasets"][name] = entry
    return out


# -- 3: 3L + ridge ------------------------------------------------------------------------------

def run_ridge(ws: Workspace, log: Log, results: Mapping) -> dict:
    """Figs. 14–15: 3L + ridge (κ grid) against our DE fit at the degree our method selected (ε = 0.01)."""
    cfg = ws.cfg
    out: dict[str, Any] = {"kappas": list(cfg.kappas), "datasets": {}}
    eps = cfg.selection_epsilon
    for name in cfg.ridge_datasets:
        data = ws.dataset(name)
        degree = selected_degree(results, name, "de", eps)
        source = "adaptive experiment"
        poly = ws.polys.get(("adaptive", name, "de", degree))
        if degree is None or poly is None:  # the adaptive experiment was not run: run DE's path here
            degree = run_adaptive_one(data, "de", ws)["selection"][eps_key(eps)]["degree"]
            poly = ws.polys[("adaptive", name, "de", degree)]
            source = "adaptive DE run made for this experiment"
        ours = fit_entry(poly, data, cfg, 0.0, **zero_set_geometry(poly, data))
        ours["seconds"] = None
        fits = []
        scale = ridge_scale(data, degree)
        for kappa in (0.0,) + tuple(cfg.kappas):
            rpoly, seconds = ridge_fit(data, degree, kappa)
            entry = fit_entry(rpoly, data, cfg, seconds, kappa=kappa, relative_weight=kappa * scale["median"],
                              **zero_set_geometry(rpoly, data))
            fits.append(entry)
            ws.polys[("ridge", name, kappa)] = rpoly
            log(f"ridge {name} degree {degree} kappa {kappa:g}: roundness {fmt(entry['roundness'], 3)}, "
                f"max error {fmt(entry['max_error'], 3)}, F {fmt(entry['f_score'], 3)}")
        ws.polys[("ridge-ours", name)] = poly
        out["datasets"][name] = {"data": data.describe(), "degree": degree, "epsilon": eps, "ours_source": source,
                                 "ours": ours, "fits": fits, "data_roundness": contour_roundness(data.ref_points),
                                 "ridge_scale": scale}
    return out


# -- 4: noise -----------------------------------------------------------------------------------

def run_noise(ws: Workspace, log: Log, results: Mapping) -> dict:
    """Fig. 16: Gaussian noise (σ × box diagonal), normals re-estimated, adaptive DE with ε = 0.01."""
    cfg = ws.cfg
    out: dict[str, Any] = {"sigmas": list(cfg.noise_sigmas), "epsilon": cfg.noise_epsilon, "method": "de",
                           "datasets": {}}
    for name in cfg.noise_datasets:
        clean = ws.dataset(name)
        runs = []
        for sigma in cfg.noise_sigmas:
            noisy, k, agreement = with_noise(clean, sigma, ws.seed)
            result, records = adaptive_fit(noisy, "de", cfg, rng_for(ws.seed, f"noise{sigma!r}", name, "de"),
                                           epsilon=cfg.noise_epsilon)
            chosen = result.at_degree(result.selected_degree)
            entry = fit_entry(chosen.polynomial, noisy, cfg, chosen.seconds, sigma=sigma, normal_agreement=agreement,
                              normal_k=k, selected_degree=result.selected_degree, reason=result.reason,
                              path=[{"degree": d.degree, "smoothness": d.smoothness} for d in result.degrees],
                              path_seconds=result.seconds, **refine_summary(records[result.selected_degree]))
            runs.append(entry)
            ws.polys[("noise", name, sigma)] = (chosen.polynomial, noisy.points)
            log(f"noise {name} sigma {sigma:g}: degree {result.selected_degree} ({result.reason}), "
                f"F {fmt(entry['f_score'], 3)}, normal agreement {agreement:.3f}")
        out["datasets"][name] = {"data": clean.describe(), "runs": runs}
    return out


# -- 5: convergence -----------------------------------------------------------------------------

def run_convergence(ws: Workspace, log: Log, results: Mapping) -> dict:
    """Best distance per iteration: DE, PSO (generations), the polish alone and after each (L-BFGS steps)."""
    cfg = ws.cfg
    out: dict[str, Any] = {"datasets": {}}
    for name in cfg.convergence_datasets:
        data = ws.dataset(name)
        entry: dict[str, Any] = {"dataset": data.describe(), "degrees": {}}
        for degree in cfg.convergence_degrees:
            runs = {}
            for method in METHODS:
                res = refine_fit(data, degree, method, cfg, delta=cfg.delta,
                                 rng=rng_for(ws.seed, "convergence", name, str(degree), method))
                runs[method] = history_entry(res, res.history)
                after = polish_fit(data, degree, cfg, start=res.polynomial)
                runs[f"{method}+polish"] = history_entry(
                    after, np.concatenate([res.history, after.polish_history]), nfev=res.nfev + after.nfev,
                    seconds=res.seconds + after.seconds, best_seed_distance=res.best_start_value,
                    switch=len(res.history) - 1)
            res = polish_fit(data, degree, cfg)
            runs["polish"] = history_entry(res, np.concatenate([res.history, res.polish_history]))
            entry["degrees"][str(degree)] = {"degree": degree, "runs": runs}
            log(f"convergence {name} degree {degree}: "
                + ", ".join(f"{m} {r['final']:.5g}" for m, r in runs.items())
                + f" (best seed {runs['de']['best_seed_distance']:.5g})")
        out["datasets"][name] = entry
    return out


#: The experiments by name, in report order (:data:`~ipfit.reproduce.config.EXPERIMENTS`).
EXPERIMENT_RUNNERS: dict[str, Callable[[Workspace, Log, Mapping], dict]] = {
    "delta": run_delta, "adaptive": run_adaptive, "ridge": run_ridge, "noise": run_noise,
    "convergence": run_convergence,
}

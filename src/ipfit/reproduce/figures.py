"""The report's figures, drawn from a run's results and the polynomials it kept.

One PNG per experiment part: the δ sweep, each dataset × method of the adaptive runs, each
ridge dataset, the noise grid and the convergence curves. :func:`write_figures` draws them all
into the output folder (each file written atomically) and returns ``{key: file name}``; a
figure that cannot be drawn is logged and left out, never half-written.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._utils.atomic import atomic_path
from ..exceptions import IpfitError
from ..viz.plotting import METHOD_TITLES, plot_curve, plot_points, plot_result, plot_surface
from ..zeroset.extract import data_bounds
from .config import METHODS, Config, eps_key
from .data import Workspace
from .formatting import fmt

__all__ = ["write_figures", "figure_delta", "figure_adaptive", "figure_ridge", "figure_noise", "figure_convergence"]


def _figure(ncols: int, nrows: int, size: float = 2.6, extra_height: float = 0.0):
    from matplotlib.figure import Figure

    return Figure(figsize=(size * ncols, size * nrows + extra_height), layout="constrained")


def _draw_fit(fig, nrows, ncols, index, poly, points, cfg: Config, title: str, box=None):
    dim = points.shape[1]
    ax = fig.add_subplot(nrows, ncols, index, projection="3d" if dim == 3 else None)
    try:
        if dim == 2:
            plot_curve(poly, points, ax, bounds=box, resolution=cfg.plot_resolution_2d, axis_off=True)
        else:
            plot_surface(poly, points, ax, bounds=box, resolution=cfg.plot_resolution_3d, max_faces=12000,
                         axis_off=True)
    except IpfitError:
        if dim == 2:
            plot_points(points, ax)
        ax.set_axis_off()
        title += "\n(no zero set drawn)"
    ax.set_title(title, fontsize="small")
    return ax


def _box(points: NDArray) -> NDArray:
    return data_bounds(points, 0.25)


def figure_delta(exp: Mapping, ws: Workspace, path: Path) -> None:
    """Fig. 7: one panel per δ (columns) and seed (rows)."""
    cfg = ws.cfg
    data = ws.data[exp["dataset"]["name"]]
    deltas = [p["delta"] for p in exp["per_delta"]]
    seeds = exp["seeds"]
    fig = _figure(len(deltas), seeds, size=2.2)
    box = _box(data.ref_points)
    for k in range(seeds):
        for j, delta in enumerate(deltas):
            run = next(r for r in exp["runs"] if r["delta_value"] == delta and r["seed_index"] == k)
            title = f"δ = {delta:g}" + (f", seed {k}" if seeds > 1 else "") + \
                f"\nF {fmt(run['f_score'], 2)}, smooth {run['smoothness']:.3f}"
            _draw_fit(fig, seeds, len(deltas), k * len(deltas) + j + 1, ws.polys[("delta", delta, k)],
                      data.points, cfg, title, box)
    fig.suptitle(f"{data.name}, degree {exp['degree']}, DE, for each δ")
    fig.savefig(path, dpi=cfg.dpi)


def figure_adaptive(name: str, method: str, results: Mapping, ws: Workspace, path: Path) -> None:
    """Figs. 8–13: the library's result figure of one adaptive run, with the linear fits beside it."""
    cfg = ws.cfg
    data = ws.data[name]
    run = results["adaptive"]["datasets"][name]["runs"][method]
    eps = eps_key(cfg.selection_epsilon)
    selected = run["selection"][eps]["degree"]
    poly = ws.polys[("adaptive", name, method, selected)]
    payload = poly.to_dict()
    payload["selected_degree"] = selected
    payload["degrees"] = [{k: p[k] for k in ("degree", "smoothness", "method", "coefficients")} for p in run["path"]]
    comparisons = {}
    degrees = [selected] + sorted({s["degree"] for s in run["selection"].values()} - {selected})
    for degree in degrees:
        suffix = "" if degree == selected else " (ε=0 choice)"
        for lin in ("lstsq", "3l"):
            lpoly = ws.polys[("linear", name, lin, degree)]
            comparisons[METHOD_TITLES[lin] + suffix] = {"coefficients": [float(c) for c in lpoly.coefficients]}
    payload["comparisons"] = comparisons
    fig = plot_result(payload, points=data.points,
                      resolution=cfg.plot_resolution_3d if data.dim == 3 else cfg.plot_resolution_2d,
                      title=f"{name}, adaptive fit with {METHOD_TITLES[method]} (selected: degree {selected} at "
                            f"ε={eps})", max_faces=12000)
    fig.savefig(path, dpi=cfg.dpi)


def figure_ridge(name: str, exp: Mapping, ws: Workspace, path: Path) -> None:
    """Figs. 14–15: our fit, then 3L + ridge for each κ."""
    cfg = ws.cfg
    data = ws.data[name]
    ds = exp["datasets"][name]
    panels = [(ws.polys[("ridge-ours", name)], f"ours (DE), degree {ds['degree']}", ds["ours"])]
    for fit in ds["fits"]:
        label = "3L (κ = 0)" if fit["kappa"] == 0 else f"3L+RRR κ = {fit['kappa']:g}"
        panels.append((ws.polys[("ridge", name, fit["kappa"])], label, fit))
    ncols = min(4, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    fig = _figure(ncols, nrows, size=2.6)
    box = _box(data.ref_points)
    for i, (poly, label, entry) in enumerate(panels):
        title = f"({chr(97 + i)}) {label}\nround {fmt(entry['roundness'], 3)}, max err {fmt(entry['max_error'], 3)}"
        _draw_fit(fig, nrows, ncols, i + 1, poly, data.points, cfg, title, box)
    fig.suptitle(f"{name}: our method against 3L + ridge regression")
    fig.savefig(path, dpi=cfg.dpi)


def figure_noise(exp: Mapping, ws: Workspace, path: Path) -> None:
    """Fig. 16: one panel per dataset (rows) and σ (columns), drawn over the noisy points."""
    cfg = ws.cfg
    names = list(exp["datasets"])
    sigmas = exp["sigmas"]
    fig = _figure(len(sigmas), len(names), size=2.4)
    for r, name in enumerate(names):
        data = ws.data[name]
        box = _box(data.ref_points)
        for c, sigma in enumerate(sigmas):
            poly, noisy = ws.polys[("noise", name, sigma)]
            run = next(x for x in exp["datasets"][name]["runs"] if x["sigma"] == sigma)
            title = f"{name}, σ = {sigma:g}\ndegree {run['selected_degree']}, F {fmt(run['f_score'], 2)}"
            _draw_fit(fig, len(names), len(sigmas), r * len(sigmas) + c + 1, poly, noisy, cfg, title, box)
    fig.suptitle("Fits to noisy data (σ relative to the box diagonal), normals re-estimated")
    fig.savefig(path, dpi=cfg.dpi)


def figure_convergence(exp: Mapping, cfg: Config, path: Path) -> None:
    """Best distance per iteration of every refinement, one panel per dataset and degree."""
    names = list(exp["datasets"])
    ncols = max(len(exp["datasets"][n]["degrees"]) for n in names)
    fig = _figure(ncols, len(names), size=3.4)
    styles = {"de": ("#1f77b4", "-"), "pso": ("#d62728", "-"), "de+polish": ("#1f77b4", ":"),
              "pso+polish": ("#d62728", ":"), "polish": ("#2ca02c", "-")}
    for r, name in enumerate(names):
        for i, deg in enumerate(exp["datasets"][name]["degrees"].values()):
            ax = fig.add_subplot(len(names), ncols, r * ncols + i + 1)
            for method, run in deg["runs"].items():
                color, style = styles.get(method, ("k", "-"))
                h = np.asarray(run["history"])
                ax.plot(np.arange(len(h)), h, style, color=color, lw=1.4, label=METHOD_TITLES.get(method, method))
            ax.axhline(deg["runs"]["de"]["best_seed_distance"], color="0.5", lw=0.8, ls="--",
                       label="best linear seed")
            ax.set_yscale("log")
            ax.set_xlabel("iteration (generation or L-BFGS step)")
            ax.set_ylabel("best distance")
            ax.set_title(f"{name}, degree {deg['degree']}", fontsize="medium")
            ax.grid(alpha=0.3, which="both")
            if r == 0 and i == 0:
                ax.legend(fontsize="x-small", frameon=False)
    fig.suptitle("Convergence of the refinements")
    fig.savefig(path, dpi=cfg.dpi)


def _shrink_png(path: Path) -> None:
    """Re-save a figure with a 256-colour palette: a third of the size, no visible change for plots."""
    from PIL import Image

    with Image.open(path) as im:
        small = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    small.save(path, format="PNG", optimize=True)


def write_figures(results: Mapping, ws: Workspace, out: Path, log: Callable[[str], None]) -> dict[str, str]:
    """Draw every figure the experiments in ``results`` call for into ``out``; ``{key: file name}``."""
    cfg = ws.cfg
    figures: dict[str, str] = {}

    def attempt(key: str, filename: str, draw: Callable[[Path], None]) -> None:
        try:
            with atomic_path(out / filename) as tmp:
                draw(tmp)
                _shrink_png(tmp)
            figures[key] = filename
        except IpfitError as exc:
            log(f"figure {filename} not drawn: {exc}")

    if "delta" in results:
        attempt("delta", "fig_delta.png", lambda p: figure_delta(results["delta"], ws, p))
    if "adaptive" in results:
        for name in results["adaptive"]["datasets"]:
            for method in METHODS:
                attempt(f"adaptive/{name}/{method}", f"fig_adaptive_{name}_{method}.png",
                        partial(figure_adaptive, name, method, results, ws))
    if "ridge" in results:
        for name in results["ridge"]["datasets"]:
            attempt(f"ridge/{name}", f"fig_ridge_{name}.png",
                    partial(figure_ridge, name, results["ridge"], ws))
    if "noise" in results:
        attempt("noise", "fig_noise.png", lambda p: figure_noise(results["noise"], ws, p))
    if "convergence" in results:
        attempt("convergence", "fig_convergence.png", lambda p: figure_convergence(results["convergence"], cfg, p))
    log(f"figures: {len(figures)} written")
    return figures

"""Figures like the paper's Figs. 8–13, one per result: ``python experiments/figures.py``.

Each figure shows the points, the zero set of every degree tried, the smoothness against
the degree, and the classic linear and 3L fits at the selected degree.

Usage::

    python experiments/figures.py --results RESULTS_DIR -o FIGURES_DIR [--fit-missing]
    python experiments/figures.py A.json B.json -o FIGURES_DIR

The figure of ``NAME.json`` is ``FIGURES_DIR/NAME.png``. The data of a result is read from
its recorded ``"input": {"source": ...}`` (a path or a bundled dataset name), else from the
bundled dataset named like the file. With ``--fit-missing``, every bundled dataset without a
result in RESULTS_DIR is fitted first (``ipfit fit NAME``), so one command produces the
figures of every bundled dataset. A result without ``"comparisons"`` gets the classic
(``lstsq``) and ``3l`` fits at its selected degree computed from the data, unless
``--no-comparisons``; the result files themselves are never changed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one


# The bundled scans are y-up (Stanford bunny, Turk's apple); everything else is drawn z-up.
DEFAULT_UP = {"bunny": "y", "apple": "y"}


def _bundled_names() -> list[str]:
    try:
        from ipfit.datasets import bundled
    except ImportError:
        return []
    return list(bundled.dataset_names())


def load_data(name: str, result: dict):
    """(points, normals, faces) of a result's data, or (None, None, None) when not found."""
    from ipfit import load

    recorded = result.get("input")
    candidates = []
    if isinstance(recorded, dict) and isinstance(recorded.get("source"), str):
        candidates.append(recorded["source"])
    candidates.append(name)
    for spec in candidates:
        try:
            data = load(spec)
        except Exception:  # noqa: BLE001  try the next candidate; a figure without points still helps
            continue
        if data.points.shape[1] == result.get("dim", data.points.shape[1]):
            return data.points, data.normals, data.faces
    return None, None, None


def add_comparisons(result: dict, points: np.ndarray, normals: np.ndarray | None) -> dict:
    """A copy of ``result`` with the classic and 3L fits at its selected degree."""
    import ipfit
    from ipfit.polynomial import Normalization

    degree = int(result.get("selected_degree") or result["degree"])
    if normals is None:
        from ipfit.normals import estimate_normals

        normals = estimate_normals(points)
    top = Normalization(result["normalization"]["center"], result["normalization"]["scale"])
    out = dict(result)
    comparisons = {}
    for name, fit in (("lstsq", lambda: ipfit.fit_lstsq(points, normals, degree)),
                      ("3l", lambda: ipfit.fit_3l(points, normals, degree))):
        poly = fit()
        entry = {"degree": degree, "coefficients": [float(c) for c in poly.coefficients]}
        same = (np.allclose(poly.normalization.center, top.center, rtol=0, atol=1e-12 * top.scale)
                and abs(poly.normalization.scale - top.scale) <= 1e-12 * top.scale)
        if not same:
            entry["normalization"] = poly.normalization.to_dict()
        comparisons[name] = entry
    out["comparisons"] = comparisons
    return out


def fit_dataset(name: str, results_dir: Path, method: str) -> Path:
    """Fit a bundled dataset with the ``ipfit fit`` command; returns the result's path."""
    from ipfit.cli import main as ipfit_main

    prefix = results_dir / name
    code = ipfit_main(["fit", name, "-o", str(prefix), "--method", method, "--no-picture", "--no-zero-set", "-q"])
    if code != 0:
        raise SystemExit(f"figures: fitting {name} failed (exit code {code})")
    return prefix.with_suffix(".json")


def make_figure(result_path: Path, out_dir: Path, *, comparisons: bool = True, resolution: int | None = None,
                up: str | None = None) -> Path:
    from ipfit.viz.plotting import plot_result
    from ipfit.degree.results import load_result

    name = result_path.stem
    result = load_result(result_path)
    points, normals, _ = load_data(name, result)
    if comparisons and points is not None and not result.get("comparisons"):
        result = add_comparisons(result, points, normals)
    target = out_dir / f"{name}.png"
    plot_result(result, points=points, path=target, title=name, resolution=resolution,
                up=up or DEFAULT_UP.get(name, "z"))
    return target


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="*", type=Path, help="result JSON files")
    parser.add_argument("--results", dest="results_dir", type=Path, help="folder of result JSON files (NAME.json)")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/figures"), help="figure folder")
    parser.add_argument("--fit-missing", action="store_true",
                        help="fit every bundled dataset without a result in --results first")
    parser.add_argument("--method", default="3l", help="fixed-degree method for --fit-missing (default 3l)")
    parser.add_argument("--no-comparisons", action="store_true", help="do not add classic/3L fits to the figures")
    parser.add_argument("--resolution", type=int, help="grid nodes along the box's longest side")
    parser.add_argument("--up", choices=("x", "y", "z"), help="3D vertical axis (default: per dataset, else z)")
    args = parser.parse_args(argv)

    paths = list(args.results)
    if args.results_dir is not None:
        args.results_dir.mkdir(parents=True, exist_ok=True)
        if args.fit_missing:
            for name in _bundled_names():
                if not (args.results_dir / f"{name}.json").exists():
                    print(f"fitting {name} ...", file=sys.stderr)
                    fit_dataset(name, args.results_dir, args.method)
        paths.extend(sorted(args.results_dir.glob("*.json")))
    if not paths:
        parser.error("no results: pass result files or --results DIR (with --fit-missing to fit the bundled data)")
    args.output.mkdir(parents=True, exist_ok=True)
    for path in paths:
        target = make_figure(path, args.output, comparisons=not args.no_comparisons, resolution=args.resolution,
                             up=args.up)
        print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main())

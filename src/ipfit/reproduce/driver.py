"""The run: check the arguments, run the experiments, then write results, figures and report.

:func:`reproduce` is what ``ipfit reproduce`` calls. The order is fixed: experiments, then
``results.json``'s content is made plain JSON (:func:`~ipfit.polynomial.to_jsonable`), the
figures are drawn, the verdicts computed from the plain results, and the two text files are
written atomically; figures of an earlier run that this run did not draw are removed.
"""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._utils.atomic import write_text_atomic
from .._utils.validation import check_int, error
from ..exceptions import InvalidInputError
from ..polynomial import to_jsonable
from .config import DEFAULT_CONFIG, EXPERIMENTS, Config, get_config
from .data import Workspace
from .experiments import EXPERIMENT_RUNNERS
from .figures import write_figures
from .report import render_report
from .verdicts import summarize

__all__ = ["reproduce", "load_results", "dumps"]


def reproduce(out: str | os.PathLike, config: str | Config = DEFAULT_CONFIG, *, seed: int = 0,
              only: Sequence[str] | None = None, datasets: Sequence[str] | None = None,
              log: Callable[[str], None] | None = None, command: str | None = None) -> dict:
    """Run the experiments and write ``results.json``, ``README.md`` and the figures into ``out``.

    Parameters
    ----------
    out : output folder (created).
    config : ``'quick'``, ``'medium'``, ``'full'`` (default) or a :class:`~ipfit.reproduce.config.Config`.
    seed : the run's seed; every random choice derives from it.
    only : experiments to run (default all, see :data:`~ipfit.reproduce.config.EXPERIMENTS`).
    datasets : restrict the adaptive experiment to these datasets.
    log : called with one line per step (e.g. ``print``).
    command : the command line recorded in the report.

    Returns
    -------
    dict : the results (as written to ``results.json``).
    """
    cfg = get_config(config, datasets)
    unknown = sorted(set(only or ()) - set(EXPERIMENTS))
    if unknown:
        raise error("--only", f"some of {', '.join(EXPERIMENTS)}", repr(unknown[0]), "Drop or correct it.")
    chosen = tuple(e for e in EXPERIMENTS if not only or e in set(only))
    seed = check_int(seed, "--seed", minimum=0)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"--output: {out} exists and is not a folder. Choose another folder.")
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()

    def say(message: str) -> None:
        if log is not None:
            log(f"[{time.perf_counter() - started:7.1f} s] {message}")

    ws = Workspace(cfg, seed)
    results: dict[str, Any] = {"config": to_jsonable(asdict(cfg))}
    timings: dict[str, float] = {}
    for name in chosen:
        t0 = time.perf_counter()
        say(f"experiment {name}")
        results[name] = EXPERIMENT_RUNNERS[name](ws, say, results)
        timings[name] = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = to_jsonable(results)
    results["data"] = to_jsonable({k: v.describe() for k, v in ws.data.items()})
    results["figures"] = write_figures(results, ws, out, say)
    timings["figures"] = time.perf_counter() - t0
    results["summary"] = to_jsonable(summarize(results))
    results["run"] = to_jsonable({
        "command": command
        or f"ipfit reproduce --output {out}" + ("" if cfg.name == DEFAULT_CONFIG else f" --{cfg.name}"),
        "seed": seed, "experiments": list(chosen), "ipfit_version": __version__, "commit": _commit(),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
                   f"NumPy {np.__version__}",
        "timings": timings, "seconds": time.perf_counter() - started})
    write_text_atomic(out / "results.json", dumps(results))
    write_text_atomic(out / "README.md", render_report(results))
    for old in out.glob("fig_*.png"):
        if old.name not in set(results["figures"].values()):
            old.unlink()
    say(f"wrote {out / 'README.md'} and {out / 'results.json'}")
    return results


def _commit() -> str | None:
    """``git describe`` of the checkout ipfit runs from, or None outside one."""
    try:
        root = Path(__file__).resolve().parents[3]
        out = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty"], capture_output=True,
                             text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None if out.returncode == 0 else None


_NUMBER_LIST = re.compile(r"\[\n\s+(-?[\d.eE+-]+(?:,\n\s+-?[\d.eE+-]+)*)\n\s*\]")


def dumps(results: Mapping) -> str:
    """``results.json``'s text: indented, but every list of numbers on one line.

    >>> print(dumps({"f": [1, 2.5], "name": "boot"}), end="")
    {
     "f": [1, 2.5],
     "name": "boot"
    }
    """
    text = json.dumps(results, indent=1, allow_nan=False, ensure_ascii=False)
    return _NUMBER_LIST.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text) + "\n"


def load_results(folder: str | os.PathLike) -> dict:
    """The ``results.json`` of a reproduction folder."""
    path = Path(folder) / "results.json"
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InvalidInputError(f"{path}: no such file. Run `ipfit reproduce --output {folder}` first.") from None

"""Reproduce the paper's experiments (Interian et al. 2017, Section 5) on ipfit's datasets.

:func:`reproduce` runs five experiments with fixed seeds and writes, into one folder,
``results.json`` (every number of the run), ``README.md`` (the report, rendered from
``results.json`` alone by :func:`render_report`) and PNG figures. A summary table compares the
run's numbers with the paper's claims; the verdicts are computed (:func:`summarize`), never typed.

The package, in the order a run goes through it:

- :mod:`.config`: the experiments, the paper's numbers, and the ``quick`` / ``medium`` /
  ``full`` configurations (:data:`CONFIGS`);
- :mod:`.data`: the bundled datasets as fitted and as scored, seeded streams, noisy copies;
- :mod:`.runs`: every fit of a run (the only module that calls ``refine``, ``fit_adaptive``
  and ``fit_linear``);
- :mod:`.measure`: what is recorded about one fit;
- :mod:`.experiments`: the five experiments (δ, adaptive, ridge, noise, convergence);
- :mod:`.verdicts`: the paper's claims against the numbers;
- :mod:`.figures` and :mod:`.report`: the PNG figures and the Markdown page;
- :mod:`.driver`: :func:`reproduce` itself, and reading/writing ``results.json``.
"""

from .config import (
           CONFIGS,
           DATASETS,
           DEFAULT_CONFIG,
           EXPERIMENTS,
           METHODS,
           PAPER_DEGREES,
           PATH_EPSILON,
           Config,
           get_config,
)
from .data import Data, Workspace, noise_neighbours, noisy_normals, prepare_data, rng_for
from .driver import dumps, load_results, reproduce
from .experiments import run_adaptive, run_convergence, run_delta, run_noise, run_ridge
from .measure import ridge_scale
from .report import render_report
from .verdicts import summarize

__all__ = ["Config", "CONFIGS", "DEFAULT_CONFIG", "EXPERIMENTS", "DATASETS", "METHODS", "PAPER_DEGREES",
           "PATH_EPSILON", "get_config", "Data", "Workspace", "prepare_data", "rng_for", "noise_neighbours",
           "noisy_normals", "reproduce", "render_report", "summarize", "load_results", "dumps", "ridge_scale",
           "run_delta", "run_adaptive", "run_ridge", "run_noise", "run_convergence"]

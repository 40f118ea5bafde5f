"""What a reproduction run does: the experiments, the paper's numbers, and the three configurations.

Everything here is plain data. A :class:`Config` holds every setting of a run (all of them are
printed in the report header); :data:`CONFIGS` names the three that ``ipfit reproduce`` offers:

- ``quick``: a smoke test of seconds on small subsets (the test suite); its numbers mean nothing;
- ``medium``: the paper's parameters with 100 iterations instead of 500;
- ``full``: the paper's parameters, 3D data subsampled to 2,000 points (the committed report
  ``docs/reproduction``, the default).

>>> CONFIGS["full"].iterations, CONFIGS["quick"].iterations
(500, 5)
>>> get_config("full").max_degree(3)
8
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

from .._utils.validation import check_choice, error

__all__ = ["Config", "CONFIGS", "DEFAULT_CONFIG", "EXPERIMENTS", "DATASETS", "METHODS", "PAPER_DEGREES",
           "PATH_EPSILON", "get_config", "eps_key", "selected_degree"]

#: Experiment names, in report order.
EXPERIMENTS = ("delta", "adaptive", "ridge", "noise", "convergence")
#: The paper's datasets (Figs. 8–13), 2D first.
DATASETS = ("airplane", "boot", "butterfly", "apple", "duck", "bunny")
#: The paper's selected degrees per dataset: (ε = 0.01, ε = 0). ``">6"`` means the paper's
#: smoothness kept increasing (Figs. 9 and 13), so ε = 0 does not stop at the ε = 0.01 degree.
PAPER_DEGREES: dict[str, tuple[int, int | str]] = {
    "airplane": (4, 4), "boot": (6, ">6"), "butterfly": (4, 8), "apple": (4, 4), "duck": (6, 6), "bunny": (6, ">6"),
}
#: ε of the single adaptive run per dataset: below any possible smoothness change (smoothness
#: lies in [−1, 1]), so Algorithm 1 never stops early and the whole path up to G is fitted;
#: the rule is then applied to that one path for each ε of the report.
PATH_EPSILON = -3.0
#: Refinement methods compared in the adaptive runs: the paper's pure variants.
METHODS = ("de", "pso")


@dataclass(frozen=True)
class Config:
    """Every setting of a reproduction run (all are printed in the report header)."""

    name: str
    description: str
    iterations: int                      # metaheuristic generations (paper: 500)
    population: int | None = None        # None: 4 × the number of coefficients (paper)
    seeds: tuple[str, ...] | None = ("lstsq", "3l")  # linear start fits (paper: classic and 3L); None: ipfit's pool
    delta: float = 0.25                  # δ of the distance (paper: 0.25)
    epsilons: tuple[float, ...] = (0.0, 0.01)
    datasets: tuple[str, ...] = DATASETS
    max_degree_2d: int = 12
    max_degree_3d: int = 8
    points_2d: int | None = None         # cap on 2D contour points (every k-th point); None: all
    points_3d: int = 1000                # 3D points fitted (uniform random subset)
    bunny_source: str = "bunny"          # bundled name the bunny is taken from
    delta_dataset: str = "boot"
    delta_degree: int = 4
    delta_values: tuple[float, ...] = (0.0, 0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.0)
    delta_seeds: int = 3
    ridge_datasets: tuple[str, ...] = ("airplane", "butterfly")
    kappas: tuple[float, ...] = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
    noise_datasets: tuple[str, ...] = ("boot", "apple")
    noise_sigmas: tuple[float, ...] = (0.0, 0.005, 0.01, 0.02, 0.03)
    noise_epsilon: float = 0.01
    convergence_datasets: tuple[str, ...] = ("boot", "apple")
    convergence_degrees: tuple[int, ...] = (4, 6, 8)
    quality_resolution_3d: int = 96
    quality_max_samples: int = 100_000
    plot_resolution_2d: int = 400
    plot_resolution_3d: int = 64
    dpi: int = 80

    def max_degree(self, dim: int) -> int:
        """The highest degree the adaptive search tries on ``dim``-dimensional data."""
        return self.max_degree_2d if dim == 2 else self.max_degree_3d

    @property
    def selection_epsilon(self) -> float:
        """The ε whose selected degree the ridge experiment and the figures use (0.01, the paper's)."""
        return 0.01 if 0.01 in self.epsilons else self.epsilons[-1]


CONFIGS: dict[str, Config] = {
    "quick": Config(
        name="quick", description="smoke test: tiny runs on small subsets (seconds); numbers not meaningful",
        iterations=5, max_degree_2d=6, max_degree_3d=4, convergence_datasets=("boot",), points_2d=300,
        points_3d=200, bunny_source="bunny_res4",
        delta_seeds=1, noise_sigmas=(0.0, 0.01, 0.03), convergence_degrees=(4, 6), quality_resolution_3d=40,
        quality_max_samples=20_000, plot_resolution_2d=160, plot_resolution_3d=24, dpi=60),
    "medium": Config(
        name="medium", description="the paper's parameters but 100 iterations instead of 500; 3D data "
        "subsampled to 1,000 points", iterations=100),
    "full": Config(
        name="full", description="the paper's parameters (500 iterations, population 4 × coefficients, "
        "δ = 0.25, classic and 3L seeds); 3D data subsampled to 2,000 points", iterations=500, points_3d=2000,
        delta_seeds=5, plot_resolution_3d=72),
}
#: The configuration of ``ipfit reproduce`` without --quick/--medium: the committed report.
DEFAULT_CONFIG = "full"


def get_config(config: str | Config = DEFAULT_CONFIG, datasets: Sequence[str] | None = None) -> Config:
    """The :class:`Config` named ``config`` (or ``config`` itself), restricted to ``datasets``.

    ``datasets`` limits the adaptive experiment; they stay in the paper's order.

    >>> get_config("quick", datasets=["bunny", "boot"]).datasets
    ('boot', 'bunny')
    >>> get_config("fast")
    Traceback (most recent call last):
    ...
    ipfit.exceptions.InvalidInputError: config: expected one of 'quick', 'medium', 'full', got str 'fast'.
    """
    cfg = config if isinstance(config, Config) else CONFIGS[check_choice(config, "config", CONFIGS)]
    if datasets:
        unknown = sorted(set(datasets) - set(DATASETS))
        if unknown:
            raise error("--datasets", f"some of {', '.join(DATASETS)}", repr(unknown[0]), "Drop or correct it.")
        cfg = replace(cfg, datasets=tuple(d for d in DATASETS if d in set(datasets)))
    return cfg


def eps_key(eps: float) -> str:
    """The key under which a run's results keep the degree selected with ε = ``eps``.

    >>> eps_key(0.01), eps_key(0.0)
    ('0.01', '0')
    """
    return f"{eps:g}"


def selected_degree(results: Mapping, name: str, method: str, eps: float) -> int | None:
    """The degree the adaptive run of ``method`` on ``name`` selected at ε, or None if it did not run."""
    try:
        return results["adaptive"]["datasets"][name]["runs"][method]["selection"][eps_key(eps)]["degree"]
    except (KeyError, TypeError):
        return None

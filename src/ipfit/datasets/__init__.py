"""Datasets: analytic shapes (``ipfit.datasets.synthetic``) and the bundled real data."""

from . import synthetic

__all__ = ["synthetic"]

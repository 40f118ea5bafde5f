"""Datasets: analytic shapes (:mod:`ipfit.datasets.synthetic`) and the bundled real data.

The bundled files and their credits are listed by :func:`list_datasets` (``ipfit datasets``);
:func:`load` reads a point file or a bundled dataset by name as one :class:`~ipfit.Cloud`.
"""

from . import synthetic
from .bundled import dataset_faces, dataset_names, dataset_path, list_datasets, load_dataset
from .collection import GeneratedShape, collection
from .loading import load

__all__ = ["synthetic", "collection", "GeneratedShape", "list_datasets", "dataset_names", "dataset_path",
           "load_dataset", "dataset_faces", "load"]

"""Scenes: several objects in one scan, each fitted with its own polynomial.

Here live the segmentation of a scan into objects (:mod:`.segment`: stray returns set aside,
dominant planes removed by RANSAC, the rest split by connectivity at a few times the point
spacing, tiny pieces reported as clutter; an image's separate silhouettes), the scene fit
(:func:`fit_scene`: one :func:`~ipfit.fit_adaptive` per object, on Dask through the batch
machinery when asked), its result and JSON (:class:`SceneResult`, :func:`load_scene`) and its
pictures (:mod:`.draw`: one figure and one viewer page for every object).
"""

from .fit import fit_scene, from_labels
from .results import SceneResult, SceneView, is_scene, load_scene
from .segment import Plane, PlaneModel, Segmentation, neck, segment

__all__ = ["fit_scene", "from_labels", "SceneResult", "SceneView", "load_scene", "is_scene", "segment",
           "Segmentation", "Plane", "PlaneModel", "neck"]

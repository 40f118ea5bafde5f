"""Using a fitted polynomial: source code in other languages (:mod:`~ipfit.analysis.codegen`), ray
intersections and rendering (:mod:`~ipfit.analysis.rays`), closest points on the zero set
(:mod:`~ipfit.analysis.projection`), curvature (:mod:`~ipfit.analysis.curvature`), invariant
descriptors (:mod:`~ipfit.analysis.invariants`) and shape retrieval with them
(:mod:`~ipfit.analysis.recognition`). ``ImplicitPolynomial.to_source``, ``intersect``, ``project``,
``curvature`` and ``hessian`` call these modules.

The functions ``curvature`` and ``invariants`` are not re-exported here: ``ipfit.analysis.curvature``
and ``ipfit.analysis.invariants`` are their modules.
"""

from .codegen import LANGUAGES, to_source
from .curvature import Curvature, hessian
from .invariants import descriptors, similarity
from .projection import Projection, project
from .rays import RayHits, intersect_rays, render

__all__ = [
    "to_source",
    "LANGUAGES",
    "RayHits",
    "intersect_rays",
    "render",
    "Projection",
    "project",
    "Curvature",
    "hessian",
    "descriptors",
    "similarity",
]

"""Using a fitted polynomial: source code in other languages (:mod:`~ipfit.analysis.codegen`), ray
intersections and rendering (:mod:`~ipfit.analysis.rays`), closest points on the zero set
(:mod:`~ipfit.analysis.projection`), curvature (:mod:`~ipfit.analysis.curvature`), invariant
descriptors (:mod:`~ipfit.analysis.invariants`) and shape retrieval with them
(:mod:`~ipfit.analysis.recognition`). ``ImplicitPolynomial.to_source``, ``intersect``, ``project``,
``curvature`` and ``hessian`` call these modules.

The public names are in :mod:`ipfit` (``ipfit.to_source``, ``ipfit.project``, ...); nothing is
re-exported here (see :mod:`ipfit.geometry`): ``poly.to_source()`` loads the code generator alone.
"""

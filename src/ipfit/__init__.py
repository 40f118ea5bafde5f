"""ipfit: fit implicit polynomial curves and surfaces to 2D and 3D point clouds.

The method is Interian et al. (2017): linear fits (classic least squares, 3L, 3L + ridge),
the distance measure dissimilarity + δ(1 − smoothness), metaheuristic refinement and
adaptive degree selection.

Every public name is here, in one ``__all__``. The package is grouped by concept: the core model
at the top level (``polynomial``, ``basis``, ``cloud``), then ``fitting`` (one degree), ``degree``
(choosing it), ``zeroset`` (extracting and measuring the zero set), ``geometry``, ``analysis``
(using a fit), ``viz``, ``io``, ``normals``, ``datasets``, ``batch``, ``scene`` (several objects in
one scan), ``reproduce`` and ``cli``;
``docs/architecture.md`` shows their layers.
"""

from __future__ import annotations

from .exceptions import ConditioningWarning, InvalidInputError, IpfitError, IpfitWarning, ReadError

# Loaded on first use (PEP 562): `ipfit` itself imports in milliseconds, so the command line
# owns SIGINT before numpy/scipy load and a Ctrl-C at start-up never prints a traceback.
# Name -> the module that defines it; None: the name is a module or subpackage of ipfit.
_LAZY = {
    "basis": None, "optimize": None,
    "Cloud": "cloud",
    "ImplicitPolynomial": "polynomial", "Normalization": "polynomial",
    "outward_vertices": "geometry.mesh", "winding_number": "geometry.mesh",
    "LINEAR_METHODS": "fitting.linear", "fit_3l": "fitting.linear", "fit_gradient_one": "fitting.linear",
    "fit_linear": "fitting.linear", "fit_lstsq": "fitting.linear", "fit_ridge": "fitting.linear",
    "fit_taubin": "fitting.linear", "ImplicitPolynomialModel": "fitting.model",
    "score_outliers": "robust", "OutlierScore": "robust",
    "fit_chunked": "fitting.chunked",
    "Measures": "fitting.objective", "Objective": "fitting.objective", "measures": "fitting.objective",
    "FarFieldTerm": "fitting.farfield", "far_field_samples": "fitting.farfield",
    "SearchOptions": "fitting.options", "RECOMMENDED": "fitting.options", "PAPER": "fitting.options",
    "PAPER_METHOD": "fitting.options", "PAPER_RULE": "fitting.options",
    "REFINE_METHODS": "fitting.refine", "RefineResult": "fitting.refine", "refine": "fitting.refine",
    "AdaptiveResult": "degree.adaptive", "DegreeResult": "degree.loop", "fit_adaptive": "degree.adaptive",
    "select_degree": "degree.adaptive",
    "DegreeRule": "degree.rules",
    "ZeroSet": "zeroset.extract", "extract_zero_set": "zeroset.extract", "grid_values": "zeroset.extract",
    "Quality": "zeroset.quality", "quality": "zeroset.quality",
    "Trim": "zeroset.trim", "trim_zero_set": "zeroset.trim",
    "save_zero_set": "zeroset.export",
    "to_source": "analysis.codegen", "RayHits": "analysis.rays", "intersect_rays": "analysis.rays",
    "render": "analysis.rays", "Projection": "analysis.projection", "project": "analysis.projection",
    "Curvature": "analysis.curvature", "hessian": "analysis.curvature",
    "descriptors": "analysis.invariants", "similarity": "analysis.invariants",
    "plot_curve": "viz.plotting", "plot_result": "viz.plotting", "plot_smoothness": "viz.plotting",
    "plot_surface": "viz.plotting",
    "read_mesh": "io", "read_points": "io", "write_points": "io",
    "contour_normals": "normals", "estimate_normals": "normals", "normal_agreement": "normals",
    "orient_normals": "normals", "round_rims": "normals",
    "dataset_names": "datasets", "list_datasets": "datasets", "load_dataset": "datasets", "load": "datasets",
    "fit_many": "batch", "BatchResult": "batch",
    "load_result": "degree.results",
    "fit_scene": "scene", "SceneResult": "scene", "load_scene": "scene",
    # the rooms of the package, reachable as attributes (ipfit.analysis.curvature, ...)
    "analysis": None, "batch": None, "datasets": None, "degree": None, "fitting": None, "geometry": None,
    "io": None, "normals": None, "reproduce": None, "scene": None, "viz": None, "zeroset": None,
}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    module = importlib.import_module(f".{_LAZY[name] or name}", __name__)
    value = module if _LAZY[name] is None else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


# The one version of ipfit: pyproject.toml reads it from here (dynamic), the site from the metadata.
__version__ = "0.1.0"

__all__ = [
    "ImplicitPolynomial",
    "Normalization",
    "fit_lstsq",
    "fit_taubin",
    "fit_3l",
    "fit_ridge",
    "fit_gradient_one",
    "fit_linear",
    "ImplicitPolynomialModel",
    "score_outliers",
    "OutlierScore",
    "LINEAR_METHODS",
    "measures",
    "Measures",
    "Objective",
    "refine",
    "RefineResult",
    "SearchOptions",
    "RECOMMENDED",
    "PAPER",
    "PAPER_METHOD",
    "PAPER_RULE",
    "REFINE_METHODS",
    "optimize",
    "fit_adaptive",
    "fit_many",
    "fit_chunked",
    "BatchResult",
    "fit_scene",
    "SceneResult",
    "load_scene",
    "load_result",
    "read_points",
    "read_mesh",
    "write_points",
    "estimate_normals",
    "orient_normals",
    "round_rims",
    "normal_agreement",
    "contour_normals",
    "winding_number",
    "outward_vertices",
    "load",
    "Cloud",
    "load_dataset",
    "list_datasets",
    "dataset_names",
    "AdaptiveResult",
    "DegreeResult",
    "select_degree",
    "DegreeRule",
    "far_field_samples",
    "FarFieldTerm",
    "ZeroSet",
    "extract_zero_set",
    "grid_values",
    "trim_zero_set",
    "Trim",
    "save_zero_set",
    "Quality",
    "quality",
    "plot_curve",
    "plot_surface",
    "plot_smoothness",
    "plot_result",
    "IpfitError",
    "InvalidInputError",
    "ReadError",
    "IpfitWarning",
    "ConditioningWarning",
    "basis",
    "to_source",
    "intersect_rays",
    "RayHits",
    "render",
    "project",
    "Projection",
    "Curvature",
    "hessian",
    "descriptors",
    "similarity",
    "analysis",
]

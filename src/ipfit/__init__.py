"""ipfit: fit implicit polynomial curves and surfaces to 2D and 3D point clouds.

The method is Interian et al. (2017): linear fits (classic least squares, 3L, 3L + ridge),
the distance measure dissimilarity + δ(1 − smoothness), metaheuristic refinement and
adaptive degree selection.
"""

from __future__ import annotations

import sys
import types

from .exceptions import ConditioningWarning, InvalidInputError, IpfitError, IpfitWarning, ReadError

# Loaded on first use (PEP 562): `ipfit` itself imports in milliseconds, so the command line
# owns SIGINT before numpy/scipy load and a Ctrl-C at start-up never prints a traceback.
_LAZY = {
    "basis": None, "optimize": None,
    "LINEAR_METHODS": "linear", "fit_3l": "linear", "fit_gradient_one": "linear", "fit_linear": "linear",
    "fit_lstsq": "linear", "fit_ridge": "linear", "fit_taubin": "linear",
    "AdaptiveResult": "adaptive", "DegreeResult": "adaptive", "fit_adaptive": "adaptive", "select_degree": "adaptive",
    "DegreeRule": "rules",
    "save_zero_set": "export",
    "fit_many": "batch", "BatchResult": "batch", "fit_chunked": "chunked",
    "dataset_names": "datasets", "list_datasets": "datasets", "load_dataset": "datasets", "load": "datasets",
    "Cloud": "cloud",
    "FarFieldTerm": "farfield", "far_field_samples": "farfield",
    "read_mesh": "io", "read_points": "io", "write_points": "io",
    "contour_normals": "normals", "estimate_normals": "normals", "normal_agreement": "normals",
    "orient_normals": "normals",
    "Measures": "objective", "Objective": "objective", "measures": "objective",
    "plot_curve": "plotting", "plot_result": "plotting", "plot_smoothness": "plotting", "plot_surface": "plotting",
    "ImplicitPolynomial": "polynomial", "Normalization": "polynomial",
    "ImplicitPolynomialModel": "model",
    "Quality": "quality", "quality": "quality",
    "REFINE_METHODS": "refine", "RefineResult": "refine", "refine": "refine",
    "SearchOptions": "options", "RECOMMENDED": "options", "PAPER": "options", "PAPER_METHOD": "options",
    "PAPER_RULE": "options",
    "outward_vertices": "solid", "winding_number": "solid",
    "ZeroSet": "zeroset", "extract_zero_set": "zeroset", "grid_values": "zeroset",
    "Trim": "trim", "trim_zero_set": "trim",
    "to_source": "codegen", "RayHits": "rays", "intersect_rays": "rays", "render": "rays",
    "Projection": "projection", "project": "projection", "Curvature": "curvature", "hessian": "curvature",
    "descriptors": "invariants", "similarity": "invariants",
    # ipfit.curvature and ipfit.invariants stay the modules: their same-named functions are
    # ipfit.curvature.curvature (or poly.curvature) and ipfit.invariants.invariants.
    "codegen": None, "curvature": None, "invariants": None, "projection": None, "rays": None, "recognition": None,
}


class _Package(types.ModuleType):
    def __setattr__(self, name: str, value) -> None:
        # importing the submodule ipfit.quality (or .refine) must not hide the function of that
        # name, exactly as the eager `from .quality import quality` used to rebind it
        if isinstance(value, types.ModuleType) and _LAZY.get(name) == name:
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


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


__version__ = "0.1.0"

__all__ = [
    "ImplicitPolynomial",
    "Normalization",
    "ImplicitPolynomialModel",
    "fit_lstsq",
    "fit_taubin",
    "fit_3l",
    "fit_ridge",
    "fit_gradient_one",
    "fit_linear",
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
    "read_points",
    "read_mesh",
    "write_points",
    "estimate_normals",
    "orient_normals",
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
    "codegen",
    "rays",
    "projection",
    "curvature",
    "invariants",
    "recognition",
]

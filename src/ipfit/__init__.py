"""ipfit: fit implicit polynomial curves and surfaces to 2D and 3D point clouds.

The method is Interian et al. (2017): linear fits (classic least squares, 3L, 3L + ridge),
the distance measure dissimilarity + δ(1 − smoothness), metaheuristic refinement and
adaptive degree selection.
"""

from __future__ import annotations

from . import basis, optimize
from .exceptions import ConditioningWarning, InvalidInputError, IpfitError, IpfitWarning, ReadError
from .linear import LINEAR_METHODS, fit_3l, fit_gradient_one, fit_linear, fit_lstsq, fit_ridge, fit_taubin
from .adaptive import AdaptiveResult, DegreeResult, fit_adaptive, select_degree
from .export import save_zero_set
from .datasets import dataset_names, list_datasets, load_dataset
from .farfield import FarFieldTerm, far_field_samples
from .io import read_mesh, read_points, write_points
from .normals import contour_normals, estimate_normals, normal_agreement, orient_normals
from .objective import Measures, Objective, measures
from .plotting import plot_curve, plot_result, plot_smoothness, plot_surface
from .polynomial import ImplicitPolynomial, Normalization
from .quality import Quality, quality
from .refine import REFINE_METHODS, RefineResult, refine
from .solid import outward_vertices, winding_number
from .zeroset import ZeroSet, extract_zero_set, grid_values
from .codegen import to_source
from .rays import RayHits, intersect_rays, render
from .projection import Projection, project
from .curvature import Curvature, hessian
from .invariants import descriptors, similarity
# ipfit.curvature and ipfit.invariants stay the modules: their same-named functions are
# ipfit.curvature.curvature (or poly.curvature) and ipfit.invariants.invariants.
from . import codegen, curvature, invariants, projection, rays, recognition

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
    "LINEAR_METHODS",
    "measures",
    "Measures",
    "Objective",
    "refine",
    "RefineResult",
    "REFINE_METHODS",
    "optimize",
    "fit_adaptive",
    "read_points",
    "read_mesh",
    "write_points",
    "estimate_normals",
    "orient_normals",
    "normal_agreement",
    "contour_normals",
    "winding_number",
    "outward_vertices",
    "load_dataset",
    "list_datasets",
    "dataset_names",
    "AdaptiveResult",
    "DegreeResult",
    "select_degree",
    "far_field_samples",
    "FarFieldTerm",
    "ZeroSet",
    "extract_zero_set",
    "grid_values",
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

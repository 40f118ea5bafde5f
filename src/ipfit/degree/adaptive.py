"""Adaptive degree selection: the paper's Algorithm 1, and the rules built on it.

For g = 2, 4, …, G, fit at degree g with a fixed-degree method and, with a geometric rule,
measure the zero set's quality; a degree rule (:class:`ipfit.degree.rules.DegreeRule`) says whether to
measure and repair, when to stop, which degree to take and why. This module is the loop alone.
Every degree tried is kept, so a user can inspect the whole path and take another degree.
"""

from __future__ import annotations

import copy
import dataclasses
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._result_schema import check_coordinates
from .._utils.foreign import is_foreign
from .._utils.result import Result
from .._utils.validation import (
    as_faces,
    as_normals,
    as_points,
    check_choice,
    check_enough_points,
    check_int,
    check_nonnegative,
    check_real,
    check_rng,
    error,
)
from ..cloud import Cloud, as_cloud
from ..exceptions import IpfitWarning
from ..fitting.farfield import confident_mask
from ..fitting.linear import LINEAR_METHODS, fit_linear
from ..fitting.objective import Measures
from ..fitting.objective import measures as compute_measures
from ..fitting.options import (
    DEFAULT_DELTA,
    DEFAULT_EPSILON,
    DEFAULT_METHOD,
    DEFAULT_RULE,
    RECOMMENDED,
    REFINE_METHODS,
    SearchOptions,
)
from ..fitting.refine import refine
from ..geometry.sampling import spread_subsample, surface_points
from ..normals import estimate_normals
from ..normals.estimate import layered_normals, looks_noisy
from ..normals.rims import round_rims
from ..polynomial import ImplicitPolynomial, Normalization
from ..robust import OutlierScore, check_outliers, score_outliers
from ..zeroset.quality import Quality, looks_like_contour, quality
from ..zeroset.topology import Topology, describe_mismatch
from .repair import fill_missing, other_solutions, repair
from .rules import (
    EXTEND_BELOW,
    MISSES_BELOW,
    RULES,
    TOLERANCE,
    TOPOLOGY,
    DegreeRule,
    TopologyRule,
    get_rule,
    select_degree,
    select_degree_geometric,
    topology_differs,
)

__all__ = ["fit_adaptive", "AdaptiveResult", "DegreeResult", "select_degree", "select_degree_geometric",
           "fixed_degree_methods", "RULES"]


def fixed_degree_methods() -> tuple[str, ...]:
    """Names accepted by ``fit_adaptive(method=...)``: the linear fits and the refinements."""
    return tuple(LINEAR_METHODS) + REFINE_METHODS


@dataclass(frozen=True, eq=False)
class DegreeResult(Result):
    """What the adaptive loop found at one degree (SciPy's vocabulary, like every result).

    Attributes
    ----------
    x, fun : the coefficients (normalised coordinates) and the value the fixed-degree method
        minimised at them (SciPy's meaning: the paper's distance plus any far-field term; the
        paper's distance itself for a linear or custom fit, which minimise nothing of ours, and
        for another of the search's solutions put in place of a fit its repair left not clean,
        :func:`ipfit.degree.repair.other_solutions`).
    distance : the paper's distance at ``x`` (Eq. 4), without any extra term.
    nit, nfev : the fixed-degree method's iterations and objective evaluations (0 for a linear fit).
    success, message : whether the method reached a finite fit, and how it ended.
    degree, polynomial, measures : the fit and its :class:`~ipfit.fitting.objective.Measures`.
    quality : its :class:`~ipfit.zeroset.quality.Quality`, when the rule measured it.
    seconds : wall-clock time of this degree.
    solutions : the refinement's best distinct solutions (empty for a linear fit).
    """

    degree: int
    polynomial: ImplicitPolynomial
    measures: Measures
    seconds: float
    quality: Quality | None = None
    solutions: tuple[ImplicitPolynomial, ...] = ()
    cleanup: tuple[Mapping[str, Any], ...] = ()
    reason: str = ""

    @property
    def dissimilarity(self) -> float:
        return float(self.measures.dissimilarity)

    @property
    def smoothness(self) -> float:
        return float(self.measures.smoothness)

    @property
    def distance(self) -> float:
        return float(self.measures.distance)

    def to_dict(self) -> dict:
        """The entry of ``degrees`` in the JSON result (contract keys, plus nit/nfev/quality)."""
        out: dict[str, Any] = {
            "degree": self.degree, "dissimilarity": self.dissimilarity, "smoothness": self.smoothness,
            "distance": self.distance, "seconds": self.seconds, "method": self.polynomial.method,
            "coefficients": [float(c) for c in self.polynomial.coefficients], "nit": self.nit,
            "nfev": self.nfev, "success": self.success, "message": self.message}
        if self.quality is not None:
            out["quality"] = self.quality.to_dict()
        if self.cleanup:
            out["cleanup"] = [dict(attempt) for attempt in self.cleanup]
        if self.reason:
            out["reason"] = self.reason
        return out


@dataclass(frozen=True, eq=False)
class AdaptiveResult(Result):
    """Result of :func:`fit_adaptive`.

    Attributes
    ----------
    x, fun, distance : coefficients, the minimised value and the paper's distance at the
        selected degree (as on its :class:`DegreeResult`).
    nit, nfev : iterations and objective evaluations over all degrees.
    n_degrees : the number of degrees tried (``len(degrees)``).
    success : a degree was selected by the rule on a complete path, clean unless no degree
        was (False when interrupted, or when an unclean degree was selected over clean ones:
        the capture rule's clean degrees missed the data, F-score below
        :data:`~ipfit.degree.rules.MISSES_BELOW`).
    message : which degree was selected and why, in words.
    polynomial : the fit at the selected degree (measures filled in).
    selected_degree : int
    degrees : one :class:`DegreeResult` per degree tried, in order.
    reason : why the loop stopped or the degree was chosen: 'captured', 'flattened' or
        'no_f_gain' (capture rule), 'criterion' (Algorithm 1), 'geometric', 'max_degree', 'fixed' or 'interrupted'.
    rule : the degree rule's name.
    epsilon, delta, method, seconds
    options : the search settings used by a refinement method (None for a linear fit).
    outliers : the :class:`~ipfit.robust.OutlierScore` of the input points (per-point weights,
        the inlier mask over every point given, the noise scale) when ``outliers`` was not
        'none'; the fit is of the inliers, weighted by their weights when outliers were found.
    """

    polynomial: ImplicitPolynomial
    selected_degree: int
    degrees: tuple[DegreeResult, ...]
    reason: str
    epsilon: float
    delta: float
    method: str
    rule: str
    seconds: float
    options: SearchOptions | None = None
    outliers: OutlierScore | None = None

    @property
    def distance(self) -> float:
        return self.at_degree(self.selected_degree).distance

    @property
    def n_degrees(self) -> int:
        return len(self.degrees)

    @property
    def far_term_weight(self) -> float:
        return self.options.far_term_weight if self.options is not None else 0.0

    @property
    def smoothness_path(self) -> NDArray[np.float64]:
        return np.array([d.smoothness for d in self.degrees])

    def at_degree(self, degree: int) -> DegreeResult:
        """The result kept for ``degree`` (so another degree than the selected one can be taken)."""
        for entry in self.degrees:
            if entry.degree == degree:
                return entry
        tried = ", ".join(str(d.degree) for d in self.degrees)
        raise error("degree", f"one of the degrees tried ({tried})", str(degree))

    def show(self, points=None, **kwargs):
        """An interactive plotly figure of every degree (:func:`ipfit.viz.viewer.result_figure`)."""
        from ..viz.viewer import result_figure

        return result_figure(self, points, **kwargs)

    def _repr_html_(self) -> str:
        # Notebooks display the viewer inline, without writing files (plotly is inlined).
        from ..viz.viewer import to_html

        return to_html(self, full_html=False)

    def to_dict(self) -> dict:
        """The JSON result: the foundation format plus ``selected_degree`` and ``degrees``."""
        out = self.polynomial.to_dict()
        out["selected_degree"] = self.selected_degree
        out["degrees"] = [d.to_dict() for d in self.degrees]
        out["adaptive"] = {"epsilon": self.epsilon, "delta": self.delta, "method": self.method,
                           "reason": self.reason, "rule": self.rule, "far_term_weight": self.far_term_weight,
                           "seconds": self.seconds, "success": self.success, "message": self.message}
        if self.options is not None:
            out["adaptive"]["options"] = self.options.to_dict()
        if self.outliers is not None:
            out["outliers"] = self.outliers.to_dict()
        chosen = self.at_degree(self.selected_degree)
        if chosen.quality is not None:
            out["quality"] = chosen.quality.to_dict()
        return out


FitFunction = Callable[..., ImplicitPolynomial]


class _Fitter:
    """Fits one degree with the chosen method; warm-starts each degree from the previous one."""

    def __init__(self, method, options: SearchOptions | None, delta: float, rng, progress,
                 noise_scale: float | None = None) -> None:
        self.method, self.delta, self.rng, self.progress = method, delta, rng, progress
        self.options, self.noise_scale = options, noise_scale
        self.previous: ImplicitPolynomial | None = None

    def __call__(self, cloud: Cloud, normals, degree, options: SearchOptions | None = None, extra_starts=(),
                 method: str | None = None, keep_clear=None):
        # ``normals`` as the fit was given them (made unit once); the cloud holds them normalised again.
        if callable(self.method):
            poly = self.method(cloud.points, normals, degree)
            if not isinstance(poly, ImplicitPolynomial):
                raise error("method", "a callable returning an ImplicitPolynomial", type(poly).__name__)
            return poly, (), 0, 0, True, "custom fit", None
        if self.method in LINEAR_METHODS:
            return fit_linear(cloud, None, degree, self.method), (), 0, 0, True, "linear fit", None
        options = cast(SearchOptions, options or self.options)  # a refinement method: check_settings gave options

        def report(state):
            self.progress({"event": "iteration", "degree": degree, "stage": state.message, "nit": state.nit,
                           "fun": state.fun})

        starts = list(extra_starts)
        if options.warm_start and self.previous is not None and self.previous.degree < degree:
            starts.append(_embed(self.previous, degree))
        result = refine(cloud, None, degree, method=method or self.method, options=options, delta=self.delta,
                        starts=starts or None, keep_clear=keep_clear, noise_scale=self.noise_scale, rng=self.rng,
                        callback=report if self.progress is not None else None)
        return (result.polynomial, tuple(result.solutions), result.nit, result.nfev, result.success,
                result.message, result.fun)


def _embed(poly: ImplicitPolynomial, degree: int) -> NDArray[np.float64]:
    """The coefficients of ``poly`` at a higher degree: graded order lists every lower-degree
    monomial first, so the same polynomial is its coefficients followed by zeros."""
    out = np.zeros(basis.n_coefficients(poly.dim, degree))
    out[: poly.n_coefficients] = poly.coefficients
    return out


def _check_progress(progress):
    if progress is not None and not callable(progress):
        raise error("progress", "a callable taking one event dict, or None", type(progress).__name__)
    return progress


# The second pass of bare 3D clouds (_reoriented): the points within this share of the box
# diagonal of the selected zero set take its gradient's sign, and the pass runs only if more
# than _REORIENT_FEWEST of them turn.
_REORIENT_REACH = 0.05
_REORIENT_FEWEST = 0.01
# The close-layer look (_layered) runs only if its signs differ from the fit's at more than this share.
_LAYERS_FEWEST = 0.01
# A 3D fit whose best clean F-score is below this (the rule's "not yet good" in 3D) gets a second
# look: without the outlier score's weights when 'auto' acted (_unweighted), and with the fit's
# signs when its normals were estimated (_reoriented; a noisy cloud always gets that one), and
# before that with the close-layer vote's signs on a sparse cloud (_layered); a mesh gets one on
# points spread over its faces (_on_surface). A fit
# that already follows the data seldom gains from either (docs/reorient-clean.md), and each costs
# another degree loop.
_POOR_BELOW = EXTEND_BELOW[3]
# A noisy 3D cloud whose normals were estimated for the noise's σ is fitted again with the normals
# estimated without it when the first fit measures poorly (_POOR_BELOW). That fit is kept when its
# F-score on the points is higher by more than the degree rule's tolerance, or, when its selected
# degree is higher, by more than this (_plain_normals): under σ = 1 % of the box diagonal a
# higher degree chases the noise, scoring a little higher on the noisy points and lower against
# the clean shape (Jacobson's rocker arm: degree 10 for 8, 0.904 for 0.881 on the points, 0.82 for
# 0.92 on its surface; cheburashka: 0.921 for 0.890, 0.94 for 0.98), while grown normals that
# turned a thin part inside out lose at any degree (the Turk kerolamp: degree 4 for 6, 0.772 for
# 0.737, 0.76 for 0.66 on its surface; the turbine's blades: 0.93 for 0.81; the cow's legs, a
# degree 2: 0.94 for 0.55). The messages in docs/reorient.json and docs/reorient-external.json
# give both F-scores of every look.
_NEAREST_NORMALS_MARGIN = 0.05
# A 3D cloud is flat when its spread across its best plane is below this share of its widest
# spread: far below any scan's noise (a sheet of paper: 3e-4), above the rounding of a 2D outline
# or mesh saved with z = 0 and then turned (1e-8 through the covariance).
_FLAT_SPREAD = 1e-6


def _warn_if_flat(pts: NDArray[np.float64]) -> None:
    """Warn when every point lies on one plane: each degree's zero set is then that plane (or
    holds it), whatever the shape the points outline, and the fit cannot say so itself."""
    centred = pts - pts.mean(axis=0)
    values, vectors = np.linalg.eigh(centred.T @ centred)
    if values[0] <= _FLAT_SPREAD ** 2 * values[-1]:
        normal = vectors[:, 0] * np.sign(vectors[np.argmax(np.abs(vectors[:, 0])), 0])  # its largest part > 0
        text = ", ".join(f"{v:.3g}" for v in normal)
        warnings.warn(f"points: all {len(pts):,} lie on one plane (normal {text}), so the fitted surface is that "
                      "plane at every degree. To fit their outline, give their 2D coordinates in the plane "
                      "(the x and y columns when z is constant).", IpfitWarning, stacklevel=3)


def fit_adaptive(points: ArrayLike | Cloud, normals: ArrayLike | None = None, *,
                 method: str | FitFunction = DEFAULT_METHOD, options: SearchOptions | None = None,
                 max_degree: int | None = None, min_degree: int = 2,
                 epsilon: float = DEFAULT_EPSILON, delta: float = DEFAULT_DELTA,
                 rule: str | DegreeRule = DEFAULT_RULE,
                 faces: ArrayLike | None = None, ordered_contour: bool | None = None,
                 outliers: str | float = "auto", rng=None,
                 progress: Callable[[dict], None] | None = None) -> AdaptiveResult:
    """Find the degree the data needs (Algorithm 1) and fit at it.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array, or a :class:`~ipfit.Cloud` (e.g. :func:`ipfit.load`'s): then
        its normals (estimated when it has none), faces and weights (a robust fit) are used; or
        a ``trimesh.Trimesh`` or ``PointCloud``, an Open3D ``PointCloud`` or ``TriangleMesh``, a
        PyVista ``PolyData`` or a pandas DataFrame (x, y[, z] columns): its points, and its
        normals and faces when it has them (:mod:`ipfit._utils.foreign`).
    normals : (N, dim) array, or None to estimate them (:func:`ipfit.estimate_normals`) or to take
        a geometry object's; None with a cloud.
    method : a fixed-degree method: a refinement ('de+polish' (default), 'pso+polish', 'de',
        'pso', 'polish'), a linear fit ('lstsq', 'taubin', '3l', 'ridge', 'gradient_one',
        '3l-far'), or a callable ``(points, normals, degree) -> ImplicitPolynomial`` (use
        :func:`functools.partial` to set a linear fit's parameters).
    options : :class:`~ipfit.SearchOptions` of the refinement methods (default
        :data:`ipfit.RECOMMENDED`; :data:`ipfit.PAPER` is the paper's); an error with a linear
        method or a callable, which have no search.
    max_degree : G, the last degree tried. Default: with the capture rule 20 in 2D and 12 in 3D
        (beyond 14 in 2D and 8 in 3D only while each degree raises the F-score), lowered to the
        highest degree with at least 2 points per coefficient; with the other rules 10 in 2D and
        8 in 3D (the paper).
    min_degree : the first degree tried (default 2).
    epsilon : ε, the smallest smoothness gain that justifies a higher degree.
    delta : δ of the paper's distance.
    rule : 'capture' (default), 'geometric' or 'paper' (Algorithm 1 exactly), or a
        :class:`~ipfit.degree.rules.DegreeRule` object (one of :data:`ipfit.degree.rules.RULES` or your own);
        see :mod:`ipfit.degree.rules`. 'capture' and 'geometric' measure the geometric quality of every
        degree (:func:`ipfit.zeroset.quality.quality`: F-score, precision, recall, spurious components,
        closed) and try to clean a degree whose zero set is not clean before rejecting it
        (with 'capture', also a clean degree that bulges away from the data: precision below
        0.95 at a recall of at least 0.9).
        'capture' goes on while a degree still gains substantially (smoothness, F-score, recall,
        distances), stops once the shape is captured or two degrees in a row gain little, and
        selects the lowest clean degree within 0.01 of the best clean F-score. 'geometric' is
        the paper's rule restricted to clean degrees.
    faces, ordered_contour : describe the data's shape for the quality measures (mesh faces, None
        with a cloud;
        a 2D contour in order, detected by :func:`ipfit.zeroset.quality.looks_like_contour` when
        None), used by the 'capture' and 'geometric' rules.
    outliers : 'auto' (default), 'none' or a share in [0, 0.9): which points are stray returns,
        left out of the fit. 'auto' finds them from the data alone
        (:func:`ipfit.robust.score_outliers`: points far sparser than the shape's samples, or off
        their neighbourhood's line or plane beyond the noise); on clean data it finds none and
        the fit is exactly the fit of every point. A share marks that many of the most outlying
        points. Normals are estimated on the inliers only. When outliers were found, the inliers
        are fitted with their weights (times a given cloud's own), robustly (:func:`ipfit.refine`
        on a weighted cloud: reweighted start fits, a loss truncated at a few noise scales), so
        that strays the score missed pull little; normals estimated for a weighted cloud come
        from its confident points (weight >= 0.9), and each weight is multiplied by the
        normal's confidence (see :func:`ipfit.estimate_normals`); in 3D, where that factor also
        removes clean points (rows of a mesh's vertices, creases), the degrees are fitted once
        more with the score's weights alone, and that fit is kept when its selected degree has
        the higher F-score on the points of weight >= 0.5 after the factor and is clean there
        (or the first is not either), its ``message`` saying which. When 'auto' left points out
        of a 3D cloud and the fit's best clean F-score is below 0.95, every point is fitted once
        more, unweighted (sparse thin parts of a clean cloud can score as strays), and that fit is
        kept when it measures better on the same points of weight >= 0.5; the result then treats
        no point as an outlier, and the ``message`` says which fit was kept. A mesh's vertices are its
        surface: 'auto' treats none as outliers there, and a share keeps the faces whose
        vertices are all inliers. The result records the decision (:attr:`AdaptiveResult.outliers`).
    rng : seed or Generator (SPEC 7), passed to the metaheuristics.
    progress : called with a dict per event ('degree_start', 'iteration' with its 'stage',
        'degree_done'; 'normals' while normals are estimated, see :func:`ipfit.estimate_normals`;
        'topology_repair' with its 'degree', 'mismatch' and, once done, 'f_score' and 'matches'
        when the rule repairs a degree to the data's topology after the loop; 'every_point' with
        the 'degree', 'n_points' and 'fit_points' when a big cloud's degrees were fitted on an even
        subsample of it and the selected one is measured on every point, see
        :class:`~ipfit.SearchOptions` ``fit_points``); 'mesh_points' with a 'message' when a sparse
        mesh is fitted with points spread over its faces too, or a mesh whose fit measured poorly
        is fitted again so (``SearchOptions.mesh_points``, see Notes);
        'weights_variant' with a 'message' before
        each further fit of a weighted 3D cloud (see ``outliers``); 'normals_variant' with a
        'message' before the fit of a noisy 3D cloud with the normals estimated without the
        noise's σ (see Notes); 'layers' with a 'message' before the fits of a sparse 3D cloud
        with its normals oriented by the close-layer vote (see Notes); 'reorient' with a 'message'
        before the second fit of a 3D cloud with estimated normals (see Notes).

    Returns
    -------
    AdaptiveResult

    Notes
    -----
    The normals of a noisy 3D cloud are estimated knowing the noise's σ that the outlier score
    found (``estimate_normals(..., noise=)``), on an even sample of the points whose k nearest
    reach about 4 σ; when that fit's best clean F-score is below 0.95, the cloud is fitted again
    with the normals estimated without σ (neighbourhoods grown to where they look flattest: closer
    on smooth parts, but a thin part can come out inside out as a whole), and that fit is kept
    when its F-score on the points is higher by more than 0.01 (by more than 0.05 at a higher
    degree, which may chase the noise), the ``message`` saying which.

    On a sparse or unevenly sampled 3D cloud whose normals the fit estimated (and no outlier
    weights), a first fit whose best clean F-score is below 0.95 gets a look with the normals
    oriented by the close-layer vote too (:func:`~ipfit.normals.estimate.layered_normals`: a thin
    part's two sides, closer than the neighbour links reach, can be turned inside out as a whole;
    a point whose normal line meets the other side close in front of it votes its part the other
    way round). The selected degree is fitted with them first; only if that measures better on the
    points is the whole loop run again, kept when it measures better (docs/reorient-clean.md).

    A 3D cloud whose normals are estimated is fitted twice when it looks noisy
    (``ipfit.normals.estimate.looks_noisy``) or its first fit's best clean F-score is below
    0.95: under noise, and on sparse clouds with thin parts, the estimated signs come out wrong
    on whole regions, and the second fit takes, at each point within 5 % of the box diagonal of
    the first fit's zero set, the sign of that fit's gradient; it is kept when it measures
    better (as the weights' variant above), the ``message`` saying which.

    A 3D mesh with vertex normals (unweighted) whose first fit's best clean F-score is below
    0.95 is fitted again on its vertices and ``SearchOptions.mesh_points`` points spread evenly
    over its faces (their normals interpolated from the vertices'): a CAD or low-polygon mesh
    crowds its vertices on details and leaves flat parts with a few big triangles, which a fit
    weighing every point alike lets go. That fit is kept when it measures better against the
    faces, the ``message`` saying which (docs/quality-3d.md).

    Normals a measured rule's fit of a 3D cloud estimated itself are turned outward over thin
    rims before the degree loop (:func:`ipfit.round_rims`: on a dense, evenly
    spread cloud, where a point's neighbours leave a wide empty angle on its tangent plane), as a
    mesh's vertex normals are; without it the zero set runs on past a fin's or a wing's rim
    (docs/rims.md). Given normals are kept as given; the ``message`` says how many turned.

    The paper's exact pipeline is ``fit_adaptive(points, normals, method=PAPER_METHOD,
    options=PAPER, rule=PAPER_RULE, outliers="none")`` (what ``ipfit fit --paper`` runs). Ctrl-C
    (KeyboardInterrupt) during a degree ends the loop: the degrees already finished are kept
    and the rule is applied to them (``reason='interrupted'``). With none finished, the
    interrupt propagates.

    Examples
    --------
    >>> from ipfit import fit_adaptive
    >>> from ipfit.datasets import synthetic
    >>> shape = synthetic.ellipse(200)
    >>> result = fit_adaptive(shape.points, shape.normals, method="3l")
    >>> result.selected_degree, result.success
    (2, True)
    """
    given: Cloud | None
    if isinstance(points, Cloud) or is_foreign(points):
        # a Cloud refuses normals and faces; a trimesh/Open3D/PyVista object or a DataFrame gives its own
        given = as_cloud(points, normals, faces=faces)
        pts = given.points
    else:
        given = None
        pts = as_points(points)
    check_coordinates(pts)  # the result must be readable: refuse up front what it could not record
    dim = pts.shape[1]
    if dim == 3:
        _warn_if_flat(pts)
    method, options, rule, epsilon, delta, min_degree = check_settings(method, options, rule, epsilon, delta,
                                                                       min_degree, max_degree)
    outliers = check_outliers(outliers)
    generator = check_rng(rng)
    progress = _check_progress(progress)
    if ordered_contour is not None and not isinstance(ordered_contour, (bool, np.bool_)):
        raise error("ordered_contour", "True, False or None", repr(ordered_contour))
    if given is not None:
        faces, known = given.faces, given.unit_normals
    else:
        faces = None if faces is None else as_faces(faces, len(pts), dim)
        known = None if normals is None else as_normals(normals, pts)
    # A mesh's vertices are its surface by construction: 'auto' finds no stray returns there
    # (uneven triangles would read as density outliers); a forced share still applies.
    scored = None if outliers == "none" or (outliers == "auto" and faces is not None) else \
        score_outliers(pts, outliers=outliers)
    # A weighted fit (robust, see refine) when outliers were found, or the given cloud has weights.
    weights = None if given is None else given.weights
    noise = None if scored is None else scored.noise_scale
    # 'auto' that left points out of a 3D cloud gets a look without the score when its fit
    # measures poorly (_unweighted): sparse thin parts of a clean cloud can read as strays
    # (docs/reorient-clean.md).
    every = (pts, known) if (dim == 3 and rule.measured and weights is None and scored is not None
                             and scored.mode == "auto" and not scored.inliers.all()) else None
    if scored is not None and not scored.inliers.all():
        keep = scored.inliers
        pts, known, faces = pts[keep], None if known is None else known[keep], _kept_faces(faces, keep)
        weights = scored.weights[keep] * (1.0 if weights is None else weights[keep])
    # A sparse mesh's faces add points where its vertices leave its surface bare (SearchOptions.mesh_points)
    # (max_degree was checked by check_settings; one beyond the limit is refused below, unsampled)
    wanted = rule.max_degree(dim) if max_degree is None else min(int(max_degree), basis.MAX_DEGREE[dim])
    # a mesh whose fit measures poorly is fitted again on its surface (_on_surface)
    most = cast(SearchOptions, options).mesh_points if method in REFINE_METHODS else None
    surface = (pts, known, faces, most) if (dim == 3 and rule.measured and faces is not None and known is not None
                                            and weights is None and most is not None) else None
    on_faces = _on_faces(pts, known, faces, weights, options if method in REFINE_METHODS else None,
                         rule.points_per_coefficient * basis.n_coefficients(dim, wanted))
    sampled: tuple[str, ...] = ()
    if on_faces is not None:
        note = f"fitted on the mesh's {len(pts):,} vertices and {len(on_faces[0]):,} points spread over its faces"
        sampled = (note,)
        pts, known = np.vstack([pts, on_faces[0]]), np.vstack([cast(NDArray, known), on_faces[1]])
        if progress is not None:
            progress({"event": "mesh_points", "message": note})
    top = _top_degree(len(pts), dim, min_degree, max_degree, rule)
    unit = known
    scored_weights = None  # the score's weights, when the support factor below changed them
    confident: NDArray[np.bool_] | slice = slice(None)
    estimated = None  # the normals estimated for an unweighted cloud (a look re-orients them: _layered)
    if unit is None and weights is None:
        unit = estimated = estimate_normals(pts, noise=noise, progress=progress)
    elif unit is None:
        # A stray the score missed must neither tilt nor orient its neighbours' normals, nor pull
        # the fit with a normal of its own: the normals are estimated on the confident points (as
        # the far field is judged), and every weight is multiplied by how well the point's
        # neighbourhood supports its normal line (0 where it took a confident neighbour's). At 40 %
        # outliers the bundled apple went from F 0.57 to 0.97, the Turk turbine from 0.60 to 0.75
        # (docs/robust.md).
        confident = confident_mask(weights, len(pts))
        unit, support = estimate_normals(pts, inliers=None if isinstance(confident, slice) else confident,
                                         noise=noise, progress=progress, return_confidence=True)
        if support.any():
            scored_weights, weights = weights, weights * support
    # Noisy 3D points may have had their normals estimated for the noise's σ (estimate_normals'
    # noise): a fit that misses the shape then gets a look with the normals estimated without it.
    for_noise = known is None and noise is not None and dim == 3 and rule.measured
    # One cloud for the whole fit: it keeps what every degree and repair round reuses (far-field
    # samples, start fits' R factors, spacing, the data's side of the quality measurements). Its
    # normals are ``unit`` normalised once more, as refine and the linear fits have always done
    # with the normals they are given: that rounding is part of every fit's coefficients.
    cloud = Cloud._checked(pts, as_normals(unit, pts), faces, weights)
    if rule.measured and ordered_contour is None:
        ordered_contour = dim == 2 and looks_like_contour(pts)
    # Normals the fit estimated turn outward over thin rims (docs/rims.md); given ones (a mesh's, a
    # scanner's) are the user's: rounding a scanner's face normals gained as often as it lost there.
    settings = _LoopSettings(method, options, rule, epsilon, delta, min_degree, top, progress, noise,
                             ordered_contour, rims=rule.measured and dim == 3 and known is None)
    start = time.perf_counter()
    # 3D clouds whose normals were estimated: their signs are fitted again (see _reoriented) when
    # the rule measures the fits that the second pass must beat, and the cloud looks noisy or its
    # first fit measures poorly.
    reorient = rule.measured and known is None and dim == 3
    second_pass = copy.deepcopy(generator) if reorient else None
    surface_pass = copy.deepcopy(generator) if surface is not None else None
    unweighted_pass = copy.deepcopy(generator) if every is not None else None
    plain_pass = copy.deepcopy(generator) if for_noise else None
    layers_pass = copy.deepcopy(generator) if reorient and estimated is not None else None
    if scored_weights is None or dim != 3:
        loop = _degree_loop(cloud, unit, settings, generator)
        total = [loop]
    else:
        # 3D: the support factor keeps a stray the score missed from pulling the fit, but it also
        # zeroes clean points whose k nearest lie on a row or straddle a crease (a quarter of a
        # CAD mesh's vertices), and with them the parts they sample. Both weightings are fitted
        # from the same random stream; the second is kept when it measures better on the points
        # both trust (_measures_better, docs/robust.md).
        twin = copy.deepcopy(generator)
        supported = loop = _degree_loop(cloud, unit, settings, generator)
        total = [supported]
        if progress is not None:
            progress({"event": "weights_variant", "message": "fitting again, weighted by the outlier score alone"})
        plain = _another_loop(Cloud._checked(pts, cloud.oriented, faces, scored_weights), unit, settings, twin, total)
        if plain is not None:
            # measured on the points both fits trust (the supported weights' inliers), not on
            # every point kept: a sheet grown through strays the score missed would gain there
            trusted = _trusted(pts, weights)
            if _measures_better(plain, supported, trusted, rule):
                cloud = Cloud._checked(pts, cloud.oriented, faces, scored_weights)
                note = "weights: the outlier score's alone (the fit with the normals' support on them measured lower)"
                loop = dataclasses.replace(plain, notes=(note,))
            else:
                note = ("weights: the outlier score's times the normals' support (the fit with the score's alone "
                        "measured no better)")
                loop = dataclasses.replace(supported, notes=(note,))
    if every is not None and loop.reason != "interrupted" and rule.best_clean_f(loop.results) < _POOR_BELOW:
        # measured, as the weightings are, on the points the score and the normals' support both
        # trust: a fit through every point gains on strays the score missed
        trusted = _trusted(pts, weights)
        loop, unweighted = _unweighted(loop, every, cast(OutlierScore, scored), trusted, settings, unweighted_pass,
                                       total)
        if unweighted is not None:
            cloud, unit = unweighted
            confident = slice(None)  # every point, its normals estimated on all of them
            scored = dataclasses.replace(cast(OutlierScore, scored), weights=np.ones(len(cloud)),
                                         inliers=np.ones(len(cloud), bool))
    if for_noise and loop.reason != "interrupted" and rule.best_clean_f(loop.results) < _POOR_BELOW:
        nearest = _without_noise(cloud.points, confident, unit)
        if nearest is not None:
            loop, cloud, unit = _plain_normals(loop, cloud, unit, nearest, settings, plain_pass, total)
    if layers_pass is not None and unit is estimated and loop.reason != "interrupted" and \
            rule.best_clean_f(loop.results) < _POOR_BELOW:
        loop, cloud, unit = _layered(loop, cloud, unit, noise, settings, layers_pass, total)
    if second_pass is not None and loop.reason != "interrupted" and (
            rule.best_clean_f(loop.results) < _POOR_BELOW or looks_noisy(pts)):
        loop = _reoriented(loop, cloud, unit, settings, second_pass, total)
    if surface is not None and surface_pass is not None and loop.reason != "interrupted" and \
            rule.best_clean_f(loop.results) < _POOR_BELOW:
        loop, sampled = _on_surface(loop, surface, settings, surface_pass, total, sampled)
    chosen = loop.results[loop.index]
    name = method if isinstance(method, str) else getattr(method, "__name__", "custom")
    success = loop.reason != "interrupted" and rule.success(loop.results, loop.index)
    # a sparse cloud's last degree is its number of points', not the rule's: when the fit took it,
    # say so, and how to go on (an explicit maximum allows one point per coefficient, so only a
    # rule that asks for more leaves room to)
    last = max(r.degree for r in loop.results)
    capped: tuple[str, ...] = ()
    if loop.reason == "max_degree" and max_degree is None and top < rule.max_degree(dim) and chosen.degree == last \
            and rule.points_per_coefficient > 1:
        note = (f"{len(pts):,} points allow degrees up to {top} at {rule.points_per_coefficient} points per "
                f"coefficient, so degree {last} was the last; more points, or a higher maximum degree, go further")
        capped = (note,)
    return AdaptiveResult(
        x=chosen.x, fun=chosen.fun, nit=sum(r.nit for done in total for r in done.results),
        nfev=sum(r.nfev for done in total for r in done.results), success=success,
        message="; ".join((loop.message, *loop.notes, *sampled, *capped)), polynomial=chosen.polynomial,
        selected_degree=chosen.degree, degrees=tuple(loop.results), reason=loop.reason, epsilon=epsilon, delta=delta,
        method=name, rule=rule.name, seconds=time.perf_counter() - start,
        options=options if method in REFINE_METHODS else None, outliers=scored)


@dataclass(frozen=True)
class _LoopSettings:
    """What every degree loop of one :func:`fit_adaptive` call shares (checked there)."""

    method: Any
    options: SearchOptions | None
    rule: DegreeRule
    epsilon: float
    delta: float
    min_degree: int
    top: int
    progress: Callable[[dict], None] | None
    noise: float | None
    ordered_contour: bool | None
    rims: bool = False  # the loop turns the normals outward over thin rims (normals.rims)


@dataclass(frozen=True)
class _Loop:
    """One degree loop's outcome: every degree's result, the selected one's index, why, and how."""

    results: list[DegreeResult]
    index: int
    reason: str
    message: str
    notes: tuple[str, ...] = ()  # what fit_adaptive decided around the loop, said after its message


def _trusted(points: NDArray, weights: NDArray | None) -> Cloud:
    """The points two fits are compared on: those of weight at least 0.5 (every point unweighted),
    so that a fit that grew a sheet through strays the score missed gains nothing there."""
    return Cloud._checked(points if weights is None else points[weights >= 0.5], None)


def _measures_better(one: _Loop, other: _Loop, points: Cloud, rule: DegreeRule, margin: float = 0.0) -> bool:
    """Whether ``one``'s selected degree measures better than ``other``'s on ``points``: an F-score
    higher by more than ``margin``, and clean there unless ``other``'s is not either (a sheet grown
    through strays the score missed is spurious on them; a fit that is clean is not traded for one
    that is not) or misses the data (F-score below :data:`~ipfit.degree.rules.MISSES_BELOW`: the
    bare Turk scissors' closed blob of F 0.02 on its points was kept over a degree 4 of F 0.67
    that is not closed inside the box)."""
    return _compared(one, other, points, rule, margin)[0]


def _compared(one: _Loop, other: _Loop, points: Cloud, rule: DegreeRule,
              margin: float = 0.0) -> tuple[bool, float, float]:
    """:func:`_measures_better`, and the two selected degrees' F-scores on ``points``."""
    def measured(loop: _Loop) -> tuple[bool, float]:
        q = quality(loop.results[loop.index].polynomial, points)
        return bool(rule.is_clean(q)), q.f_score

    (one_clean, one_f), (other_clean, other_f) = measured(one), measured(other)
    better = one_f > other_f + margin and (one_clean or not other_clean or other_f < MISSES_BELOW)
    return better, one_f, other_f


def _against_gradient(poly: ImplicitPolynomial, points: NDArray, normals: NDArray) -> NDArray[np.bool_]:
    """Which ``normals`` point against ``poly``'s gradient at points within ``_REORIENT_REACH`` of
    the box diagonal of its zero set (first-order distance); farther points are never taken."""
    value, gradient = poly.value_and_gradient(points)
    reach = _REORIENT_REACH * float(np.linalg.norm(np.ptp(points, axis=0)))
    with np.errstate(invalid="ignore"):  # a non-finite value or gradient is not near
        near = np.abs(value) < reach * np.linalg.norm(gradient, axis=1)
    return near & (np.einsum("ij,ij->i", normals, gradient) < 0)


def _layered(loop: _Loop, cloud: Cloud, unit, noise: float | None, settings: _LoopSettings, generator,
             total: list[_Loop]) -> tuple[_Loop, Cloud, NDArray]:
    """``(loop, cloud, unit)``, or the degree loop run again with the normals oriented with the
    close-layer vote (:func:`~ipfit.normals.estimate.layered_normals`), its cloud and normals, when
    it measures better on the points.

    On a sparse 3D cloud a thin part's two sides are closer than the neighbour links reach, and
    the sign propagation can turn the part inside out as a whole (the Turk chopper's rotor). The
    vote puts it right where a point's normal line meets the other side close in front of it; two
    separate parts facing each other as close look the same to it (the Turk Porsche's wheels),
    hence the fits kept only when they measure better (docs/real-clouds.md).
    """
    layered = layered_normals(cloud.points, noise)
    turned = np.einsum("ij,ij->i", layered, cloud.oriented) < 0
    if turned.sum() <= _LAYERS_FEWEST * len(turned):
        return loop, cloud, unit
    if settings.progress is not None:
        settings.progress({"event": "layers", "message": f"{int(turned.sum()):,} normals turned by the close-layer "
                                                          "vote, fitting again"})
    layered_cloud = Cloud._checked(cloud.points, as_normals(layered, cloud.points), cloud.faces, cloud.weights)
    trusted = _trusted(cloud.points, cloud.weights)
    share = f"{turned.mean():.0%} of the normals turned by the close-layer vote"
    # a look at the selected degree first: the whole loop again only where that measures better
    degree = loop.results[loop.index].degree
    probe = _another_loop(layered_cloud, layered, dataclasses.replace(settings, min_degree=degree, top=degree),
                          copy.deepcopy(generator), total)
    if probe is None:
        return loop, cloud, unit
    if not _measures_better(probe, loop, trusted, settings.rule):
        note = f"{share} (degree {degree} fitted again with them measured no better: kept)"
        return dataclasses.replace(loop, notes=(*loop.notes, note)), cloud, unit
    again = _another_loop(layered_cloud, layered, settings, generator, total)
    if again is None:
        return loop, cloud, unit
    if _measures_better(again, loop, trusted, settings.rule):
        return (dataclasses.replace(again, notes=(*loop.notes, f"{share} and fitted again (measured better)")),
                layered_cloud, layered)
    return dataclasses.replace(loop, notes=(*loop.notes, f"{share} and fitted again (measured no better: kept)")), \
        cloud, unit


def _on_surface(loop: _Loop, mesh: tuple[NDArray, NDArray, NDArray, int], settings: _LoopSettings,
                generator, total: list[_Loop], sampled: tuple[str, ...]) -> tuple[_Loop, tuple[str, ...]]:
    """``(loop, sampled)``, or the degree loop run again on the ``mesh``'s vertices and ``most``
    (its last item) points spread evenly over its faces (its vertex normals interpolated there) with what the
    message says of them, when that measures better against the faces.

    A mesh's vertices sample its surface as its modeller placed them: a CAD or low-polygon mesh
    leaves a jet's wings or a lamp's shade with a few big triangles and crowds its details, and
    the fit, which weighs every point alike, follows the details and lets the bare parts go
    (the Turk F-16: degree 2, F 0.84 on its vertices). The faces are what every degree is
    measured against, so the look is judged where the answer is known (docs/quality-3d.md).
    """
    vertices, normals, faces, most = mesh
    extra, extra_normals = surface_points(vertices, faces, normals, most)
    if not len(extra):
        return loop, sampled
    note = f"fitted on the mesh's {len(vertices):,} vertices and {len(extra):,} points spread over its faces"
    if settings.progress is not None:
        settings.progress({"event": "mesh_points", "message": f"the fit measured poorly: {note}"})
    points, unit = np.vstack([vertices, extra]), np.vstack([normals, extra_normals])
    again = _another_loop(Cloud._checked(points, as_normals(unit, points), faces), unit, settings, generator,
                          total)
    if again is None:
        return loop, sampled
    better, new_f, old_f = _compared(again, loop, Cloud._checked(vertices, None, faces), settings.rule)
    if better:
        return (dataclasses.replace(again, notes=loop.notes),
                (f"{note} (the first fit measured F {old_f:.3f} against the faces, this one {new_f:.3f})",))
    note = (f"{note.replace('fitted on', 'a fit on')} measured F {new_f:.3f} against the faces, the first "
            f"{old_f:.3f}: kept")
    return dataclasses.replace(loop, notes=(*loop.notes, note)), sampled


def _reoriented(loop: _Loop, cloud: Cloud, unit, settings: _LoopSettings, generator, total: list[_Loop]) -> _Loop:
    """``loop`` or, if it measures better, the degree loop run again with the normals' signs taken
    from ``loop``'s selected fit (``total`` gets the second loop).

    Under noise, sign propagation between neighbours runs across the noise band, and whole
    regions come out inside out (a quarter of the points of detailed meshes at σ = 1 % of the box
    diagonal); the fit still follows most of the shape, and a polynomial's gradient is a
    consistent orientation of its whole zero set. Each point within ``_REORIENT_REACH`` of the
    selected zero set takes the sign of the gradient there; the rest keep theirs
    (docs/reorient.md, docs/reorient-external.md).
    """
    poly = loop.results[loop.index].polynomial
    flip = _against_gradient(poly, cloud.points, cloud.oriented)
    if flip.sum() <= _REORIENT_FEWEST * len(flip):
        return loop
    signs = np.where(flip, -1.0, 1.0)[:, None]
    turned = Cloud._checked(cloud.points, cloud.oriented * signs, cloud.faces, cloud.weights)
    if settings.progress is not None:
        settings.progress({"event": "reorient", "message": f"{int(flip.sum()):,} normals turned to the fit's "
                                                             "gradient, fitting again"})
    again = _another_loop(turned, unit * signs, settings, generator, total)
    if again is None:
        return loop
    trusted = _trusted(cloud.points, cloud.weights)
    share = f"{flip.mean():.0%} of the normals turned to the degree-{poly.degree} fit's gradient"
    if _measures_better(again, loop, trusted, settings.rule):
        return dataclasses.replace(again, notes=(*loop.notes, f"{share} and fitted again (measured better)"))
    return dataclasses.replace(loop, notes=(*loop.notes, f"{share} and fitted again (measured no better: kept)"))


def _unweighted(loop: _Loop, every: tuple[NDArray, NDArray | None], scored: OutlierScore, trusted: Cloud,
                settings: _LoopSettings, generator,
                total: list[_Loop]) -> tuple[_Loop, tuple[Cloud, NDArray] | None]:
    """``(loop, (cloud, normals))`` of the degree loop on every point, unweighted, when it measures
    better than ``loop`` (the fit 'auto' weighted) on ``trusted``, the points the score and the
    normals' support both trust; else ``(loop, None)``, its notes saying that the look was taken
    (unless interrupted).

    A fit through planted strays grows sheets away from the trusted points, so this loop loses
    wherever the score was right (measured on the score's inliers alone, it won on strays the
    score missed: the Turk turbine at 40 %); where a sparse clean cloud's thin parts scored as
    strays, it wins (the Turk spider, docs/reorient-clean.md).
    """
    points, known = every
    if settings.progress is not None:
        settings.progress({"event": "weights_variant", "message": f"fitting again on every point, unweighted "
                                                                  f"(the {scored.count:,} points scored as outliers "
                                                                  "included)"})
    unit = estimate_normals(points, noise=settings.noise, progress=settings.progress) if known is None else known
    cloud = Cloud._checked(points, as_normals(unit, points), None, None)
    again = _another_loop(cloud, unit, settings, generator, total)
    if again is None:
        return loop, None
    share = f"{scored.count:,} points ({scored.outlier_share:.0%}) scored as outliers"
    if not _measures_better(again, loop, trusted, settings.rule):
        note = f"{share} left out (the fit on every point, unweighted, measured no better on the rest)"
        return dataclasses.replace(loop, notes=(*loop.notes, note)), None
    note = f"{share} kept: the fit on every point, unweighted, measured better on the rest"
    return dataclasses.replace(again, notes=(*loop.notes, note)), (cloud, unit)


def _without_noise(points: NDArray, confident: NDArray[np.bool_] | slice, unit: NDArray) -> NDArray | None:
    """The normals of ``points`` estimated as without the noise's σ (on the ``confident`` points,
    as ``unit`` was), or None when they are ``unit`` (not noisy, or σ changed nothing)."""
    if not looks_noisy(points):
        return None
    plain = estimate_normals(points, inliers=None if isinstance(confident, slice) else confident)
    return None if np.array_equal(plain, unit) else plain


def _plain_normals(loop: _Loop, cloud: Cloud, unit, plain: NDArray, settings: _LoopSettings, generator,
                   total: list[_Loop]) -> tuple[_Loop, Cloud, NDArray]:
    """``(loop, cloud, unit)``, or the degree loop run again with the ``plain`` normals (estimated
    without the noise's σ: neighbourhoods grown to where they look flattest, or the k nearest
    points where none does), its cloud and normals, when it measures better by more than
    :data:`~ipfit.degree.rules.TOLERANCE`, or by more than ``_NEAREST_NORMALS_MARGIN`` at a higher
    selected degree.

    The normals estimated for σ (on an even sample whose k nearest points reach 4 σ) err at
    random, a few per cent of their signs too; those grown to where they look flattest are
    closer on smooth parts, but tilt a thin body's rim as a whole, and across a part thinner than
    them they see both sides and turn it inside out.
    """
    if settings.progress is not None:
        settings.progress({"event": "normals_variant", "message": "fitting again with the normals estimated "
                                                                  "without the noise's σ"})
    turned = Cloud._checked(cloud.points, as_normals(plain, cloud.points), cloud.faces, cloud.weights)
    again = _another_loop(turned, plain, settings, generator, total)
    if again is None:
        return loop, cloud, unit
    trusted = _trusted(cloud.points, cloud.weights)
    higher = again.results[again.index].degree > loop.results[loop.index].degree
    margin = _NEAREST_NORMALS_MARGIN if higher else TOLERANCE
    better, nearest_f, noise_f = _compared(again, loop, trusted, settings.rule, margin)
    if better:
        note = (f"normals: estimated without the noise's σ (F-score {nearest_f:.3f} on the points, against "
                f"{noise_f:.3f} with those estimated for it)")
        return dataclasses.replace(again, notes=(*loop.notes, note)), turned, plain
    note = (f"normals: estimated for the noise (F-score {noise_f:.3f} on the points; those without its σ gave "
            f"{nearest_f:.3f}{' at a higher degree' if higher else ''}, not better by more than {margin:g})")
    return dataclasses.replace(loop, notes=(*loop.notes, note)), cloud, unit


def _another_loop(cloud: Cloud, unit, settings: _LoopSettings, generator, total: list[_Loop]) -> _Loop | None:
    """The degree loop run once more, on ``cloud``, appended to ``total``; None when interrupted
    before its first degree finished (the fit so far stands)."""
    try:
        again = _degree_loop(cloud, unit, settings, generator)
    except KeyboardInterrupt:
        return None
    total.append(again)
    return again


def _degree_loop(cloud: Cloud, unit, settings: _LoopSettings, generator) -> _Loop:
    """The degree loop on ``cloud`` (with ``unit``, its normals as given), the rule's selection,
    and the selected degree measured on every point when the loop fitted a subsample."""
    method, options, rule, epsilon, delta = (settings.method, settings.options, settings.rule, settings.epsilon,
                                             settings.delta)
    progress, ordered_contour, top, min_degree = (settings.progress, settings.ordered_contour, settings.top,
                                                  settings.min_degree)
    # A big cloud's degrees are fitted on an even subsample of it (SearchOptions.fit_points);
    # the selected one is measured on every point after the loop.
    work, work_unit = _working_cloud(cloud, unit, options if method in REFINE_METHODS else None)
    subsample = work is not cloud
    measured = rule.measured
    rims: tuple[str, ...] = ()  # what the message says of the normals' rims
    if settings.rims:
        # estimated normals are a dense scan's faces': they leave the zero set free to run on past
        # a thin part's rim (docs/rims.md)
        rounded, turn = round_rims(work.points, work.oriented, weights=work.weights, return_turn=True)
        if turn.any():
            work_unit = rounded
            work = Cloud._checked(work.points, as_normals(rounded, work.points), None, work.weights)
            turned = f"the normals of {np.count_nonzero(turn):,} points ({np.mean(turn > 0):.0%})"
            rims = (f"{turned} turned outward over thin rims",)
    fitter = _Fitter(method, options if method in REFINE_METHODS else None, delta, generator, progress,
                     settings.noise)
    degrees = list(range(min_degree, top + 1, 2)) if top > min_degree else [min_degree]
    results: list[DegreeResult] = []
    # per degree, for a topology variant after the loop: its fit before any repair, its refit, its
    # measure of another polynomial, its warm start
    unrepaired: list[tuple[DegreeResult, Callable[..., DegreeResult], Callable[..., DegreeResult],
                           ImplicitPolynomial | None]] = []
    reason = "max_degree"
    variant = _variants(results, unrepaired, rule, fitter, work, ordered_contour, progress) \
        if measured and fitter.options is not None and rule.prefers_topology else None
    beyond: int | None = None  # a degree tried after the rule's stop, for the data's topology
    aside: DegreeResult | None = None  # that degree, when it has another topology too
    for degree in degrees:
        if progress is not None:
            progress({"event": "degree_start", "degree": degree})
        try:
            entry = before_repair = _fit_degree(fitter, work, work_unit, degree, delta, measured, ordered_contour)
            best_f = rule.best_clean_f(results)

            def refit(options, start, keep_clear, degree=degree):
                return _fit_degree(fitter, work, work_unit, degree, delta, True, ordered_contour,
                                   options=options, extra_starts=[start], method="polish", keep_clear=keep_clear)

            if measured and fitter.options is not None and not rule.is_done(entry, best_f):
                entry = repair(entry, refit, fitter.options, work, ordered_contour, rule, best_f)
            if measured and fitter.options is not None and rule.fills_missing(entry, best_f):
                entry = fill_missing(entry, refit, fitter.options, work, ordered_contour, rule)

            def measure(poly, fitted=before_repair):
                return _measured_fit(fitted, poly, work, work_unit, delta, ordered_contour)

            if measured and fitter.options is not None and not rule.is_clean(entry.quality):
                entry = other_solutions(entry, before_repair.solutions, measure, fitter.options, rule)
            unrepaired.append((before_repair, refit, measure, fitter.previous))
        except KeyboardInterrupt:
            if not results:
                raise
            reason = "interrupted"
            break
        # A degree whose topology was repaired warm-starts the next one from its fit before the
        # repair, as without the topology check: holding a neck inside at degree 6 cost the fish the
        # shape its degree 8 grew from the unrepaired fit (F 0.96 for 1.0).
        topology_repaired = before_repair is not entry and rule.checks_topology and \
            topology_differs(before_repair.quality)
        fitter.previous = (before_repair if topology_repaired else entry).polynomial
        results.append(entry)
        if progress is not None:
            progress({"event": "degree_done", **entry.to_dict()})
        if degree == beyond:
            try:  # repaired at once, whatever its F-score as fitted: the repair is why it was tried
                if variant is not None and topology_differs(entry.quality):
                    tried, repaired = variant(len(results) - 1)
                    results[-1] = repaired or tried
            except KeyboardInterrupt:
                reason = "interrupted"
            if topology_differs(results[-1].quality):
                # tried for the data's topology alone, and it has another one too: the choice stays
                # among the degrees the rule fitted (the cow's degree 10 gains F-score with two parts)
                aside = results.pop()
                break
            if reason == "interrupted":
                break
        stop = rule.stop(results, epsilon)
        # Not trying a higher degree for want of a gain says nothing when there is none to try.
        if stop is not None and not (stop == "no_f_gain" and degree == degrees[-1]):
            # One degree more when the rule would keep another topology than the data's for want
            # of a degree of the data's within its tolerance: homer's degree 8 keeps a handle
            # across the narrow gap between its feet under every repair, its degree 10 closes it.
            reason = stop
            try:
                settled = None if variant is None or beyond is not None or degree == degrees[-1] else \
                    _settled_on_wrong_topology(results, rule, epsilon, stop, variant)
            except KeyboardInterrupt:  # the degrees fitted stand, as when a degree is interrupted
                reason, settled = "interrupted", None
            if settled is None:
                break
            results[:] = settled  # with the repair rounds tried on the way
            beyond = degree + 2
    results, index, reason, message = _select(results, rule, epsilon, reason, fixed=len(degrees) == 1,
                                              variant=variant if reason != "interrupted" else None)
    if beyond is not None and reason != "interrupted":
        outcome = "" if aside is None else \
            f", and it has another topology too ({_mismatch(aside)}): not selected"
        message = (f"{message}; degree {beyond} was tried after the rule had stopped at degree {beyond - 2}, as no "
                   f"degree up to it within {TOLERANCE:g} of the best clean F-score had the data's topology{outcome}")
    results = [dataclasses.replace(r, reason=rule.reason(results, i, index, message, epsilon))
               for i, r in enumerate(results)]
    if aside is not None:
        results.append(dataclasses.replace(aside, reason=f"tried after the rule's stop, for the data's topology: "
                                                         f"{_mismatch(aside)}"))
    if subsample and reason != "interrupted":
        sampled = f"degrees fitted on {len(work):,} of the {len(cloud):,} points spread evenly"
        try:
            if progress is not None:
                progress({"event": "every_point", "degree": results[index].degree, "n_points": len(cloud),
                          "fit_points": len(work)})
            results[index] = _on_every_point(cloud, unit, results[index], delta, measured, ordered_contour)
            message = f"{message}; {sampled}, degree {results[index].degree} measured on every point"
        except KeyboardInterrupt:  # the subsample's fit stands, as a degree finished in the loop does
            reason = "interrupted"
            message = f"{message}; {sampled}; interrupted while measuring degree {results[index].degree} on every point"
    return _Loop(results, index, reason, "; ".join((message, *rims)))


def _variants(results: list[DegreeResult], unrepaired: list, rule: DegreeRule, fitter: _Fitter, work: Cloud,
              ordered_contour, progress) -> Callable[[int], tuple[DegreeResult, DegreeResult | None]]:
    """The ``variant`` a rule that prefers the data's topology settles with (see
    :meth:`~ipfit.degree.rules.DegreeRule.settle`): degree ``i`` of ``results`` (the loop's list,
    as it grows) repaired for the topology from its fit before any repair, each degree once."""
    done: dict[int, tuple[DegreeResult, DegreeResult | None]] = {}

    def variant(i: int) -> tuple[DegreeResult, DegreeResult | None]:
        if i in done:
            return done[i]
        previous = fitter.previous
        fit, refit, measure, fitter.previous = unrepaired[i]  # the polish starts as it did in the loop
        event = {"event": "topology_repair", "degree": results[i].degree, "mismatch": _mismatch(results[i])}
        if progress is not None:
            progress(event)
        try:
            entry, repaired = _topology_variant(results[i], fit, refit, measure, cast(SearchOptions, fitter.options),
                                                work, ordered_contour, rule.best_clean_f(results))
        finally:
            fitter.previous = previous  # a degree still to come starts from the loop's fit
        if progress is not None:
            done_q = cast(Quality, (repaired or entry).quality)
            progress({**event, "f_score": done_q.f_score, "matches": repaired is not None,
                      "seconds": entry.seconds - results[i].seconds})
        done[i] = entry, repaired
        return done[i]

    return variant


def _mismatch(entry: DegreeResult) -> str:
    q = cast(Quality, entry.quality)
    return describe_mismatch(cast(Topology, q.topology), cast(Topology, q.data_topology))


def _settled_on_wrong_topology(results: list[DegreeResult], rule: DegreeRule, epsilon: float, stop: str,
                               variant) -> list[DegreeResult] | None:
    """``results`` as ``rule`` settles them when it settles on a clean degree of another topology
    than the data's (known with confidence), else None."""
    settled, index, _ = rule.settle(results, epsilon, stop, variant, final=False)
    wrong = rule.is_clean(settled[index].quality) and topology_differs(settled[index].quality)
    return settled if wrong else None


def _on_faces(points: NDArray, normals: NDArray | None, faces: NDArray | None, weights: NDArray | None,
              options: SearchOptions | None, needed: int) -> tuple[NDArray, NDArray] | None:
    """Points spread over a 3D mesh's faces and their interpolated normals, as many as its
    vertices fall short of ``options.mesh_points`` (at least of ``needed``, what the highest degree
    asks for); None unless an unweighted 3D mesh with vertex normals has fewer than ``needed``
    vertices."""
    most = None if options is None else options.mesh_points
    if most is None or faces is None or normals is None or weights is not None or len(points) >= needed:
        return None
    on_faces = surface_points(points, faces, normals, max(most, needed) - len(points))
    return None if not len(on_faces[0]) else on_faces


def _working_cloud(cloud: Cloud, unit, options: SearchOptions | None):
    """The cloud the degree loop fits, and its normals as given: ``cloud`` itself, or an even
    subsample of ``options.fit_points`` of its points (fixed seed) when it has more. A mesh is
    fitted on every vertex: its faces describe the surface every degree is measured against
    (and its topology, known with confidence), which a subsample of its vertices would lose."""
    most = None if options is None else options.fit_points
    if most is None or len(cloud) <= most or cloud.faces is not None:
        return cloud, unit
    pick = spread_subsample(cloud, most)
    return (Cloud._checked(cloud.points[pick], as_normals(unit[pick], cloud.points[pick]), None,
                           None if cloud.weights is None else cloud.weights[pick]), unit[pick])


def _on_every_point(cloud: Cloud, unit, entry: DegreeResult, delta: float, measured: bool,
                    ordered_contour) -> DegreeResult:
    """``entry`` (a degree fitted on the working subsample) written in the normalisation of the
    whole ``cloud`` and measured on every point of it, its reason, repairs, evaluations and time
    carried over. It is not polished there again: on 50,000 points spread evenly the fit has
    settled, and a polish on every point, without the repairs' samples, can undo a repair."""
    start = time.perf_counter()
    norm = Normalization.from_points(cloud.points)
    moved = dataclasses.replace(entry.polynomial, coefficients=_renormalised(entry.polynomial, norm),
                                normalization=norm)
    poly, m, q = _measure(moved, cloud, unit, delta, measured, ordered_contour)
    # `fun` stays what the method minimised (on the subsample); the measures are every point's
    return dataclasses.replace(entry, x=poly.coefficients, polynomial=poly, measures=m, quality=q,
                               seconds=entry.seconds + time.perf_counter() - start)


def _renormalised(poly: ImplicitPolynomial, norm: Normalization) -> NDArray[np.float64]:
    """The unit coefficient vector of ``poly`` in the normalised coordinates of ``norm``: the
    same polynomial (a similarity keeps the degree), solved for at 4·d points of the unit box."""
    v = np.random.default_rng(0).uniform(-1.5, 1.5, size=(4 * poly.n_coefficients, poly.dim))
    coefficients = np.linalg.lstsq(basis.monomials(v, poly.exponents), poly(norm.invert(v)), rcond=None)[0]
    return coefficients / np.linalg.norm(coefficients)


def _kept_faces(faces: NDArray[np.int64] | None, keep: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """The triangles whose three vertices are all kept, indexing the kept points."""
    if faces is None:
        return None
    new_index = np.cumsum(keep) - 1
    kept = new_index[faces[keep[faces].all(axis=1)]]
    return kept if len(kept) else None


class _WithinTolerance(TopologyRule):
    """The topology rule, its repair going on until a clean zero set of the data's topology is
    within the capture rule's tolerance of ``best_f`` (the variants :func:`_topology_variant` makes)."""

    def is_done(self, entry, best_f=0.0):
        return self.is_clean(entry.quality) and entry.quality.f_score >= best_f - TOLERANCE


def _topology_variant(entry: DegreeResult, unrepaired: DegreeResult, refit: Callable[..., DegreeResult],
                      measure: Callable[[ImplicitPolynomial], DegreeResult], options: SearchOptions, cloud: Cloud,
                      ordered_contour, best_f: float) -> tuple[DegreeResult, DegreeResult | None]:
    """``entry`` (a degree as its rule repaired it, of another topology than the data's) with what
    was tried for the data's topology recorded, and the best of it when that has a clean zero set
    of the data's topology (else None): first the search's other solutions of the degree (each
    measured by ``measure``), then, unless one of them is within the tolerance of ``best_f``, the
    topology rule's repair of its unrepaired fit, going on until a round is. Both carry every
    attempt, their evaluations and their time."""
    within = _WithinTolerance()
    other = other_solutions(unrepaired, unrepaired.solutions, measure, options, within)
    attempts = tuple(other.cleanup[len(unrepaired.cleanup):])
    nfev = 0
    best = other
    if not within.is_done(other, best_f):
        repaired = repair(unrepaired, refit, options, cloud, ordered_contour, within, best_f)
        attempts += tuple(repaired.cleanup)
        nfev = repaired.nfev - unrepaired.nfev
        if TOPOLOGY.is_clean(repaired.quality) and (not TOPOLOGY.is_clean(other.quality) or
                                                    repaired.quality.f_score >= other.quality.f_score):
            best = repaired
    totals = {"cleanup": tuple(entry.cleanup) + attempts, "nfev": entry.nfev + nfev,
              "seconds": entry.seconds + sum(a["seconds"] for a in attempts)}
    fixed = TOPOLOGY.is_clean(best.quality)
    return dataclasses.replace(entry, **totals), dataclasses.replace(best, **totals) if fixed else None


def _select(results, rule: DegreeRule, epsilon: float, reason: str, fixed: bool,
            variant=None) -> tuple[list[DegreeResult], int, str, str]:
    """``(results, index, reason, message)``: the results as the rule settles them (``variant``:
    see :meth:`~ipfit.degree.rules.DegreeRule.settle`), its choice among them and its explanation;
    a single degree asked for (``fixed``) leaves no choice to a rule."""
    if fixed and reason != "interrupted":
        return list(results), 0, "fixed", f"fixed degree {results[0].degree}"
    results, index, reason = rule.settle(results, epsilon, reason, variant)
    return results, index, reason, rule.explain(results, index, reason, epsilon)


def check_settings(method, options, rule, epsilon, delta, min_degree,
                   max_degree=None) -> tuple[Any, SearchOptions | None, DegreeRule, float, float, int]:
    """The data-independent arguments of :func:`fit_adaptive`, checked (the one place: batches
    check them once before sending shapes to workers). Returns them normalised (the rule as its
    :class:`~ipfit.degree.rules.DegreeRule` object)."""
    if not callable(method):
        method = check_choice(method, "method", fixed_degree_methods())
    if method in REFINE_METHODS:
        options = RECOMMENDED if options is None else options
        if not isinstance(options, SearchOptions):
            raise error("options", "a SearchOptions (e.g. ipfit.RECOMMENDED or ipfit.PAPER)", type(options).__name__)
        options.check_method(method)
    elif options is not None:
        name = method if isinstance(method, str) else "a callable"
        raise error("options", f"None for method {name!r}, which has no search", "SearchOptions",
                    "Drop the search options (or the far-field term weight) or pick a refinement method.")
    rule = get_rule(rule)
    epsilon = check_real(epsilon, "epsilon")
    delta = check_nonnegative(delta, "delta")
    min_degree = check_int(min_degree, "min_degree", minimum=1)
    if max_degree is not None:
        check_int(max_degree, "max_degree", minimum=min_degree)
    return method, options, rule, epsilon, delta, min_degree


def _top_degree(n_points: int, dim: int, min_degree: int, max_degree: int | None, rule: DegreeRule) -> int:
    if max_degree is None:
        top = rule.max_degree(dim)
    else:
        top = check_int(max_degree, "max_degree", minimum=min_degree)
        if top > basis.MAX_DEGREE[dim]:
            raise error("max_degree", f"at most {basis.MAX_DEGREE[dim]} in {dim}D (ipfit's limit)", str(top),
                        "Lower the maximum degree.")
    largest_possible = max((g for g in range(1, top + 1) if basis.n_coefficients(dim, g) <= n_points), default=0)
    if max_degree is None:
        # An explicit maximum is the user's; automatic degrees keep the rule's points per coefficient.
        comfortable = max((g for g in range(1, top + 1)
                           if rule.points_per_coefficient * basis.n_coefficients(dim, g) <= n_points), default=0)
        largest_possible = min(largest_possible, max(comfortable, min_degree))
    if largest_possible < min_degree:
        check_enough_points(n_points, dim, min_degree)
    if top > largest_possible:
        if max_degree is not None:
            raise error("max_degree", f"at most {largest_possible} for {n_points} points "
                        f"(degree {top} has {basis.n_coefficients(dim, top)} coefficients)", str(top),
                        "Lower the maximum degree or pass more points.")
        top = largest_possible
    return top


def _measure(poly: ImplicitPolynomial, cloud: Cloud, unit, delta, measured: bool, ordered_contour
             ) -> tuple[ImplicitPolynomial, Measures, Quality | None]:
    """``poly`` with its paper's measures on ``cloud`` attached, those measures, and its quality
    when ``measured``: how every fit of the loop is measured."""
    m = compute_measures(poly, cloud.points, unit, delta=delta)
    poly = poly.with_coefficients(poly.coefficients, measures=m.to_dict())
    return poly, m, quality(poly, cloud, ordered_contour=ordered_contour) if measured else None


def _measured_fit(fitted: DegreeResult, poly: ImplicitPolynomial, cloud: Cloud, unit, delta, ordered_contour
                  ) -> DegreeResult:
    """``fitted`` (a degree's fit) with ``poly`` (another solution of the same search) in its
    place, measured as :func:`_fit_degree` measures a fit; its seconds are the measurement's."""
    t0 = time.perf_counter()
    poly, m, q = _measure(poly, cloud, unit, delta, True, ordered_contour)
    return dataclasses.replace(fitted, x=poly.coefficients, fun=float(m.distance), polynomial=poly, measures=m,
                               quality=q, seconds=time.perf_counter() - t0, cleanup=())


def _fit_degree(fitter: _Fitter, cloud: Cloud, unit, degree, delta, measured: bool, ordered_contour, *, options=None,
                extra_starts=(), method=None, keep_clear=None) -> DegreeResult:
    t0 = time.perf_counter()
    poly, solutions, nit, nfev, success, message, fun = fitter(cloud, unit, degree, options, extra_starts,
                                                               method, keep_clear)
    poly, m, q = _measure(poly, cloud, unit, delta, measured, ordered_contour)
    return DegreeResult(x=poly.coefficients, fun=float(m.distance if fun is None else fun), nit=nit, nfev=nfev,
                        success=success, message=message, degree=degree, polynomial=poly, measures=m,
                        seconds=time.perf_counter() - t0, quality=q, solutions=solutions)

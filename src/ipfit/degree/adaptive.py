"""Adaptive degree selection, :func:`fit_adaptive`: the paper's Algorithm 1, and the rules built on it.

For g = 2, 4, …, G, fit at degree g with a fixed-degree method and, with a geometric rule,
measure the zero set's quality; a degree rule (:class:`ipfit.degree.rules.DegreeRule`) says whether to
measure and repair, when to stop, which degree to take and why. This module checks the
arguments (once, here), prepares the cloud the loop fits (stray returns left out, normals
estimated, a sparse mesh's faces sampled) and builds the :class:`AdaptiveResult`; the loop itself
is :mod:`ipfit.degree.loop`, the second looks a poor first fit gets :mod:`ipfit.degree.looks`.
Every degree tried is kept, so a user can inspect the whole path and take another degree.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
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
from ..fitting.linear import LINEAR_METHODS
from ..fitting.options import (
    DEFAULT_DELTA,
    DEFAULT_EPSILON,
    DEFAULT_METHOD,
    DEFAULT_RULE,
    RECOMMENDED,
    REFINE_METHODS,
    SearchOptions,
)
from ..geometry.sampling import surface_points
from ..normals import estimate_normals
from ..polynomial import ImplicitPolynomial
from ..robust import OutlierScore, check_outliers, score_outliers
from ..zeroset.quality import looks_like_contour
from .looks import Looks, fit_with_looks
from .loop import DegreeResult, FitFunction, LoopSettings
from .rules import (
    RULES,
    DegreeRule,
    get_rule,
    select_degree,
    select_degree_geometric,
)

__all__ = ["fit_adaptive", "AdaptiveResult", "DegreeResult", "select_degree", "select_degree_geometric",
           "fixed_degree_methods", "RULES"]


def fixed_degree_methods() -> tuple[str, ...]:
    """Names accepted by ``fit_adaptive(method=...)``: the linear fits and the refinements."""
    return tuple(LINEAR_METHODS) + REFINE_METHODS


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


def _check_progress(progress):
    if progress is not None and not callable(progress):
        raise error("progress", "a callable taking one event dict, or None", type(progress).__name__)
    return progress


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
        'local_surface' with a 'message' when a sparse bare 3D cloud whose fit measured poorly is
        fitted again with points spread between its points (see Notes);
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

    A bare 3D cloud (normals estimated, no faces, unweighted when it comes to it) of at most 10,000
    points whose fit's best clean F-score is still below 0.95 after the looks above is fitted again
    on its points and ``SearchOptions.mesh_points`` points spread over the triangles between
    neighbouring points (:func:`~ipfit.geometry.sampling.local_triangles`: each point's umbrella on
    its tangent plane), its normals interpolated there, as a mesh is on its faces; that fit is kept
    when it measures better against those triangles, the ``message`` saying which (suzanne's 507
    bare points: F 0.906 → 0.925 against its faces; docs/real-clouds.md).

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
    # measures poorly (looks._unweighted): sparse thin parts of a clean cloud can read as strays
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
    # a mesh whose fit measures poorly is fitted again on its surface (looks._on_surface)
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
    estimated = None  # the normals estimated for an unweighted cloud (a look re-orients them: looks._layered)
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
    settings = LoopSettings(method, options, rule, epsilon, delta, min_degree, top, progress, noise,
                            ordered_contour, rims=rule.measured and dim == 3 and known is None)
    start = time.perf_counter()
    # 3D clouds whose normals were estimated: their signs are fitted again (looks._reoriented) when
    # the rule measures the fits that the second pass must beat, and the cloud looks noisy or its
    # first fit measures poorly.
    reorient = rule.measured and known is None and dim == 3
    # a sparse bare 3D cloud whose fit measures poorly is fitted again with points spread between its
    # points too (looks._on_local_surface), as a mesh is on its faces
    local_surface = most if reorient and faces is None else None
    looks = Looks(scored=scored, scored_weights=scored_weights, every=every, estimated=estimated,
                  confident=confident, reorient=reorient, for_noise=for_noise, surface=surface,
                  local_surface=local_surface)
    outcome = fit_with_looks(cloud, unit, settings, generator, looks, sampled)
    loop, total, scored, sampled = outcome.loop, outcome.loops, outcome.scored, outcome.sampled
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


def _kept_faces(faces: NDArray[np.int64] | None, keep: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """The triangles whose three vertices are all kept, indexing the kept points."""
    if faces is None:
        return None
    new_index = np.cumsum(keep) - 1
    kept = new_index[faces[keep[faces].all(axis=1)]]
    return kept if len(kept) else None


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

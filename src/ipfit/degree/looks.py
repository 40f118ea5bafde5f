"""Second looks: a first fit that measures poorly, or a noisy cloud's, fitted again another way.

A degree loop (:mod:`ipfit.degree.loop`) trusts what it is given: the outlier score's weights,
the estimated normals' signs, a mesh's vertices. Each of these can be wrong in a way the first
fit shows (its best clean F-score below 0.95 in 3D), and each look here runs the whole loop
again with one of them changed, keeping the new fit only when it measures better on the points
both fits trust: the score's weights alone, every point unweighted, the normals estimated
without the noise's σ, oriented by the close-layer vote or by the first fit's gradient, or a
mesh's faces sampled too. :func:`fit_with_looks` runs the first loop and the looks in that
order; docs/reorient-clean.md and docs/reorient.md measure what they gain and cost.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import NDArray

from .._utils.validation import as_normals
from ..cloud import Cloud
from ..geometry.sampling import local_triangles, surface_points
from ..normals import estimate_normals
from ..normals.estimate import layered_normals, looks_noisy
from ..polynomial import ImplicitPolynomial
from ..robust import OutlierScore
from ..zeroset.quality import quality
from .loop import Loop, LoopSettings, another_loop, degree_loop
from .rules import EXTEND_BELOW, MISSES_BELOW, TOLERANCE, DegreeRule

__all__ = ["Looks", "Outcome", "fit_with_looks"]


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
# A sparse bare 3D cloud whose first fit measures poorly is fitted again with points spread over the
# triangles between its points (_on_local_surface) up to this many points: beyond, its points sample
# the surface densely enough that SearchOptions.mesh_points more change little, and the triangles
# (a Delaunay triangulation around each point) would cost seconds.
_LOCAL_SURFACE_MOST = 10_000


def _trusted(points: NDArray, weights: NDArray | None) -> Cloud:
    """The points two fits are compared on: those of weight at least 0.5 (every point unweighted),
    so that a fit that grew a sheet through strays the score missed gains nothing there."""
    return Cloud._checked(points if weights is None else points[weights >= 0.5], None)


def _measures_better(one: Loop, other: Loop, points: Cloud, rule: DegreeRule, margin: float = 0.0) -> bool:
    """Whether ``one``'s selected degree measures better than ``other``'s on ``points``: an F-score
    higher by more than ``margin``, and clean there unless ``other``'s is not either (a sheet grown
    through strays the score missed is spurious on them; a fit that is clean is not traded for one
    that is not) or misses the data (F-score below :data:`~ipfit.degree.rules.MISSES_BELOW`: the
    bare Turk scissors' closed blob of F 0.02 on its points was kept over a degree 4 of F 0.67
    that is not closed inside the box)."""
    return _compared(one, other, points, rule, margin)[0]


def _compared(one: Loop, other: Loop, points: Cloud, rule: DegreeRule,
              margin: float = 0.0) -> tuple[bool, float, float]:
    """:func:`_measures_better`, and the two selected degrees' F-scores on ``points``."""
    def measured(loop: Loop) -> tuple[bool, float]:
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


def _layered(loop: Loop, cloud: Cloud, unit, noise: float | None, settings: LoopSettings, generator,
             total: list[Loop]) -> tuple[Loop, Cloud, NDArray]:
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
    probe = another_loop(layered_cloud, layered, dataclasses.replace(settings, min_degree=degree, top=degree),
                          copy.deepcopy(generator), total)
    if probe is None:
        return loop, cloud, unit
    if not _measures_better(probe, loop, trusted, settings.rule):
        note = f"{share} (degree {degree} fitted again with them measured no better: kept)"
        return dataclasses.replace(loop, notes=(*loop.notes, note)), cloud, unit
    again = another_loop(layered_cloud, layered, settings, generator, total)
    if again is None:
        return loop, cloud, unit
    if _measures_better(again, loop, trusted, settings.rule):
        return (dataclasses.replace(again, notes=(*loop.notes, f"{share} and fitted again (measured better)")),
                layered_cloud, layered)
    return dataclasses.replace(loop, notes=(*loop.notes, f"{share} and fitted again (measured no better: kept)")), \
        cloud, unit


def _with_spread(loop: Loop, given: tuple[NDArray, NDArray], spread: tuple[NDArray, NDArray],
                 faces: NDArray | None, reference: NDArray, event: str, note: str, settings: LoopSettings,
                 generator, total: list[Loop]) -> tuple[Loop, bool, float, float] | None:
    """The degree loop run again on the ``given`` points and normals with the ``spread`` ones (its
    cloud with ``faces``), whether it measures better than ``loop`` against the given points'
    ``reference`` triangles, and both F-scores there (:func:`_compared`); None when interrupted.
    The look that spread them (a mesh's faces, a bare cloud's triangles) is announced first."""
    if settings.progress is not None:
        settings.progress({"event": event, "message": f"the fit measured poorly: {note}"})
    points, unit = np.vstack([given[0], spread[0]]), np.vstack([given[1], spread[1]])
    again = another_loop(Cloud._checked(points, as_normals(unit, points), faces), unit, settings, generator, total)
    if again is None:
        return None
    return again, *_compared(again, loop, Cloud._checked(given[0], None, reference), settings.rule)


def _on_surface(loop: Loop, mesh: tuple[NDArray, NDArray, NDArray, int], settings: LoopSettings,
                generator, total: list[Loop], sampled: tuple[str, ...]) -> tuple[Loop, tuple[str, ...]]:
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
    fitted = _with_spread(loop, (vertices, normals), (extra, extra_normals), faces, faces, "mesh_points", note,
                          settings, generator, total)
    if fitted is None:
        return loop, sampled
    again, better, new_f, old_f = fitted
    if better:
        return (dataclasses.replace(again, notes=loop.notes),
                (f"{note} (the first fit measured F {old_f:.3f} against the faces, this one {new_f:.3f})",))
    note = (f"{note.replace('fitted on', 'a fit on')} measured F {new_f:.3f} against the faces, the first "
            f"{old_f:.3f}: kept")
    return dataclasses.replace(loop, notes=(*loop.notes, note)), sampled


def _on_local_surface(loop: Loop, cloud: Cloud, unit, most: int, settings: LoopSettings, generator,
                      total: list[Loop]) -> Loop:
    """``loop``, or the degree loop run again on ``cloud``'s points and ``most`` points spread over
    the triangles between neighbouring points (:func:`~ipfit.geometry.sampling.local_triangles`,
    with ``cloud``'s normals, interpolated there), when that measures better against those
    triangles; its notes say which.

    A sparse bare cloud leaves the fit free between its points, where a mesh's faces would hold
    it (:func:`_on_surface`): suzanne's 507 bare points gave F 0.906 against its faces (0.925 with
    this look), the mesh's own fit 0.97. The triangles the points span stand in for the faces,
    both to fill the gaps and to judge the fit; on thin plates (the Turk scissors and airplane) a
    fit through them loses recall, and there the judgement keeps the first fit
    (docs/real-clouds.md).
    """
    points = cloud.points
    triangles = local_triangles(points, cloud.oriented)
    if not len(triangles):
        return loop
    extra, extra_normals = surface_points(points, triangles, cloud.oriented, most)
    if not len(extra):
        return loop
    note = (f"fitted on the {len(points):,} points and {len(extra):,} points spread over the triangles between "
            "neighbouring points")
    fitted = _with_spread(loop, (points, unit), (extra, extra_normals), None, triangles, "local_surface", note,
                          settings, generator, total)
    if fitted is None:
        return loop
    again, better, new_f, old_f = fitted
    if better:
        note = f"{note} (the first fit measured F {old_f:.3f} against those triangles, this one {new_f:.3f})"
        return dataclasses.replace(again, notes=(*loop.notes, note))
    note = (f"{note.replace('fitted on', 'a fit on')} measured F {new_f:.3f} against those triangles, the first "
            f"{old_f:.3f}: kept")
    return dataclasses.replace(loop, notes=(*loop.notes, note))


def _reoriented(loop: Loop, cloud: Cloud, unit, settings: LoopSettings, generator,
                total: list[Loop]) -> tuple[Loop, Cloud, NDArray]:
    """``(loop, cloud, unit)`` or, if it measures better, the degree loop run again with the
    normals' signs taken from ``loop``'s selected fit, its cloud and normals (``total`` gets the
    second loop).

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
        return loop, cloud, unit
    signs = np.where(flip, -1.0, 1.0)[:, None]
    turned = Cloud._checked(cloud.points, cloud.oriented * signs, cloud.faces, cloud.weights)
    if settings.progress is not None:
        settings.progress({"event": "reorient", "message": f"{int(flip.sum()):,} normals turned to the fit's "
                                                             "gradient, fitting again"})
    again = another_loop(turned, unit * signs, settings, generator, total)
    if again is None:
        return loop, cloud, unit
    trusted = _trusted(cloud.points, cloud.weights)
    share = f"{flip.mean():.0%} of the normals turned to the degree-{poly.degree} fit's gradient"
    if _measures_better(again, loop, trusted, settings.rule):
        return (dataclasses.replace(again, notes=(*loop.notes, f"{share} and fitted again (measured better)")),
                turned, unit * signs)
    return dataclasses.replace(loop, notes=(*loop.notes, f"{share} and fitted again (measured no better: kept)")), \
        cloud, unit


def _unweighted(loop: Loop, every: tuple[NDArray, NDArray | None], scored: OutlierScore, trusted: Cloud,
                settings: LoopSettings, generator,
                total: list[Loop]) -> tuple[Loop, tuple[Cloud, NDArray] | None]:
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
    again = another_loop(cloud, unit, settings, generator, total)
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


def _plain_normals(loop: Loop, cloud: Cloud, unit, plain: NDArray, settings: LoopSettings, generator,
                   total: list[Loop]) -> tuple[Loop, Cloud, NDArray]:
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
    again = another_loop(turned, plain, settings, generator, total)
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


@dataclass(frozen=True)
class Looks:
    """What :func:`ipfit.fit_adaptive` learnt of its input that decides the looks a first fit gets."""

    scored: OutlierScore | None  # the outlier score, when one was computed
    scored_weights: NDArray | None  # its weights alone, when the normals' support changed them (3D)
    every: tuple[NDArray, NDArray | None] | None  # every point given and its known normals (_unweighted)
    estimated: NDArray | None  # normals the fit estimated for an unweighted cloud (_layered)
    confident: NDArray[np.bool_] | slice  # the points those normals were estimated on
    reorient: bool  # a measured 3D fit whose normals were estimated (_reoriented)
    for_noise: bool  # ... and estimated for the noise's σ (_plain_normals)
    surface: tuple[NDArray, NDArray, NDArray, int] | None  # a mesh to sample (_on_surface)
    local_surface: int | None  # a sparse bare cloud: how many points to spread between its points (_on_local_surface)


@dataclass(frozen=True)
class Outcome:
    """The loop kept, every loop run (their evaluations count), and what the looks changed."""

    loop: Loop
    loops: list[Loop]
    scored: OutlierScore | None
    sampled: tuple[str, ...]


def fit_with_looks(cloud: Cloud, unit, settings: LoopSettings, generator, looks: Looks,
                   sampled: tuple[str, ...] = ()) -> Outcome:
    """The degree loop on ``cloud`` (``unit``: its normals as given) and the second looks
    ``looks`` allows, in order; ``sampled`` is what the message says of a mesh's face points.

    Every look draws from its own copy of ``generator`` as it was before the first loop, so that
    a fit does not depend on which looks ran before it."""
    pts, faces, weights = cloud.points, cloud.faces, cloud.weights
    rule, progress, noise, dim = settings.rule, settings.progress, settings.noise, cloud.dim
    scored, scored_weights, every, estimated, confident, surface, for_noise = (
        looks.scored, looks.scored_weights, looks.every, looks.estimated, looks.confident, looks.surface,
        looks.for_noise)
    second_pass = copy.deepcopy(generator) if looks.reorient else None
    surface_pass = copy.deepcopy(generator) if surface is not None else None
    unweighted_pass = copy.deepcopy(generator) if every is not None else None
    plain_pass = copy.deepcopy(generator) if for_noise else None
    layers_pass = copy.deepcopy(generator) if looks.reorient and estimated is not None else None
    local_pass = copy.deepcopy(generator) if looks.local_surface is not None else None
    if scored_weights is None or dim != 3:
        loop = degree_loop(cloud, unit, settings, generator)
        total = [loop]
    else:
        # 3D: the support factor keeps a stray the score missed from pulling the fit, but it also
        # zeroes clean points whose k nearest lie on a row or straddle a crease (a quarter of a
        # CAD mesh's vertices), and with them the parts they sample. Both weightings are fitted
        # from the same random stream; the second is kept when it measures better on the points
        # both trust (_measures_better, docs/robust.md).
        twin = copy.deepcopy(generator)
        supported = loop = degree_loop(cloud, unit, settings, generator)
        total = [supported]
        if progress is not None:
            progress({"event": "weights_variant", "message": "fitting again, weighted by the outlier score alone"})
        plain = another_loop(Cloud._checked(pts, cloud.oriented, faces, scored_weights), unit, settings, twin, total)
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
        loop, cloud, unit = _reoriented(loop, cloud, unit, settings, second_pass, total)
    if surface is not None and surface_pass is not None and loop.reason != "interrupted" and \
            rule.best_clean_f(loop.results) < _POOR_BELOW:
        loop, sampled = _on_surface(loop, surface, settings, surface_pass, total, sampled)
    if looks.local_surface is not None and local_pass is not None and loop.reason != "interrupted" and \
            cloud.weights is None and len(cloud) <= _LOCAL_SURFACE_MOST and \
            rule.best_clean_f(loop.results) < _POOR_BELOW:
        loop = _on_local_surface(loop, cloud, unit, looks.local_surface, settings, local_pass, total)
    return Outcome(loop, total, scored, sampled)

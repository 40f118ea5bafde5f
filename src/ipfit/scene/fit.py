"""``fit_scene``: segment a scan into objects and fit each with its own polynomial."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._result_schema import check_coordinates
from .._utils.validation import as_normals, as_points, error
from ..batch import client_for, shape_seed
from ..degree.adaptive import check_settings, fit_adaptive
from ..exceptions import InvalidInputError
from ..fitting.options import DEFAULT_DELTA, DEFAULT_EPSILON, DEFAULT_METHOD, DEFAULT_RULE, SearchOptions
from .results import SceneResult, object_box
from .segment import CLUTTER, OBJECT, OUTLIER, Cluster, Segmentation, segment

__all__ = ["fit_scene", "object_name", "from_labels"]


def object_name(index: int) -> str:
    """The name object ``index`` is seeded by (:func:`ipfit.batch.shape_seed` of the scene's seed and it)."""
    return f"object-{index}"


def from_labels(points, labels: ArrayLike, min_points: int = 1) -> Segmentation:
    """A :class:`Segmentation` from known labels (an image's silhouettes): label i >= 0 is object
    i; -1 is not an object. Objects are kept in the labels' order."""
    labels = np.asarray(labels)
    if labels.shape != (len(points),) or labels.dtype.kind not in "iu":
        raise error("labels", f"one whole number per point ({len(points)})", f"shape {labels.shape} and dtype "
                    f"{labels.dtype}")
    kinds = np.where(labels >= 0, OBJECT, CLUTTER).astype(np.int64)
    objects: list[Cluster] = []
    clutter: list[Cluster] = []
    for value in np.unique(labels[labels >= 0]):
        members = np.flatnonzero(labels == value)
        (objects if len(members) >= min_points else clutter).append(Cluster(members))
    out = np.full(len(points), -1, dtype=np.int64)
    for i, cluster in enumerate(objects):
        out[cluster.indices] = i
    for cluster in clutter:
        kinds[cluster.indices] = CLUTTER
    spacing = 0.0
    if len(points) > 1:
        from scipy.spatial import cKDTree

        spacing = float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))
    return Segmentation(out, kinds, tuple(objects), (), tuple(clutter), spacing, 0.0, 0.0,
                        {"labels_given": True, "min_points": min_points})


def fit_scene(points: ArrayLike, normals: ArrayLike | None = None, *, labels: ArrayLike | None = None,
              planes: bool | None = None, keep_planes: bool = False, outliers: str | float = "auto",
              link: float | None = None, min_points: int | None = None,
              method: str = DEFAULT_METHOD, options: SearchOptions | None = None, max_degree: int | None = None,
              min_degree: int = 2, epsilon: float = DEFAULT_EPSILON, delta: float = DEFAULT_DELTA,
              rule: str = DEFAULT_RULE, rng: int | None = 0, client=None, workers: int | None = None,
              scheduler: str | None = None, progress: Callable[[dict], None] | None = None) -> SceneResult:
    """Fit a scene: find its objects and fit each with :func:`~ipfit.fit_adaptive`.

    The scan is segmented by :func:`ipfit.scene.segment.segment` (stray returns set aside,
    dominant planes removed by RANSAC, the rest split by connectivity at a few times the point
    spacing, tiny components reported as clutter), or by ``labels`` when they are known (an
    image's silhouettes). Every object is then fitted alone: its own degree, quality and reasons.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array: the whole scan.
    normals : (N, dim) array or None (each object's are then estimated from its own points).
    labels : (N,) whole numbers, or None to segment: the object of each point (0, 1, ...), -1 for
        none. Objects of fewer than ``min_points`` points are clutter.
    planes : remove dominant planes (default: in 3D yes, in 2D no).
    keep_planes : also keep each removed plane as a degree-1 polynomial (:attr:`SceneResult.planes`).
    outliers : 'auto' (default), 'none' or a share: the scan's stray returns, set aside before the
        segmentation (and each object's fit looks again, as :func:`~ipfit.fit_adaptive` does).
    link, min_points : the segmentation's link distance and smallest object (see
        :func:`~ipfit.scene.segment.segment`).
    method, options, max_degree, min_degree, epsilon, delta, rule
        As :func:`~ipfit.fit_adaptive`, for every object.
    rng : int seed (or None for a fresh one, or a Generator to draw it from): object ``i`` is fitted
        with ``rng=shape_seed(seed, "object-i")`` (:func:`ipfit.batch.shape_seed`), on Dask or not.
    client, workers, scheduler : fit the objects on Dask (as :func:`ipfit.fit_many`): a client, an
        embedded cluster of ``workers`` processes, or a scheduler's address. None of them: here.
    progress : callable, optional
        Called after each object with a dict: ``event`` ("object"), ``index``, ``n_objects``,
        ``n_points``, ``selected_degree``, ``f_score``, ``touching``.

    Returns
    -------
    SceneResult

    Raises
    ------
    InvalidInputError
        Bad arguments, or a scan with no object to fit (everything planes, clutter or outliers).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    >>> ring = np.column_stack([np.cos(t), np.sin(t)])
    >>> scene = fit_scene(np.vstack([ring, 0.5 * ring + [4.0, 0.0]]), method="3l", outliers="none")
    >>> len(scene), [r.selected_degree for r in scene]
    (2, [2, 2])
    """
    start = time.perf_counter()
    pts = as_points(points, min_points=2)
    check_coordinates(pts)
    known = None if normals is None else as_normals(normals, pts)
    method, options, rule_object, epsilon, delta, min_degree = check_settings(
        method, options, rule, epsilon, delta, min_degree, max_degree)
    if progress is not None and not callable(progress):
        raise error("progress", "a callable taking one event dict, or None", type(progress).__name__)
    seed = _seed(rng)
    if labels is not None:
        from .segment import MIN_POINTS

        seg = from_labels(pts, labels, MIN_POINTS[pts.shape[1]] if min_points is None else min_points)
    else:
        seg = segment(pts, planes=planes, outliers=outliers, link=link, min_points=min_points, rng=seed)
    if not seg.objects:
        raise InvalidInputError(
            f"points: expected at least one object, got none: of {len(pts):,} points, "
            f"{int(np.count_nonzero(seg.kinds == OUTLIER)):,} are outliers, "
            f"{sum(p.n_points for p in seg.planes):,} lie on {len(seg.planes)} plane(s) and "
            f"{sum(c.n_points for c in seg.clutter):,} in {len(seg.clutter)} piece(s) too small to fit. "
            "Pass a scan with objects of at least a few dozen points.")
    settings: dict[str, Any] = {"method": method, "options": options, "min_degree": min_degree,
                                "max_degree": max_degree, "epsilon": epsilon, "delta": delta, "rule": rule_object,
                                "outliers": outliers}
    tasks = [(pts[c.indices], None if known is None else known[c.indices], shape_seed(seed, object_name(i)))
             for i, c in enumerate(seg.objects)]
    if client is None and workers is None and scheduler is None:
        results = []
        for i, (p, n, s) in enumerate(tasks):
            results.append(fit_adaptive(p, n, rng=s, **settings))
            _report(progress, i, seg, results[-1])
    else:
        results = _on_dask(tasks, settings, client, workers, scheduler, progress, seg)
    kept = ()
    if keep_planes:
        kept = tuple(plane.polynomial(pts[plane.indices]) for plane in seg.planes)
    touching = [i for i, c in enumerate(seg.objects) if c.touching]
    message = _message(seg, touching)
    return SceneResult(objects=tuple(results), segmentation=seg,
                       boxes=tuple(object_box(pts[c.indices]) for c in seg.objects), dim=pts.shape[1],
                       n_points=len(pts), nit=sum(r.nit for r in results), nfev=sum(r.nfev for r in results),
                       success=all(r.success for r in results), message=message,
                       seconds=time.perf_counter() - start, planes=kept)


def _seed(rng) -> int:
    if rng is None:
        return int(np.random.default_rng().integers(2**32))
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(2**32))
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and rng >= 0:
        return int(rng)
    raise error("rng", "a whole number >= 0, None or a numpy Generator", repr(rng))


def _message(seg: Segmentation, touching: list[int]) -> str:
    n = len(seg.objects)
    parts = [f"{n} object{'s' if n != 1 else ''}"]
    if touching:
        parts.append(f"object{'s' if len(touching) > 1 else ''} {', '.join(map(str, touching))} may be two "
                     "touching objects fitted as one")
    if seg.planes:
        parts.append(f"{len(seg.planes)} plane{'s' if len(seg.planes) > 1 else ''} removed")
    if seg.clutter:
        parts.append(f"{len(seg.clutter)} piece{'s' if len(seg.clutter) > 1 else ''} of clutter "
                     f"({sum(c.n_points for c in seg.clutter):,} points) not fitted")
    if seg.n_outliers:
        parts.append(f"{seg.n_outliers:,} outliers set aside")
    return "; ".join(parts)


def _report(progress, index: int, seg: Segmentation, result) -> None:
    if progress is None:
        return
    chosen = result.at_degree(result.selected_degree)
    progress({"event": "object", "index": index, "n_objects": len(seg.objects),
              "n_points": seg.objects[index].n_points, "selected_degree": result.selected_degree,
              "f_score": None if chosen.quality is None else chosen.quality.f_score,
              "touching": seg.objects[index].touching})


def _fit_one(points, normals, seed: int, settings: dict):
    """One object on a worker (a module-level function: Dask pickles it by name)."""
    with np.errstate(all="ignore"):
        return fit_adaptive(points, normals, rng=seed, **settings)


def _on_dask(tasks, settings, client, workers, scheduler, progress, seg) -> list:
    """The objects' fits on a Dask cluster (the batch's: :func:`ipfit.batch.client_for`), in order."""
    from ..batch import dask_warnings_logged, require_distributed

    require_distributed()
    # a rule object travels by name: the workers look it up (rules are module objects)
    settings = {**settings, "rule": settings["rule"].name}
    out: list = [None] * len(tasks)
    with dask_warnings_logged(), client_for(client, workers, scheduler) as active:
        from distributed import as_completed

        futures = {active.submit(_fit_one, p, n, s, settings, pure=False, retries=0): i
                   for i, (p, n, s) in enumerate(tasks)}
        for future in as_completed(futures):
            i = futures[future]
            out[i] = future.result()
            _report(progress, i, seg, out[i])
    return out

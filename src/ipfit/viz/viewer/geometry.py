"""Geometry for display: decimated meshes, and which zero-set components are spurious."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._utils.validation import check_int
from ...zeroset.extract import ZeroSet

__all__ = ["decimate", "spurious_flags"]


def decimate(vertices: ArrayLike, faces: ArrayLike, max_faces: int,
             labels: ArrayLike | None = None) -> tuple[NDArray, NDArray, NDArray]:
    """Vertex clustering: merge the vertices of each cubic cell until at most ``max_faces`` remain.

    Each cell's vertices become their mean; faces that collapse are dropped, as are
    repeated ones. The cell grows until the face count fits, so every vertex moves by at
    most one cell diagonal. ``labels`` (one per face) follow their faces.

    Returns ``(vertices, faces, labels)``.

    >>> import trimesh
    >>> sphere = trimesh.creation.icosphere(subdivisions=4)
    >>> v, f, _ = decimate(sphere.vertices, sphere.faces, 500)
    >>> len(f) <= 500, bool(abs(np.linalg.norm(v, axis=1) - 1).max() < 0.1)
    (True, True)
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    lab = np.zeros(len(f), dtype=np.int64) if labels is None else np.asarray(labels, dtype=np.int64)
    max_faces = check_int(max_faces, "max_faces", minimum=1)
    if len(f) <= max_faces:
        return v, f, lab
    edges = np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1)
    cell = float(np.mean(edges)) * math.sqrt(len(f) / max_faces)
    while True:
        keys = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
        _, cluster = np.unique(keys, axis=0, return_inverse=True)
        cluster = cluster.ravel()
        counts = np.bincount(cluster)
        merged = np.column_stack([np.bincount(cluster, weights=v[:, j]) for j in range(3)]) / counts[:, None]
        g = cluster[f]
        keep = (g[:, 0] != g[:, 1]) & (g[:, 1] != g[:, 2]) & (g[:, 0] != g[:, 2])
        g, kept = g[keep], lab[keep]
        _, first = np.unique(np.sort(g, axis=1), axis=0, return_index=True)
        first.sort()
        if len(first) <= max_faces:
            used, g = np.unique(g[first], return_inverse=True)
            return merged[used], g.reshape(-1, 3), kept[first]
        cell *= 1.25


def spurious_flags(zero_set: ZeroSet, points: ArrayLike, *, faces: ArrayLike | None = None,
                   ordered_contour: bool = False, tau: float | None = None,
                   n_spurious: int | None = None) -> NDArray[np.bool_]:
    """Which components of ``zero_set`` are spurious, by the rule of :func:`ipfit.quality`.

    A component is spurious when no part of it comes within τ of the data. Each component
    is measured by :func:`ipfit.quality` on its own, so the rule is quality's, not a copy.
    ``n_spurious`` (the count a result already records) skips the work when it decides the
    answer: 0, or every component.
    """
    from ...zeroset.quality import quality

    n = zero_set.n_components
    if n_spurious is not None and n_spurious in (0, n):
        return np.full(n, bool(n_spurious))
    flags = np.zeros(n, dtype=bool)
    pieces = zero_set.components()
    for c, piece in enumerate(pieces):
        if zero_set.dim == 2:
            part = ZeroSet(2, zero_set.bounds, zero_set.spacing, zero_set.shape, curves=(piece,))
        else:
            part = ZeroSet(3, zero_set.bounds, zero_set.spacing, zero_set.shape, vertices=piece[0], faces=piece[1])
        flags[c] = quality(part, points, faces=faces, ordered_contour=ordered_contour, tau=tau).n_spurious > 0
    return flags

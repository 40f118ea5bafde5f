"""Noisy data: each point's neighbourhood grown to see past the noise, and their orientation.

On data whose noise is wider than the k nearest neighbours, the plain fit sees the noise, not the
shape, and sign propagation between close points runs across the noise band. :func:`noise_scale`
detects that case and picks, per point, the neighbourhood size at which it looks flattest;
:func:`orient_coarse` orients those normals on a denoised, coarser sample of the shape.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._utils.numeric import unique_rows
from .local import DEFAULT_K, argmax_per_group, blocks, flatness_of, neighbours, pca, spread
from .orient import orient_graph, winding_numbers

# Noise: the share of a neighbourhood's spread along its normal (the surface variation
# λ_min / Σλ of Pauly et al. 2002) is near 0 on a clean curve or surface sampled finely enough,
# and tends to 1/D where the noise is wider than the neighbourhood. Above these medians at the
# given k, the data may be noisy (clean bundled data: at most 0.025 in 2D except the coarse
# 200-point airplane's 0.12, 0.005 in 3D; boot and butterfly with noise of 0.5 % of their size:
# 0.24; bunny_res2: 0.08; a sphere of 3,000 points with noise 0.5 %: 0.03) ...
_NOISY = {2: 0.1, 3: 0.025}
# ... and the neighbourhoods are grown, doubling k up to this factor (Mitra & Nguyen 2003: a
# neighbourhood must be several times wider than the noise for its PCA to see the shape; much
# wider and curvature takes over). Noise it is if growing lowers the median surface variation
# below _GAIN of its value at k or 2k, whichever is larger (a few points of pure noise look
# flatter than they are: 0.24 at k = 6 in 2D, 0.33 at 12): on coarse but clean shapes (the
# airplane, bunny_res4, a torus of 300 points) wider neighbourhoods are only rounder.
# In 3D, noise must also show in the smallest neighbourhoods: the point and its 3 nearest, a
# tetrahedron, flat on a clean surface and of random shape under noise (median surface variation
# 0.0105-0.0165 on every noisy sphere, torus and ellipsoid of 300-3,000 points the test above takes
# for noisy; 0.011-0.016 on a noisy torus of 300,000). Clean but sparse or uneven samples, such as
# CAD meshes' vertices (rows of points, creases, thin parts, a coarse sampling of small details),
# are rough at 12 points, but their tetrahedra are flat: 0-0.005 on the 12 development meshes,
# 0.004 on bunny_res4. Wider neighbourhoods would only blur them.
_ROUGH_TETRAHEDRA = 0.008
_MAX_GROWTH = 32
_MAX_WIDE_K = 400
_GAIN = 0.75
# A surface's neighbourhood is local while its radius (median over the points) is at most this
# share of the cloud's box diagonal; wider ones are not chosen and do not count as evidence of noise.
# On small clouds under heavy noise (the Turk turbine, hammerhead and airplane: 1,300-3,300
# points at σ = 1 % of the diagonal) only neighbourhoods of 10-16 % of the diagonal looked
# flatter, because they see the object's overall shape, not averaged noise: their normals were
# 35-45° off with a third of the signs wrong, and the fits fell to F 0.15-0.63; the plain
# estimate gives 0.88-0.98 there (docs/robust.md). The bundled bunny and duck at σ = 1 % flatten
# at 4-5 % (k = 192-384 of 35,000 points), well inside.
_LOCAL_REACH = 0.08
# Noise of known σ (the outlier score's estimate) that no neighbourhood size flattens: σ = 1 % of
# the diagonal on meshes of 3,000-10,000 vertices (homer, the rocker arm, cheburashka, fandisk),
# where the shape curves within the few σ a neighbourhood must span. The k nearest points then
# reach about 2 σ and fit the noise (normals 24-32° off, a quarter to a third of the signs wrong:
# homer's fit F 0.94); the neighbourhoods are grown to the first size whose median radius is
# SIGMAS_WIDE σ (normals 11-15° off, under 5 % of the signs wrong; homer's fit F 0.99). Local sizes
# only, as above. Parts thinner than that come out inside out as wholes (the cow's legs), which
# fit_adaptive answers with a look at the plain normals when the fit is poor.
SIGMAS_WIDE = 4.0
# ... when the k nearest reach less than this many σ. At σ = 0.5 % they reach 3.5-4 σ, and growing
# them to 4 σ cost the cow, homer and cheburashka up to 0.01 of F.
SIGMAS_ENOUGH = 3.0


# Each noisy point takes its sign from the _VOTERS representatives nearest to it, weighted by
# the inverse square of a distance that counts the offset along their normals _OFF_SHEET + 1
# times: across a thin part (a bunny's ear, a few times the noise thick) the other side's
# representatives are near but off their sheet, and must not vote.
_VOTERS = 8
_OFF_SHEET = 8.0
_CELL = 3.0  # the representatives' grid: the neighbourhoods' median radius over this
# A representative's sheet is looked at _SHEET_STEP cells off it on either side; it is one sheet of
# a thin solid where the mean winding number there is within _ONE_SHEET of 0 (a solid's surface:
# ½), of a thin gap within _ONE_SHEET of 1 (see _one_sheet_sides).
_SHEET_STEP = 1.0
_ONE_SHEET = 0.25
# ... and of a patch of them: at least half of its _PATCH nearest representatives are one too.
_PATCH = 6
# Sources of those winding numbers: at most this many representatives, spread.
_WINDING_SOURCES = 10_000


class _Scaled(NamedTuple):
    normals: NDArray[np.float64]
    flatness: NDArray[np.float64]
    centroid: NDArray[np.float64]  # of each point's chosen neighbourhood
    radius: float  # median radius of the chosen neighbourhoods
    confidence: NDArray[np.float64]  # 1 - λ₁/λ₂ of the chosen neighbourhood (local.normal_confidence)
    by_sigma: bool = False  # every neighbourhood grown to SIGMAS_WIDE σ of a known noise (none looked flatter)


def roughness(points: NDArray, idx: NDArray[np.intp], flatness: NDArray) -> float | None:
    """The median surface variation of the neighbourhoods ``idx`` if it says noise, else None.

    ``idx`` may be the neighbourhoods of a sample of the points (the test of a big cloud).
    """
    dim = points.shape[1]
    start = float(np.median((1.0 - flatness) / dim))
    if start <= _NOISY[dim]:
        return None
    if dim == 3 and idx.shape[1] >= 4:
        tetrahedra = float(np.median((1.0 - flatness_of(pca(points, idx[:, :4])[1])) / dim))
        if tetrahedra <= _ROUGH_TETRAHEDRA:
            return None
    return start


def noise_scale(points: NDArray, tree: cKDTree, idx: NDArray[np.intp], flatness: NDArray,
                workers: int, sigma: float | None = None) -> _Scaled | None:
    """Normals on neighbourhoods grown to see past the noise, or None if the data are not noisy.

    Each point gets the scale (k doubled 1 to 5 times) at which the surface variation, averaged
    over its k nearest neighbours to steady it, is least: where the shape is smooth that is a
    wide neighbourhood that averages the noise; near thin parts and tight bends, where wide
    neighbourhoods take in the other side or the bend, a narrower one. In 3D only local
    neighbourhoods count (at most ``_LOCAL_REACH`` of the box diagonal wide, see there).
    In 3D, when no scale is flatter and the noise's ``sigma`` (in the units of ``points``) is
    known, every point gets the first scale at least ``SIGMAS_WIDE`` σ wide, if the k nearest
    reach less than ``SIGMAS_ENOUGH`` σ.
    """
    n, k = idx.shape
    dim = points.shape[1]
    start = roughness(points, idx, flatness)
    if start is None:
        return None
    k_max = min(_MAX_GROWTH * k, _MAX_WIDE_K, n // 4)
    scales = []
    kk = 2 * k
    while kk <= k_max:
        scales.append(kk)
        kk *= 2
    if not scales:
        return None
    m = len(scales)
    normals = np.empty((m, n, dim))
    values = np.empty((m, n, dim))
    centroid = np.empty((m, n, dim))
    reach = np.empty((m, n))  # distance to the farthest point of each neighbourhood
    sizes = np.array(scales, dtype=np.intp)
    from ._scale_kernels import multiscale_pca  # here: numba loads only for noisy data
    # In the k-d tree's leaf order, neighbours are near each other in memory: the wide queries
    # and the pass over them read from cache (twice as fast on 10⁵ points).
    order = tree.indices
    local = points[order]
    local_tree = cKDTree(local)
    # Blocks of points, so the widest neighbourhoods (up to _MAX_WIDE_K points each) are never
    # held for all points at once.
    for rows in blocks(n, scales[-1]):
        dist, wide = local_tree.query(local[rows], k=scales[-1], workers=workers)
        wide = np.minimum(wide, n - 1)  # an overflowed distance finds no point: any index keeps shapes
        b = len(wide)
        block = np.empty((m, b, dim)), np.empty((m, b, dim)), np.empty((m, b, dim))
        multiscale_pca(local, wide, sizes, *block)
        at = order[rows]
        normals[:, at], values[:, at], centroid[:, at] = block
        reach[:, at] = dist[:, sizes - 1].T
    flat = np.stack([flatness_of(v) for v in values])
    with np.errstate(divide="ignore", invalid="ignore"):
        support = np.where(values[:, :, 1] > 0, 1.0 - values[:, :, 0] / values[:, :, 1], 0.0)
    variation = (1.0 - flat) / dim  # (scales, n)
    local = np.ones(m, dtype=bool)
    if dim == 3:
        local = np.median(reach, axis=1) <= _LOCAL_REACH * float(np.linalg.norm(np.ptp(points, axis=0)))
        if not local.any():
            return None
    medians = np.median(variation, axis=1)
    at = np.arange(n)
    if medians[local].min() > _GAIN * max(start, medians[0]):
        wide = _wide_enough(points, idx, np.median(reach, axis=1), local, sigma)
        if wide is None:
            return None
        choice, by_sigma = np.full(n, wide), True
    else:
        by_sigma = False
        smooth = variation[:, idx].mean(axis=2)
        smooth[~local] = np.inf
        choice = np.argmin(smooth, axis=0)
    normals, flat, centroid = normals[choice, at], flat[choice, at], centroid[choice, at]
    radius = float(np.median(reach[choice, at]))
    return _Scaled(normals, flat, centroid, radius, np.clip(support[choice, at], 0.0, 1.0), by_sigma)


def _wide_enough(points: NDArray, idx: NDArray[np.intp], reach: NDArray, local: NDArray[np.bool_],
                 sigma: float | None) -> int | None:
    """The index of the first local scale whose median ``reach`` is ``SIGMAS_WIDE`` σ (else the widest
    local one), or None when σ is unknown or the k nearest of ``idx`` reach ``SIGMAS_ENOUGH`` σ."""
    if sigma is None or not sigma > 0 or points.shape[1] != 3:
        return None
    wanted = SIGMAS_WIDE * sigma
    if float(np.median(np.linalg.norm(points[idx[:, -1]] - points, axis=1))) >= SIGMAS_ENOUGH * sigma:
        return None
    fits = np.flatnonzero(local & (reach >= wanted))
    return int(fits[0]) if len(fits) else int(np.flatnonzero(local)[-1])


def orient_coarse(points: NDArray, tree: cKDTree, scaled: _Scaled, workers: int) -> NDArray[np.float64]:
    """Orient the normals of noisy points on a denoised, coarser sample of the shape.

    On noisy data the sign propagation between neighbouring points fails: the link between two
    close points runs across the noise band as often as along the shape. The centroids of the
    wide neighbourhoods lie on a smoothed copy of the shape (their noise is the points' divided
    by √k); one centroid per cell of a grid a third of the neighbourhoods' median radius wide
    (and no two closer than half that) is a clean, evenly spaced sample of it, oriented by
    :func:`orient_graph` like clean data. Each point then takes the sign that agrees best with the
    oriented representatives nearest to it on its own side (see _OFF_SHEET).
    """
    normals, flatness, centroid, radius = scaled.normals, scaled.flatness, scaled.centroid, scaled.radius
    n, dim = points.shape
    size = radius / _CELL
    fallback = not size > 0
    if not fallback:
        keys = np.floor((centroid - centroid.min(axis=0)) / size).astype(np.int64)
        cell = unique_rows(keys)[2]
        ncell = int(cell.max()) + 1
        counts = np.bincount(cell, minlength=ncell).astype(float)
        mean = np.stack([np.bincount(cell, centroid[:, j], ncell) for j in range(dim)], axis=1) / counts[:, None]
        gap = centroid - mean[cell]
        # in the cells' order, not the points': the result does not depend on the input order
        rep = argmax_per_group(-np.einsum("ij,ij->i", gap, gap), cell, ncell)
        close = cKDTree(centroid[rep]).query_pairs(size / 2.0, output_type="ndarray")
        if len(close):
            rep = np.delete(rep, np.unique(close.max(axis=1)))
        fallback = len(rep) < dim + 2
    if fallback:
        return orient_graph(points, normals, neighbours(tree, min(DEFAULT_K[dim], n), workers), flatness, tree=tree)
    coarse = centroid[rep]
    m = len(rep)
    coarse_tree = cKDTree(coarse)
    oriented = orient_graph(coarse, normals[rep], neighbours(coarse_tree, min(DEFAULT_K[dim], m), workers),
                            flatness[rep], tree=coarse_tree)
    near = neighbours(coarse_tree, min(_VOTERS, m), workers, points)
    step = points[:, None, :] - coarse[near]
    off = np.einsum("ikj,ikj->ik", step, oriented[near])
    cost = np.einsum("ikj,ikj->ik", step, step) + _OFF_SHEET * off ** 2
    weight = 1.0 / (cost + (1e-9 * radius) ** 2) ** 2
    # a representative of a thin part seen as one sheet has the points of both its sides: each
    # takes the side it lies on (outward of a thin solid, inward of a thin gap)
    sheet = _one_sheet_sides(coarse, coarse_tree, oriented, size, workers) if dim == 3 else np.zeros(m)
    side = np.where(sheet[near] == 0, 1.0, sheet[near] * np.where(off < 0, -1.0, 1.0))
    vote = (weight * side * np.einsum("ij,ikj->ik", normals, oriented[near])).sum(axis=1)
    return normals * np.where(vote < 0, -1.0, 1.0)[:, None]


def _one_sheet_sides(coarse: NDArray, tree: cKDTree, oriented: NDArray, size: float,
                     workers: int) -> NDArray[np.float64]:
    """Per representative: 0 on the surface of a solid, +1 where the shape lies on neither side
    of its sheet (a thin solid seen as one sheet: its points face away from it), −1 where it lies
    on both (a thin gap: they face it).

    At noise comparable to a part's thickness (a bunny's ear at σ = 1 % of the box diagonal is
    about 2 σ thick) the wide neighbourhoods' centroids of both its sides fall on its middle, and
    the representatives there are one sheet, oriented one way: one side's points came out inside
    out as a whole. The generalized winding number of the oriented representatives tells the
    sheets apart: just off a solid's surface it is 1 behind and 0 in front (mean ½), off a thin
    solid's middle sheet ±½ (mean 0: outside on both sides), off a thin gap's ½ ± ½ + ½ (mean 1).
    """
    sources = spread(coarse, _WINDING_SOURCES)
    step = _SHEET_STEP * size
    off = np.vstack([coarse - step * oriented, coarse + step * oriented])
    behind, ahead = np.split(winding_numbers(off, coarse[sources], oriented[sources], (size / 2.0) ** 2), 2)
    jump = float(np.median(behind - ahead))  # 1 × the sources' common area, wherever the sheet
    if not jump > 0:
        return np.zeros(len(coarse))
    mean = (behind + ahead) / (2.0 * jump)
    outward = 1.0 if np.median(mean) >= 0 else -1.0  # orient_graph's choice: mostly out (mean ½)
    level = outward * mean
    sheet = np.zeros(len(coarse))
    sheet[np.abs(level) < _ONE_SHEET] = outward
    sheet[level > 1.0 - _ONE_SHEET] = -outward
    # a thin part is a patch of the sheet, not a lone representative (a hole's rim, a crease)
    if len(coarse) > _PATCH:
        near = neighbours(tree, _PATCH + 1, workers)[:, 1:]
        sheet[(sheet[near] == sheet[:, None]).sum(axis=1) < _PATCH // 2] = 0.0
    return sheet


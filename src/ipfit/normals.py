"""Normal vectors for point clouds: estimation, consistent orientation and comparison.

:func:`estimate_normals` fits a tangent line/plane to each point's k nearest neighbours
(Hoppe et al. 1992), refitted where those are the wrong sample: along the curve in 2D
(NN-crust neighbours), across the curves of surfaces sampled on distant rings or scan lines
in 3D; :func:`orient_normals` makes the signs consistent by propagation along a
minimum spanning tree of the neighbour graph, seeded at points whose outward direction is
known, so that closed shapes get outward normals. :func:`contour_normals` gives the normals of
an ordered 2D contour, and :func:`normal_agreement` compares two sets of normals.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import spsolve
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ._validation import as_points, check_int, error

__all__ = [
    "DEFAULT_K",
    "estimate_normals",
    "orient_normals",
    "contour_normals",
    "normal_agreement",
    "Agreement",
]

# Default neighbourhood sizes (the point itself included). A contour is a curve: k points
# reach about k/2 samples to each side. 6 (±2-3 samples) is enough to average the 45° steps of
# pixel-traced contours, and small enough not to round off the tips of coarse polygons (the
# 200-point airplane) nor to reach across thin parts. A surface needs a 2D patch: 12 is about
# the first two rings of neighbours, which averages scanner noise on the bunny and the duck
# while staying inside thin parts (ears, beak); larger k blurs creases.
DEFAULT_K = {2: 6, 3: 12}

# Kruskal treats zero weights as missing edges; this keeps perfectly consistent edges in.
_WEIGHT_FLOOR = 1e-9
# Tree links heavier than this are doubtful: the pieces between them are re-oriented as wholes.
_DOUBTFUL = 0.1
_CHUNK = 1 << 15  # points per block of the batched eigen-decomposition: bounds memory
_BLOCK_ELEMENTS = 1 << 19  # and points × neighbours per block, for wide neighbourhoods


class Agreement(NamedTuple):
    """How two sets of normals agree, row by row (rows with NaN in either are skipped).

    ``angles`` are between the normal lines in degrees (0-90, orientation ignored);
    ``flipped`` marks rows whose normals point to opposite sides (negative dot product).
    """

    angles: NDArray[np.float64]
    flipped: NDArray[np.bool_]
    median_angle: float
    flipped_fraction: float
    compared: int


def _default_k(k, dim: int, n: int) -> int:
    k = DEFAULT_K[dim] if k is None else check_int(k, "k", minimum=dim)
    return int(min(k, n))


def _neighbours(points: NDArray, k: int, workers: int) -> NDArray[np.intp]:
    _, idx = cKDTree(points).query(points, k=k, workers=workers)
    return np.asarray(idx, dtype=np.intp).reshape(len(points), k)


def _pca_normals(points: NDArray, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Direction of least spread of each neighbourhood (row of ``idx``), and how flat it is."""
    n, dim = len(idx), points.shape[1]
    normals = np.empty((n, dim))
    flatness = np.empty(n)
    chunk = min(_CHUNK, max(1, _BLOCK_ELEMENTS // idx.shape[1]))
    for start in range(0, n, chunk):  # blocks of points, not points: bounds the (B, k, D) copy
        nb = points[idx[start:start + chunk]]
        centred = nb - nb.mean(axis=1, keepdims=True)
        cov = np.matmul(centred.transpose(0, 2, 1), centred)
        # Unit trace: eigh's tolerances and the flatness no longer depend on the data's units.
        trace = np.trace(cov, axis1=1, axis2=2)
        cov /= np.where(trace > 0, trace, 1.0)[:, None, None]
        values, vectors = np.linalg.eigh(cov)  # ascending eigenvalues
        normals[start:start + chunk] = vectors[:, :, 0]
        # Share of the spread along the normal: 0 on a flat patch, 1/D when isotropic.
        flatness[start:start + chunk] = np.clip(1.0 - dim * values[:, 0], 0.0, 1.0)
    return normals, flatness


# A 3D point is on a "sampled curve" when its nearest _CURVE_K points (the point and ±3 samples
# along a curve) are nearly collinear: second singular value below _CURVE_RATIO of the first. A
# 24-gon ring gives 0.23 there; random samples of a surface rarely go below 0.3 (~2 % of a
# uniform sphere's points, where the refit below is harmless: it still finds the surface).
_CURVE_K = 7
_CURVE_RATIO = 0.3
_CURVE_LINK_SLOPE = np.sin(np.radians(20.0))  # links across the curve: this close to the tangent plane
# The refit's neighbourhood, in multiples of k (72 points for k = 12): it must reach past the
# point's own curve, so rings of up to ~60 points are handled. Too wide and it takes in other
# surfaces: on the apple, whose stem stands 4-6 mm from the dimple's wall, 4k and 8k both leave
# the stem's lowest ring (24 points) flipped; 6k gets it right.
_CURVE_REACH = 6


def _refit_sampled_curves(points: NDArray, idx: NDArray[np.intp], normals: NDArray,
                          workers: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Normals across the curves of anisotropically sampled surfaces (3D), in place.

    A lathe or scan-line model samples its surface densely along curves (rings of a stem,
    scan lines) that lie farther apart than the samples on them. Then the k nearest
    neighbours all lie on one curve, and their direction of least spread is the normal of the
    curve's plane (the stem's axis), not the surface's: on the bundled apple's stem, ~80° off.
    The surface contains the curve, so its normal is perpendicular to the curve's tangent t
    (reliable from the nearest few points); within the plane perpendicular to t, it is the
    direction of least spread of a neighbourhood wide enough to reach the neighbouring curves.

    Returns links for the orientation graph (whose k-nearest edges stay on the curve): from each
    refitted point to its nearest point on either side across the curve, near its tangent plane
    (within 20°): the orientation then follows the surface the normal was measured on.
    """
    n, k = idx.shape
    ks = min(_CURVE_K, k)
    none = np.empty(0, np.intp)
    if ks < 3 or n <= k:
        return none, none
    nb = points[idx[:, :ks]]
    centred = nb - nb.mean(axis=1, keepdims=True)
    values, vectors = np.linalg.eigh(np.matmul(centred.transpose(0, 2, 1), centred))
    values = np.clip(values, 0.0, None)
    curve = np.flatnonzero(values[:, 1] < _CURVE_RATIO ** 2 * values[:, 2])
    if len(curve) == 0:
        return none, none
    link_lo, link_hi = [], []
    kb = min(_CURVE_REACH * k, n)
    _, wide = cKDTree(points).query(points[curve], k=kb, workers=workers)
    for start in range(0, len(curve), _CHUNK):
        rows = slice(start, start + _CHUNK)
        t = vectors[curve[rows], :, 2]
        nb = points[wide[rows]]
        centred = nb - nb.mean(axis=1, keepdims=True)
        cov = np.matmul(centred.transpose(0, 2, 1), centred)
        trace = np.trace(cov, axis1=1, axis2=2)
        cov /= np.where(trace > 0, trace, 1.0)[:, None, None]
        tt = t[:, :, None] * t[:, None, :]
        proj = np.eye(3) - tt
        # Spread across t only, and t itself made the direction of most spread: the least
        # is then the normal, perpendicular to the curve.
        _, vectors_w = np.linalg.eigh(proj @ cov @ proj + 2.0 * tt)
        nrm = vectors_w[:, :, 0]
        normals[curve[rows]] = nrm
        step = nb - points[curve[rows]][:, None, :]
        across = np.einsum("ikj,ij->ik", step, np.cross(nrm, t))
        along = np.abs(np.einsum("ikj,ij->ik", step, t))
        off = np.abs(np.einsum("ikj,ij->ik", step, nrm))
        length = np.linalg.norm(step, axis=2)
        fit = (np.abs(across) > along) & (off < _CURVE_LINK_SLOPE * length)
        for side in (across > 0, across < 0):
            cand = fit & side  # the wide neighbours come nearest first: take the first candidate
            has = cand.any(axis=1)
            first = np.argmax(cand, axis=1)
            link_lo.append(curve[rows][has])
            link_hi.append(wide[rows][has, first[has]])
    return np.concatenate(link_lo), np.concatenate(link_hi)


def _refit_along_curve(points: NDArray, idx: NDArray[np.intp], normals: NDArray, flatness: NDArray) -> None:
    """Refit 2D normals on the neighbours along the curve instead of the nearest ones, in place.

    On a coarse contour the k nearest points of a sharp tip or of one side of a thin part
    include points of the other side, and the fitted line mixes both (the airplane's tips:
    75° off). The curve through the points is reconstructed locally by the NN-crust of
    Dey & Kumar (1999): each point joins its nearest neighbour and its nearest neighbour on
    the other side (in the half-plane away from the first). Where those links are mutual for
    (k-1)//2 hops each way, the point is refitted on that chain of k-1 or k points (the same
    reach along the curve as k nearest points on a smooth part); elsewhere (branchings,
    ambiguous links of noisy or pixel-traced data) the k-nearest fit is kept.
    """
    n, k = idx.shape
    hops = (k - 1) // 2
    if hops < 1:
        return
    at = np.arange(n)
    step = points[idx[:, 1:]] - points[:, None, :]
    behind = np.einsum("ikj,ij->ik", step, step[:, 0]) < 0  # away from the nearest neighbour
    ok = behind.any(axis=1)
    second = np.where(ok, idx[:, 1:][at, np.argmax(behind, axis=1)], n)
    links = np.vstack([np.column_stack([idx[:, 1], second]), [n, n]])  # row n: "no point"
    chain = [at]
    for side in (0, 1):
        prev, cur = at, links[at, side]
        for _ in range(hops):
            # the link prev → cur must be mutual; then go on to cur's other link
            mutual = (links[cur, 0] == prev) | (links[cur, 1] == prev)
            ok &= mutual & (cur < n)
            chain.append(np.where(ok, cur, at))
            prev, cur = cur, np.where(links[cur, 0] == prev, links[cur, 1], links[cur, 0])
    chain = np.column_stack(chain)
    ordered = np.sort(chain, axis=1)
    ok &= (np.diff(ordered, axis=1) > 0).all(axis=1)  # a chain round a tiny loop repeats points
    use = np.flatnonzero(ok)
    if len(use):
        normals[use], flatness[use] = _pca_normals(points, chain[use])


def estimate_normals(points: ArrayLike, k: int | None = None, *, orient: bool = True,
                     workers: int = -1) -> NDArray[np.float64]:
    """Unit normals of a 2D or 3D point cloud by k-nearest-neighbour PCA.

    Two refinements of the plain fit, both where the k nearest neighbours are the wrong
    sample of the shape: in 2D each point is refitted on its neighbours *along* the curve
    (see :func:`_refit_along_curve`), so that the two sides of a thin part or of a sharp tip
    do not mix; in 3D, points whose nearest neighbours all lie on one sampled curve (rings,
    scan lines farther apart than the samples along them) get a normal across that curve
    (see :func:`_refit_sampled_curves`).

    Noisy data (noise wider than the k nearest neighbours) are detected and handled apart:
    each point's neighbourhood is grown to the scale where it looks flattest (up to 32k
    points, see :func:`_noise_scale`), and the signs are propagated on a denoised, coarser
    sample of the shape, from which each point takes its own (see :func:`_orient_coarse`).
    Parts thinner than a few times the noise (a butterfly's antennae under noise wider than
    they are) cannot be told apart and come out with one side flipped.

    Parameters
    ----------
    points : (N, D) array, D = 2 or 3, N >= 3
    k : int, optional
        Neighbours per point, the point itself included; default 6 in 2D, 12 in 3D
        (:data:`DEFAULT_K`). Lower it for thin parts; on noisy data it is the smallest
        neighbourhood tried (see above).
    orient : bool
        Make the signs consistent, outward for closed shapes (see :func:`orient_normals`).
        If False the signs are arbitrary.
    workers : int
        Threads for the neighbour search (-1: all cores).

    Returns
    -------
    (N, D) array of unit normals.

    >>> from ipfit.datasets.synthetic import circle
    >>> pts, true, _ = circle(100)
    >>> bool((estimate_normals(pts) * true).sum(axis=1).min() > 0.99)
    True
    """
    pts = as_points(points, min_points=3)
    idx = _neighbours(pts, _default_k(k, pts.shape[1], len(pts)), workers)
    normals, flatness = _pca_normals(pts, idx)
    scaled = _noise_scale(pts, idx, flatness, workers)
    if scaled is not None:
        # Noise-dominated: the normals of wider neighbourhoods, oriented on a denoised,
        # coarser sample of the shape (see _orient_coarse).
        return _orient_coarse(pts, scaled, workers) if orient else scaled.normals
    links = None
    if pts.shape[1] == 2:
        _refit_along_curve(pts, idx, normals, flatness)
    else:
        links = _refit_sampled_curves(pts, idx, normals, workers)
    return _orient(pts, normals, idx, flatness, links) if orient else normals


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
_MAX_GROWTH = 32
_MAX_WIDE_K = 400
_GAIN = 0.75


# Each noisy point takes its sign from the _VOTERS representatives nearest to it, weighted by
# the inverse square of a distance that counts the offset along their normals _OFF_SHEET + 1
# times: across a thin part (a bunny's ear, a few times the noise thick) the other side's
# representatives are near but off their sheet, and must not vote.
_VOTERS = 8
_OFF_SHEET = 8.0
_CELL = 3.0  # the representatives' grid: the neighbourhoods' median radius over this


class _Scaled(NamedTuple):
    normals: NDArray[np.float64]
    flatness: NDArray[np.float64]
    centroid: NDArray[np.float64]  # of each point's chosen neighbourhood
    radius: float  # median radius of the chosen neighbourhoods


def _noise_scale(points: NDArray, idx: NDArray[np.intp], flatness: NDArray, workers: int) -> _Scaled | None:
    """Normals on neighbourhoods grown to see past the noise, or None if the data are not noisy.

    Each point gets the scale (k doubled 1 to 5 times) at which the surface variation, averaged
    over its k nearest neighbours to steady it, is least: where the shape is smooth that is a
    wide neighbourhood that averages the noise; near thin parts and tight bends, where wide
    neighbourhoods take in the other side or the bend, a narrower one.
    """
    n, k = idx.shape
    dim = points.shape[1]
    start = float(np.median((1.0 - flatness) / dim))
    if start <= _NOISY[dim]:
        return None
    k_max = min(_MAX_GROWTH * k, _MAX_WIDE_K, n // 4)
    scales = []
    kk = 2 * k
    while kk <= k_max:
        scales.append(kk)
        kk *= 2
    if not scales:
        return None
    dist, wide = cKDTree(points).query(points, k=scales[-1], workers=workers)
    wide = np.asarray(wide, dtype=np.intp).reshape(n, scales[-1])
    dist = np.asarray(dist).reshape(n, scales[-1])
    fits = [_pca_normals(points, wide[:, :kk]) for kk in scales]
    variation = np.stack([(1.0 - fl) / dim for _, fl in fits])  # (scales, n)
    medians = np.median(variation, axis=1)
    if medians.min() > _GAIN * max(start, medians[0]):
        return None
    smooth = variation[:, idx].mean(axis=2)
    choice = np.argmin(smooth, axis=0)
    at = np.arange(n)
    normals = np.stack([nrm for nrm, _ in fits])[choice, at]
    flat = np.stack([fl for _, fl in fits])[choice, at]
    size = np.asarray(scales)[choice]
    centroid = np.empty_like(points)
    block = max(1, _BLOCK_ELEMENTS // scales[-1])
    for s in range(0, n, block):
        rows = slice(s, s + block)
        within = np.arange(scales[-1]) < size[rows, None]
        centroid[rows] = (points[wide[rows]] * within[:, :, None]).sum(axis=1) / size[rows, None]
    radius = float(np.median(dist[at, size - 1]))
    return _Scaled(normals, flat, centroid, radius)


def _orient_coarse(points: NDArray, scaled: _Scaled, workers: int) -> NDArray[np.float64]:
    """Orient the normals of noisy points on a denoised, coarser sample of the shape.

    On noisy data the sign propagation between neighbouring points fails: the link between two
    close points runs across the noise band as often as along the shape. The centroids of the
    wide neighbourhoods lie on a smoothed copy of the shape (their noise is the points' divided
    by √k); one centroid per cell of a grid a third of the neighbourhoods' median radius wide
    (and no two closer than half that) is a clean, evenly spaced sample of it, oriented by
    :func:`_orient` like clean data. Each point then takes the sign that agrees best with the
    oriented representatives nearest to it on its own side (see _OFF_SHEET).
    """
    normals, flatness, centroid, radius = scaled
    n, dim = points.shape
    size = radius / _CELL
    fallback = not size > 0
    if not fallback:
        keys = np.floor((centroid - centroid.min(axis=0)) / size).astype(np.int64)
        _, cell = np.unique(keys, axis=0, return_inverse=True)
        cell = cell.ravel()
        ncell = int(cell.max()) + 1
        counts = np.bincount(cell, minlength=ncell).astype(float)
        mean = np.stack([np.bincount(cell, centroid[:, j], ncell) for j in range(dim)], axis=1) / counts[:, None]
        gap = centroid - mean[cell]
        # in the cells' order, not the points': the result does not depend on the input order
        rep = _argmax_per_group(-np.einsum("ij,ij->i", gap, gap), cell, ncell)
        close = cKDTree(centroid[rep]).query_pairs(size / 2.0, output_type="ndarray")
        if len(close):
            rep = np.delete(rep, np.unique(close.max(axis=1)))
        fallback = len(rep) < dim + 2
    if fallback:
        return _orient(points, normals, _neighbours(points, DEFAULT_K[dim], workers), flatness)
    coarse = centroid[rep]
    m = len(rep)
    oriented = _orient(coarse, normals[rep], _neighbours(coarse, min(DEFAULT_K[dim], m), workers), flatness[rep])
    near_k = min(_VOTERS, m)
    _, near = cKDTree(coarse).query(points, k=near_k, workers=workers)
    near = np.reshape(near, (n, near_k))
    step = points[:, None, :] - coarse[near]
    off = np.einsum("ikj,ikj->ik", step, oriented[near])
    cost = np.einsum("ikj,ikj->ik", step, step) + _OFF_SHEET * off ** 2
    weight = 1.0 / (cost + (1e-9 * radius) ** 2) ** 2
    vote = (weight * np.einsum("ij,ikj->ik", normals, oriented[near])).sum(axis=1)
    return normals * np.where(vote < 0, -1.0, 1.0)[:, None]


def orient_normals(points: ArrayLike, normals: ArrayLike, k: int | None = None, *,
                   workers: int = -1) -> NDArray[np.float64]:
    """Flip normals so that neighbours agree and closed shapes point outward.

    The signs propagate along a minimum spanning tree of the k-nearest-neighbour graph
    (Hoppe et al. 1992), rooted at anchors whose outward direction is known: the vertices of
    the convex hull, and in each connected component its point farthest from its centroid.
    Two changes to Hoppe's 1 − |n_i·n_j| make it robust on thin parts and sharp tips: the
    edge weight compares n_i with n_j mirrored across the bisector of the two points, and
    the pieces of the tree between doubtful links are re-oriented as wholes by a least-squares
    vote of all neighbour edges and anchors.

    Parameters
    ----------
    points : (N, D) array
    normals : (N, D) array
        Normals whose signs may be arbitrary; their lines are kept.
    k : int, optional
        Neighbours per point for the graph (default as in :func:`estimate_normals`).
    workers : int
        Threads for the neighbour search.

    Returns
    -------
    (N, D) array: the unit normals, some negated.
    """
    pts = as_points(points, min_points=3)
    nrm = as_points(normals, "normals", dims=(pts.shape[1],))
    if nrm.shape != pts.shape:
        raise error("normals", f"shape {pts.shape} to match the points", f"shape {nrm.shape}",
                    "Pass one normal per point.")
    length = np.linalg.norm(nrm, axis=1)
    if not (length > 0).all():
        raise error("normals", "non-zero normal vectors", f"{int((length == 0).sum())} zero-length normals",
                    "Estimate them with ipfit.estimate_normals.")
    idx = _neighbours(pts, _default_k(k, pts.shape[1], len(pts)), workers)
    return _orient(pts, nrm / length[:, None], idx, np.ones(len(pts)))


def _orient(points: NDArray, normals: NDArray, idx: NDArray[np.intp], flatness: NDArray,
            links: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None) -> NDArray[np.float64]:
    n = len(points)
    rows = np.repeat(np.arange(n), idx.shape[1])
    cols = idx.ravel()
    # Each undirected edge once (COO → CSR would sum duplicate weights): j→i is dropped when i→j
    # is also listed, i.e. when i is among j's neighbours too.
    mutual = (idx[cols] == rows[:, None]).any(axis=1)
    keep = (rows != cols) & ((rows < cols) | ~mutual)
    lo, hi = rows[keep], cols[keep]
    if links is not None and len(links[0]):
        # Extra links, each once and only if not already a k-nearest edge.
        a, b = np.minimum(*links), np.maximum(*links)
        pairs = np.unique(np.column_stack([a, b])[a != b], axis=0)
        a, b = pairs[:, 0], pairs[:, 1]
        known = (idx[a] == b[:, None]).any(axis=1) | (idx[b] == a[:, None]).any(axis=1)
        lo, hi = np.concatenate([lo, a[~known]]), np.concatenate([hi, b[~known]])
    bridge_lo, bridge_hi = _bridges(points, lo, hi, idx.shape[1])
    lo, hi = np.concatenate([lo, bridge_lo]), np.concatenate([hi, bridge_hi])
    agree, off_plane = _consistency(points, normals, lo, hi, with_off_plane=True)
    # Links through curved or rough neighbourhoods (creases, tips, noise) are less trustworthy
    # than their normals' agreement says: the flatness terms make the tree avoid them. So are
    # links leaving both tangent planes: between close points, a step along the normal is more
    # often noise than the crossing of a thin part, and it reverses the mirrored comparison.
    doubt = 1.0 - flatness
    weight = np.maximum(1.0 - np.abs(agree), 0.0) + doubt[lo] + doubt[hi] + off_plane + _WEIGHT_FLOOR
    ncomp, labels = csgraph.connected_components(sparse.csr_matrix((weight, (lo, hi)), shape=(n, n)),
                                                 directed=False)

    # Anchors hang from one virtual node: the tree roots each branch at the anchor that reaches
    # it most cheaply, so one ambiguous link cannot flip everything behind it.
    anchor, direction = _anchors(points, labels, ncomp)
    anchor_cos = np.einsum("ij,ij->i", normals[anchor], direction)
    anchor_weight = np.maximum(1.0 - np.abs(anchor_cos), 0.0) + doubt[anchor] + _WEIGHT_FLOOR
    virtual = n
    graph = sparse.csr_matrix((np.concatenate([weight, anchor_weight]),
                               (np.concatenate([lo, anchor]), np.concatenate([hi, np.full(len(anchor), virtual)]))),
                              shape=(n + 1, n + 1))
    tree = csgraph.minimum_spanning_tree(graph)
    _, pred = csgraph.breadth_first_order(tree, virtual, directed=False, return_predecessors=True)

    parent = pred[:n].astype(np.intp)
    parent[parent < 0] = virtual  # unreachable cannot happen (every component has an anchor); be safe
    flip = np.zeros(n + 1, dtype=bool)
    inner = np.flatnonzero(parent != virtual)
    flip[inner] = _consistency(points, normals, inner, parent[inner]) < 0
    cos_to_anchor = np.zeros(n)
    cos_to_anchor[anchor] = anchor_cos
    rooted = np.flatnonzero(parent == virtual)
    flip[rooted] = cos_to_anchor[rooted] < 0

    # Sign of each node = parity of the flips on its path to the root, by pointer jumping:
    # log2(depth) vectorised rounds instead of a walk down the tree.
    anc = np.append(parent, virtual)
    parity = flip
    while True:
        done = anc == virtual
        if done.all():
            break
        parity = parity ^ (parity[anc] & ~done)
        anc = np.where(done, anc, anc[anc])
    sign = np.where(parity[:n], -1.0, 1.0)

    # A tree decides each doubtful link (a tip, a crease) on one edge alone. Cut it there and
    # flip the pieces as wholes to agree best, in least squares, with all neighbour edges
    # (signed by their agreement and flatness) and all anchors: a small system, one unknown
    # per piece.
    t = tree.tocoo()
    sure = (t.row < n) & (t.col < n) & (t.data < _DOUBTFUL)
    npieces, piece = csgraph.connected_components(
        sparse.csr_matrix((np.ones(int(sure.sum())), (t.row[sure], t.col[sure])), shape=(n, n)), directed=False)
    if npieces > 1:
        vote = agree * flatness[lo] * flatness[hi] * sign[lo] * sign[hi]
        across = piece[lo] != piece[hi]
        pi, pj, v = piece[lo][across], piece[hi][across], vote[across]
        coupling = sparse.csr_matrix((np.concatenate([v, v]), (np.concatenate([pi, pj]), np.concatenate([pj, pi]))),
                                     shape=(npieces, npieces))
        degree = np.bincount(np.concatenate([pi, pj]), np.abs(np.concatenate([v, v])), npieces)
        trust = flatness[anchor] * np.abs(anchor_cos)
        pull = np.bincount(piece[anchor], trust, npieces)
        rhs = np.bincount(piece[anchor], trust * np.sign(anchor_cos) * sign[anchor], npieces)
        # Signed graph Laplacian + anchor terms: positive definite wherever a piece connects to
        # an anchor; the tiny shift keeps isolated, unanchored pieces (x = 0: left as they are) solvable.
        system = (sparse.diags(degree + pull + 1e-12) - coupling).tocsc()
        x = spsolve(system, rhs, permc_spec="MMD_AT_PLUS_A")
        sign *= np.where(x[piece] < 0, -1.0, 1.0)
    return normals * sign[:, None]


def _bridges(points: NDArray, lo: NDArray, hi: NDArray, k: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Edges joining the pieces of a k-nearest-neighbour graph that are close to each other.

    Sparse or uneven sampling splits a curve or surface into fragments whose own extreme
    points say nothing about outward (the farthest point of an arc fragment is at its end).
    As in Hoppe's Euclidean-MST edges, each fragment is joined by its shortest link to another
    one (Borůvka rounds), searching up to 8k neighbours: far-apart shapes stay separate.
    """
    n = len(points)
    graph = sparse.csr_matrix((np.ones(len(lo)), (lo, hi)), shape=(n, n))
    ncomp, labels = csgraph.connected_components(graph, directed=False)
    found_lo, found_hi = [], []
    tree = None
    reach = 2 * k
    while ncomp > 1 and reach <= 8 * k:
        if tree is None:
            tree = cKDTree(points)
        largest = np.argmax(np.bincount(labels))
        query = np.flatnonzero(labels != largest)  # links are symmetric: the largest piece is found by the others
        dist, near = tree.query(points[query], k=min(reach, n))
        dist = np.where(labels[near] != labels[query][:, None], dist, np.inf)
        best = np.argmin(dist, axis=1)
        rows = np.arange(len(query))
        dist, near = dist[rows, best], near[rows, best]
        ok = np.isfinite(dist)
        if not ok.any():
            reach *= 2
            continue
        start, end, length, comp = query[ok], near[ok], dist[ok], labels[query[ok]]
        shortest = np.lexsort((length, comp))
        first = np.ones(len(shortest), dtype=bool)
        first[1:] = comp[shortest][1:] != comp[shortest][:-1]
        pick = shortest[first]  # the shortest link of each fragment that found one
        found_lo.append(start[pick])
        found_hi.append(end[pick])
        joined = sparse.csr_matrix((np.ones(len(pick)), (labels[start[pick]], labels[end[pick]])), shape=(ncomp, ncomp))
        ncomp, merged = csgraph.connected_components(joined, directed=False)
        labels = merged[labels]
    if not found_lo:
        return np.empty(0, np.intp), np.empty(0, np.intp)
    a, b = np.concatenate(found_lo), np.concatenate(found_hi)
    pairs = np.unique(np.column_stack([np.minimum(a, b), np.maximum(a, b)]), axis=0)  # A→B and B→A: once
    return pairs[:, 0].astype(np.intp), pairs[:, 1].astype(np.intp)


def _consistency(points: NDArray, normals: NDArray, i: NDArray, j: NDArray, *, with_off_plane: bool = False):
    """n_i · R n_j, R the mirror across the bisector plane of p_i and p_j (König & Gumhold 2009).

    Points on a common circle or sphere with outward normals give exactly +1, whatever the
    curvature. The outward normals across a sharp tip or on the two sides of a thin part are
    mirror images, not parallel, so Hoppe's n_i · n_j alone would orient them wrongly.
    ``with_off_plane`` also returns |n_i·e| |n_j·e| (e: unit p_j − p_i), near 1 when the link
    runs along both normals.
    """
    e = points[j] - points[i]
    length = np.linalg.norm(e, axis=1)
    e /= np.where(length > 0, length, 1.0)[:, None]
    ni, nj = normals[i], normals[j]
    ai, aj = np.einsum("ij,ij->i", ni, e), np.einsum("ij,ij->i", nj, e)
    c = np.einsum("ij,ij->i", ni, nj) - 2.0 * ai * aj
    return (c, np.abs(ai * aj)) if with_off_plane else c


def _anchors(points: NDArray, labels: NDArray, ncomp: int) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Points with a known outward direction (unit vectors) on closed shapes.

    * The vertices of the convex hull: its facets are supporting planes, so the outward
      normal there is on the side of the mean of the adjacent facets' normals.
    * In each connected component, the point farthest from the component's centroid: the
      component lies in the ball through it, so its normal is along point − centroid.
    """
    dim = points.shape[1]
    counts = np.bincount(labels, minlength=ncomp).astype(float)
    centroid = np.stack([np.bincount(labels, points[:, j], ncomp) for j in range(dim)], axis=1) / counts[:, None]
    radial = points - centroid[labels]
    seeds = _argmax_per_group(np.einsum("ij,ij->i", radial, radial), labels, ncomp)
    idx, dirs = [seeds], [radial[seeds]]
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        pass  # flat or degenerate cloud: the seeds alone orient it
    else:
        acc = np.zeros_like(points)
        for j in range(dim):
            np.add.at(acc, hull.simplices[:, j], hull.equations[:, :dim])
        idx.insert(0, hull.vertices)
        dirs.insert(0, acc[hull.vertices])
    idx = np.concatenate(idx)
    dirs = np.concatenate(dirs)
    length = np.linalg.norm(dirs, axis=1)
    # A component whose points all coincide has no outward side: any direction will do.
    dirs[length == 0, 0], length[length == 0] = 1.0, 1.0
    dirs /= length[:, None]
    idx, first = np.unique(idx, return_index=True)
    return idx.astype(np.intp), dirs[first]


def _argmax_per_group(values: NDArray, labels: NDArray, ngroups: int) -> NDArray[np.intp]:
    order = np.lexsort((values, labels))
    last = np.cumsum(np.bincount(labels, minlength=ngroups)) - 1
    return order[last]


def contour_normals(points: ArrayLike, *, closed: bool = True, span: int = 1) -> NDArray[np.float64]:
    """Outward unit normals of an ordered 2D contour: perpendiculars of central differences.

    The outward side comes from the sign of the enclosed area (for an open contour, of the
    area closed by the chord between its ends), so either direction of travel works.

    Parameters
    ----------
    points : (N, 2) array, in order along the contour, N >= 3
    closed : bool
        Whether the last point connects back to the first.
    span : int
        Difference between the points ``span`` places ahead and behind. On pixel-traced
        contours span=1 only sees the 45° staircase; 2 or 3 averages it.

    >>> square = [[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]]
    >>> contour_normals(square)[1].tolist()
    [0.0, -1.0]
    """
    pts = as_points(points, dims=(2,), min_points=3)
    span = check_int(span, "span", minimum=1, maximum=max(1, (len(pts) - 1) // 2))
    if closed:
        nxt, prv = np.roll(pts, -span, axis=0), np.roll(pts, span, axis=0)
    else:
        at = np.arange(len(pts))
        nxt = pts[np.minimum(at + span, len(pts) - 1)]
        prv = pts[np.maximum(at - span, 0)]
    tangent = nxt - prv
    # A spike that goes out and back has a zero central difference: use a one-sided one.
    for fallback in (nxt - pts, pts - prv):
        zero = ~(np.abs(tangent).sum(axis=1) > 0)
        tangent[zero] = fallback[zero]
    x, y = pts[:, 0] - pts[:, 0].mean(), pts[:, 1] - pts[:, 1].mean()
    twice_area = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # right of travel: outward if counter-clockwise
    if twice_area < 0:
        normal = -normal
    length = np.linalg.norm(normal, axis=1)
    if not (length > 0).all():
        raise error("points", "a contour without repeated consecutive points",
                    f"{int((length == 0).sum())} points with no direction", "Remove repeated points first.")
    return normal / length[:, None]


def normal_agreement(estimated: ArrayLike, reference: ArrayLike) -> Agreement:
    """Compare two sets of normals row by row.

    Rows where either has NaN (e.g. mesh vertices without faces) are skipped.

    Returns
    -------
    Agreement
        Angles between the normal lines in degrees, which rows are flipped, the median
        angle, the fraction flipped and the number of rows compared.

    >>> a = normal_agreement([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, -1.0]])
    >>> a.median_angle, a.flipped_fraction
    (0.0, 0.5)
    """
    est = np.asarray(estimated, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.ndim != 2 or est.shape != ref.shape:
        raise error("reference", f"an array of the same shape as estimated {est.shape}", f"shape {ref.shape}",
                    "Pass one normal per row of the same points.")
    ok = np.isfinite(est).all(axis=1) & np.isfinite(ref).all(axis=1)
    e, r = est[ok], ref[ok]
    denom = np.linalg.norm(e, axis=1) * np.linalg.norm(r, axis=1)
    cos = np.einsum("ij,ij->i", e, r) / np.where(denom > 0, denom, 1.0)
    angles = np.degrees(np.arccos(np.clip(np.abs(cos), 0.0, 1.0)))
    flipped = cos < 0
    m = int(ok.sum())
    if m == 0:
        return Agreement(angles, flipped, float("nan"), float("nan"), 0)
    return Agreement(angles, flipped, float(np.median(angles)), float(flipped.mean()), m)

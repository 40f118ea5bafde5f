"""Normal vectors for point clouds: estimation, consistent orientation and comparison.

:func:`estimate_normals` fits a tangent line/plane to each point's k nearest neighbours
(Hoppe et al. 1992) and :func:`orient_normals` makes the signs consistent by propagating
along a minimum spanning tree of the neighbour graph, seeded at extreme points whose outward
direction is known, so that closed shapes get outward normals. :func:`contour_normals` gives
the exact-order alternative for ordered 2D contours, and :func:`normal_agreement` compares two
sets of normals.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ._validation import as_points, check_int, error

__all__ = [
    "DEFAULT_K",
    "estimate_normals",
    "orient_normals",
    "contour_normals",
    "normal_agreement",
    "Agreement",
]

# Default neighbourhood sizes. A curve is a 1-manifold: k points span about k/2 samples on
# each side, so 10 averages the pixel staircase of traced contours (steps of 1 and sqrt(2))
# over ~5 px while staying narrower than the thin parts of typical silhouettes. A surface
# needs a 2D patch: 15 neighbours is about two rings around the point, enough to average
# scanner noise yet local enough for the ears of the bunny; larger k blurs creases and lets
# neighbourhoods reach across thin parts.
DEFAULT_K = {2: 10, 3: 15}

# Edge weight of the orientation graph: 1 − |n_i·n_j| (Hoppe) plus a penalty for edges that
# leave the tangent planes. Hoppe's weight alone is smallest between the two sides of a thin
# part (anti-parallel normals, |n_i·n_j| = 1), which is exactly where propagation must not
# go; the penalty |d·n| / |d| is ~0 along the surface and ~1 across it.
_CROSSING_PENALTY = 1.0
# Kruskal treats zero weights as missing edges; this keeps perfectly aligned edges in.
_WEIGHT_FLOOR = 1e-9


class Agreement(NamedTuple):
    """How two sets of normals agree, row by row (rows with NaN in either are skipped).

    ``angles`` are between the lines (0-90°, orientation ignored); ``flipped`` marks rows whose
    normals point to opposite sides (negative dot product).
    """

    angles: NDArray[np.float64]
    flipped: NDArray[np.bool_]
    median_angle: float
    flipped_fraction: float
    compared: int


def _default_k(k, dim: int, n: int, name: str = "k") -> int:
    if k is None:
        k = DEFAULT_K[dim]
    else:
        k = check_int(k, name, minimum=dim)
    return int(min(k, n))


def _neighbours(points: NDArray, k: int, workers: int) -> NDArray[np.intp]:
    _, idx = cKDTree(points).query(points, k=k, workers=workers)
    return np.asarray(idx, dtype=np.intp).reshape(len(points), k)


def _pca_normals(points: NDArray, idx: NDArray[np.intp]) -> NDArray[np.float64]:
    nb = points[idx]  # (N, k, D)
    centred = nb - nb.mean(axis=1, keepdims=True)
    cov = np.matmul(centred.transpose(0, 2, 1), centred)
    # Scale each covariance to unit trace: eigh's absolute tolerances then do not depend on
    # the units of the data (the bunny is ~0.1 m wide, silhouettes are hundreds of pixels).
    trace = np.trace(cov, axis1=1, axis2=2)
    cov /= np.where(trace > 0, trace, 1.0)[:, None, None]
    _, vectors = np.linalg.eigh(cov)
    return np.ascontiguousarray(vectors[:, :, 0])  # eigenvalues ascend: smallest spread


def estimate_normals(points: ArrayLike, k: int | None = None, *, orient: bool = True,
                     workers: int = -1) -> NDArray[np.float64]:
    """Unit normals of a 2D or 3D point cloud by k-nearest-neighbour PCA.

    Parameters
    ----------
    points : (N, D) array, D = 2 or 3, N >= 3
    k : int, optional
        Neighbours per point (the point itself included); default 10 in 2D, 15 in 3D
        (:data:`DEFAULT_K`). Raise it for noisy data, lower it for thin parts.
    orient : bool
        Make the signs consistent (:func:`orient_normals`), outward for closed shapes. If
        False the signs are arbitrary.
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
    k = _default_k(k, pts.shape[1], len(pts))
    idx = _neighbours(pts, k, workers)
    normals = _pca_normals(pts, idx)
    if orient:
        normals = _orient(pts, normals, idx)
    return normals


def orient_normals(points: ArrayLike, normals: ArrayLike, k: int | None = None, *,
                   workers: int = -1) -> NDArray[np.float64]:
    """Flip unoriented normals so that neighbours agree and closed shapes point outward.

    The signs propagate along a minimum spanning tree of the k-nearest-neighbour graph
    (weight 1 − |n_i·n_j|, plus a penalty for edges crossing the tangent plane), one tree
    per connected component, each seeded by its extreme points: at the point farthest from
    the component's centroid, and at the extremes along each axis, the outward normal of a
    closed shape is known.

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
    k = _default_k(k, pts.shape[1], len(pts))
    return _orient(pts, nrm / length[:, None], _neighbours(pts, k, workers))


def _orient(points: NDArray, normals: NDArray, idx: NDArray[np.intp]) -> NDArray[np.float64]:
    n = len(points)
    rows = np.repeat(np.arange(n), idx.shape[1])
    cols = idx.ravel()
    keep = rows != cols
    lo, hi = np.minimum(rows[keep], cols[keep]), np.maximum(rows[keep], cols[keep])
    # Each undirected edge once: COO → CSR would otherwise sum the weights of duplicates.
    key = np.unique(lo.astype(np.int64) * n + hi)
    lo, hi = key // n, key % n
    d = points[hi] - points[lo]
    dlen = np.linalg.norm(d, axis=1)
    d = d / np.where(dlen > 0, dlen, 1.0)[:, None]
    align = np.abs(np.einsum("ij,ij->i", normals[lo], normals[hi]))
    crossing = 0.5 * (np.abs(np.einsum("ij,ij->i", d, normals[lo])) + np.abs(np.einsum("ij,ij->i", d, normals[hi])))
    weight = np.maximum(1.0 - align, 0.0) + _CROSSING_PENALTY * crossing + _WEIGHT_FLOOR
    graph = sparse.csr_matrix((weight, (lo, hi)), shape=(n, n))
    tree = csgraph.minimum_spanning_tree(graph)
    ncomp, labels = csgraph.connected_components(tree, directed=False)

    # Root every component at its point farthest from its centroid (the whole shape lies in
    # the ball through that point, so the surface normal there is along point − centroid),
    # through one virtual node so that a single breadth-first search reaches everything.
    counts = np.bincount(labels, minlength=ncomp).astype(float)
    centroid = np.stack([np.bincount(labels, points[:, j], ncomp) for j in range(points.shape[1])], axis=1)
    centroid /= counts[:, None]
    radial = points - centroid[labels]
    seeds = _argmax_per_group(np.einsum("ij,ij->i", radial, radial), labels, ncomp)

    tree = tree.tocoo()
    virtual = n
    r = np.concatenate([tree.row, np.full(ncomp, virtual)])
    c = np.concatenate([tree.col, seeds])
    adjacency = sparse.csr_matrix((np.ones(len(r)), (r, c)), shape=(n + 1, n + 1))
    _, pred = csgraph.breadth_first_order(adjacency, virtual, directed=False, return_predecessors=True)

    parent = pred[:n].copy()
    at_seed = parent == virtual
    flip = np.zeros(n + 1, dtype=bool)
    nonseed = ~at_seed
    flip[:n][nonseed] = np.einsum("ij,ij->i", normals[nonseed], normals[parent[nonseed]]) < 0
    seed_dir = radial[at_seed]
    flip[:n][at_seed] = np.einsum("ij,ij->i", normals[at_seed], seed_dir) < 0

    # Sign of each node = parity of the flips on its path to the root, by pointer jumping:
    # log2(depth) vectorised rounds instead of a walk over the tree.
    anc = np.append(parent, virtual).astype(np.intp)
    parity = flip
    while True:
        done = anc == virtual
        if done.all():
            break
        parity = parity ^ (parity[anc] & ~done)
        anc = np.where(done, anc, anc[anc])
    oriented = np.where(parity[:n, None], -normals, normals)

    # The single seed can sit on a noisy tip; confirm each component's sign by a vote of its
    # extreme points along ±each axis, where the outward normal is also known.
    vote = np.zeros(ncomp)
    for axis in range(points.shape[1]):
        for sign in (1.0, -1.0):
            at = _argmax_per_group(sign * points[:, axis], labels, ncomp)
            vote += sign * oriented[at, axis]
    vote += np.einsum("ij,ij->i", oriented[seeds], radial[seeds]) / np.maximum(
        np.linalg.norm(radial[seeds], axis=1), np.finfo(float).tiny)
    wrong = vote < 0
    if wrong.any():
        oriented = np.where(wrong[labels][:, None], -oriented, oriented)
    return oriented


def _argmax_per_group(values: NDArray, labels: NDArray, ngroups: int) -> NDArray[np.intp]:
    order = np.lexsort((values, labels))
    last = np.cumsum(np.bincount(labels, minlength=ngroups)) - 1
    return order[last]


def contour_normals(points: ArrayLike, *, closed: bool = True) -> NDArray[np.float64]:
    """Outward unit normals of an ordered 2D contour: perpendiculars of central differences.

    The outward side is found from the sign of the enclosed area (for an open contour, of the
    area closed by the chord between its ends), so either direction of travel works.

    Parameters
    ----------
    points : (N, 2) array, in order along the contour, N >= 3
    closed : bool
        Whether the last point connects back to the first.
    """
    pts = as_points(points, dims=(2,), min_points=3)
    if closed:
        nxt, prv = np.roll(pts, -1, axis=0), np.roll(pts, 1, axis=0)
    else:
        nxt = np.vstack([pts[1:], pts[-1:]])
        prv = np.vstack([pts[:1], pts[:-1]])
    tangent = nxt - prv
    # A spike that goes out and back has a zero central difference: use the forward step.
    zero = ~(np.abs(tangent).sum(axis=1) > 0)
    if zero.any():
        tangent[zero] = (nxt - pts)[zero]
        still = ~(np.abs(tangent).sum(axis=1) > 0)
        tangent[still] = (pts - prv)[still]
    x, y = pts[:, 0] - pts[:, 0].mean(), pts[:, 1] - pts[:, 1].mean()
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # right of travel: outward if counter-clockwise
    if area2 < 0:
        normal = -normal
    length = np.linalg.norm(normal, axis=1)
    if not (length > 0).all():
        raise error("points", "a contour without repeated consecutive points",
                    f"{int((length == 0).sum())} points with no direction", "Remove repeated points first.")
    return normal / length[:, None]


def normal_agreement(estimated: ArrayLike, reference: ArrayLike) -> Agreement:
    """Compare two sets of normals row by row.

    Rows where either set has NaN (e.g. mesh vertices without faces) are skipped.

    Returns
    -------
    Agreement
        Angles between the normal lines in degrees, which rows are flipped, the median angle
        and the fraction flipped.
    """
    est = np.asarray(estimated, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if est.shape != ref.shape or est.ndim != 2:
        raise error("reference", f"an array of the same shape as estimated {est.shape}", f"shape {ref.shape}")
    ok = np.isfinite(est).all(axis=1) & np.isfinite(ref).all(axis=1)
    e, r = est[ok], ref[ok]
    denom = np.linalg.norm(e, axis=1) * np.linalg.norm(r, axis=1)
    cos = np.einsum("ij,ij->i", e, r) / np.where(denom > 0, denom, 1.0)
    angles = np.degrees(np.arccos(np.clip(np.abs(cos), 0.0, 1.0)))
    flipped = cos < 0
    m = int(ok.sum())
    return Agreement(angles, flipped, float(np.median(angles)) if m else float("nan"),
                     float(flipped.mean()) if m else float("nan"), m)

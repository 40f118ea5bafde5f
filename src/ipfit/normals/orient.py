"""Consistent signs: propagation along a minimum spanning tree of the neighbour graph.

:func:`orient_normals` is the public entry; :func:`orient_graph` does the work for it and for
:func:`~ipfit.normals.estimate_normals`. The signs spread from anchors whose outward direction
is known (convex-hull vertices, each component's farthest point from its centroid), so closed
shapes come out with outward normals.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import cg, spsolve
from scipy.spatial import ConvexHull, QhullError, cKDTree

from .._utils.numeric import unit_rows, unit_rows_mask
from .._utils.validation import as_matching, as_points, error
from .local import argmax_per_group, blocks, check_workers, default_k, neighbours, pca, spread, standardise
from .poles import doubtful_points, exterior_anchors, is_uneven

__all__ = ["orient_normals"]

# Kruskal treats zero weights as missing edges; this keeps perfectly consistent edges in.
_WEIGHT_FLOOR = 1e-9
# Tree links heavier than this are doubtful: the pieces between them are re-oriented as wholes.
_DOUBTFUL = 0.1


def orient_normals(points: ArrayLike, normals: ArrayLike, k: int | None = None, *,
                   workers: int = -1) -> NDArray[np.float64]:
    """Flip normals so that neighbours agree and closed shapes point outward.

    The signs propagate along a minimum spanning tree of the k-nearest-neighbour graph
    (Hoppe et al. 1992), rooted at anchors whose outward direction is known: the vertices of
    the convex hull, and in each connected component its point farthest from its centroid.
    Two changes to Hoppe's 1 − |n_i·n_j| make it robust on thin parts and sharp tips: the
    edge weight compares n_i with n_j mirrored across the bisector of the two points, and
    the pieces of the tree between doubtful links are re-oriented as wholes by a least-squares
    vote of all neighbour edges and anchors. On sparse or unevenly sampled 3D clouds (a quarter
    of the points or more whose neighbours are a poor sample of a plane, as the vertices of CAD
    meshes), points touched by a large empty ball from one side are anchors too, and the pieces
    the winding number of the others says are inside out are flipped, as in
    :func:`estimate_normals`.

    Parameters
    ----------
    points : (N, D) array
    normals : (N, D) array
        Normals whose signs may be arbitrary; their lines are kept.
    k : int, optional
        Neighbours per point for the graph (default as in :func:`estimate_normals`).
    workers : int
        Threads for the neighbour search: -1 for all cores, or a positive number.

    Returns
    -------
    (N, D) array: the unit normals, some negated.
    """
    pts = as_points(points, min_points=3)
    nrm = as_matching(normals, pts)
    nrm, ok = unit_rows_mask(nrm)
    if not ok.all():
        raise error("normals", "non-zero normal vectors", f"{int((~ok).sum())} zero-length normals",
                    "Estimate them with ipfit.estimate_normals.")
    k = default_k(k, pts.shape[1], len(pts))
    workers = check_workers(workers)
    pts = standardise(pts)
    tree = cKDTree(pts)
    idx = neighbours(tree, k, workers)
    exterior = None
    if pts.shape[1] == 3:  # sparse or uneven clouds: anchors from empty balls and a winding vote, as estimated
        doubtful = doubtful_points(pca(pts, idx)[1])
        exterior = doubtful if is_uneven(doubtful, len(pts)) else None
    return orient_graph(pts, nrm, idx, np.ones(len(pts)), tree=tree, exterior=exterior, winding=exterior is not None)


def _edges(idx: NDArray[np.intp], links) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Each undirected edge of the k-nearest graph and of ``links`` once, as (lo, hi) with lo < hi.

    Once, because COO → CSR sums the weights of duplicate entries.
    """
    n = len(idx)
    lo = np.repeat(np.arange(n, dtype=np.int64), idx.shape[1])
    hi = idx.ravel().astype(np.int64)
    if links is not None and len(links[0]):
        lo, hi = np.concatenate([lo, links[0]]), np.concatenate([hi, links[1]])
    a, b = np.minimum(lo, hi), np.maximum(lo, hi)
    key = np.sort((a * n + b)[a != b])  # one int64 key per pair: a plain sort, no hash table
    key = key[np.concatenate([[True], key[1:] != key[:-1]])] if len(key) else key
    return (key // n).astype(np.intp), (key % n).astype(np.intp)


def orient_graph(points: NDArray, normals: NDArray, idx: NDArray[np.intp], flatness: NDArray,
                 links: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None, *,
                 tree: cKDTree | None = None, exterior: NDArray[np.intp] | None = None,
                 winding: bool = False, layers: bool = False) -> NDArray[np.float64]:
    """Signs of unit ``normals`` made consistent on the graph of ``idx`` (+ ``links``); see orient_normals.

    ``exterior``: points (3D) tested as anchors touched by a large empty ball (poles.exterior_anchors).
    ``winding``: then also flip the pieces the winding number of the others says are inside out
    (3D; see _winding_votes), for sparse or unevenly sampled clouds, whose neighbour links often
    cross thin parts.
    ``layers``: each point also votes its piece's sign by where the other side of a thin part lies
    along its normal line (see _layer_votes); a variant, since two parts facing each other closely
    vote the same way as a thin part inside out.
    """
    n = len(points)
    lo, hi = _edges(idx, links)
    tree = cKDTree(points) if tree is None else tree
    bridge_lo, bridge_hi = _bridges(points, lo, hi, idx.shape[1], tree)
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
    anchor, direction = _anchors(points, labels, ncomp, normals, tree, exterior)
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
        if layers:
            layer = _layer_votes(points, normals * sign[:, None], idx)
            pull += np.bincount(piece, _LAYER_WEIGHT * np.abs(layer), npieces)
            rhs += np.bincount(piece, _LAYER_WEIGHT * layer, npieces)
        # Signed graph Laplacian + anchor terms: positive definite wherever a piece connects to
        # an anchor; the tiny shift keeps isolated, unanchored pieces (x = 0: left as they are) solvable.
        diagonal = degree + pull + 1e-12
        system = (sparse.diags(diagonal) - coupling).tocsc()
        x = _solve(system, diagonal, rhs)
        sign *= np.where(x[piece] < 0, -1.0, 1.0)
        if winding and points.shape[1] == 3:
            for _ in range(_WINDING_ROUNDS):
                inside_out = _winding_votes(points, normals * sign[:, None], piece, npieces, idx) < 0
                if not inside_out.any():
                    break
                sign *= np.where(inside_out[piece], -1.0, 1.0)
    return normals * sign[:, None]


# The close-layer vote (orient_graph's ``layers``): a voting point's pull on its piece (an anchor's
# is at most 1), how close along its normal line the other side must be (in the point's median
# spacing to its 6 nearest), and how near that line (the cosine of the widest angle); see
# docs/real-clouds.md for where it helps and where it misleads.
_LAYER_WEIGHT = 0.5
_LAYER_REACH = 0.8
_LAYER_CONE = np.cos(np.radians(35.0))


def _layer_votes(points: NDArray, oriented: NDArray, idx: NDArray[np.intp]) -> NDArray[np.float64]:
    """Per point: +1 where another of its k nearest lies close behind it on its normal line and
    none in front (a thin part's other side, as outward normals have it), -1 where close in front
    and none behind (inside out), else 0."""
    votes = np.zeros(len(points))
    for rows in blocks(len(points), idx.shape[1]):  # (N, k, D) temporaries for big clouds: blocks
        near = points[idx[rows, 1:]] - points[rows, None, :]
        dist = np.sqrt(np.einsum("ikj,ikj->ik", near, near))
        spacing = np.median(dist[:, :6], axis=1)
        along = np.einsum("ikj,ij->ik", near, oriented[rows])
        close = (np.abs(along) > _LAYER_CONE * dist) & (np.abs(along) < _LAYER_REACH * spacing[:, None])
        votes[rows] = (close & (along < 0)).any(axis=1).astype(float) - (close & (along > 0)).any(axis=1)
    return votes


# The winding-number vote: evaluated at most at _WINDING_QUERIES points (spread over the cloud),
# from at most _WINDING_SOURCES points, in up to _WINDING_ROUNDS rounds of flips (on the
# development meshes a second round corrects a few of the first's flips; a third, next to nothing).
_WINDING_QUERIES = 1500
_WINDING_SOURCES = 10_000
_WINDING_ROUNDS = 2


@np.errstate(over="ignore", invalid="ignore", divide="ignore")  # a far outlier's terms: dropped as non-finite
def _winding_votes(points: NDArray, oriented: NDArray, piece: NDArray[np.intp], npieces: int,
                   idx: NDArray[np.intp]) -> NDArray[np.float64]:
    """Per piece: how much the other pieces' winding number says its normals point outward.

    The generalized winding number of oriented points (Barill et al. 2018; each point a small
    disc of area π h², h its median distance to its 6 nearest points) is 0 outside a closed,
    consistently oriented surface and 1 inside. Just off each point along its normal it must
    therefore drop from inside (behind) to outside (in front): its vote is w(behind) − w(in
    front), counting the points of all pieces but its own (which flips with it). The offsets
    stay within the empty balls touching the point (closed form on its k nearest points), so
    that they do not cross a thin part's other side. Unlike the neighbour links, the winding
    number sees the whole shape: a blade between blades, a leg under a body. A piece whose
    mean vote is negative is inside out. Open surfaces give weak, mixed votes (requiring a
    clearly negative vote, a quarter of the jump, only lost flips on the development meshes).
    Returns the mean vote of each piece's queried points (0 where none is queried).
    """
    near = points[idx[:, 1:]] - points[:, None, :]
    sq = np.einsum("ikj,ikj->ik", near, near)
    spacing = np.median(np.sqrt(sq[:, :6]), axis=1)
    s = np.einsum("ikj,ij->ik", near, oriented)
    front = np.where(s > 0, sq / (2.0 * s), np.inf).min(axis=1)
    back = np.where(s < 0, sq / (-2.0 * s), np.inf).min(axis=1)
    rows = spread(points, _WINDING_QUERIES)
    sources = spread(points, _WINDING_SOURCES)
    src, nrm = points[sources], oriented[sources]
    # discs of area π h², h the local spacing; a subsample's discs cover the points left out
    area = np.pi * spacing[sources] ** 2 * (len(points) / len(sources))
    soft = (spacing[sources] / 2.0) ** 2  # a disc, not a point: no blow-up next to it
    lift = np.einsum("ij,ij->i", nrm, src)
    base = np.einsum("ij,ij->i", src, src) + soft
    weight = area / (4.0 * np.pi)
    own = piece[sources]
    vote = np.zeros(len(rows))
    for part in blocks(len(rows), len(sources)):
        at = rows[part]
        total = np.zeros((len(at), len(sources)))
        _winding_block(points[at], oriented[at], -np.minimum(0.5 * back[at], spacing[at]),
                       np.minimum(0.5 * front[at], spacing[at]), src, nrm, lift, base, total)
        total *= weight
        total[(piece[at][:, None] == own) | ~np.isfinite(total)] = 0.0
        vote[part] = total.sum(axis=1)
    queried = np.bincount(piece[rows], minlength=npieces)
    return np.bincount(piece[rows], vote, npieces) / np.maximum(queried, 1)


def _winding_block(at: NDArray, oriented: NDArray, behind: NDArray, ahead: NDArray, src: NDArray, nrm: NDArray,
                   lift: NDArray, base: NDArray, total: NDArray) -> None:
    """Add n_j·(p_j − q)/|p_j − q|³ at the points behind minus at those in front of ``at``, in place."""
    for side, step in ((1.0, behind), (-1.0, ahead)):
        _winding_terms(at + step[:, None] * oriented, src, nrm, lift, base, side, total)


def _winding_terms(q: NDArray, src: NDArray, nrm: NDArray, lift: NDArray, base: NDArray, side: float,
                   total: NDArray) -> None:
    """Add ``side`` × n_j·(p_j − q)/|p_j − q|³ of every source j at every query q to ``total``, in place."""
    # by matrix products: |q|² − 2 q·p_j + |p_j|² (+ the disc's softening, in base)
    r2 = q @ (-2.0 * src.T)
    r2 += base
    r2 += np.einsum("ij,ij->i", q, q)[:, None]
    np.maximum(r2, np.finfo(float).tiny, out=r2)
    along = q @ (-side * nrm.T)
    along += side * lift
    along /= r2 * np.sqrt(r2)
    total += along


@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def winding_numbers(queries: NDArray, src: NDArray, nrm: NDArray, soft: float) -> NDArray[np.float64]:
    """Σ_j n_j·(p_j − q)/(4π |p_j − q|³) at every query q: the generalized winding number of the
    oriented sources (Barill et al. 2018) up to their common area, each source a disc of radius
    √``soft`` (no blow-up next to it). For evenly spread sources the area is one number, which a
    caller can measure as the jump across the surface (the winding number rises by 1 through it)."""
    lift = np.einsum("ij,ij->i", nrm, src)
    base = np.einsum("ij,ij->i", src, src) + soft
    out = np.empty(len(queries))
    for part in blocks(len(queries), len(src)):
        total = np.zeros((part.stop - part.start, len(src)))
        _winding_terms(queries[part], src, nrm, lift, base, 1.0, total)
        total[~np.isfinite(total)] = 0.0
        out[part] = total.sum(axis=1) / (4.0 * np.pi)
    return out


# Clouds up to _HULL_ALL points take the convex hull of all their points for anchors; larger ones
# that of _HULL_SAMPLE of them (the bundled data, at most 35,947 points, are below it).
_HULL_ALL = 50_000
_HULL_SAMPLE = 5_000
# Above this many pieces the direct solver's fill-in grows faster than the system (5 s for the
# 14,000 pieces of a random 30,000-point torus); conjugate gradients take a fraction of that and
# gave the same signs on every system tried. The bundled data stay below it (the bunny: 3,200).
_DIRECT_PIECES = 8000


def _solve(system, diagonal: NDArray, rhs: NDArray) -> NDArray[np.float64]:
    """Solve the symmetric positive definite piece system (exactly when it is small)."""
    if len(rhs) <= _DIRECT_PIECES:
        return spsolve(system, rhs, permc_spec="MMD_AT_PLUS_A")
    # Blocks without an anchor have rhs 0 and stay at x = 0, as the direct solve leaves them.
    x, info = cg(system, rhs, M=sparse.diags(1.0 / diagonal), rtol=1e-10)
    return x if info == 0 else spsolve(system, rhs, permc_spec="MMD_AT_PLUS_A")


def _bridges(points: NDArray, lo: NDArray, hi: NDArray, k: int,
             tree: cKDTree | None) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
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
    reach = 2 * k
    while ncomp > 1 and reach <= 8 * k:
        if tree is None:
            tree = cKDTree(points)
        largest = np.argmax(np.bincount(labels))
        query = np.flatnonzero(labels != largest)  # links are symmetric: the largest piece is found by the others
        dist, near = tree.query(points[query], k=min(reach, n))
        near = np.minimum(near, n - 1)  # no point found (an overflowed distance): its dist is inf
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
    c = np.empty(len(i))
    off = np.empty(len(i)) if with_off_plane else None
    for rows in blocks(len(i), 1):  # (E, D) temporaries for a million points' edges: blocks
        e = unit_rows(points[j[rows]] - points[i[rows]])
        ni, nj = normals[i[rows]], normals[j[rows]]
        ai, aj = np.einsum("ij,ij->i", ni, e), np.einsum("ij,ij->i", nj, e)
        c[rows] = np.einsum("ij,ij->i", ni, nj) - 2.0 * ai * aj
        if off is not None:  # with_off_plane
            off[rows] = np.abs(ai * aj)
    return (c, off) if with_off_plane else c


def _anchors(points: NDArray, labels: NDArray, ncomp: int, normals: NDArray, tree: cKDTree,
             exterior: NDArray[np.intp] | None) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Points with a known outward direction (unit vectors) on closed shapes.

    * The vertices of the convex hull: its facets are supporting planes, so the outward
      normal there is on the side of the mean of the adjacent facets' normals.
    * In each connected component, the point farthest from the component's centroid: the
      component lies in the ball through it, so its normal is along point − centroid.
    * In 3D, those of ``exterior`` touched from one side only by an empty ball too large for
      any solid the cloud bounds (:func:`~.poles.exterior_anchors`): the outside of concave
      and sparsely sampled shapes, far from the hull.
    """
    dim = points.shape[1]
    counts = np.bincount(labels, minlength=ncomp).astype(float)
    centroid = np.stack([np.bincount(labels, points[:, j], ncomp) for j in range(dim)], axis=1) / counts[:, None]
    radial = points - centroid[labels]
    seeds = argmax_per_group(np.einsum("ij,ij->i", radial, radial), labels, ncomp)
    idx_parts, dir_parts = [seeds], [radial[seeds]]
    candidates = np.arange(len(points))
    if len(points) > _HULL_ALL:
        # Every point of a sphere is a hull vertex: a million anchors would make a million pieces
        # below. Every step-th point in coordinate order (independent of the input order) keeps
        # the hull's vertices, its outward directions, evenly spread and few.
        order = np.lexsort(points.T[::-1])
        candidates = np.sort(order[::-(-len(points) // _HULL_SAMPLE)])
    try:
        hull = ConvexHull(points[candidates])
    except (QhullError, ValueError):
        pass  # flat or degenerate cloud: the seeds alone orient it
    else:
        corners = hull.simplices.ravel()
        facet = np.repeat(hull.equations[:, :dim], dim, axis=0)
        acc = np.stack([np.bincount(corners, facet[:, j], len(candidates)) for j in range(dim)], axis=1)
        idx_parts.insert(0, candidates[hull.vertices])
        dir_parts.insert(0, acc[hull.vertices])
    if dim == 3 and exterior is not None:
        touched, outward = exterior_anchors(points, tree, normals, exterior, 1)
        idx_parts.append(touched)
        dir_parts.append(outward)
    idx = np.concatenate(idx_parts)
    dirs = np.concatenate(dir_parts)
    dirs, ok = unit_rows_mask(dirs)
    dirs[~ok, 0] = 1.0  # a component whose points all coincide has no outward side: any will do
    idx, first = np.unique(idx, return_index=True)
    return idx.astype(np.intp), dirs[first]


"""Well-spread subsamples of a point cloud, and its local spacing.

The population search of a refinement only needs to see the shape, not every point: on a
few thousand points spread evenly over it, DE/PSO rank candidates the same way as on the
full cloud, at a fraction of the cost; the polish and every reported measure then use all
points. :func:`spread_subsample` picks one point per occupied voxel of a grid whose cell size
is chosen so that about ``n`` cells are occupied, which keeps sparse regions represented
(unlike a uniform random draw, which follows the sampling density). :func:`point_spacing`
gives each point's distance to its k-th nearest neighbour: the sampling gaps that the quality
measures, the trim distance and the repairs allow for on a bare cloud.
:func:`surface_points` goes the other way for a mesh: points spread evenly over its faces, with
normals interpolated from its vertices', where its vertices sample the surface too sparsely;
:func:`local_triangles` gives a bare 3D cloud such faces from its points alone.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import Delaunay, QhullError, cKDTree

from .._utils.numeric import tangent_frames, unit_rows_mask
from .._utils.validation import as_faces, as_points, check_int, check_rng, error
from ..cloud import Cloud, as_cloud

__all__ = ["spread_subsample", "point_spacing", "surface_points", "local_triangles"]

# local_triangles: a point's umbrella is cut from its LOCAL_NEIGHBOURS nearest points; a triangle with
# an edge longer than LOCAL_EDGE spacings of its corners (each point's median distance to its 6 nearest)
# spans a gap, not the surface, and a triangle whose plane leaves a vertex's normal by more than acos(LOCAL_COS) spans
# a fold or both sides of a thin part.
LOCAL_NEIGHBOURS = 10
LOCAL_EDGE = 3.0
LOCAL_COS = 0.7


def point_spacing(points: ArrayLike | Cloud, k: int = 1) -> NDArray[np.float64]:
    """Each point's distance to its ``k``-th nearest other point (0 for a repeated point when
    ``k`` = 1, and for every point of a cloud of at most ``k`` points).

    Given a :class:`~ipfit.Cloud`, the cloud keeps the result (:meth:`ipfit.Cloud.point_spacing`):
    a fit measures and repairs the same cloud many times.

    >>> point_spacing([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]).tolist()
    [1.0, 1.0, 2.0]
    """
    cloud = as_cloud(points)
    return cloud.point_spacing(check_int(k, "k", minimum=1)).copy()  # a copy: the cloud's stays read-only


def _occupied(keys_of, size: float) -> int:
    keys = keys_of(size)
    keys.sort()
    return int(np.count_nonzero(keys[1:] != keys[:-1])) + int(len(keys) > 0)


def spread_subsample(points: ArrayLike | Cloud, n: int, *, rng=0) -> NDArray[np.int64]:
    """Indices of ``n`` points spread evenly over the cloud (sorted; all points when N <= n).

    Parameters
    ----------
    points : (N, dim) array
    n : int
        How many points to keep.
    rng : None, int or Generator, default 0
        Breaks ties (which point of a voxel is kept, which voxels are dropped or added to hit
        ``n`` exactly): a fixed seed gives the same subsample every time.

    Examples
    --------
    >>> import numpy as np
    >>> dense = np.column_stack([np.linspace(0, 1, 1000), np.zeros(1000)])
    >>> sparse = np.column_stack([np.linspace(2, 3, 10), np.zeros(10)])
    >>> pick = spread_subsample(np.vstack([dense, sparse]), 40)
    >>> len(pick), int(np.sum(pick >= 1000))  # the sparse part keeps its share of the length
    (40, 10)
    """
    pts = as_cloud(points).points
    n = check_int(n, "n", minimum=1)
    gen = check_rng(rng)
    total = len(pts)
    if total <= n:
        return np.arange(total)
    order = gen.permutation(total)  # which point of a voxel is kept: a random one, reproducibly
    shuffled = pts[order]
    lo = shuffled.min(axis=0)
    extent = float(np.max(shuffled.max(axis=0) - lo)) or 1.0

    def keys_of(size: float, subset: int | None = None) -> NDArray[np.int64]:
        # One integer per voxel (row-major cell index): 1D np.unique is far faster than rows.
        cells = np.floor((shuffled[:subset] - lo) / size).astype(np.int64)
        return np.ravel_multi_index(cells.T, cells.max(axis=0) + 1)

    # The number of occupied voxels falls as the cell grows: bisect on log(size) until the
    # count is within 10% above n (then drop voxels at random to hit n exactly). On a big
    # cloud the size is found on a random part of 20·n points (about 20 per voxel, so the
    # same voxels are occupied), and applied to all points once.
    subset = 20 * n if total > 20 * n else None
    small, large = extent / (4.0 * n) ** (1 / pts.shape[1]) / 4.0, extent
    count = _occupied(lambda size: keys_of(size, subset), small)
    for _ in range(60):
        if n <= count <= 1.1 * n or large / small < 1.0001:
            break
        mid = np.sqrt(small * large)
        mid_count = _occupied(lambda size: keys_of(size, subset), mid)
        if mid_count >= n:
            small, count = mid, mid_count
        else:
            large = mid
    # the bisection only counts voxels (a sort); which point stands for each: at the size found
    _, first = np.unique(keys_of(small), return_index=True)
    count = len(first)
    chosen = first if count <= n else gen.choice(first, n, replace=False)
    if len(chosen) < n:
        rest = np.setdiff1d(np.arange(total), chosen)
        chosen = np.concatenate([chosen, gen.choice(rest, n - len(chosen), replace=False)])
    return np.sort(order[chosen])


#: :func:`surface_points` draws this many times the points it keeps, at random over the area,
#: and keeps an even spread of them (a random draw alone leaves clumps and gaps).
SURFACE_OVERSAMPLING = 4


def surface_points(vertices: ArrayLike, faces: ArrayLike, normals: ArrayLike, n: int, *,
                   rng=0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``n`` points spread evenly over a triangle mesh's faces, and their normals.

    Points are drawn at random over the surface (each face in proportion to its area, fixed
    seed), :data:`SURFACE_OVERSAMPLING` times as many as asked, and ``n`` of them kept by
    :func:`spread_subsample`. A point's normal is its face's three vertex normals interpolated at
    it (barycentric weights) and normalised: the smooth normal field the vertex normals stand
    for, which turns over a thin part's rim as the surface does, where the faces' own normals
    jump (docs/rims.md).

    Parameters
    ----------
    vertices : (V, 3) array
    faces : (F, 3) integer array
    normals : (V, 3) array
        The vertices' normals.
    n : int
        How many points.
    rng : None, int or Generator, default 0

    Returns
    -------
    points, normals : (n, 3) arrays; a normal whose interpolation vanishes (opposite vertex
    normals) is the face's own. No points when the faces have no area.

    Examples
    --------
    >>> import numpy as np, trimesh
    >>> box = trimesh.creation.box()
    >>> pts, nrm = surface_points(box.vertices, box.faces, box.vertex_normals, 500)
    >>> pts.shape, bool(np.allclose(np.abs(pts).max(axis=1), 0.5))  # every point on a face
    ((500, 3), True)
    """
    verts = as_points(vertices, "vertices", dims=(3,))
    tri = as_faces(faces, len(verts))
    vn = np.asarray(normals, dtype=np.float64)
    if vn.shape != verts.shape:
        raise error("normals", f"shape {verts.shape}, one per vertex", f"shape {vn.shape}")
    n = check_int(n, "n", minimum=1)
    gen = check_rng(rng)
    a, b, c = verts[tri[:, 0]], verts[tri[:, 1]], verts[tri[:, 2]]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    if not np.isfinite(area).all() or area.sum() <= 0:
        return np.empty((0, 3)), np.empty((0, 3))
    drawn = SURFACE_OVERSAMPLING * n
    face = gen.choice(len(tri), drawn, p=area / area.sum())
    # uniform on a triangle: fold the unit square's upper half back onto the lower one
    u, v = gen.random(drawn), gen.random(drawn)
    fold = u + v > 1
    u[fold], v[fold] = 1 - u[fold], 1 - v[fold]
    w = np.column_stack([1 - u - v, u, v])
    points = np.einsum("ij,ijk->ik", w, verts[tri[face]])
    keep = spread_subsample(points, n, rng=gen)
    face, w, points = face[keep], w[keep], points[keep]
    interpolated, ok = unit_rows_mask(np.einsum("ij,ijk->ik", w, vn[tri[face]]))
    own = unit_rows_mask(cross[face])[0]
    return points, np.where(ok[:, None], interpolated, own)


def local_triangles(points: ArrayLike, normals: ArrayLike) -> NDArray[np.int64]:
    """Triangles between neighbouring points of a bare 3D cloud: the faces a mesh of it would have
    where its points sample a surface, from the points and their oriented normals alone.

    Each point's umbrella: its :data:`LOCAL_NEIGHBOURS` nearest points, without those whose normal
    faces the other way (the other side of a thin part) or that lie more across its tangent plane
    than along it (one side of a fold seen from the other), projected onto the tangent plane; the
    triangles of their 2D Delaunay triangulation that have the point as a corner. Every triangle
    found from any corner is kept once, unless an edge is longer than :data:`LOCAL_EDGE` times
    the largest spacing of its corners (a gap in the sampling) or its plane turns from a corner's
    normal by more than acos(:data:`LOCAL_COS`); each is wound to agree with its corners' normals.
    Not a watertight mesh, nor meant to be: its triangles lie where the points do, so that
    :func:`surface_points` can fill the gaps between them (the bare-cloud look of
    :func:`ipfit.fit_adaptive`).

    Parameters
    ----------
    points : (N, 3) array
    normals : (N, 3) array of unit normals, oriented (a neighbour whose normal points against a
        point's is taken to be on another sheet).

    Returns
    -------
    (F, 3) integer array of vertex indices, possibly empty.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(400, 3)); p /= np.linalg.norm(p, axis=1, keepdims=True)
    >>> t = local_triangles(p, p)
    >>> bool(len(t) > 400), bool(np.abs(np.linalg.norm(surface_points(p, t, p, 500)[0], axis=1) - 1).max() < 0.1)
    (True, True)
    """
    pts = as_points(points, dims=(3,))
    unit = np.asarray(normals, dtype=np.float64)
    if unit.shape != pts.shape:
        raise error("normals", f"shape {pts.shape}, one per point", f"shape {unit.shape}")
    k = min(LOCAL_NEIGHBOURS, len(pts) - 1)
    if k < 2:
        return np.empty((0, 3), dtype=np.int64)
    distance, near = cKDTree(pts).query(pts, k=k + 1)
    distance, near = distance[:, 1:], near[:, 1:]
    spacing = np.median(distance[:, :6], axis=1)
    across_u, across_v = tangent_frames(unit)
    found: set[tuple[int, int, int]] = set()
    for i in range(len(pts)):
        n = unit[i]
        offset = pts[near[i]] - pts[i]
        across = offset @ n
        along = offset - across[:, None] * n
        reach = np.linalg.norm(along, axis=1)
        keep = (unit[near[i]] @ n >= 0) & (np.abs(across) <= 0.5 * reach)
        if np.count_nonzero(keep) < 2:
            continue
        flat = np.vstack([[0.0, 0.0], np.column_stack([along[keep] @ across_u[i], along[keep] @ across_v[i]])])
        try:
            simplices = Delaunay(flat).simplices if len(flat) > 3 else np.array([[0, 1, 2]])
        except QhullError:  # the neighbours on one line: no umbrella
            continue
        corners = np.concatenate([[i], near[i][keep]])
        for simplex in simplices[(simplices == 0).any(axis=1)]:
            found.add(tuple(sorted(int(c) for c in corners[simplex])))  # type: ignore[arg-type]
    if not found:
        return np.empty((0, 3), dtype=np.int64)
    tri = np.array(sorted(found), dtype=np.int64)
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    longest = np.max(np.column_stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                                      np.linalg.norm(a - c, axis=1)]), axis=1)
    plane, ok = unit_rows_mask(np.cross(b - a, c - a))
    turn = np.abs(np.einsum("fj,fvj->fv", plane, unit[tri])).min(axis=1)
    tri = tri[ok & (longest <= LOCAL_EDGE * spacing[tri].max(axis=1)) & (turn >= LOCAL_COS)]
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    inward = np.einsum("fj,fj->f", np.cross(b - a, c - a), unit[tri].sum(axis=1)) < 0
    tri[inward] = tri[inward][:, [0, 2, 1]]
    return tri


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
normals interpolated from its vertices', where its vertices sample the surface too sparsely.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.numeric import unit_rows_mask
from .._utils.validation import as_faces, as_points, check_int, check_rng, error
from ..cloud import Cloud, as_cloud

__all__ = ["spread_subsample", "point_spacing", "surface_points"]


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

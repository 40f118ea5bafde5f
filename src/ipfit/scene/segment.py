"""Segmentation of a scan into objects, with no setting to tune for ordinary scans.

Five steps, each on a well-kept library:

1. **Stray returns** are set aside by :func:`ipfit.robust.score_outliers` (its noise scale and
   spacing are the scan's; they size the next steps).
2. **Dominant planes** (a floor, a table top, a wall) are found by RANSAC
   (``skimage.measure.ransac`` with :class:`PlaneModel`, scikit-image's model protocol), refitted
   to their inliers by least squares and removed while each holds at least ``plane_share`` of the
   points still in play and is a support, not an object's face: a face's rim meets the object's
   other faces all round, a table's is the edge of the scan (3D only: in 2D a "plane" is a line,
   and lines are what shapes are made of). Other pieces of a removed plane (the floor beyond an
   object that hides a strip of it, or between its legs) join it, whether RANSAC finds them as a
   plane of their own or they are left as components lying on it.
3. **Objects** are the connected components (``scipy.sparse.csgraph.connected_components``) of
   a graph on the points' surfaces. Each point gets a surface frame from its 20 nearest
   neighbours: the normal of their plane (PCA) and its position moved along it onto its own
   sheet (the median offset of the neighbours within one local spacing or 2.5 noise scales of
   it: the noise no longer closes gaps, and another object across a gap is outside that window).
   Two moved points are linked when one is within ``link`` of the other (default
   :data:`LINK_REACH` × its local reach: the median, over it and its 15 nearest neighbours, of
   their distances to their :data:`LINK_NEIGHBOUR`-th nearest neighbour, so that a sparse table
   and a dense toy of one scan are each linked at their own scale; about 7 neighbours, above the
   percolation threshold of a random graph on a surface, near 4.5; a measure of the density
   alone, not of the nearest neighbour: a scanner's even grid and a random sample of one density
   get one reach, while their nearest-neighbour spacings differ by about 1.5 ×, and objects
   closer than 3 spacings of the even grid stay apart) and the link leaves neither point's plane by more
   than :data:`NORMAL_SPACINGS` local spacing: a surface's own links lie in it, while two objects
   facing each other across a gap would be linked along their normals. A thin part (a leg, a
   wire) has a neighbourhood shaped like a line, whose "normal" is across it, so links along it
   stay.
4. **Parts**: a component holding at most :data:`ATTACH_SHARE` of the points of a group within
   :data:`ATTACH_LINKS` link distances of it joins the nearest such group, smallest first: the
   sparse pieces of a leg or a cable, and what the plane's removal cut off, are parts of their
   object, while the objects of a scene are much larger shares of each other.
5. **Clutter**: components of fewer than ``min_points`` points are reported, not fitted.

Each object is then checked for a **neck** (:func:`neck`): two parts joined by far fewer links
than a single body has across any cut, the sign of two objects that touch and so cannot be told
apart by connectivity. Such an object is kept as one and said to be so. At the noise of
docs/scenes.md (about 0.4 spacing), objects closer than 3-4 spacings still merge this way.

Images are segmented by :func:`ipfit.io.silhouettes.trace_silhouettes`: every separate silhouette.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._utils.validation import as_points, check_int, error
from ..exceptions import InvalidInputError

__all__ = ["PlaneModel", "Plane", "Cluster", "Segmentation", "segment", "neck", "local_spacing", "LINK_REACH",
           "LINK_NEIGHBOUR", "LINK_SPACINGS",
           "NORMAL_SPACINGS", "ATTACH_SHARE", "ATTACH_LINKS", "PLANE_SHARE", "PLANE_PIECE_SHARE",
           "MIN_POINTS", "OBJECT", "PLANE", "CLUTTER", "OUTLIER"]

#: The link distance of the connectivity: this many times each point's local reach, the median
#: over it and its 15 nearest neighbours of their distance to their :data:`LINK_NEIGHBOUR`-th
#: nearest neighbour (see the module notes). On the counting scenes of experiments/scenes.py
#: (external and development), 0.95 and 1.02 split pieces off objects of random samples; 1.1
#: counts at least as many scenes right as the earlier 3 median spacings on random samples
#: (24 and 22 against 21 and 22, docs/scenes*.md before and after) and more on even ones.
LINK_REACH = 1.1
#: See :data:`LINK_REACH`.
LINK_NEIGHBOUR = 6
#: The patch of a plane RANSAC finds is linked at this many of its points' median spacings.
LINK_SPACINGS = 3.0
#: A link may leave a point's surface by at most this many local spacings along the surface's
#: normal (see the module notes): two objects facing each other across a gap are linked along
#: their normals, a surface's own links lie in it.
NORMAL_SPACINGS = 1.0
#: A component holding at most this share of the points of a group within :data:`ATTACH_LINKS`
#: link distances of it is a part of that group (a leg, a cable, a piece cut off by the plane's
#: removal), not an object. In the 40 counting scenes of experiments/scenes.py the smallest object
#: holds at least 6.4 % of the largest of its scene, and the fragments the isotropic link left
#: (walkman cables, ant legs) 4-9 % of their object; 0.07 and 0.15 count one scene fewer.
ATTACH_SHARE = 0.1
#: How far (in link distances) a small component's parent may be.
ATTACH_LINKS = 2.0
#: Smallest share of the points still in play that a plane must hold to be removed as dominant.
PLANE_SHARE = 0.15
#: Fewest points of an object, per dimension: a smaller component is clutter. A degree-4 surface
#: has 35 coefficients and the fit wants 2 points per coefficient; a degree-4 curve has 15.
MIN_POINTS = {2: 30, 3: 70}
#: Plane inliers: within this many noise scales of the plane, and never closer than one spacing
#: (clean data has a noise scale of nearly 0, and a random sample of a plane is not exactly on it).
PLANE_SCALES = 3.0
#: A component with at least this share of its points on a removed plane is a piece of that
#: plane (the floor between an object's legs, or cut off by an object), not an object: an
#: object standing on the floor has at most its lowest rim there.
PLANE_PIECE_SHARE = 0.9
#: At most this many planes are removed.
MAX_PLANES = 4
#: A plane whose rim is beside off-plane points over more than this share is an object's face,
#: not removed (see :func:`_is_a_face`).
FACE_RIM_SHARE = 0.5
#: What a point is, in :attr:`Segmentation.kinds`.
OBJECT, PLANE, CLUTTER, OUTLIER = 0, 1, 2, 3
# A neck: the best cut along the graph's Fiedler vector crosses fewer than this share of the
# links a cut of the same parts would cross on one smooth body (see neck()), with both parts
# holding at least _NECK_PART of the points. Two unit spheres that touch read 0.11-0.22 (6 seeds,
# 1,500 points each); one ellipsoid 0.9-1.2; the development meshes alone mostly above 0.26, thin
# ones (scissors, airplane) below: docs/scenes.md counts both.
_NECK_RATIO = 0.25
_NECK_PART = 0.15
_NECK_K = 6
_NECK_MAX_POINTS = 3000
# Fewer points than this: no neck test (the ratio's reference needs a well-sampled body).
_NECK_MIN_POINTS = 400
# The neighbours of a point's surface frame (its normal and its denoised position); 16-28 give
# the same counts on the development scenes (docs/scenes.md), 20 is their middle.
_FRAME_K = 20
# Components of fewer points are stray returns, never attached to an object.
_ATTACH_MIN_POINTS = 3


class PlaneModel:
    """A plane (a line in 2D) in scikit-image's model protocol, for ``skimage.measure.ransac``.

    ``from_estimate(data)`` fits the total-least-squares plane of ``data`` (its normal is the
    direction of least spread) and is falsy when the points do not fix one (repeated or
    collinear); ``residuals(data)`` is every point's distance to it.

    >>> import numpy as np
    >>> model = PlaneModel.from_estimate([[0.0, 0, 1], [1, 0, 1], [0, 1, 1]])
    >>> bool(model), np.abs(model.normal).tolist(), abs(model.offset)
    (True, [0.0, 0.0, 1.0], 1.0)
    >>> model.residuals([[5.0, 5.0, 3.0]]).tolist()
    [2.0]
    """

    def __init__(self, normal: NDArray[np.float64] | None = None, offset: float = 0.0) -> None:
        self.normal = normal
        self.offset = float(offset)

    @classmethod
    def from_estimate(cls, data: ArrayLike) -> PlaneModel:
        pts = np.asarray(data, dtype=np.float64)
        center = pts.mean(axis=0)
        _, s, vt = np.linalg.svd(pts - center, full_matrices=False)
        # the plane is fixed when the points span dim - 1 directions (s[-2] clearly above 0)
        if len(s) < pts.shape[1] or not s[-2] > 1e-9 * max(s[0], 1e-300):
            return cls()
        normal = vt[-1]
        return cls(normal, float(normal @ center))

    def estimate(self, data: ArrayLike) -> bool:
        """Fit ``data`` in place (scikit-image before 0.26)."""
        fitted = self.from_estimate(data)
        self.normal, self.offset = fitted.normal, fitted.offset
        return fitted.normal is not None

    def residuals(self, data: ArrayLike) -> NDArray[np.float64]:
        if self.normal is None:
            raise error("model", "a fitted plane", "a failed estimate", "Check bool(model) before using it.")
        return np.abs(np.asarray(data, dtype=np.float64) @ self.normal - self.offset)

    def __bool__(self) -> bool:
        return self.normal is not None


@dataclass(frozen=True)
class Plane:
    """A removed plane: ``normal · x = offset`` (unit normal), and the points on it."""

    normal: NDArray[np.float64]
    offset: float
    indices: NDArray[np.int64]
    threshold: float

    @property
    def n_points(self) -> int:
        return len(self.indices)

    def holds(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether each of ``points`` is within the plane's inlier threshold."""
        return np.abs(points @ self.normal - self.offset) <= self.threshold

    def polynomial(self, points: ArrayLike):
        """The plane as a degree-1 :class:`~ipfit.ImplicitPolynomial`, normalised over ``points``
        (its inliers): f(x) = normal · x − offset in the data's units."""
        from ..polynomial import ImplicitPolynomial, Normalization

        norm = Normalization.from_points(as_points(points))
        # f(c + s u) = s n·u + (n·c − d): the coefficients (1, x, y[, z]) in normalised coordinates
        coefficients = np.concatenate([[self.normal @ norm.center - self.offset], norm.scale * self.normal])
        coefficients /= np.linalg.norm(coefficients)
        return ImplicitPolynomial.from_coefficients(coefficients, len(self.normal), normalization=norm,
                                                    method="ransac plane")

    def to_dict(self) -> dict:
        return {"normal": self.normal.tolist(), "offset": self.offset, "n_points": self.n_points,
                "threshold": self.threshold}


@dataclass(frozen=True)
class Cluster:
    """One connected component: its points (indices into the scan) and whether it has a neck."""

    indices: NDArray[np.int64]
    touching: bool = False
    note: str = ""

    @property
    def n_points(self) -> int:
        return len(self.indices)


@dataclass(frozen=True)
class Segmentation:
    """What :func:`segment` found.

    Attributes
    ----------
    labels : (N,) int array: the object each point belongs to (0, 1, ...), or -1 (a plane,
        clutter or an outlier; :attr:`kinds` says which).
    kinds : (N,) int array: :data:`OBJECT`, :data:`PLANE`, :data:`CLUTTER` or :data:`OUTLIER`.
    objects : the objects, largest first (``labels == i`` is ``objects[i].indices``).
    planes : the removed planes, in the order found.
    clutter : the components too small to fit.
    spacing : the median spacing of the points kept (data units).
    link : the link distance of the connectivity (the median of the points' own, data units).
    noise_scale : the scan's noise scale (:func:`ipfit.robust.score_outliers`), or 0.
    """

    labels: NDArray[np.int64]
    kinds: NDArray[np.int64]
    objects: tuple[Cluster, ...]
    planes: tuple[Plane, ...] = ()
    clutter: tuple[Cluster, ...] = ()
    spacing: float = 0.0
    link: float = 0.0
    noise_scale: float = 0.0
    settings: dict = field(default_factory=dict)

    @property
    def n_outliers(self) -> int:
        return int(np.count_nonzero(self.kinds == OUTLIER))

    def to_dict(self, labels: bool = True) -> dict:
        out = {"n_points": len(self.labels), "n_objects": len(self.objects), "n_planes": len(self.planes),
               "n_clutter": len(self.clutter), "n_clutter_points": int(sum(c.n_points for c in self.clutter)),
               "n_outliers": self.n_outliers, "spacing": self.spacing, "link": self.link,
               "noise_scale": self.noise_scale, "clutter": [
                   {"n_points": c.n_points} for c in self.clutter], **self.settings}
        if labels:
            out["labels"] = self.labels.tolist()
            out["kinds"] = self.kinds.tolist()
        return out


def _check_share(value, name: str) -> float:
    try:
        share = float(value)
    except (TypeError, ValueError):
        raise error(name, "a number in (0, 1]", repr(value)) from None
    if not 0 < share <= 1:
        raise error(name, "a number in (0, 1]", repr(value))
    return share


def segment(points: ArrayLike, *, planes: bool | None = None, outliers: str | float = "auto",
            link: float | None = None, min_points: int | None = None, plane_share: float = PLANE_SHARE,
            rng=0) -> Segmentation:
    """Split a scan into objects: planes removed, the rest split by connectivity, tiny parts clutter.

    Parameters
    ----------
    points : (N, 2) or (N, 3) array
    planes : remove dominant planes (default: in 3D yes, in 2D no).
    outliers : 'auto' (default), 'none' or a share: the stray returns set aside first
        (:func:`ipfit.robust.score_outliers`).
    link : the connectivity's link distance in data units (default :data:`LINK_REACH` × each
        point's local reach, :func:`local_spacing` with its :data:`LINK_NEIGHBOUR`-th neighbour
        for the nearest); a link also stays within :data:`NORMAL_SPACINGS` local spacing of both
        points' planes (see the module notes).
    min_points : fewest points of an object; smaller components are clutter (default
        :data:`MIN_POINTS`).
    plane_share : smallest share of the points in play a plane must hold to be removed.
    rng : seed of RANSAC's draws.

    Returns
    -------
    Segmentation

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    >>> ring = np.column_stack([np.cos(t), np.sin(t)])
    >>> seg = segment(np.vstack([ring, ring + [5.0, 0.0]]), outliers="none")
    >>> [c.n_points for c in seg.objects], seg.labels[[0, 200]].tolist()
    ([200, 200], [0, 1])
    """
    from ..robust import check_outliers, score_outliers

    pts = as_points(points, min_points=2)
    n, dim = pts.shape
    planes = dim == 3 if planes is None else bool(planes)
    outliers = check_outliers(outliers)
    plane_share = _check_share(plane_share, "plane_share")
    min_points = MIN_POINTS[dim] if min_points is None else check_int(min_points, "min_points", minimum=1)
    if link is not None:
        link = float(link)
        if not (np.isfinite(link) and link > 0):
            raise error("link", "a finite distance > 0 (data units)", repr(link))
    kinds = np.full(n, OBJECT, dtype=np.int64)
    noise = 0.0
    if outliers != "none" and n > 20:
        scored = score_outliers(pts, outliers=outliers)
        kinds[~scored.inliers] = OUTLIER
        noise = float(scored.noise_scale or 0.0)
    keep = np.flatnonzero(kinds == OBJECT)
    if len(keep) < 2:
        raise InvalidInputError(f"points: expected a scan with objects, got {n} points of which {len(keep)} are "
                                "not outliers. Pass the whole scan.")
    local = local_spacing(pts[keep])
    spacing = float(np.median(local))
    if not spacing > 0:
        raise InvalidInputError("points: expected distinct points, got a scan whose points mostly repeat. "
                                "Remove the duplicates.")
    found: list[Plane] = []
    if planes:
        threshold = max(PLANE_SCALES * noise, spacing)
        generator = np.random.default_rng(rng)
        for _ in range(MAX_PLANES):
            plane = _dominant_plane(pts, keep, threshold, plane_share, link, generator)
            if plane is None:
                break
            kinds[plane.indices] = PLANE
            found = _with_pieces(pts, found, [plane.indices]) if _coplanar(pts, plane, found) else [*found, plane]
            keep = np.flatnonzero(kinds == OBJECT)
            if len(keep) < min_points:
                break
    labels = np.full(n, -1, dtype=np.int64)
    objects: list[Cluster] = []
    clutter: list[Cluster] = []
    pieces: list[NDArray[np.int64]] = []
    reach = np.full(1, 0.0 if link is None else link)
    if len(keep):
        local, reach = _local_scales(pts[keep], (1, LINK_NEIGHBOUR))
        reach = LINK_REACH * reach if link is None else np.full(len(keep), link)
        component = _surface_components(pts[keep], reach, local, noise)
        sizes = np.bincount(component)
        flat = _on_planes(pts[keep], found)
        for c in np.argsort(-sizes, kind="stable"):
            members = keep[component == c]
            if found and np.mean(flat[component == c]) >= PLANE_PIECE_SHARE:
                pieces.append(members)
                continue
            if sizes[c] < min_points:
                clutter.append(Cluster(members))
                continue
            objects.append(Cluster(members))
    if pieces:
        found = _with_pieces(pts, found, pieces)
        kinds[np.concatenate(pieces)] = PLANE
    for i, cluster in enumerate(objects):
        labels[cluster.indices] = i
    for cluster in clutter:
        kinds[cluster.indices] = CLUTTER
    objects = [_with_neck(pts, c, rng) for c in objects]
    return Segmentation(labels, kinds, tuple(objects), tuple(found), tuple(clutter), spacing, float(np.median(reach)),
                        noise,
                        {"link_reach": None if link is not None else LINK_REACH,
                         "link_neighbour": None if link is not None else LINK_NEIGHBOUR, "min_points": min_points,
                         "plane_share": plane_share if planes else None})


def local_spacing(points: NDArray[np.float64], tree=None) -> NDArray[np.float64]:
    """Each point's spacing where it lies: the median, over it and its 15 nearest neighbours, of
    their distances to their nearest neighbour (a scan's density varies: a table far from the
    scanner is sparser than a toy near it; the median of 16 keeps one sample's luck out of it)."""
    return _local_scales(points, (1,), tree)[0]


def _local_scales(points: NDArray[np.float64], neighbours: tuple[int, ...], tree=None) -> list[NDArray[np.float64]]:
    """:func:`local_spacing` of each of ``neighbours`` (the k-th nearest neighbour's distance in
    place of the nearest's), from one neighbour query."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points) if tree is None else tree
    k = min(max(16, max(neighbours) + 1), len(points))
    distance, near = tree.query(points, k=k)
    near = near[:, :16]
    if k < 2:
        return [np.zeros(len(points)) for _ in neighbours]
    return [np.median(distance[:, min(j, k - 1)][near], axis=1) for j in neighbours]


def _components(points: NDArray[np.float64], reach: NDArray[np.float64] | float) -> NDArray[np.int64]:
    """Connected components of the graph linking i and j when one is within the other's ``reach``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    if np.ndim(reach) == 0:
        pairs = tree.query_pairs(float(reach), output_type="ndarray")
        rows, cols = pairs[:, 0], pairs[:, 1]
    else:
        rows, cols = _ball_pairs(tree, points, np.asarray(reach))
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(points), len(points)))
    return connected_components(graph, directed=False)[1]


def _ball_pairs(tree, centres: NDArray[np.float64],
                reach: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``(rows, cols)``: each centre's index (into ``centres``) beside every tree point within its ``reach``."""
    balls = tree.query_ball_point(centres, reach, workers=-1)
    rows = np.repeat(np.arange(len(centres)), [len(b) for b in balls])
    return rows, np.fromiter((j for b in balls for j in b), dtype=np.int64, count=len(rows))


def _surface_frame(points: NDArray[np.float64], local: NDArray[np.float64],
                   noise: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each point's surface normal and its position moved onto its surface.

    The normal is the direction of least spread of its :data:`_FRAME_K` nearest neighbours
    (:func:`ipfit.normals.local.pca`); the position moves along it to the median offset of the
    neighbours within a window (one local spacing or 2.5 noise scales, whichever is larger)
    around the point's own sheet, found in two steps: a second surface nearby (another object
    across a gap) is outside the window, so the point is not pulled towards it.
    """
    from scipy.spatial import cKDTree

    from ..normals.local import blocks, pca

    k = min(_FRAME_K, len(points))
    _, near = cKDTree(points).query(points, k=k)
    normals, _ = pca(points, near)
    moved = np.empty_like(points)
    window = np.maximum(local, 2.5 * noise)
    for part in blocks(len(points), k):
        offset = np.einsum("nkd,nd->nk", points[near[part]] - points[part, None, :], normals[part])
        moved[part] = points[part] + _sheet(offset, window[part])[:, None] * normals[part]
    return normals, moved


def _sheet(offset: NDArray[np.float64], window: NDArray[np.float64]) -> NDArray[np.float64]:
    """The median offset of a point's own sheet: the neighbours within ``window`` of it, two
    steps from the point itself."""
    centre = np.zeros(len(offset))
    for _ in range(2):
        inside = np.abs(offset - centre[:, None]) <= window[:, None]
        # the point itself (offset 0) is inside the first window: never an empty slice
        centre = np.nanmedian(np.where(inside, offset, np.nan), axis=1)
        centre = np.where(np.isfinite(centre), centre, 0.0)
    return centre


def _surface_components(points: NDArray[np.float64], reach: NDArray[np.float64], local: NDArray[np.float64],
                        noise: float) -> NDArray[np.int64]:
    """Connected components of the surface-aware graph (see the module notes), small parts attached."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(points)
    if n < 3:
        return _components(points, reach)
    normals, moved = _surface_frame(points, local, noise)
    tree = cKDTree(moved)
    rows, cols = _ball_pairs(tree, moved, reach)
    step = moved[cols] - moved[rows]
    tolerance = NORMAL_SPACINGS * local
    along = (np.abs(np.einsum("nd,nd->n", step, normals[rows])) <= tolerance[rows]) & \
            (np.abs(np.einsum("nd,nd->n", step, normals[cols])) <= tolerance[cols])
    graph = coo_matrix((np.ones(int(along.sum())), (rows[along], cols[along])), shape=(n, n))
    component = connected_components(graph, directed=False)[1]
    return _attach(tree, moved, component, ATTACH_LINKS * reach, local)


def _attach(tree, points: NDArray[np.float64], component: NDArray[np.int64], reach: NDArray[np.float64],
            local: NDArray[np.float64]) -> NDArray[np.int64]:
    """Small components join larger ones; components are renumbered 0, 1, ...

    Smallest first, each component of at most :data:`ATTACH_SHARE` of the largest joins the
    nearest (in local spacings, within ``reach`` of one of its points and of the point reached)
    group holding at least 1 / :data:`ATTACH_SHARE` times its points; a group is what has joined so far, so the sparse
    pieces of a cable join the body one after the other and then carry the headphones at its end.
    """
    sizes = np.bincount(component)
    small = (sizes >= _ATTACH_MIN_POINTS) & (sizes <= ATTACH_SHARE * sizes.max())
    members = np.flatnonzero(small[component])
    if not len(members):
        return component
    at, cols = _ball_pairs(tree, points[members], reach[members])
    rows = members[at]
    mine, theirs = component[rows], component[cols]
    distance = np.linalg.norm(points[cols] - points[rows], axis=1)
    # within the reach of the point reached too: a stray's own spacing is wide (it is alone), and
    # by it alone a few strays joined an apple from a diagonal away and pulled its fit to an
    # ellipsoid (docs/scenes.md, scene 6)
    other = (mine != theirs) & (sizes[theirs] >= _ATTACH_MIN_POINTS) & (distance <= reach[cols])
    rows, cols, mine, theirs = rows[other], cols[other], mine[other], theirs[other]
    gap = distance[other] / local[rows]
    order = np.lexsort((gap, mine))
    mine, theirs = mine[order], theirs[order]
    starts = np.searchsorted(mine, np.arange(len(sizes) + 1))
    parent = np.arange(len(sizes))
    held = sizes.copy()

    def root(c: int) -> int:
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    for c in np.argsort(sizes, kind="stable"):
        if not small[c]:
            continue
        here = root(int(c))
        for t in theirs[starts[c]:starts[c + 1]]:
            there = root(int(t))
            if there != here and ATTACH_SHARE * held[there] >= held[here]:
                parent[here] = there
                held[there] += held[here]
                break
    roots = np.array([root(c) for c in range(len(sizes))])
    return np.unique(roots[component], return_inverse=True)[1].astype(np.int64)


def _on_planes(points: NDArray[np.float64], planes: list[Plane]) -> NDArray[np.bool_]:
    """Whether each point lies within the inlier threshold of one of ``planes``."""
    flat = np.zeros(len(points), dtype=bool)
    for plane in planes:
        flat |= plane.holds(points)
    return flat


def _coplanar(points: NDArray[np.float64], plane: Plane, planes: list[Plane]) -> bool:
    """Whether ``plane``'s points lie on one of ``planes`` (another piece of the same floor)."""
    return bool(planes) and bool(np.mean(_on_planes(points[plane.indices], planes)) >= PLANE_PIECE_SHARE)


def _with_pieces(points: NDArray[np.float64], planes: list[Plane], pieces: list[NDArray[np.int64]]) -> list[Plane]:
    """``planes`` with each piece (indices into ``points``) joined to the plane most of it lies on:
    the floor between an object's legs, or beyond an object that splits it, is the floor."""
    from dataclasses import replace

    extra: list[list[NDArray[np.int64]]] = [[] for _ in planes]
    for piece in pieces:
        near = [np.mean(p.holds(points[piece])) for p in planes]
        extra[int(np.argmax(near))].append(piece)
    return [replace(p, indices=np.sort(np.concatenate([p.indices, *more]))) if more else p
            for p, more in zip(planes, extra, strict=True)]


def _dominant_plane(pts, keep, threshold: float, share: float, reach: float | None, generator) -> Plane | None:
    """The plane of RANSAC on ``pts[keep]`` when one connected patch of it (linked at ``reach``, or
    at :data:`LINK_SPACINGS` of its points' local spacing when None) holds at least ``share`` of
    them, else None. The patch alone is removed: a plane that only
    slices through several objects (their bottoms, their flat faces) has no such patch."""
    from skimage.measure import ransac

    data = pts[keep]
    if len(data) < 10:
        return None
    model, inliers = ransac(data, PlaneModel, min_samples=3, residual_threshold=threshold, max_trials=1000,
                            rng=generator)
    if model is None or inliers is None or not inliers.any():
        return None
    # least squares on the inliers, then the inliers of that plane: RANSAC's is one of a sample
    refit = PlaneModel.from_estimate(data[inliers])
    if refit:
        model = refit
        inliers = model.residuals(data) <= threshold
    if inliers.sum() < share * len(data):
        return None
    on = np.flatnonzero(inliers)
    # linked at its points' own spacing: a table is often sampled sparser (or denser) than the objects
    link = np.full(len(on), reach) if reach is not None else LINK_SPACINGS * local_spacing(data[on])
    patch = _components(data[on], link)
    largest = np.bincount(patch).argmax()
    on, link = on[patch == largest], link[patch == largest]
    if len(on) < share * len(data):
        return None
    normal = np.asarray(model.normal, dtype=np.float64)
    if _is_a_face(data, on, link, normal, ~inliers):
        return None
    return Plane(normal, model.offset, keep[on], float(threshold))


def _is_a_face(data: NDArray[np.float64], on: NDArray[np.intp], link: NDArray[np.float64], normal: NDArray[np.float64],
               off: NDArray[np.bool_]) -> bool:
    """Whether the plane patch ``data[on]`` is a face of an object rather than a support: most of
    its rim (its points within a spacing of its outline, the convex hull of the patch in the
    plane) lies within a link of points off the plane (``off``). A table's or a floor's rim is the
    edge of the scan, a wall's meets the floor removed before it; a box's top meets its sides all
    round (a box on a table lost its top and two sides as planes before this test)."""
    from scipy.spatial import ConvexHull, QhullError, cKDTree

    if not off.any():
        return False
    frame = np.linalg.svd(np.eye(3) - np.outer(normal, normal))[0][:, :2]  # two axes in the plane
    flat = data[on] @ frame
    try:
        hull = ConvexHull(flat)
    except QhullError:  # a patch on one line has no outline to speak of
        return False
    inside = -(flat @ hull.equations[:, :2].T + hull.equations[:, 2]).max(axis=1)  # distance to the outline
    rim = inside <= link / LINK_SPACINGS  # within a spacing of the outline
    nearest = cKDTree(data[off]).query(data[on][rim])[0]
    return bool(np.mean(nearest <= link[rim]) > FACE_RIM_SHARE)


def neck(points: ArrayLike, rng=0) -> tuple[float, NDArray[np.bool_]]:
    """How narrow the narrowest waist of a cloud is, and the split at it.

    The k-nearest-neighbour graph's Fiedler vector orders the points from one end to the other;
    of the cuts along it (each part at least ``_NECK_PART`` of the points), the one crossing the
    fewest links per point of its smaller part is the waist. Its ratio is those links over the
    links the same cut would cross on one smooth body of that size: the perimeter of a cap
    holding the smaller part's share, (m / n)^((d-2)/(d-1))-scaled. A single convex or
    bunny-like body has a ratio near 1; two bodies that touch at a point or along a small patch
    are joined by a few links only: a ratio well below 1.

    Returns
    -------
    (ratio, side) : the ratio (inf when no cut is possible) and the (N,) mask of the smaller part.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import laplacian
    from scipy.sparse.linalg import eigsh
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=np.float64)
    n, dim = pts.shape
    side = np.zeros(n, dtype=bool)
    if n < max(4 * _NECK_K, _NECK_MIN_POINTS):
        return float("inf"), side
    pick = np.arange(n)
    if n > _NECK_MAX_POINTS:
        from ..geometry.sampling import spread_subsample

        pick = spread_subsample(pts, _NECK_MAX_POINTS, rng=rng)
    sub = pts[pick]
    m = len(sub)
    _, nearest = cKDTree(sub).query(sub, k=_NECK_K + 1)
    rows = np.repeat(np.arange(m), _NECK_K)
    cols = nearest[:, 1:].ravel()
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(m, m)).tocsr()
    graph = ((graph + graph.T) > 0).astype(np.float64)
    lap = laplacian(graph, normed=True)
    try:
        start = np.random.default_rng(0).standard_normal(m)
        values, vectors = eigsh(lap, k=2, sigma=-1e-3, which="LM", v0=start)
    except (RuntimeError, ValueError, np.linalg.LinAlgError):
        return float("inf"), side
    fiedler = vectors[:, np.argsort(values)[1]] / np.sqrt(np.maximum(np.asarray(graph.sum(axis=1)).ravel(), 1))
    order = np.argsort(fiedler)
    rank = np.empty(m, dtype=np.int64)
    rank[order] = np.arange(m)
    coo = graph.tocoo()
    upper = coo.row < coo.col
    lo = np.minimum(rank[coo.row[upper]], rank[coo.col[upper]])
    hi = np.maximum(rank[coo.row[upper]], rank[coo.col[upper]])
    # links crossing the cut after position j: lo <= j < hi
    crossing = np.cumsum(np.bincount(lo, minlength=m) - np.bincount(hi, minlength=m))[:-1]
    small = np.minimum(np.arange(1, m), m - np.arange(1, m))
    # a cut of a smooth body separating a part of share q crosses ~ q^((d-2)/(d-1)) of the links a
    # median cut crosses: the length (2D: a constant, 2 points) of the boundary of a cap of that share
    expected_shape = (small / (m / 2)) ** ((dim - 2) / (dim - 1))
    valid = small >= _NECK_PART * m
    if not valid.any():
        return float("inf"), side
    # the reference: a median cut of one smooth body of m points crosses about that many links
    body = _NECK_K * m ** ((dim - 2) / (dim - 1)) * 0.5
    ratios = np.where(valid, crossing / (body * expected_shape), np.inf)
    j = int(np.argmin(ratios))
    lower = np.zeros(m, dtype=bool)
    lower[order[: j + 1]] = True
    smaller = lower if lower.sum() <= m / 2 else ~lower
    # back to every point: each takes the side of its nearest subsample point
    _, owner = cKDTree(sub).query(pts, k=1)
    return float(ratios[j]), smaller[owner]


def _with_neck(pts, cluster: Cluster, rng) -> Cluster:
    ratio, side = neck(pts[cluster.indices], rng)
    if ratio >= _NECK_RATIO:
        return cluster
    parts = int(side.sum()), int((~side).sum())
    note = (f"may be two objects that touch: a narrow neck (ratio {ratio:.2f}) joins parts of {max(parts)} and "
            f"{min(parts)} points; fitted as one")
    return Cluster(cluster.indices, True, note)

"""The zero set Z(f) of a fitted polynomial: grid evaluation, marching squares and cubes.

The grid values come from a separable contraction: with per-axis power tables
``X[i, a] = u_x[i] ** a`` (and Y, Z alike) and the coefficients scattered into a dense
tensor ``C[a, b, c]``, the values are ``V[i, j, k] = Σ C[a, b, c] X[i, a] Y[j, b] Z[k, c]``,
three small matrix products instead of one product per grid node and monomial. The grid
lives in the polynomial's normalised coordinates (well conditioned at high degree); every
output is in the user's coordinates.

>>> from ipfit.datasets import synthetic
>>> zs = extract_zero_set(synthetic.circle().polynomial, bounds=[[-1.5, 1.5], [-1.5, 1.5]])
>>> zs.n_components, zs.closed
(1, True)
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import basis
from .._utils.optional import require
from .._utils.validation import as_points, check_int, check_nonnegative, error
from ..geometry.distance import Samples, sample_segments, sample_triangles
from ..polynomial import ImplicitPolynomial

if TYPE_CHECKING:
    from .trim import Trim

__all__ = [
    "ZeroSet",
    "Samples",
    "grid_axes",
    "grid_values",
    "extract_zero_set",
    "data_bounds",
    "default_bounds",
    "sample_segments",
    "sample_triangles",
]

DEFAULT_RESOLUTION = {2: 512, 3: 128}
MAX_GRID_POINTS = 1 << 27  # 1 GiB of float64 values: beyond that the caller surely meant less


# -- bounds and grids ------------------------------------------------------------------------

def _as_bounds(bounds: ArrayLike, dim: int) -> NDArray[np.float64]:
    try:
        arr = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        raise error("bounds", f"a ({dim}, 2) array of [low, high] per axis", repr(bounds)[:60]) from None
    if arr.shape != (dim, 2):
        raise error("bounds", f"a ({dim}, 2) array of [low, high] per axis", f"shape {arr.shape}",
                    "Pass e.g. [[xmin, xmax], [ymin, ymax]].")
    if not np.isfinite(arr).all() or not (arr[:, 1] > arr[:, 0]).all():
        raise error("bounds", "finite bounds with low < high on every axis", arr.tolist().__repr__()[:80])
    return arr


def data_bounds(points: ArrayLike, margin: float = 0.25) -> NDArray[np.float64]:
    """Bounding box of ``points`` grown by ``margin`` × its longest side on every side.

    The margin is a fraction of the longest side, not of each side, so a flat cloud still
    gets a box of some thickness around it.

    >>> data_bounds([[0.0, 0.0], [2.0, 1.0]], margin=0.25).tolist()
    [[-0.5, 2.5], [-0.5, 1.5]]
    """
    pts = as_points(points)
    margin = check_nonnegative(margin, "margin")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    longest = float((hi - lo).max())
    if longest == 0:
        longest = max(1.0, float(np.abs(lo).max()))  # one repeated point: any sensible box
    pad = margin * longest if margin > 0 else 0.0
    pads = np.where(hi - lo > 0, pad, max(pad, 0.5 * longest))  # per axis: a flat axis gets half the longest
    return np.column_stack([lo - pads, hi + pads])


def default_bounds(poly: ImplicitPolynomial, margin: float) -> NDArray[np.float64]:
    # Without data, the normalisation is the only hint of where the shape is: the fitted
    # points lie mostly within ~1.5 mean radii of the centre.
    half = 1.5 * (1.0 + 2.0 * margin) * poly.scale
    return np.column_stack([poly.center - half, poly.center + half])


def _resolution_per_axis(resolution, dim: int) -> tuple[int, ...]:
    if isinstance(resolution, (list, tuple, np.ndarray)):
        if len(resolution) != dim:
            raise error("resolution", f"an int or {dim} ints", f"{len(resolution)} values")
        shape = tuple(check_int(r, "resolution", minimum=2) for r in resolution)
    else:
        shape = (check_int(resolution, "resolution", minimum=2),) * dim
    if math.prod(shape) > MAX_GRID_POINTS:
        raise error("resolution", f"a grid of at most {MAX_GRID_POINTS} nodes", f"{math.prod(shape)} nodes",
                    "Lower the resolution.")
    return shape


def grid_axes(bounds: ArrayLike, resolution) -> list[NDArray[np.float64]]:
    """The sample positions along each axis: ``linspace(low, high, n)`` per axis."""
    arr = np.asarray(bounds, dtype=np.float64)
    shape = _resolution_per_axis(resolution, arr.shape[0])
    arr = _as_bounds(arr, len(shape))
    return [np.linspace(lo, hi, n) for (lo, hi), n in zip(arr, shape, strict=True)]


def grid_values(poly: ImplicitPolynomial, bounds: ArrayLike, resolution) -> NDArray[np.float64]:
    """f on a regular grid over ``bounds`` (user coordinates), by separable contraction.

    Parameters
    ----------
    poly : the polynomial.
    bounds : (dim, 2) array of ``[low, high]`` per axis, in user coordinates.
    resolution : int or sequence of ints
        Number of grid nodes per axis (the same for all axes when an int).

    Returns
    -------
    values : ndarray of shape ``(n_x, n_y[, n_z])``
        ``values[i, j, k] = f(x_i, y_j, z_k)`` with the axes of :func:`grid_axes`
        (``indexing="ij"``).

    Notes
    -----
    Cost: O(n³ (g+1)) for a 3D grid of n³ nodes and degree g, against O(n³ C(g+3, 3))
    point by point. The values equal point-wise evaluation up to rounding.
    """
    if not isinstance(poly, ImplicitPolynomial):
        raise error("poly", "an ImplicitPolynomial", type(poly).__name__)
    dim, degree = poly.dim, poly.degree
    axes = grid_axes(_as_bounds(bounds, dim), resolution)
    norm = poly.normalization
    tables = [basis.power_table(((ax - c) / norm.scale)[:, None], degree)[:, 0]
              for ax, c in zip(axes, norm.center, strict=True)]
    dense = np.zeros((degree + 1,) * dim)
    dense[tuple(poly.exponents.T)] = poly.coefficients
    if dim == 2:
        x, y = tables
        return (x @ dense) @ y.T
    x, y, z = tables
    # Contract the two cheap axes first so that the only big product is the last one,
    # (n_x n_y, g+1) @ (g+1, n_z), which BLAS runs at full speed.
    a = np.tensordot(x, dense, axes=(1, 0))                      # (nx, b, c)
    b = np.einsum("jb,ibc->ijc", y, a, optimize=True)            # (nx, ny, c)
    out = b.reshape(-1, degree + 1) @ z.T                        # (nx*ny, nz)
    return out.reshape(len(axes[0]), len(axes[1]), len(axes[2]))


# -- the zero set ----------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class ZeroSet:
    """The zero set of a polynomial inside a box, in user coordinates.

    Attributes
    ----------
    dim : 2 or 3.
    bounds : (dim, 2) array, the box that was searched.
    spacing : (dim,) grid step per axis (equal steps unless a per-axis resolution was given).
    shape : grid nodes per axis.
    curves : 2D only: tuple of (n, 2) polylines. A closed curve repeats its first point at
        the end; an open one ends on the box's boundary.
    vertices, faces : 3D only: the triangle mesh (faces index vertices).
    reaches_boundary : whether f changes sign (or vanishes) on the box's boundary, i.e.
        the zero set leaves the box.
    polynomial : the polynomial it was extracted from, if known.
    trim : a :class:`ipfit.zeroset.trim.Trim` record when this is a trimmed zero set
        (:meth:`trimmed`), else None.
    """

    dim: int
    bounds: NDArray[np.float64]
    spacing: NDArray[np.float64]
    shape: tuple[int, ...]
    curves: tuple[NDArray[np.float64], ...] = ()
    vertices: NDArray[np.float64] | None = None
    faces: NDArray[np.int64] | None = None
    reaches_boundary: bool = False
    polynomial: ImplicitPolynomial | None = None
    trim: Trim | None = None  # set by trimmed(): what was removed

    # -- summary ------------------------------------------------------------------------
    @property
    def step(self) -> float:
        """The largest grid step: extracted points are within about one step of Z(f)."""
        return float(np.max(self.spacing))

    @property
    def is_empty(self) -> bool:
        if self.dim == 2:
            return len(self.curves) == 0
        return self.faces is None or len(self.faces) == 0

    @property
    def closed(self) -> bool:
        """True when the zero set is non-empty, closes inside the box and was not trimmed open."""
        return not self.is_empty and not self.reaches_boundary and not (self.trim and self.trim.removed_faces)

    @property
    def curve_closed(self) -> tuple[bool, ...]:
        """2D: per curve, whether it is a closed loop."""
        return tuple(bool(len(c) > 2 and np.array_equal(c[0], c[-1])) for c in self.curves)

    @cached_property
    def component_labels(self) -> NDArray[np.int64]:
        """Component of each curve (2D) or each face (3D), numbered from 0."""
        if self.dim == 2:
            return np.arange(len(self.curves), dtype=np.int64)
        if self.is_empty:
            return np.empty(0, dtype=np.int64)
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        vertices, f = self._mesh()
        n = len(vertices)
        rows = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
        cols = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
        graph = coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n))
        _, vertex_labels = connected_components(graph, directed=False)
        # Renumber over faces only (isolated vertices never occur, but stay safe).
        _, face_labels = np.unique(vertex_labels[f[:, 0]], return_inverse=True)
        return face_labels.astype(np.int64)

    @cached_property
    def component_open(self) -> NDArray[np.bool_]:
        """Per component: whether it leaves the box (2D: an open curve; 3D: a piece with edges
        that only one triangle uses, which marching cubes leaves only where the box cuts it)."""
        if self.dim == 2:
            return ~np.array(self.curve_closed, dtype=bool)
        out = np.zeros(self.n_components, dtype=bool)
        if self.is_empty:
            return out
        vertices, f = self._mesh()
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        codes = edges[:, 0] * np.int64(len(vertices)) + edges[:, 1]
        _, inverse, counts = np.unique(codes, return_inverse=True, return_counts=True)
        border = counts[inverse] == 1
        out[self.component_labels[np.tile(np.arange(len(f)), 3)[border]]] = True
        return out

    @property
    def n_components(self) -> int:
        """Connected pieces of the zero set inside the box."""
        labels = self.component_labels
        return int(labels.max()) + 1 if labels.size else 0

    def components(self) -> list:
        """The pieces: 2D a list of polylines; 3D a list of ``(vertices, faces)`` meshes."""
        if self.dim == 2:
            return list(self.curves)
        if self.is_empty:
            return []
        out = []
        labels = self.component_labels
        vertices, faces = self._mesh()
        for c in range(self.n_components):
            f = faces[labels == c]
            used, inverse = np.unique(f, return_inverse=True)
            out.append((vertices[used], inverse.reshape(f.shape)))
        return out

    @property
    def size(self) -> float:
        """Total length (2D) or area (3D) of the extracted zero set."""
        if self.is_empty:
            return 0.0
        if self.dim == 2:
            return float(sum(np.linalg.norm(np.diff(c, axis=0), axis=1).sum() for c in self.curves))
        v, f = self._mesh()
        return float(0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum())

    def _mesh(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """3D, not empty: ``(vertices, faces)``, which such a zero set always has (the fields are
        optional only because a 2D zero set has neither)."""
        if self.vertices is None or self.faces is None:
            raise ValueError("ZeroSet: a 2D or empty zero set has no mesh")  # a bug of ipfit's, not an input error
        return self.vertices, self.faces

    # -- sampling -----------------------------------------------------------------------
    def segments(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """2D: every polyline segment as ``(starts, ends, curve_index)``."""
        if self.dim != 2 or self.is_empty:
            return np.empty((0, self.dim)), np.empty((0, self.dim)), np.empty(0, dtype=np.int64)
        starts = np.concatenate([c[:-1] for c in self.curves])
        ends = np.concatenate([c[1:] for c in self.curves])
        labels = np.repeat(np.arange(len(self.curves)), [len(c) - 1 for c in self.curves])
        return starts, ends, labels

    def sample(self, spacing: float | None = None, max_samples: int | None = None) -> Samples:
        """Dense samples of the zero set with length/area weights and component labels.

        ``spacing`` defaults to a quarter of the grid step; see :func:`sample_triangles`.
        """
        spacing = self.step / 4 if spacing is None else float(spacing)
        if self.is_empty:
            empty = np.empty(0, dtype=np.int64)
            return Samples(np.empty((0, self.dim)), np.empty(0), empty, empty)
        if self.dim == 2:
            starts, ends, labels = self.segments()
            return sample_segments(starts, ends, spacing, labels, max_samples)
        return sample_triangles(*self._mesh(), spacing, self.component_labels, max_samples)

    def trimmed(self, points: ArrayLike, distance: float | None = None, *, faces: ArrayLike | None = None) -> ZeroSet:
        """The parts within ``distance`` of the data ``points`` (and their ``faces``), as a new
        zero set whose ``trim`` records what went; see :func:`ipfit.zeroset.trim.trim_zero_set`."""
        from .trim import trim_zero_set

        return trim_zero_set(self, points, distance, faces=faces)

    # -- export -------------------------------------------------------------------------
    def _mesh_for(self, library: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        if self.dim != 3:
            raise error("zero set", "a 3D zero set (a mesh)", "a 2D zero set (curves)",
                        f"Only surfaces become {library} meshes; write 2D zero sets as SVG or CSV.")
        if self.vertices is None or self.faces is None:  # no surface in the box
            return np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
        return self.vertices, self.faces

    def to_trimesh(self):
        """3D: the mesh as a ``trimesh.Trimesh`` (vertices unmerged, unprocessed)."""
        vertices, faces = self._mesh_for("trimesh")
        import trimesh

        return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)

    def to_open3d(self):
        """3D: the mesh as an ``open3d.geometry.TriangleMesh`` (``pip install 'ipfit[open3d]'``)."""
        vertices, faces = self._mesh_for("Open3D")
        o3d = require("open3d", "ZeroSet.to_open3d")
        return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces))

    def to_pyvista(self):
        """3D: the mesh as a ``pyvista.PolyData`` (``pip install 'ipfit[pyvista]'``)."""
        vertices, faces = self._mesh_for("PyVista")
        pv = require("pyvista", "ZeroSet.to_pyvista")
        cells = np.column_stack([np.full(len(faces), 3, dtype=np.int64), faces]).ravel()
        return pv.PolyData(vertices, cells)

    def save(self, path: str | os.PathLike) -> None:
        """Write to ``path`` by extension: .ply/.obj/.stl (3D), .svg/.csv (2D); atomically."""
        from .export import save_zero_set

        save_zero_set(self, path)

    def __repr__(self) -> str:
        what = (f"curves={len(self.curves)}" if self.dim == 2 else
                f"vertices={0 if self.vertices is None else len(self.vertices)}, "
                f"faces={0 if self.faces is None else len(self.faces)}")
        return (f"ZeroSet(dim={self.dim}, {what}, components={self.n_components}, closed={self.closed}, "
                f"step={self.step:.4g})")


def _boundary_has_zero(values: NDArray) -> bool:
    signs = []
    for axis in range(values.ndim):
        for index in (0, -1):
            face = np.take(values, index, axis=axis)
            signs.append((face.min() <= 0, face.max() >= 0))
    has_neg = any(s[0] for s in signs)
    has_pos = any(s[1] for s in signs)
    return bool(has_neg and has_pos)


def extract_zero_set(poly: ImplicitPolynomial, bounds: ArrayLike | None = None, points: ArrayLike | None = None,
                     margin: float = 0.25, resolution: int | Sequence[int] | None = None) -> ZeroSet:
    """Extract Z(f) inside a box: marching squares (2D) or marching cubes (3D).

    Parameters
    ----------
    poly : the polynomial.
    bounds : (dim, 2) box in user coordinates. Default: the bounding box of ``points``
        grown by ``margin`` (see :func:`data_bounds`), or without points a box of
        1.5·(1 + 2·margin) mean radii around the polynomial's normalisation centre.
    points : the data, used only for the default box.
    margin : fraction of the box's longest side added on every side.
    resolution : int or sequence of ints
        An int is the number of grid nodes along the box's longest side; the other sides
        get the same step. A sequence gives the nodes per axis. Default 512 (2D), 128 (3D).

    Returns
    -------
    ZeroSet
        Points of the extracted set lie within about one grid step of the true zero set
        (linear interpolation along grid edges).
    """
    if not isinstance(poly, ImplicitPolynomial):
        raise error("poly", "an ImplicitPolynomial", type(poly).__name__)
    dim = poly.dim
    if bounds is not None:
        box = _as_bounds(bounds, dim)
    elif points is not None:
        pts = as_points(points, dims=(dim,))
        box = data_bounds(pts, margin)
    else:
        box = default_bounds(poly, check_nonnegative(margin, "margin"))
    if resolution is None:
        resolution = DEFAULT_RESOLUTION[dim]
    if isinstance(resolution, (list, tuple, np.ndarray)):
        shape = _resolution_per_axis(resolution, dim)
    else:
        n = check_int(resolution, "resolution", minimum=2)
        sides = box[:, 1] - box[:, 0]
        step = float(sides.max()) / (n - 1)
        counts = np.maximum(2, np.ceil(sides / step - 1e-9).astype(np.int64) + 1)
        # Grow the shorter sides symmetrically to a whole number of equal steps.
        extra = (counts - 1) * step - sides
        box = np.column_stack([box[:, 0] - extra / 2, box[:, 0] - extra / 2 + (counts - 1) * step])
        shape = _resolution_per_axis(tuple(int(c) for c in counts), dim)
    values = grid_values(poly, box, shape)
    if not np.isfinite(values).all():
        raise error("poly", "finite values over the box", "overflow to inf or NaN",
                    "Use a smaller box (bounds or margin).")
    spacing = (box[:, 1] - box[:, 0]) / (np.asarray(shape) - 1)
    reaches = _boundary_has_zero(values)
    lo = box[:, 0]
    crosses = values.min() <= 0 <= values.max() and values.min() < values.max()
    if dim == 2:
        from skimage.measure import find_contours

        curves = tuple(lo + c * spacing for c in find_contours(values, 0.0)) if crosses else ()
        return ZeroSet(2, box, spacing, shape, curves=curves, reaches_boundary=reaches, polynomial=poly)
    verts = np.empty((0, 3))
    faces = np.empty((0, 3), dtype=np.int64)
    if crosses:
        from skimage.measure import marching_cubes

        try:
            verts, faces, _, _ = marching_cubes(values, level=0.0, allow_degenerate=False)
        except (ValueError, RuntimeError):  # no crossing left after degenerate faces are dropped
            verts, faces = np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
        # Grid units, scaled here in float64: skimage scales by the spacing in float32, which
        # overflows beyond 3e38 (and every face degenerates).
        verts = verts.astype(np.float64) * spacing + lo
        faces = faces.astype(np.int64)
    return ZeroSet(3, box, spacing, shape, vertices=verts, faces=faces, reaches_boundary=reaches, polynomial=poly)

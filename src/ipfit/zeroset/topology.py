"""The topology of a shape: of a zero set, and of the data it should have.

F-score and spurious counts say how close a zero set is to the data, not whether it has the
data's *shape*: a horse's tail that floats free as its own loop is a wrong shape even at
F = 0.998. This module counts, on the same terms for both sides:

* **2D**: the closed curves (*loops*), how they nest (each loop's depth: how many loops
  enclose it) and the open arcs (curves that end on the box, or an open contour);
* **3D**: the connected components, which of them are open (a border: the box cuts them, or
  an open mesh), and the Euler characteristic χ = V − E + F and genus g = (2 − χ)/2 of each
  closed one.

The zero set's topology (:func:`zero_set_topology`) is read from the
:class:`~ipfit.zeroset.extract.ZeroSet` the quality measure already extracted, ignoring only
the specks (:func:`is_speck`) that the degree rules ignore. The data's (:func:`data_topology`)
comes from its order, faces or points, with a stated ``confidence``:

* ``"high"``: an ordered contour or a traced silhouette (its loops are given), a mesh whose
  components are all closed and do not pass through each other;
* ``"medium"``: an estimate that agrees at two scales: a bare cloud's components (and in 2D
  its loops, the holes of the union of discs around the points), an open mesh whose holes
  are capped for the genus;
* ``"low"``: the estimates disagree, or a mesh's parts intersect; ``"unknown"``: nothing to
  go by. Only a high-confidence topology is held against a zero set by the degree rules.

A :class:`Topology` is cached on the :class:`~ipfit.Cloud` for the data (``Cloud.derived``).
:func:`topology_samples` gives the places where a zero set's inside and the data's disagree
far from the data (a thin part cut off, a loop in a gap): the repair holds them on the data's
side.

>>> from ipfit.datasets import synthetic
>>> from ipfit.zeroset.extract import extract_zero_set
>>> shape = synthetic.circle()
>>> zero_set_topology(extract_zero_set(shape.polynomial, points=shape.points)).describe()
'1 loop'
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..cloud import Cloud
from ..geometry.distance import contour_pieces
from ..polynomial import ImplicitPolynomial
from .extract import ZeroSet, data_bounds, grid_axes, grid_values

__all__ = ["Topology", "zero_set_topology", "data_topology", "topology_samples", "is_speck",
           "SPECK_REACH", "CONFIDENCES", "ENFORCED", "describe_mismatch", "MAX_PARTS", "ESTIMATE_POINTS",
           "MAX_INSIDE_FACES"]


#: A speck comes within this many τ of the data (see :func:`is_speck`).
SPECK_REACH = 2.0
#: The confidences of a data topology, most confident first.
CONFIDENCES = ("high", "medium", "low", "unknown")
#: The confidence at which a data topology is held against a zero set (the degree rules).
ENFORCED = "high"
#: A mesh of more parts than this has a topology of low confidence (no pairwise intersection test).
MAX_PARTS = 50
#: A bare cloud's estimate is made on at most this many of its points (evenly strided).
ESTIMATE_POINTS = 20_000
#: The repair's places of the topology need a closed mesh's inside on a raster (winding numbers,
#: raster nodes × faces): beyond this many faces the repair goes without them.
MAX_INSIDE_FACES = 200_000


def is_speck(component: dict, tau: float) -> bool:
    """Whether a spurious component (an entry of :attr:`Quality.spurious`) is a speck: smaller
    than a τ/2 square (length τ/2 in 2D, area τ²/4 in 3D) and within :data:`SPECK_REACH` τ of
    the data, i.e. a fragment of a thin part at the sampling resolution, not an oval in empty
    space. (A thin model's fit breaks up into such fragments; the repair of a degree does not
    chase them, and ``ipfit fit --trim`` removes them from an exported zero set.)

    >>> is_speck({"size": 0.01, "distance": 0.06, "center": [0.0, 0.0]}, tau=0.05)
    True
    >>> is_speck({"size": 0.01, "distance": 2.0, "center": [0.0, 0.0]}, tau=0.05)
    False
    """
    return component["size"] < (tau / 2) ** (len(component["center"]) - 1) and component["distance"] < SPECK_REACH * tau


@dataclass(frozen=True)
class Topology:
    """The topology of a zero set or of the data (see the module's notes).

    Attributes
    ----------
    dim : 2 or 3.
    components : the pieces counted (2D: loops and arcs; 3D: surfaces).
    open : those of them that are open (2D arcs; 3D surfaces with a border).
    nesting : 2D: the depth of each loop (0: inside no other loop; 1: inside one...), sorted.
    euler, genus : 3D: χ and g of each closed component, sorted by genus then χ; a genus is
        None where χ is odd or above 2 (not one closed orientable surface). For an open mesh of the data,
        of every component with its holes capped (and a zero set is compared with that closed
        surface: its openness is not).
    ignored : specks left out (a zero set's), or tiny pieces left out of an estimate (bare data).
    source : "zero set", or the data's: "contour", "silhouette", "mesh", "points", "none".
    confidence : one of :data:`CONFIDENCES` (a zero set's own topology is "high").
    """

    dim: int
    components: int
    open: int = 0
    nesting: tuple[int, ...] = ()
    euler: tuple[int, ...] = ()
    genus: tuple[int | None, ...] = ()
    ignored: int = 0
    source: str = "zero set"
    confidence: str = "high"

    @property
    def loops(self) -> int:
        """2D: the closed curves; 3D: the closed components."""
        return self.components - self.open

    @property
    def capped(self) -> bool:
        """Whether this is an open mesh of the data standing for the closed surface its holes,
        capped, bound (its genus is that surface's; its openness is not compared)."""
        return self.dim == 3 and self.source == "mesh" and self.open > 0

    @property
    def known(self) -> bool:
        """Whether the degree rules hold this topology against a zero set (:data:`ENFORCED`)."""
        return CONFIDENCES.index(self.confidence) <= CONFIDENCES.index(ENFORCED)

    def matches(self, other: Topology) -> bool | None:
        """Whether ``other`` (a zero set's) has this topology (the data's); None when this one is
        not known well enough to say ("low" or "unknown"). What this one leaves out is not
        compared: a bare 3D cloud's genus (empty here), and the genus of a mesh's component whose χ
        is odd (None: a pinched or non-orientable mesh, whose genus no zero set can have)."""
        if self.confidence in ("low", "unknown"):
            return None
        if self.components != other.components or (not self.capped and self.open != other.open):
            return False
        if self.dim == 2:
            return self.nesting == other.nesting if self.nesting or not self.loops else True
        if not self.genus:
            return True
        known = Counter(g for g in self.genus if g is not None)
        return len(other.genus) == len(self.genus) and not known - Counter(map(_genus_key, other.genus))

    def describe(self) -> str:
        """In words, as the terminal says it: '5 loops', '1 loop and 1 arc', '2 surfaces (genus 0, 1)'."""
        if self.confidence == "unknown":
            return "an unknown topology"
        if self.dim == 2:
            loops = f"{self.loops} loop{'s' if self.loops != 1 else ''}"
            nested = sum(1 for d in self.nesting if d > 0)
            if nested:
                loops += f" ({nested} inside another)"
            arcs = f"{self.open} open arc{'s' if self.open != 1 else ''}"
            return loops if not self.open else (arcs if not self.loops else f"{loops} and {arcs}")
        text = f"{self.components} surface{'s' if self.components != 1 else ''}"
        if self.genus:
            text += " (genus " + ", ".join("?" if g is None else str(g) for g in self.genus) + ")"
        if self.open:
            text += f", {self.open} open"
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Topology:
        """The topology :meth:`to_dict` wrote (a result file's)."""
        fields = {k: data[k] for k in cls.__dataclass_fields__ if k in data}
        for key in ("nesting", "euler", "genus"):
            fields[key] = tuple(fields.get(key) or ())
        return cls(**fields)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (tuples become lists), with ``loops``."""
        out = asdict(self)
        for key in ("nesting", "euler", "genus"):
            out[key] = list(out[key])
        out["loops"] = self.loops
        return out


def describe_mismatch(topology: Topology, data: Topology) -> str:
    """How a zero set's topology differs from the data's, in one phrase ('' when it does not,
    or the data's is not known): '5 loops where the data has 1'.

    >>> describe_mismatch(Topology(2, 5, nesting=(0, 0, 0, 0, 0)), Topology(2, 1, nesting=(0,), source="contour"))
    '5 loops where the data has 1'
    """
    if data.matches(topology) is not False:
        return ""
    estimated = "" if data.known else " (estimated)"
    if topology.dim == 2:
        if topology.loops != data.loops:
            return f"{_count(topology.loops, 'loop')} where the data{estimated} has {data.loops}"
        if topology.open != data.open:
            return f"{_count(topology.open, 'open arc')} where the data{estimated} has {data.open or 'none'}"
        return (f"{topology.loops} loops nested {_depths(topology.nesting)} where the data{estimated}'s are "
                f"nested {_depths(data.nesting)}")
    if topology.components != data.components:
        return f"{_count(topology.components, 'surface')} where the data{estimated} has {data.components}"
    if data.capped and topology.open:  # compared with the closed surface the capped mesh bounds
        return f"{_count(topology.open, 'open surface')} where the data{estimated} has none, its holes capped"
    if not data.capped and topology.open != data.open:
        return f"{_count(topology.open, 'open surface')} where the data{estimated} has {data.open or 'none'}"
    return f"genus {_genera(topology.genus)} where the data{estimated} has genus {_genera(data.genus)}"


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'s' if n != 1 else ''}"


def _depths(nesting: Sequence[int]) -> str:
    return "(depths " + ", ".join(map(str, nesting)) + ")"


def _genera(genus: Sequence[int | None]) -> str:
    return ", ".join("?" if g is None else str(g) for g in genus)


def _genus_key(g: int | None) -> int:
    return -1 if g is None else g


# -- the zero set -------------------------------------------------------------------------------

def zero_set_topology(zero_set: ZeroSet, spurious: Sequence[dict] = (), spurious_flags: NDArray | None = None,
                      tau: float | None = None) -> Topology:
    """The topology of ``zero_set``, specks left out.

    Parameters
    ----------
    zero_set : the extracted zero set (2D curves or a 3D mesh).
    spurious, spurious_flags, tau : the quality measure's spurious components (records as in
        :attr:`Quality.spurious`, flags per component) and tolerance; the components that are
        specks (:func:`is_speck`) are left out. None and () count every component.
    """
    flags = np.zeros(zero_set.n_components, dtype=bool) if spurious_flags is None else np.asarray(spurious_flags)
    ignore = np.zeros(zero_set.n_components, dtype=bool)
    if tau is not None and len(spurious):
        specks = np.array([is_speck(c, tau) for c in spurious], dtype=bool)
        ignore[np.flatnonzero(flags)[specks]] = True
    keep = np.flatnonzero(~ignore)
    if zero_set.dim == 2:
        closed = np.array(zero_set.curve_closed, dtype=bool)
        loops = [zero_set.curves[i] for i in keep if closed[i]]
        return Topology(2, components=len(keep), open=int((~closed[keep]).sum()), nesting=_nesting(loops),
                        ignored=int(ignore.sum()))
    if zero_set.is_empty:
        return Topology(3, components=0)
    vertices, faces = zero_set.vertices, zero_set.faces
    assert vertices is not None and faces is not None  # a 3D zero set that is not empty has its mesh
    euler = _euler_per_label(faces, zero_set.component_labels, zero_set.n_components)
    is_open = zero_set.component_open
    chi, genus = _euler_genus([int(euler[i]) for i in keep if not is_open[i]])
    return Topology(3, components=len(keep), open=int(is_open[keep].sum()), euler=chi, genus=genus,
                    ignored=int(ignore.sum()))


def _euler_per_label(faces: NDArray, labels: NDArray, n: int) -> NDArray[np.int64]:
    """χ = V − E + F of each component (``labels`` per face) of a triangle mesh."""
    f = np.asarray(faces, dtype=np.int64)
    n_faces = np.bincount(labels, minlength=n)
    vertex_label = np.full(int(f.max()) + 1 if f.size else 0, -1, dtype=np.int64)
    vertex_label[f.ravel()] = np.repeat(labels, 3)
    used = vertex_label[vertex_label >= 0]
    n_vertices = np.bincount(used, minlength=n)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    # one integer per edge: a 1D np.unique is many times faster than one of rows
    first = np.unique(edges[:, 0] * len(vertex_label) + edges[:, 1]) // max(len(vertex_label), 1)
    n_edges = np.bincount(vertex_label[first], minlength=n)
    return (n_vertices - n_edges + n_faces).astype(np.int64)


def _euler_genus(euler: list[int]) -> tuple[tuple[int, ...], tuple[int | None, ...]]:
    """(χ, genus) of closed surfaces, sorted by genus then χ (a genus is None where χ is odd, or
    above 2: not one closed orientable surface, e.g. spheres meeting at a vertex)."""
    genus = [(2 - x) // 2 if x % 2 == 0 and x <= 2 else None for x in euler]
    order = sorted(range(len(euler)), key=lambda i: (_genus_key(genus[i]), euler[i]))
    return tuple(euler[i] for i in order), tuple(genus[i] for i in order)


def _nesting(loops: list[NDArray]) -> tuple[int, ...]:
    """The depth of each closed polyline: how many of the others enclose it (by one of its
    vertices: closed zero-set curves and contour loops do not cross), sorted."""
    from skimage.measure import points_in_poly

    if len(loops) < 2:
        return (0,) * len(loops)
    depth = np.zeros(len(loops), dtype=np.int64)
    probes = np.array([loop[0] for loop in loops])
    for loop in loops:
        inside = points_in_poly(probes, loop)
        # a loop's own first vertex lies on its boundary: never count a loop as inside itself
        inside &= ~np.all(probes == loop[0], axis=1)
        depth += inside
    return tuple(sorted(int(d) for d in depth))


# -- the data -----------------------------------------------------------------------------------

def data_topology(cloud: Cloud, ordered_contour: bool = False) -> Topology:
    """The topology of the shape the data stands for, with its confidence (module notes).

    Kept on ``cloud`` (computed once per cloud and ``ordered_contour``).

    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    >>> ring = np.vstack([np.c_[np.cos(t), np.sin(t)], 0.5 * np.c_[np.cos(t), np.sin(t)][::-1]])
    >>> data_topology(Cloud(ring), ordered_contour=True).describe()
    '2 loops (1 inside another)'
    """
    return cloud.derived("topology", bool(ordered_contour), lambda: _data_topology(cloud, bool(ordered_contour)))


def _data_topology(cloud: Cloud, ordered_contour: bool) -> Topology:
    pts = cloud.points
    if cloud.faces is not None and len(cloud.faces):
        return _mesh_topology(pts, cloud.faces)
    if cloud.dim == 2 and ordered_contour:
        pieces = contour_pieces(pts)
        loops = [np.vstack([pts[a:b], pts[a:a + 1]]) for a, b, closed in pieces if closed]
        arcs = sum(1 for *_, closed in pieces if not closed)
        # an open contour: which closed curve (if any) the polynomial should make is a guess
        return Topology(2, components=len(pieces), open=arcs, nesting=_nesting(loops), source="contour",
                        confidence="high" if not arcs else "low")
    if len(pts) < 10:
        return Topology(cloud.dim, components=0, source="points", confidence="unknown")
    return _points_topology(cloud)


def _mesh_topology(points: NDArray, faces: NDArray) -> Topology:
    """A mesh's components (sharing a vertex position), which are open, χ and genus of each (an
    open one with its holes capped); confidence high when every component is closed and none
    passes through another."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from ..geometry.mesh import merge_duplicates, winding_number

    merged = merge_duplicates(points)  # meshes exported per face repeat their vertices
    f = merged.index[np.asarray(faces)]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    n = len(merged.points)
    rows, cols = np.concatenate([f[:, 0], f[:, 1]]), np.concatenate([f[:, 1], f[:, 2]])
    _, vertex_labels = connected_components(coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n)),
                                            directed=False)
    _, labels = np.unique(vertex_labels[f[:, 0]], return_inverse=True)
    labels = labels.ravel()
    n_comp = int(labels.max()) + 1 if labels.size else 0
    euler = _euler_per_label(f, labels, n_comp)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    border = unique[counts == 1]
    holes = np.zeros(n_comp, dtype=np.int64)
    if len(border):
        # the holes: the cycle rank E − V + 1 of each piece of the border's graph (two holes
        # that touch at a vertex are one piece of it, and two cycles)
        used, inverse = np.unique(border, return_inverse=True)
        inverse = inverse.reshape(border.shape)
        k, loop_labels = connected_components(
            coo_matrix((np.ones(len(border)), (inverse[:, 0], inverse[:, 1])), shape=(len(used), len(used))),
            directed=False)
        rank = np.bincount(loop_labels[inverse[:, 0]], minlength=k) - np.bincount(loop_labels, minlength=k) + 1
        owner = np.full(k, -1, dtype=np.int64)
        owner[loop_labels] = _component_of_vertex(f, labels, n)[used]
        np.add.at(holes, owner, rank)
    is_open = holes > 0
    # capping each hole with a disc adds one face and no edge or vertex: χ + holes
    capped = [int(euler[i] + holes[i]) for i in range(n_comp)]
    confidence = "high" if not is_open.any() else "medium"
    # many parts (a scene, a kit of pieces): which of them a polynomial should keep apart is a guess
    if confidence == "high" and n_comp > 1 and (
            n_comp > MAX_PARTS or _parts_intersect(merged.points, f, labels, n_comp, winding_number)):
        confidence = "low"
    chi, genus = _euler_genus(capped)
    return Topology(3, components=n_comp, open=int(is_open.sum()), euler=chi, genus=genus, source="mesh",
                    confidence=confidence)


def _component_of_vertex(f: NDArray, labels: NDArray, n: int) -> NDArray[np.int64]:
    out = np.full(n, -1, dtype=np.int64)
    out[f.ravel()] = np.repeat(labels, 3)
    return out


def _parts_intersect(points, f, labels, n_comp, winding_number) -> bool:
    """Whether two closed components pass through each other: some vertices of one inside the
    other and some outside (a nested shell, all inside, is a topology of its own)."""
    boxes = []
    for c in range(n_comp):
        v = points[np.unique(f[labels == c])]
        boxes.append((v.min(axis=0), v.max(axis=0), v))
    for a in range(n_comp):
        for b in range(n_comp):
            lo_a, hi_a, va = boxes[a]
            lo_b, hi_b, _ = boxes[b]
            if a == b or np.any(hi_a < lo_b) or np.any(hi_b < lo_a):
                continue
            probe = va[:: max(1, len(va) // 200)]
            inside = np.abs(winding_number(points, f[labels == b], probe)) > 0.5
            if inside.any() and not inside.all():
                return True
    return False


def _points_topology(cloud: Cloud) -> Topology:
    """A bare cloud's estimate at two scales (3 and 6 median spacings): the components of the
    neighbourhood graph (pieces of fewer than 1 % of the points, at least 5, left out as
    strays) and, in 2D, the loops: the holes of the union of discs of that radius around the
    points, with their nesting. Agreeing scales give "medium", else "low"."""
    if len(cloud) > ESTIMATE_POINTS:  # the neighbourhood graph at 6 spacings grows fast: a stride of the points
        cloud = Cloud(cloud.points[:: -(-len(cloud) // ESTIMATE_POINTS)])
    spacing = float(np.median(cloud.spacing))
    if not spacing > 0:
        return Topology(cloud.dim, components=0, source="points", confidence="unknown")
    found = [_estimate_at(cloud, k * spacing) for k in (3.0, 6.0)]
    agree = all(getattr(found[0], k) == getattr(found[1], k) for k in ("components", "open", "nesting"))
    return dataclasses.replace(found[1], confidence="medium" if agree else "low")


def _estimate_at(cloud: Cloud, radius: float) -> Topology:
    from scipy.sparse.csgraph import connected_components

    pts = cloud.points
    graph = cloud.kdtree.sparse_distance_matrix(cloud.kdtree, radius, output_type="coo_matrix")
    _, labels = connected_components(graph, directed=False)
    sizes = np.bincount(labels)
    small = max(5, 0.01 * len(pts))
    n_comp, ignored = int((sizes >= small).sum()), int((sizes < small).sum())
    if cloud.dim == 3:
        return Topology(3, components=n_comp, ignored=ignored, source="points", confidence="medium")
    loops, nesting = _disc_union_holes(pts, radius, labels, sizes >= small)
    # each piece of band around a closed curve encloses a hole; a band with none is an open arc
    return Topology(2, components=n_comp, open=max(0, n_comp - loops), nesting=nesting, ignored=ignored,
                    source="points", confidence="medium")


def _disc_union_holes(pts: NDArray, radius: float, labels: NDArray, kept: NDArray) -> tuple[int, tuple[int, ...]]:
    """The bounded holes of the union of discs of ``radius`` around the kept points, on a raster
    of radius/3, and their nesting (a hole inside the filled outline of another)."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    use = pts[kept[labels]]
    step = radius / 3
    lo = use.min(axis=0) - 2 * radius
    shape = np.ceil((use.max(axis=0) + 2 * radius - lo) / step).astype(int) + 1
    if np.prod(shape) > 4_000_000:  # a cloud far longer than its spacing: coarser raster
        step *= math.sqrt(np.prod(shape) / 4_000_000)
        shape = np.ceil((use.max(axis=0) + 2 * radius - lo) / step).astype(int) + 1
    axes = [lo[j] + step * np.arange(shape[j]) for j in range(2)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    d, _ = cKDTree(use).query(grid, distance_upper_bound=radius)
    solid = np.isfinite(d).reshape(shape)
    background, n_bg = ndimage.label(~solid)
    edge = np.unique(np.concatenate([background[0], background[-1], background[:, 0], background[:, -1]]))
    holes = [h for h in range(1, n_bg + 1) if h not in set(edge.tolist())]
    # holes of a few raster cells are gaps between samples, not loops
    areas = ndimage.sum_labels(np.ones_like(background), background, holes) if holes else []
    holes = [h for h, a in zip(holes, areas, strict=True) if a >= 9]
    filled = [ndimage.binary_fill_holes(background == h) for h in holes]
    probes = [np.argwhere(background == h)[0] for h in holes]
    depth = [sum(1 for j, g in enumerate(filled) if j != i and g[tuple(p)]) for i, p in enumerate(probes)]
    return len(holes), tuple(sorted(depth))


# -- where the zero set's inside and the data's disagree -----------------------------------------

def topology_samples(poly: ImplicitPolynomial, cloud: Cloud, *, ordered_contour: bool = False, most: int = 400,
                     margin: float = 0.25, far: float | None = None) -> NDArray[np.float64]:
    """Up to ``most`` places where the inside of ``poly`` (the sign it has on most of the data's
    inside) disagrees with the data's where that changes the topology: the neck of a thin part
    the zero set cut off (inside for the data), a bridge the zero set threw across a gap, a
    loop in a gap or a hole in the solid (outside, or inside, for the data). Empty when the
    data's inside is not known (it is for an ordered contour of closed loops and a closed mesh).

    On a raster over the data's box, a region of disagreement matters when it touches two
    pieces of the polynomial's inside (a cut neck) or of its outside (a bridge), or two pieces of
    the data's other side (a cut through the solid between two of its boundaries, an envelope
    round two parts), or when it is a whole piece of the polynomial's inside or outside (an extra
    loop, an extra hole), or, in 3D, when turning it changes the raster's Euler number (a handle
    or a tunnel the data has not, which joins no pieces: homer's feet bridged); bands along the
    data where the zero set is merely a little off do not.
    Each region that matters gets an equal share of the places, those farthest from the data
    first (the middle of a neck or of a gap).

    With ``far`` (a distance), up to ``most`` more places: every node of the raster where the
    two insides disagree farther than ``far`` from the data, evenly thinned. Which regions change
    the topology is a judgement on a raster; where a zero set crosses itself or runs in a thin
    gap the regions found are too small to move it, and holding every clear disagreement does
    (the horse silhouette's degree 14, whose hind legs cross and whose front legs enclose a loop:
    ``tests/test_topology.py`` fits it under several seeds).
    """
    inside, nodes, _ = _data_inside(cloud, ordered_contour, margin)
    if inside is None:
        return np.empty((0, cloud.dim))
    from scipy import ndimage

    values = grid_values(poly, _box(nodes), inside.shape)
    negative = values < 0
    # the polynomial's inside is the sign it has where the data is inside (most of it)
    f_inside = negative if np.mean(negative[inside]) >= 0.5 else ~negative
    structure = ndimage.generate_binary_structure(cloud.dim, 1)
    in_labels, _ = ndimage.label(f_inside, structure)
    out_labels, _ = ndimage.label(~f_inside, structure)
    data_in, _ = ndimage.label(inside, structure)
    data_out, _ = ndimage.label(~inside, structure)
    regions = []
    # data inside, polynomial outside (a cut neck, a cut through the solid, an extra hole); data
    # outside, polynomial inside (a bridge across a gap, an envelope round two parts, an extra loop):
    # ``same`` labels the polynomial's side the region is on, ``other`` its other side, ``across``
    # the data's other side
    for wrong, same, other, across in ((inside & ~f_inside, out_labels, in_labels, data_out),
                                       (~inside & f_inside, in_labels, out_labels, data_in)):
        labels, _ = ndimage.label(wrong, structure)
        for r, where in enumerate(ndimage.find_objects(labels), start=1):
            if where is None:
                continue
            # a box around the region grown by one node: its neighbours
            grown = tuple(slice(max(0, sl.start - 1), sl.stop + 1) for sl in where)
            mask = labels[grown] == r
            ring = ndimage.binary_dilation(mask, structure) & ~mask
            touches = np.unique(other[grown][ring])
            joins = np.unique(across[grown][ring])
            piece = np.unique(same[grown][mask])
            whole = len(piece) == 1 and int(np.count_nonzero(same == piece[0])) == int(mask.sum())
            if len(touches[touches > 0]) >= 2 or len(joins[joins > 0]) >= 2 or whole or \
                    (cloud.dim == 3 and _changes_euler(f_inside[grown], mask)):
                idx = np.argwhere(mask) + [sl.start for sl in grown]
                regions.append(idx)
    places = _spread_places(regions, nodes, cloud, most)
    if far is None:
        return places
    wrong = np.argwhere(inside != f_inside)
    at = np.column_stack([nodes[j][wrong[:, j]] for j in range(cloud.dim)])
    clear = at[cloud.kdtree.query(at)[0] > far]
    if len(clear) > most:  # evenly over the raster's order: every part of every region keeps some
        clear = clear[np.linspace(0, len(clear) - 1, most).astype(np.int64)]
    return np.concatenate([places, clear])


def _changes_euler(solid: NDArray, region: NDArray) -> bool:
    """Whether turning ``region`` to the other side changes the Euler number of ``solid`` (a box
    one node wider than the region all round: the Euler number is a sum over 2×2×2 windows, and
    only the windows in the box see the region, so the box's change is the whole raster's)."""
    from skimage.measure import euler_number

    turned = solid.copy()
    turned[region] = ~turned[region]
    return bool(euler_number(solid, connectivity=1) != euler_number(turned, connectivity=1))


def _spread_places(regions: list[NDArray], nodes: list[NDArray], cloud: Cloud, most: int) -> NDArray[np.float64]:
    """An equal share of ``most`` places per region (raster indices), farthest from the data first."""
    if not regions:
        return np.empty((0, cloud.dim))
    share = max(1, most // len(regions))
    out = []
    for idx in regions:
        at = np.column_stack([nodes[j][idx[:, j]] for j in range(cloud.dim)])
        d, _ = cloud.kdtree.query(at)
        out.append(at[np.argsort(-d, kind="stable")[:share]])
    return np.concatenate(out)[:most]


def _box(nodes: list[NDArray]) -> NDArray:
    return np.array([[ax[0], ax[-1]] for ax in nodes])


def _data_inside(cloud: Cloud, ordered_contour: bool, margin: float):
    """(inside mask on a raster, its axes, its step), or (None, None, None) when unknown; kept
    on the cloud (the data's, the same for every degree and repair round)."""
    return cloud.derived("topology_inside", (bool(ordered_contour), float(margin)),
                         lambda: _data_inside_now(cloud, ordered_contour, margin))


def _data_inside_now(cloud: Cloud, ordered_contour: bool, margin: float):
    topo = data_topology(cloud, ordered_contour)
    if topo.confidence != "high" or topo.open:
        return None, None, None
    box = data_bounds(cloud.points, margin)
    if cloud.dim == 2:
        from skimage.measure import points_in_poly

        nodes = grid_axes(box, _raster_shape(box, 400))
        grid = np.stack(np.meshgrid(*nodes, indexing="ij"), axis=-1).reshape(-1, 2)
        parity = np.zeros(len(grid), dtype=bool)
        for a, b, _ in contour_pieces(cloud.points):
            parity ^= points_in_poly(grid, cloud.points[a:b])
        shape = tuple(len(ax) for ax in nodes)
        return parity.reshape(shape), nodes, float(max(ax[1] - ax[0] for ax in nodes))
    from ..geometry.mesh import winding_number

    assert cloud.faces is not None  # a high-confidence 3D topology is a closed mesh's
    if len(cloud.faces) > MAX_INSIDE_FACES:
        return None, None, None
    nodes = grid_axes(box, _raster_shape(box, 28))
    grid = np.stack(np.meshgrid(*nodes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = np.abs(winding_number(cloud.points, cloud.faces, grid)) > 0.5
    return inside.reshape(tuple(len(ax) for ax in nodes)), nodes, float(max(ax[1] - ax[0] for ax in nodes))


def _raster_shape(box: NDArray, n: int) -> tuple[int, ...]:
    sides = box[:, 1] - box[:, 0]
    step = float(sides.max()) / (n - 1)
    return tuple(int(max(2, math.ceil(s / step) + 1)) for s in sides)

"""Topology of zero sets and of the data, on shapes whose topology is known by construction."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ipfit import Cloud
from ipfit.datasets import synthetic
from ipfit.degree.results import validate_result
from ipfit.degree.rules import CaptureRule
from ipfit.geometry.distance import contour_pieces
from ipfit.zeroset.extract import extract_zero_set
from ipfit.zeroset.quality import quality
from ipfit.zeroset.topology import Topology, data_topology, describe_mismatch, zero_set_topology


def _times(a: dict, b: dict) -> dict:
    out: dict = {}
    for ea, ca in a.items():
        for eb, cb in b.items():
            e = tuple(i + j for i, j in zip(ea, eb, strict=True))
            out[e] = out.get(e, 0.0) + ca * cb
    return out


def _plus(*terms: dict) -> dict:
    out: dict = {}
    for t in terms:
        for e, c in t.items():
            out[e] = out.get(e, 0.0) + c
    return out


def _circle_terms(r: float, cx: float = 0.0) -> dict:
    # (x - cx)² + y² - r²
    return {(2, 0): 1.0, (1, 0): -2 * cx, (0, 2): 1.0, (0, 0): cx * cx - r * r}


def _ring(n: int = 200, radii=(1.0, 0.5)) -> np.ndarray:
    """An annulus outline as an ordered contour: the outer circle counter-clockwise, then the
    inner one clockwise (a hole), one after the other."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    outer = radii[0] * np.c_[np.cos(t), np.sin(t)]
    inner = radii[1] * np.c_[np.cos(t), np.sin(t)][::-1]
    return np.vstack([outer, inner])


def test_contour_pieces_split_at_the_jump_between_loops():
    ring = _ring()
    assert contour_pieces(ring) == [(0, 200, True), (200, 400, True)]
    # one loop, its closing gap as short as the others: one closed piece
    assert contour_pieces(ring[:200]) == [(0, 200, True)]
    # half a circle: its closing gap is the diameter, an open arc
    assert contour_pieces(ring[:100]) == [(0, 100, False)]


def test_annulus_outline_has_two_nested_loops_and_its_polynomial_matches():
    ring = _ring()
    data = data_topology(Cloud(ring), ordered_contour=True)
    assert (data.loops, data.open, data.nesting, data.confidence) == (2, 0, (0, 1), "high")
    assert data.describe() == "2 loops (1 inside another)"
    annulus = synthetic.from_terms(2, 4, _times(_circle_terms(1.0), _circle_terms(0.5)))
    q = quality(annulus, ring, ordered_contour=True)
    assert q.f_score == 1.0
    assert q.topology.nesting == (0, 1) and q.topology_matches is True
    # two circles side by side: two loops too, but neither inside the other
    pair = synthetic.from_terms(2, 4, _times(_circle_terms(0.4, -0.5), _circle_terms(0.4, 0.5)))
    side = zero_set_topology(extract_zero_set(pair, bounds=[[-1.5, 1.5], [-1.5, 1.5]]))
    assert side.nesting == (0, 0) and data.matches(side) is False
    assert describe_mismatch(side, data).startswith("2 loops nested (depths 0, 0)")
    # a single circle: one loop where the data has two
    one = zero_set_topology(extract_zero_set(synthetic.circle().polynomial, bounds=[[-2, 2], [-2, 2]]))
    assert describe_mismatch(one, data) == "1 loop where the data has 2"


def test_bare_annulus_cloud_is_estimated_with_medium_confidence():
    rng = np.random.default_rng(3)
    ring = _ring(300)
    shuffled = ring[rng.permutation(len(ring))]
    estimate = data_topology(Cloud(shuffled))
    assert (estimate.loops, estimate.open, estimate.nesting) == (2, 0, (0, 1))
    assert estimate.confidence == "medium" and not estimate.known
    # an arc: no loop, one open piece
    arc = ring[:100][rng.permutation(100)]
    estimate = data_topology(Cloud(arc))
    assert (estimate.loops, estimate.open) == (0, 1)


def test_data_topology_is_kept_on_the_cloud():
    cloud = Cloud(_ring())
    assert data_topology(cloud, True) is data_topology(cloud, True)
    assert data_topology(cloud, False) is not data_topology(cloud, True)


def _genus_two() -> synthetic.ImplicitPolynomial:
    """((x² + y²)² − x² + y²)² + z² − c: a tube around Bernoulli's lemniscate (a figure eight),
    whose two lobes make a surface of genus 2."""
    g = {(4, 0, 0): 1.0, (2, 2, 0): 2.0, (0, 4, 0): 1.0, (2, 0, 0): -1.0, (0, 2, 0): 1.0}
    return synthetic.from_terms(3, 8, _plus(_times(g, g), {(0, 0, 2): 1.0, (0, 0, 0): -0.005}))


def test_genus_two_surface_has_euler_characteristic_minus_two():
    zs = extract_zero_set(_genus_two(), bounds=[[-1.4, 1.4], [-0.7, 0.7], [-0.3, 0.3]], resolution=112)
    t = zero_set_topology(zs)
    assert (t.components, t.open, t.euler, t.genus) == (1, 0, (-2,), (2,))
    assert t.describe() == "1 surface (genus 2)"


@pytest.mark.parametrize("shape, euler, genus", [("sphere", 2, 0), ("torus", 0, 1)])
def test_sphere_and_torus(shape, euler, genus):
    s = getattr(synthetic, shape)()
    t = zero_set_topology(extract_zero_set(s.polynomial, points=s.points, resolution=48))
    assert (t.components, t.euler, t.genus) == (1, (euler,), (genus,))


def test_mesh_topology_components_genus_and_confidence():
    import trimesh

    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    t = data_topology(Cloud(torus.vertices, faces=torus.faces))
    assert (t.components, t.open, t.genus, t.confidence) == (1, 0, (1,), "high")
    a, b = trimesh.creation.icosphere(2), trimesh.creation.icosphere(2)
    apart = trimesh.util.concatenate([a, b.apply_translation([3.0, 0, 0])])
    t = data_topology(Cloud(apart.vertices, faces=apart.faces))
    assert (t.components, t.genus, t.confidence) == (2, (0, 0), "high")
    # two spheres passing through each other bound one solid: the parts' count is no guide
    c = trimesh.creation.icosphere(2)
    crossing = trimesh.util.concatenate([trimesh.creation.icosphere(2), c.apply_translation([1.0, 0, 0])])
    assert data_topology(Cloud(crossing.vertices, faces=crossing.faces)).confidence == "low"
    # a sphere with a hole: open, its genus with the hole capped
    sphere = trimesh.creation.icosphere(2)
    holed = Cloud(sphere.vertices, faces=sphere.faces[5:])
    t = data_topology(holed)
    assert (t.components, t.open, t.genus, t.confidence) == (1, 1, (0,), "medium")


def test_open_mesh_is_compared_as_the_closed_surface_its_capped_holes_bound():
    import trimesh

    sphere = trimesh.creation.icosphere(3)
    data = data_topology(Cloud(sphere.vertices, faces=sphere.faces[8:]))  # a sphere with a hole
    assert data.capped and (data.components, data.open, data.genus) == (1, 1, (0,))
    box = [[-1.5, 1.5]] * 3
    closed = zero_set_topology(extract_zero_set(synthetic.sphere().polynomial, bounds=box, resolution=40))
    assert (closed.open, closed.genus) == (0, (0,))
    assert data.matches(closed) is True and describe_mismatch(closed, data) == ""
    # a plane through the box is open where the box cuts it: not the closed surface the mesh bounds
    plane = synthetic.from_terms(3, 2, {(0, 0, 1): 1.0, (0, 0, 0): -0.1})
    cut = zero_set_topology(extract_zero_set(plane, bounds=box, resolution=40))
    assert (cut.components, cut.open, cut.genus) == (1, 1, ())
    assert data.matches(cut) is False
    assert describe_mismatch(cut, data) == "1 open surface where the data (estimated) has none, its holes capped"
    # a mesh closed as given is compared as it is, openness included
    whole = data_topology(Cloud(sphere.vertices, faces=sphere.faces))
    assert not whole.capped and describe_mismatch(cut, whole) == "1 open surface where the data has none"


def test_a_mesh_component_of_unknown_genus_matches_any_genus_but_not_another_count():
    # a closed mesh whose χ is odd (a pinched vertex, a non-orientable part) leaves its genus open
    data = Topology(3, 2, euler=(1, 2), genus=(None, 0), source="mesh", confidence="high")
    assert data.matches(Topology(3, 2, euler=(2, 2), genus=(0, 0))) is True
    assert data.matches(Topology(3, 2, euler=(0, 2), genus=(0, 1))) is True
    assert data.matches(Topology(3, 2, euler=(0, 0), genus=(1, 1))) is False  # the known genus 0 is missing
    assert data.matches(Topology(3, 1, euler=(2,), genus=(0,))) is False
    assert data.matches(Topology(3, 3, euler=(2, 2, 2), genus=(0, 0, 0))) is False
    # known genera are compared as before
    torus = Topology(3, 1, euler=(0,), genus=(1,), source="mesh", confidence="high")
    assert torus.matches(Topology(3, 1, euler=(0,), genus=(1,))) is True
    assert torus.matches(Topology(3, 1, euler=(2,), genus=(0,))) is False


def test_a_chain_of_spheres_meeting_at_vertices_has_no_genus():
    """Three closed spheres in a row, each touching the next at one shared vertex: one connected
    mesh of χ = 3 · 2 − 2 = 4, which no closed orientable surface has (its genus would be −1):
    the genus is unknown."""
    import trimesh

    from ipfit.zeroset.topology import _mesh_topology

    s = trimesh.creation.icosphere(1)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    right, left = int(np.argmax(v[:, 0])), int(np.argmin(v[:, 0]))
    n = len(v)
    # the middle sphere's leftmost vertex is the left one's rightmost, and so on to the right
    shift = v[right] - v[left]
    vertices = np.vstack([v - shift, v, v + shift])
    faces = np.vstack([f, f + n, f + 2 * n])
    faces[faces == right] = n + left          # left sphere's right pole -> middle's left pole
    faces[faces == n + right] = 2 * n + left  # middle's right pole -> right sphere's left pole
    topo = _mesh_topology(vertices, faces)
    assert topo.components == 1 and topo.open == 0 and topo.euler == (4,) and topo.genus == (None,)


def test_bare_3d_cloud_counts_components():
    s = synthetic.sphere(400)
    two = np.vstack([s.points, s.points + [4.0, 0.0, 0.0]])  # 2 apart: wider than 6 spacings
    t = data_topology(Cloud(two))
    assert (t.components, t.genus, t.confidence) == (2, (), "medium")
    # the genus of a bare cloud is not estimated, so it is not compared
    assert t.matches(Topology(3, 2, euler=(0, 2), genus=(0, 1))) is True
    assert t.matches(Topology(3, 1, euler=(2,), genus=(0,))) is False


def test_quality_reports_topology_in_the_json_and_ignores_only_specks():
    ring = _ring()
    annulus = synthetic.from_terms(2, 4, _times(_circle_terms(1.0), _circle_terms(0.5)))
    q = quality(annulus, ring, ordered_contour=True)
    out = json.loads(json.dumps(q.to_dict()))
    assert out["topology"]["loops"] == 2 and out["data_topology"]["source"] == "contour"
    assert out["topology_matches"] is True
    validate_result({"format": "ipfit", "version": 2, "exponents": annulus.exponents.tolist(),
                     "coefficients": annulus.coefficients.tolist(), "quality": out})
    # a tiny oval just off the data is a speck: left out; the same oval far away is a loop
    for center, counted in ((1.09, False), (1.6, True)):  # tau is 0.057: between tau and 2 tau, or far
        tiny = synthetic.from_terms(2, 6, _times(_times(_circle_terms(1.0), _circle_terms(0.5)),
                                                 _circle_terms(0.004, center)))
        q = quality(tiny, ring, ordered_contour=True, bounds=[[-2, 2], [-2, 2]], resolution=2001)
        assert q.n_components == 3
        assert q.topology.loops == (3 if counted else 2)
        assert q.topology.ignored == (0 if counted else 1)


# -- silhouettes and contour files of several loops -------------------------------------------------

FIXTURES = __import__("pathlib").Path(__file__).parent / "data"


def _ring_image(tmp_path, island: bool = False):
    from PIL import Image

    yy, xx = np.mgrid[:120, :140]
    r = np.hypot(xx - 70.0, yy - 60.0)
    shape = (r < 50) & (r > 25)
    if island:  # a disc inside the hole: another shape, not part of the ring
        shape |= r < 10
    path = tmp_path / "ring.png"
    Image.fromarray(np.where(shape, 0, 255).astype(np.uint8)).save(path)
    return path


def _signed_area(p):
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


@pytest.mark.parametrize("island", [False, True])
def test_silhouette_with_a_hole_reads_outline_and_hole_oriented(tmp_path, island):
    from ipfit import load

    cloud = load(_ring_image(tmp_path, island))
    pieces = contour_pieces(cloud.points)
    assert [closed for *_, closed in pieces] == [True, True]
    (a, b, _), (c, d, _) = pieces
    outer, hole = cloud.points[a:b], cloud.points[c:d]
    center = np.array([70.0, -60.0])
    assert np.allclose(np.linalg.norm(outer - center, axis=1), 50, atol=1.0)
    assert np.allclose(np.linalg.norm(hole - center, axis=1), 25, atol=1.0)
    assert _signed_area(outer) > 0 > _signed_area(hole)  # counter-clockwise outline, clockwise hole
    # normals point out of the solid: away from the centre on the outline, towards it on the hole
    radial = np.einsum("ij,ij->i", cloud.normals, cloud.points - center)
    assert np.all(radial[a:b] > 0) and np.all(radial[c:d] < 0)
    t = data_topology(cloud, ordered_contour=True)
    assert (t.loops, t.nesting, t.confidence) == (2, (0, 1), "high")
    alone = load(_ring_image(tmp_path, island), largest_outline=True)
    np.testing.assert_array_equal(alone.points, outer)
    assert data_topology(alone, ordered_contour=True).loops == 1


def test_horse_and_ampersand_fixtures():
    from ipfit import load

    horse = data_topology(load(FIXTURES / "horse.png"), ordered_contour=True)
    assert (horse.loops, horse.open) == (1, 0)
    # DejaVu Sans Bold's "&" has one counter: its outline and one hole
    glyph = data_topology(load(FIXTURES / "ampersand.png"), ordered_contour=True)
    assert (glyph.loops, glyph.nesting) == (2, (0, 1))
    assert load(FIXTURES / "ampersand.png", largest_outline=True).n_file < load(FIXTURES / "ampersand.png").n_file


@pytest.mark.parametrize("separator", ["\n", "nan,nan,nan,nan\n"])
def test_contour_file_of_several_loops(tmp_path, separator):
    from ipfit import read_points

    ring = _ring()
    normals = np.vstack([ring[:200], -ring[200:] / 0.5])  # outward of the solid: into the hole
    rows = np.hstack([ring, normals])
    lines = [",".join(repr(float(v)) for v in row) + "\n" for row in rows]
    text = "x,y,nx,ny\n" + "".join(lines[:200]) + separator + "".join(lines[200:])
    path = tmp_path / "ring.csv"
    path.write_text(text)
    cloud = read_points(path)
    assert [(b - a, closed) for a, b, closed in contour_pieces(cloud.points)] == [(200, True), (200, True)]
    # the same rows, each with its normal, only the hole started elsewhere
    got = sorted(map(tuple, np.hstack([cloud.points, cloud.normals]).round(9)))
    assert got == sorted(map(tuple, rows.round(9)))
    np.testing.assert_array_equal(cloud.points[:200], ring[:200])


# -- in the rule ----------------------------------------------------------------------------------

def _dumbbell(w: float = 0.2, r: float = 1.0, c: float = 2.0, step: float = 0.03) -> np.ndarray:
    """Two unit discs at x = ±2 joined by a bar of half-width ``w``: an ordered outline."""
    a, t0 = np.sqrt(r * r - w * w), np.arcsin(w / r)
    arc = np.linspace(np.pi - t0, -np.pi + t0, 400)
    dense = np.vstack([np.c_[np.linspace(-c + a, c - a, 200), np.full(200, w)],
                       np.c_[c + r * np.cos(arc), r * np.sin(arc)],
                       np.c_[np.linspace(c - a, -c + a, 200), np.full(200, -w)],
                       np.c_[-c - r * np.cos(arc), -r * np.sin(arc)]])
    closed = np.vstack([dense, dense[:1]])
    s = np.r_[0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    at = np.arange(0, s[-1], step)
    return np.c_[np.interp(at, s, closed[:, 0]), np.interp(at, s, closed[:, 1])]


def _neck_broken(poly) -> bool:
    """The zero set cuts the bar: f has another sign at the neck's middle than in the discs."""
    f = poly([[0.0, 0.0], [2.0, 0.0], [-2.0, 0.0]])
    return bool(np.sign(f[0]) != np.sign(f[1]) and np.sign(f[1]) == np.sign(f[2]))


def test_dumbbell_whose_neck_a_low_degree_breaks(seed):
    # (holds for seeds 0-5: IPFIT_TEST_SEED)
    from ipfit import fit_adaptive
    from ipfit.normals import contour_normals

    points = _dumbbell()
    normals = contour_normals(points)
    # the default capture rule reports the topology; the "topology" rule also holds it
    blind = fit_adaptive(points, normals, max_degree=6, ordered_contour=True, rng=seed)
    four = blind.at_degree(4)
    # the reported topology agrees with the polynomial's signs: two loops where the neck is cut
    assert _neck_broken(four.polynomial) and four.quality.topology.loops == 2
    assert four.quality.topology_matches is False and not four.cleanup  # blind: nothing to repair
    result = fit_adaptive(points, normals, max_degree=6, ordered_contour=True, rule="topology", rng=seed)
    repaired = result.at_degree(4)
    assert repaired.cleanup and repaired.cleanup[0]["target"] == "topology"  # its fit had two loops too
    for entry in result.degrees:
        loops = entry.quality.topology.loops
        assert (loops == 2) == _neck_broken(entry.polynomial) or loops not in (1, 2)
        if entry.quality.topology_matches is False:
            assert entry.reason.startswith("rejected") and "loops where the data has 1" in entry.reason
    chosen = result.at_degree(result.selected_degree)
    assert chosen.quality.topology.loops == 1 and not _neck_broken(chosen.polynomial)
    assert chosen.quality.f_score >= 0.99 and result.success


def test_the_paper_rule_measures_nothing_and_the_topology_rule_checks_topology():
    from ipfit.degree.rules import CAPTURE, GEOMETRIC, PAPER, RULES, TOPOLOGY, is_clean

    assert (PAPER.measured, PAPER.checks_topology) == (False, False)
    # the default prefers the data's topology where that costs no F-score; the "topology" rule holds it
    assert not CAPTURE.checks_topology and not GEOMETRIC.checks_topology
    assert CAPTURE.prefers_topology and not TOPOLOGY.prefers_topology and not PAPER.prefers_topology
    assert TOPOLOGY.checks_topology and RULES["topology"] is TOPOLOGY
    ring = _ring()
    pair = synthetic.from_terms(2, 4, _times(_circle_terms(0.4, -0.5), _circle_terms(0.4, 0.5)))
    q = quality(pair, ring, ordered_contour=True)  # two loops side by side where the data nests them
    assert q.topology_matches is False
    assert not is_clean(q) and not is_clean(q, ignore_specks=False) and not TOPOLOGY.is_clean(q)
    assert CAPTURE.is_clean(q)  # the default rule reports it and lets it pass
    # a bare cloud's estimate is reported but never held against a zero set: two circles closer
    # than the estimate's scales look like one band (one loop) to it
    close = _ring(300, radii=(1.0, 0.97))
    both = synthetic.from_terms(2, 4, _times(_circle_terms(1.0), _circle_terms(0.97)))
    q = quality(both, close[np.random.default_rng(0).permutation(len(close))])
    assert (q.data_topology.loops, q.data_topology.confidence, q.topology.loops) == (1, "medium", 2)
    assert q.topology_matches is False and TOPOLOGY.is_clean(q) and GEOMETRIC.is_clean(q)


def test_the_default_gives_the_horse_one_loop_at_no_cost_in_f_score(seed):
    # scikit-image's horse: the capture rule's choice (degree 14) had 3-5 loops under seeds 0-4
    # (a loop between the front legs, the hind legs crossing); the default now repairs it to one
    # loop within the rule's tolerance of the best F-score where such a repair exists (F
    # 0.989-0.998 under seeds 0-4 on an Intel Xeon), and keeps the F-score either way.
    from ipfit import fit_adaptive, load
    from ipfit.degree.rules import TOLERANCE, CaptureRule

    class Blind(CaptureRule):
        prefers_topology = False

    horse = load(FIXTURES / "horse.png")
    result = fit_adaptive(horse, rng=seed)
    selected = result.at_degree(result.selected_degree)
    chosen = selected.quality
    assert chosen.f_score >= 0.98 and result.success
    blind = fit_adaptive(horse, rng=seed, rule=Blind())
    best = max(d.quality.f_score for d in blind.degrees if Blind().is_clean(d.quality))
    assert chosen.f_score >= best - TOLERANCE
    if not chosen.topology_matches:
        # Not every BLAS kernel gets there: with OpenBLAS's Haswell kernel on an AMD EPYC (seeds
        # 0-2) degree 14 keeps a small second loop, and no repair round with one loop comes within
        # the tolerance (F 0.72-0.86 at the far-field weight that removes the loop; issue 31). The
        # rule may keep the loop only then: every repair round that matched fell below it.
        rounds = [a for a in selected.cleanup if a["target"] == "topology"]
        assert rounds and all(a["f_score"] < best - TOLERANCE for a in rounds if a["topology_matches"])
    else:
        assert chosen.topology.loops == 1
    # the same path of degrees: the preference only chooses, and repairs, after the loop, save one
    # degree beyond the rule's stop when no degree within the tolerance had one loop (the Haswell
    # kernel, seeds 1-2: degree 16 after the stop at 14), which the message names
    path, blind_path = [d.degree for d in result.degrees], [d.degree for d in blind.degrees]
    assert path[:len(blind_path)] == blind_path and len(path) <= len(blind_path) + 1
    if len(path) > len(blind_path):
        assert f"degree {path[-1]} was tried after the rule had stopped at degree {blind_path[-1]}" in result.message
    if blind.at_degree(blind.selected_degree).quality.topology_matches is False:
        repaired = result.at_degree(result.selected_degree)
        if chosen.topology_matches and repaired.degree == blind.selected_degree:
            assert any(a["topology_matches"] for a in repaired.cleanup)   # the repair's rounds are recorded
        elif chosen.topology_matches:  # another degree already had the data's topology: the message says so
            assert "with the data's topology" in result.message


@pytest.mark.slow
def test_ampersand_fits_as_its_outline_and_hole(tmp_path):
    from ipfit.cli import main

    prefix = tmp_path / "amp"
    assert main(["fit", str(FIXTURES / "ampersand.png"), "-o", str(prefix), "--no-picture", "--no-zero-set",
                 "--rule", "topology", "-q"]) == 0
    quality = json.loads(prefix.with_suffix(".json").read_text())["quality"]
    assert quality["topology"]["nesting"] == [0, 1] and quality["topology_matches"] is True
    assert quality["f_score"] >= 0.98  # 0.998 with seed 0 (docs/topology.md)


def test_topology_samples_find_the_neck_and_the_envelope():
    import trimesh

    from ipfit.zeroset.topology import topology_samples

    # 2D: a dumbbell outline and two circles in its discs (the neck cut): the places are in the bar
    points = _dumbbell()
    pair = synthetic.from_terms(2, 4, _times(_circle_terms(1.0, -2.0), _circle_terms(1.0, 2.0)))
    places = topology_samples(pair, Cloud(points), ordered_contour=True)
    assert len(places) and np.all(np.abs(places[:, 0]) < 1.1) and np.all(np.abs(places[:, 1]) < 0.2)
    # the dumbbell's own outline as a zero set of the right topology: nothing to hold
    one = synthetic.from_terms(2, 2, {(2, 0): 1 / 9, (0, 2): 1.0, (0, 0): -1.0})  # one loop through the discs
    assert quality(one, points, ordered_contour=True).topology_matches is True
    assert len(topology_samples(one, Cloud(points), ordered_contour=True)) == 0
    # with ``far``: every clear disagreement too (the bar's middle, beyond 0.1 from its sides),
    # each farther than ``far`` from the data, where the dumbbell is inside and the pair outside
    from skimage.measure import points_in_poly

    wide = topology_samples(pair, Cloud(points), ordered_contour=True, far=0.1)
    assert len(wide) > len(places) and np.array_equal(wide[: len(places)], places)
    extra = wide[len(places):]
    gap, _ = Cloud(points).kdtree.query(extra)
    assert np.all(gap > 0.1) and np.all(points_in_poly(extra, points)) and np.all(pair(extra) * pair([[2.0, 0]]) < 0)
    assert len(extra) <= 400
    # 3D: two spheres apart, one ellipsoid round both (an envelope): the places lie outside both
    a, b = trimesh.creation.icosphere(2), trimesh.creation.icosphere(2)
    mesh = trimesh.util.concatenate([a.apply_translation([-1.5, 0, 0]), b.apply_translation([1.5, 0, 0])])
    envelope = synthetic.from_terms(3, 2, {(2, 0, 0): 1 / 6.25, (0, 2, 0): 1 / 1.44, (0, 0, 2): 1 / 1.44,
                                           (0, 0, 0): -1.0})
    cloud = Cloud(mesh.vertices, faces=mesh.faces)
    assert data_topology(cloud).components == 2
    places = topology_samples(envelope, cloud)
    assert len(places)
    assert np.all(np.minimum(np.linalg.norm(places - [-1.5, 0, 0], axis=1),
                             np.linalg.norm(places - [1.5, 0, 0], axis=1)) > 1.0)


def _c_shaped_torus(gap: float = 0.25, major: float = 1.0, minor: float = 0.3, step: float = 0.04):
    """A closed mesh of a solid torus cut through at x < 0, |y| < ``gap`` (a 'C': genus 0), from
    marching cubes on the larger of the torus' and the cut's signed distances."""
    from skimage.measure import marching_cubes

    axis = np.arange(-1.6, 1.6 + step / 2, step)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    tube = np.hypot(np.hypot(x, y) - major, z) - minor
    cut = np.where(x < 0, gap - np.abs(y), -np.inf)
    verts, faces, _, _ = marching_cubes(np.maximum(tube, cut), 0.0, spacing=(step,) * 3)
    return verts + axis[0], faces


def test_topology_samples_find_a_handle_the_data_has_not():
    """A whole torus fitted to a C (the torus cut through): the zero set joins the C's ends into
    a handle, which changes no count of pieces, only the genus; the places are in the cut."""
    from ipfit.zeroset.topology import topology_samples

    torus = synthetic.torus(major=1.0, minor=0.3).polynomial
    verts, faces = _c_shaped_torus()
    c_shape = Cloud(verts, faces=faces)
    data = data_topology(c_shape)
    assert (data.components, data.genus, data.confidence) == (1, (0,), "high")
    assert quality(torus, c_shape).topology.genus == (1,)
    places = topology_samples(torus, c_shape)
    assert len(places)
    assert np.all(places[:, 0] < 0) and np.all(np.abs(places[:, 1]) < 0.25 + 0.1)
    assert np.all(np.abs(np.hypot(places[:, 0], places[:, 1]) - 1.0) < 0.3 + 0.1)
    # the same torus against a whole torus mesh: nothing to hold
    verts, faces = _c_shaped_torus(gap=0.0)
    assert len(topology_samples(torus, Cloud(verts, faces=faces))) == 0


@pytest.mark.parametrize("where, changes", [("ring", True), ("cavity", True), ("bump", False), ("notch", False)])
def test_turning_a_region_changes_the_euler_number_exactly_when_the_raster_says_so(where, changes):
    """Whether turning a region changes the Euler number, judged on the region's box one node
    wider, as on the whole raster: a handle cut or a cavity made does, a bump or a notch does not."""
    from skimage.measure import euler_number

    from ipfit.zeroset.topology import _changes_euler

    n = 24
    x, y, z = np.meshgrid(*(np.linspace(-1.5, 1.5, n),) * 3, indexing="ij")
    tube = np.hypot(np.hypot(x, y) - 1.0, z)
    solid = tube < 0.4  # a solid torus: Euler number 0
    region = np.zeros_like(solid)
    if where == "ring":  # a cross-section of the ring taken out: a bent cylinder (Euler number 1)
        region[n // 2 - 1:n // 2 + 1, :n // 3] = solid[n // 2 - 1:n // 2 + 1, :n // 3]
    else:
        near = {"cavity": solid & (tube < 0.15), "bump": ~solid & (np.abs(tube - 0.45) < 0.05),
                "notch": solid & (np.abs(tube - 0.35) < 0.06)}[where]
        region[tuple(np.argwhere(near)[0])] = True
    turned = solid ^ region
    assert (euler_number(turned, connectivity=1) != euler_number(solid, connectivity=1)) == changes
    box = tuple(slice(max(0, a.min() - 1), a.max() + 2) for a in np.nonzero(region))
    assert _changes_euler(solid[box], region[box]) == changes


class _StopsAtFour(CaptureRule):
    """The capture rule, stopping after degree 4."""

    def stop(self, results, epsilon):
        return "flattened" if results[-1].degree >= 4 else None


def _circles(k: int, radius: float, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """``k`` circles of radius 0.4 with centres evenly on a circle of ``radius``: points, normals."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t)]
    angles = 2 * np.pi * np.arange(k) / k
    centers = radius * np.c_[np.cos(angles), np.sin(angles)]
    return np.vstack([c + 0.4 * circle for c in centers]), np.tile(circle, (k, 1))


def test_a_degree_beyond_the_stop_is_tried_when_the_stop_keeps_another_topology(seed):
    # (holds for seeds 0-5: IPFIT_TEST_SEED)
    """Six circles and a rule that stops after degree 4: by Harnack's theorem a quartic has at
    most 4 ovals, so no degree up to the stop has the data's 6 loops, fitted or repaired; degree 6
    is tried after the stop and selected with them, and the attempts at degree 4 are recorded.
    Where degree 4 has the data's topology (an ellipse), nothing more is tried."""
    from ipfit import fit_adaptive
    from ipfit.normals import contour_normals

    points, normals = _circles(6, 2.2)
    result = fit_adaptive(points, normals, ordered_contour=True, rule=_StopsAtFour(), min_degree=4, max_degree=10,
                          rng=seed)
    four, six = result.degrees
    assert (four.degree, six.degree) == (4, 6) and four.quality.topology_matches is False and four.cleanup
    assert result.selected_degree == 6 and six.quality.topology.loops == 6 and six.quality.f_score >= 0.99
    assert "degree 6 was tried after the rule had stopped at degree 4" in result.message
    assert "superseded" in four.reason
    # an ellipse has the data's one loop at degree 4 already: the rule's stop stands
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    ellipse = np.c_[2 * np.cos(t), np.sin(t)]
    alone = fit_adaptive(ellipse, contour_normals(ellipse), ordered_contour=True, rule=_StopsAtFour(), min_degree=4,
                         max_degree=10, rng=seed)
    assert [d.degree for d in alone.degrees] == [4] and "tried after the rule" not in alone.message


def test_a_topology_repair_ends_with_a_round_from_its_best_clean_round(seed, monkeypatch):
    # (holds for seeds 0-5: IPFIT_TEST_SEED)
    """The dumbbell's degree 4 cuts the neck; held to a band no round reaches (F 1), its topology
    variant measures the search's other solutions first, then runs the repair's rounds from the
    degree's own fit, and ends with one more from its best clean round of one loop."""
    from ipfit import fit_adaptive
    from ipfit.degree import loop, repair
    from ipfit.degree.rules import TOPOLOGY
    from ipfit.normals import contour_normals

    rounds = []  # (degree, start, result) of every refit of a topology variant

    def recorded(entry, refit, options, cloud, ordered_contour, rule, best_f=0.0):
        if not isinstance(rule, loop._WithinTolerance):
            return repair.repair(entry, refit, options, cloud, ordered_contour, rule, best_f)

        def refit_and_record(options, start, keep_clear):
            trial = refit(options, start, keep_clear)
            rounds.append((entry.degree, np.array(start), trial))
            return trial
        return repair.repair(entry, refit_and_record, options, cloud, ordered_contour, rule, 1.0)

    monkeypatch.setattr(loop, "repair", recorded)
    points = _dumbbell()
    result = fit_adaptive(points, contour_normals(points), ordered_contour=True, rule=_StopsAtFour(), min_degree=4,
                          max_degree=6, rng=seed)
    four = result.degrees[0]  # as fitted, or as repaired when a round came within the rule's tolerance
    assert four.degree == 4 and any(a["target"] == "topology" for a in four.cleanup)
    others = [a for a in four.cleanup if a["target"] == "another solution"]
    assert others and list(four.cleanup[:len(others)]) == others
    at_four = [(start, trial) for degree, start, trial in rounds if degree == 4]
    assert len(at_four) == len(four.cleanup) - len(others) >= 2
    one_loop = [trial for _, trial in at_four[:-1] if TOPOLOGY.is_clean(trial.quality)]
    assert one_loop  # the places held give one loop at some round
    best = max(one_loop, key=lambda t: t.quality.f_score)
    assert np.allclose(at_four[-1][0], best.x)
    assert all(np.allclose(start, at_four[0][0]) for start, _ in at_four[:-1])  # the rounds before: its fit


def test_a_degree_beyond_the_stop_of_another_topology_too_is_recorded_not_selected(seed):
    # (holds for seeds 0-5: IPFIT_TEST_SEED)
    """24 small circles: by Harnack's theorem a curve of degree 6 has at most 11 ovals, so the
    degree tried beyond a stop at 4 cannot have the data's 24 loops either; it is kept in the
    record, set aside, and the rule's choice stays."""
    from ipfit import fit_adaptive

    points, normals = _circles(24, 5.0, n=24)
    result = fit_adaptive(points, normals, ordered_contour=True, rule=_StopsAtFour(), min_degree=4, max_degree=10,
                          rng=seed)
    assert [d.degree for d in result.degrees] == [4, 6] and result.selected_degree == 4
    six = result.degrees[1]
    assert six.quality.data_topology.loops == 24 and six.quality.topology.loops <= 11
    assert six.cleanup and six.reason.startswith("tried after the rule's stop, for the data's topology:")
    assert result.message.endswith("where the data has 24): not selected")
    assert result.reason == "flattened"
    validate_result(json.loads(json.dumps(result.to_dict())))


def test_another_solution_of_the_data_topology_spares_the_repair():
    """When one of the search's other solutions of a degree has the data's topology within the
    tolerance, the topology variant takes it and runs no repair round."""
    from ipfit import fit_adaptive
    from ipfit.degree.loop import _measured_fit, _topology_variant
    from ipfit.fitting.options import RECOMMENDED
    from ipfit.normals import contour_normals

    points = _dumbbell()
    normals = contour_normals(points)
    cloud = Cloud(points, normals)
    four = fit_adaptive(cloud, ordered_contour=True, min_degree=4, max_degree=4, rng=0).degrees[0]
    assert four.quality.topology.loops == 2
    # one loop round the dumbbell at degree 4 (x⁴/81 + y² = 1, through both discs' far ends)
    loop = synthetic.from_terms(2, 4, {(4, 0): 1 / 81, (0, 2): 1.0, (0, 0): -1.0})
    entry = dataclasses.replace(four, solutions=(four.polynomial, loop), cleanup=())

    def measure(poly):
        return _measured_fit(entry, poly, cloud, cloud.oriented, 0.01, True)

    def refit(*args):
        raise AssertionError("no repair round when another solution will do")

    f_loop = measure(loop).quality.f_score
    tried, taken = _topology_variant(entry, entry, refit, measure, RECOMMENDED, cloud, True, best_f=f_loop + 0.005)
    assert taken is not None and taken.quality.topology.loops == 1 and np.allclose(taken.x, measure(loop).x)
    assert [a["target"] for a in taken.cleanup] == ["another solution"] and tried.cleanup == taken.cleanup
    # out of the tolerance, the repair runs after it (and is recorded)
    with pytest.raises(AssertionError, match="no repair round"):
        _topology_variant(entry, entry, refit, measure, RECOMMENDED, cloud, True, best_f=f_loop + 0.05)


def test_an_interrupt_while_deciding_on_a_degree_beyond_the_stop_keeps_the_fit_so_far():
    """Ctrl-C during the topology repair that decides whether to go beyond the rule's stop: the
    degrees fitted stand and the run says it was interrupted, as for an interrupt in the loop."""
    from ipfit import fit_adaptive

    def progress(event):
        if event["event"] == "topology_repair":
            raise KeyboardInterrupt

    points, normals = _circles(6, 2.2)
    result = fit_adaptive(points, normals, ordered_contour=True, rule=_StopsAtFour(), min_degree=4, max_degree=10,
                          rng=0, progress=progress)
    assert [d.degree for d in result.degrees] == [4] and result.selected_degree == 4
    assert result.reason == "interrupted" and "tried after the rule" not in result.message

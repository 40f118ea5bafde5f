"""Scenes (issue 36): several objects in one scan, each found and fitted with its own polynomial."""

import json

import numpy as np
import pytest

import ipfit
from ipfit.cli import main
from ipfit.exceptions import InvalidInputError, ReadError
from ipfit.scene import fit_scene, load_scene, segment
from ipfit.scene.segment import CLUTTER, OBJECT, OUTLIER, PLANE, PlaneModel


def _sphere(rng, n, center, radius):
    v = rng.normal(size=(n, 3))
    return np.asarray(center) + radius * v / np.linalg.norm(v, axis=1, keepdims=True)


def _two_spheres_on_a_plane(seed, gap_centres=2.8, n_plane=2500, noise=0.003, outliers=0.05):
    """Sphere A (r 1 at the origin), sphere B (r 0.5, ``gap_centres`` along x), a plane under them;
    noise and uniform outliers. Returns (points, truth): 0 A, 1 B, -1 plane, -2 outlier."""
    rng = np.random.default_rng(seed)
    a = _sphere(rng, 1500, [0, 0, 0], 1.0)
    b = _sphere(rng, 700, [gap_centres, 0, -0.5], 0.5)
    plane = np.column_stack([rng.uniform(-2, 4.5, n_plane), rng.uniform(-2.5, 2.5, n_plane), np.full(n_plane, -1.1)])
    clean = np.vstack([a, b, plane])
    pts = clean + rng.normal(0, noise, clean.shape)
    truth = np.concatenate([np.zeros(len(a)), np.ones(len(b)), np.full(n_plane, -1)]).astype(int)
    n_out = int(outliers * len(pts))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pts = np.vstack([pts, rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), (n_out, 3))])
    return pts, np.concatenate([truth, np.full(n_out, -2)])


def _radius(poly, center):
    """The median distance from ``center`` of the polynomial's zero set (its vertices)."""
    zs = ipfit.extract_zero_set(poly, bounds=np.column_stack([np.asarray(center) - 2.0, np.asarray(center) + 2.0]),
                                resolution=64)
    return float(np.median(np.linalg.norm(zs.vertices - center, axis=1)))


# -- segmentation --------------------------------------------------------------------------------
def test_plane_model_speaks_scikit_image_protocol():
    from skimage.measure import ransac

    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.uniform(-1, 1, (200, 2)), np.zeros(200)]) @ np.linalg.qr(rng.normal(size=(3, 3)))[0]
    strays = rng.uniform(-1, 1, (60, 3))
    model, inliers = ransac(np.vstack([plane, strays]), PlaneModel, min_samples=3, residual_threshold=1e-6, rng=0)
    assert inliers[:200].all() and inliers[200:].sum() <= 1
    assert model.residuals(plane).max() < 1e-9
    assert not PlaneModel.from_estimate([[0.0, 0, 0], [1, 1, 1], [2, 2, 2]])  # collinear: no plane


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_spheres_and_a_plane_segmented(seed):
    pts, truth = _two_spheres_on_a_plane(seed)
    seg = segment(pts, rng=seed)
    assert len(seg.objects) == 2
    assert len(seg.planes) == 1
    normal = seg.planes[0].normal
    assert abs(abs(normal[2]) - 1) < 1e-3 and abs(abs(seg.planes[0].offset) - 1.1) < 0.01
    for k, cluster in enumerate(seg.objects):  # largest first: the big sphere is object 0
        mine = truth[cluster.indices]
        assert np.mean(mine == k) > 0.97  # no object spans the other sphere or much of the plane
        assert np.mean(seg.labels[truth == k] == k) > 0.9
        assert not cluster.touching
    assert np.mean(seg.kinds[truth == -1] == PLANE) > 0.93  # a few of its edge points read as outliers
    assert np.mean(seg.kinds[truth == -2] == OUTLIER) > 0.8
    assert set(np.unique(seg.kinds)) <= {OBJECT, PLANE, CLUTTER, OUTLIER}


def _box_surface(rng, n, lo, hi):
    """Points uniform on a box's faces but its bottom (it stands on a table); ``n`` before that cut."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    extent = hi - lo
    areas = np.array([extent[1] * extent[2], extent[0] * extent[2], extent[0] * extent[1]])
    axis = rng.choice(3, size=n, p=areas / areas.sum())
    top = rng.integers(0, 2, n) == 1
    points = lo + rng.random((n, 3)) * extent
    points[np.arange(n), axis] = np.where(top, hi[axis], lo[axis])
    return points[~((axis == 2) & ~top)]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_box_on_a_table_keeps_its_faces(seed):
    """The box's top (a third of the points left once the table is gone) is a plane RANSAC finds;
    its rim meets the box's sides all round, so it is a face, not a support (before: the top and
    two sides removed as planes, the box in three pieces)."""
    rng = np.random.default_rng(seed)
    box = _box_surface(rng, 2600, [-1.0, -0.8, -1.1], [1.0, 0.8, -0.1])
    ball = _sphere(rng, 700, [2.8, 0, -0.6], 0.5)
    table = np.column_stack([rng.uniform(-2, 4.5, 2500), rng.uniform(-2.5, 2.5, 2500), np.full(2500, -1.1)])
    table = table[~((np.abs(table[:, 0]) < 1) & (np.abs(table[:, 1]) < 0.8))]  # hidden under the box
    truth = np.concatenate([np.zeros(len(box)), np.ones(len(ball)), np.full(len(table), -1)])
    pts = np.vstack([box, ball, table]) + rng.normal(0, 0.003, (len(truth), 3))
    seg = segment(pts, rng=seed)
    assert len(seg.planes) == 1 and abs(abs(seg.planes[0].normal[2]) - 1) < 1e-3
    assert len(seg.objects) == 2
    for k, cluster in enumerate(seg.objects):  # the box is the larger
        assert np.mean(truth[cluster.indices] == k) > 0.97
        assert np.mean(seg.labels[truth == k] == k) > 0.95


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_floor_and_a_wall_are_both_supports(seed):
    """A room's corner: the floor and the wall are removed (the wall's rim meets only the floor,
    removed before it), the ball in front of them is the one object."""
    rng = np.random.default_rng(seed)
    floor = np.column_stack([rng.uniform(-2, 4, 3000), rng.uniform(-2, 3, 3000), np.zeros(3000)])
    wall = np.column_stack([rng.uniform(-2, 4, 2000), np.full(2000, 3.0), rng.uniform(0, 3, 2000)])
    ball = _sphere(rng, 900, [1.0, 0.5, 0.7], 0.6)
    truth = np.concatenate([np.full(len(floor), -1), np.full(len(wall), -2), np.zeros(len(ball))])
    pts = np.vstack([floor, wall, ball]) + rng.normal(0, 0.003, (len(truth), 3))
    seg = segment(pts, rng=seed)
    assert len(seg.planes) == 2
    assert sorted(np.argmax(np.abs(p.normal)) for p in seg.planes) == [1, 2]  # the wall's y, the floor's z
    assert len(seg.objects) == 1
    assert np.mean(truth[seg.objects[0].indices] == 0) > 0.97
    assert np.mean(seg.labels[truth == 0] == 0) > 0.95


def _grid_sheet(rng, corner, n, step, jitter):
    """An ``n`` × ``n`` square grid of ``step`` in the plane z = 0 from ``corner``, each point moved by
    up to ``jitter`` steps: what a scanner's regular sampling of a flat face looks like."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    flat = np.column_stack([i.ravel(), j.ravel()]) * step + np.asarray(corner)
    flat += rng.uniform(-jitter, jitter, flat.shape) * step
    return np.column_stack([flat, np.zeros(len(flat))])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_even_sheets_two_and_a_half_steps_apart_are_two_objects(seed):
    """Two flat sheets side by side in one plane, sampled on a scanner's even grid, 2.5 grid steps
    apart: links lie in both sheets' planes, so only the reach can tell them apart. It comes from
    the density (the 6th neighbour, 1.41 steps on a square grid: a reach of 1.56 steps), not from
    the nearest neighbour (3 of them: 3 steps, and the sheets were one object)."""
    rng = np.random.default_rng(seed)
    step = 0.025
    a = _grid_sheet(rng, [0.0, 0.0], 40, step, 0.1)
    b = _grid_sheet(rng, [(39 + 2.5) * step, 0.0], 40, step, 0.1)
    seg = segment(np.vstack([a, b]), planes=False, outliers="none", rng=seed)
    assert len(seg.objects) == 2
    assert sorted(np.unique(seg.labels[: len(a)]).tolist() + np.unique(seg.labels[len(a):]).tolist()) == [0, 1]
    assert 1.3 * step < seg.link < 1.8 * step


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("noise", [0.0, 0.003])
@pytest.mark.parametrize("n_far", [120, 800])
def test_a_floor_in_two_pieces_is_one_plane(seed, noise, n_far):
    """A floor seen in two pieces (a strip of it hidden, as behind a box): its largest patch is
    removed first, and the other piece, too small to be a dominant plane of its own (120 points)
    or found as one (800), lies on it: the floor, one plane, not an object or a second plane
    (before: a flat object at the floor's height, or two planes)."""
    rng = np.random.default_rng(seed)
    ball = _sphere(rng, 900, [1.0, 0.0, 0.7], 0.6)
    near = np.column_stack([rng.uniform(-1, 3, 2400), rng.uniform(-2, 2, 2400), np.zeros(2400)])
    width = 1.4 * n_far / 800  # the far piece at the near one's density
    far = np.column_stack([rng.uniform(3.6, 3.6 + width, n_far), rng.uniform(-2, 2, n_far), np.zeros(n_far)])
    truth = np.concatenate([np.zeros(len(ball)), np.full(len(near) + len(far), -1)])
    pts = np.vstack([ball, near, far]) + noise * rng.normal(size=(len(truth), 3))
    seg = segment(pts, rng=seed)
    assert len(seg.planes) == 1 and len(seg.objects) == 1
    assert np.mean(truth[seg.objects[0].indices] == 0) > 0.97
    assert np.mean(seg.kinds[len(ball) + len(near):] == PLANE) > 0.9  # the far piece is the floor
    assert seg.planes[0].n_points == np.count_nonzero(seg.kinds == PLANE)


@pytest.mark.parametrize("seed", [0, 3])
def test_two_spheres_and_a_plane_fitted_radii_to_one_percent(seed):
    pts, _ = _two_spheres_on_a_plane(seed)
    scene = fit_scene(pts, rng=seed)
    assert len(scene) == 2 and len(scene.segmentation.planes) == 1
    for result, center, radius in zip(scene, [(0, 0, 0), (2.8, 0, -0.5)], [1.0, 0.5], strict=True):
        assert result.selected_degree == 2
        assert _radius(result.polynomial, center) == pytest.approx(radius, rel=0.01)
    assert scene.touching == ()
    assert "2 objects" in scene.message and "1 plane removed" in scene.message


def test_touching_objects_reported_as_one_and_said_so(capsys, tmp_path):
    rng = np.random.default_rng(5)
    apart = np.vstack([_sphere(rng, 1500, [0, 0, 0], 1.0), _sphere(rng, 1500, [2.6, 0, 0], 1.0)])
    touching = np.vstack([_sphere(rng, 1500, [0, 0, 0], 1.0), _sphere(rng, 1500, [2.0, 0, 0], 1.0)])
    one = _sphere(rng, 3000, [0, 0, 0], 1.0) * [1.6, 1.0, 0.8]  # one body of the same size: no neck
    assert [c.touching for c in segment(apart, outliers="none").objects] == [False, False]
    assert [c.touching for c in segment(one, outliers="none").objects] == [False]
    seg = segment(touching, outliers="none")
    assert len(seg.objects) == 1 and seg.objects[0].touching
    assert "touch" in seg.objects[0].note
    path = tmp_path / "touching.xyz"
    np.savetxt(path, touching)
    code = main(["fit", str(path), "--objects", "-o", str(tmp_path / "t"), "--method", "3l", "--max-degree", "4",
                 "--no-picture", "--no-zero-set", "--outliers", "none"])
    assert code == 0
    out = capsys.readouterr().out
    assert "object 0: may be two objects that touch" in out and "found 1 object" in out
    data = json.loads((tmp_path / "t.json").read_text())
    assert data["objects"][0]["touching"] is True and "touch" in data["objects"][0]["note"]
    assert "may be two touching objects" in data["segmentation"]["message"]


def _noisy(rng, clean, sigma):
    return clean + rng.normal(0, sigma, clean.shape)


def _spacing(points):
    from scipy.spatial import cKDTree

    return float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_noisy_spheres_four_spacings_apart_are_two_objects(seed):
    # noise of 0.5 % of a sphere's diagonal (0.4 spacing): the isotropic link at 3 local spacings
    # joined them (0 of 6 seeds apart); the links across the gap run along both surfaces' normals
    rng = np.random.default_rng(seed)
    a = _sphere(rng, 1500, [0, 0, 0], 1.0)
    b = _sphere(rng, 1500, [2 + 4 * _spacing(a), 0, 0], 1.0)
    seg = segment(_noisy(rng, np.vstack([a, b]), 0.005 * 2 * np.sqrt(3)))
    assert len(seg.objects) == 2
    for cluster in seg.objects:
        mine = cluster.indices < 1500
        assert mine.all() or not mine.any()
        assert cluster.n_points > 0.95 * 1500


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_thin_legged_body_stays_one_object(seed):
    # a body with four legs as thin as the noise is wide and sampled along them only: a leg's
    # neighbourhood is a line, its pieces join the body
    rng = np.random.default_rng(seed)
    body = _sphere(rng, 1500, [0, 0, 0], 1.0) * [1.0, 0.6, 0.4]
    legs = []
    for angle in (0.6, 2.5, 3.8, 5.7):
        t = rng.uniform(0, 1, 60)
        start = np.array([0.8 * np.cos(angle), 0.5 * np.sin(angle), 0.0])
        end = start * 1.6 + [0, 0, -1.0]
        legs.append(start + t[:, None] * (end - start) + rng.normal(0, 0.01, (60, 3)))
    clean = np.vstack([body, *legs])
    seg = segment(_noisy(rng, clean, 0.005 * 2.5), outliers="none")
    assert len(seg.objects) == 1
    assert seg.objects[0].n_points > 0.95 * len(clean)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_small_piece_near_a_body_joins_it_a_larger_one_does_not(seed):
    # the same density on both (119 points per unit area), 5 spacings apart: a piece of 6 % of
    # the body's points is a part of it (a cable, a cut-off bit), one of 25 % is an object
    rng = np.random.default_rng(seed)
    body = _sphere(rng, 1500, [0, 0, 0], 1.0)
    gap = 5 * _spacing(body)
    piece = _sphere(rng, 94, [1.25 + gap, 0, 0], 0.25)
    other = _sphere(rng, 375, [-1.5 - gap, 0, 0], 0.5)
    seg = segment(_noisy(rng, np.vstack([body, piece, other]), 0.005 * 2 * np.sqrt(3)))
    assert len(seg.objects) == 2
    assert np.mean(seg.labels[:1594] == 0) > 0.97
    assert np.mean(seg.labels[1594:] == 1) > 0.97

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_few_strays_far_from_an_object_do_not_join_it(seed):
    # 20 strays in a loose patch 1.5 radii off a dense sphere, 0.4 apart: they link to each other
    # at their own wide spacing, and by their reach alone they joined the sphere (and bent its fit)
    rng = np.random.default_rng(seed)
    body = _sphere(rng, 1500, [0, 0, 0], 1.0)
    y, z = np.meshgrid(np.arange(5) * 0.4 - 0.8, np.arange(4) * 0.4 - 0.6)
    strays = np.column_stack([np.full(20, 2.5), y.ravel(), z.ravel()]) + rng.normal(0, 0.03, (20, 3))
    seg = segment(np.vstack([body, strays]), outliers="none")
    assert len(seg.objects) == 1
    members = seg.objects[0].indices
    assert np.all(members < 1500) and len(members) > 0.99 * 1500
    assert sum(c.n_points for c in seg.clutter) >= 20     # the strays: clutter, not a part


# -- images --------------------------------------------------------------------------------------
def _three_shapes_png(path):
    from PIL import Image
    from skimage.draw import disk, ellipse, polygon

    img = np.full((220, 320), 255, dtype=np.uint8)
    img[disk((60, 60), 40)] = 0  # centre column 60, row 60 -> (60, -60)
    img[ellipse(150, 170, 35, 70)] = 0  # (170, -150)
    img[polygon([20, 100, 100], [230, 200, 300])] = 0  # a triangle, centroid near (243, -73)
    img[205:208, 5:8] = 0  # a speck: not a shape
    Image.fromarray(img).save(path)


def test_image_with_three_silhouettes(tmp_path):
    from ipfit.io.silhouettes import read_silhouettes

    path = tmp_path / "three.png"
    _three_shapes_png(path)
    shapes = read_silhouettes(path)
    assert len(shapes) == 3
    centres = sorted(tuple(np.round(p.mean(axis=0) / 5) * 5) for p, _ in shapes)
    assert centres[0] == (60.0, -60.0) and centres[1] == (170.0, -150.0)
    assert abs(centres[2][0] - 243) < 6 and abs(centres[2][1] + 73) < 6
    # the single-shape reader still reads the largest only (the ellipse)
    one = ipfit.read_points(path)
    assert np.allclose(one.points.mean(axis=0), [170, -150], atol=1.0)
    points = np.vstack([p for p, _ in shapes])
    labels = np.concatenate([np.full(len(p), i) for i, (p, _) in enumerate(shapes)])
    scene = fit_scene(points, np.vstack([n for _, n in shapes]), labels=labels, method="3l", max_degree=4)
    assert len(scene) == 3
    disc = next(r for r, (p, _) in zip(scene, shapes, strict=True) if abs(p.mean(axis=0)[0] - 60) < 3)
    vertices = np.vstack(ipfit.extract_zero_set(disc.polynomial, bounds=[[0, 120], [-120, 0]]).curves)
    assert np.median(np.linalg.norm(vertices - [60, -60], axis=1)) == pytest.approx(40, abs=1.0)


# -- the result ----------------------------------------------------------------------------------
def test_scene_json_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    t = np.linspace(0, 2 * np.pi, 150, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    pts = np.vstack([ring, 0.5 * ring + [4.0, 1.0], rng.uniform(-1, 5, (3, 2)) * [1, 0.1] + [0, 8]])
    scene = fit_scene(pts, method="3l", max_degree=4, outliers="none")
    assert len(scene) == 2 and len(scene.segmentation.clutter) >= 1
    data = scene.to_dict("rings.csv")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    assert ipfit.load_result(path)["objects"][1]["n_points"] == 150
    view = load_scene(path)
    assert len(view) == 2 and view.dim == 2
    probe = rng.uniform(-1, 5, (20, 2))
    for obj, result, box in zip(view.objects, scene, scene.boxes, strict=True):
        assert np.allclose(obj.polynomial(probe), result.polynomial(probe), rtol=1e-12, atol=1e-14)
        assert np.array_equal(np.asarray(obj.data["bounding_box"]), box)
        ipfit.load_result(dict(obj.data))  # each object alone is a complete result
    assert np.array_equal(view.labels, scene.segmentation.labels)
    # a result of one shape is not a scene, a scene is not one polynomial, and a corrupt scene is refused
    with pytest.raises(InvalidInputError, match="not a scene"):
        load_scene(data["objects"][0])
    with pytest.raises(InvalidInputError, match="scene of 2 objects"):
        ipfit.degree.results.result_view(data)
    data["objects"][1]["bounding_box"] = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]
    path.write_text(json.dumps(data))
    with pytest.raises(ReadError, match=r'objects\[1\].bounding_box'):
        load_scene(path)


# -- the command line ----------------------------------------------------------------------------
def test_cli_objects_end_to_end(tmp_path, capsys):
    rng = np.random.default_rng(3)
    plane = np.column_stack([rng.uniform(-2, 4, 1500), rng.uniform(-2, 2, 1500), np.full(1500, -1.2)])
    pts = np.vstack([_sphere(rng, 600, [0, 0, 0], 1.0), _sphere(rng, 300, [2.8, 0, -0.5], 0.5), plane])
    scan = tmp_path / "scan.xyz"
    np.savetxt(scan, pts)
    prefix = tmp_path / "out" / "scan"
    assert main(["fit", str(scan), "--objects", "--keep-planes", "-o", str(prefix), "--method", "3l",
                 "--max-degree", "2"]) == 0
    out = capsys.readouterr().out
    assert "found 2 objects; 1 plane removed" in out
    assert sorted(p.name for p in prefix.parent.iterdir()) == ["scan.json", "scan.ply", "scan.png"]
    data = json.loads((tmp_path / "out" / "scan.json").read_text())
    # a random sample leaves a few points farther from the rest than the link: clutter, not fitted
    assert [o["n_points"] for o in data["objects"]] == [pytest.approx(600, abs=10), pytest.approx(300, abs=6)]
    assert data["planes"][0]["polynomial"]["degree"] == 1
    assert data["input"]["path"] == str(scan.resolve())
    result = str(tmp_path / "out" / "scan.json")
    assert main(["mesh", result, "-o", str(tmp_path / "m.ply")]) == 0
    assert (tmp_path / "m-object-0.ply").exists() and (tmp_path / "m-object-1.ply").exists()
    assert main(["mesh", result, "-o", str(tmp_path / "all.obj"), "--combined"]) == 0
    assert main(["plot", result, "-o", str(tmp_path / "p.png")]) == 0
    assert main(["export", result, "--to", "python", "-o", str(tmp_path / "f.py")]) == 0
    namespace: dict = {}
    exec((tmp_path / "f.py").read_text(), namespace)

    def distance(i, point):  # first-order distance |f| / |grad f| with object i's exported functions
        return abs(namespace[f"f_{i}"](*point)) / np.linalg.norm(namespace[f"gradient_{i}"](*point))

    assert distance(0, (1.0, 0.0, 0.0)) < 0.01 and distance(1, (2.8, 0.5, -0.5)) < 0.01
    assert distance(0, (2.8, 0.5, -0.5)) > 0.3  # object 0's function is not object 1's
    capsys.readouterr()
    assert main(["view", result, "-o", str(tmp_path / "v.html")]) == 0
    page = (tmp_path / "v.html").read_text()
    assert page.count('"legendgroup":"object 0"') >= 1 and '"legendgroup":"object 1"' in page


def test_cli_objects_bad_input_writes_nothing(tmp_path, capsys):
    rng = np.random.default_rng(4)
    flat = np.column_stack([rng.uniform(-2, 2, (1500, 2)), np.zeros(1500)])  # a plane and nothing on it
    scan = tmp_path / "flat.xyz"
    np.savetxt(scan, flat)
    assert main(["fit", str(scan), "--objects", "-o", str(tmp_path / "out" / "flat"), "--method", "3l"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "expected at least one object" in err[0]
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    assert main(["fit", str(scan), "--workers", "2", "-o", str(tmp_path / "x")]) == 2
    assert "add --objects" in capsys.readouterr().err
    assert not any(p.name.startswith("x") for p in tmp_path.iterdir())


@pytest.mark.slow
def test_fit_scene_on_dask_matches_the_local_fit():
    pytest.importorskip("distributed")
    pts, _ = _two_spheres_on_a_plane(0, n_plane=1500)
    here = fit_scene(pts, method="3l", max_degree=4, rng=7)
    there = fit_scene(pts, method="3l", max_degree=4, rng=7, workers=1)
    assert [r.selected_degree for r in here] == [r.selected_degree for r in there]
    for a, b in zip(here, there, strict=True):
        assert np.allclose(a.polynomial.coefficients, b.polynomial.coefficients, atol=1e-8)

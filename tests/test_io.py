"""Reading and writing point files: every format, the bundled files, bad files, random bytes."""

import io as pyio
import os
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image
from plyfile import PlyData, PlyElement
from scipy.spatial import cKDTree

from ipfit import io
from ipfit.datasets.bundled import DATA_DIR
from ipfit.geometry.mesh import face_normals, merge_duplicates, vertex_normals_from_faces
from ipfit.exceptions import InvalidInputError, ReadError

FIXTURES = Path(__file__).with_name("data")

SHAPES = {"2d": ["boot.csv", "butterfly.csv", "airplane.csv", "boot.gif", "butterfly.gif"],
          "3d": ["bun_zipper.ply", "bun_zipper_res2.ply", "bun_zipper_res3.ply", "bun_zipper_res4.ply",
                 "apple.ply", "rubber_duck.ply"]}


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _one_line_error(path, exc_info, *words):
    message = str(exc_info.value)
    assert "\n" not in message
    assert message.startswith(str(path))
    for word in words:
        assert word in message.lower(), message


# -- the bundled files ---------------------------------------------------------------------------

@pytest.mark.parametrize("folder, name", [(f, n) for f, names in SHAPES.items() for n in names])
def test_every_bundled_file_loads(folder, name):
    path = DATA_DIR / folder / name
    points, normals = io.read_points(path)
    dim = 2 if folder == "2d" else 3
    assert points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == dim
    assert len(points) >= 200
    if path.suffix == ".csv":  # plain contours: no normals in the file
        assert normals is None
    else:  # vertex normals, face normals or the traced boundary's
        assert normals.shape == points.shape
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_the_list_covers_every_bundled_file():
    on_disk = sorted(p.name for p in DATA_DIR.glob("*/*"))
    assert on_disk == sorted(SHAPES["2d"] + SHAPES["3d"])


def test_contour_csv_keeps_its_order():
    points, _ = io.read_points(FIXTURES / "boot.csv")
    expected = np.loadtxt(FIXTURES / "boot.csv", delimiter=",", skiprows=3)
    np.testing.assert_array_equal(points, expected)
    assert io.read_mesh(FIXTURES / "boot.csv").normals is None


def test_duck_rows_split_per_face_merge_to_their_distinct_positions():
    path = FIXTURES / "duck_patch.ply"
    raw = PlyData.read(str(path))["vertex"]
    distinct = {(x, y, z) for x, y, z in zip(raw["x"], raw["y"], raw["z"])}  # independent reference
    mesh = io.read_mesh(path)
    assert len(mesh.points) == len(distinct) < len(raw)
    assert {tuple(p) for p in mesh.points.astype(np.float32)} == distinct
    assert mesh.faces.shape == (150, 3) and mesh.faces.max() < len(distinct)
    assert io.read_mesh(path, merge=False).points.shape == (len(raw), 3)
    # the file's flat per-face normals, averaged per position, agree with the faces' normals
    from_faces = vertex_normals_from_faces(mesh.points, mesh.faces)
    assert np.median(np.einsum("ij,ij->i", mesh.normals, from_faces)) > 0.99


def test_bunny_normals_come_from_its_faces():
    path = FIXTURES / "bun_zipper_res4.ply"
    mesh = io.read_mesh(path)
    assert mesh.normals is None and mesh.faces.shape == (948, 3)
    cloud = io.read_points(path)
    points, normals = cloud
    assert cloud.normals_source == "faces"
    from_faces = vertex_normals_from_faces(mesh.points, mesh.faces)
    ok = from_faces.any(axis=1)  # vertices only in zero-area faces borrow a neighbour's
    assert ok.mean() > 0.98
    np.testing.assert_allclose(normals[ok], from_faces[ok])
    assert io.read_points(path, face_normals=False).normals is None
    # closed and outward: normals point away from the centre on most of the surface
    assert np.mean(np.einsum("ij,ij->i", normals, points - points.mean(axis=0)) > 0) > 0.85


def test_vertices_without_faces_get_their_nearest_neighbours_normal(tmp_path):
    bunny = PlyData.read(str(FIXTURES / "bun_zipper_res4.ply"))
    vertex = bunny["vertex"].data
    extra = vertex[:3].copy()
    for name in "xyz":
        extra[name] = extra[name] + 1e-3  # three points beside the surface, in no face
    bunny["vertex"].data = np.concatenate([vertex, extra])
    bunny.write(str(tmp_path / "b.ply"))
    points, normals = io.read_points(tmp_path / "b.ply")
    mesh = io.read_mesh(tmp_path / "b.ply")
    lonely = ~vertex_normals_from_faces(mesh.points, mesh.faces).any(axis=1)
    assert lonely.sum() == 3 and np.isfinite(normals).all()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    nearest = cKDTree(points[~lonely]).query(points[lonely])[1]
    np.testing.assert_array_equal(normals[lonely], normals[~lonely][nearest])


def test_apple_keeps_its_own_normals():
    path = FIXTURES / "apple_patch.ply"
    raw = PlyData.read(str(path))["vertex"]
    cloud = io.read_points(path)
    assert cloud.normals_source == "file"
    np.testing.assert_allclose(cloud.points, np.column_stack([raw["x"], raw["y"], raw["z"]]))
    np.testing.assert_allclose(cloud.normals, _unit(np.column_stack([raw["nx"], raw["ny"], raw["nz"]])), atol=1e-6)


def test_boot_silhouette_traces_to_the_boot_contour():
    traced, normals = io.read_points(FIXTURES / "boot.gif")
    contour, _ = io.read_points(FIXTURES / "boot.csv")
    assert abs(len(traced) - len(contour)) <= 5
    assert cKDTree(contour).query(traced)[0].max() < 0.5
    assert cKDTree(traced).query(contour)[0].max() < 0.5
    outward = np.einsum("ij,ij->i", normals, traced - traced.mean(axis=0)) > 0
    assert outward.mean() > 0.8


# -- round trips ---------------------------------------------------------------------------------

@pytest.mark.parametrize("suffix", io.WRITE_FORMATS)
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("with_normals", [True, False])
def test_every_writable_format_round_trips(tmp_path, rng, suffix, dim, with_normals):
    points = rng.normal(size=(50, dim)) * 1e3
    normals = _unit(rng.normal(size=(50, dim))) if with_normals else None
    path = tmp_path / f"cloud{suffix}"
    assert io.write_points(path, points, normals) == path
    back, back_normals = io.read_points(path)
    np.testing.assert_array_equal(back, points)
    if with_normals:
        np.testing.assert_allclose(back_normals, normals, atol=1e-15)
    else:
        assert back_normals is None
    assert sorted(os.listdir(tmp_path)) == [path.name]  # no temporary file left behind


def test_ascii_ply_round_trip_and_is_text(tmp_path, rng):
    points, normals = rng.random((20, 3)), _unit(rng.normal(size=(20, 3)))
    path = io.write_points(tmp_path / "a.ply", points, normals, binary=False)
    assert path.read_bytes().startswith(b"ply\nformat ascii 1.0")
    back = io.read_points(path)
    np.testing.assert_array_equal(back.points, points)
    np.testing.assert_allclose(back.normals, normals, atol=1e-15)


def test_write_errors(tmp_path, rng):
    points = rng.random((10, 3))
    with pytest.raises(InvalidInputError, match=r"\.ply"):
        io.write_points(tmp_path / "x.vtk", points)
    with pytest.raises(InvalidInputError, match="does not exist"):
        io.write_points(tmp_path / "missing" / "x.ply", points)
    with pytest.raises(InvalidInputError, match="shape"):
        io.write_points(tmp_path / "x.ply", points, points[:5])
    assert list(tmp_path.iterdir()) == []


# -- the formats, one by one ---------------------------------------------------------------------

def _ply(path, points, normals=None, faces=None, *, text=True, extra=True):
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else []) + (["confidence"] if extra else [])
    table = np.empty(len(points), dtype=[(n, "f4") for n in names])
    for j, a in enumerate("xyz"):
        table[a] = points[:, j]
        if normals is not None:
            table["n" + a] = normals[:, j]
    if extra:
        table["confidence"] = 1.0
    elements = [PlyElement.describe(table, "vertex")]
    if faces is not None:
        ftab = np.empty(len(faces), dtype=[("vertex_indices", "i4", (faces.shape[1],))])
        ftab["vertex_indices"] = faces
        elements.append(PlyElement.describe(ftab, "face"))
    PlyData(elements, text=text).write(str(path))
    return path


def _tetra():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # counter-clockwise from outside
    return points, faces


@pytest.mark.parametrize("text", [True, False], ids=["ascii", "binary"])
@pytest.mark.parametrize("with_normals", [True, False])
@pytest.mark.parametrize("with_faces", [True, False])
def test_ply_variants(tmp_path, text, with_normals, with_faces):
    points, faces = _tetra()
    normals = _unit(points - 0.25) if with_normals else None
    path = _ply(tmp_path / "t.ply", points, normals, faces if with_faces else None, text=text)
    mesh = io.read_mesh(path)
    np.testing.assert_allclose(mesh.points, points)
    assert (mesh.faces is not None) == with_faces
    cloud = io.read_points(path)
    if with_normals:
        np.testing.assert_allclose(cloud.normals, normals, atol=1e-6)
    elif with_faces:
        assert np.all(np.einsum("ij,ij->i", cloud.normals, points - 0.25) > 0)  # outward from faces
    else:
        assert cloud.normals is None


def test_ply_quads_are_triangulated(tmp_path):
    cube = trimesh.creation.box()
    points = np.asarray(cube.vertices)
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    ftab = np.empty(6, dtype=[("vertex_indices", "i4", (4,))])
    ftab["vertex_indices"] = quads
    vtab = np.array([tuple(p) for p in points], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    PlyData([PlyElement.describe(vtab, "vertex"), PlyElement.describe(ftab, "face")]).write(str(tmp_path / "c.ply"))
    mesh = io.read_mesh(tmp_path / "c.ply")
    assert mesh.faces.shape == (12, 3)


@pytest.mark.parametrize("path", sorted((DATA_DIR / "3d").glob("*.ply")) + sorted(FIXTURES.glob("*.ply")),
                         ids=lambda p: p.name)
def test_an_ascii_ply_is_parsed_by_numpy_as_plyfile_parses_it(path):
    from ipfit.io.meshfiles import _ascii_ply, _plyfile_elements

    raw = path.read_bytes()
    fast, slow = _ascii_ply(raw), _plyfile_elements(path, raw)
    assert fast is not None
    assert fast[0] == slow[0] and fast[2] == slow[2]  # elements, comments
    assert fast[1].dtype == slow[1].dtype
    for name in slow[1].dtype.names:
        assert np.array_equal(fast[1][name], slow[1][name])  # the same text, the same float32 values
    assert np.array_equal(fast[3][0], slow[3][0]) and np.array_equal(fast[3][1], slow[3][1].astype(np.int64))


def test_unusual_ascii_plys_are_left_to_plyfile(tmp_path):
    from ipfit.io.meshfiles import _ascii_ply

    points, faces = _tetra()
    # a triangle and a quad: mixed polygons
    vtab = np.array([tuple(p) for p in points] + [(1.0, 1.0, 0.0)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    ftab = np.empty(2, dtype=[("vertex_indices", object)])
    ftab["vertex_indices"] = [np.array([0, 2, 1], "i4"), np.array([0, 1, 4, 2], "i4")]
    PlyData([PlyElement.describe(vtab, "vertex"), PlyElement.describe(ftab, "face")], text=True).write(
        str(tmp_path / "mixed.ply"))
    assert _ascii_ply((tmp_path / "mixed.ply").read_bytes()) is None
    assert io.read_mesh(tmp_path / "mixed.ply").faces.tolist() == [[0, 2, 1], [0, 1, 4], [0, 4, 2]]
    good = _ply(tmp_path / "t.ply", points, None, faces).read_bytes()
    assert _ascii_ply(good) is not None
    head, body = good.split(b"end_header\n")
    rows = body.split(b"\n")
    # plyfile's own one-line complaint, row and property named, as before
    for bad, said in [(rows[:1] + [b""] + rows[1:], "row 1: property 'x': early end-of-line"),  # numpy skips it
                      ([rows[0] + b" 7"] + rows[1:], "row 0: expected end-of-line"),
                      ([b" ".join(rows[0].split()[:-1])] + rows[1:], "row 0: property 'confidence': early end-of-line"),
                      (rows[:4] + [b"3 0 1 99999999999"] + rows[5:], "'face': row 0: property 'vertex_indices'")]:
        raw = head + b"end_header\n" + b"\n".join(bad)
        assert _ascii_ply(raw) is None, said
        (tmp_path / "bad.ply").write_bytes(raw)
        with pytest.raises(ReadError, match=re.escape(said)):
            io.read_mesh(tmp_path / "bad.ply")
    assert _ascii_ply(_ply(tmp_path / "b.ply", points, None, faces, text=False).read_bytes()) is None


def test_obj_with_and_without_normals(tmp_path):
    points, faces = _tetra()
    lines = [f"v {x} {y} {z}" for x, y, z in points] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (tmp_path / "t.obj").write_text("# tetra\n" + "\n".join(lines) + "\n")
    cloud = io.read_points(tmp_path / "t.obj")
    np.testing.assert_allclose(cloud.points, points)
    assert np.all(np.einsum("ij,ij->i", cloud.normals, points - 0.25) > 0)
    normals = _unit(points - 0.25)
    lines = [f"v {x} {y} {z}" for x, y, z in points] + [f"vn {x} {y} {z}" for x, y, z in normals]
    (tmp_path / "p.obj").write_text("\n".join(lines) + "\n")
    cloud = io.read_points(tmp_path / "p.obj")
    np.testing.assert_allclose(cloud.normals, normals)


def test_off_and_stl(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    sphere.export(tmp_path / "s.off")
    sphere.export(tmp_path / "s.stl")
    sphere.export(tmp_path / "a.stl", file_type="stl_ascii")
    for name in ("s.off", "s.stl", "a.stl"):
        points, normals = io.read_points(tmp_path / name)
        assert len(points) == len(sphere.vertices)  # STL repeats every corner: merged back
        assert np.all(np.einsum("ij,ij->i", normals, _unit(points)) > 0.95)


def test_noff_vertex_normals(tmp_path):
    # a tetrahedron written by hand: NOFF vertex lines are x y z nx ny nz
    text = """NOFF
# a comment
4 4 0
0 0 0  -1 -1 -1
1 0 0  1 0 0
0 1 0  0 1 0
0 0 1  0 0 1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
"""
    (tmp_path / "t.off").write_text(text)
    mesh = io.read_mesh(tmp_path / "t.off")
    assert mesh.faces.shape == (4, 3)
    np.testing.assert_allclose(mesh.normals, [[-3 ** -0.5] * 3, [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    (tmp_path / "h.off").write_text("4OFF\n3 0 0\n0 0 0 1\n1 0 0 1\n0 1 0 1\n")
    with pytest.raises(ReadError, match="4OFF files .* are not supported"):
        io.read_points(tmp_path / "h.off")


@pytest.mark.parametrize("text, dim, has_normals", [
    ("0 0\n1 0\n0 1\n", 2, False),
    ("x,y\n0,0\n1,0\n0,1\n", 2, False),
    ("\ufeff# comment\nx;y;z\n0;0;0\n1;0;0\n0;1;0 # trailing comment\n\n", 3, False),
    ("0\t0\t0\t1\t0\t0\n1 0 0 0 1 0\n0 1 0 0 0 1\n", 3, True),
    ("0,0,1,0\n1,0,0,1\n0,1,-1,0\n", 2, True),
    ("nz,ny,nx,z,y,x,intensity\n1,0,0,0,0,0,5\n0,1,0,0,0,1,5\n0,0,1,0,1,0,5\n", 3, True),
    ("X Y\n1e3 -2.5E-1\n+4 .5\n7 8\n", 2, False),
], ids=["plain2d", "header", "bom-semicolon-comments", "tabs-normals", "csv4", "named-columns", "exponents"])
def test_text_tables(tmp_path, text, dim, has_normals):
    for suffix in (".txt", ".csv", ".xyz"):
        path = tmp_path / f"t{suffix}"
        path.write_text(text, encoding="utf-8")
        points, normals = io.read_points(path)
        assert points.shape == (3, dim)
        assert (normals is not None) == has_normals


def test_named_columns_are_picked_by_name(tmp_path):
    path = tmp_path / "n.csv"
    path.write_text("nz,ny,nx,z,y,x\n1,0,0,7,8,9\n0,1,0,1,2,3\n0,0,1,4,5,6\n")
    points, normals = io.read_points(path)
    np.testing.assert_array_equal(points[0], [9, 8, 7])
    np.testing.assert_array_equal(normals[0], [0, 0, 1])


def test_npy_and_npz(tmp_path, rng):
    points, normals = rng.random((10, 3)), _unit(rng.normal(size=(10, 3)))
    np.save(tmp_path / "a.npy", points.astype(np.float32))
    np.save(tmp_path / "b.npy", np.hstack([points, normals]))
    np.savez(tmp_path / "c.npz", points=points, normals=normals)
    np.savez(tmp_path / "d.npz", whatever=points[:, :2])
    assert io.read_points(tmp_path / "a.npy").normals is None
    np.testing.assert_allclose(io.read_points(tmp_path / "b.npy").normals, normals)
    np.testing.assert_allclose(io.read_points(tmp_path / "c.npz").normals, normals)
    assert io.read_points(tmp_path / "d.npz").points.shape == (10, 2)


def test_merge_duplicates_averages_normals_and_keeps_order():
    points = np.array([[1.0, 0, 0], [0, 0, 0], [1, 0, 0], [-0.0, 0, 0], [2, 0, 0]])
    normals = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0]])
    merged = merge_duplicates(points, normals)
    np.testing.assert_array_equal(merged.points, [[1, 0, 0], [0, 0, 0], [2, 0, 0]])
    np.testing.assert_array_equal(merged.index, [0, 1, 0, 1, 2])
    np.testing.assert_allclose(merged.normals[0], _unit(np.array([[1.0, 0, 1]]))[0])
    np.testing.assert_allclose(merged.normals[1], [0, 1, 0])


def test_face_and_vertex_normals_are_area_weighted():
    # a big triangle in z = 0 and a small one in x = 0 share vertex 0
    points = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 3, 4]])
    np.testing.assert_allclose(face_normals(points, faces), [[0, 0, 1], [1, 0, 0]])
    vn = vertex_normals_from_faces(points, faces)
    np.testing.assert_allclose(vn[0], _unit(np.array([[1.0, 0, 100]]))[0])
    assert not vertex_normals_from_faces(np.vstack([points, [[5, 5, 5]]]), faces)[5].any()  # no direction: zero


# -- silhouettes ---------------------------------------------------------------------------------

def _disc_image(size=64, center=(20, 32), radius=15, fg=255, bg=0):
    rows, cols = np.mgrid[:size, :size]
    inside = (rows - center[0]) ** 2 + (cols - center[1]) ** 2 <= radius ** 2
    return np.where(inside, fg, bg).astype(np.uint8)


@pytest.mark.parametrize("suffix", [".png", ".gif", ".bmp", ".tif"])
def test_silhouette_formats_and_polarity(tmp_path, suffix):
    white = _disc_image()
    Image.fromarray(white).save(tmp_path / f"w{suffix}")
    Image.fromarray(255 - white).save(tmp_path / f"b{suffix}")  # dark shape on white
    a, na = io.read_points(tmp_path / f"w{suffix}")
    b, _ = io.read_points(tmp_path / f"b{suffix}")
    np.testing.assert_allclose(a, b)
    center = np.array([32.0, -20.0])  # x = column, y = -row
    radius = np.linalg.norm(a - center, axis=1)
    assert abs(radius.mean() - 15.3) < 0.5
    assert np.all(np.einsum("ij,ij->i", na, a - center) > 0)


def test_silhouette_touching_the_border_is_closed(tmp_path):
    img = _disc_image(center=(2, 32), radius=15)  # cut by the top edge
    Image.fromarray(img).save(tmp_path / "cut.png")
    points, normals = io.read_points(tmp_path / "cut.png")
    assert points[:, 1].max() == pytest.approx(0.5)  # closes along the border, half a pixel out
    assert np.all(np.linalg.norm(normals, axis=1) > 0.99)


def test_silhouette_from_alpha_and_antialiasing(tmp_path):
    rgba = np.zeros((64, 64, 4), dtype=np.uint8)
    rgba[..., :3] = 128
    rgba[..., 3] = _disc_image()
    Image.fromarray(rgba, "RGBA").save(tmp_path / "alpha.png")
    points, _ = io.read_points(tmp_path / "alpha.png")
    assert abs(np.linalg.norm(points - [32, -20], axis=1).mean() - 15.3) < 0.5
    rows, cols = np.mgrid[:64, :64]
    smooth = np.clip(15.5 - np.hypot(rows - 20, cols - 32), 0, 1) * 255  # anti-aliased disc
    Image.fromarray(smooth.astype(np.uint8)).save(tmp_path / "aa.png")
    points, _ = io.read_points(tmp_path / "aa.png")
    assert np.ptp(np.linalg.norm(points - [32, -20], axis=1)) < 0.3  # subpixel: nearly a circle


# -- bad files -----------------------------------------------------------------------------------

def _bad_files(tmp_path):
    cases = {}

    def add(key, name, data, *words):
        path = tmp_path / name
        if isinstance(data, str):
            path.write_text(data)
        elif data is not None:
            path.write_bytes(data)
        cases[key] = (path, words)

    add("missing", "missing.ply", None, "no such file")
    add("empty", "empty.csv", b"", "empty")
    add("comments only", "comments.xyz", "# nothing\n\n", "no data")
    add("unknown format", "points.vtk", "1 2 3\n", "unknown format", ".ply")
    add("no extension", "points", "1 2 3\n", "format")
    add("columns", "five.csv", "1,2,3,4,5\n1,2,3,4,5\n1,2,3,4,5\n", "5 columns")
    add("ragged", "ragged.txt", "1 2 3\n4 5 6\n7 8\n", "line 3", "2 values", "expected 3")
    add("non-numeric", "words.csv", "x,y\n1,2\n3,abc\n5,6\n", "line 3", "abc", "not a number")
    add("nan rows", "nan.csv", "1,2\nnan,3\n4,5\n6,7\n", "nan", "line 2")
    add("two points", "two.xyz", "1 2 3\n4 5 6\n", "only 2 points", "at least 3")
    add("duplicates", "dups.xyz", "1 2 3\n1 2 3\n4 5 6\n", "distinct")
    add("binary text", "bin.csv", b"\x89\xff\xfe\x00abc", "not a text file")
    raw = (FIXTURES / "bun_zipper_res4.ply").read_bytes()
    add("truncated ascii ply", "cut.ply", raw[: len(raw) // 2], "truncated")
    ply = PlyData.read(str(FIXTURES / "apple_patch.ply"))
    ply.text = False
    ply.write(str(tmp_path / "full_bin.ply"))
    data = (tmp_path / "full_bin.ply").read_bytes()
    add("truncated binary ply", "cutbin.ply", data[: len(data) - 100], "truncated")
    add("not a ply", "junk.ply", b"hello world\n", "not a valid ply")
    add("ply without vertices", "novert.ply", "ply\nformat ascii 1.0\nelement point 1\nproperty float a\n"
        "end_header\n1\n", "vertex")
    np.save(tmp_path / "cube.npy", np.zeros((4, 3, 2)))
    cases["3d array"] = (tmp_path / "cube.npy", ("shape",))
    npy = pyio.BytesIO()
    np.save(npy, np.zeros((100, 3)))
    add("truncated npy", "cut.npy", npy.getvalue()[:300], "truncated")
    add("truncated npz", "cut.npz", b"PK\x03\x04" + b"\x00" * 20, "npz")
    add("truncated image", "cut.gif", (FIXTURES / "boot.gif").read_bytes()[:200], "image")
    Image.fromarray(np.zeros((10, 10), dtype=np.uint8)).save(tmp_path / "black.png")
    cases["uniform image"] = (tmp_path / "black.png", ("uniform",))
    add("truncated off", "cut.off", "OFF\n4 4 6\n0 0 0\n1 0 0\n", "truncated")
    (tmp_path / "folder.ply").mkdir()
    cases["folder"] = (tmp_path / "folder.ply", ("folder",))
    return cases


def test_bad_files_give_one_clear_line(tmp_path):
    for key, (path, words) in _bad_files(tmp_path).items():
        with pytest.raises(ReadError) as exc_info:
            io.read_points(path)
        try:
            _one_line_error(path, exc_info, *words)
        except AssertionError as exc:
            raise AssertionError(f"{key}: {exc}") from None


def test_read_error_is_a_value_error(tmp_path):
    with pytest.raises(ValueError):
        io.read_points(tmp_path / "nothing.csv")


# -- property-based: random bytes and truncated real files raise only ReadError -----------------

def _only_read_error(path):
    try:
        points, normals = io.read_points(path)
    except ReadError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(str(path))
        return
    assert points.ndim == 2 and len(points) >= 3 and np.isfinite(points).all()
    assert normals is None or normals.shape == points.shape


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=2000), suffix=st.sampled_from(io.READ_FORMATS))
def test_random_bytes_raise_only_read_error(tmp_path, data, suffix):
    path = tmp_path / f"random{suffix}"
    path.write_bytes(data)
    _only_read_error(path)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(min_size=1, max_size=400),
       prefix=st.sampled_from([b"ply\nformat ascii 1.0\n", b"ply\nformat binary_little_endian 1.0\n", b"OFF\n",
                               b"solid x\n", b"\x93NUMPY", b"PK\x03\x04", b"GIF89a", b"\x89PNG\r\n\x1a\n",
                               b"x,y\n", b"v 1 2 3\n"]),
       suffix=st.sampled_from([".ply", ".off", ".stl", ".npy", ".npz", ".gif", ".png", ".csv", ".obj"]))
def test_plausible_headers_with_garbage_raise_only_read_error(tmp_path, data, prefix, suffix):
    path = tmp_path / f"garbage{suffix}"
    path.write_bytes(prefix + data)
    _only_read_error(path)


@pytest.fixture(scope="module")
def real_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("real")
    files = {name: (FIXTURES / name).read_bytes()
             for name in ["bun_zipper_res4.ply", "apple_patch.ply", "boot.csv", "boot.gif", "duck_patch.ply"]}
    rng = np.random.default_rng(0)
    points, normals = rng.random((60, 3)), _unit(rng.normal(size=(60, 3)))
    for name in ("bin.ply", "cloud.npy", "cloud.npz", "cloud.xyz"):
        io.write_points(folder / name, points, normals)
    sphere = trimesh.creation.icosphere(subdivisions=1)
    sphere.export(folder / "s.stl")
    sphere.export(folder / "s.off")
    sphere.export(folder / "s.obj")
    for path in folder.iterdir():
        files[path.name] = path.read_bytes()
    return files


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(choice=st.integers(min_value=0, max_value=100), fraction=st.floats(min_value=0.0, max_value=1.0))
def test_truncated_real_files_raise_only_read_error(tmp_path, real_files, choice, fraction):
    names = sorted(real_files)
    name = names[choice % len(names)]
    raw = real_files[name]
    path = tmp_path / f"cut_{name}"
    path.write_bytes(raw[: int(fraction * (len(raw) - 1))])
    _only_read_error(path)


def test_ascii_plys_with_empty_or_odd_elements_read_as_plyfile_reads_them(tmp_path):
    from ipfit.io.meshfiles import _ascii_ply, _plyfile_elements

    header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    body = "0 0 0\n1 0 0\n0 1 0\n"
    for extra, expect_fast in [("element face 0\nproperty list uchar int vertex_indices\n", True),  # no faces
                               ("element edge 0\n", False),  # an element without properties
                               ("element face 1\nproperty list uchar float vertex_indices\n", False)]:  # float indices
        raw = (header + extra + "end_header\n" + body + ("3 0 1 2\n" if "face 1" in extra else "")).encode()
        fast = _ascii_ply(raw)
        assert (fast is not None) == expect_fast, extra
        if fast is not None:
            slow = _plyfile_elements(tmp_path / "x.ply", raw)
            assert fast[0] == slow[0] and fast[3] is None and slow[3] is None
            assert np.array_equal(fast[1]["x"], slow[1]["x"])
    repeated = (header.replace("property float z", "property float x") + "end_header\n" + body).encode()
    assert _ascii_ply(repeated) is None  # plyfile decides what a repeated property means

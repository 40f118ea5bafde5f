"""Readers on structurally corrupted files and extreme but finite values (issue 13): one clear
line (ReadError / InvalidInputError) or a correct read, never a foreign exception or a numpy
warning, and never a silent substitution."""

import warnings

import numpy as np
import pytest
from PIL import Image

import ipfit
from ipfit import io
from ipfit.geometry.mesh import vertex_normals_from_faces
from ipfit.exceptions import InvalidInputError, NormalsDroppedWarning, ReadError

OFF_1E308 = "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 1e308 0\n3 0 1 2\n"
PLY_1E308 = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n0 1e308 0\n3 0 1 2\n")


def _read_clean(path, **kwargs):
    """read_points with every warning an error: nothing but our own warnings may be raised."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return io.read_points(path, **kwargs)


def _one_line(exc_info, path, *words):
    message = str(exc_info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    for word in words:
        assert word in message.lower(), message


@pytest.mark.parametrize("name, text", [("huge.off", OFF_1E308), ("huge.ply", PLY_1E308)])
def test_a_vertex_at_1e308_outside_every_face_reads(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    cloud = _read_clean(path)
    np.testing.assert_array_equal(cloud.points[3], [0, 1e308, 0])
    # the triangle lies in z = 0; the lonely vertex borrows its nearest neighbour's normal
    np.testing.assert_allclose(np.abs(cloud.normals), [[0, 0, 1]] * 4)
    assert cloud.normals_source == "faces"


@pytest.mark.parametrize("scale", [1e150, 1e-150, 1e300])
def test_face_normals_do_not_depend_on_the_scale(scale):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(vertex_normals_from_faces(points * scale, faces),
                                   vertex_normals_from_faces(points, faces), atol=1e-15)


@pytest.mark.parametrize("name, text, words", [
    ("out.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", ["face", "outside"]),
    ("out.ply", PLY_1E308.replace("3 0 1 2", "3 0 1 9"), ["vertex 9", "4 vertices"]),
    ("neg.ply", PLY_1E308.replace("3 0 1 2", "3 0 -1 2"), ["vertex -1"]),
])
def test_face_indices_out_of_range_are_refused(tmp_path, name, text, words):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, *words)


@pytest.mark.parametrize("name, text, words", [
    ("short.off", "OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n3 0 1 2\n", ["announces 5 vertices and 3 faces"]),
    ("faces.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n2 0 1\n", ["2 faces"]),
    ("short.ply", PLY_1E308.replace("element vertex 4", "element vertex 9"), ["truncated", "9 vertex"]),
    ("negative.off", "OFF\n-4 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", ["negative"]),
])
def test_count_mismatches_are_refused(tmp_path, name, text, words):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, *(words or []))


@pytest.mark.parametrize("name, text", [
    ("n.csv", "x,y,nx,ny\n0,0,1e200,0\n1,0,0,1e-200\n0,1,-3e200,4e200\n"),
    ("n.xyz", "0 0 1e200 0\n1 0 0 1e-200\n0 1 -3e200 4e200\n"),
])
def test_huge_and_tiny_normals_keep_their_direction(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    normals = _read_clean(path).normals
    np.testing.assert_allclose(normals, [[1, 0], [0, 1], [-0.6, 0.8]])


def test_subnormal_normals_come_back_with_unit_length(tmp_path):
    path = tmp_path / "s.xyz"
    path.write_text("0 0 1e-310 1e-310\n1 0 0 3e-320\n0 1 -1 0\n")
    normals = _read_clean(path).normals
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(normals, [[2 ** -0.5, 2 ** -0.5], [0, 1], [-1, 0]], rtol=1e-15)


def test_all_zero_normals_are_dropped_with_one_warning(tmp_path):
    path = tmp_path / "z.csv"
    path.write_text("x,y,z,nx,ny,nz\n0,0,0,0,0,0\n1,0,0,0,0,0\n0,1,0,0,0,0\n0,0,1,0,0,0\n")
    with pytest.warns(NormalsDroppedWarning) as record:
        cloud = io.read_points(path)
    assert len(record) == 1
    message = str(record[0].message)
    assert "\n" not in message and "zero" in message and "dropped" in message and "estimated" in message
    assert cloud.normals is None and cloud.normals_source is None


def test_some_zero_normals_take_a_neighbours_with_a_warning(tmp_path):
    path = tmp_path / "z.xyz"
    path.write_text("0 0 0 1\n1 0 0 0\n5 0 1 0\n")
    with pytest.warns(NormalsDroppedWarning, match="1 of 3 normals are zero"):
        normals = io.read_points(path).normals
    np.testing.assert_array_equal(normals, [[0, 1], [0, 1], [1, 0]])


def test_a_header_with_half_the_normal_columns_warns(tmp_path):
    path = tmp_path / "n.csv"
    path.write_text("x,y,nx\n0,0,1\n1,0,1\n0,1,1\n")
    with pytest.warns(NormalsDroppedWarning, match="names nx but not all 2 normal components"):
        assert io.read_points(path).normals is None


def test_obj_with_fewer_vn_than_v_lines_warns(tmp_path):
    path = tmp_path / "v.obj"
    rng = np.random.default_rng(0)
    lines = [f"v {x} {y} {z}" for x, y, z in rng.random((40, 3))] + ["vn 0 0 1"] * 25
    path.write_text("\n".join(lines) + "\n")
    with pytest.warns(NormalsDroppedWarning, match="25 normals for 40 vertices"):
        cloud = io.read_points(path)
    assert cloud.normals is None and len(cloud.points) == 40


def test_complex_points_are_refused():
    points = np.array([[0, 0], [1, 0], [0, 1]]) + 1j
    with pytest.raises(InvalidInputError, match="points: expected real coordinates"):
        ipfit.write_points("never.csv", points)
    with pytest.raises(InvalidInputError, match="real"):
        ipfit.fit_3l(points, np.ones((3, 2)), 2)


def test_complex_npy_is_refused(tmp_path):
    path = tmp_path / "c.npy"
    np.save(path, np.ones((5, 3), dtype=complex))
    with pytest.raises(ReadError, match="complex"):
        _read_clean(path)


def test_points_scaled_by_1e_minus_200_are_not_all_identical(rng):
    points = rng.normal(size=(40, 2))
    tiny = ipfit.Normalization.from_points(points * 1e-200)
    assert tiny.scale == pytest.approx(ipfit.Normalization.from_points(points).scale * 1e-200, rel=1e-12)


@pytest.mark.parametrize("suffix, words", [(".obj", ["obj"]), (".stl", ["stl"])])
def test_garbage_mesh_files_give_the_real_reason(tmp_path, suffix, words):
    path = tmp_path / f"garbage{suffix}"
    path.write_bytes(bytes(range(256)) * 3)  # binary, with NUL bytes, not UTF-8
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, *words)
    assert "module" not in str(exc_info.value) and "charset" not in str(exc_info.value)


def test_binary_stl_with_a_wrong_triangle_count_says_so(tmp_path):
    path = tmp_path / "b.stl"
    path.write_bytes(b"\x00" * 80 + (5).to_bytes(4, "little") + b"\x01" * 50 * 3)
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, "5 triangles", "334 bytes", "solid")


def test_bad_image_names_the_path_and_says_it_is_not_an_image(tmp_path):
    path = tmp_path / "bad.png"
    path.write_bytes(b"this is not a picture" * 10)
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, "not a readable image")
    assert "BytesIO" not in str(exc_info.value)


def test_a_truncated_image_says_so(tmp_path):
    full = tmp_path / "full.png"
    Image.fromarray((np.arange(64 * 64).reshape(64, 64) % 256).astype(np.uint8)).save(full)
    path = tmp_path / "cut.png"
    path.write_bytes(full.read_bytes()[: len(full.read_bytes()) // 2])
    with pytest.raises(ReadError) as exc_info:
        _read_clean(path)
    _one_line(exc_info, path, "image")


@pytest.mark.parametrize("bad", [None, 5, 3.5, b"points.csv", ["a.csv"], ""])
def test_read_points_needs_a_path(bad):
    for reader in (io.read_points, io.read_mesh):
        with pytest.raises(InvalidInputError) as exc_info:
            reader(bad)
        message = str(exc_info.value)
        assert message.startswith("path: expected a file path") and "\n" not in message


@pytest.mark.parametrize("bad", [0, 2, -1, 2.5, "10", True])
def test_max_points_must_be_a_whole_number_of_at_least_3(tmp_path, bad):
    path = tmp_path / "p.xyz"
    path.write_text("0 0\n1 0\n0 1\n1 1\n")
    with pytest.raises(InvalidInputError, match="max_points"):
        io.read_points(path, max_points=bad)

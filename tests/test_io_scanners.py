"""Scanner and scene formats (issue 20): glTF/GLB, LAS/LAZ, PCD, E57, written by the tests
with the same libraries; subsampling on read; `ipfit fit` end to end on a GLB and a LAZ file."""

import os
import struct
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ipfit import io
from ipfit.exceptions import ReadError
from scanner_files import e57_file, glb_scene, las_file, pcd_file, unit
from running import quick_fit

OFFSETS = (4.5e5, 5.2e6, 300.0)


@pytest.fixture
def world_cloud(rng):
    """An ellipsoid in UTM-like world coordinates, with outward normals."""
    direction = unit(rng.normal(size=(600, 3)))
    radii = np.array([20.0, 12.0, 8.0])
    xyz = direction * radii + np.array(OFFSETS) + [50.0, 50.0, 10.0]
    normals = unit(direction / radii)
    return xyz, normals


def test_multi_mesh_glb_is_merged_with_its_node_transforms(tmp_path):
    path = tmp_path / "scene.glb"
    scene = glb_scene(path)
    # the reference: trimesh moves each mesh itself (normals with the inverse transpose)
    moved = [scene.geometry[name].copy().apply_transform(transform)
             for transform, name in (scene.graph[node] for node in scene.graph.nodes_geometry)]
    expected = np.concatenate([m.vertices for m in moved])
    expected_normals = np.concatenate([m.vertex_normals for m in moved])
    mesh = io.read_mesh(path, merge=False)
    assert len(mesh.points) == len(expected)
    assert len(mesh.faces) == sum(len(m.faces) for m in moved)
    distance, row = cKDTree(mesh.points).query(expected)  # node order need not be kept
    assert distance.max() < 1e-5 and len(set(row)) == len(expected)
    assert mesh.normals is not None
    np.testing.assert_allclose(mesh.normals[row], expected_normals, atol=1e-5)
    assert io.read_points(path).normals_source == "file"


def test_multi_mesh_3mf_is_merged_with_its_build_transforms(tmp_path):
    path = tmp_path / "scene.3mf"
    scene = glb_scene(path, "3mf")
    moved = [scene.geometry[name].copy().apply_transform(transform)
             for transform, name in (scene.graph[node] for node in scene.graph.nodes_geometry)]
    expected = np.concatenate([m.vertices for m in moved])
    mesh = io.read_mesh(path, merge=False)
    assert len(mesh.points) == len(expected) and len(mesh.faces) == sum(len(m.faces) for m in moved)
    distance, row = cKDTree(mesh.points).query(expected)
    assert distance.max() < 1e-5 and len(set(row)) == len(expected)
    cloud = io.read_points(path)
    assert cloud.normals_source == "faces"  # 3MF stores no normals


def test_multi_mesh_collada_is_merged(tmp_path):
    import trimesh

    path = tmp_path / "scene.dae"
    moved = [trimesh.creation.box(extents=[1.0, 2.0, 3.0]).apply_translation([5.0, 0.0, -1.0]),
             trimesh.creation.icosphere(subdivisions=1).apply_scale(2.0)]
    path.write_bytes(trimesh.exchange.dae.export_collada(moved))
    expected = np.concatenate([m.vertices for m in moved])
    mesh = io.read_mesh(path, merge=False)
    assert len(mesh.faces) == sum(len(m.faces) for m in moved)
    distance, _ = cKDTree(mesh.points).query(expected)
    assert distance.max() < 1e-5  # every transformed vertex is read where the scene put it


def test_glb_without_normals_takes_them_from_the_faces(tmp_path):
    path = tmp_path / "ball.glb"
    ball = trimesh.creation.icosphere(subdivisions=2)
    path.write_bytes(trimesh.Scene(ball).export(file_type="glb", include_normals=False))
    cloud = io.read_points(path)
    assert cloud.normals_source == "faces"
    np.testing.assert_allclose(np.einsum("ij,ij->i", cloud.normals, unit(cloud.points)), 1.0, atol=0.02)


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_keeps_float64_world_coordinates_and_normals(tmp_path, world_cloud, suffix):
    xyz, normals = world_cloud
    path = tmp_path / f"scan{suffix}"
    stored = las_file(path, xyz, normals, offsets=OFFSETS)
    cloud = io.read_points(path, merge=False)
    assert cloud.points.dtype == np.float64 and cloud.n_file == len(xyz)
    np.testing.assert_allclose(cloud.points, stored, rtol=1e-9)
    assert np.abs(cloud.points - xyz).max() <= 0.5e-3 + 1e-9  # the file's 1 mm scale
    assert cloud.normals_source == "file"
    np.testing.assert_allclose(cloud.normals, normals, atol=1e-12)


def test_las_without_normals_has_none(tmp_path, world_cloud):
    path = tmp_path / "plain.laz"
    las_file(path, world_cloud[0])
    cloud = io.read_points(path)
    assert cloud.normals is None and cloud.normals_source is None


@pytest.mark.parametrize("encoding", ["ascii", "binary", "binary_compressed"])
def test_pcd_points_and_normals(tmp_path, world_cloud, encoding):
    xyz, normals = world_cloud
    path = tmp_path / f"cloud_{encoding}.pcd"
    pcd_file(path, xyz, normals, encoding)
    cloud = io.read_points(path, merge=False)
    tolerance = 1e-9 if encoding == "ascii" else 0.0  # ASCII PCD prints fewer digits
    np.testing.assert_allclose(cloud.points, xyz, rtol=tolerance, atol=0)
    np.testing.assert_allclose(cloud.normals, normals, atol=1e-6 if encoding == "ascii" else 1e-15)
    assert cloud.normals_source == "file"


def test_pcd_without_normals(tmp_path, world_cloud):
    path = tmp_path / "xyz.pcd"
    pcd_file(path, world_cloud[0], None, "binary")
    assert io.read_points(path).normals is None


def test_e57_with_normals_and_scan_poses(tmp_path, world_cloud):
    xyz, normals = world_cloud
    turn = Rotation.from_euler("zyx", [30, 10, -5], degrees=True)
    w_last = turn.as_quat()
    pose = ((w_last[3], *w_last[:3]), xyz[0])
    local = xyz[:100] - xyz[0]
    path = tmp_path / "scan.e57"
    e57_file(path, [(xyz, normals, None), (local, normals[:100], pose)])
    cloud = io.read_points(path, merge=False)
    assert cloud.n_file == 700 and cloud.normals_source == "file"
    np.testing.assert_allclose(cloud.points[:600], xyz, rtol=1e-12)
    np.testing.assert_allclose(cloud.points[600:], turn.apply(local) + xyz[0], rtol=1e-12)
    np.testing.assert_allclose(cloud.normals[:600], normals, atol=1e-12)
    np.testing.assert_allclose(cloud.normals[600:], turn.apply(normals[:100]), atol=1e-12)


def test_e57_without_normals(tmp_path, world_cloud):
    path = tmp_path / "plain.e57"
    e57_file(path, [(world_cloud[0], None, None)])
    cloud = io.read_points(path)
    assert cloud.normals is None and len(cloud.points) == 600


def test_max_points_keeps_a_fixed_subset_and_records_the_counts(tmp_path, world_cloud):
    xyz, normals = world_cloud
    path = tmp_path / "big.laz"
    stored = las_file(path, xyz, normals)
    a = io.read_points(path, max_points=100)
    b = io.read_points(path, max_points=100)
    c = io.read_points(path, max_points=100, rng=1)
    assert (a.n_file, a.n_kept) == (600, 100)
    np.testing.assert_array_equal(a.points, b.points)  # the same seed, the same subset
    assert not np.array_equal(a.points, c.points)
    # a subset of the file's rows, in file order, each with its own normal
    rows = [int(np.flatnonzero((stored == p).all(axis=1))[0]) for p in a.points]
    assert rows == sorted(rows)
    np.testing.assert_allclose(a.normals, normals[rows], atol=1e-12)
    assert io.read_points(path, max_points=10_000).n_kept == 600


def test_max_points_on_a_mesh_keeps_face_normals(tmp_path):
    path = tmp_path / "ball.glb"
    path.write_bytes(trimesh.Scene(trimesh.creation.icosphere(subdivisions=3)).export(file_type="glb",
                                                                                      include_normals=False))
    cloud = io.read_points(path, max_points=50)
    assert cloud.n_kept == 50 and cloud.n_file == 642 and cloud.normals_source == "faces"
    np.testing.assert_allclose(np.einsum("ij,ij->i", cloud.normals, unit(cloud.points)), 1.0, atol=0.01)


@pytest.mark.parametrize("suffix", [".las", ".pcd", ".e57", ".glb", ".3mf"])
def test_corrupted_scanner_files_give_one_line(tmp_path, suffix):
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(b"LASF" + b"\x07" * 300 if suffix == ".las" else b"\x00garbage" * 40)
    with pytest.raises(ReadError) as exc_info:
        io.read_points(path)
    message = str(exc_info.value)
    assert message.startswith(str(path)) and "\n" not in message


def test_a_missing_scanner_library_names_the_extra(tmp_path, monkeypatch):
    import sys

    path = tmp_path / "scan.pcd"
    path.write_text("not used")
    monkeypatch.setitem(sys.modules, "pypcd4", None)  # as if not installed: import fails
    with pytest.raises(ReadError, match=r"needs the 'pypcd4' package.*pip install 'ipfit\[scanners\]'"):
        io.read_points(path)


def test_fit_end_to_end_on_a_glb(tmp_path):
    path = tmp_path / "ball.glb"
    ball = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    ball.apply_translation([10.0, -4.0, 1.0])
    path.write_bytes(trimesh.Scene(ball).export(file_type="glb"))
    result = quick_fit(tmp_path, path)
    assert result["selected_degree"] == 2 and result["dim"] == 3


def test_fit_end_to_end_on_a_laz_with_max_points(tmp_path, world_cloud, capsys):
    path = tmp_path / "scan.laz"
    las_file(path, *world_cloud)
    result = quick_fit(tmp_path, path, "--max-points", "300")
    assert result["selected_degree"] == 2 and result["input"]["n_points"] == 300
    assert "kept 300 of the file's 600 points" in capsys.readouterr().err


def test_fit_max_points_on_a_bundled_dataset(tmp_path, capsys):
    result = quick_fit(tmp_path, "bunny_res4", "--max-points", "100")
    assert result["selected_degree"] == 2 and result["input"]["n_points"] == 100
    assert "kept 100 of its 453 points" in capsys.readouterr().err


# -- PCD headers that announce more than the file holds (the OOM of the slow fuzz test) -----------

def _pcd_bytes(points=4, width=None, height=1, size="4 4 4", count="1 1 1", data="ascii", body=None):
    """A hand-made PCD file with fields x y z; the header's values are taken as given."""
    header = (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE {size}\nTYPE F F F\n"
              f"COUNT {count}\nWIDTH {points if width is None else width}\nHEIGHT {height}\n"
              f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n").encode()
    xyz = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    if body is None:
        body = b"".join(f"{x} {y} {z}\n".encode() for x, y, z in xyz) if data == "ascii" else xyz.tobytes()
    return header + body


_BAD_PCD = {
    "points_1e12_ascii": (_pcd_bytes(points=10**12), r"announces 1000000000000 points but only 4 lines"),
    "points_1e12_binary": (_pcd_bytes(points=10**12, data="binary"), r"1000000000000 points of 12 bytes but"),
    # 83,333,333,334 points of 12 bytes: 10**12 bytes, with size fields at their 32-bit maximum
    "points_1e12_compressed": (_pcd_bytes(points=83_333_333_334, data="binary_compressed",
                                          body=struct.pack("<II", 16, 2**32 - 1) + bytes(16)),
                               r"announces 4294967295 bytes from 16 compressed bytes, but 83333333334 points"),
    "compressed_size_beyond_file": (_pcd_bytes(data="binary_compressed",
                                               body=struct.pack("<II", 2**32 - 1, 48) + bytes(48)),
                                    r"4294967295 bytes of compressed data but the file holds only 48"),
    "uncompressed_size_beyond_points": (_pcd_bytes(data="binary_compressed",
                                                   body=struct.pack("<II", 40, 2**32 - 1) + bytes(40)),
                                        r"announces 4294967295 bytes from 40 compressed bytes, but 4 points"),
    "width_x_height_not_points": (_pcd_bytes(points=4, width=4, height=2), r"WIDTH 4 x HEIGHT 2 but POINTS 4"),
    "count_1e9": (_pcd_bytes(count="1 1 1000000000"), r"COUNT 1 1 1000000000;.*at most 100000 values"),
    # 30,000 short lines announced as 100,000 values each: a 24 GB table from 180 kB of text
    "wide_ascii_rows": (_pcd_bytes(points=30_000, count="1 1 99998", body=b"0 0 0\n" * 30_000),
                        r"30000 points of 100000 values each, but 180000 bytes of text cannot hold"),
    "count_huge_binary": (_pcd_bytes(count="2147483648 1 1", data="binary"), r"COUNT 2147483648 1 1;"),
    "size_3": (_pcd_bytes(size="4 4 3"), r"field 'z' .* SIZE 3; PCD fields are F of 4 or 8 bytes"),
    "count_missing_a_field": (_pcd_bytes(count="1 1"), r"3 FIELDS, 3 SIZE, 3 TYPE and 2 COUNT values"),
    "negative_points": (_pcd_bytes(points=-1, width=4), r"POINTS '-1' in the PCD header is not a whole number"),
    "no_data_line": (_pcd_bytes().replace(b"DATA ascii\n", b""), r"no DATA line ends the PCD header"),
}


def test_hand_made_pcd_files_read(tmp_path):
    """The builder of the bad headers below makes valid files when its values agree."""
    for data in ("ascii", "binary"):
        path = tmp_path / f"ok_{data}.pcd"
        path.write_bytes(_pcd_bytes(data=data))
        assert len(io.read_points(path, merge=False).points) == 4
    path = tmp_path / "organized.pcd"  # WIDTH x HEIGHT = POINTS, an organized cloud
    path.write_bytes(_pcd_bytes(points=4, width=2, height=2))
    assert len(io.read_points(path, merge=False).points) == 4


@pytest.mark.parametrize("case", sorted(_BAD_PCD))
def test_pcd_header_announcing_more_than_the_file_raises_fast(tmp_path, case):
    pytest.importorskip("pypcd4")
    data, message = _BAD_PCD[case]
    path = tmp_path / f"{case}.pcd"
    path.write_bytes(data)
    start = time.perf_counter()
    with pytest.raises(ReadError, match=message) as exc_info:
        io.read_points(path)
    assert time.perf_counter() - start < 0.5
    text = str(exc_info.value)
    assert text.startswith(str(path)) and "\n" not in text and len(text) < 300


def test_pcd_header_checks_allocate_nothing(tmp_path):
    """Under a 1.5 GB address-space limit every bad header gives a ReadError, not a MemoryError
    (which read_points would also turn into a ReadError) nor a kill."""
    pytest.importorskip("pypcd4")
    pytest.importorskip("resource")  # the limit is POSIX only
    for case, (data, _) in _BAD_PCD.items():
        (tmp_path / f"{case}.pcd").write_bytes(data)
    script = textwrap.dedent(f"""
        import resource, sys
        from pathlib import Path
        import pypcd4
        from ipfit import io
        from ipfit.exceptions import ReadError
        resource.setrlimit(resource.RLIMIT_AS, ({int(1.5 * 2**30)}, {int(1.5 * 2**30)}))
        for path in sorted(Path({str(tmp_path)!r}).glob("*.pcd")):
            try:
                io.read_points(path)
            except ReadError as exc:
                assert "more data than fits in memory" not in str(exc), exc
            else:
                sys.exit(f"{{path}} was read")
        print("ok")
    """)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]

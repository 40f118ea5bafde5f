"""Scanner and scene formats (issue 20): glTF/GLB, LAS/LAZ, PCD, E57, written by the tests
with the same libraries; subsampling on read; `ipfit fit` end to end on a GLB and a LAZ file."""

import json

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ipfit import io
from ipfit.cli import main
from ipfit.exceptions import ReadError
from scanner_files import e57_file, glb_scene, las_file, pcd_file, unit

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


def _fit(tmp_path, path, *extra):
    prefix = tmp_path / "out" / "fit"
    code = main(["fit", str(path), "-o", str(prefix), "--degree", "2", "--method", "3l", "--no-picture",
                 "--no-zero-set", "-q", *extra])
    assert code == 0
    return json.loads(prefix.with_suffix(".json").read_text())


def test_fit_end_to_end_on_a_glb(tmp_path):
    path = tmp_path / "ball.glb"
    ball = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    ball.apply_translation([10.0, -4.0, 1.0])
    path.write_bytes(trimesh.Scene(ball).export(file_type="glb"))
    result = _fit(tmp_path, path)
    assert result["selected_degree"] == 2 and result["dim"] == 3


def test_fit_end_to_end_on_a_laz_with_max_points(tmp_path, world_cloud, capsys):
    path = tmp_path / "scan.laz"
    las_file(path, *world_cloud)
    result = _fit(tmp_path, path, "--max-points", "300")
    assert result["selected_degree"] == 2 and result["input"]["n_points"] == 300
    assert "kept 300 of the file's 600 points" in capsys.readouterr().err


def test_fit_max_points_on_a_bundled_dataset(tmp_path, capsys):
    result = _fit(tmp_path, "bunny_res4", "--max-points", "100")
    assert result["selected_degree"] == 2 and result["input"]["n_points"] == 100
    assert "kept 100 of its 453 points" in capsys.readouterr().err

"""Geometry objects of trimesh, Open3D, PyVista and pandas give the same fits as their arrays (issue 35).

The real packages, no stand-ins: each object is built by its library, fitted, and the fit compared
bit for bit with the fit of the arrays the object holds (the same code path after conversion).
"""

from __future__ import annotations

import numpy as np
import pytest

import ipfit
from ipfit.exceptions import InvalidInputError

trimesh = pytest.importorskip("trimesh")


def _open3d():
    try:
        import open3d
    except ImportError as exc:  # the wheel needs libusb-1.0 (Debian: libusb-1.0-0, installed by .ci/run)
        pytest.skip(f"open3d cannot be imported here: {exc}")
    return open3d


def _ellipsoid_mesh():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.apply_scale([1.0, 0.7, 0.5])
    return mesh


def _same_fit(a, b):
    assert a.selected_degree == b.selected_degree
    np.testing.assert_array_equal(a.x, b.x)


def _fit(points, normals=None, faces=None):
    return ipfit.fit_adaptive(points, normals, faces=faces, max_degree=4, method="3l", rng=0, outliers="none")


def test_trimesh_mesh_fits_as_its_vertices_normals_and_faces():
    mesh = _ellipsoid_mesh()
    arrays = (np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals), np.asarray(mesh.faces))
    _same_fit(_fit(mesh), _fit(*arrays))
    full = ipfit.fit_adaptive(mesh, max_degree=4, rng=0)  # the recommended pipeline, once
    _same_fit(full, ipfit.fit_adaptive(arrays[0], arrays[1], faces=arrays[2], max_degree=4, rng=0))
    # the ellipsoid x² + y²/0.49 + z²/0.25 = 1 (vertices on it to the icosphere's facets)
    assert full.selected_degree == 2
    assert np.max(np.abs(full.polynomial.residuals(arrays[0]))) < 0.05


def test_trimesh_point_cloud_gives_points_only():
    mesh = _ellipsoid_mesh()
    cloud = trimesh.PointCloud(mesh.vertices)
    _same_fit(_fit(cloud), _fit(np.asarray(mesh.vertices)))  # normals estimated in both


def test_explicit_normals_take_the_place_of_the_objects():
    mesh = _ellipsoid_mesh()
    flipped = -np.asarray(mesh.vertex_normals)
    _same_fit(_fit(mesh, flipped), _fit(np.asarray(mesh.vertices), flipped, np.asarray(mesh.faces)))


def test_open3d_point_cloud_and_mesh():
    o3d = _open3d()
    mesh = _ellipsoid_mesh()
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(mesh.vertices)))
    _same_fit(_fit(pcd), _fit(np.asarray(mesh.vertices)))
    normals = np.array(mesh.vertex_normals)  # a writeable copy: Open3D refuses trimesh's read-only cache
    pcd.normals = o3d.utility.Vector3dVector(normals)
    _same_fit(_fit(pcd), _fit(np.asarray(mesh.vertices), normals))
    tri = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(mesh.vertices)),
                                    o3d.utility.Vector3iVector(np.asarray(mesh.faces)))
    tri.compute_vertex_normals()
    _same_fit(_fit(tri), _fit(np.asarray(tri.vertices), np.asarray(tri.vertex_normals), np.asarray(tri.triangles)))


def test_pyvista_polydata():
    pv = pytest.importorskip("pyvista")
    mesh = _ellipsoid_mesh()
    cells = np.column_stack([np.full(len(mesh.faces), 3), mesh.faces]).ravel()
    poly = pv.PolyData(np.asarray(mesh.vertices, float), cells)
    _same_fit(_fit(poly), _fit(np.asarray(poly.points), None, np.asarray(mesh.faces)))
    with_normals = poly.compute_normals(point_normals=True, cell_normals=False, auto_orient_normals=True)
    _same_fit(_fit(with_normals), _fit(np.asarray(with_normals.points), np.asarray(with_normals.point_data["Normals"]),
                                       np.asarray(with_normals.faces).reshape(-1, 4)[:, 1:]))
    points_only = pv.PolyData(np.asarray(mesh.vertices, float))
    _same_fit(_fit(points_only), _fit(np.asarray(mesh.vertices)))
    quads = pv.Plane(i_resolution=3, j_resolution=3)  # quadrilaterals: one line, asking to triangulate
    with pytest.raises(InvalidInputError, match=r"^faces: expected triangles.*triangulate\(\)"):
        ipfit.fit_adaptive(quads, max_degree=2)


def test_dataframe_with_normal_columns():
    pd = pytest.importorskip("pandas")
    mesh = _ellipsoid_mesh()
    v, n = np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals)
    frame = pd.DataFrame({"X": v[:, 0], "y": v[:, 1], "z": v[:, 2], "nx": n[:, 0], "ny": n[:, 1], "nz": n[:, 2],
                          "label": "a"})
    _same_fit(_fit(frame), _fit(v, n))
    _same_fit(_fit(frame[["X", "y", "z"]]), _fit(v))


def test_load_refine_and_linear_fits_take_objects():
    mesh = _ellipsoid_mesh()
    cloud = ipfit.load(mesh)
    np.testing.assert_array_equal(cloud.points, mesh.vertices)
    np.testing.assert_array_equal(cloud.faces, mesh.faces)
    assert cloud.name == "Trimesh" and cloud.source == "trimesh.Trimesh"
    assert len(ipfit.load(mesh, max_points=50)) == 50
    v, n = np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals)
    np.testing.assert_array_equal(ipfit.fit_3l(mesh, None, 2).coefficients, ipfit.fit_3l(v, n, 2).coefficients)
    a = ipfit.refine(mesh, None, 2, method="polish", rng=0)
    b = ipfit.refine(v, n, 2, method="polish", rng=0)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(ipfit.estimate_normals(trimesh.PointCloud(v)), ipfit.estimate_normals(v))


def test_unknown_object_of_a_known_library_is_one_line():
    path = trimesh.load_path(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]))
    with pytest.raises(InvalidInputError) as info:
        ipfit.fit_adaptive(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith("points: expected points as an array, a Cloud or one of")
    assert "Path3D" in message


@pytest.mark.parametrize("library", ["trimesh", "open3d", "pyvista"])
def test_zero_set_to_other_libraries(library):
    mesh = _ellipsoid_mesh()
    zs = ipfit.extract_zero_set(_fit(mesh).polynomial, resolution=24)
    if library == "open3d":
        _open3d()
        out = zs.to_open3d()
        vertices, faces = np.asarray(out.vertices), np.asarray(out.triangles)
    elif library == "pyvista":
        pytest.importorskip("pyvista")
        out = zs.to_pyvista()
        vertices, faces = np.asarray(out.points), np.asarray(out.faces).reshape(-1, 4)[:, 1:]
    else:
        out = zs.to_trimesh()
        vertices, faces = np.asarray(out.vertices), np.asarray(out.faces)
    np.testing.assert_array_equal(vertices, zs.vertices)
    np.testing.assert_array_equal(faces, zs.faces)
    # the surface is the ellipsoid: its vertices satisfy x² + (y/0.7)² + (z/0.5)² ≈ 1
    level = vertices[:, 0] ** 2 + (vertices[:, 1] / 0.7) ** 2 + (vertices[:, 2] / 0.5) ** 2
    assert np.all(np.abs(level - 1.0) < 0.1)


def test_a_2d_zero_set_is_not_a_mesh():
    boot = ipfit.load("boot")
    zs = ipfit.extract_zero_set(ipfit.fit_3l(boot.points, boot.normals, 4), resolution=32)
    for convert in (zs.to_trimesh, zs.to_pyvista, zs.to_open3d):
        with pytest.raises(InvalidInputError, match="^zero set: expected a 3D zero set"):
            convert()


def test_trimesh_arrays_are_arrays():
    """trimesh's TrackedArray (mesh.vertices) is an ndarray subclass, not an object to unpack."""
    mesh = _ellipsoid_mesh()
    assert type(mesh.vertices).__module__.startswith("trimesh")
    np.testing.assert_array_equal(ipfit.fit_3l(mesh.vertices, mesh.vertex_normals, 2).coefficients,
                                  ipfit.fit_3l(np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals), 2).coefficients)

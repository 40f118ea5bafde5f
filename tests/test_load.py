"""ipfit.load and ipfit.Cloud: the one loader of a point file or a bundled dataset.

The CLI, fit_many and the scripts read their data through it, so these tests pin what it
gives: the same points, normals, faces and fixed-seed subsample as the readers, the file read
once, nothing printed, one-line errors; and the CLI's own "kept N of M" line.
"""


import numpy as np
import pytest
import trimesh

import ipfit
from ipfit.datasets import dataset_faces, load_dataset
from ipfit.exceptions import InvalidInputError, ReadError
from ipfit.io import readers
from running import quick_fit


def _circle(n=600):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([np.cos(t), np.sin(t)]), np.column_stack([np.cos(t), np.sin(t)])


def _same_rows_as_todays_subsample(n, max_points):
    # the draw `ipfit fit --max-points` has always made: seed 0, without replacement, order kept
    return np.sort(np.random.default_rng(0).choice(n, max_points, replace=False))


def test_a_bundled_3d_dataset_has_points_normals_faces_and_its_name(capsys):
    cloud = ipfit.load("Bunny_Res4")  # names ignore case
    points, normals = load_dataset("bunny_res4")
    assert isinstance(cloud, ipfit.Cloud)
    assert cloud.name == cloud.source == "bunny_res4"
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.normals, normals)
    np.testing.assert_array_equal(cloud.faces, dataset_faces("bunny_res4"))
    assert (cloud.dim, len(cloud), cloud.n_file, cloud.normals_source) == (3, 453, 453, "faces")
    assert capsys.readouterr() == ("", "")


def test_a_bundled_contour_has_contour_normals_and_no_faces():
    cloud = ipfit.load("boot")
    assert (cloud.dim, cloud.faces, cloud.normals_source, cloud.n_file) == (2, None, "contour", len(cloud))
    np.testing.assert_array_equal(cloud.normals, load_dataset("boot").normals)


def test_the_arrays_are_read_only():
    cloud = ipfit.load("boot")
    for arr in (cloud.points, cloud.normals):
        with pytest.raises(ValueError, match="read-only"):
            arr[0, 0] = 1.0
    with pytest.raises(AttributeError):
        cloud.points = None  # frozen
    assert ipfit.load("boot").points.flags.writeable is False  # not changed by the attempt either


def test_a_csv_written_by_write_points_comes_back_as_read_points_reads_it(tmp_path, capsys):
    points, normals = _circle()
    path = ipfit.write_points(tmp_path / "circle.csv", points, normals)
    for spec in (str(path), path):  # a str or a Path
        cloud = ipfit.load(spec)
        expected = ipfit.read_points(path)
        np.testing.assert_array_equal(cloud.points, expected.points)
        np.testing.assert_array_equal(cloud.normals, expected.normals)
        assert (cloud.name, cloud.source, cloud.faces, cloud.normals_source) == ("circle", path, None, "file")
        assert cloud.n_file == len(cloud) == 600
    assert capsys.readouterr() == ("", "")


def test_a_ply_mesh_gives_its_faces_from_one_read_of_the_file(tmp_path, monkeypatch):
    path = tmp_path / "ball.ply"
    ball = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    path.write_bytes(ball.export(file_type="ply"))
    mesh, expected = ipfit.read_mesh(path), ipfit.read_points(path)

    reads = []
    read_bytes = readers._read_bytes
    monkeypatch.setattr(readers, "_read_bytes", lambda p: reads.append(p) or read_bytes(p))
    cloud = ipfit.load(str(path))
    assert reads == [path]  # once: points, normals and faces from the same bytes
    np.testing.assert_array_equal(cloud.points, mesh.points)
    np.testing.assert_array_equal(cloud.faces, mesh.faces)
    np.testing.assert_array_equal(cloud.normals, expected.normals)
    assert (cloud.normals_source, len(cloud.faces)) == ("faces", len(ball.faces))


def test_max_points_keeps_the_same_rows_as_before_and_counts_the_source(tmp_path, capsys):
    cloud = ipfit.load("boot", max_points=300)
    n = len(load_dataset("boot").points)
    keep = _same_rows_as_todays_subsample(n, 300)
    np.testing.assert_array_equal(cloud.points, load_dataset("boot").points[keep])
    np.testing.assert_array_equal(cloud.normals, load_dataset("boot").normals[keep])
    assert (len(cloud), cloud.n_file) == (300, n)

    mesh = ipfit.load("bunny_res4", max_points=100)
    assert (len(mesh), mesh.n_file, mesh.faces) == (100, 453, None)  # the faces indexed the dropped points

    points, normals = _circle()
    path = ipfit.write_points(tmp_path / "circle.csv", points, normals)
    from_file = ipfit.load(str(path), max_points=250)
    keep = _same_rows_as_todays_subsample(600, 250)
    np.testing.assert_array_equal(from_file.points, ipfit.read_points(path).points[keep])
    np.testing.assert_array_equal(from_file.points, ipfit.read_points(path, max_points=250).points)
    assert (len(from_file), from_file.n_file) == (250, 600)

    assert len(ipfit.load("boot", max_points=10**6)) == n  # nothing to drop
    assert capsys.readouterr() == ("", "")  # the counts are attributes, never printed


def test_another_seed_draws_other_rows():
    assert not np.array_equal(ipfit.load("boot", max_points=300, rng=1).points, ipfit.load("boot", max_points=300).points)


@pytest.mark.parametrize("bad", [2, 0, 1.5, "10", True])
def test_max_points_is_a_whole_number_of_at_least_3_for_datasets_too(bad):
    with pytest.raises(InvalidInputError, match="max_points"):
        ipfit.load("boot", max_points=bad)


def test_an_unknown_name_is_one_line_with_the_nearest_name():
    with pytest.raises(ReadError) as info:
        ipfit.load("bunyy")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("bunyy: no such file, nor a bundled dataset name (") and "Did you mean 'bunny'?" in message


def test_a_missing_path_is_one_line(tmp_path):
    with pytest.raises(ReadError, match="no such file, nor a bundled dataset name") as info:
        ipfit.load(str(tmp_path / "missing.csv"))
    assert "\n" not in str(info.value)
    with pytest.raises(ReadError, match="no such file. Check the path"):  # a Path is never a dataset's name
        ipfit.load(tmp_path / "boot.csv")


@pytest.mark.parametrize("bad", [None, 3, b"boot", ""])
def test_a_spec_that_is_no_path_is_refused_by_name(bad):
    with pytest.raises(InvalidInputError, match="spec"):
        ipfit.load(bad)


def test_a_cloud_built_in_code_checks_its_arrays_and_leaves_the_callers_writable():
    points, normals = _circle(10)
    cloud = ipfit.Cloud(points, normals, name="circle")
    assert (cloud.normals_source, cloud.n_file, cloud.source) == ("file", 10, None)
    points[0, 0] = 5.0  # the caller's array stays writable (the cloud holds a read-only view)
    assert "10 2D points" in repr(cloud)
    assert ipfit.Cloud(points).normals_source is None
    with pytest.raises(InvalidInputError, match="normals"):
        ipfit.Cloud(points, normals[:5])
    with pytest.raises(InvalidInputError, match="faces"):
        ipfit.Cloud(np.zeros((3, 3)), faces=[[0, 1, 3]])
    with pytest.raises(InvalidInputError, match="n_file"):
        ipfit.Cloud(points, n_file=5)


def test_the_cli_prints_its_kept_line_from_the_counts(tmp_path, capsys):
    result = quick_fit(tmp_path, "boot", "--max-points", "300")
    assert result["input"]["n_points"] == 300
    assert capsys.readouterr().err == "ipfit: boot: kept 300 of its 1,354 points (--max-points, fixed seed)\n"

    points, normals = _circle()
    path = ipfit.write_points(tmp_path / "circle.csv", points, normals)
    quick_fit(tmp_path, path, "--max-points", "250")
    assert capsys.readouterr().err == (f"ipfit: {path}: kept 250 of the file's 600 points "
                                       "(--max-points 250, fixed seed)\n")
    quick_fit(tmp_path, path, "--max-points", "1000")
    assert capsys.readouterr().err == ""

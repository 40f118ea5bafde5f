"""The bundled datasets: names, credits, files, points and reference normals."""

import hashlib
from pathlib import Path
import numpy as np
import pytest

from ipfit.datasets import bundled
from ipfit.exceptions import InvalidInputError
from ipfit.normals import contour_normals

EXPECTED = {"bunny": 35_947, "bunny_res2": 8_171, "bunny_res3": 1_889, "bunny_res4": 453, "apple": 867,
            "duck": 5_482, "boot": 1_354, "airplane": 200, "butterfly": 3_214}


def test_list_datasets():
    infos = bundled.list_datasets()
    assert [i.name for i in infos] == list(EXPECTED) == bundled.dataset_names()
    for info in infos:
        name, dim, description, credit = info  # unpacks as 4
        assert dim in (2, 3) and description and credit
        assert bundled.dataset_path(name).is_file()
    credits = (bundled.DATA_DIR / "CREDITS.md").read_text()
    for phrase in ("Stanford", "Turk", "MPEG-7", "Kimia", "LINEMOD"):
        assert phrase in credits


@pytest.mark.parametrize("name", list(EXPECTED))
def test_load_dataset(name):
    points, normals = bundled.load_dataset(name)
    dim = 2 if name in ("boot", "airplane", "butterfly") else 3
    assert points.shape == (EXPECTED[name], dim) and normals.shape == points.shape
    assert np.isfinite(points).all()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    faces = bundled.dataset_faces(name)
    if dim == 2:
        assert faces is None
    else:
        assert faces.ndim == 2 and faces.shape[1] == 3 and faces.max() < len(points)
    # outward: on a closed shape most normals point away from the centroid
    assert np.mean(np.einsum("ij,ij->i", normals, points - points.mean(axis=0)) > 0) > 0.8


def test_loaded_arrays_are_independent_copies():
    a, na = bundled.load_dataset("airplane")
    a[:] = 0
    na[:] = 0
    b, nb = bundled.load_dataset("airplane")
    assert np.abs(b).sum() > 0 and np.abs(nb).sum() > 0


def test_contour_normals_come_from_the_order():
    points, normals = bundled.load_dataset("boot")
    np.testing.assert_allclose(normals, contour_normals(points, span=2))


def test_bundled_files_are_the_published_ones():
    """Checksums of the files as published (tests/data/bundled.sha256): a damaged or edited copy fails."""
    manifest = (Path(__file__).with_name("data") / "bundled.sha256").read_text().split("\n")
    expected = dict(reversed(line.split()) for line in manifest if line)
    on_disk = {f"{p.parent.name}/{p.name}": hashlib.sha256(p.read_bytes()).hexdigest()
               for p in bundled.DATA_DIR.glob("*/*")}
    assert on_disk == expected


def test_datasets_formats_lists_every_readable_suffix(capsys):
    from ipfit import io
    from ipfit.cli import main

    assert main(["datasets", "--formats"]) == 0
    out = capsys.readouterr().out
    for suffix in io.READ_FORMATS:
        assert f" {suffix}" in out or f"{suffix} " in out, suffix
    for library in ("plyfile", "trimesh", "laspy + lazrs", "pypcd4", "pye57", "ipfit[scanners]"):
        assert library in out


@pytest.mark.parametrize("name", ["rabbit", "", None, 3])
def test_unknown_name(name):
    with pytest.raises(InvalidInputError, match="bunny"):
        bundled.load_dataset(name)
    with pytest.raises(InvalidInputError):
        bundled.dataset_path(name)

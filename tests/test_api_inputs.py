"""What the public API accepts as points and normals, and how it refuses the rest (issue: the
hostile-user campaign): one InvalidInputError line from ipfit's validator, never numpy's or
pandas' exception and never a warning; and silhouette images checked against MAX_IMAGE_PIXELS
from their header, before anything is decoded."""

import os
import struct
import subprocess
import sys
import warnings
import zlib

import numpy as np
import pandas as pd
import pytest

import ipfit
from ipfit.datasets import synthetic
from ipfit.exceptions import InvalidInputError, IpfitError
from ipfit.io.silhouettes import MAX_IMAGE_PIXELS, trace_silhouette
from ipfit.zeroset.quality import stray_samples

SRC = os.path.join(os.path.dirname(__file__), os.pardir, "src")


@pytest.fixture(scope="module")
def circle():
    shape = synthetic.circle(80)
    return shape.points, shape.normals


@pytest.fixture(scope="module")
def poly(circle):
    return ipfit.fit_3l(*circle, 2)


def _strict(call, *args, **kwargs):
    """Run ``call`` with every warning an error: a leaked numpy or pandas warning fails."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return call(*args, **kwargs)


def _refused(call, *words, name="points"):
    with pytest.raises(InvalidInputError) as info:
        _strict(call)
    message = str(info.value)
    assert isinstance(info.value, (IpfitError, ValueError))
    assert "\n" not in message and message.startswith(f"{name}: expected "), message
    for word in words:
        assert word in message, message
    return message


def _bad_inputs(points):
    """(label, value, words of the message) for inputs that hold no coordinates."""
    masked = np.ma.masked_invalid(np.vstack([points, [[np.nan, 0.0]]]))
    return [
        ("booleans", points > 0, ["booleans", "not a mask"]),
        ("complex", points + 0j, ["complex numbers"]),
        ("text", points.astype(str), ["text"]),
        ("objects", points.astype(object), ["Python objects"]),
        ("dates", np.zeros(points.shape, dtype="datetime64[s]"), ["dates"]),
        ("generator", (row for row in points), ["an iterator (generator)", "np.array(list(points))"]),
        ("iterator", iter(points.tolist()), ["an iterator"]),
        ("ragged", [[0.0, 1.0], [2.0]], ["list [[0.0, 1.0], [2.0]]"]),
        ("masked", masked, ["1 row with masked values (first at row 80)", "np.ma.compress_rows"]),
        ("frame without x, y", pd.DataFrame(points), ["a DataFrame with columns x, y[, z]", "got columns 0, 1"]),
        ("frame with text y", pd.DataFrame({"x": points[:, 0], "y": ["a"] * len(points)}),
         ["numeric columns x, y", "column y of dtype"]),
        ("frame with x twice", pd.DataFrame(np.c_[points, points[:, 0]], columns=["x", "y", "X"]),
         ["2 columns named x"]),
        ("file name", "points.csv", ["ipfit.read_points(path)"]),
        ("None", None, ["got None"]),
        ("dict", {"x": [1.0], "y": [2.0]}, ["got a dict"]),
        ("scalar", 3.0, ["got shape ()"]),
        ("1-D", points[:, 0], [f"got shape ({len(points)},)"]),
        ("3-D", points[None], [f"got shape (1, {len(points)}, 2)"]),
        ("4 columns", np.c_[points, points], [f"got shape ({len(points)}, 4)"]),
        ("empty", np.zeros((0, 2)), ["got 0"]),
        ("NaN", np.vstack([points, [[np.nan, 1.0]]]), ["1 rows with NaN or inf (first at row 80)"]),
        ("inf", np.vstack([[np.inf, 1.0], points]), ["(first at row 0)"]),
    ]


_CALLS = {
    "fit_3l": lambda p, n, poly: ipfit.fit_3l(p, n, 2),
    "fit_lstsq": lambda p, n, poly: ipfit.fit_lstsq(p, None, 2),
    "fit_linear": lambda p, n, poly: ipfit.fit_linear(p, n, 2, "3l"),
    "fit_adaptive": lambda p, n, poly: ipfit.fit_adaptive(p, n, method="3l", max_degree=2),
    "refine": lambda p, n, poly: ipfit.refine(p, n, 2, method="3l"),
    "estimate_normals": lambda p, n, poly: ipfit.estimate_normals(p),
    "orient_normals": lambda p, n, poly: ipfit.orient_normals(p, n),
    "quality": lambda p, n, poly: ipfit.quality(poly, p),
    "stray_samples": lambda p, n, poly: stray_samples(poly, p),
    "poly()": lambda p, n, poly: poly(p),
    "poly.gradient": lambda p, n, poly: poly.gradient(p),
    "poly.contains": lambda p, n, poly: poly.contains(p),
    "poly.project": lambda p, n, poly: poly.project(p),
    "extract_zero_set": lambda p, n, poly: ipfit.extract_zero_set(poly, points=p),
    "Normalization.from_points": lambda p, n, poly: ipfit.Normalization.from_points(p),
    "measures": lambda p, n, poly: ipfit.measures(poly, p, n),
}


@pytest.mark.parametrize("call", list(_CALLS), ids=list(_CALLS))
def test_every_public_function_refuses_non_coordinates_in_one_line(circle, poly, call):
    points, normals = circle
    for label, value, words in _bad_inputs(points):
        if label == "None" and call == "extract_zero_set":
            continue  # points=None is its default: the box comes from ``bounds``
        _refused(lambda: _CALLS[call](value, normals, poly), *words)


@pytest.mark.parametrize("call", ["fit_3l", "refine", "orient_normals", "measures"])
def test_normals_are_checked_by_the_same_validator(circle, poly, call):
    points, normals = circle
    _refused(lambda: _CALLS[call](points, normals > 0, poly), "booleans", name="normals")
    _refused(lambda: _CALLS[call](points, pd.DataFrame(normals), poly), "columns nx, ny[, nz]", name="normals")
    _refused(lambda: _CALLS[call](points, np.ma.masked_less(normals, 0), poly), "masked values", name="normals")


def test_canonical_checks_the_normals_it_is_given(circle, poly):
    points, normals = circle
    _refused(lambda: poly.canonical(points, normals[:10]), "shape (80, 2) to match the points", name="normals")
    _refused(lambda: poly.canonical(points, (n for n in normals)), "an iterator", name="normals")


def test_a_dataframe_gives_its_x_y_columns_in_any_case_and_the_rest_is_ignored(circle):
    points, normals = circle
    frame = pd.DataFrame({"label": ["a"] * len(points), "Y": points[:, 1], " X ": points[:, 0],
                          "NX": normals[:, 0], "ny": normals[:, 1], "weight": np.arange(len(points))})
    from_frame = _strict(ipfit.fit_3l, frame, frame, 2)  # one frame: x, y for points, nx, ny for normals
    np.testing.assert_allclose(from_frame.coefficients, ipfit.fit_3l(points, normals, 2).coefficients, rtol=1e-12)


def test_a_dataframe_with_z_gives_3d_points_and_nullable_missing_values_are_named():
    frame = pd.DataFrame({"x": [0.0, 1.0, 0.0], "y": [0.0, 0.0, 1.0], "z": [0.0, 0.0, 0.0]})
    assert _strict(ipfit.Normalization.from_points, frame).dim == 3
    frame["z"] = pd.array([0.0, None, 0.0], dtype="Float64")
    _refused(lambda: ipfit.Normalization.from_points(frame), "1 rows with NaN or inf (first at row 1)")


def test_masked_arrays_without_masked_values_and_matrices_are_points(circle):
    points, normals = circle
    reference = ipfit.fit_3l(points, normals, 2).coefficients
    masked = np.ma.masked_greater(np.vstack([points, [[99.0, 99.0]]]), 50)
    normals_kept = np.vstack([normals, [[1.0, 0.0]]])[~masked.mask.any(axis=1)]
    for kept in (np.ma.array(points), np.ma.compress_rows(masked)):
        np.testing.assert_allclose(_strict(ipfit.fit_3l, kept, normals_kept, 2).coefficients, reference, rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PendingDeprecationWarning)  # numpy's own, at construction
        matrix, matrix_normals = np.matrix(points), np.asmatrix(normals)
    np.testing.assert_allclose(_strict(ipfit.fit_3l, matrix, matrix_normals, 2).coefficients, reference, rtol=1e-12)
    values = _strict(ipfit.fit_3l(points, normals, 2), matrix)
    assert type(values) is np.ndarray and values.shape == (len(points),)


def test_quality_validates_before_its_cache_so_masked_data_is_not_served_a_stored_result(circle, poly):
    points, _ = circle
    assert ipfit.quality(poly, points).f_score > 0.9
    _refused(lambda: ipfit.quality(poly, np.ma.masked_greater(points, 0.5)), "masked values")
    _refused(lambda: ipfit.quality(poly, points + 0j), "complex numbers")


def test_a_single_ray_still_comes_as_one_point_and_bad_origins_are_refused(poly):
    hits = _strict(poly.intersect_rays, [0.0, 0.0], np.array([1.0, 0.0]))
    assert abs(np.abs(hits.t[np.isfinite(hits.t)]).min() - 1.0) < 0.01  # the fitted unit circle
    _refused(lambda: poly.intersect_rays(np.zeros((3, 2), dtype=bool), [1.0, 0.0]), "booleans", name="origins")
    _refused(lambda: poly.intersect_rays(pd.DataFrame(np.zeros((3, 2))), [1.0, 0.0]), "columns x, y",
             name="origins")


def test_far_field_samples_checks_its_arrays(circle):
    points, normals = circle
    _refused(lambda: ipfit.far_field_samples(points, normals[:5]), "to match the points", name="normals")
    _refused(lambda: ipfit.far_field_samples(points > 0, normals), "booleans", name="u")


def test_fit_chunked_refuses_in_one_line_and_takes_a_dataframe(circle):
    pytest.importorskip("dask")
    points, normals = circle
    _refused(lambda: ipfit.fit_chunked(points > 0, normals, 2, scheduler="sync"), "booleans")
    _refused(lambda: ipfit.fit_chunked(points[:, 0], normals, 2, scheduler="sync"), "shape (80,)")
    _refused(lambda: ipfit.fit_chunked(iter(points), normals, 2, scheduler="sync"), "an iterator")
    frame = pd.DataFrame({"x": points[:, 0], "y": points[:, 1], "nx": normals[:, 0], "ny": normals[:, 1]})
    chunked = ipfit.fit_chunked(frame, frame, 2, scheduler="sync")
    np.testing.assert_allclose(chunked.coefficients, ipfit.fit_3l(points, normals, 2).coefficients, atol=1e-8)


# -- images -------------------------------------------------------------------------------------

def _blank_png(path, width, height):
    """A valid 1-bit grey PNG of any size, written row by row: a few hundred KB at most."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    row, packer = b"\0" * (1 + (width + 7) // 8), zlib.compressobj(9)
    pixels = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0))
                     + chunk(b"IDAT", pixels) + chunk(b"IEND", b""))
    return path


# The peak from /proc (VmHWM, this process's own memory): ru_maxrss would count the RSS
# inherited from pytest through fork.
_READ_AND_PEAK = """
import sys
import ipfit
try:
    ipfit.read_points(sys.argv[1])
except ipfit.ReadError as exc:
    print(exc)
print(next(line.split()[1] for line in open("/proc/self/status") if line.startswith("VmHWM:")))
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="the peak is read from Linux's /proc")
def test_a_12000_square_png_is_refused_from_its_header_with_a_small_peak(tmp_path):
    path = _blank_png(tmp_path / "big.png", 12000, 12000)
    assert path.stat().st_size < 1_000_000
    run = subprocess.run([sys.executable, "-c", _READ_AND_PEAK, str(path)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": SRC}, timeout=60)
    message, peak_kb = run.stdout.splitlines()
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert message == (f"{path}: expected at most {MAX_IMAGE_PIXELS:,} pixels, got 12000 x 12000 = 144,000,000. "
                       "Downscale it (e.g. to 7071 x 7071)."), message
    # decoding alone would take 144 MB, tracing 2.6 GB; importing ipfit, numpy and Pillow ~80 MB
    assert int(peak_kb) < 200_000, peak_kb


def test_pillow_decompression_bomb_error_becomes_our_line(tmp_path):
    from PIL import Image

    path = _blank_png(tmp_path / "bomb.png", 20000, 20000)  # over twice Pillow's limit: it raises
    with pytest.raises(ipfit.ReadError) as info:
        _strict(ipfit.read_points, path)
    assert str(info.value) == (f"{path}: expected at most {MAX_IMAGE_PIXELS:,} pixels, got more than "
                               f"{2 * Image.MAX_IMAGE_PIXELS:,}. Downscale the image.")


def test_the_cli_refuses_a_huge_image_in_one_line_and_writes_nothing(tmp_path):
    path = _blank_png(tmp_path / "big.png", 12000, 6000)
    run = subprocess.run([sys.executable, "-m", "ipfit.cli", "fit", str(path), "--degree", "2", "--method", "3l",
                          "-o", str(tmp_path / "out")], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": SRC}, timeout=60)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [f"ipfit fit: error: {path}: expected at most {MAX_IMAGE_PIXELS:,} pixels, "
                                       "got 12000 x 6000 = 72,000,000. Downscale it (e.g. to 10000 x 5000)."]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.png"]


def test_trace_silhouette_refuses_a_huge_array_before_copying_it():
    huge = np.broadcast_to(np.uint8(0), (8000, 7000))  # no memory behind it: a copy would take 448 MB
    _refused(lambda: trace_silhouette(huge), "got 7000 x 8000 = 56,000,000", "Downscale it", name="image")
    _refused(lambda: trace_silhouette(np.full((5, 5), "a")), "a 2D array of grey levels", name="image")


def test_trace_silhouette_result_is_unchanged_by_the_in_place_steps():
    rows, cols = np.mgrid[:60, :80]
    disc = ((rows - 30) ** 2 + (cols - 40) ** 2 < 400).astype(float) * 0.7 + 0.1  # dark background, grey levels
    disc[0, 0] = 0.05  # three levels: the Otsu threshold is used
    points, normals = trace_silhouette(disc)
    radius = np.linalg.norm(points - [40, -30], axis=1)
    assert abs(radius.mean() - 20) < 0.5 and radius.std() < 0.3
    assert np.all(np.einsum("ij,ij->i", normals, points - [40, -30]) > 0)  # outward
    inverted, _ = trace_silhouette(1.0 - disc)  # bright background: the same shape
    assert abs(np.linalg.norm(inverted - [40, -30], axis=1).mean() - 20) < 0.5


def test_any_real_number_is_taken_and_a_non_finite_one_refused():
    from fractions import Fraction

    from ipfit._utils.validation import check_real

    assert check_real(Fraction(1, 4), "epsilon") == 0.25  # every numbers.Real converts through float()
    assert check_real(np.float32(0.5), "epsilon") == 0.5 and check_real(3, "epsilon") == 3.0
    for bad in (Fraction(10**400), 10**400, float("nan"), np.inf, True, "0.1", 1j):
        with pytest.raises(ipfit.InvalidInputError, match="epsilon: expected a finite real number"):
            check_real(bad, "epsilon")

"""Linear fits of chunked (Dask) clouds equal the in-memory fits."""

from __future__ import annotations

import numpy as np
import pytest

da = pytest.importorskip("dask.array")

from ipfit import InvalidInputError, ReadError, fit_linear  # noqa: E402
from ipfit.fitting.chunked import CHUNKED_METHODS, fit_chunked, open_cloud  # noqa: E402
from ipfit.datasets import synthetic  # noqa: E402


@pytest.fixture
def cloud(rng):
    shape = synthetic.torus(20_000, rng=rng)
    points = shape.points * [2.0, 1.0, 1.5] + [3.0, -1.0, 0.5] + 0.01 * rng.standard_normal(shape.points.shape)
    return points, shape.normals * rng.uniform(0.5, 2.0, (len(points), 1))  # normals of any length


def _relative(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


@pytest.mark.parametrize("method", CHUNKED_METHODS)
def test_chunked_fit_equals_the_in_memory_fit(cloud, method):
    points, normals = cloud
    memory = fit_linear(points, None if method == "lstsq" else normals, 4, method)
    chunked = fit_chunked(da.from_array(points, chunks=(3_001, 3)), None if method == "lstsq" else
                          da.from_array(normals, chunks=(3_001, 3)), 4, method, scheduler="threads")
    assert _relative(chunked.coefficients, memory.coefficients) < 1e-10
    assert np.allclose(chunked.normalization.center, memory.normalization.center, rtol=1e-12)
    assert chunked.info["chunks"] == 7 and chunked.info["n_points"] == len(points)


def test_far_field_rows_come_from_a_subsample_when_the_cloud_is_bigger(cloud):
    points, normals = cloud
    whole = fit_chunked(points, normals, 4, "3l-far", chunk_rows=5_000, scheduler="sync")
    sampled = fit_chunked(points, normals, 4, "3l-far", chunk_rows=5_000, sample_size=4_000, scheduler="sync")
    assert sampled.info["sample_size"] == 4_000
    # the far-field rows carry 1e-3 of the weight: a subsample moves the fit only a little
    assert 0 < _relative(sampled.coefficients, whole.coefficients) < 0.05
    assert _relative(whole.coefficients, fit_linear(points, normals, 4, "3l-far").coefficients) < 1e-10


def test_clouds_stored_as_npy_memmaps_or_chunk_files(cloud, tmp_path):
    points, normals = cloud
    np.save(tmp_path / "points.npy", points)
    np.save(tmp_path / "normals.npy", normals)
    chunks = tmp_path / "chunks"
    chunks.mkdir()
    for i, start in enumerate(range(0, len(points), 6_000)):
        np.save(chunks / f"points-{i:03d}.npy", points[start:start + 6_000])
        np.save(chunks / f"normals-{i:03d}.npy", normals[start:start + 6_000])
    memory = fit_linear(points, normals, 4, "ridge")
    for folder, n_chunks in ((tmp_path, 3), (chunks, 4)):
        p, n = open_cloud(folder, chunk_rows=8_000)
        fit = fit_chunked(p, n, 4, "ridge", scheduler="sync")
        assert fit.info["chunks"] == n_chunks
        assert _relative(fit.coefficients, memory.coefficients) < 1e-10


def test_bad_chunked_inputs_are_one_clear_error(cloud, tmp_path):
    points, normals = cloud
    with pytest.raises(InvalidInputError, match="^method: "):
        fit_chunked(points, normals, 4, "taubin")
    with pytest.raises(InvalidInputError, match="^normals: "):
        fit_chunked(points, normals[:-1], 4, "3l")
    with pytest.raises(InvalidInputError, match="^normals: "):
        fit_chunked(points, None, 4, "3l")
    with pytest.raises(InvalidInputError, match="^kappa: "):
        fit_chunked(points, normals, 4, "3l", kappa=1.0)
    with pytest.raises(ReadError, match="points.npy"):
        open_cloud(tmp_path)

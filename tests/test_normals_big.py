"""Big noisy clouds: the compiled multi-scale PCA, the even-sample path, progress, the kernel cache."""

import os
import subprocess
import sys

import numpy as np
import pytest

from ipfit.cli import main
from ipfit.datasets import synthetic
from ipfit.normals import estimate_normals, normal_agreement
from ipfit.normals._scale_kernels import jacobi_eigen, multiscale_pca


@pytest.mark.parametrize("dim", [2, 3])
def test_jacobi_matches_lapack_on_random_and_degenerate_matrices(dim):
    rng = np.random.default_rng(dim)
    vec, w = np.empty((dim, dim)), np.empty(dim)
    for trial in range(300):
        m = rng.normal(size=(dim, dim))
        a = m @ m.T
        if trial % 3 == 0:  # rank one: two equal (zero) eigenvalues
            u = rng.normal(size=dim)
            a = np.outer(u, u)
        b = a.copy()
        jacobi_eigen(b, vec, w)
        scale = np.abs(a).max()
        assert np.abs(a @ vec - vec * w).max() <= 1e-13 * scale
        assert np.abs(vec.T @ vec - np.eye(dim)).max() <= 1e-13
        assert np.sort(w) == pytest.approx(np.linalg.eigvalsh(a), abs=1e-13 * scale)


@pytest.mark.parametrize("dim", [2, 3])
def test_multiscale_pca_is_the_pca_of_each_nested_neighbourhood(dim):
    rng = np.random.default_rng(7)
    points = rng.normal(size=(500, dim)) * np.arange(1, dim + 1)  # anisotropic: a definite normal
    from scipy.spatial import cKDTree

    _, wide = cKDTree(points).query(points[:40], k=64)
    scales = np.array([8, 16, 64])
    out = [np.empty((3, 40, dim)) for _ in range(3)]
    multiscale_pca(points, wide, scales, *out)
    normals, values, centroid = out
    for s, kk in enumerate(scales):
        nb = points[wide[:, :kk]]
        mean = nb.mean(axis=1)
        cov = np.einsum("bki,bkj->bij", nb - mean[:, None], nb - mean[:, None])
        lam, vec = np.linalg.eigh(cov)
        lam /= lam.sum(axis=1, keepdims=True)
        assert values[s] == pytest.approx(lam, abs=1e-12)
        assert centroid[s] == pytest.approx(mean, abs=1e-12)
        cos = np.abs(np.einsum("bi,bi->b", normals[s], vec[:, :, 0]))
        gap = (lam[:, 1] - lam[:, 0]) > 1e-6  # a normal is defined only where the least spread is alone
        assert cos[gap] == pytest.approx(1.0, abs=1e-8)


def _noisy_torus(n, fraction, seed):
    points, truth, _ = synthetic.torus(n, rng=np.random.default_rng(seed))
    sigma = fraction * float(np.linalg.norm(np.ptp(points, axis=0)))
    return points + np.random.default_rng(seed + 100).normal(0.0, sigma, points.shape), truth


@pytest.mark.parametrize("seed", [0, 1])
def test_a_big_noisy_cloud_is_estimated_on_an_even_sample_and_says_so(seed):
    points, truth = _noisy_torus(60_000, 0.005, seed)
    events = []
    normals = estimate_normals(points, progress=events.append)
    messages = [e["message"] for e in events]
    assert "noisy: estimating on an even sample of 30,000 of the 60,000 points" in messages  # every 2nd
    assert messages[-1] == "done" and all(e["event"] == "normals" for e in events)
    seconds = [e["seconds"] for e in events]
    assert seconds == sorted(seconds)
    a = normal_agreement(normals, truth)
    # σ = 0.5 % of the diagonal is 5 % of the tube's radius: the full-cloud estimate gives 2.5-2.7°
    assert a.median_angle < 4.0 and a.flipped_fraction < 0.002


def test_a_small_or_clean_cloud_keeps_every_point():
    points, truth = _noisy_torus(60_000, 0.0, 0)
    events = []
    normals = estimate_normals(points, progress=events.append)
    assert not any("sample" in e["message"] for e in events)
    a = normal_agreement(normals, truth)
    assert a.median_angle < 1.0 and a.flipped_fraction == 0.0


def test_progress_must_be_callable():
    with pytest.raises(Exception, match=r"^progress: expected a callable"):
        estimate_normals(np.eye(3), progress="yes")


def test_ipfit_normals_prints_the_stages_of_a_big_noisy_cloud(tmp_path, capsys):
    points, _ = _noisy_torus(60_000, 0.005, 3)
    src = tmp_path / "torus.xyz"
    np.savetxt(src, points)
    assert main(["normals", str(src), "-o", str(tmp_path / "out.ply")]) == 0
    out = capsys.readouterr().out
    # a stage line appears once estimation has taken a second (this cloud takes several)
    assert "normals: noisy: estimating on an even sample of 30,000 of the 60,000 points (" in out
    assert "\nnormals: done in " in out


def _cold(cache_dir, call=""):
    code = ("from ipfit.cli._common import cold_kernels\n"
            f"{call}\n"
            "print(cold_kernels(('ipfit.normals._scale_kernels',)))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return done.stdout.strip()


def test_the_kernel_cache_on_disk_is_checked(tmp_path):
    assert "jacobi_eigen" in _cold(tmp_path)  # nothing cached yet
    call = ("import numpy as np\nfrom ipfit.normals._scale_kernels import jacobi_eigen\n"
            "jacobi_eigen(np.eye(2), np.empty((2, 2)), np.empty(2))")
    _cold(tmp_path, call)  # compiles and writes the cache
    after = _cold(tmp_path)
    assert "jacobi_eigen" not in after and "multiscale_pca" in after


@pytest.mark.slow
def test_the_first_fit_says_it_compiles_and_the_second_does_not(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def fit(prefix):
        cmd = [sys.executable, "-m", "ipfit.cli", "fit", "boot", "--max-degree", "4", "--no-picture", "-o", prefix]
        return subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp_path)

    first = fit("first")
    assert first.returncode == 0, first.stderr
    assert first.stderr.startswith("ipfit fit: compiling kernels, first run only")
    second = fit("second")
    assert second.returncode == 0, second.stderr
    assert "compiling kernels" not in second.stderr


def test_reading_a_file_and_clean_normals_load_no_compiler(tmp_path):
    # numba takes a second or more to import: a command that reads a file (a batch with nothing
    # to do, ipfit view) or estimates clean normals must not pay for it
    np.savetxt(tmp_path / "c.xyz", synthetic.circle(50).points)
    code = ("import sys, ipfit, ipfit.io\n"
            f"p, _ = ipfit.io.read_points({str(tmp_path / 'c.xyz')!r})\n"
            "ipfit.estimate_normals(p)\n"
            "print('numba' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"

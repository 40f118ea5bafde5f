"""The local quadric fits under the outlier score (ipfit.robust.local), against a plain per-query reference."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ipfit.robust import local


def _design(u):
    if u.shape[1] == 1:
        x = u[:, 0]
        return np.column_stack([np.ones_like(x), x, x * x])
    x, y = u[:, 0], u[:, 1]
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])


def _reference(ref, query, dist, wide, k):
    """The module's recipe written out for one query at a time with LAPACK's eigh and solve."""
    n = len(query)
    residual, offset, extent = np.empty(n), np.empty(n), np.empty(n)
    chosen = np.empty((n, k), dtype=np.intp)
    for i in range(n):
        inside = np.isfinite(dist[i])
        rel = ref[wide[i]] - query[i]
        centred = rel[inside] - rel[inside].mean(axis=0)
        vectors = np.linalg.eigh(centred.T @ centred)[1]
        u, h = rel @ vectors[:, 1:], rel @ vectors[:, 0]
        along = np.where(inside, (u * u).sum(axis=1), np.inf)
        pick = np.argsort(along, kind="stable")[:k]
        chosen[i] = wide[i][pick]
        size = np.sqrt(along[pick].max()) or 1.0
        x, y = _design(u[pick] / size), h[pick]
        w = np.ones(k)
        floor = 1e-12 * np.abs(y).max() + 1e-300
        for _ in range(local._IRLS_STEPS):
            normal = x.T @ (w[:, None] * x) + 1e-9 * np.eye(x.shape[1])
            r = y - x @ np.linalg.solve(normal, x.T @ (w * y))
            t = r / (local._TUKEY * max(1.4826 * np.median(np.abs(r)), floor))
            w = np.where(np.abs(t) < 1, (1 - t * t) ** 2, 0.0)
        normal = x.T @ (w[:, None] * x) + 1e-9 * np.eye(x.shape[1])
        beta = np.linalg.solve(normal, x.T @ (w * y))
        leverage = np.linalg.inv(normal)[0, 0]
        residual[i] = abs(beta[0]) / np.sqrt(1 + min(leverage, local._LEVERAGE_CAP))
        mean = u[pick].mean(axis=0)
        extent[i] = np.sqrt(((u[pick] - mean) ** 2).sum() / k)
        offset[i] = np.linalg.norm(mean) / extent[i]
    return residual, offset, extent, chosen


def _noisy_surface(rng, dim, n):
    if dim == 2:
        t = rng.uniform(0, 2 * np.pi, n)
        pts = np.column_stack([np.cos(t), 0.6 * np.sin(t)])
    else:
        pts = rng.normal(size=(n, 3))
        pts /= np.linalg.norm(pts, axis=1, keepdims=True)
        pts *= [1.0, 0.7, 0.5]
    return pts + rng.normal(scale=0.01, size=pts.shape)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("reach", [None, 0.0, 0.08])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_compiled_fits_are_the_recipe(dim, reach, seed):
    rng = np.random.default_rng(seed)
    ref = _noisy_surface(rng, dim, 1500)
    query = np.vstack([ref[:150], rng.uniform(-1.3, 1.3, size=(50, dim))])  # samples (left out) and strays
    own = np.concatenate([np.arange(150), np.full(50, -1)])
    k = 10 if dim == 2 else 12
    fit = local.fit_local(ref, query, own, k, reach, workers=1)
    dist, wide, _ = local._frames(cKDTree(ref), query, own, k, reach, 1)
    residual, offset, extent, chosen = _reference(ref, query, dist, wide, k)
    assert np.array_equal(np.sort(fit.neighbours, axis=1), np.sort(chosen, axis=1))
    assert not (fit.neighbours[:150] == np.arange(150)[:, None]).any()  # a sample is never in its own fit
    np.testing.assert_allclose(fit.residual, residual, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(fit.offset, offset, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(fit.extent, extent, rtol=1e-9)


def test_a_point_above_a_flat_patch_is_off_by_its_height_over_its_spread(monkeypatch):
    # A 5 x 5 grid of the plane z = 0 without its centre, the query above the centre: its 20
    # nearest along the tangent are the grid without the corners (rings at 1, sqrt 2, 2, sqrt 5),
    # the fitted quadric is the plane, so the residual is the height over sqrt(1 + leverage),
    # the leverage that of those 20 points' least squares at the centre. Without reweighting:
    # on data this exact the Tukey weights follow the ridge's 1e-11 misfits (the reference
    # test covers the reweighting).
    monkeypatch.setattr(local, "_IRLS_STEPS", 0)
    g = np.arange(-2.0, 3.0)
    ref = np.array([(x, y, 0.0) for x in g for y in g if (x, y) != (0.0, 0.0)])
    query = np.array([[0.0, 0.0, 0.3]])
    fit = local.fit_local(ref, query, np.array([-1]), 20, None, workers=1)
    used = ref[np.abs(ref[:, :2]).sum(axis=1) < 4]
    assert np.array_equal(np.sort(fit.neighbours[0]), np.flatnonzero(np.abs(ref[:, :2]).sum(axis=1) < 4))
    x = _design(used[:, :2] / np.sqrt(5.0))
    leverage = np.linalg.inv(x.T @ x)[0, 0]
    assert fit.residual[0] == pytest.approx(0.3 / np.sqrt(1 + leverage), rel=1e-9)
    assert fit.offset[0] == pytest.approx(0.0, abs=1e-12)  # the 20 are centred on the query's foot
    assert fit.extent[0] == pytest.approx(np.sqrt((4 * 1 + 4 * 2 + 4 * 4 + 8 * 5) / 20), rel=1e-12)


def test_the_fits_split_over_threads_are_the_same_fits(monkeypatch):
    rng = np.random.default_rng(5)
    ref = _noisy_surface(rng, 3, 6000)
    query = np.vstack([ref, rng.uniform(-1.2, 1.2, size=(2000, 3))])
    own = np.concatenate([np.arange(len(ref)), np.full(2000, -1)])
    monkeypatch.setattr(local, "_MIN_PART", 1000)
    one = local.fit_local(ref, query, own, 12, None, workers=1)
    two = local.fit_local(ref, query, own, 12, None, workers=3)
    for a, b in zip(one[:4], two[:4], strict=True):
        assert np.array_equal(a, b)

"""The close-layer vote: a thin part's two sides, turned inside out as a whole (issue 30).

On a sparse 3D cloud the two sides of a thin part are closer than the neighbour links reach, and
sign propagation can turn the part inside out as a whole. A point whose normal line meets the
other side close in front of it votes its piece the other way round
(``ipfit.normals.orient._layer_votes``); two separate parts facing each other as close look the
same, so :func:`ipfit.fit_adaptive` fits with those signs only as a second look at a poor first
fit, kept when it measures better on the points. The references: two parallel sheets sampled on a
jittered grid (the votes derived by hand), and a torus whose normals are exact.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

import ipfit
from ipfit.datasets import synthetic
from ipfit.degree import adaptive, looks
from ipfit.normals.estimate import layered_normals
from ipfit.normals.orient import _layer_votes


def _sheets(rng: np.random.Generator, gap: float, both: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Points on the planes z = 0 and z = ``gap`` (a 12 × 12 grid of spacing 1, jittered by at most
    0.05), with the slab's outward normals: −z below, +z above."""
    grid = np.stack(np.meshgrid(np.arange(12.0), np.arange(12.0)), -1).reshape(-1, 2)
    layers = []
    for z, up in ((0.0, -1.0), (gap, 1.0))[: 2 if both else 1]:
        xy = grid + rng.uniform(-0.05, 0.05, grid.shape)
        layers.append((np.column_stack([xy, np.full(len(xy), z)]), np.tile([0.0, 0.0, up], (len(xy), 1))))
    return np.vstack([p for p, _ in layers]), np.vstack([n for _, n in layers])


def _votes(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    return _layer_votes(points, normals, cKDTree(points).query(points, 17)[1])


@pytest.mark.parametrize("offset", [0, 1, 2])
def test_a_thin_slab_votes_for_its_outward_normals(seed, offset):
    # The other side lies 0.4 straight behind every point (within 0.8 of its median spacing to its
    # 6 nearest, about 1, and 35° of its normal line); nothing of its own sheet lies along that line.
    rng = np.random.default_rng(seed + offset)
    points, outward = _sheets(rng, 0.4)
    assert np.all(_votes(points, outward) == 1.0)
    assert np.all(_votes(points, -outward) == -1.0)  # inside out: the other side in front
    # a single sheet, or two sheets farther apart than the reach, say nothing either way
    single, up = _sheets(rng, 0.4, both=False)
    assert np.all(_votes(single, up) == 0.0)
    apart, outward = _sheets(rng, 3.0)
    assert np.all(_votes(apart, outward) == 0.0)


def test_the_votes_do_not_depend_on_pose_or_units(seed):
    rng = np.random.default_rng(seed)
    points, outward = _sheets(rng, 0.4)
    outward[rng.random(len(outward)) < 0.3] *= -1.0  # mixed signs: +1, -1 and 0 votes
    rotation = Rotation.random(random_state=seed).as_matrix()
    moved = 250.0 * points @ rotation.T + np.array([1e3, -7.0, 40.0])
    assert np.array_equal(_votes(moved, outward @ rotation.T), _votes(points, outward))


def test_layered_normals_are_the_estimate_where_the_vote_does_not_apply(seed):
    # the vote runs only where the estimate orients a sparse or unevenly sampled 3D cloud (the
    # winding vote's clouds); an even torus and a 2D contour are oriented as estimate_normals does
    rng = np.random.default_rng(seed)
    torus = synthetic.torus(3000, rng=rng).points
    assert np.array_equal(layered_normals(torus), ipfit.estimate_normals(torus))
    circle = synthetic.circle(200, rng=rng).points
    assert np.array_equal(layered_normals(circle), ipfit.estimate_normals(circle))


def _cap_inside_out(normals: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.where(points[:, 2:] > 0.1, -normals, normals)


@pytest.mark.parametrize("offset", [0, 1])
def test_the_layered_fit_is_kept_only_when_it_measures_better(seed, offset, monkeypatch):
    # The estimate is replaced by exact torus normals with a cap turned inside out, and the
    # variant by the exact ones: the first fit is poor, the variant measures better and is kept.
    # Then the other way round, every fit looked at again: the variant is worse and is not kept.
    monkeypatch.setattr(looks, "_REORIENT_FEWEST", 2.0)  # the fit's-gradient pass out of the way
    monkeypatch.setattr(looks, "_LOCAL_SURFACE_MOST", 0)  # and the triangles look
    rng = np.random.default_rng(seed + offset)
    shape = synthetic.torus(800, rng=rng)
    points, exact = shape.points, shape.normals
    wrong = _cap_inside_out(exact, points)
    monkeypatch.setattr(adaptive, "estimate_normals", lambda pts, **_: wrong)
    monkeypatch.setattr(looks, "layered_normals", lambda pts, noise=None: exact)
    events: list[dict] = []
    fixed = ipfit.fit_adaptive(points, max_degree=4, rng=seed, progress=events.append)
    assert sum(e["event"] == "layers" for e in events) == 1
    assert "close-layer vote and fitted again (measured better)" in fixed.message
    assert ipfit.quality(fixed.polynomial, points).f_score > 0.95
    assert fixed.nfev > sum(d.nfev for d in fixed.degrees)  # every loop's evaluations counted

    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)  # every first fit looked at again
    monkeypatch.setattr(adaptive, "estimate_normals", lambda pts, **_: exact)
    monkeypatch.setattr(looks, "layered_normals", lambda pts, noise=None: wrong)
    kept = ipfit.fit_adaptive(points, max_degree=4, rng=seed)
    once = ipfit.fit_adaptive(points, exact, max_degree=4, rng=seed)
    assert "close-layer vote (degree" in kept.message and "measured no better: kept" in kept.message
    assert np.allclose(kept.polynomial.coefficients, once.polynomial.coefficients)


def test_the_layered_look_needs_estimated_normals_a_measuring_rule_and_3d(seed, monkeypatch):
    # every first fit looked at again, a variant that differs everywhere: still no look where the
    # normals are the user's, under the paper's rule, or in 2D
    monkeypatch.setattr(looks, "_POOR_BELOW", 1.01)
    monkeypatch.setattr(looks, "layered_normals", lambda pts, noise=None: -ipfit.estimate_normals(pts))
    rng = np.random.default_rng(seed)
    torus = synthetic.torus(600, rng=rng)
    circle = synthetic.circle(200, rng=rng)
    events: list[dict] = []
    ipfit.fit_adaptive(torus.points, max_degree=4, rng=seed, progress=events.append)  # the look, for reference
    assert sum(e["event"] == "layers" for e in events) == 1
    for points, normals, kwargs in ((torus.points, torus.normals, {}),
                                    (torus.points, None, {"method": "3l", "rule": "paper"}),
                                    (circle.points, None, {})):
        events: list[dict] = []
        result = ipfit.fit_adaptive(points, normals, max_degree=4, rng=seed, progress=events.append, **kwargs)
        assert not any(e["event"] == "layers" for e in events)
        assert "close-layer" not in result.message

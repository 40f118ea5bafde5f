"""Normals rounded over thin rims (ipfit.normals.rims.round_rims) and where the fit uses them."""

import numpy as np
import pytest

import ipfit
from ipfit.degree import loop
from ipfit.normals.rims import round_rims


def plate(n_side=61, half=1.0, gap=0.01):
    """A thin square plate's two faces (gap apart), sampled on a grid, with their outward normals,
    and the grid's x and y per point."""
    g = np.linspace(-half, half, n_side)
    x, y = [a.ravel() for a in np.meshgrid(g, g)]
    top = np.column_stack([x, y, np.full(x.size, gap / 2)])
    points = np.vstack([top, top * [1, 1, -1]])
    normals = np.repeat([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], x.size, axis=0)
    return points, normals, np.tile(x, 2), np.tile(y, 2)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def test_plate_rims_turn_outward_and_the_middle_keeps_its_normals():
    points, normals, x, y = plate()
    out, turn = round_rims(points, normals, return_turn=True)
    middle = np.maximum(abs(x), abs(y)) < 0.8
    assert np.allclose(out[middle], normals[middle], atol=1e-12)
    for axis, coordinate in ((0, x), (1, y)):
        for side in (1.0, -1.0):
            rim = (coordinate == side) & (abs(y if axis == 0 else x) < 0.5)
            assert turn[rim].min() > 0.9
            assert np.all(side * out[rim, axis] > 0.9)  # outward over the rim, on both faces
    # each face's normal keeps its side: turned within its own half-space
    assert np.all(np.einsum("ij,ij->i", out, normals) >= -1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_the_turns_move_with_the_cloud(seed):
    rng = np.random.default_rng(seed)
    points, normals, _, _ = plate()
    rotation = random_rotation(rng)
    out = round_rims(points, normals)
    moved = round_rims(3.7 * points @ rotation.T + rng.normal(size=3) * 10, normals @ rotation.T)
    assert np.allclose(moved, out @ rotation.T, atol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_a_dense_sphere_has_no_rim(seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(30_000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    _, turn = round_rims(2.0 * v + 5.0, v, return_turn=True)
    assert not turn.any()


def test_a_sparse_or_uneven_cloud_keeps_its_normals():
    points, normals, x, _ = plate(n_side=9)  # 81 points a face: too few within the radius
    out, turn = round_rims(points, normals, return_turn=True)
    assert not turn.any()
    assert np.allclose(out, normals)
    points, normals, x, _ = plate(n_side=121)
    keep = (x < -0.5) | (np.arange(len(x)) % 9 == 0)  # 3/4 of it 9 times sparser: a mesh's vertices
    out, turn = round_rims(points[keep], normals[keep], return_turn=True)
    assert not turn.any()
    # the same half-thinned plate turns its rims once it is made even again
    _, turn = round_rims(points[x < 0], normals[x < 0], return_turn=True)
    assert turn.any()


def test_weights_keep_strays_from_hiding_a_rim():
    points, normals, x, y = plate()
    rng = np.random.default_rng(0)
    strays = np.column_stack([rng.uniform(1.0, 1.06, 400), rng.uniform(-1, 1, 400), rng.uniform(-0.005, 0.005, 400)])
    cloud = np.vstack([points, strays])
    stray_normals = np.tile([0.0, 0.0, 1.0], (len(strays), 1))
    both = np.vstack([normals, stray_normals])
    rim = np.r_[(x == 1) & (abs(y) < 0.5), np.zeros(len(strays), bool)]
    weights = np.r_[np.ones(len(points)), np.zeros(len(strays))]
    _, hidden = round_rims(cloud, both, return_turn=True)
    _, seen = round_rims(cloud, both, weights=weights, return_turn=True)
    assert hidden[rim].max() == 0.0  # the strays fill the rim's empty side...
    assert seen[rim].min() > 0.9  # ... unless their weights leave them out


@pytest.mark.parametrize("call, match", [
    (lambda: round_rims(np.zeros((10, 2)), np.ones((10, 2))), "3D points"),
    (lambda: round_rims(np.random.default_rng(0).normal(size=(10, 3)), np.ones((9, 3))), "shape"),
    (lambda: round_rims(np.random.default_rng(0).normal(size=(10, 3)), np.ones((10, 3)), radius=0), "radius"),
])
def test_bad_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def _counting(monkeypatch):
    calls = []

    def counted(*args, **kwargs):
        calls.append(len(args[0]))
        return round_rims(*args, **kwargs)

    monkeypatch.setattr(loop, "round_rims", counted)
    return calls


def test_the_recommended_fit_rounds_the_normals_it_estimated_and_no_others(monkeypatch):
    calls = _counting(monkeypatch)
    apple = ipfit.load("apple")
    points = np.asarray(apple.points)
    ipfit.fit_adaptive(apple, max_degree=2, rng=0)  # a mesh: its vertex normals are its own
    ipfit.fit_adaptive(points, np.asarray(apple.unit_normals), max_degree=2, rng=0)  # given normals
    ipfit.fit_adaptive(points, max_degree=2, rng=0, rule="paper")  # the paper's pipeline
    ipfit.fit_adaptive(points[:, :2] + 0.01 * points[:, 2:], max_degree=2, rng=0)  # 2D
    assert calls == []
    ipfit.fit_adaptive(points, max_degree=2, rng=0)
    # its points, and (a degree-2 fit measures poorly) its points with 2,000 spread between them
    # by the triangles look (looks._on_local_surface), whose normals are the estimated ones too
    assert calls and calls[0] == len(points) and set(calls) <= {len(points), len(points) + 2000}

"""ipfit.Cloud owns the data of a fit and what is derived from it: computed once per cloud,
never kept across calls given arrays, and never out of date (the cloud's arrays cannot change)."""

from __future__ import annotations

import importlib
import threading

import numpy as np
import pytest
from scipy.spatial import cKDTree

import ipfit
from ipfit import Cloud, InvalidInputError
from ipfit.datasets import synthetic
from ipfit.geometry.sampling import point_spacing

farfield = importlib.import_module("ipfit.fitting.farfield")
quality_module = importlib.import_module("ipfit.zeroset.quality")


def _counted(monkeypatch, module, name: str) -> list:
    calls = []
    real = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **k: calls.append(1) or real(*a, **k))
    return calls


def test_derived_data_is_computed_once_read_only_and_right():
    shape = synthetic.ellipse(120)
    cloud = Cloud(shape.points, 3.0 * shape.normals)
    assert cloud.kdtree is cloud.kdtree and cloud.unit_normals is cloud.unit_normals
    assert cloud.spacing is cloud.point_spacing(1) and cloud.point_spacing(2) is cloud.point_spacing(2)
    np.testing.assert_allclose(np.linalg.norm(cloud.unit_normals, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(cloud.spacing, cKDTree(shape.points).query(shape.points, k=2)[0][:, 1], rtol=0)
    for derived in (cloud.points, cloud.normals, cloud.unit_normals, cloud.spacing):
        assert not derived.flags.writeable
        with pytest.raises(ValueError):
            derived[0] = 1.0
    # the public function gives the cloud's spacing as the caller's own copy, and arrays the same values
    given = point_spacing(cloud)
    assert given.flags.writeable and np.array_equal(given, cloud.spacing)
    assert np.array_equal(point_spacing(shape.points, k=2), cloud.point_spacing(2))
    assert Cloud(shape.points).unit_normals is None


def test_a_cloud_never_measures_changed_data(monkeypatch):
    # Its arrays are copies, read-only: the caller changing its own array after building the cloud
    # changes neither the cloud nor what the cloud keeps (the measurement is still the right one).
    shape = synthetic.circle(60)
    pts = shape.points.copy()
    cloud = Cloud(pts)
    q = ipfit.quality(shape.polynomial, cloud)
    pts += 0.5
    assert np.array_equal(cloud.points, shape.points)
    extractions = _counted(monkeypatch, quality_module, "extract_zero_set")
    assert ipfit.quality(shape.polynomial, cloud) == q and not extractions  # kept, and still right
    assert ipfit.quality(shape.polynomial, Cloud(cloud.points)) == q and len(extractions) == 1  # new cloud: measured
    assert ipfit.quality(shape.polynomial, pts).recall < 0.5  # the changed array is other data


def test_the_data_side_is_built_once_per_cloud_and_measurements_are_bounded(monkeypatch):
    shape = synthetic.circle(80)
    cloud = Cloud(shape.points)
    targets = _counted(monkeypatch, quality_module, "data_target")
    extractions = _counted(monkeypatch, quality_module, "extract_zero_set")
    circles = [synthetic.from_terms(2, 2, {(2, 0): 1.0, (0, 2): 1.0, (0, 0): -(r * r)})
               for r in np.linspace(0.9, 1.1, 5)]
    first = [ipfit.quality(p, cloud) for p in circles]
    assert len(targets) == 1 and len(extractions) == 5  # one data side for every polynomial
    assert ipfit.quality(circles[-1], cloud) == first[-1] and len(extractions) == 5  # the last ones are kept
    assert ipfit.quality(circles[0], cloud) == first[0] and len(extractions) == 6  # only the last few: measured again
    assert [ipfit.quality(p, shape.points) for p in circles] == first and len(targets) == 6  # arrays: every call


def test_refinements_of_one_cloud_share_their_far_field_samples_and_match_arrays(monkeypatch):
    shape = synthetic.ellipse(150)
    opts = ipfit.RECOMMENDED.replace(iterations=5, population_size=20)
    selections = _counted(monkeypatch, farfield, "_term_samples")
    from_arrays = [ipfit.refine(shape.points, shape.normals, g, options=opts, rng=0) for g in (2, 4)]
    assert len(selections) == 2  # arrays: a transient cloud each, nothing kept across calls
    cloud = Cloud(shape.points, shape.normals)
    on_cloud = [ipfit.refine(cloud, None, g, options=opts, rng=0) for g in (2, 4)]
    assert len(selections) == 3  # the samples depend on the data alone: once for both degrees
    for a, b in zip(from_arrays, on_cloud):
        assert a.x.tobytes() == b.x.tobytes() and a.fun == b.fun  # the same computation, bit for bit


def test_fit_adaptive_takes_a_cloud_with_its_normals_and_faces():
    shape = synthetic.ellipse(200)
    cloud = Cloud(shape.points, shape.normals, name="ellipse")
    opts = ipfit.RECOMMENDED.replace(iterations=5, population_size=20)
    by_cloud = ipfit.fit_adaptive(cloud, options=opts, max_degree=4, rng=0)
    by_arrays = ipfit.fit_adaptive(shape.points, shape.normals, options=opts, max_degree=4, rng=0)
    assert by_cloud.selected_degree == by_arrays.selected_degree
    for a, b in zip(by_cloud.degrees, by_arrays.degrees):
        assert a.x.tobytes() == b.x.tobytes() and a.quality == b.quality
    # a cloud carries its own normals and faces: passing others too is one clear error
    for extra in ({"normals": shape.normals}, {"faces": [[0, 1, 2]]}):
        with pytest.raises(InvalidInputError, match="when the points are a Cloud") as info:
            ipfit.fit_adaptive(cloud, method="3l", **extra)
        assert "\n" not in str(info.value)


def test_linear_fits_take_a_cloud_and_need_its_normals():
    shape = synthetic.circle(50)
    with_normals = Cloud(shape.points, shape.normals)
    assert (ipfit.fit_3l(with_normals, None, 2).coefficients.tobytes()
            == ipfit.fit_3l(shape.points, shape.normals, 2).coefficients.tobytes())
    with pytest.raises(InvalidInputError, match="required by fit_3l"):
        ipfit.fit_3l(Cloud(shape.points), None, 2)
    with pytest.raises(InvalidInputError, match="3D points to match"):  # a 2D cloud, a 3D polynomial
        ipfit.quality(synthetic.sphere(50).polynomial, with_normals)


def test_derived_data_is_shared_by_threads():
    cloud = Cloud(synthetic.sphere(400).points)
    barrier = threading.Barrier(4)
    got = []

    def ask():
        barrier.wait()
        got.append(cloud.derived("slow", 1, lambda: np.arange(3)))

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(got) == 4 and all(g is got[0] for g in got)  # whoever computed, one result is kept


def test_a_cloud_travels_to_other_processes_without_its_derived_data():
    import copy
    import pickle

    shape = synthetic.circle(40)
    cloud = Cloud(shape.points, shape.normals, name="circle")
    assert cloud.spacing is not None and cloud.kdtree is not None
    for other in (pickle.loads(pickle.dumps(cloud)), copy.deepcopy(cloud)):
        assert other.name == "circle" and np.array_equal(other.points, cloud.points)
        assert not other.points.flags.writeable
        assert np.array_equal(other.spacing, cloud.spacing) and other.spacing is not cloud.spacing  # derived again
        assert other.derived("x", 1, lambda: 5) == 5


def test_no_module_level_cache_is_left():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("ipfit._recent")

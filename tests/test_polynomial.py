import json

import numpy as np
import pytest

from ipfit import ImplicitPolynomial, InvalidInputError, Normalization, ReadError, fit_3l
from ipfit.datasets import synthetic


def test_normalization_centres_and_scales(rng):
    pts = rng.normal(size=(100, 3)) * 7 + 3
    norm = Normalization.from_points(pts)
    u = norm.apply(pts)
    np.testing.assert_allclose(u.mean(axis=0), 0, atol=1e-12)
    assert np.linalg.norm(u, axis=1).mean() == pytest.approx(1.0)
    np.testing.assert_allclose(norm.invert(u), pts)


def test_evaluation_and_gradient_in_user_coordinates_through_the_scale():
    # the circle of radius 2 around (1, -1), written in coordinates normalised by centre and scale 2
    norm = Normalization([1.0, -1.0], 2.0)
    poly = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2, normalization=norm)
    pts = np.array([[3.0, -1.0], [1.0, 1.0], [1.0, -1.0], [5.0, -1.0]])
    np.testing.assert_allclose(poly(pts), [0, 0, -1, 3])
    # f = ((x-1)² + (y+1)²)/4 − 1, so ∇f = ((x−1)/2, (y+1)/2)
    np.testing.assert_allclose(poly.gradient(pts), [[1, 0], [0, 1], [0, 0], [2, 0]])
    np.testing.assert_allclose(poly.taubin_distance(pts[:2]), 0, atol=1e-15)


def test_polynomial_is_immutable():
    poly = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    with pytest.raises(ValueError):
        poly.coefficients[0] = 5
    with pytest.raises(AttributeError):
        poly.method = "x"


def test_canonical_form_is_unit_norm_and_positive_outside():
    poly = ImplicitPolynomial.from_coefficients([3, 0, 0, -3, 0, -3], dim=2)  # −3(x²+y²−1)
    canon = poly.canonical()
    assert np.linalg.norm(canon.coefficients) == pytest.approx(1)
    assert canon([[5.0, 0.0]])[0] > 0 and canon([[0.0, 0.0]])[0] < 0
    shape = synthetic.circle(20)
    flipped = poly.canonical(shape.points, -shape.normals)  # inward normals: f > 0 inside
    assert flipped([[0.0, 0.0]])[0] > 0


def test_json_round_trip_keeps_the_contract_keys(tmp_path):
    shape = synthetic.sphere(200, radius=3.0, center=(1, 2, 3))
    poly = fit_3l(shape.points, shape.normals, degree=4)
    data = json.loads(poly.to_json())
    for key in ("format", "version", "dim", "degree", "exponents", "coefficients", "normalization", "method"):
        assert key in data
    assert data["format"] == "ipfit" and data["version"] == 2 and data["dim"] == 3 and data["degree"] == 4
    assert set(data["normalization"]) == {"center", "scale"}
    path = tmp_path / "fit.json"
    poly.save(path)
    back = ImplicitPolynomial.load(path)
    np.testing.assert_array_equal(back.coefficients, poly.coefficients)
    np.testing.assert_array_equal(back.center, poly.center)
    assert back.scale == poly.scale and back.method == "3l"
    probe = shape.points + 0.3
    np.testing.assert_allclose(back(probe), poly(probe))
    assert ImplicitPolynomial.from_json(poly.to_json()).degree == 4


def test_json_contract_example_from_the_issue_loads():
    text = json.dumps({"format": "ipfit", "version": 1, "dim": 3, "degree": 1,
                       "exponents": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                       "coefficients": [0.1, 0.2, 0.3, 0.4],
                       "normalization": {"center": [0.0, 0.0, 0.0], "scale": 1.0}, "method": "3l",
                       "measures": {"dissimilarity": 0.01, "smoothness": 0.95, "distance": 0.02, "delta": 0.25}})
    poly = ImplicitPolynomial.from_json(text)
    assert poly([[1.0, 1.0, 1.0]])[0] == pytest.approx(1.0)
    assert poly.measures["smoothness"] == 0.95


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(ReadError, match="no such file"):
        ImplicitPolynomial.load(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ReadError, match="bad.json: not valid JSON"):
        ImplicitPolynomial.load(bad)
    other = tmp_path / "other.json"
    other.write_text('{"format": "something"}')
    with pytest.raises(ReadError, match="not an ipfit result"):
        ImplicitPolynomial.load(other)


def test_bad_coefficient_count_is_explained():
    with pytest.raises(InvalidInputError, match="coefficients: expected a length"):
        ImplicitPolynomial.from_coefficients([1, 2, 3, 4, 5], dim=2)


def test_evaluation_rejects_wrong_dimension():
    poly = ImplicitPolynomial.from_coefficients([-1, 0, 0, 1, 0, 1], dim=2)
    with pytest.raises(InvalidInputError, match=r"points: expected an array of shape \(N, 2\)"):
        poly(np.zeros((4, 3)))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("degree", [1, 2, 5, 8, 10])
def test_gradient_in_user_coordinates_matches_central_differences(dim, degree, rng):
    from ipfit import basis

    norm = Normalization(rng.normal(0, 10, dim), float(rng.uniform(0.1, 10)))
    coef = rng.normal(size=basis.n_coefficients(dim, degree))
    poly = ImplicitPolynomial.from_coefficients(coef, dim=dim, normalization=norm)
    pts = norm.invert(rng.uniform(-1.2, 1.2, size=(15, dim)))
    h = 1e-6 * norm.scale
    fd = np.stack([(poly(pts + h * e) - poly(pts - h * e)) / (2 * h) for e in np.eye(dim)], axis=1)
    np.testing.assert_allclose(poly.gradient(pts), fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())

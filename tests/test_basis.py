import numpy as np
import pytest

from ipfit import basis

TABLE_1 = {2: {1: 3, 2: 6, 4: 15, 6: 28, 8: 45, 10: 66, 12: 91, 14: 120, 16: 153},
           3: {1: 4, 2: 10, 4: 35, 6: 84, 8: 165, 10: 286, 12: 455, 14: 680, 16: 969}}


@pytest.mark.parametrize("dim", [2, 3])
def test_coefficient_counts_match_paper_table_1(dim):
    for degree, count in TABLE_1[dim].items():
        assert basis.n_coefficients(dim, degree) == count
        assert basis.exponents(dim, degree).shape == (count, dim)
        assert basis.degree_from_n_coefficients(dim, count) == degree


def test_graded_order_starts_like_the_paper():
    assert basis.exponents(3, 2).tolist()[:5] == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0]]
    exps = basis.exponents(2, 6)
    assert np.all(np.diff(exps.sum(axis=1)) >= 0)
    assert len({tuple(e) for e in exps.tolist()}) == len(exps)


def test_degree_from_count_rejects_non_counts():
    with pytest.raises(ValueError, match="not the number of coefficients"):
        basis.degree_from_n_coefficients(2, 7)


@pytest.mark.parametrize("dim", [2, 3])
def test_monomials_match_direct_powers(dim, rng):
    pts = rng.normal(size=(50, dim))
    exps = basis.exponents(dim, 5)
    expected = np.prod(pts[:, None, :] ** exps[None, :, :], axis=2)
    np.testing.assert_allclose(basis.monomials(pts, exps), expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("degree", range(1, 11))
def test_gradients_agree_with_central_differences(dim, degree, rng):
    pts = rng.uniform(-1.2, 1.2, size=(20, dim))
    coef = rng.normal(size=basis.n_coefficients(dim, degree))
    m, dm = basis.monomials_and_gradients(pts, degree)
    exps = basis.exponents(dim, degree)
    grad = (dm @ coef).T
    h = 1e-6
    for k in range(dim):
        step = np.zeros(dim)
        step[k] = h
        fd = (basis.monomials(pts + step, exps) @ coef - basis.monomials(pts - step, exps) @ coef) / (2 * h)
        np.testing.assert_allclose(grad[:, k], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
    np.testing.assert_allclose(m @ coef, basis.monomials(pts, exps) @ coef)


def test_derivative_map_of_a_known_polynomial():
    # f = 3x²y + 2y² - x  ->  ∂f/∂x = 6xy - 1, ∂f/∂y = 3x² + 4y
    exps = basis.exponents(2, 3)
    index = {tuple(e): i for i, e in enumerate(exps.tolist())}
    a = np.zeros(len(exps))
    a[index[(2, 1)]], a[index[(0, 2)]], a[index[(1, 0)]] = 3, 2, -1
    low = {tuple(e): i for i, e in enumerate(basis.exponents(2, 2).tolist())}
    dx = basis.derivative_map(2, 3, 0) @ a
    dy = basis.derivative_map(2, 3, 1) @ a
    assert dx[low[(1, 1)]] == 6 and dx[low[(0, 0)]] == -1 and np.count_nonzero(dx) == 2
    assert dy[low[(2, 0)]] == 3 and dy[low[(0, 1)]] == 4 and np.count_nonzero(dy) == 2


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_population_gradient_coefficients_are_the_derivative_maps(dim, dtype, rng):
    # Member p's ∂f/∂x_k coefficients sit in column k·P + p; the gradients at the points then
    # agree with the central differences checked above.
    degree, members = 4, 7
    at = rng.normal(size=(basis.n_coefficients(dim, degree), members)).astype(dtype)
    out = basis.gradient_coefficients(at, dim, degree)
    assert out.dtype == dtype and out.shape == (basis.n_coefficients(dim, degree - 1), dim * members)
    for k, dmap in enumerate(basis.derivative_maps(dim, degree)):
        np.testing.assert_allclose(out[:, k * members:(k + 1) * members], dmap @ at.astype(np.float64),
                                   rtol=1e-6 if dtype == np.float32 else 1e-15)
    pts = rng.uniform(-1, 1, size=(5, dim))
    m, dm = basis.monomials_and_gradients(pts, degree)
    low = m[:, : basis.n_coefficients(dim, degree - 1)]
    for k in range(dim):
        np.testing.assert_allclose(low @ out[:, k * members:(k + 1) * members].astype(np.float64),
                                   dm[k] @ at.astype(np.float64), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("dim, degree", [(2, 0), (2, 5), (2, 14), (3, 1), (3, 8), (3, 12)])
def test_the_compiled_design_matrix_is_the_array_one_to_the_bit(dim, degree, rng):
    # The same products in the same order (powers from 1 by repeated multiplication, factors in
    # axis order), and products alone leave the compiler nothing to reassociate or fuse: equal
    # bits on any machine, NaN, infinities, signed zeros and overflow included.
    n = basis._COMPILED_ROWS + 37
    pts = rng.normal(size=(n, dim)) * np.exp(rng.uniform(-30, 30, size=(n, 1)))
    pts[:6] = [[np.nan] * dim, [np.inf] * dim, [-np.inf] * dim, [-0.0] * dim, [0.0] * dim, [1e200] * dim]
    pts = np.asfortranarray(pts)  # not C-contiguous: the kernel gets a copy
    exps = basis.exponents(dim, degree)
    compiled = basis.monomials(pts, exps)
    with np.errstate(over="ignore", invalid="ignore"):  # numpy warns of the overflow; the kernel is silent
        array = basis.monomials(pts, exps, basis.power_table(pts, degree))  # the array version
    assert compiled.shape == (n, len(exps)) and compiled.dtype == np.float64
    assert np.array_equal(compiled.view(np.uint64), array.view(np.uint64))
    # and by hand: x² y at (2, 3) is 12
    if degree >= 3:
        k = [tuple(e) for e in exps.tolist()].index((2, 1) + (0,) * (dim - 2))
        assert basis.monomials(np.tile([[2.0, 3.0, 5.0][:dim]], (n, 1)), exps)[0, k] == 12.0

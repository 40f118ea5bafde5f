"""``ipfit._utils.numeric.unique_rows``: numpy's ``unique(axis=0)`` of rows, by a sort of columns."""

import numpy as np
import pytest

from ipfit._utils.numeric import unique_rows


def _numpy(a):
    u, first, inverse, counts = np.unique(a, axis=0, return_index=True, return_inverse=True, return_counts=True)
    return u, first, inverse.ravel(), counts


@pytest.mark.parametrize("kind", ["float", "int", "ties in the first column", "all equal", "one column"])
def test_unique_rows_is_numpys_unique_of_rows(kind, rng):
    for _ in range(50):
        n, d = int(rng.integers(1, 400)), int(rng.integers(2, 4))
        if kind == "float":
            a = rng.normal(size=(n, d))
            a = np.vstack([a, a[rng.integers(0, n, size=n // 3)]])  # repeated rows
        elif kind == "int":
            a = rng.integers(-3, 3, size=(n, d))
        elif kind == "ties in the first column":
            a = rng.normal(size=(n, d))
            a[:, 0] = np.round(a[:, 0])
        elif kind == "all equal":
            a = np.ones((n, d))
        else:
            a = rng.integers(0, 5, size=(n, 1)).astype(float)
        a = a[rng.permutation(len(a))]
        for ours, theirs in zip(unique_rows(a), _numpy(a), strict=True):
            np.testing.assert_array_equal(ours, theirs)


def test_unique_rows_takes_zero_and_minus_zero_as_one_row():
    u, first, inverse, counts = unique_rows(np.array([[0.0, 1.0], [-0.0, 1.0], [2.0, 1.0]]))
    assert len(u) == 2 and first.tolist() == [0, 2] and inverse.tolist() == [0, 0, 1] and counts.tolist() == [2, 1]


def test_unique_rows_of_no_rows():
    u, first, inverse, counts = unique_rows(np.empty((0, 3)))
    assert u.shape == (0, 3) and len(first) == len(inverse) == len(counts) == 0

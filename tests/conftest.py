"""Shared fixtures.

Tests are seeded: ``IPFIT_TEST_SEED`` (default 0) picks the seed, so the same suite can be
re-run under other seeds (``IPFIT_TEST_SEED=7 pytest``) to show results do not hinge on one.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


def test_seed() -> int:
    return int(os.environ.get("IPFIT_TEST_SEED", "0"))


test_seed.__test__ = False  # a helper, not a test


@pytest.fixture
def seed() -> int:
    return test_seed()


@pytest.fixture
def rng(seed) -> np.random.Generator:
    return np.random.default_rng(seed)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data folder not found at {SHARED_DATA}")
    return SHARED_DATA

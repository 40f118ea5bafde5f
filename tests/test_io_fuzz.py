"""Hypothesis fuzzing of every reader (issue 13, item 5): mutated valid files of each format
give a clean read or one IpfitError line, never a foreign exception or a numpy warning.

The default suite runs a few examples per format; the slow suite (``-m slow``) 1,000 per
format. The seeds, mutations and the oracle live in ``fuzz_readers.py`` (also used by the
robustness report through ``fuzz_readers.fuzz_counts``).
"""

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_readers import MUTATIONS, is_text, make_seeds, mutate, read_outcome

FORMATS = ["ply-binary", "ply-ascii", "ply-mesh", "csv", "xyz", "npy", "npz", "obj", "off", "stl-binary",
           "stl-ascii", "glb", "3mf", "dae", "png", "gif", "las", "laz", "pcd-ascii", "pcd-binary", "e57"]


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz_seeds")
    files = make_seeds(folder)
    assert sorted(files) == sorted(FORMATS)  # every format the seeds cover is fuzzed
    return {label: (path.suffix, path.read_bytes()) for label, path in files.items()}


def test_every_reader_has_a_fuzz_seed(seeds):
    from ipfit.io import FORMATS as READERS

    fuzzed = {suffix for suffix, _ in seeds.values()}
    readers = {fmt.reader for fmt in READERS.values()}
    covered = {READERS[suffix].reader for suffix in fuzzed}
    assert covered == readers


def test_the_seeds_read_cleanly(seeds, tmp_path):
    for label, (suffix, data) in seeds.items():
        path = tmp_path / f"seed_{label}{suffix}"
        path.write_bytes(data)
        assert read_outcome(path) == ("read", ""), label


def _check(seeds, tmp_path, label, kind, seed):
    suffix, data = seeds[label]
    path = tmp_path / f"fuzz_{label}{suffix}"
    path.write_bytes(mutate(data, kind, random.Random(seed), is_text(data)))
    outcome, detail = read_outcome(path)
    assert outcome != "foreign", f"{label} / {kind} / seed {seed}: {detail}"


_FUZZ = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.mark.parametrize("label", FORMATS)
@settings(max_examples=6, **_FUZZ)
@given(kind=st.sampled_from(MUTATIONS), seed=st.integers(0, 2**32 - 1))
def test_mutated_files_raise_only_ipfit_errors(seeds, tmp_path, label, kind, seed):
    _check(seeds, tmp_path, label, kind, seed)


@pytest.mark.slow
@pytest.mark.parametrize("label", FORMATS)
@settings(max_examples=1000, **_FUZZ)
@given(kind=st.sampled_from(MUTATIONS), seed=st.integers(0, 2**32 - 1))
def test_mutated_files_raise_only_ipfit_errors_1000_per_format(seeds, tmp_path, label, kind, seed):
    _check(seeds, tmp_path, label, kind, seed)

"""Helpers for tests that run the command line: a quick fit's JSON, waiting for a condition."""

from __future__ import annotations

import json
import time

from ipfit.cli import main


def quick_fit(tmp_path, spec, *extra) -> dict:
    """``ipfit fit SPEC`` at degree 2 with 3L (seconds), its JSON; ``extra`` options appended."""
    prefix = tmp_path / "out" / "fit"
    code = main(["fit", str(spec), "-o", str(prefix), "--degree", "2", "--method", "3l", "--no-picture",
                 "--no-zero-set", "-q", *extra])
    assert code == 0
    return json.loads(prefix.with_suffix(".json").read_text())


def wait_for(predicate, timeout: float = 120.0) -> bool:
    """Poll ``predicate`` until it holds (True) or ``timeout`` seconds pass (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.01)
    return False

"""How numbers are printed in the report, the verdicts' texts and the progress lines.

>>> fmt(0.98765, 3), fmt(None), fmt(True), fmt(1.5e-7), sig(0.012345), pct(0.2677)
('0.988', '–', 'yes', '1.500e-07', '0.01235', '26.77 %')
"""

from __future__ import annotations

import math

__all__ = ["fmt", "sig", "pct"]


def fmt(value, digits: int = 4) -> str:
    """``digits`` decimals; scientific notation for very small or large values; '–' for missing."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if not math.isfinite(value):
        return "–"
    if value != 0 and (abs(value) < 10 ** -(digits - 1) or abs(value) >= 10 ** (digits + 2)):
        return f"{value:.{max(1, digits - 1)}e}"
    return f"{value:.{digits}f}"


def sig(value, digits: int = 4) -> str:
    """``digits`` significant digits; '–' for missing."""
    return "–" if value is None else f"{float(value):.{digits}g}"


def pct(value) -> str:
    """A share as a percentage with two decimals; '–' for missing."""
    return "–" if value is None else f"{100 * value:.2f} %"

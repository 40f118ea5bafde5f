"""Error and warning types raised by ipfit.

Every caller error derives from :class:`IpfitError`; the ones about values also derive
from :class:`ValueError`, so ``except ValueError`` keeps working for users who do not
know ipfit's types.
"""

from __future__ import annotations

__all__ = [
    "IpfitError",
    "InvalidInputError",
    "ReadError",
    "IpfitWarning",
    "ConditioningWarning",
    "NormalsDroppedWarning",
]


class IpfitError(Exception):
    """Base class of every error raised on purpose by ipfit."""


class InvalidInputError(IpfitError, ValueError):
    """An argument has the wrong shape, type or value.

    The message names the parameter, what was expected, what came, and the fix.
    """


def error(name: str, expected: str, got: str, fix: str = "") -> InvalidInputError:
    """Build the library's standard caller error (returned, so callers write ``raise``)."""
    message = f"{name}: expected {expected}, got {got}."
    if fix:
        message += f" {fix}"
    return InvalidInputError(message)


class ReadError(InvalidInputError):
    """A file could not be read as points (missing, empty, truncated, unknown format...).

    The message starts with the file's path.
    """


class IpfitWarning(UserWarning):
    """Base class of ipfit's warnings."""


class ConditioningWarning(IpfitWarning):
    """A linear system was rank deficient or badly conditioned; the fit may be unstable."""


class NormalsDroppedWarning(IpfitWarning):
    """A file's normals could not be used (all zero, or not one per point): they were dropped
    or repaired, and ipfit takes them from the faces or estimates them instead."""

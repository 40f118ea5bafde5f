"""Readers of tables: text (XYZ/TXT/CSV, with or without a header) and NumPy (.npy/.npz).

Columns are x, y[, z] optionally followed by as many normal components, or named by a
header (x, y, z, nx, ny, nz / normal_x... ). NumPy headers are checked against the file's
size before anything is allocated.

A 2D text file of several closed contours (an outline and its holes, or several shapes) lists
them one after the other, separated by a blank line or a row of NaN: they are read as one
ordered contour of several loops (:func:`ipfit.io._base.chain_loops`), each later loop
starting where the jump to it is longest, so that the quality measures and the topology tell
them apart.
"""

from __future__ import annotations

import io as _io
import zipfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ReadError
from ._base import Raw, chain_offsets, short

__all__ = ["read_text", "read_npy", "read_npz"]

_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"), ("n_x", "n_y", "n_z"))


def _split(line: str, delimiter: str | None) -> list[str]:
    return [w.strip() for w in line.split(delimiter)] if delimiter else line.split()


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def read_text(path: Path, raw: bytes) -> Raw:
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ReadError(f"{path}: not a text file (byte {exc.start} is not UTF-8 text). "
                        "Check the format of the file.") from None
    if "\x00" in text:
        raise ReadError(f"{path}: not a text file (it contains NUL bytes). Check the format of the file.")
    lines, blocks, block = [], [], 0
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0].strip()
        if content:
            lines.append((number, content))
            blocks.append(block)
        elif not line.strip():
            block += 1  # a blank line: the rows after it are another contour
    if not lines:
        raise ReadError(f"{path}: no data rows (only blank or comment lines). Add one point per row.")
    first = lines[0][1]
    delimiter = "," if "," in first else (";" if ";" in first else None)
    names = None
    if not all(_is_number(w) for w in _split(first, delimiter)):
        names = [w.strip().strip('"').strip("'").lower() for w in _split(first, delimiter)]
        lines, blocks = lines[1:], blocks[1:]
        if not lines:
            raise ReadError(f"{path}: a header line but no data rows. Add one point per row.")
    numbers = [number for number, _ in lines]
    body = [line for _, line in lines]
    ncols = len(_split(body[0], delimiter))
    try:
        table = np.loadtxt(body, delimiter=delimiter, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        _diagnose_table(path, body, numbers, delimiter, ncols if names is None else len(names))
        raise  # _diagnose_table always raises; this keeps type checkers content
    if names is not None and len(names) != table.shape[1]:
        raise ReadError(f"{path}: the header names {len(names)} columns but line {numbers[0]} has "
                        f"{table.shape[1]} values. Make them match.")
    separators = np.isnan(table).all(axis=1)  # a row of NaN: the rows after it are another contour
    bad = ~np.isfinite(table).all(axis=1) & ~separators
    if bad.any():
        first_bad = numbers[int(np.flatnonzero(bad)[0])]
        raise ReadError(f"{path}: {int(bad.sum())} rows with NaN or infinite values (first at line {first_bad}). "
                        "Remove or repair them.")
    if separators.any() or blocks[-1] != blocks[0]:
        table = _chained(table, np.asarray(blocks) + np.cumsum(separators))
    if not len(table):
        raise ReadError(f"{path}: no data rows (only separators). Add one point per row.")
    return _columns(path, table, names)


def _chained(table: NDArray, blocks: NDArray) -> NDArray:
    """The rows without the NaN separators; the contours of a 2D table (``blocks`` numbers
    them, separators included) chained as loops of one ordered contour. Contours of fewer than
    3 rows, or 3D rows, are kept in the file's order."""
    keep = ~np.isnan(table).all(axis=1)
    table, blocks = table[keep], blocks[keep]
    starts = np.flatnonzero(np.r_[True, blocks[1:] != blocks[:-1]]) if len(blocks) else np.empty(0, dtype=int)
    parts = np.split(table, starts[1:])
    if len(parts) < 2 or table.shape[1] not in (2, 4) or min(map(len, parts)) < 3:
        return table
    offsets = chain_offsets([part[:, :2] for part in parts])
    return np.concatenate([np.roll(part, -k, axis=0) for part, k in zip(parts, offsets, strict=True)])


#: Rows searched for a number before a text file that fails to read is called a text without numbers.
_NUMBER_SEARCH_ROWS = 10_000


def _diagnose_table(path: Path, body: list[str], numbers: list[int], delimiter: str | None, ncols: int) -> None:
    """Find the first bad line (only on failure: a Python loop is fine here) and raise."""
    # A prose or a list of words is no table with a bad row: say that nothing in it is a number
    # (its first line, taken for a header, would otherwise set the expected column count).
    searched = body[:_NUMBER_SEARCH_ROWS]
    if not any(_is_number(word) for line in searched for word in _split(line, delimiter)):
        where = "in it" if len(searched) == len(body) else f"in its first {len(searched):,} rows"
        raise ReadError(f"{path}: nothing {where} is a number, so it holds no points (a text document?). "
                        "Expected one point per row: x y [z], optionally followed by the normal's components.")
    for number, line in zip(numbers, body, strict=True):
        words = _split(line, delimiter)
        if len(words) != ncols:
            raise ReadError(f"{path}: line {number} has {len(words)} values, expected {ncols} like the first row. "
                            "Every row needs the same columns.")
        for word in words:
            if not _is_number(word):
                shown = word if len(word) <= 20 else word[:17] + "..."
                raise ReadError(f"{path}: line {number}: '{shown}' is not a number. "
                                "Use plain decimal numbers (a '#' starts a comment).")
    raise ReadError(f"{path}: the rows could not be read as numbers. Check the delimiter and the values.")


def _columns(path: Path, table: NDArray, names: list[str] | None) -> Raw:
    if names is not None and {"x", "y"} <= set(names):
        axes = ["x", "y", "z"] if "z" in names else ["x", "y"]
        points = table[:, [names.index(a) for a in axes]]
        for candidate in _NORMAL_NAMES:
            wanted = list(candidate[:len(axes)])
            if set(wanted) <= set(names):
                return Raw(points, table[:, [names.index(a) for a in wanted]])
        partial = [name for candidate in _NORMAL_NAMES for name in candidate if name in names]
        if partial:
            return Raw(points, dropped_normals=f"the header names {', '.join(partial)} but not all "
                                              f"{len(axes)} normal components")
        return Raw(points)
    return _positional(path, table)


def _positional(path: Path, table: NDArray) -> Raw:
    ncols = table.shape[1]
    if ncols in (2, 3):
        return Raw(table)
    if ncols in (4, 6):
        half = ncols // 2
        return Raw(table[:, :half], table[:, half:])
    raise ReadError(f"{path}: {ncols} columns; expected 2 or 3 coordinates, optionally followed by as many "
                    "normal components (2, 3, 4 or 6 columns), or a header naming x, y[, z][, nx, ny[, nz]].")


# -- NumPy ---------------------------------------------------------------------------------------

def _check_npy_header(path: Path, stream) -> None:
    """Refuse arrays whose header announces more data than the file holds."""
    start = stream.tell()
    version = np.lib.format.read_magic(stream)
    reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, _, dtype = reader(stream)
    if dtype.hasobject:
        raise ReadError(f"{path}: the array holds Python objects, not numbers. Save a numeric array.")
    needed = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    here = stream.tell()
    stream.seek(0, 2)
    available = stream.tell() - here
    stream.seek(start)
    if needed > available:
        raise ReadError(f"{path}: truncated: the header announces an array of shape {shape} "
                        f"({needed} bytes) but {available} bytes follow.")


def read_npy(path: Path, raw: bytes) -> Raw:
    stream = _io.BytesIO(raw)
    _check_npy_header(path, stream)
    arr = np.load(stream, allow_pickle=False)
    return _array_columns(path, arr, "the array")


def _array_columns(path: Path, arr: NDArray, what: str) -> Raw:
    if arr.dtype.kind not in "biuf":
        raise ReadError(f"{path}: {what} holds {arr.dtype} values, not numbers.")
    if arr.ndim != 2:
        raise ReadError(f"{path}: {what} has shape {arr.shape}; expected (N, 2), (N, 3), or with normals "
                        "as extra columns (N, 4) or (N, 6).")
    return _positional(path, arr.astype(np.float64))


def read_npz(path: Path, raw: bytes) -> Raw:
    try:
        archive = np.load(_io.BytesIO(raw), allow_pickle=False)
    except zipfile.BadZipFile as exc:
        raise ReadError(f"{path}: not a valid NPZ archive ({short(exc)}).") from None
    with archive:
        keys = list(archive.files)
        if "points" in keys:
            key = "points"
        elif len(keys) == 1:
            key = keys[0]
        else:
            raise ReadError(f"{path}: no array named 'points' (arrays: {', '.join(keys) or 'none'}). "
                            "Save with np.savez(path, points=..., normals=...).")
        data = _array_columns(path, archive[key], f"array '{key}'")
        if "normals" in keys:
            normals = archive["normals"]
            if normals.dtype.kind not in "biuf":
                raise ReadError(f"{path}: array 'normals' holds {normals.dtype} values, not numbers.")
            data = Raw(data.points, normals.astype(np.float64))
        if "faces" in keys and archive["faces"].dtype.kind in "iu" and archive["faces"].ndim == 2 \
                and archive["faces"].shape[1] == 3:
            data = Raw(data.points, data.normals, archive["faces"].astype(np.int64))
    return data


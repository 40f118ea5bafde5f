"""Atomic file output: write beside the target, then rename, so no reader ever sees half a file.

Every temporary file this process creates is recorded here, so that one call,
:func:`discard_temporaries`, removes whatever an interrupted or failed run left behind
(the command line calls it on every exit). An ``OSError`` raised while writing names the
final path, never the temporary one, so the message tells the user which output failed.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
import time
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "write_text_atomic", "write_bytes_atomic", "reserve", "publish", "discard_temporaries",
           "written_paths", "remove_temporary", "aimed_at"]

#: Bytes written by :func:`reserve` to prove the folder takes a file (space, permissions).
PROBE_BYTES = 4096

_live: set[Path] = set()  # temporary files not yet renamed into place or removed
_created_dirs: list[Path] = []  # folders made for outputs; removed again if they stay empty
_written: list[Path] = []  # final paths published by this process, in order


def _folder_of(target: Path) -> Path:
    return target.parent if str(target.parent) else Path(".")


def aimed_at(exc: OSError, target: Path) -> OSError:
    """``exc`` re-aimed at ``target`` when it was about one of its temporary files (or no file).

    Temporary names are ``.NAME.XXXX.partial.SUFFIX``, and a writer's own temporary file for
    a staged one adds another dot in front, so the dots are stripped before comparing.
    """
    name = exc.filename
    temporary = isinstance(name, str) and Path(name).name.lstrip(".").startswith(f"{target.name.lstrip('.')}.")
    if name is None or temporary:
        return type(exc)(exc.errno, exc.strerror or str(exc), str(target))
    return exc


def _temporary(target: Path, suffix: str | None) -> Path:
    directory = _folder_of(target)
    if target.is_dir():
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(target))
    ancestor = directory
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():  # a file where a folder is needed
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(ancestor))
    if not directory.is_dir():
        from .exceptions import InvalidInputError

        raise InvalidInputError(f"{target}: the folder {directory} does not exist. Create it first or choose another path.")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial" + (
            suffix if suffix is not None else target.suffix), dir=directory)
    except OSError as exc:
        raise aimed_at(exc, target) from None
    os.close(fd)
    _live.add(Path(tmp))
    return Path(tmp)


def remove_temporary(tmp: Path) -> None:
    """Delete one temporary file (if still there) and forget it."""
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    _live.discard(tmp)


def _test_delay() -> None:
    """Test hook: ``IPFIT_TEST_WRITE_DELAY=seconds`` slows every file write (inert when unset)."""
    delay = os.environ.get("IPFIT_TEST_WRITE_DELAY")
    if delay:
        time.sleep(float(delay))


def publish(tmp: Path, target: str | os.PathLike) -> None:
    """Rename the temporary ``tmp`` onto ``target``, with the permissions a plain ``open()`` gives."""
    target = Path(target)
    mask = os.umask(0)
    os.umask(mask)
    try:
        os.chmod(tmp, 0o666 & ~mask)  # mkstemp creates 0600 files
        os.replace(tmp, target)
    except OSError as exc:
        raise aimed_at(exc, target) from None
    _live.discard(tmp)
    _written.append(target)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` only on success.

    The temporary file keeps the target's suffix so that writers choosing a format by
    extension (matplotlib, trimesh) still work.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "a.txt") as tmp:
    ...     _ = tmp.write_text("done")
    >>> sorted(p.name for p in folder.iterdir())
    ['a.txt']
    """
    target = Path(path)
    tmp = _temporary(target, suffix)
    try:
        try:
            yield tmp
            _test_delay()
        except OSError as exc:
            raise aimed_at(exc, target) from None
        publish(tmp, target)
    finally:
        remove_temporary(tmp)


def reserve(path: str | os.PathLike, make_folders: bool = True) -> Path:
    """Create the temporary sibling that will become ``path``, proving it can be written.

    Missing folders are made if ``make_folders`` (and recorded, so :func:`discard_temporaries` removes them
    again if they stay empty); :data:`PROBE_BYTES` bytes are written and flushed to disk,
    so a full disk, a read-only file system or a missing permission shows up now, before
    any long computation. The caller later writes the real content to the returned path
    and :func:`publish`-es it, or leaves it to :func:`discard_temporaries`.
    """
    target = Path(path)
    missing = []
    folder = _folder_of(target)
    while make_folders and not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    for folder in reversed(missing):
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise aimed_at(exc, target) from None
        _created_dirs.append(folder)
    tmp = _temporary(target, None)
    try:
        with open(tmp, "wb") as fh:
            fh.write(b"\0" * PROBE_BYTES)
            fh.flush()
            os.fsync(fh.fileno())
        os.truncate(tmp, 0)
    except OSError as exc:
        remove_temporary(tmp)
        raise aimed_at(exc, target) from None
    return tmp


def discard_temporaries() -> None:
    """Remove every temporary file still pending, and the output folders made that stayed empty."""
    for tmp in list(_live):
        remove_temporary(tmp)
    for folder in reversed(_created_dirs):
        with contextlib.suppress(OSError):
            folder.rmdir()
    _created_dirs.clear()


def written_paths() -> list[Path]:
    """The final paths written so far by this process, oldest first."""
    return list(_written)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)

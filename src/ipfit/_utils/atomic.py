"""Atomic file output: write beside the target, then rename, so no reader ever sees half a file.

The hidden files this module makes beside a target are named after its *output set*, a hash
``KEY`` of the target's name without its suffix (``r.json``, ``r.png`` and ``r.svg`` share
``r``'s), so that their names stay short whatever the target's:

``.ipfit-KEY-XXXXXXXX.partial.SUFFIX``
    a temporary file, renamed onto its target once complete;
``.ipfit-KEY.lock``
    locked (``flock``) by the process writing the set, from its first temporary file until the
    last one is renamed or removed; another process waits up to :data:`LOCK_WAIT` seconds for
    it, then refuses with one line;
``.ipfit-KEY.journal``
    the renames of a set being published (:func:`publish_set`), written once every temporary
    file of the set is complete.

A process killed by SIGKILL leaves its hidden files behind. The next process that writes to the
same set, once it holds the lock (so the writer is gone), finishes the publication a journal
records and removes the other temporary files (:func:`settle`). Every temporary file this
process creates is recorded, so that :func:`discard_temporaries` removes whatever an
interrupted or failed run left (the command line calls it on every exit). Errors name the
final path, never a hidden file.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import stat
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no advisory locks, writes are still atomic
    fcntl = None  # type: ignore[assignment]  # an optional module: mypy has no type for "the module or None"

from ..exceptions import InvalidInputError, IpfitError

__all__ = ["atomic_path", "write_text_atomic", "write_bytes_atomic", "reserve", "publish", "publish_set",
           "discard_temporaries", "written_paths", "remove_temporary", "aimed_at", "reaimed", "settle",
           "special_kind", "refuse_special", "unfinished", "LOCK_WAIT"]

#: Bytes written by :func:`reserve` to prove the folder takes a file (space, permissions).
PROBE_BYTES = 4096
#: Seconds a writer waits for another process writing the same output set before refusing.
LOCK_WAIT = 2.0

_HIDDEN = ".ipfit-"
_KEY = re.compile(r"\.ipfit-([0-9a-f]{12})[-.]")
_MAX_SUFFIX = 16  # longer suffixes name no format a writer knows; they would only lengthen the name

_live: dict[Path, tuple | None] = {}  # temporary files not yet renamed into place or removed -> their set's lock
_created_dirs: list[Path] = []  # folders made for outputs; removed again if they stay empty
_written: list[Path] = []  # final paths published by this process, in order
_locks: dict[tuple, list] = {}  # (folder device, folder inode, key) -> [descriptor, holds, lock path]
_guard = threading.RLock()  # threads of one process share a lock (a second flock would block on the first)

_SPECIAL = ((stat.S_ISFIFO, "named pipe (FIFO)"), (stat.S_ISCHR, "character device"),
            (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket"))


def _folder_of(target: Path) -> Path:
    return target.parent if str(target.parent) else Path(".")


def _key(target: Path) -> str:
    """The output set of ``target``: a hash of its name without the suffix; a hidden file of
    ours (a writer's own temporary for a staged one) belongs to the set it was made for."""
    match = _KEY.match(target.name)
    if match:
        return match.group(1)
    return hashlib.sha1(target.stem.encode("utf-8", "surrogateescape")).hexdigest()[:12]


def special_kind(path: str | os.PathLike) -> str | None:
    """What ``path`` is, when it exists (symlinks followed) as neither a regular file nor a folder."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    return next((name for test, name in _SPECIAL if test(mode)), None)


def refuse_special(target: str | os.PathLike, name: str | None = None) -> None:
    """An InvalidInputError (named ``name``, else the path) when ``target`` is a device, FIFO or
    socket: renaming a file onto it would replace the system's ``/dev/null``, say."""
    kind = special_kind(target)
    if kind is not None:
        from .validation import error

        got = f"{target}, a {kind}" if name else f"a {kind}"
        raise error(name or str(target), "a regular file or a new file name", got,
                    "Choose another output path: ipfit would replace it with a file.")


def _named(exc: OSError, target: Path) -> OSError:
    return type(exc)(exc.errno, exc.strerror or str(exc), str(target))


def aimed_at(exc: OSError, target: Path) -> OSError:
    """``exc`` re-aimed at ``target`` when it was about one of our hidden files (or no file)."""
    name = exc.filename
    if name is None or (isinstance(name, (str, os.PathLike)) and Path(name).name.startswith(_HIDDEN)):
        return _named(exc, target)
    return exc


def reaimed(exc: BaseException, hidden: Path, target: Path) -> BaseException:
    """``exc`` naming ``target`` where it named the hidden file ``hidden``: an OSError about it (or
    about no file), or an ipfit error whose message quotes its path."""
    if isinstance(exc, OSError):
        name = exc.filename
        same = name is None or (isinstance(name, (str, os.PathLike)) and os.fspath(name) == str(hidden))
        return _named(exc, target) if same else exc
    if isinstance(exc, IpfitError) and str(hidden) in str(exc):
        with contextlib.suppress(TypeError):
            return type(exc)(str(exc).replace(str(hidden), str(target)))
    return exc


# -- the lock of an output set ------------------------------------------------------------------

def _open_lock(path: Path, target: Path) -> int:
    # O_NOFOLLOW, O_NONBLOCK: a symlink or FIFO planted under the lock's name is neither followed nor waited on
    flags = os.O_NOFOLLOW | os.O_NONBLOCK
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT | flags, 0o666)
    except PermissionError as exc:  # another user's lock file: flock works on a read-only descriptor too
        try:
            return os.open(path, os.O_RDONLY | flags)
        except OSError:
            raise aimed_at(exc, target) from None
    except OSError as exc:
        raise aimed_at(exc, target) from None


def _still_there(fd: int, path: Path, target: Path) -> bool:
    """Whether the locked descriptor is still the file at ``path`` (its holder removes it when done)."""
    try:
        on_disk = os.lstat(path)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    if not stat.S_ISREG(mine.st_mode):
        raise InvalidInputError(f"{target}: {path} is in the way (it is not a regular file). Remove it.")
    return (on_disk.st_dev, on_disk.st_ino) == (mine.st_dev, mine.st_ino)


def _holder(fd: int) -> str:
    with contextlib.suppress(OSError, ValueError):
        return f" (pid {int(os.pread(fd, 32, 0).decode().strip())})"
    return ""


def _acquire(path: Path, target: Path) -> tuple[int, bool]:
    """Lock ``path`` (made if missing), waiting up to :data:`LOCK_WAIT` seconds for another process.

    Also says whether a killed holder left it: a holder writes its pid into the file and removes
    the file when done, so only a dead one leaves a non-empty lock file.
    """
    deadline = time.monotonic() + LOCK_WAIT
    while True:
        fd = _open_lock(path, target)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if _still_there(fd, path, target):
                left = os.fstat(fd).st_size > 0
                with contextlib.suppress(OSError):  # who holds it, for the message of the next one
                    os.ftruncate(fd, 0)
                    os.write(fd, f"{os.getpid()}\n".encode())
                return fd, left
        except BlockingIOError:
            holder = _holder(fd)
            if time.monotonic() >= deadline:
                os.close(fd)
                raise InvalidInputError(f"{target}: another ipfit process{holder} is writing {target.stem}.* right "
                                        "now. Wait for it to finish, or choose another output path.") from None
            time.sleep(0.05)
        except OSError as exc:  # a file system without locks (some network mounts): write unlocked
            if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP):
                return fd, False
            os.close(fd)
            raise aimed_at(exc, target) from None
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)  # removed by its holder meanwhile, or still held: try again


def _hold(target: Path) -> tuple | None:
    """Hold the lock of ``target``'s output set (re-entrant within this process). The first hold
    finishes or clears what a killed writer of the set left (see :func:`_recover`)."""
    if fcntl is None:  # pragma: no cover
        return None
    folder, key = _folder_of(target), _key(target)
    try:
        info = os.stat(folder)
    except OSError as exc:
        raise aimed_at(exc, target) from None
    ident = (info.st_dev, info.st_ino, key)
    with _guard:
        held = _locks.get(ident)
        if held is not None:
            held[1] += 1
            return ident
        path = Path(os.path.abspath(folder / f"{_HIDDEN}{key}.lock"))
        fd, left = _acquire(path, target)
        _locks[ident] = [fd, 1, path]
        try:
            if left:  # only then can there be anything to finish or clear (no listing of big folders)
                _recover(folder, key)
        except OSError as exc:
            _release(ident)
            raise aimed_at(exc, target) from None
        except BaseException:
            _release(ident)
            raise
    return ident


def _release(ident: tuple | None) -> None:
    with _guard:
        if ident is None:  # no lock was taken (no fcntl)
            return
        held = _locks.get(ident)
        if held is None:
            return
        held[1] -= 1
        if held[1] > 0:
            return
        del _locks[ident]
        fd, _, path = held
        # removed while still locked: a process that opened it meanwhile sees it gone and retries
        with contextlib.suppress(OSError):
            path.unlink()
        os.close(fd)


def unfinished(path: str | os.PathLike) -> bool:
    """Whether a writer of ``path``'s output set was killed while renaming it into place (its
    journal is still there): the set may be half old, half new until :func:`settle`."""
    target = Path(path)
    return _journal(_folder_of(target), _key(target)).exists()


def settle(path: str | os.PathLike) -> None:
    """Finish or clear what a killed writer left for ``path``'s output set (waits for a live one).

    Every write does this first; a reader that wants the set complete may call it too.
    """
    target = Path(path)
    _release(_hold(target))


# -- publication as a set -----------------------------------------------------------------------

def _journal(folder: Path, key: str) -> Path:
    return folder / f"{_HIDDEN}{key}.journal"


def _entry(folder: Path, key: str, pair) -> tuple[Path, Path] | None:
    """A journal line as (temporary, target) in ``folder``, if it is one this set can have written."""
    if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(n, str) for n in pair)):
        return None
    tmp, final = pair
    if any(os.sep in n or n in ("", ".", "..") for n in pair):
        return None
    if not tmp.startswith(f"{_HIDDEN}{key}-") or final.startswith(_HIDDEN) or _key(Path(final)) != key:
        return None
    return folder / tmp, folder / final


def _recover(folder: Path, key: str) -> None:
    """With the set's lock held: rename what a killed writer's journal lists (each temporary it
    names was complete when the journal was written), then remove every temporary of the set."""
    journal = _journal(folder, key)
    if journal.is_file():
        try:
            renames = list(json.loads(journal.read_text(encoding="utf-8"))["renames"])
        except (ValueError, LookupError, TypeError):  # not ours, or damaged: nothing to finish
            renames = []
        for tmp, final in filter(None, (_entry(folder, key, pair) for pair in renames)):
            if tmp.is_file() and not tmp.is_symlink() and special_kind(final) is None:
                _make_public(tmp)
                os.replace(tmp, final)
        journal.unlink()
    for stale in folder.glob(f"{_HIDDEN}{key}-*"):
        stale.unlink(missing_ok=True)


def _make_public(tmp: Path) -> None:
    """The permissions a plain ``open()`` gives (mkstemp creates 0600 files)."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _commit(folder: Path, key: str, group: Sequence[tuple[Path, Path]]) -> Path:
    """Write the journal of ``group`` (itself atomically: renamed into place, synced to disk)."""
    journal = _journal(folder, key)
    text = json.dumps({"pid": os.getpid(), "renames": [[tmp.name, final.name] for tmp, final in group]})
    fd, name = tempfile.mkstemp(prefix=f"{_HIDDEN}{key}-", suffix=".partial", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(name, journal)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(name)
        raise
    _fsync_folder(folder)
    return journal


def publish_set(pairs: Sequence[tuple[Path, Path]]) -> None:
    """Rename every complete temporary onto its target, each output set as a whole.

    The renames of a set are first recorded in its journal: a process killed (SIGKILL) half-way
    leaves the journal, and the next writer of the set finishes them. Whatever stops the renames
    here, the ones left are still done (an error is raised afterwards).
    """
    groups: dict[tuple[Path, str], list[tuple[Path, Path]]] = {}
    for tmp, target in pairs:
        groups.setdefault((_folder_of(Path(target)), _key(Path(target))), []).append((Path(tmp), Path(target)))
    for (folder, key), group in groups.items():
        if len(group) == 1:  # one rename is atomic by itself
            publish(*group[0])
            continue
        ident = _hold(group[0][1])  # until the journal is gone
        try:
            journal = _commit(folder, key, group)
            try:
                for tmp, target in group:
                    _test_delay()
                    publish(tmp, target)
            finally:
                for tmp, target in group:
                    if tmp in _live:
                        with contextlib.suppress(OSError):
                            publish(tmp, target)
                journal.unlink(missing_ok=True)
        finally:
            _release(ident)


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
        raise InvalidInputError(f"{target}: the folder {directory} does not exist. "
                                "Create it first or choose another path.")
    refuse_special(target)
    ident = _hold(target)
    ext = suffix if suffix is not None else target.suffix
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{_HIDDEN}{_key(target)}-",
                                   suffix=".partial" + (ext if len(ext) <= _MAX_SUFFIX else ""), dir=directory)
    except OSError as exc:
        _release(ident)
        raise aimed_at(exc, target) from None
    os.close(fd)
    _live[Path(tmp)] = ident
    return Path(tmp)


def remove_temporary(tmp: Path) -> None:
    """Delete one temporary file (if still there) and forget it."""
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    if tmp in _live:
        _release(_live.pop(tmp))


def _test_delay() -> None:
    """Test hook: ``IPFIT_TEST_WRITE_DELAY=seconds`` slows every file write and every rename of a
    set's publication (inert when unset)."""
    delay = os.environ.get("IPFIT_TEST_WRITE_DELAY")
    if delay:
        time.sleep(float(delay))


def publish(tmp: Path, target: str | os.PathLike) -> None:
    """Rename the temporary ``tmp`` onto ``target``, with the permissions a plain ``open()`` gives."""
    target = Path(target)
    try:
        _make_public(tmp)
        os.replace(tmp, target)
    except OSError as exc:
        raise aimed_at(exc, target) from None
    if tmp in _live:
        _release(_live.pop(tmp))
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
            publish(tmp, target)
        except (OSError, IpfitError) as exc:
            raise reaimed(exc, tmp, target) from None
    finally:
        remove_temporary(tmp)


def _make_folders(target: Path) -> None:
    missing = []
    folder = _folder_of(target)
    while not folder.exists() and folder != folder.parent:
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


def reserve(path: str | os.PathLike, make_folders: bool = True) -> Path:
    """Create the temporary sibling that will become ``path``, proving it can be written.

    Missing folders are made if ``make_folders`` (and recorded, so :func:`discard_temporaries` removes them
    again if they stay empty); :data:`PROBE_BYTES` bytes are written and flushed to disk,
    so a full disk, a read-only file system or a missing permission shows up now, before
    any long computation. The caller later writes the real content to the returned path
    and :func:`publish`-es it, or leaves it to :func:`discard_temporaries`.
    """
    target = Path(path)
    if make_folders:
        _make_folders(target)
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
    """Remove every temporary file still pending, release the locks, and remove the output
    folders made that stayed empty."""
    for tmp in list(_live):
        remove_temporary(tmp)
    with _guard:
        for ident in list(_locks):
            _locks[ident][1] = 1
            _release(ident)
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

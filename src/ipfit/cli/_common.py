"""Helpers shared by the subcommands: option types, signals and all-or-nothing output.

Inputs are read by :func:`ipfit.load` (a file or a bundled dataset's name).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import ClassVar

import numpy as np

from .._utils import atomic as _atomic
from ..exceptions import InvalidInputError, IpfitError


def _whole_number_at_least(minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {value}")
        return value

    return parse


positive_int = _whole_number_at_least(1)
nonnegative_int = _whole_number_at_least(0)


class LazyChoices(Sequence[str]):
    """argparse ``choices`` listed on first use: every start builds the command's parser, and some
    lists (the fit methods) take seconds of imports that a run which never names one should not pay.
    Give the option a ``metavar`` (argparse would list the choices to make one) and write
    ``%(choices)s`` in its help."""

    def __init__(self, load: Callable[[], Sequence[str]]) -> None:
        self._load = load
        self._items: tuple[str, ...] | None = None

    def _get(self) -> tuple[str, ...]:
        if self._items is None:
            self._items = tuple(self._load())
        return self._items

    def __contains__(self, value: object) -> bool:
        return value in self._get()

    def __iter__(self) -> Iterator[str]:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())

    def __getitem__(self, index):
        return self._get()[index]


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def nonnegative_float(text: str) -> float:
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM, raised in the main thread; ``signum`` says which."""

    def __init__(self, signum: int = signal.SIGINT) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _SignalState:
    command = "ipfit"
    defer: ClassVar[list[str | None]] = []  # what is being finished while signals are held (innermost last)
    pending: int | None = None  # a signal held until a safe moment
    received: int | None = None  # the last signal of this run


def _inside_native_callback(frame) -> bool:
    """Whether Python code called back from native code is running (numba's JIT compiler calls
    llvmlite's Python callbacks through ctypes): an exception raised there is printed as
    "Exception ignored" and lost."""
    while frame is not None:
        if "llvmlite" in frame.f_code.co_filename:
            return True
        frame = frame.f_back
    return False


def _on_signal(signum: int, frame) -> None:
    _SignalState.received = signum
    if _inside_native_callback(frame):
        # Deliver it again in a moment, once the callback has returned.
        threading.Timer(0.05, os.kill, (os.getpid(), signum)).start()
        return
    if _SignalState.defer and _SignalState.pending is None:
        _SignalState.pending = signum
        doing = _SignalState.defer[-1]
        if doing:
            print(f"{_SignalState.command}: {signal.Signals(signum).name}: finishing {doing} first "
                  "(send it again to abandon it)", file=sys.stderr, flush=True)
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def handle_signals(command: str) -> Iterator[None]:
    """SIGINT and SIGTERM both raise :class:`Interrupted` in the main thread (restored on exit).

    Python turns only SIGINT into ``KeyboardInterrupt``; SIGTERM would otherwise kill the
    process without running a single ``finally``, leaving temporary files behind.
    """
    _SignalState.command, _SignalState.defer, _SignalState.pending, _SignalState.received = command, [], None, None
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def deferred_signals(doing: str | None = None) -> Iterator[None]:
    """Hold SIGINT/SIGTERM during the block, so an interrupt never loses finished work.

    A held signal stays pending (the run then ends as interrupted, see
    :func:`received_signal`, or :func:`stop_at_iterations` raises it at a safe moment); a
    second signal during the block abandons it. ``doing`` is named in the one line
    printed when a signal is held.
    """
    _SignalState.defer.append(doing)
    try:
        yield
    finally:
        _SignalState.defer.pop()


def stop_at_iterations(progress: Callable[[dict], None] | None) -> Callable[[dict], None]:
    """Wrap a ``fit_adaptive`` progress callback so an interrupt stops the fit where it is safe.

    ``fit_adaptive`` keeps the finished degrees only when the interrupt arrives inside a
    degree's optimisation; a signal arriving while the callback itself runs (printing the
    finished degree, say) is held and raised at the next iteration event, which comes from
    inside the optimisation. Without further iterations the fit completes and the run still
    ends as interrupted, with everything written.
    """
    def call(event: dict) -> None:
        with deferred_signals():
            if progress is not None:
                progress(event)
        if event.get("event") == "iteration" and _SignalState.pending is not None:
            signum, _SignalState.pending = _SignalState.pending, None
            raise Interrupted(signum)

    return call


def received_signal() -> int | None:
    """The signal (SIGINT/SIGTERM) received during this run, or None."""
    return _SignalState.received


#: What ``ipfit fit`` writes beside its prefix; a suffix in ``fit -o`` names one of them.
FIT_SUFFIXES = (".json", ".png", ".ply", ".svg", ".csv")


def beside(prefix: Path, suffix: str) -> Path:
    return prefix.with_name(prefix.name + suffix)


def _same_file(a: Path, b: Path) -> bool:
    if a.exists() and b.exists():
        with contextlib.suppress(OSError):
            return os.path.samefile(a, b)
    return a.resolve() == b.resolve()


def _input_files(inputs: Sequence[str | os.PathLike | None]) -> list[Path]:
    return [Path(p) for p in inputs if p is not None and Path(p).is_file()]


def recorded_sources(result) -> list[str]:
    """The data files a result records (``"input": {"path": ..., "source": ...}``), to protect them."""
    recorded = result.get("input") if isinstance(result, Mapping) else None
    if not isinstance(recorded, Mapping):
        return []
    return [v for v in (recorded.get("path"), recorded.get("source")) if isinstance(v, str)]


def _is_ipfit_result(path: Path) -> bool:
    from ..polynomial import FORMAT_NAME

    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh).get("format") == FORMAT_NAME
    except (OSError, ValueError, AttributeError):
        return False


def default_prefix(stem: str, suffixes: Sequence[str], inputs: Sequence[str | os.PathLike | None] = ()) -> Path:
    """The default output prefix: ``STEM``, else ``STEM-fit``, so that no user file is replaced.

    A default output may replace only a previous result of the same prefix: an existing
    ``PREFIX.json`` with ``"format": "ipfit"`` marks the files beside it as ipfit's own.
    Any other existing file (an input above all, e.g. ``heart.csv`` for ``ipfit fit
    heart.csv``) moves the default to ``STEM-fit``; when that collides too, the caller
    must pass ``-o``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "heart.csv").write_text("x,y")
    >>> default_prefix(str(folder / "heart"), [".json", ".csv"], inputs=[folder / "heart.csv"]).name
    'heart-fit'
    >>> default_prefix(str(folder / "heart"), [".json", ".png"], inputs=[folder / "heart.csv"]).name
    'heart'
    """
    files = _input_files(inputs)
    for candidate in (Path(stem), Path(f"{stem}-fit")):
        own = _is_ipfit_result(beside(candidate, ".json"))
        clash = [p for p in (beside(candidate, s) for s in suffixes)
                 if p.exists() or p.is_symlink()]
        if all(own and p.is_file() and not any(_same_file(p, f) for f in files) for p in clash):
            return candidate
    raise InvalidInputError(f"--output: the default outputs {stem}.* and {stem}-fit.* would replace files ipfit did "
                            "not write. Pass -o PREFIX to choose where the results go.")


def fit_prefix(output: str) -> Path:
    """``fit -o``: a prefix, or one of the output files (``pfx.json``) naming the prefix."""
    path = Path(output)
    return path.with_suffix("") if path.suffix.lower() in FIT_SUFFIXES else path


class Outputs:
    """Output files checked before the work starts and written all together or not at all.

    Construction checks every path (not a folder, not a device, FIFO or socket, not one of
    ``inputs``, an allowed extension) and reserves its temporary sibling, which locks the
    output set against other processes (see :mod:`ipfit._utils.atomic`) and proves the folder
    exists (or, with ``make_folders``, can be made), is writable and has room; on any
    failure nothing is left behind. Then::

        with outputs.writing() as stage:
            writer(stage(final))          # write each output to its staged path

    publishes every staged file as one set (:func:`ipfit._utils.atomic.publish_set`) when the
    block ends normally, removes them all when it raises, and holds SIGINT/SIGTERM meanwhile
    so finished work is not lost. Errors name the outputs, never their temporary files.
    """

    def __init__(self, paths: Sequence[str | os.PathLike], *, inputs: Sequence[str | os.PathLike | None] = (),
                 option: str = "--output", suffixes: Sequence[str] | None = None, make_folders: bool = False) -> None:
        self._staged: dict[Path, Path] = {}
        self._used: set[Path] = set()
        files = _input_files(inputs)
        try:
            for final in map(Path, paths):
                if suffixes is not None and final.suffix.lower() not in suffixes:
                    raise InvalidInputError(f"{option}: cannot write '{final.suffix or final.name}' files, got "
                                            f"{final}. Use one of: {', '.join(suffixes)}.")
                if final.is_dir():
                    raise InvalidInputError(f"{option}: {final} is a folder. Choose a file name (a file inside "
                                            "that folder works too).")
                _atomic.refuse_special(final, option)
                source = next((f for f in files if _same_file(final, f)), None)
                if source is not None:
                    raise InvalidInputError(f"{option}: {final} is the input file {source}; writing it would "
                                            "destroy the data. Choose another output path.")
                self._staged[final] = _atomic.reserve(final, make_folders)
        except BaseException:
            self.discard()
            raise

    def discard(self) -> None:
        for tmp in self._staged.values():
            _atomic.remove_temporary(tmp)
        self._staged.clear()

    def _stage(self, final: str | os.PathLike) -> Path:
        self._used.add(Path(final))
        return self._staged[Path(final)]

    def _publication(self) -> list[tuple[Path, Path]]:
        used = [(tmp, final) for final, tmp in self._staged.items() if final in self._used]
        # the JSON last: a result whose JSON is new has every other output new as well
        return sorted(used, key=lambda pair: pair[1].suffix.lower() == ".json")

    def _named(self, exc: BaseException) -> BaseException:
        """``exc`` naming the output it is about, never its temporary file."""
        for final, tmp in self._staged.items():
            exc = _atomic.reaimed(exc, tmp, final)
        if isinstance(exc, OSError) and self._staged:  # another hidden file of the set (its journal)
            exc = _atomic.aimed_at(exc, next(iter(self._staged)))
        return exc

    @contextlib.contextmanager
    def writing(self) -> Iterator[Callable[[str | os.PathLike], Path]]:
        with deferred_signals("writing the outputs"):
            try:
                yield self._stage
                _atomic.publish_set(self._publication())
            except (OSError, IpfitError) as exc:
                raise self._named(exc) from None
            finally:
                self.discard()


def show_progress(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()


@contextlib.contextmanager
def cli_names(names: dict[str, str]):
    """Re-raise library errors that start with a parameter name under the option the user typed.

    ``max_degree: expected at most 22 ...`` becomes ``--max-degree: expected at most 22 ...``.
    """
    try:
        yield
    except InvalidInputError as exc:
        text = str(exc)
        head, sep, rest = text.partition(":")
        if sep and head in names:
            raise InvalidInputError(f"{names[head]}:{rest}") from None
        raise


#: The compiled kernels a fit runs (``render`` adds the ray kernels).
FIT_KERNELS = ("ipfit._basis_kernels", "ipfit.fitting._objective_kernels", "ipfit.optimize._kernels",
               "ipfit.geometry._distance_kernels", "ipfit.robust._local_kernels")


def cold_kernels(modules: Sequence[str] = FIT_KERNELS) -> list[str]:
    """The compiled kernels of ``modules`` that have no usable entry in numba's on-disk cache.

    numba compiles a kernel on its first call and keeps the machine code beside the source (or in
    ``NUMBA_CACHE_DIR``); its index records the source's timestamp, and an index written for an
    older source is not used. A kernel listed here is compiled on this run: the first run after
    an install takes some 20 s longer, and the commands say so first.
    """
    import importlib

    from numba.core.registry import CPUDispatcher

    cold = []
    for name in modules:
        module = importlib.import_module(name)
        for attr, kernel in vars(module).items():
            if not isinstance(kernel, CPUDispatcher) or getattr(kernel, "_cache", None) is None:
                continue
            try:  # numba's cache index, as its own loader reads it (empty when stale)
                index = kernel._cache._cache_file._load_index()  # type: ignore[attr-defined]
            except Exception:  # noqa: BLE001 - an unreadable index is one numba will rewrite
                index = {}
            if not index:
                cold.append(f"{name}.{attr}")
    return cold


def say_if_compiling(command: str, modules: Sequence[str] = FIT_KERNELS) -> None:
    """One line on stderr before a run that compiles kernels (the first after an install)."""
    if cold_kernels(modules):
        print(f"ipfit {command}: compiling kernels, first run only (about 20 s)", file=sys.stderr, flush=True)

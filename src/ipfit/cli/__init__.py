"""The ``ipfit`` command line: ``main(argv) -> exit code``, one module per subcommand.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``. :func:`main` is the one error boundary: caller errors (bad files,
bad option values, unwritable outputs) print one line on stderr and exit with code 2;
SIGINT/SIGTERM exit with 130/143 after cleaning up. Subcommands check their outputs
before working and write them with :class:`ipfit.cli._common.Outputs`.
"""

from __future__ import annotations

# Only cheap modules at import time: a Ctrl-C before main() runs would print a traceback,
# so everything heavier (argparse, signal, numpy, the subcommands) is imported inside main().
import errno
import os
import sys
import warnings

from ..exceptions import IpfitError, IpfitWarning

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing
if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence

SUBCOMMANDS = ("fit", "batch", "normals", "mesh", "plot", "view", "score", "export", "render", "datasets",
               "reproduce")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; with ``command``, only that subcommand's options are built (the
    others are listed, for ``ipfit --help``): building one imports what its choices need. With
    ``command=""`` none is (``ipfit --version``, ``ipfit --help``: no fitting stack imported)."""
    import argparse
    import importlib

    from .. import __version__

    class _Parser(argparse.ArgumentParser):
        def error(self, message: str):  # one line, exit 2, as argparse does, but without the usage block
            self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")

    parser = _Parser(prog="ipfit", description="Fit implicit polynomial curves and surfaces to 2D/3D point clouds "
                     "(Interian et al. 2017), with adaptive degree selection.")
    parser.add_argument("--version", action="version", version=f"ipfit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # subcommand not installed in this build
            raise
        p = sub.add_parser(module.NAME, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        if command is None or command == name:
            module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


_FIXES = {
    errno.ENOSPC: "Free some space or write somewhere else.",
    errno.EDQUOT: "Free some space or write somewhere else.",
    errno.EROFS: "The file system is read-only; write somewhere else.",
    errno.EACCES: "Check the permissions or write somewhere else.",
    errno.EPERM: "Check the permissions or write somewhere else.",
    errno.EISDIR: "That is a folder; pass a file name.",
    errno.ENOTDIR: "A part of the path is a file, not a folder; check the path.",
    errno.ENOENT: "Check the path.",
}


def _os_error_line(exc: OSError) -> str:
    """One line naming the path and the reason, e.g. ``out/a.json: No space left on device. Free...``."""
    reason = exc.strerror or exc.__class__.__name__
    where = ": ".join(str(p) for p in (exc.filename, exc.filename2) if p is not None)
    fix = "" if exc.errno is None else _FIXES.get(exc.errno, "")
    return " ".join(filter(None, [f"{where}: {reason}." if where else f"{reason}.", fix]))


def _warning_line(command: str):
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        label = "warning" if issubclass(category, IpfitWarning) else category.__name__
        print(f"ipfit {command}: {label}: {str(message).splitlines()[0] if str(message) else ''}", file=sys.stderr)

    return show


#: The options of each command that bound its memory, named when it runs out.
_MEMORY_OPTIONS = {
    "fit": "a lower --max-points or --max-degree",
    "batch": "fewer --workers, or a lower --max-degree",
    "normals": "a lower --k",
    "mesh": "a lower --resolution",
    "plot": "a lower --resolution or --dpi",
    "view": "a lower --max-faces",
    "score": "a lower --resolution",
    "render": "a smaller --size",
    "reproduce": "--quick",
}


def _memory_line(command: str, args) -> str:
    """``out of memory`` naming the input and the command's own options that use less of it."""
    what = getattr(args, "result", None) or getattr(args, "input", None)
    fix = _MEMORY_OPTIONS.get(command)
    return (f"out of memory{f' on {what}' if what else ''}. "
            + (f"Try {fix}, or smaller data." if fix else "Try smaller data."))


def _interrupted_line(command: str, signum: int, before: int) -> str:
    from .._utils import atomic as _atomic

    written = _atomic.written_paths()[before:]
    what = ("wrote " + ", ".join(map(str, written))) if written else "nothing was written"
    import signal

    name = "" if signum == signal.SIGINT else f" by {signal.Signals(signum).name}"
    return f"ipfit {command}: interrupted{name}; {what}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; the single place where failures become one line and an exit code.

    Exit codes: 0 success; 2 a caller error (bad file, option, output path; an OS error
    while reading or writing, named with its path; out of memory); 130 after SIGINT, 143
    after SIGTERM (finished work written, see ``fit``); 1 an unexpected exception, with
    its traceback, which is a bug. NumPy's floating-point ``RuntimeWarning`` never
    reaches the terminal; other warnings print as one line.
    """
    try:
        return _main(argv)
    except KeyboardInterrupt:  # before the boundary below is in place (still importing)
        print("ipfit: interrupted; nothing was written", file=sys.stderr)
        return 130


def _main(argv: Sequence[str] | None) -> int:
    import signal

    from .._utils import atomic as _atomic
    from ._common import handle_signals, received_signal

    args_list = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in args_list if a in SUBCOMMANDS), "")
    label = command or "ipfit"
    before = len(_atomic.written_paths())
    with handle_signals(f"ipfit {command}".strip()), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.simplefilter("default", IpfitWarning)
        warnings.showwarning = _warning_line(label)
        args = None
        try:
            parser = build_parser(command)
            args, extra = parser.parse_known_args(argv)
            if not getattr(args, "command", None):
                if extra:
                    parser.error(f"unrecognized arguments: {' '.join(extra)}")
                parser.print_help()
                return 2
            command = label = args.command
            if extra:  # argparse would name the top-level parser, not the command
                print(f"ipfit {label}: error: unrecognized arguments: {' '.join(extra)} "
                      f"(see 'ipfit {label} --help')", file=sys.stderr)
                return 2
            code = int(args._run(args) or 0)
            signum = received_signal()
            return 128 + signum if signum and code in (0, 130) else code
        except IpfitError as exc:
            print(f"ipfit {label}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:
            signum = getattr(exc, "signum", None) or received_signal() or signal.SIGINT
            if sys.stderr.isatty():
                print(file=sys.stderr)  # end a progress line
            print(_interrupted_line(label, signum, before), file=sys.stderr)
            return 128 + signum
        except BrokenPipeError:
            # stdout closed early (`ipfit datasets | head`): not an error; keep Python quiet at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
        except OSError as exc:
            print(f"ipfit {label}: error: {_os_error_line(exc)}", file=sys.stderr)
            return 2
        except ModuleNotFoundError as exc:
            from .._utils.optional import missing

            error = missing(exc, f"ipfit {label}")
            if error is None:
                raise
            print(f"ipfit {label}: error: {error}", file=sys.stderr)
            return 2
        except MemoryError:
            print(f"ipfit {label}: error: {_memory_line(command, args)}", file=sys.stderr)
            return 2
        finally:
            _atomic.discard_temporaries()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

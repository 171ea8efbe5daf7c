"""``ltd-brake``: the command-line tool; one module per verb (simulate, validate, ...).

Every verb prints a helpful error and exits non-zero on bad input, never a traceback: the verbs
raise :class:`~ltd_brake_ros.inputs.InputError` (a bad recording:
:class:`~ltd_brake_ros.recording.reader.BagError`, one of them) and :func:`main` is the one place
that turns it, or an output that cannot be written (:class:`OSError`), into a line on stderr.
"""
from __future__ import annotations

import argparse
import functools
import gc
import importlib
import os
import signal
import sys
import threading

from .options import CONVENTIONS

#: The verbs in the order ``ltd-brake --help`` lists them, each the module of its name.
VERBS = ("simulate", "validate", "calibrate", "report", "recover", "campaign")
#: Allocations between two young-generation collections of the program (Python's default 700).
GC_THRESHOLD = 50_000


def build_parser(verb: str | None = None) -> argparse.ArgumentParser:
    """The ``ltd-brake`` argument parser.

    Parameters
    ----------
    verb : str, optional
        Build only this verb's options (all a command line naming it can use); default, or a
        name that is not a verb: every verb, as ``ltd-brake --help`` lists them.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
        prog="ltd-brake",
        description="Freight-train emergency braking: longitudinal train dynamics with the "
                    "empirical UIC braked-weight air-brake model (Bosso, Magelli, Zampieri et al.).",
        epilog=CONVENTIONS, formatter_class=argparse.RawDescriptionHelpFormatter)
    from .._version import __version__

    parser.add_argument("--version", action="version", version=f"ltd-brake {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    if verb in VERBS:
        modules = [importlib.import_module(f".{verb}", __package__)]
    else:
        from . import calibrate, campaign, recover, report, simulate, validate  # noqa: F401

        modules = [sys.modules[f"{__package__}.{name}"] for name in VERBS]
    for module in modules:
        module.add_parser(sub)
    return parser


@functools.lru_cache(maxsize=None)
def _parser(verb: str | None) -> argparse.ArgumentParser:
    """:func:`build_parser`, once per process and verb: building one costs more than parsing
    with it (argparse looks up message translations and the terminal for every option), and
    parsing leaves it unchanged."""
    return build_parser(verb)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ltd-brake``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 success, 1 a verdict or comparison found worse (FAIL), 2 bad input or
        an output that cannot be written, 3 simulation failure, 4 a comparison inconclusive
        (``campaign report --against``), 130 interrupted, 143 terminated (SIGTERM), 141 the
        output was closed early (as a shell reports a writer ended by SIGPIPE).

    Notes
    -----
    Started as the program (``argv`` None), the process collects cyclic garbage rarely
    (:data:`GC_THRESHOLD`) and not at exit: numba's registries are about 10^5 objects that
    every full collection traverses, while importing and again in the interpreter's teardown
    (0.1-0.5 s of a warm ``simulate`` command of about one second). Outputs are closed by the
    verbs, never left to a collection.
    """
    program = argv is None
    argv = sys.argv[1:] if argv is None else argv
    if program:
        gc.set_threshold(GC_THRESHOLD, *gc.get_threshold()[1:])
    try:
        return _main(argv)
    finally:
        if program:
            gc.freeze()  # the teardown frees by reference count, without traversing them


def _main(argv: list[str]) -> int:
    # a command line starting with a verb builds that verb alone: the others' options (and the
    # modules their help names) cost start-up time and cannot appear on it
    parser = _parser(argv[0] if argv and argv[0] in VERBS else None)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    # after parsing: --help and usage errors need neither the inputs nor the physics
    from ..inputs import InputError
    from ..simulator import SimulationError

    previous = _terminate_as_interrupt()
    try:
        status = args.func(args)
        sys.stdout.flush()  # an output that cannot be written is reported here, not at exit
        return status
    except Terminated:
        print(f"ltd-brake {args.command}: terminated", file=sys.stderr)
        return 143
    except InputError as exc:
        print(f"ltd-brake {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"ltd-brake {args.command}: simulation failed: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"ltd-brake {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`ltd-brake ... | head`): nothing more to say, and nothing to
        # flush at exit either
        _discard_stdout()
        return 141
    except OSError as exc:
        # an output that cannot be written: a full disk, a read-only folder, ...
        if exc.filename:
            what = f"cannot write {exc.filename}: {exc.strerror}"
        else:
            what = f"cannot write the output: {exc.strerror or exc}"
        print(f"ltd-brake {args.command}: error: {what}", file=sys.stderr)
        try:
            sys.stdout.flush()
        except OSError:
            _discard_stdout()
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like Ctrl-C, so workers and partial outputs are cleaned up."""


def _terminate_as_interrupt():
    """Turn SIGTERM into :class:`Terminated` in the main thread; the previous handler."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum, frame):
        raise Terminated()

    return signal.signal(signal.SIGTERM, handler)


def _discard_stdout() -> None:
    """Point standard output at the null device: what is left in its buffer goes nowhere."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


if __name__ == "__main__":
    sys.exit(main())

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
        status = _check_streams(argv[0] if argv and argv[0] in VERBS else None)
        if status is not None:
            return status
    try:
        status = _main(argv)
        if program and status == 0 and _unread_when_reader_left():
            return _closed_early()
        return status
    finally:
        if program:
            gc.freeze()  # the teardown frees by reference count, without traversing them


def _main(argv: list[str]) -> int:
    try:
        # a command line starting with a verb builds that verb alone: the others' options (and
        # the modules their help names) cost start-up time and cannot appear on it
        parser = _parser(argv[0] if argv and argv[0] in VERBS else None)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
    except BrokenPipeError:  # help or usage to a reader that went away
        return _closed_early()
    # after parsing: --help and usage errors need neither the inputs nor the physics
    from ..inputs import InputError
    from ..simulator import SimulationError

    previous = _terminate_as_interrupt()
    verb = f"ltd-brake {args.command}"
    try:
        status = args.func(args)
        sys.stdout.flush()  # an output that cannot be written is reported here, not at exit
        return status
    except Terminated:
        _say(f"{verb}: terminated")
        return 143
    except InputError as exc:
        _say(f"{verb}: error: {exc}")
        return 2
    except SimulationError as exc:
        _say(f"{verb}: simulation failed: {exc}")
        return 3
    except KeyboardInterrupt:
        _say(f"{verb}: interrupted")
        return 130
    except BrokenPipeError:
        # the reader of standard output or error went away (`ltd-brake ... | head`): nothing
        # more to say, and nothing to flush at exit either
        return _closed_early()
    except OSError as exc:
        # an output that cannot be written: a full disk, a read-only folder, ...
        if exc.filename:
            what = f"cannot write {exc.filename}: {exc.strerror}"
        else:
            what = f"cannot write the output: {exc.strerror or exc}"
        _say(f"{verb}: error: {what}")
        _flush_or_discard(sys.stdout)
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _say(line: str) -> None:
    """One line on standard error; a standard error that cannot take it is left alone (the
    exit status says what happened), and the line never goes to standard output."""
    stream = sys.stderr
    if stream is None:
        return
    try:
        print(line, file=stream, flush=True)
    except (OSError, ValueError):
        _flush_or_discard(stream)


def _closed_early() -> int:
    """After a broken pipe: what is still buffered for a reader that is gone goes nowhere
    (not into a message at exit); the exit status a shell gives a writer ended by SIGPIPE."""
    _flush_or_discard(sys.stdout)
    _flush_or_discard(sys.stderr)
    return 141


def _flush_or_discard(stream) -> None:
    """Flush ``stream``; if it cannot be written, point its descriptor at the null device so
    that nothing is left to fail at exit (a stream without a descriptor is left as it is)."""
    if stream is None:
        return
    try:
        stream.flush()
    except (OSError, ValueError):
        try:
            _null_on(stream.fileno())
        except (OSError, ValueError, AttributeError):
            pass


def _null_on(fd: int) -> None:
    """Open the null device on descriptor ``fd``."""
    null = os.open(os.devnull, os.O_RDWR)
    if null != fd:
        os.dup2(null, fd)
        os.close(null)


def _check_streams(verb: str | None) -> int | None:
    """Before the command runs: its standard output and error must be open and, if they are
    pipes or sockets, still have a reader.

    A closed descriptor 0, 1 or 2 is given the null device first, so that no file the
    command opens takes its number (and with it the command's messages or another
    output's bytes). Returns the exit status when the command cannot run (2: a stream is
    closed, with one line on standard error; 141: its reader is gone, said by the status
    alone as for a writer ended by SIGPIPE), None when it can. A closed or broken standard
    error leaves nothing to say the reason on; standard output is never written to instead.
    """
    closed = set()
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            closed.add(fd)
            _null_on(fd)
    gone = {fd for fd in (1, 2) if fd not in closed and _reader_gone(fd)}
    if 2 in closed or 2 in gone:
        return 2 if 2 in closed else 141
    name = f"ltd-brake {verb}" if verb else "ltd-brake"
    if 1 in closed:
        _say(f"{name}: error: standard output is closed: nothing the command prints could be "
             "read")
        return 2
    if 1 in gone:  # as a writer ended by SIGPIPE: nothing to say
        return 141
    return None


#: Longest wait at exit for the reader of a standard output pipe to take what is in it [s].
READER_WAIT_S = 0.2


def _unread_when_reader_left(fd: int = 1) -> bool:
    """Whether the reader of a pipe ``fd`` leaves (or has left) output unread: the command's
    output did not all arrive (``ltd-brake ... | head -c 10``), although every write fitted in
    the pipe.

    Waits at most :data:`READER_WAIT_S` while the pipe holds output and its reader is still
    there (a slow reader past that counts as reading it all).
    """
    import select
    import stat
    import time

    try:
        import fcntl
        import struct
        import termios

        if not stat.S_ISFIFO(os.fstat(fd).st_mode) or not hasattr(select, "poll"):
            return False
        poll = select.poll()
        poll.register(fd, 0)  # wakes only when the reader closes its end
        deadline = time.monotonic() + READER_WAIT_S
        while True:
            unread = struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0" * 4))[0]
            if unread == 0:
                return False
            left = deadline - time.monotonic()
            gone = any(ev & (select.POLLERR | select.POLLHUP) for _, ev in
                       poll.poll(max(0, min(10, int(left * 1e3)))))
            if gone:
                return True
            if left <= 0:
                return False
    except (OSError, ImportError, AttributeError):
        return False


def _reader_gone(fd: int) -> bool:
    """A pipe or socket ``fd`` whose reading end is closed (poll says so without blocking)."""
    import select
    import stat

    try:
        mode = os.fstat(fd).st_mode
        if not (stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode)) or not hasattr(select, "poll"):
            return False
        poll = select.poll()
        poll.register(fd, select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    except OSError:
        return False


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like Ctrl-C, so workers and partial outputs are cleaned up."""


def _terminate_as_interrupt():
    """Turn SIGTERM into :class:`Terminated` in the main thread; the previous handler."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum, frame):
        raise Terminated()

    return signal.signal(signal.SIGTERM, handler)



if __name__ == "__main__":
    sys.exit(main())

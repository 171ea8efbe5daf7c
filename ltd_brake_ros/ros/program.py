"""What every node program does around its node: signals, arguments and one-line errors.

:func:`run` is the body of ``sim_node`` and ``replay_node``:

* SIGINT and SIGTERM end the program cleanly at any moment. While its modules load (see
  :func:`install_if_program`) and its node starts, the first one ends it with one line and
  nothing left behind; once the node runs, the spin loop ends and the node is closed (a
  recording is finished); while it closes, a further signal is only logged, so that it cannot
  cut the recording short. SIGKILL still ends the process at once.
* Arguments are checked before anything starts: a ``--params-file`` that cannot be read, an
  argument outside ``--ros-args`` (``sim_node -p record:=true`` sets nothing) and a parameter the
  node does not declare (``-p recrod:=true``: nothing would be recorded) are refused, naming
  the closest parameters the node has.
* An error a user can act on (a parameter, an input file, a recording) is one line and exit
  status 1, never a traceback.

Only the standard library is imported at module level: a program installs its signal handling
before it loads rclpy.
"""
from __future__ import annotations

import difflib
import os
import re
import signal
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterable, Iterator, Protocol

__all__ = ["Interrupted", "Signals", "install_if_program", "unknown_parameters", "run",
           "threaded_executor"]

#: Wall time the spin loop waits for work before checking for a signal or the node's end [s].
SPIN_PERIOD_S = 0.2
#: rcl's source locations in its error messages (``, at /project/src/rcl/arguments.c:415``).
_RCL_WHERE = re.compile(r", at \S+:\d+")


def _caused_by_interrupt(exc: BaseException):
    """The :class:`Interrupted` in ``exc``'s chain of causes, or None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, Interrupted):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM while the node starts (nothing to finish yet).

    Parameters
    ----------
    signum : int
    """

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


class Signals:
    """SIGINT/SIGTERM handling of a node program.

    The first signal is remembered (:attr:`received`); inside :meth:`interruptible` it also
    raises :class:`Interrupted`. Any further signal is only logged.

    Parameters
    ----------
    name : str
        The program (logger name).
    """

    def __init__(self, name: str):
        self.name = name
        #: The first signal received (None before).
        self.received: int | None = None
        self._raising = False

    def install(self) -> "Signals":
        """Handle SIGINT and SIGTERM from now on (only possible on the main thread)."""
        try:
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, self._handle)
        except ValueError:  # not the main thread: the embedding program handles signals
            return self
        previous = sys.unraisablehook

        def unraisable(info) -> None:
            # an Interrupted raised while C code had called back into Python (numba's
            # compiler does) cannot leave the callback: Python would print it as "Exception
            # ignored"; the signal stays remembered and interruptible() raises it again
            if isinstance(info.exc_type, type) and issubclass(info.exc_type, Interrupted):
                return
            # an object whose construction the signal interrupted (llvmlite's, while the
            # kernel loads) can fail in its finalizer when the stopping program collects it
            if self.received is not None and getattr(info.object, "__name__", "") == "__del__":
                return
            previous(info)

        sys.unraisablehook = unraisable
        return self

    @contextmanager
    def interruptible(self) -> Iterator[None]:
        """Within the block the first signal raises :class:`Interrupted` at once.

        For start-up, where nothing needs finishing yet and a slow step (compiling the kernel)
        must not delay the exit. A signal whose exception was lost in a C callback is raised
        when the block ends.
        """
        if self.received is not None:
            raise Interrupted(self.received)
        self._raising = True
        try:
            yield
        finally:
            self._raising = False
        if self.received is not None:
            raise Interrupted(self.received)

    def _handle(self, signum, _frame) -> None:
        if self.received is None:
            self.received = signum
            if self._raising:
                self._raising = False
                raise Interrupted(signum)
            return
        _log(self.name, "warning", f"{signal.Signals(signum).name} ignored: shutting down, "
                                   "finishing what is open (SIGKILL aborts)")


def install_if_program(name: str) -> Signals | None:
    """Handle SIGINT/SIGTERM from now on if this process runs the program ``name``.

    Called by a program's module before its heavy imports, so that a signal while they load
    (a second or two) ends the program with one line instead of a traceback. The program is
    recognised by its first argument (the console script, ``ros2 run``'s executable, or the
    module run with ``python -m``); a process that only imports the module keeps its own
    handling.

    Parameters
    ----------
    name : str
        Program name (``sim_node``).

    Returns
    -------
    Signals or None
        The installed handling, or None when this process is another program.
    """
    if not sys.argv or Path(sys.argv[0]).stem != name:
        return None
    return Signals(name).install()


def _log(name: str, level: str, text: str) -> None:
    """Log ``text`` through rclpy's logging, or stderr when that is not available."""
    try:
        import rclpy.logging

        getattr(rclpy.logging.get_logger(name), level)(text)
    except Exception:  # noqa: BLE001 - rclpy not loaded yet, or shut down: never fail here
        print(f"[{level.upper()}] [{name}]: {text}", file=sys.stderr, flush=True)


def _rcl_reason(exc: BaseException) -> str:
    """rcl's error message in one line, without its source locations."""
    text = _RCL_WHERE.sub("", " ".join(str(exc).split()))
    for prefix in ("failed to initialize rcl: ", "Failed to parse ROS arguments: "):
        text = text.removeprefix(prefix)
    return text


def _split_arguments(argv: list[str]) -> tuple[list[str], list[str]]:
    """The arguments outside ``--ros-args ... [--]`` sections (after the program name), and the
    ``--params-file`` files inside them; read the way rcl reads a command line."""
    rest, files, inside = [], [], False
    for k, arg in enumerate(argv[1:], start=1):
        if arg == "--ros-args":
            inside = True
        elif inside and arg == "--":
            inside = False
        elif not inside:
            rest.append(arg)
        elif arg == "--params-file" and k + 1 < len(argv):
            files.append(argv[k + 1])
    return rest, files


def _argument_problem(argv: list[str], positional: Iterable[str], usage: str) -> str | None:
    """Why ``argv`` cannot start the program, or None (checked before rcl reads it)."""
    rest, files = _split_arguments(argv)
    for path in files:
        if not os.path.isfile(path):
            return f"--params-file {path}: no such file"
        if not os.access(path, os.R_OK):
            return f"--params-file {path}: not readable"
    allowed = list(positional)
    if len(rest) > len(allowed):
        return f"unexpected argument {rest[len(allowed)]!r}; usage: {usage}"
    return None


def unknown_parameters(node, known: Iterable[str]) -> tuple[str, str] | None:
    """The first parameter given to ``node`` that it does not have, and why; else None.

    rclpy ignores a value given for a parameter the node never declares, so a typo would go
    unnoticed: ``-p recrod:=true`` records nothing and the node exits 0.

    Parameters
    ----------
    node : rclpy.node.Node
        After its parameters are declared.
    known : iterable of str
        The node's own parameter names (offered as corrections).

    Returns
    -------
    tuple of str or None
        ``("recrod", "sim_node has no such parameter (did you mean record?)")``.
    """
    # rclpy keeps the values from the command line and parameter files here (no public
    # accessor in Jazzy); rclpy's own parameters (use_sim_time, ...) are declared by then
    given = getattr(node, "_parameter_overrides", {})
    known = list(known)
    for name in given:
        if not node.has_parameter(name):
            close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
            hint = f"did you mean {' or '.join(close)}?" if close else \
                f"it has {', '.join(known)}"
            return name, f"{node.get_name()} has no such parameter ({hint})"
    return None


class NodeProgram(Protocol):
    """What :func:`run` needs of a node."""

    exit_status: int

    def start(self) -> None: ...
    def running(self) -> bool: ...
    def close(self) -> None: ...


#: Longest wait for a pool thread to start the callback just handed to it [s].
START_WAIT_S = 0.2


def threaded_executor(threads: int, context=None):
    """A multi-threaded rclpy executor that waits for each callback to start before it looks
    for the next one.

    rclpy's ``MultiThreadedExecutor`` hands a ready callback to its thread pool and offers the
    same callback again until a pool thread has started it: while the threads wait for the
    interpreter lock it loops thousands of times a second, holding that lock, and a lock-step
    step then took about 30 ms instead of 3 ms. Here the spinning thread waits (at most
    :data:`START_WAIT_S`) until the callback has started.

    Parameters
    ----------
    threads : int
        Threads of the pool.
    context : rclpy.context.Context, optional
        Default: rclpy's default context.

    Returns
    -------
    rclpy.executors.MultiThreadedExecutor
    """
    import threading

    from rclpy.executors import (ConditionReachedException, ExternalShutdownException,
                                 MultiThreadedExecutor, ShutdownException, TimeoutException)

    class _Executor(MultiThreadedExecutor):
        def _spin_once_impl(self, timeout_sec=None, wait_condition=lambda: False):
            try:
                handler, _entity, _node = self.wait_for_ready_callbacks(
                    timeout_sec, None, wait_condition)
            except (ExternalShutdownException, ShutdownException, TimeoutException,
                    ConditionReachedException):
                return
            started = threading.Event()

            def call():
                started.set()
                handler()

            self._futures.append(self._executor.submit(call))
            started.wait(START_WAIT_S)
            for future in self._futures[:]:
                if future.done():
                    self._futures.remove(future)
                    future.result()  # a callback's exception ends the spin, as rclpy's does

    return _Executor(num_threads=threads, context=context)


def run(name: str, args: list[str] | None, make_node: Callable[[list[str]], NodeProgram], *,
        usage: str, signals: Signals | None = None, positional: Iterable[str] = (),
        errors: tuple[type[BaseException], ...] = (), threads: int = 1) -> int:
    """Run a node program from its command line to its exit (see the module docstring).

    Parameters
    ----------
    name : str
        Program and logger name.
    args : list of str or None
        Command line (default ``sys.argv``).
    make_node : callable
        ``make_node(positional_arguments)`` -> the node, not yet started; may raise one of
        ``errors`` (or :class:`~ltd_brake_ros.inputs.InputError`) for one line.
    usage : str
        One line: how to call the program.
    signals : Signals, optional
        Installed while the program's modules loaded (:func:`install_if_program`).
    positional : iterable of str
        Names of the arguments allowed outside ``--ros-args``.
    errors : tuple of exception types
        Errors reported as one line (besides input errors and rcl's argument errors).
    threads : int, optional
        Executor threads: more than 1 lets callbacks of different callback groups run while
        one waits (a multi-threaded executor).

    Returns
    -------
    int
        0 after a clean end (a signal included), 1 when the node cannot start or failed.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from ..inputs import InputError

    argv = list(sys.argv if args is None else args)
    signals = signals or Signals(name).install()
    log = rclpy.logging.get_logger(name)
    problem = _argument_problem(argv, positional, usage)
    if problem:
        log.fatal(f"cannot start: {problem}")
        return 1
    node = None
    try:
        with signals.interruptible():
            rcl = rclpy.logging.get_logger("rcl")
            level = rcl.get_effective_level()
            rcl.set_level(rclpy.logging.LoggingSeverity.FATAL)  # its own line besides ours
            try:
                # rclpy's own handlers would shut the context down under the running node
                rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
            except RuntimeError as exc:  # rcl's: a parameter file or rule it rejects
                log.fatal(f"cannot start: {_rcl_reason(exc)}")
                return 1
            finally:
                rcl.set_level(level)
            node = make_node(_split_arguments(argv)[0])
        node.start()
        executor = SingleThreadedExecutor() if threads <= 1 else threaded_executor(threads)
        executor.add_node(node)
        while rclpy.ok() and signals.received is None and node.running():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
        return node.exit_status
    except Interrupted as exc:
        log.info(f"{exc} while starting: stopped")
        return 0
    except (InputError, *errors) as exc:
        log.fatal(f"cannot start: {exc}")
        return 1
    except ExternalShutdownException:
        return 0
    except Exception as exc:
        # the signal's Interrupted wrapped by Python on its way out (raised inside a class
        # body's __set_name__, say, while an import loads): still the signal, not a failure
        if not _caused_by_interrupt(exc):
            raise
        log.info(f"{_caused_by_interrupt(exc)} while starting: stopped")
        return 0
    finally:
        if node is not None:
            node.close()
        rclpy.try_shutdown()

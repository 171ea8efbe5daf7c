"""The first run of a train whose simulation kernels are not compiled yet.

numba compiles the step loop on its first call: 15-45 s, once per installation, machine, brake
model and whether local time stepping is compiled in (then it loads it from its disk cache in a
fraction of a second). Every compile is announced with its estimated duration
(:func:`~ltd_brake_ros.compiled.compile_notice`) and its measured duration is kept for the
next announcement (:func:`~ltd_brake_ros.user_files.record_compile`). A
first run of ``ltd-brake simulate`` or of the Python API does not wait for that: a background
process compiles the kernels for the same train while the run starts at once with the kernels
as plain Python (:func:`~ltd_brake_ros.physics.equations.plain`: the same arithmetic, so the
same results, a few hundred times slower), and the run goes on compiled from the first chunk
after they are ready. A short run (an emergency stop of a few dozen wagons) ends before; the
background process finishes the compile all the same, so the next run loads it.

One background compile runs at a time for a numba cache: it holds a lock file
(:func:`lock_path`) from before it starts until it has written the cache, and a run that
finds it held waits for that one instead of starting another. The lock, the compile's log and
its inputs live in the user's private folder (:func:`~ltd_brake_ros.user_files.private_folder`),
never under fixed names in a shared temporary folder; where that folder is not private the run
says so in one line and compiles in the foreground.

``LTD_BRAKE_FIRST_RUN=wait`` compiles in the foreground instead (before the run, as a process
that runs many trains wants it; the test suite does).
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .user_files import UnsafeFolder, private_folder, record_compile

#: Environment variable choosing how a first run compiles: ``background`` (the default) or
#: ``wait``.
MODE_ENV = "LTD_BRAKE_FIRST_RUN"
#: Seconds between two looks at the lock while the background compile runs.
POLL_S = 0.25
#: Seconds after which a background compile gives up (SIGALRM ends it; about 15 s is usual).
COMPILE_LIMIT_S = 900

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no flock, the first run compiles in place
    fcntl = None


def lock_path(numba_cache_dir: str | None = None) -> Path:
    """The lock file of background compiles into this installation's numba cache.

    Parameters
    ----------
    numba_cache_dir : str, optional
        The cache's ``NUMBA_CACHE_DIR`` (default: this process's, "" when unset).

    Returns
    -------
    Path
        In the user's private folder, named after the package's folder and the cache.

    Raises
    ------
    UnsafeFolder
        The private folder cannot be used.
    """
    if numba_cache_dir is None:
        numba_cache_dir = os.environ.get("NUMBA_CACHE_DIR", "")
    key = f"{Path(__file__).resolve().parent}\0{numba_cache_dir}"
    digest = hashlib.sha256(key.encode()).hexdigest()[:16]
    return private_folder() / f"compile-{digest}.lock"


class Background:
    """A background compile, as :func:`~ltd_brake_ros.physics.equations.run_plain_while`
    asks it: true while it runs (looked at every :data:`POLL_S` at most).

    Parameters
    ----------
    process : subprocess.Popen or None
        The compiling process this run started (None: another run's, found running).
    say : callable
        Where to say that the compile failed (one line).
    inputs : str, optional
        The file of pickled inputs given to ``process`` (removed if it is left behind).
    lock : Path, optional
        The compile's lock (default: :func:`lock_path`).
    """

    def __init__(self, process: subprocess.Popen | None, say, inputs: str | None = None,
                 lock: Path | None = None):
        self.process, self._say, self._inputs = process, say, inputs
        self._lock = lock if lock is not None else lock_path()
        self._next = 0.0
        self.running = True

    def __call__(self) -> bool:
        now = time.monotonic()
        if not self.running or now < self._next:
            return self.running
        self._next = now + POLL_S
        self.running = _held(self._lock)
        if not self.running and self.process is not None:
            code = self.process.wait()
            if self._inputs is not None and os.path.exists(self._inputs):
                os.unlink(self._inputs)  # a process that failed before reading them
            if code != 0:
                self._say(f"the background compile failed (exit status {code}, its messages "
                          f"in {self._lock.with_suffix('.log')}): compiling here")
        return self.running


def _open_private(path: Path) -> int:
    """A descriptor of the file ``path`` of the private folder, open for reading and writing
    (created; no symbolic link followed)."""
    return os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o600)


def _held(path: Path) -> bool:
    """Whether a process holds the lock ``path`` (without keeping it)."""
    try:
        fd = _open_private(path)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing it releases a lock taken here
    return False


def wait_for_compile(numba_cache_dir: str | None = None, timeout_s: float | None = None
                     ) -> bool:
    """Wait until no background compile into a numba cache runs.

    Parameters
    ----------
    numba_cache_dir : str, optional
        As for :func:`lock_path`.
    timeout_s : float, optional
        Give up after this long [s] (default: wait as long as it takes).

    Returns
    -------
    bool
        False: still running after ``timeout_s``.
    """
    try:
        path = lock_path(numba_cache_dir)
    except UnsafeFolder:
        return True  # no background compile can run without the folder
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    while _held(path):
        if deadline is not None and time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def start(simulator_kwargs: dict, say) -> Background | None:
    """Compile a train's kernels in a background process and run them as plain Python in this
    one until they are ready.

    Call it only when the kernels are not in the cache
    (:func:`~ltd_brake_ros.compiled.compile_notice`).

    Parameters
    ----------
    simulator_kwargs : dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` for the run's train (picklable
        inputs); the background process warms such a simulator up.
    say : callable
        Called with one line if the background compile fails (this process then compiles).

    Returns
    -------
    Background or None
        None: nothing started (``LTD_BRAKE_FIRST_RUN=wait``, no file locks on this system, or
        no private folder, which ``say`` is told): compile in the foreground.
    """
    from .physics.equations import HAVE_NUMBA, run_plain_while

    if os.environ.get(MODE_ENV, "background") == "wait" or fcntl is None or not HAVE_NUMBA:
        return None
    try:
        path = lock_path()
        fd = _open_private(path)
    except UnsafeFolder as exc:
        say(f"{exc}: compiling in the foreground")
        return None
    except OSError:
        return None
    process = inputs = None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # another run's compile is under way: wait for that one
            pass
        else:  # the child inherits the lock with the descriptor and holds it until it ends
            with tempfile.NamedTemporaryFile("wb", suffix=".pickle", prefix="inputs-",
                                             dir=path.parent, delete=False) as inputs:
                try:
                    pickle.dump(simulator_kwargs, inputs)
                except (pickle.PicklingError, TypeError, AttributeError):
                    os.unlink(inputs.name)
                    return None
            inputs = inputs.name
            try:
                log_fd = _open_private(path.with_suffix(".log"))
                os.ftruncate(log_fd, 0)
                with os.fdopen(log_fd, "wb") as log:
                    process = subprocess.Popen(
                        [sys.executable, "-m", "ltd_brake_ros.first_run", str(fd), inputs],
                        stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                        pass_fds=(fd,),
                        start_new_session=True)  # the compile outlives a run that ends first
            except OSError:
                os.unlink(inputs)
                raise
    except OSError:
        return None
    finally:
        os.close(fd)
    background = Background(process, say, inputs, path)
    _STARTED.append(background)
    run_plain_while(background)
    return background


def _kind_of(simulator_kwargs: dict) -> tuple:
    """``(consist, params, tolerance_m_s)`` of a simulator's arguments."""
    from .physics.kernel import DEFAULT_TOLERANCE_M_S

    return (simulator_kwargs["consist"], simulator_kwargs.get("params"),
            simulator_kwargs.get("tolerance_m_s", DEFAULT_TOLERANCE_M_S))


def begin(simulator_kwargs: dict, say) -> str | None:
    """Before a user's run: what to tell the user about compiling its kernels, the compile
    started in the background where it can be.

    Parameters
    ----------
    simulator_kwargs : dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` for the run's train
        (``consist`` and ``params`` at least).
    say : callable
        Called with one line if a background compile fails.

    Returns
    -------
    str or None
        One line with the compile's estimated duration; None when the kernels are cached (the
        run loads them).
    """
    from .compiled import compile_notice

    notice = compile_notice(*_kind_of(simulator_kwargs))
    if notice is None or start(simulator_kwargs, say) is None:
        return notice
    return compile_notice(*_kind_of(simulator_kwargs), background=True)


def prepare(simulator_kwargs: dict, say):
    """Before a user's run: load its kernels, or on a first run compile them (in the
    background while the run computes as plain Python, else here), announced with the
    compile's estimated duration and, when compiled here, its measured one.

    Parameters
    ----------
    simulator_kwargs : dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` for the run's train.
    say : callable
        Called with each line to show the user.

    Returns
    -------
    Simulator
        One of the run's train, its kernels loaded (or running as plain Python).
    """
    from .physics.equations import plain_now
    from .simulator import Simulator

    notice = begin(simulator_kwargs, say)
    if notice:
        say(notice)
    if notice and plain_now():
        return Simulator(**simulator_kwargs)
    with measured(simulator_kwargs, say, announce=False) if notice else \
            contextlib.nullcontext():
        sim = Simulator(**simulator_kwargs)  # it loads (or compiles) part of the kernels
        sim.warm_up()
    return sim


@contextlib.contextmanager
def measured(simulator_kwargs: dict, say, announce: bool = True):
    """Around code that compiles the kernels of a run here: announce it with its estimated
    duration if they are not cached, and afterwards say and keep how long it took.

    Parameters
    ----------
    simulator_kwargs : dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` for the run's train
        (``consist``, ``params`` and ``tolerance_m_s`` are read).
    say : callable
        Called with each line.
    announce : bool, optional
        Say the announcement here (False: the caller did).
    """
    from .compiled import compile_kind, compile_notice

    if announce:
        notice = compile_notice(*_kind_of(simulator_kwargs))
        if notice is None:
            yield
            return
        say(notice)
    started = time.monotonic()
    yield
    took = time.monotonic() - started
    record_compile(*compile_kind(*_kind_of(simulator_kwargs)), took)
    say(f"compiled the simulation kernels in {took:.0f} s; later runs load them")


def compile_here(runs, say) -> None:
    """Before a study's processes start: compile here, announced and measured, the kernels of
    every kind its runs need that are not cached, so that its workers load them.

    Parameters
    ----------
    runs : iterable of dict
        Arguments of :class:`~ltd_brake_ros.simulator.Simulator` for the study's trains
        (``consist`` and ``speed_kmh`` at least).
    say : callable
        Called with each line.
    """
    from .compiled import compile_kind
    from .simulator import Simulator

    seen = set()
    for kwargs in runs:
        kind = compile_kind(*_kind_of(kwargs))
        if kind in seen:
            continue
        seen.add(kind)
        with measured(kwargs, say):
            Simulator(**kwargs).warm_up()


#: Background compiles this process started (kept so that their processes are reaped).
_STARTED: list[Background] = []


def _compile(fd: int, inputs: str) -> int:
    """The background process: warm a simulator of the run's train up, then release the
    lock (by ending)."""
    try:
        with open(inputs, "rb") as f:
            kwargs = pickle.load(f)
    finally:
        os.unlink(inputs)
    os.set_inheritable(fd, False)
    if hasattr(signal, "alarm"):  # a compile that hangs must not hold the lock for ever
        signal.alarm(COMPILE_LIMIT_S)
    from .compiled import compile_kind
    from .simulator import Simulator

    started = time.monotonic()
    Simulator(**kwargs).warm_up()
    record_compile(*compile_kind(*_kind_of(kwargs)), time.monotonic() - started)
    return 0


if __name__ == "__main__":
    sys.exit(_compile(int(sys.argv[1]), sys.argv[2]))

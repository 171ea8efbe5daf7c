"""The user's private folder, and the compile times kept in it.

The first-run compile (:mod:`~ltd_brake_ros.first_run`) keeps its lock, its log and its
inputs here, and every compile of the simulation kernels records how long it took, so that the
next one is announced with that figure. The folder is ``$XDG_CACHE_HOME/ltd_brake_ros``
(``~/.cache/ltd_brake_ros`` when ``XDG_CACHE_HOME`` is unset or not an absolute path), created
with mode 0700. It is refused (:class:`UnsafeFolder`) when it is a symbolic link, belongs to
another user, may be written by others, or sits in a folder anyone may write without the
sticky bit (where another user could swap it): another user's files then change nothing,
and the package compiles in the foreground instead of using it.
"""
from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path

__all__ = ["FIRST_COMPILE_S", "UnsafeFolder", "compile_estimate", "private_folder",
           "record_compile"]

#: The folder's name under the user's cache folder.
FOLDER_NAME = "ltd_brake_ros"
#: The file of measured compile times in the private folder (JSON: kind -> seconds).
TIMES_FILE = "compile_times.json"
#: Largest compile-times file read [bytes]; a larger one is ignored.
TIMES_MAX_BYTES = 65536

#: Seconds a compile of each kind of kernels takes from an empty cache with a core to itself
#: (its CPU time, ``python benchmarks/bench_startup.py --kinds`` on a 2-core machine: 33 and
#: 101 vehicles, load average 3-6), by brake model and whether local time stepping is
#: compiled in (a train of 64 vehicles or more with error control). A busy machine's shared
#: caches make CPU time longer than an idle one's: an estimate errs long rather than short.
FIRST_COMPILE_S = {
    ("uic_empirical", False): 18.6, ("uic_empirical", True): 26.6,
    ("linear_ramp", False): 18.5, ("linear_ramp", True): 28.1,
    ("uic_brake_pipe", False): 21.9, ("uic_brake_pipe", True): 30.8,
}


class UnsafeFolder(OSError):
    """The private folder cannot be used safely; ``str()`` is one line naming it and why."""


def private_folder() -> Path:
    """The user's private folder, created (mode 0700) if it does not exist.

    Returns
    -------
    Path

    Raises
    ------
    UnsafeFolder
        It cannot be created, or it is not private (see the module's description).
    """
    base = os.environ.get("XDG_CACHE_HOME", "")
    try:
        base = Path(base) if os.path.isabs(base) else Path.home() / ".cache"
    except (RuntimeError, KeyError):  # no home folder to be found
        raise UnsafeFolder("no private folder: XDG_CACHE_HOME is not set and the home "
                           "folder is unknown") from None
    folder = base / FOLDER_NAME
    try:
        base.mkdir(parents=True, exist_ok=True, mode=0o700)
        os.mkdir(folder, 0o700)
    except FileExistsError:
        pass
    except OSError as exc:
        raise UnsafeFolder(f"cannot create {folder}: {exc.strerror or exc}") from None
    _check_private(folder)
    return folder


def _check_private(folder: Path) -> None:
    """Refuse ``folder`` unless only this user can change what is in it."""
    try:
        st = os.lstat(folder)
        parent = os.stat(folder.parent)
    except OSError as exc:
        raise UnsafeFolder(f"cannot use {folder}: {exc.strerror or exc}") from None
    why = None
    if stat.S_ISLNK(st.st_mode):
        why = "it is a symbolic link"
    elif not stat.S_ISDIR(st.st_mode):
        why = "it is not a folder"
    elif hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        why = f"it belongs to user id {st.st_uid}, not to this user ({os.geteuid()})"
    elif st.st_mode & 0o022:
        why = (f"others may write to it (mode {stat.S_IMODE(st.st_mode):03o}; "
               f"chmod 700 {folder} if it is yours)")
    elif parent.st_mode & 0o002 and not parent.st_mode & stat.S_ISVTX:
        why = f"anyone may write to {folder.parent}, which has no sticky bit"
    if why is not None:
        raise UnsafeFolder(f"not using {folder}: {why}")


def open_private(name: str, flags: int, mode: int = 0o600) -> int:
    """A descriptor of the file ``name`` in the private folder (no symbolic link followed).

    Parameters
    ----------
    name : str
        A plain file name.
    flags : int
        As for :func:`os.open`.
    mode : int, optional
        Permissions of a file it creates.

    Raises
    ------
    UnsafeFolder, OSError
    """
    return os.open(private_folder() / name, flags | getattr(os, "O_NOFOLLOW", 0), mode)


def _kind(brake_model: str, local_steps: bool) -> str:
    return f"{brake_model}{' local steps' if local_steps else ''}"


def _read_times() -> dict[str, float]:
    """The measured compile times (empty if none, or the file is unreadable)."""
    try:
        fd = open_private(TIMES_FILE, os.O_RDONLY)
    except OSError:
        return {}
    try:
        with os.fdopen(fd, "rb") as fh:
            text = fh.read(TIMES_MAX_BYTES + 1)
        data = json.loads(text) if len(text) <= TIMES_MAX_BYTES else {}
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {k: float(v) for k, v in data.items()
            if isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(v) and 0.0 < v < 86400.0}


def record_compile(brake_model: str, local_steps: bool, seconds: float) -> None:
    """Keep how long a compile of the kernels took, for the next announcement.

    Parameters
    ----------
    brake_model : str
    local_steps : bool
    seconds : float
        Its wall time [s].

    Notes
    -----
    The file is replaced atomically; a folder that is not private, or a failed write, keeps
    nothing (the next compile is estimated again).
    """
    from .outputs import write_replacing

    if not (math.isfinite(seconds) and 0.0 < seconds < 86400.0):
        return
    times = _read_times()
    times[_kind(brake_model, local_steps)] = round(float(seconds), 2)
    try:
        write_replacing(private_folder() / TIMES_FILE,
                        json.dumps(times, indent=1, sort_keys=True) + "\n")
    except OSError:
        pass


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the platform reports it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def compile_estimate(brake_model: str, local_steps: bool, beside_a_run: bool = False
                     ) -> tuple[float, str]:
    """How long a compile of the kernels will take, and how that was estimated.

    Parameters
    ----------
    brake_model : str
        The run's brake model.
    local_steps : bool
        Local time stepping is compiled in.
    beside_a_run : bool, optional
        The compile runs in the background while a run computes beside it (one more busy
        core).

    Returns
    -------
    seconds : float
    basis : str
        "as the last compile took", or the cores and load the first-compile figure of
        :data:`FIRST_COMPILE_S` was scaled for: the compile gets the share
        ``cores / (load + busy)`` of a core when fewer cores than work are free.
    """
    last = _read_times().get(_kind(brake_model, local_steps))
    if last is not None:
        return last, "as the last compile took"
    base = FIRST_COMPILE_S.get((brake_model, bool(local_steps)),
                               max(FIRST_COMPILE_S.values()))
    cores = usable_cores()
    try:
        load = max(0.0, os.getloadavg()[0])
    except (AttributeError, OSError):
        load = 0.0
    busy = 2 if beside_a_run else 1
    share = min(1.0, cores / (load + busy))
    return base / share, (f"estimated for {cores} core{'s' if cores != 1 else ''} at load "
                          f"{load:.1f}")

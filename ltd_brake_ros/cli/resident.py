"""A resident process that runs ``ltd-brake simulate`` commands with the kernels loaded.

Importing numba and loading the compiled kernels from its disk cache cost about 0.5 s per
process on two cores: several times what an emergency stop of a freight train takes. After a
``simulate`` command that paid it, ``ltd-brake`` starts this server in the background; later
``simulate`` commands hand their command line to it, and it runs each one in a process forked
from itself, with the kernels already in memory, attached to the command's own standard input,
output and error, working folder, environment and umask. The exit status passes back, Ctrl-C,
SIGTERM and SIGHUP pass on, and a command that goes away takes its forked process with it: a
command behaves as if it ran in its own process, only sooner.

Who may use it: the server listens on a Unix socket in a folder only its user can enter
(``$XDG_RUNTIME_DIR/ltd_brake_ros``, else ``<temporary folder>/ltd_brake_ros-<uid>``) and
answers only that user. The socket's name is a digest of what the loaded code depends on (the
package's files, the Python, the folders of installed packages and the ``NUMBA_*``,
``LTD_BRAKE_*`` and ``PYTHON*`` environment): a command whose code or settings differ finds
no server and runs in its own process. A server stops after :data:`IDLE_S` without a command
(``LTD_BRAKE_SERVER_IDLE_S``), on ``ltd-brake server stop``, and on SIGTERM.
``LTD_BRAKE_SERVER=off`` runs every command in its own process and starts no server.
"""
from __future__ import annotations

import json
import os
import signal
import socket
import struct
import sys
from pathlib import Path

#: Environment variable: ``auto`` (the default: use a server, start one after a command that
#: ran without) or ``off``.
MODE_ENV = "LTD_BRAKE_SERVER"
#: Environment variable: the folder of the servers' sockets (default, see the module's text).
DIR_ENV = "LTD_BRAKE_SERVER_DIR"
#: Environment variable: seconds a server waits for a command before it stops.
IDLE_ENV = "LTD_BRAKE_SERVER_IDLE_S"
#: Default of ``LTD_BRAKE_SERVER_IDLE_S`` [s].
IDLE_S = 600.0
#: The verbs a server runs (the others start few kernels or run long enough not to care).
SERVED = ("simulate",)
#: Seconds a command waits for a server to take its command line before running it itself.
CONNECT_S = 1.0
#: Seconds a command waits for a server to start the run it sent (then it gives up, exit 3).
START_S = 30.0
#: The signals a command passes on to its run in the server.
COMMAND_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: The command a server runs to load what a ``simulate`` command needs.
WARM_UP = ("simulate", "--scenario", "6")

#: Set in a server and in the processes it forks: they never hand a command on.
SERVING = False
#: In a command a server runs: the server's process id.
SERVED_BY: int | None = None

_LENGTH = struct.Struct("!I")


def enabled() -> bool:
    """Whether commands may use a server here (not ``off``, a Unix socket and fork exist)."""
    return (not SERVING and os.environ.get(MODE_ENV, "auto") != "off"
            and hasattr(socket, "AF_UNIX") and hasattr(os, "fork")
            and hasattr(socket, "send_fds") and sys.platform != "win32")


def folder() -> Path | None:
    """The folder of this user's server sockets, made if need be; None if it is not this
    user's alone (then no server is used)."""
    base = os.environ.get(DIR_ENV)
    if not base:
        runtime = os.environ.get("XDG_RUNTIME_DIR")
        if runtime and os.path.isdir(runtime):
            base = os.path.join(runtime, "ltd_brake_ros")
        else:
            import tempfile

            base = os.path.join(tempfile.gettempdir(), f"ltd_brake_ros-{os.getuid()}")
    try:
        os.mkdir(base, 0o700)
    except FileExistsError:
        pass
    except OSError:
        return None
    try:
        st = os.lstat(base)
    except OSError:
        return None
    import stat

    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        return None
    return Path(base)


def digest() -> str:
    """What the code a server loads depends on, as 16 hex digits."""
    import hashlib

    from .._version import __version__

    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(f"{__version__}\0{sys.executable}\0{sys.version}\0{package}\0".encode())
    for name in sorted(os.environ):
        if name.startswith(("NUMBA_", "LTD_BRAKE_", "PYTHON")) and name not in (
                MODE_ENV, DIR_ENV, IDLE_ENV):
            h.update(f"{name}={os.environ[name]}\0".encode())
    # a package installed, upgraded or removed changes its folder; the first entry is the
    # script's folder or the working one, which differ between a command and its server
    for entry in sys.path[1:]:
        try:
            h.update(f"{entry}\0{os.stat(entry or '.').st_mtime_ns}\0".encode())
        except OSError:
            pass
    for root, dirs, files in os.walk(package):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            path = os.path.join(root, name)
            try:
                st = os.stat(path)
            except OSError:
                continue
            h.update(f"{path}\0{st.st_mtime_ns}\0{st.st_size}\0".encode())
    return h.hexdigest()[:16]


def socket_path(key: str | None = None) -> Path | None:
    """This installation's server socket, or the one named ``key`` (None: no folder for it)."""
    base = folder()
    return None if base is None else base / f"{key or digest()}.sock"


def _send(sock: socket.socket, message: dict, fds: list[int] | None = None) -> None:
    data = json.dumps(message).encode()
    data = _LENGTH.pack(len(data)) + data
    if fds:
        sent = socket.send_fds(sock, [data], fds)
        data = data[sent:]
    sock.sendall(data)


def _receive(sock: socket.socket, max_fds: int = 0) -> tuple[dict | None, list[int]]:
    """One message (None at the end of the stream) and the descriptors that came with it."""
    buf, fds = b"", []
    while len(buf) < _LENGTH.size or len(buf) < _LENGTH.size + _LENGTH.unpack_from(buf)[0]:
        if max_fds and not fds:
            chunk, got, _, _ = socket.recv_fds(sock, 65536, max_fds)
            fds.extend(got)
        else:
            chunk = sock.recv(65536)
        if not chunk:
            for fd in fds:
                os.close(fd)
            return None, []
        buf += chunk
        if len(buf) >= _LENGTH.size and _LENGTH.unpack_from(buf)[0] > 16 * 2**20:
            raise ValueError("message too long")
    return json.loads(buf[_LENGTH.size:]), fds


# --- the command's side ------------------------------------------------------------------

def forward(argv: list[str]) -> int | None:
    """Run a command in this installation's server, if one answers.

    Parameters
    ----------
    argv : list of str
        The command line after ``ltd-brake``.

    Returns
    -------
    int or None
        The command's exit status; None: no server took it (run it here).
    """
    import threading

    if not argv or argv[0] not in SERVED or not enabled() \
            or threading.current_thread() is not threading.main_thread():
        return None
    try:
        path = socket_path()
        cwd = os.getcwd()
    except OSError:
        return None
    if path is None:
        return None
    umask = os.umask(0o022)
    os.umask(umask)
    message = {"kind": "run", "key": path.stem, "argv": list(argv), "argv0": sys.argv[0],
               "cwd": cwd, "env": dict(os.environ), "umask": umask,
               "nice": os.getpriority(os.PRIO_PROCESS, 0),
               "cpus": sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
               else None,
               "encodings": [_encoding(s) for s in (sys.stdin, sys.stdout, sys.stderr)]}
    pid, pending, interrupts = None, [], []

    def relay(signum, frame):
        if frame is not None and signum == signal.SIGINT:
            interrupts.append(signum)
            if len(interrupts) >= 3:  # the run does not end (a server stopped): give up
                raise KeyboardInterrupt
        if pid is None:
            pending.append(signum)
            return
        try:
            os.kill(pid, signum)
        except OSError:
            pass

    previous = {s: signal.signal(s, relay) for s in COMMAND_SIGNALS}
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        try:
            sock.settimeout(CONNECT_S)
            sock.connect(str(path))
            _send(sock, message, [0, 1, 2])
        except OSError:  # no server: nothing was run
            return 128 + pending[0] if pending else None
        # the command line is sent: from here on it is the server's, and never run twice
        try:
            sock.settimeout(START_S)
            reply, _ = _receive(sock)
        except (OSError, ValueError):
            print(f"ltd-brake {argv[0]}: error: the ltd-brake server did not start the run "
                  f"within {START_S:.0f} s; run it again, or with {MODE_ENV}=off",
                  file=sys.stderr)
            return 3
        if not reply or "pid" not in reply:  # refused, or gone before it forked: run it here
            return 128 + pending[0] if pending else None
        pid = int(reply["pid"])
        for signum in pending:
            relay(signum, None)
        try:
            sock.settimeout(None)
            reply, _ = _receive(sock)
        except (OSError, ValueError):
            reply = None
        if not reply or "exit" not in reply:
            print(f"ltd-brake {argv[0]}: error: the ltd-brake server stopped during the run "
                  f"(process {pid}); run it again, or with {MODE_ENV}=off", file=sys.stderr)
            return 3
        return int(reply["exit"])
    except KeyboardInterrupt:  # a third Ctrl-C
        print(f"ltd-brake {argv[0]}: interrupted (the run in the ltd-brake server did not end)",
              file=sys.stderr)
        return 130
    finally:
        sock.close()
        for s, handler in previous.items():
            signal.signal(s, handler)


def _encoding(stream) -> list[str] | None:
    if stream is None:
        return None
    return [getattr(stream, "encoding", None) or "utf-8",
            getattr(stream, "errors", None) or "strict"]


def spawn() -> None:
    """Start this installation's server in the background unless one runs, or the last one
    failed to start (its log says why; ``ltd-brake server start`` tries again)."""
    if not enabled():
        return
    try:
        path = socket_path()
        if path is None or path.with_suffix(".failed").exists() or _answers(path):
            return
        import subprocess

        with open(os.open(path.with_suffix(".log"), os.O_WRONLY | os.O_APPEND | os.O_CREAT,
                          0o600), "ab") as log:
            subprocess.Popen([sys.executable, "-m", "ltd_brake_ros.cli.resident_server", path.stem],
                             stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                             cwd=str(path.parent), start_new_session=True)
    except OSError:
        pass


def _answers(path: Path) -> bool:
    return _ask(path, {"kind": "status"}) is not None


def _ask(path: Path, message: dict, timeout_s: float = 5.0) -> dict | None:
    """A server's reply to a control message (None: nothing listens there)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.settimeout(timeout_s)
        sock.connect(str(path))
        _send(sock, message)
        reply, _ = _receive(sock)
        return reply
    except (OSError, ValueError):
        return None
    finally:
        sock.close()


def servers() -> list[tuple[Path, dict]]:
    """The servers of this user that answer, each with its status.

    Returns
    -------
    list of (Path, dict)
        Socket and status (``pid``, ``started`` [s since the epoch], ``served``, ``idle_s``,
        ``version``, ``key``); this installation's first.
    """
    base = folder()
    if base is None:
        return []
    found = []
    for path in sorted(base.glob("*.sock")):
        status = _ask(path, {"kind": "status"})
        if status is not None:
            found.append((path, status))
    mine = digest()
    return sorted(found, key=lambda f: f[0].stem != mine)


def stop(path: Path) -> bool:
    """Ask the server at ``path`` to stop (it finishes the commands it runs); False if none
    answered."""
    return _ask(path, {"kind": "stop"}) is not None

"""The resident server's side: it loads what a ``simulate`` command needs once, and runs each
command it is handed in a process forked from itself (:mod:`ltd_brake_ros.cli.resident`)."""
from __future__ import annotations

import os
import selectors
import signal
import socket
import struct
import sys
import time
from pathlib import Path

from . import resident
from .resident import COMMAND_SIGNALS, IDLE_ENV, IDLE_S, WARM_UP, _receive, _send


class _Server:
    """The listening socket, the forked commands and their connections, in one thread.

    Parameters
    ----------
    path : Path
        The socket to listen on (replaced if a dead server left it).
    idle_s : float
        Seconds without a command before :meth:`run` returns.
    lock : int
        The descriptor holding the server's lock (closed in the forked commands).
    """

    def __init__(self, path: Path, idle_s: float, lock: int):
        self.path, self.idle_s, self.key, self.lock = path, idle_s, path.stem, lock
        self.pid = os.getpid()
        # stopping: take no more commands; terminating (a signal): end the runs too
        self.started, self.served = time.time(), 0
        self.stopping = self.terminating = False
        self.children: dict[int, socket.socket | None] = {}
        self.selector = selectors.DefaultSelector()
        self.last = time.monotonic()
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            path.unlink()  # a server that ended without removing it (the lock says none runs)
        except FileNotFoundError:
            pass
        old = os.umask(0o177)
        try:
            self.listener.bind(str(path))
        finally:
            os.umask(old)
        self.listener.listen(16)
        self.inode = os.stat(path).st_ino
        self.wake_r, self.wake_w = os.pipe()
        os.set_blocking(self.wake_r, False)
        os.set_blocking(self.wake_w, False)
        signal.set_wakeup_fd(self.wake_w)
        signal.signal(signal.SIGCHLD, lambda *a: None)
        for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            signal.signal(s, self._on_stop)
        self.selector.register(self.listener, selectors.EVENT_READ, "accept")
        self.selector.register(self.wake_r, selectors.EVENT_READ, "wake")

    def _on_stop(self, signum, frame) -> None:
        self.stopping = self.terminating = True

    def run(self) -> None:
        terminated = False
        while True:
            self._reap()
            if self.stopping:
                self._close_listener()
            if self.terminating and not terminated:
                terminated = True
                for pid in self.children:
                    _kill(pid, signal.SIGTERM)
            if self.stopping and not self.children:
                break
            idle = time.monotonic() - self.last
            if not self.children and idle >= self.idle_s:
                break
            timeout = None if self.children else self.idle_s - idle
            for key, _ in self.selector.select(timeout):
                if key.data == "accept":
                    self._accept()
                elif key.data == "wake":
                    try:
                        while os.read(self.wake_r, 512):
                            pass
                    except BlockingIOError:
                        pass
                else:  # a command's connection: it went away (or spoke out of turn)
                    self._gone(key.fileobj, key.data)
        self._close_listener()

    def _close_listener(self) -> None:
        if self.listener.fileno() < 0:
            return
        self.selector.unregister(self.listener)
        self.listener.close()
        try:
            if os.stat(self.path).st_ino == self.inode:
                self.path.unlink()
        except OSError:
            pass

    def _accept(self) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        fds: list[int] = []
        try:
            conn.settimeout(5.0)
            creds = conn.getsockopt(socket.SOL_SOCKET, getattr(socket, "SO_PEERCRED", 17),
                                    struct.calcsize("3i"))
            if struct.unpack("3i", creds)[1] != os.getuid():
                conn.close()
                return
            message, fds = _receive(conn, max_fds=3)
            kind = (message or {}).get("kind")
            if kind == "status":
                from .._version import __version__

                _send(conn, {"pid": os.getpid(), "started": self.started, "served": self.served,
                             "running": len(self.children), "idle_s": self.idle_s,
                             "version": __version__, "key": self.key})
            elif kind == "stop":
                _send(conn, {"stopping": os.getpid()})
                self.stopping = True
            elif kind == "run" and message.get("key") == self.key and len(fds) == 3 \
                    and not self.stopping:
                self._run(conn, message, fds)
                return
            else:
                _send(conn, {"refused": "not this server's command"})
        except (OSError, ValueError, KeyError, TypeError):
            pass
        for fd in fds:
            os.close(fd)
        conn.close()

    def _run(self, conn: socket.socket, message: dict, fds: list[int]) -> None:
        # a signal for the command that comes before it has its own handlers waits for them
        # (with the server's, it would be lost)
        pid = -1
        signal.pthread_sigmask(signal.SIG_BLOCK, COMMAND_SIGNALS)
        try:
            pid = os.fork()
        finally:
            if pid != 0:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, COMMAND_SIGNALS)
        if pid == 0:  # pragma: no cover - the forked command; coverage cannot follow it
            _child(message, fds, server=self, conn=conn)
        for fd in fds:
            os.close(fd)
        self.served += 1
        self.children[pid] = conn
        try:
            _send(conn, {"pid": pid})
            conn.settimeout(None)
            self.selector.register(conn, selectors.EVENT_READ, pid)
        except OSError:  # the command went away already
            self._gone(conn, pid)

    def _gone(self, conn: socket.socket, pid: int) -> None:
        try:
            self.selector.unregister(conn)
        except (KeyError, ValueError):
            pass
        conn.close()
        if self.children.get(pid) is conn:
            self.children[pid] = None
            _kill(pid, signal.SIGTERM)

    def _reap(self) -> None:
        while self.children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                break
            if pid == 0:
                break
            conn = self.children.pop(pid, None)
            self.last = time.monotonic()
            if conn is None:
                continue
            code = os.waitstatus_to_exitcode(status)  # -N: ended by signal N
            try:
                self.selector.unregister(conn)
            except (KeyError, ValueError):
                pass
            try:
                _send(conn, {"exit": 128 - code if code < 0 else code})
            except OSError:  # the command went away meanwhile
                pass
            conn.close()

    def close_in_child(self, keep: socket.socket) -> None:
        signal.set_wakeup_fd(-1)
        for fd in (self.wake_r, self.wake_w, self.lock):
            os.close(fd)
        self.listener.close()
        for conn in self.children.values():
            if conn is not None:
                conn.close()
        keep.close()


def _kill(pid: int, signum: int) -> None:
    try:
        os.kill(pid, signum)
    except OSError:
        pass


def _child(message: dict, fds: list[int], server: _Server, conn: socket.socket) -> None:
    """The forked command: the caller's streams, folder, environment and umask, then
    ``ltd-brake`` as if started there; never returns."""
    code = 1
    try:
        for s in (signal.SIGCHLD, signal.SIGTERM, signal.SIGHUP):
            signal.signal(s, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, COMMAND_SIGNALS)
        server.close_in_child(conn)
        from ..studies.parallel import _orphan_guard

        parent = server.pid
        _orphan_guard(parent)  # the run ends with its server
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        for fd in fds:
            if fd > 2:
                os.close(fd)
        os.chdir(message["cwd"])
        os.environ.clear()
        os.environ.update(message["env"])
        os.umask(int(message["umask"]))
        try:  # the command's priority (nice) and cores (taskset), where the system lets it
            os.setpriority(os.PRIO_PROCESS, 0, int(message["nice"]))
        except OSError:
            pass
        if message.get("cpus") and hasattr(os, "sched_setaffinity"):
            try:
                os.sched_setaffinity(0, message["cpus"])
            except OSError:
                pass
        ins, outs, errs = message["encodings"]
        sys.stdin = None if ins is None else _stream(0, "r", ins)
        sys.stdout = None if outs is None else _stream(1, "w", outs)
        sys.stderr = None if errs is None else _stream(2, "w", errs)
        sys.argv = [message["argv0"], *message["argv"]]
        if "numpy" in sys.modules:  # every forked command would draw the same numbers
            sys.modules["numpy"].random.seed()
        resident.SERVED_BY = parent
        from .main import main

        code = main(list(message["argv"]))
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 0 if exc.code is None else 1
        if not isinstance(exc.code, (int, type(None))):
            print(exc.code, file=sys.stderr)
    except BaseException:  # noqa: BLE001 - as Python itself would end: the traceback, status 1
        import traceback

        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):
                pass
        os._exit(code & 0xFF)


def _stream(fd: int, mode: str, encoding: list[str]):
    import io

    raw = io.FileIO(fd, mode, closefd=False)
    buffered = io.BufferedReader(raw) if mode == "r" else io.BufferedWriter(raw)
    return io.TextIOWrapper(buffered, encoding=encoding[0], errors=encoding[1],
                            line_buffering=fd == 2 or (mode == "w" and os.isatty(fd)))


def _warm_up() -> None:
    """Load what a ``simulate`` command needs: the kernels of the paper's brake model (only if
    they are compiled: a first run's background compile is waited for) and the modules."""
    import io

    from ..first_run import wait_for_compile
    from ..simulator import kernels_cached

    wait_for_compile()
    from .main import main

    if kernels_cached() is not True:
        return
    out, err = sys.stdout, sys.stderr
    sys.stdout = sys.stderr = io.StringIO()
    try:
        main(list(WARM_UP))
    finally:
        sys.stdout, sys.stderr = out, err


def serve(idle_s: float | None = None, key: str | None = None) -> int:
    """Run this installation's server until it has been idle ``idle_s``, is asked to stop, or
    receives SIGTERM.

    Parameters
    ----------
    idle_s : float, optional
        Seconds without a command before it stops (default ``LTD_BRAKE_SERVER_IDLE_S``, else
        :data:`IDLE_S`).
    key : str, optional
        The socket's name, as the command that starts it computed it (default:
        :func:`digest`).

    Returns
    -------
    int
        0; 1 if it could not start (said on stderr, and remembered so that commands do not
        start it again until ``ltd-brake server start``).
    """
    import fcntl
    import traceback

    resident.SERVING = True
    if key is not None and (len(key) != 16 or key.strip("0123456789abcdef")):
        key = None
    if idle_s is None:
        try:
            idle_s = float(os.environ.get(IDLE_ENV, IDLE_S))
        except ValueError:
            idle_s = IDLE_S
    path = resident.socket_path(key)
    if path is None:
        print("ltd-brake server: no folder of this user's alone for the socket", file=sys.stderr)
        return 1
    lock = os.open(path.with_suffix(".lock"), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return 0  # one runs already
    failed = path.with_suffix(".failed")
    try:
        _warm_up()
        server = _Server(path, idle_s, lock)
    except Exception:  # noqa: BLE001 - said in the log; commands then run in their own process
        traceback.print_exc()
        failed.touch()
        return 1
    print(f"ltd-brake server {os.getpid()} listening on {path}", file=sys.stderr, flush=True)
    server.run()
    print(f"ltd-brake server {os.getpid()}: {server.served} commands served, stopped",
          file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(serve(key=sys.argv[1] if len(sys.argv) > 1 else None))

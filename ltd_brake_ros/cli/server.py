"""``ltd-brake server``: the resident process that runs ``simulate`` commands warm."""
from __future__ import annotations

import argparse

EPILOG = """\
how it works:
  A simulate command started as ltd-brake hands its command line to this installation's server
  when one runs: a process forked from the server, with the simulation kernels already loaded,
  runs it with the command's own output, working folder, environment, umask and priority
  (about 0.5 s sooner on two cores). Otherwise the command runs in its own process and starts a server in
  the background for the next one. A server answers only its user, serves only commands of the
  same installation and settings, and stops after 10 min without a command
  (LTD_BRAKE_SERVER_IDLE_S, seconds). LTD_BRAKE_SERVER=off: no server is used or started.
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``server`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    ap = subparsers.add_parser(
        "server", help="the resident process that runs simulate commands with warm kernels",
        description="Show, start or stop the resident server that runs `ltd-brake simulate` "
                    "commands with the simulation kernels already loaded.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("action", choices=("status", "start", "stop"),
                    help="status: the servers running for this user; start: start this "
                         "installation's server (again after one failed) and wait until it "
                         "answers; stop: stop every server of this user (runs in progress "
                         "finish)")
    ap.add_argument("--timeout-s", type=float, default=60.0,
                    help="start: seconds to wait for the server to answer (default 60)")
    ap.set_defaults(func=run)
    return ap


def run(args: argparse.Namespace) -> int:
    """Carry out the action and say what happened.

    Raises
    ------
    InputError
        No server can run here (turned off, or no folder of this user's alone).
    """
    import os
    import time

    from . import resident as server
    from ..inputs import InputError

    if args.action == "status":
        found = server.servers()
        if not found:
            print("no server runs: the next simulate command starts one"
                  if server.enabled() else
                  f"no server runs ({server.MODE_ENV}=off, or no Unix sockets here)")
            return 0
        mine = server.digest()
        for path, status in found:
            up = time.time() - status["started"]
            which = "this installation" if path.stem == mine else \
                "another installation or other settings"
            print(f"pid {status['pid']}: {which}, version {status['version']}, up "
                  f"{up / 60:.0f} min, {status['served']} commands served "
                  f"({status['running']} running), stops after {status['idle_s']:g} s idle; "
                  f"socket {path}")
        return 0
    if args.action == "stop":
        found = server.servers()
        for path, _ in found:
            server.stop(path)
        print(f"stopped {len(found)} server(s)")
        return 0
    if not server.enabled():
        raise InputError("environment", server.MODE_ENV,
                         "is off, or this system has no Unix sockets: no server can run")
    path = server.socket_path()
    if path is None:
        raise InputError("environment", server.DIR_ENV,
                         "no folder of this user's alone for the server's socket")
    try:
        os.unlink(path.with_suffix(".failed"))
    except FileNotFoundError:
        pass
    server.spawn()
    deadline = time.monotonic() + args.timeout_s
    while time.monotonic() < deadline:
        status = server._ask(path, {"kind": "status"})
        if status is not None:
            print(f"server {status['pid']} answers on {path}")
            return 0
        if path.with_suffix(".failed").exists():
            break
        time.sleep(0.1)
    raise InputError("server", str(path.with_suffix(".log")),
                     f"the server did not answer within {args.timeout_s:g} s: its log says why")

"""The resident server: a ``simulate`` command it runs behaves as one run in its own process.

Each test gives its servers a socket folder of their own and stops them (and checks that no
process of theirs is left) when it ends; a server left behind by a killed test stops after a
minute without commands.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
import yaml

from conftest import executable

#: The fields of ``simulate --json`` a served run may change: timing, and who ran it.
NOT_COMPARED = {"startup_s", "wall_time_s", "real_time_factor", "served_by"}


class Servers:
    """Commands in an environment whose servers live in a folder of their own."""

    def __init__(self):
        # short: a Unix socket's path has at most 107 bytes
        self.folder = Path(tempfile.mkdtemp(prefix="ltds-", dir="/tmp"))
        self.env = dict(os.environ, LTD_BRAKE_SERVER="auto",
                        LTD_BRAKE_SERVER_DIR=str(self.folder / "s"),
                        LTD_BRAKE_SERVER_IDLE_S="60")

    def run(self, *args: str, env: dict | None = None, **kw) -> subprocess.CompletedProcess:
        """``ltd-brake ARGS`` to its end."""
        return subprocess.run([executable("ltd-brake"), *args], env=env or self.env,
                              capture_output=True, text=True, timeout=300, **kw)

    def start(self, *args: str, **kw) -> subprocess.Popen:
        """``ltd-brake ARGS`` started, its output in pipes."""
        return subprocess.Popen([executable("ltd-brake"), *args], env=self.env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)

    def status(self) -> list[dict]:
        """What each running server of this folder says of itself."""
        from ltd_brake_ros.cli import resident as server

        old = os.environ.get(server.DIR_ENV)
        os.environ[server.DIR_ENV] = self.env[server.DIR_ENV]
        try:
            return [s for _, s in server.servers()]
        finally:
            os.environ.pop(server.DIR_ENV) if old is None else \
                os.environ.__setitem__(server.DIR_ENV, old)

    def one(self, timeout_s: float = 30.0) -> dict:
        """The status of the one server, once it answers."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            found = self.status()
            if len(found) == 1:
                return found[0]
            time.sleep(0.05)
        pytest.fail(f"not one server answering within {timeout_s:g} s: {self.status()}")

    def wait_running(self, n: int, timeout_s: float = 60.0) -> dict:
        """Wait until the one server runs ``n`` commands; its status."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            found = self.status()
            if found and found[0]["running"] == n:
                return found[0]
            time.sleep(0.05)
        pytest.fail(f"no server running {n} command(s) within {timeout_s:g} s: {self.status()}")

    def processes(self) -> list[int]:
        """Processes started with this folder in their environment (servers, commands)."""
        needle = f"LTD_BRAKE_SERVER_DIR={self.env['LTD_BRAKE_SERVER_DIR']}".encode()
        found = []
        for environ in Path("/proc").glob("[0-9]*/environ"):
            try:
                if needle in environ.read_bytes().split(b"\0"):
                    found.append(int(environ.parent.name))
            except (OSError, ValueError):
                continue
        return [p for p in found if p != os.getpid()]

    def wait_gone(self, timeout_s: float = 30.0) -> None:
        """Wait until no process of this folder is left; kill and fail if one is."""
        deadline = time.monotonic() + timeout_s
        while self.processes() and time.monotonic() < deadline:
            time.sleep(0.05)
        left = self.processes()
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        assert not left, f"processes left behind: {left}"


@pytest.fixture
def servers():
    s = Servers()
    try:
        yield s
    finally:
        # SIGTERM: each server ends the runs it has (a stop would let them finish)
        for status in s.status():
            try:
                os.kill(status["pid"], signal.SIGTERM)
            except OSError:
                pass
        try:
            s.wait_gone()
        finally:
            shutil.rmtree(s.folder, ignore_errors=True)


def _started(servers: Servers) -> dict:
    done = servers.run("server", "start")
    assert done.returncode == 0 and "answers on" in done.stdout, done.stdout + done.stderr
    return servers.one()


def test_a_served_run_prints_what_a_run_in_its_own_process_prints(servers, tmp_path):
    alone = servers.run("simulate", "--scenario", "6", "--json",
                        env=dict(servers.env, LTD_BRAKE_SERVER="off"))
    assert alone.returncode == 0, alone.stderr
    assert not servers.status()  # a command with the server off starts none
    status = _started(servers)
    served = servers.run("simulate", "--scenario", "6", "--json")
    assert served.returncode == 0, served.stderr
    mine, theirs = json.loads(alone.stdout), json.loads(served.stdout)
    assert (mine["served_by"], theirs["served_by"]) == (None, status["pid"])
    assert {k: v for k, v in mine.items() if k not in NOT_COMPARED} \
        == {k: v for k, v in theirs.items() if k not in NOT_COMPARED}
    text = servers.run("simulate", "--scenario", "6")
    assert text.returncode == 0, text.stderr
    assert f"(run by the ltd-brake server, process {status['pid']}" in text.stdout
    after = servers.one()
    assert (after["pid"], after["served"], after["running"]) == (status["pid"], 2, 0)


def test_a_served_run_has_the_commands_folder_umask_and_exit_status(servers, tmp_path):
    _started(servers)
    bad = servers.run("simulate", "--scenario", "99")
    alone = servers.run("simulate", "--scenario", "99",
                        env=dict(servers.env, LTD_BRAKE_SERVER="off"))
    assert (bad.returncode, bad.stdout, bad.stderr) \
        == (alone.returncode, alone.stdout, alone.stderr) and bad.returncode == 2
    # a relative output lands in the command's folder, made with the command's umask
    done = servers.run("simulate", "--scenario", "6", "--record", "rec", cwd=tmp_path,
                       preexec_fn=lambda: os.umask(0o077))
    assert done.returncode == 0, done.stderr
    assert "run by the ltd-brake server" in done.stdout
    files = [p for p in (tmp_path / "rec").iterdir()]
    assert any(p.suffix == ".mcap" for p in files), files
    assert all(stat.S_IMODE(p.stat().st_mode) & 0o077 == 0 for p in files), \
        [oct(p.stat().st_mode) for p in files]
    report = servers.run("report", "rec", cwd=tmp_path)
    assert report.returncode == 0, report.stderr
    assert servers.one()["served"] == 2


def _long_run(tmp_path: Path) -> Path:
    # the train coasts for a day of simulated time: minutes of wall time
    script = tmp_path / "coast.yaml"
    script.write_text(yaml.safe_dump({"duration_s": 86400.0,
                                      "commands": [{"t_s": 0.0, "traction": 0.0}]}))
    return script


def test_ctrl_c_and_a_command_gone_end_the_served_run(servers, tmp_path):
    server = _started(servers)["pid"]
    script = _long_run(tmp_path)
    command = servers.start("simulate", "--scenario", "6", "--commands", str(script),
                            preexec_fn=lambda: os.nice(5))
    servers.wait_running(1)
    # the run takes the command's priority, not the server's, as it starts
    (run,) = map(int, Path(f"/proc/{server}/task/{server}/children").read_text().split())
    want = os.getpriority(os.PRIO_PROCESS, server) + 5
    deadline = time.monotonic() + 30
    while os.getpriority(os.PRIO_PROCESS, run) != want and time.monotonic() < deadline:
        time.sleep(0.05)
    assert os.getpriority(os.PRIO_PROCESS, run) == want
    os.kill(command.pid, signal.SIGINT)  # Ctrl-C reaches the run, which ends as it would alone
    out, err = command.communicate(timeout=60)
    assert command.returncode == 130 and "ltd-brake simulate: interrupted" in err, (out, err)
    servers.wait_running(0)
    # a command killed outright: its run ends with it
    command = servers.start("simulate", "--scenario", "6", "--commands", str(script))
    servers.wait_running(1)
    command.kill()
    command.wait(30)
    servers.wait_running(0, timeout_s=30)


def test_a_server_killed_during_a_run_fails_the_command_in_one_line(servers, tmp_path):
    status = _started(servers)
    # a server that cannot answer (stopped): Ctrl-C, pressed again, still ends the command
    command = servers.start("simulate", "--scenario", "6", "--commands",
                            str(_long_run(tmp_path)))
    servers.wait_running(1)
    os.kill(status["pid"], signal.SIGSTOP)
    try:
        deadline = time.monotonic() + 30
        while command.poll() is None and time.monotonic() < deadline:
            os.kill(command.pid, signal.SIGINT)
            time.sleep(0.2)
        out, err = command.communicate(timeout=30)
    finally:
        os.kill(status["pid"], signal.SIGCONT)
    assert command.returncode == 130 and "the run in the ltd-brake server did not end" in err, \
        (out, err)
    servers.wait_running(0)  # the run ended at the first Ctrl-C; the server says so now
    command = servers.start("simulate", "--scenario", "6", "--commands",
                            str(_long_run(tmp_path)))
    servers.wait_running(1)
    os.kill(status["pid"], signal.SIGKILL)
    out, err = command.communicate(timeout=60)
    assert command.returncode == 3, (out, err)
    # one line from the command; the run, ended with its server, may say so too
    lines = err.strip().splitlines()
    assert [s for s in lines if s.startswith(
        "ltd-brake simulate: error: the ltd-brake server stopped during the run")] \
        and set(lines) <= {lines[0], lines[-1], "ltd-brake simulate: terminated"}, err
    servers.wait_gone()  # the run ended with its server


def test_other_settings_a_shared_folder_and_idleness_keep_a_command_to_itself(servers):
    # a socket folder others may enter is not used, and no server starts there
    shared = servers.folder / "shared"
    shared.mkdir(mode=0o755)
    shared.chmod(0o755)
    env = dict(servers.env, LTD_BRAKE_SERVER_DIR=str(shared))
    done = servers.run("simulate", "--scenario", "6", env=env)
    assert done.returncode == 0 and "run by the ltd-brake server" not in done.stdout
    refused = servers.run("server", "start", env=env)
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1 \
        and "LTD_BRAKE_SERVER_DIR" in refused.stderr, refused.stderr
    assert list(shared.iterdir()) == []
    # idle servers stop by themselves, removing their sockets
    servers.env["LTD_BRAKE_SERVER_IDLE_S"] = "5"
    started = servers.run("server", "start")
    assert started.returncode == 0 and "answers on" in started.stdout, started.stderr
    servers.wait_gone(timeout_s=60)  # idle for 5 s, then gone
    assert not list(Path(servers.env["LTD_BRAKE_SERVER_DIR"]).glob("*.sock"))
    # other settings than the server's: the command runs in its own process (and starts a
    # server of its settings for the next one)
    servers.env["LTD_BRAKE_SERVER_IDLE_S"] = "60"
    _started(servers)
    other = servers.run("simulate", "--scenario", "6",
                        env=dict(servers.env, LTD_BRAKE_UNUSED_SETTING="1"))
    assert other.returncode == 0, other.stderr
    assert "run by the ltd-brake server" not in other.stdout
    # explicit readiness: its socket answers (then both are stopped when the test ends)
    deadline = time.monotonic() + 60
    while len(servers.status()) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert len(servers.status()) == 2, servers.status()

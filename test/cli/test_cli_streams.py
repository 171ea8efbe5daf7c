"""Every verb with its standard output or error closed, or read by no one, ends non-zero with
no traceback, and standard output never carries error text (run as a user runs them: each in
its own process)."""
from __future__ import annotations

import json
import os
import subprocess

import pytest

from bag_helpers import record_emergency_stop
from campaigns.campaign_helpers import write_campaign
from conftest import executable
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import get_scenario

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def commands(tmp_path_factory):
    """One real command line per verb (and the program's own options), with what they read."""
    root = tmp_path_factory.mktemp("streams")
    sc = get_scenario(1)
    record_emergency_stop(root / "run", sc.consist(), sc.speed_kmh, ns="/train")
    campaign = write_campaign(root, runs=4, batch=2)
    assert main(["campaign", "run", str(campaign), "--out", str(root / "results"), "--quiet",
                 "--jobs", "1"]) == 0
    return {
        "simulate": ["simulate", "--scenario", "1", "--json"],
        "validate": ["validate", "--scenarios", "1", "--jobs", "1", "--json"],
        "calibrate": ["calibrate", "--target", "paper", "--fit", "k0", "--scenarios", "1",
                      "--step-s", "0.05", "--max-nfev", "1", "--jobs", "1", "--quiet"],
        "report": ["report", str(root / "run"), "--out", str(root / "report"), "--json"],
        "recover": ["recover", str(root / "run"), str(root / "recovered_{}")],
        "campaign": ["campaign", "report", str(root / "results"), "--json"],
        "help": ["--help"],
        "version": ["--version"],
    }


VERBS = ["simulate", "validate", "calibrate", "report", "recover", "campaign", "help",
         "version"]


def _argv(commands, verb: str, case: str) -> list[str]:
    return [executable("ltd-brake")] + [a.format(case) for a in commands[verb]]


def _no_traceback(*texts) -> None:
    for text in texts:
        assert "Traceback" not in text and "Exception ignored" not in text, text


def _closing(fd: int):
    return lambda: os.close(fd)


@pytest.mark.parametrize("verb", VERBS)
def test_closed_standard_output_is_one_line_and_a_failure(commands, verb):
    out = subprocess.run(_argv(commands, verb, "out_closed"), stdin=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, timeout=300,
                         preexec_fn=_closing(1))
    assert out.returncode != 0
    _no_traceback(out.stderr)
    assert out.stderr.count("\n") == 1 and "standard output is closed" in out.stderr


@pytest.mark.parametrize("verb", VERBS)
def test_closed_standard_error_is_a_failure_and_leaves_standard_output_clean(commands, verb):
    out = subprocess.run(_argv(commands, verb, "err_closed"), stdin=subprocess.DEVNULL,
                         stdout=subprocess.PIPE, text=True, timeout=300,
                         preexec_fn=_closing(2))
    assert out.returncode != 0
    assert out.stdout == ""  # no error text, and no output a reader could take as complete


@pytest.mark.parametrize("stream", ["stdout", "stderr"])
@pytest.mark.parametrize("verb", VERBS)
def test_a_pipe_whose_reader_is_gone_is_a_failure(commands, verb, stream):
    """The reader closes its end at once (before the command writes anything)."""
    other = "stderr" if stream == "stdout" else "stdout"
    proc = subprocess.Popen(_argv(commands, verb, f"{stream}_gone"), stdin=subprocess.DEVNULL,
                            **{stream: subprocess.PIPE, other: subprocess.PIPE}, text=True)
    getattr(proc, stream).close()
    rest = getattr(proc, other).read()
    assert proc.wait(timeout=300) != 0
    assert rest == ""  # nothing to say (as a writer ended by SIGPIPE), no error text


def test_a_reader_that_leaves_output_unread_is_seen():
    """``ltd-brake simulate --scenario 1 --json | head -c 10``: the output fits the pipe, and
    its reader takes ten bytes and leaves (here on a pipe of the test's own, so that the
    reader leaves before the look, whatever the machine's load)."""
    from ltd_brake_ros.cli.main import _unread_when_reader_left

    read, write = os.pipe()
    try:
        os.write(write, b'{"consist": "..."}' * 300)
        os.read(read, 10)
        os.close(read)
        assert _unread_when_reader_left(write)
    finally:
        os.close(write)


def test_a_reader_that_takes_everything_or_is_slow_is_not_a_failure():
    import time

    from ltd_brake_ros.cli import main as main_module

    read, write = os.pipe()
    try:
        os.write(write, b"x" * 5000)
        os.read(read, 5000)
        assert not main_module._unread_when_reader_left(write)  # all taken
        os.write(write, b"y" * 5000)
        start = time.monotonic()
        assert not main_module._unread_when_reader_left(write)  # still there, not reading
        assert time.monotonic() - start < main_module.READER_WAIT_S + 1.0
        assert len(os.read(read, 10_000)) == 5000  # the output waits for it, whole
    finally:
        os.close(read)
        os.close(write)


def test_a_reader_that_takes_everything_sees_complete_json(commands):
    out = subprocess.run(_argv(commands, "simulate", "all"), stdin=subprocess.DEVNULL,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["vehicles"] == 11

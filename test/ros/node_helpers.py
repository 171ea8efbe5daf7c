"""Helpers for tests that run the installed ``sim_node`` and read what it recorded."""
from __future__ import annotations

import os
import re
import signal
import sys
import time
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from conftest import executable

PNG = b"\x89PNG\r\n\x1a\n"
#: Per-chunk state topics of the node (relative), all Float64MultiArray.
ARRAY_TOPICS = ("vehicles/speed", "vehicles/position", "vehicles/brake_force",
                "vehicles/traction_force", "couplers/force")
#: Per-chunk stamped state topics of the node (relative), sensor_msgs/JointState.
STATE_TOPICS = ("vehicles/state", "couplers/state")


def node_argv(ns: str, *params: str, ros_args: tuple[str, ...] = ()) -> list[str]:
    """Command line of the installed sim_node in namespace ``ns``, its /clock moved under ``ns``.

    Moving /clock keeps nodes of parallel trials apart; /diagnostics stays global (its
    status name tells the nodes apart).
    """
    argv = [executable("sim_node"), "--ros-args", *ros_args, "-r", f"__ns:={ns}",
            "-r", f"/clock:={ns}/clock"]
    for p in params:
        argv += ["-p", p]
    return argv


def limited_argv(argv: list[str], max_file_bytes: int) -> list[str]:
    """``argv`` run with RLIMIT_FSIZE: writes past ``max_file_bytes`` fail with EFBIG.

    SIGXFSZ is ignored (inherited through exec), so the write returns the error instead of
    killing the process: the portable, unprivileged stand-in for a full disk.
    """
    code = ("import os, resource, signal, sys\n"
            "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
            f"resource.setrlimit(resource.RLIMIT_FSIZE, ({max_file_bytes}, {max_file_bytes}))\n"
            "os.execv(sys.argv[1], sys.argv[1:])\n")
    return [sys.executable, "-c", code, *argv]


def wait_for_output(proc, text: str, timeout_s: float = 60.0) -> float:
    """Wait until ``text`` is in the process's output; returns the monotonic time seen."""
    end = time.monotonic() + timeout_s
    while text not in proc.output():
        if proc.popen.poll() is not None:
            pytest.fail(f"{proc.argv[0]} exited ({proc.popen.returncode}) before printing "
                        f"{text!r}:\n{proc.output()}")
        if time.monotonic() > end:
            pytest.fail(f"no {text!r} within {timeout_s:g} s:\n{proc.output()}")
        time.sleep(0.02)
    return time.monotonic()


def wait_until_signals_handled(proc, timeout_s: float = 60.0) -> float:
    """Wait until the process handles SIGTERM itself (``SigCgt`` in ``/proc/<pid>/status``);
    returns the monotonic time seen. Python handles SIGINT from its start, SIGTERM only once
    the program installs its own handling."""
    mask = 1 << (signal.SIGTERM - 1)
    end = time.monotonic() + timeout_s
    while True:
        try:
            status = Path(f"/proc/{proc.pid}/status").read_text()
        except OSError:
            status = ""
        caught = next((int(line.split()[1], 16) for line in status.splitlines()
                       if line.startswith("SigCgt:")), 0)
        if caught & mask:
            return time.monotonic()
        if proc.popen.poll() is not None or time.monotonic() > end:
            pytest.fail(f"{proc.argv[0]} never handled SIGTERM:\n{proc.output()}")
        time.sleep(0.002)


def signal_group(proc, sig: int) -> None:
    """Send ``sig`` to the process group of ``proc`` (robust to the ROS wheels' re-exec)."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def chunks_from_log(output: str) -> int:
    """Chunks advanced, from the node's last log line ``stopped at t = ... after N chunks``."""
    found = re.findall(r"after (\d+) chunks", output)
    assert found, f"no final 'after N chunks' line in:\n{output}"
    return int(found[-1])


def read_mcap(path: Path) -> tuple[object, dict[str, list]]:
    """Summary and ``topic -> [(log_time_ns, schema name, data)]`` with the ``mcap`` reader.

    Parameters
    ----------
    path : pathlib.Path
        Bag folder (its single ``.mcap`` file is read) or ``.mcap`` file.
    """
    file = path if path.is_file() else next(path.glob("*.mcap"))
    messages: dict[str, list] = defaultdict(list)
    with open(file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            messages[channel.topic].append((message.log_time, schema.name, message.data))
    return summary, messages


def diagnostics_of(arrays, node: str) -> list[dict[str, str]]:
    """Key/values of each diagnostics status of ``node`` in ``arrays`` (level under ``_level``)."""
    out = []
    for array in arrays:
        for status in array.status:
            if status.name == f"{node}: train plant":
                out.append({kv.key: kv.value for kv in status.values}
                           | {"_level": level_int(status.level), "_message": status.message})
    return out


def level_int(level) -> int:
    """A ``byte`` field as an int (rclpy gives bytes, the other decoders ints)."""
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def plain(msg):
    """Comparable plain data of the node's message types, whichever library decoded them."""
    if hasattr(msg, "layout"):  # Float64MultiArray
        dims = [(d.label, int(d.size), int(d.stride)) for d in msg.layout.dim]
        return dims, int(msg.layout.data_offset), [float(v) for v in msg.data]
    if hasattr(msg, "effort"):  # JointState
        return ((int(msg.header.stamp.sec), int(msg.header.stamp.nanosec)), msg.header.frame_id,
                list(msg.name), *([float(v) for v in getattr(msg, f)]
                                  for f in ("position", "velocity", "effort")))
    if hasattr(msg, "clock"):
        return int(msg.clock.sec), int(msg.clock.nanosec)
    if hasattr(msg, "status"):
        return (int(msg.header.stamp.sec), int(msg.header.stamp.nanosec),
                [(level_int(s.level), s.name, s.message, s.hardware_id,
                  [(kv.key, kv.value) for kv in s.values]) for s in msg.status])
    return msg.data  # Bool, Float64


def rss_kb(pid: int) -> int:
    """Resident set size of process ``pid`` [kB] (Linux)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError(f"no VmRSS for pid {pid}")


SIGNALS = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM", signal.SIGKILL: "SIGKILL"}

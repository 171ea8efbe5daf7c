"""The recording's layout: a rosbag2 folder holding one MCAP file (profile ``ros2``).

A recording is a folder, as ``ros2 bag record -s mcap`` writes it::

    run_2025_01_01-12_00_00/
        metadata.yaml                      rosbag2 metadata, version 9 (Jazzy)
        run_2025_01_01-12_00_00_0.mcap     profile ros2, ros2msg schemas, cdr payloads

File layout and why
-------------------
* Header, then the run's Metadata record (``ltd_brake_ros.run``), then one Schema and one
  Channel record per topic, all written straight to the file (outside chunks) as soon as they
  are known, so that a file cut short still names its topics and types.
* Messages are collected into chunks (zstd or lz4 compressed, CRC of the uncompressed records)
  each followed by its Message Index records. A chunk is sealed as soon as it is full or
  ``flush_interval_s`` of wall time has passed, and a writer thread puts it and its indexes in
  the file with one system call, so a process killed at any instant leaves a file whose every
  complete chunk is readable, and only the last second or so of messages is at risk.
* Closing adds a ``rosbag2`` Metadata record whose ``serialized_metadata`` is the complete
  version-9 metadata (rosbag2's reader assumes version 8, and integer QoS values, when that key
  is missing), then the summary section (schemas, channels, statistics, chunk and metadata
  indexes, summary offsets), the footer, and ``metadata.yaml`` beside the file.
* While a recording is written its folder holds a file named ``UNFINISHED``
  (:data:`UNFINISHED_NAME`), created exclusively before the MCAP file and removed once
  ``metadata.yaml`` is in place: a folder that has it is being recorded, or its recorder was
  killed. The MCAP file keeps its final name from the start (so a recording under way, or cut
  short, opens in any MCAP reader as it is); the finished folder is exactly what
  ``ros2 bag record`` leaves, for ``ros2 bag info``, ``rosbags`` and Foxglove. Readers say
  when a folder is unfinished (:func:`unfinished`) and read it as it is.

Message payloads are stored exactly as given: the bytes of
``rclpy.serialization.serialize_message(msg)``, CDR with its 4-byte encapsulation header.

The modules of this folder, format below and ROS above: this one (constants and the run
information's encoding), :mod:`.writer`, :mod:`.reader` and :mod:`.recover` need only the
``mcap`` library; :mod:`.ros_types` knows ROS message types (names, ``.msg`` definitions, type
hashes, read from the installed message packages) and :mod:`.qos` ROS QoS profiles;
:mod:`.cdr` decodes the payloads the analysis reads, without ROS.
"""
from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

#: Name of the MCAP Metadata record holding the run information.
RUN_METADATA_NAME = "ltd_brake_ros.run"
#: rosbag2 metadata version written (ROS 2 Jazzy).
ROSBAG2_VERSION = 9
#: ROS distribution named in the rosbag2 metadata.
ROS_DISTRO = "jazzy"
#: MCAP magic bytes, at the start and the end of a file.
MAGIC = b"\x89MCAP0\r\n"
#: Library named in the MCAP header.
LIBRARY = "ltd_brake_ros"


def _json_default(value):
    # numpy scalars and arrays, paths: what run information typically holds
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def encode_run_metadata(metadata: dict) -> dict[str, str]:
    """MCAP metadata entries of the run information: each top-level key, its value as JSON.

    Parameters
    ----------
    metadata : dict
        JSON-serialisable values (numpy scalars and arrays, paths allowed).

    Returns
    -------
    dict of str to str

    Raises
    ------
    TypeError
        A value that cannot be stored.
    """
    return {str(k): json.dumps(v, default=_json_default) for k, v in metadata.items()}


def decode_run_metadata(entries: dict) -> dict:
    """The run information from its MCAP metadata entries (a value not JSON stays text).

    Parameters
    ----------
    entries : dict of str to str

    Returns
    -------
    dict
    """
    out = {}
    for k, v in entries.items():
        try:
            out[k] = json.loads(v)
        except ValueError:
            out[k] = v
    return out


#: The file a bag folder holds while its recording is unfinished.
UNFINISHED_NAME = "UNFINISHED"
#: Largest marker read [bytes].
_UNFINISHED_MAX_BYTES = 4096


def mark_unfinished(folder: Path, file_name: str) -> Path:
    """Create the marker of an unfinished recording in ``folder`` (exclusively).

    Parameters
    ----------
    folder : pathlib.Path
    file_name : str
        The MCAP file being written.

    Returns
    -------
    pathlib.Path
        The marker.

    Raises
    ------
    FileExistsError
        The folder has one: another recorder writes it, or one was killed there.
    """
    marker = folder / UNFINISHED_NAME
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    text = (f"This recording is unfinished: process {os.getpid()} on {socket.gethostname()} "
            f"started writing {file_name} at {started} and has not closed it.\n"
            "If that process has ended, it was killed: `ltd-brake report` reads the recording "
            "as it is, and `ltd-brake recover` writes a finished copy.\n"
            f"pid: {os.getpid()}\nhost: {socket.gethostname()}\nfile: {file_name}\n")
    try:
        fd = os.open(marker, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                     | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except FileExistsError:
        raise FileExistsError(f"{marker} exists: another recorder is writing {folder}, or one "
                              "was killed there; choose a new bag folder") from None
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    return marker


def unfinished(path) -> str:
    """Why a recording is unfinished, from its folder's marker; empty when it has none.

    Parameters
    ----------
    path : str or path-like
        Bag folder, or an ``.mcap`` file (its folder's marker counts).

    Returns
    -------
    str
        One sentence: still being recorded by a process of this machine, or left unfinished by
        one that stopped without closing it.
    """
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    marker = folder / UNFINISHED_NAME
    try:
        with open(marker, "rb") as fh:
            text = fh.read(_UNFINISHED_MAX_BYTES).decode("utf-8", "replace")
    except OSError:
        return ""
    fields = dict(line.split(": ", 1) for line in text.splitlines() if ": " in line)
    pid, host = fields.get("pid", "").strip(), fields.get("host", "").strip()
    if pid.isdigit() and host == socket.gethostname():
        try:
            os.kill(int(pid), 0)
            alive = True
        except ProcessLookupError:
            alive = False
        except OSError:  # another user's process
            alive = True
        if alive:
            return (f"{folder} is unfinished: process {pid} is still recording it (read as it "
                    "is now)")
        return (f"{folder} is unfinished: process {pid}, which recorded it, ended without "
                "closing it (killed?); read to its last complete chunk")
    who = f"process {pid} on {host}" if pid and host else "its recorder"
    return (f"{folder} is unfinished ({marker.name}): {who} did not close it; read to its last "
            "complete chunk")

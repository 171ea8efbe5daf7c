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

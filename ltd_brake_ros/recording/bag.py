"""Recording in the rosbag2 MCAP layout: writer, reader and crash recovery.

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
* :meth:`BagWriter.close` adds a ``rosbag2`` Metadata record whose ``serialized_metadata`` is
  the complete version-9 metadata (rosbag2's reader assumes version 8, and integer QoS values,
  when that key is missing), then the summary section (schemas, channels, statistics, chunk and
  metadata indexes, summary offsets), the footer, and ``metadata.yaml`` beside the file.

Message payloads are stored exactly as given: the bytes of
``rclpy.serialization.serialize_message(msg)``, CDR with its 4-byte encapsulation header.
Only reading the installed ``.msg`` files for the schema text needs the ROS message packages;
reading and recovering need only the ``mcap`` library.
"""
from __future__ import annotations

import importlib
import io
import json
import math
import os
import queue
import struct
import sys
import threading
import time
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import yaml
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.exceptions import McapError
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message,
                          Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.opcode import Opcode
from mcap.stream_reader import breakup_chunk

from .qos import parse_qos_profiles, qos_profiles_yaml

__all__ = ["BagWriter", "BagInfo", "TopicInfo", "TruncatedBagWarning", "bag_info", "read_bag",
           "recover", "default_recover_destination", "message_definition", "message_class",
           "type_name",
           "type_description_hash", "qos_profiles_yaml", "parse_qos_profiles",
           "RUN_METADATA_NAME", "ROSBAG2_VERSION"]

#: Name of the MCAP Metadata record holding the run information.
RUN_METADATA_NAME = "ltd_brake_ros.run"
#: rosbag2 metadata version written (ROS 2 Jazzy).
ROSBAG2_VERSION = 9
ROS_DISTRO = "jazzy"

_MAGIC = b"\x89MCAP0\r\n"
_LIBRARY = "ltd_brake_ros"
# Message record: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")
# Message Index record: opcode, record length, channel id, byte length of the entries.
_INDEX_HEADER = struct.Struct("<BQHI")
# Chunk record up to the compression name: opcode, record length, start, end, uncompressed
# size, uncompressed CRC, length of the compression name.
_CHUNK_HEADER = struct.Struct("<BQQQQII")
# rmw's "infinite" duration, which rosbag2 records for unset deadlines and lifespans.


class TruncatedBagWarning(UserWarning):
    """A recording ends before its summary (the recorder was killed); see :func:`recover`."""


# --------------------------------------------------------------------------- message definitions


def _split_type(msg_type: str) -> tuple[str, str, str]:
    parts = msg_type.split("/")
    if len(parts) == 2:
        return parts[0], "msg", parts[1]
    if len(parts) == 3 and all(parts):
        return parts[0], parts[1], parts[2]
    raise ValueError(f"message type must look like 'pkg/msg/Type', got {msg_type!r}")


def message_class(msg_type: str):
    pkg, ns, name = _split_type(msg_type)
    try:
        return getattr(importlib.import_module(f"{pkg}.{ns}"), name)
    except (ImportError, AttributeError) as exc:
        raise LookupError(f"message type {msg_type} is not installed ({exc})") from None


def type_name(msg) -> str:
    """``pkg/msg/Type`` of a message instance or class (``std_msgs/msg/Bool``).

    Parameters
    ----------
    msg : message or message class

    Returns
    -------
    str
    """
    cls = msg if isinstance(msg, type) else type(msg)
    parts = cls.__module__.split(".")
    return f"{parts[0]}/{parts[1]}/{cls.__name__}"


def _share_dirs(pkg: str) -> Iterator[Path]:
    """Candidate ``share/<pkg>`` directories, most authoritative first."""
    if os.environ.get("AMENT_PREFIX_PATH"):
        try:
            from ament_index_python.packages import get_package_share_directory

            yield Path(get_package_share_directory(pkg))
        except Exception:  # noqa: BLE001 - package not registered in the index
            pass
    # Wheels and ROS installs both put share/ under the prefix that holds the Python package.
    try:
        module = importlib.import_module(pkg)
        for parent in Path(module.__file__).resolve().parents:
            yield parent / "share" / pkg
    except Exception:  # noqa: BLE001 - not importable: fall through to sys.prefix
        pass
    yield Path(sys.prefix) / "share" / pkg


def _interface_file(msg_type: str, suffix: str) -> Path:
    pkg, ns, name = _split_type(msg_type)
    for share in _share_dirs(pkg):
        path = share / ns / f"{name}{suffix}"
        if path.is_file():
            return path
    raise LookupError(f"cannot find {pkg}/{ns}/{name}{suffix} in any installed share/{pkg}")


def _nested_types(msg_type: str) -> list[str]:
    """Message types used by the fields of ``msg_type`` as ``pkg/Type``, sorted."""
    from rosidl_parser.definition import AbstractNestedType, NamespacedType

    deps = set()
    for slot in message_class(msg_type).SLOT_TYPES:
        base = slot.value_type if isinstance(slot, AbstractNestedType) else slot
        if isinstance(base, NamespacedType):
            deps.add(f"{base.namespaces[0]}/{base.name}")
    return sorted(deps)


def message_definition(msg_type: str) -> str:
    """Full ``ros2msg`` schema text of a message type, as rosbag2 stores it in MCAP.

    The type's ``.msg`` file, then every nested type once (depth first, each level in sorted
    order), each preceded by a line of 80 ``=`` and ``MSG: pkg/Type``. The text is read from
    the installed message packages; nested types come from the message class's field types.

    Parameters
    ----------
    msg_type : str
        Full type name, e.g. ``std_msgs/msg/Float64MultiArray``.

    Returns
    -------
    str
    """
    seen: set[str] = set()

    def expand(name: str) -> str:
        text = _interface_file(name, ".msg").read_text()
        for dep in _nested_types(name):
            if dep not in seen:
                seen.add(dep)
                text += "\n" + "=" * 80 + f"\nMSG: {dep}\n" + expand(dep)
        return text

    return expand(msg_type)


def type_description_hash(msg_type: str) -> str:
    """REP-2011 type hash (``RIHS01_...``) from the installed type description, or ``""``.

    Parameters
    ----------
    msg_type : str

    Returns
    -------
    str
    """
    try:
        desc = json.loads(_interface_file(msg_type, ".json").read_text())
    except (LookupError, ValueError, OSError):
        return ""
    pkg, ns, name = _split_type(msg_type)
    full = f"{pkg}/{ns}/{name}"
    return next((h["hash_string"] for h in desc.get("type_hashes", ())
                 if h.get("type_name") == full), "")


# --------------------------------------------------------------------------- writer


def _json_default(value):
    # numpy scalars and arrays, paths: what run information typically holds
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def _json_entries(metadata: dict) -> dict[str, str]:
    """MCAP metadata entries: each top-level key, its value as JSON text."""
    return {str(k): json.dumps(v, default=_json_default) for k, v in metadata.items()}


@dataclass
class _Topic:
    channel_id: int
    name: str
    msg_type: str
    qos: str
    type_hash: str
    count: int = 0
    index: list = field(default_factory=list)  # flat [log_time, offset, ...] of this chunk


class BagWriter:
    """Write a rosbag2-compatible MCAP recording, streaming, crash tolerant.

    Parameters
    ----------
    folder : str or path-like
        Bag folder to create (it may exist if empty); the file inside is
        ``<folder-name>_0.mcap``.
    metadata : dict, optional
        Free-form run information (consist summary, parameters, scenario), JSON-serialisable.
        Stored as the MCAP Metadata record ``ltd_brake_ros.run`` (each top-level key one entry,
        its value JSON-encoded) and in ``custom_data`` of ``metadata.yaml``.
    compression : str, optional
        Chunk compression: ``"zstd"`` (level 1: as small as level 3 for these arrays, in less
        than half the time), ``"lz4"`` or ``"none"``.
    chunk_size : int, optional
        Uncompressed chunk size that triggers a flush [bytes].
    flush_interval_s : float, optional
        Longest wall time a message may wait in memory before its chunk is handed to the
        writer thread [s]. Checked on every :meth:`write` and by :meth:`flush_if_due`.

    Notes
    -----
    :meth:`write` only appends to the chunk in memory. Compressing, checksumming and writing a
    finished chunk happen on a writer thread (those calls release the GIL), in order, through
    a queue of at most ``max_pending`` chunks: when the disk falls behind, :meth:`write`
    waits rather than drop anything or grow memory. :attr:`messages_on_disk` counts what has
    reached the operating system (and so survives the process being killed).

    Memory stays flat: the current chunk, the queue, and one index entry per chunk.
    The object is safe to use from several threads.
    """

    max_pending = 8

    def __init__(self, folder, *, metadata: dict | None = None, compression: str = "zstd",
                 chunk_size: int = 1 << 20, flush_interval_s: float = 1.0):
        compression = (compression or "none").lower()
        if compression == "zstd":
            import zstandard

            self._compress = zstandard.ZstdCompressor(level=1).compress
        elif compression == "lz4":
            import lz4.frame

            self._compress = lz4.frame.compress
        elif compression in ("none", ""):
            compression, self._compress = "", None
        else:
            raise ValueError(f"compression must be zstd, lz4 or none, got {compression!r}")
        if chunk_size < 1:
            raise ValueError("chunk_size must be positive")
        run_entries = _json_entries(dict(metadata or {}))  # fails before anything is created
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.path = self.folder / f"{self.folder.name}_0.mcap"
        for existing in (self.path, self.folder / "metadata.yaml"):
            if existing.exists():
                raise FileExistsError(f"{existing} exists: choose a new bag folder")
        self.compression = compression
        self.chunk_size = int(chunk_size)
        self.flush_interval_s = float(flush_interval_s)
        self.metadata = dict(metadata or {})
        self._lock = threading.Lock()
        self._closed = False
        # state of the calling threads (guarded by _lock)
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, Schema] = {}
        self._channels: list[Channel] = []
        self._chunk = bytearray()
        self._last_flush = time.monotonic()
        # state of the writer thread (read by others only once the queue is drained)
        self._file = open(self.path, "xb", buffering=0)  # noqa: SIM115 - closed in close()
        self._pos = 0
        self._chunk_count = 0
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._on_disk = 0
        #: CPU time the writer thread spent compressing and writing [s].
        self.writer_thread_cpu_s = 0.0
        self._error: BaseException | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=self.max_pending)
        self._thread = threading.Thread(target=self._worker, name=f"bag {self.folder.name}",
                                        daemon=True)
        self._thread.start()
        rb = RecordBuilder()
        Header(profile="ros2", library=_LIBRARY).write(rb)
        self._submit(("raw", _MAGIC + rb.end(), None))
        if run_entries:
            self._add_metadata(RUN_METADATA_NAME, run_entries)

    # ----------------------------------------------------------------- writer thread

    def _submit(self, job) -> None:
        if self._error is not None:
            raise OSError(f"writing {self.path} failed: {self._error}") from self._error
        self._queue.put(job)

    def _worker(self) -> None:
        while True:
            job = self._queue.get()
            cpu = time.thread_time()
            try:
                if job is None:
                    return
                if self._error is None:
                    if job[0] == "chunk":
                        self._write_chunk(*job[1:])
                    else:
                        offset = self._pos
                        self._emit([job[1]])
                        if job[2] is not None:
                            self._metadata_indexes.append(
                                MetadataIndex(offset=offset, length=len(job[1]), name=job[2]))
            except BaseException as exc:  # noqa: BLE001 - reported to the caller's thread
                self._error = exc
            finally:
                self.writer_thread_cpu_s += time.thread_time() - cpu
                self._queue.task_done()

    def _emit(self, parts) -> None:
        # one system call per record group; a kill leaves at most one record incomplete
        total = sum(len(p) for p in parts)
        n = os.writev(self._file.fileno(), parts)
        if n < total:
            rest = memoryview(b"".join(parts))[n:]
            while rest:
                rest = rest[self._file.write(rest):]
        self._pos += total

    def _write_chunk(self, records: bytearray, indexes, start: int, end: int,
                     messages: int) -> None:
        crc = zlib.crc32(records)
        data = self._compress(records) if self._compress else records
        comp = self.compression.encode()
        head = _CHUNK_HEADER.pack(Opcode.CHUNK, 40 + len(comp) + len(data), start, end,
                                  len(records), crc, len(comp)) \
            + comp + struct.pack("<Q", len(data))
        offset = self._pos
        parts = [head, data]
        pos = offset + len(head) + len(data)
        chunk_length = pos - offset
        offsets = {}
        for channel_id, flat in indexes:
            n = len(flat) // 2
            rec = _INDEX_HEADER.pack(Opcode.MESSAGE_INDEX, 6 + 16 * n, channel_id, 16 * n) \
                + struct.pack(f"<{2 * n}Q", *flat)
            offsets[channel_id] = pos
            pos += len(rec)
            parts.append(rec)
        self._emit(parts)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=offset,
            chunk_length=chunk_length, message_index_offsets=offsets,
            message_index_length=pos - offset - chunk_length, compression=self.compression,
            compressed_size=len(data), uncompressed_size=len(records)))
        self._chunk_count += 1
        self._on_disk += messages

    # ----------------------------------------------------------------- calling threads

    def _add_metadata(self, name: str, entries: dict[str, str]) -> None:
        rb = RecordBuilder()
        Metadata(name=name, metadata=dict(entries)).write(rb)
        self._submit(("raw", rb.end(), name))

    def _add_channel(self, topic: str, msg_type: str, encoding: str, schema_data: bytes,
                     channel_metadata: dict[str, str]) -> _Topic:
        # the caller holds the lock (or is the only user, as recover() is)
        self._check_open()
        rb = RecordBuilder()
        schema = self._schemas.get(msg_type)
        if schema is None:
            schema = Schema(id=len(self._schemas) + 1, name=msg_type, encoding=encoding,
                            data=schema_data)
            self._schemas[msg_type] = schema
            schema.write(rb)
        channel = Channel(id=len(self._channels) + 1, topic=topic, message_encoding="cdr",
                          schema_id=schema.id, metadata=dict(channel_metadata))
        self._channels.append(channel)
        channel.write(rb)
        self._submit(("raw", rb.end(), None))
        t = _Topic(channel.id, topic, msg_type, channel_metadata.get("offered_qos_profiles", ""),
                   channel_metadata.get("topic_type_hash", ""))
        self._topics[topic] = t
        return t

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"the bag {self.folder} is closed")

    def add_topic(self, topic: str, msg_type: str, qos: str | None = None) -> None:
        """Declare a topic before writing to it.

        Parameters
        ----------
        topic : str
            Fully qualified topic name (``/train1/vehicles/speed``).
        msg_type : str
            ``pkg/msg/Type``; its definition is read from the installed message package.
        qos : str, optional
            ``offered_qos_profiles`` YAML (see :func:`qos_profiles_yaml`); default reliable,
            volatile, keep_last 10.

        Raises
        ------
        ValueError
            The topic is not fully qualified, or was declared with another type.
        """
        if not topic.startswith("/"):
            raise ValueError(f"topic names must be fully qualified, got {topic!r}")
        _split_type(msg_type)
        with self._lock:
            known = self._topics.get(topic)
            if known is not None:
                if known.msg_type != msg_type:
                    raise ValueError(f"{topic} was declared as {known.msg_type}, not {msg_type}")
                return
            schema = self._schemas.get(msg_type)
            data = schema.data if schema else message_definition(msg_type).encode()
            meta = {"offered_qos_profiles": qos if qos is not None else qos_profiles_yaml(),
                    "topic_type_hash": type_description_hash(msg_type)}
            self._add_channel(topic, msg_type, "ros2msg", data, meta)

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> None:
        """Record one serialized message.

        Parameters
        ----------
        topic : str
            A topic declared with :meth:`add_topic`.
        data : bytes
            ``rclpy.serialization.serialize_message(msg)``, stored unchanged.
        log_time_ns : int
            Receive/record time, simulation time [ns].
        publish_time_ns : int, optional
            Publish time [ns]; defaults to ``log_time_ns``.
        """
        # the hot path of recording: kept to appends (times, counts and bounds of a chunk are
        # worked out once per chunk, on sealing)
        with self._lock:
            t = self._topics.get(topic)
            if t is None or self._closed:
                self._check_open()
                raise KeyError(f"topic {topic} was not declared with add_topic()")
            buf = self._chunk
            index = t.index
            index.append(log_time_ns)
            index.append(len(buf))
            buf += _MESSAGE_HEADER.pack(
                5, 22 + len(data), t.channel_id, t.count & 0xFFFFFFFF, log_time_ns,
                log_time_ns if publish_time_ns is None else publish_time_ns)
            buf += data
            t.count += 1
            if len(buf) >= self.chunk_size or \
                    time.monotonic() - self._last_flush >= self.flush_interval_s:
                self._seal_chunk()

    def _append(self, t: _Topic, data, log: int, pub: int, seq: int) -> None:
        """Like :meth:`write` with an explicit sequence number (used by :func:`recover`)."""
        self._check_open()
        buf = self._chunk
        t.index.append(log)
        t.index.append(len(buf))
        buf += _MESSAGE_HEADER.pack(5, 22 + len(data), t.channel_id, seq & 0xFFFFFFFF, log, pub)
        buf += data
        t.count += 1
        if len(buf) >= self.chunk_size:
            self._seal_chunk()

    def _seal_chunk(self) -> bool:
        """Hand the chunk in memory to the writer thread."""
        self._last_flush = time.monotonic()
        if not self._chunk:
            return False
        indexes = []
        start, end, messages = None, 0, 0
        for t in self._topics.values():
            if t.index:
                times = t.index[0::2]
                lo, hi = min(times), max(times)
                start = lo if start is None else min(start, lo)
                end = max(end, hi)
                messages += len(times)
                indexes.append((t.channel_id, t.index))
                t.index = []
        job = ("chunk", self._chunk, indexes, start, end, messages)
        self._chunk = bytearray()
        self._submit(job)
        return True

    def flush_if_due(self) -> bool:
        """Hand over the chunk in memory if it has waited ``flush_interval_s`` or longer.

        Returns
        -------
        bool
            True if a chunk was handed to the writer thread.
        """
        with self._lock:
            if self._closed or not self._chunk:
                return False
            if time.monotonic() - self._last_flush >= self.flush_interval_s:
                return self._seal_chunk()
            return False

    def seconds_until_flush(self) -> float:
        """Wall time until :meth:`flush_if_due` would hand over the chunk in memory [s].

        Lets an otherwise idle caller wake up in time; ``inf`` when nothing is waiting.

        Returns
        -------
        float
        """
        with self._lock:
            if self._closed or not self._chunk:
                return math.inf
            return max(0.0, self._last_flush + self.flush_interval_s - time.monotonic())

    def flush(self) -> None:
        """Write everything recorded so far to the file and wait until it is there.

        A smaller chunk compresses less well; the periodic flushing needs no call.
        """
        with self._lock:
            if self._closed:
                return
            self._seal_chunk()
            self._queue.join()
            if self._error is not None:
                raise OSError(f"writing {self.path} failed: {self._error}") from self._error

    @property
    def message_count(self) -> int:
        """Messages recorded so far (in memory or on disk)."""
        return sum(t.count for t in list(self._topics.values()))

    @property
    def messages_on_disk(self) -> int:
        """Messages in chunks already written to the file (they survive a kill)."""
        return self._on_disk

    def topic_counts(self) -> dict[str, int]:
        """Messages recorded so far per topic."""
        with self._lock:
            return {name: t.count for name, t in self._topics.items()}

    def close(self) -> None:
        """Finish the file (summary, indexes, footer) and write ``metadata.yaml``.

        Safe to call more than once.
        """
        with self._lock:
            if self._closed:
                return
            try:
                self._seal_chunk()
                self._queue.join()  # chunk indexes complete: they give the time span
                info = self._rosbag2_metadata()
                self._add_metadata("rosbag2", {"serialized_metadata": yaml.safe_dump(
                    info, sort_keys=False, default_flow_style=False)})
                rb = RecordBuilder()
                DataEnd(data_section_crc=0).write(rb)
                self._submit(("raw", rb.end(), None))
                self._queue.join()
                self._submit(("raw", self._summary(), None))
            finally:
                self._closed = True
                self._queue.put(None)
                self._thread.join()
                try:
                    if self._error is None:
                        os.fsync(self._file.fileno())
                finally:
                    self._file.close()
            if self._error is not None:
                raise OSError(f"writing {self.path} failed: {self._error}") from self._error
            text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False,
                                  default_flow_style=False)
            tmp = self.folder / "metadata.yaml.tmp"
            tmp.write_text(text)
            os.replace(tmp, self.folder / "metadata.yaml")

    def _summary(self) -> bytes:
        """Summary section, footer and closing magic (the writer thread is idle)."""
        start = self._pos
        rb = RecordBuilder()
        offsets = []

        def group(opcode, records):
            begin = rb.count
            for r in records:
                r.write(rb)
            if rb.count > begin:
                offsets.append(SummaryOffset(group_opcode=opcode, group_start=start + begin,
                                             group_length=rb.count - begin))

        group(Opcode.SCHEMA, self._schemas.values())
        group(Opcode.CHANNEL, self._channels)
        first, last = self._time_span()
        group(Opcode.STATISTICS, [Statistics(
            message_count=self.message_count, schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=0,
            metadata_count=len(self._metadata_indexes), chunk_count=self._chunk_count,
            message_start_time=first, message_end_time=last,
            channel_message_counts={t.channel_id: t.count for t in self._topics.values()})])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offset_start = start + rb.count
        for o in offsets:
            o.write(rb)
        summary = rb.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, start, offset_start), crc)
        Footer(summary_start=start, summary_offset_start=offset_start,
               summary_crc=crc).write(rb)
        return summary + rb.end() + _MAGIC

    def _time_span(self) -> tuple[int, int]:
        if not self._chunk_indexes:
            return 0, 0
        return (min(c.message_start_time for c in self._chunk_indexes),
                max(c.message_end_time for c in self._chunk_indexes))

    def _rosbag2_metadata(self) -> dict:
        start, end = self._time_span()
        duration = end - start
        count = self.message_count
        topics = [{
            "topic_metadata": {
                "name": t.name, "type": t.msg_type, "serialization_format": "cdr",
                "offered_qos_profiles": parse_qos_profiles(t.qos),
                "type_description_hash": t.type_hash},
            "message_count": t.count} for t in self._topics.values()]
        custom = _json_entries(self.metadata) or None
        return {
            "version": ROSBAG2_VERSION, "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": topics,
            "compression_format": "", "compression_mode": "",
            "relative_file_paths": [self.path.name],
            "files": [{"path": self.path.name,
                       "starting_time": {"nanoseconds_since_epoch": start},
                       "duration": {"nanoseconds": duration},
                       "message_count": count}],
            "custom_data": custom, "ros_distro": ROS_DISTRO}

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# --------------------------------------------------------------------------- reading


def _mcap_files(path) -> list[Path]:
    p = Path(path)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise FileNotFoundError(f"no recording at {p}")
    meta = p / "metadata.yaml"
    if meta.is_file():
        info = (yaml.safe_load(meta.read_text()) or {}).get("rosbag2_bagfile_information", {})
        files = [p / Path(f).name for f in info.get("relative_file_paths", [])]
        if files and all(f.is_file() for f in files):
            return files
    files = sorted(p.glob("*.mcap"))
    if not files:
        raise FileNotFoundError(f"{p} holds no .mcap file")
    return files


@dataclass
class _Scan:
    """State of a linear scan through one file."""

    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    metadata: list = field(default_factory=list)
    chunks: int = 0
    complete: bool = False
    error: str = ""


def _scan_records(path: Path, scan: _Scan, *, strict: bool) -> Iterator[tuple[Channel, Message]]:
    """Yield (channel, message) in file order, one chunk in memory at a time.

    Every record is framed against the file size before it is parsed, so a file cut short
    ends the scan cleanly at its last complete record (``scan.complete`` stays False and
    ``scan.error`` says where). A complete record that does not parse or fails its CRC raises
    when ``strict``, otherwise it ends the scan too.
    """
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        magic = f.read(len(_MAGIC))
        if magic != _MAGIC:
            if len(magic) < len(_MAGIC) and _MAGIC.startswith(magic):
                scan.error = "file ends inside the magic bytes"
                return
            raise McapError(f"{path} is not an MCAP file")
        pos = len(_MAGIC)
        while True:
            head = f.read(9)
            if len(head) < 9:
                scan.error = f"file ends at byte {pos + len(head)} before the footer"
                return
            opcode, length = struct.unpack("<BQ", head)
            if pos + 9 + length > size:
                scan.error = (f"record at byte {pos} (opcode {opcode:#x}) needs {length} bytes, "
                              f"the file ends {size - pos - 9} bytes in")
                return
            body = f.read(length)
            at, pos = pos, pos + 9 + length
            try:
                records = _parse_record(opcode, body)
            except Exception as exc:  # noqa: BLE001 - any decoding failure of a complete record
                scan.error = f"bad record at byte {at} (opcode {opcode:#x}): {exc!r}"
                if strict:
                    raise McapError(f"{path}: {scan.error}") from exc
                return
            if opcode == Opcode.CHUNK:
                scan.chunks += 1
            elif opcode == Opcode.FOOTER:
                if f.read(len(_MAGIC)) != _MAGIC:
                    scan.error = "file ends inside the closing magic bytes"
                    return
                scan.complete = True
                return
            for r in records:
                if isinstance(r, Message):
                    channel = scan.channels.get(r.channel_id)
                    if channel is None:
                        raise McapError(f"{path}: message on unknown channel {r.channel_id}")
                    yield channel, r
                elif isinstance(r, Channel):
                    scan.channels[r.id] = r
                elif isinstance(r, Schema):
                    scan.schemas[r.id] = r
                elif isinstance(r, Metadata):
                    scan.metadata.append(r)


def _parse_record(opcode: int, body: bytes) -> list:
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.CHUNK:
        return breakup_chunk(Chunk.read(stream), validate_crc=True)
    if opcode == Opcode.MESSAGE:
        return [Message.read(stream, len(body))]
    if opcode == Opcode.CHANNEL:
        return [Channel.read(stream)]
    if opcode == Opcode.SCHEMA:
        return [Schema.read(stream)]
    if opcode == Opcode.METADATA:
        return [Metadata.read(stream)]
    return []  # indexes, statistics, summary: rebuilt by writers, not needed to read


def _iter_messages(path, *, strict: bool = True, warn: bool = True):
    for file in _mcap_files(path):
        scan = _Scan()
        for channel, message in _scan_records(file, scan, strict=strict):
            yield scan, channel, message
        if not scan.complete and warn:
            warnings.warn(f"{file} ends early ({scan.error}): the recorder did not finish it; "
                          "read up to its last complete chunk. `ltd-brake recover` rewrites it.",
                          TruncatedBagWarning, stacklevel=3)


def read_bag(path) -> Iterator[tuple[str, str, int, bytes]]:
    """Iterate over a recording's messages in file (recorded) order.

    Streams: one chunk in memory at a time. A file whose recorder was killed is read up to its
    last complete chunk, with a :class:`TruncatedBagWarning`.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.

    Yields
    ------
    tuple
        ``(topic, msg_type, log_time_ns, data)``; ``data`` is the CDR payload as recorded.
    """
    schema_names: dict = {}
    for scan, channel, message in _iter_messages(path):
        key = (id(scan), channel.schema_id)
        name = schema_names.get(key)
        if name is None:
            schema = scan.schemas.get(channel.schema_id)
            name = schema_names[key] = schema.name if schema else ""
        yield channel.topic, name, message.log_time, message.data


@dataclass(frozen=True)
class TopicInfo:
    """One recorded topic.

    Attributes
    ----------
    name : str
    msg_type : str
    message_count : int
    qos_profiles : list of dict
        Parsed ``offered_qos_profiles``.
    """

    name: str
    msg_type: str
    message_count: int
    qos_profiles: list


@dataclass(frozen=True)
class BagInfo:
    """What a recording holds.

    Attributes
    ----------
    files : list of pathlib.Path
    topics : dict of str to TopicInfo
        In channel order.
    metadata : dict
        The run information stored by the recorder (``ltd_brake_ros.run``).
    message_count : int
    start_ns, end_ns : int
        First and last log time [ns].
    complete : bool
        Every file has its summary (False after a crash: see :func:`recover`).
    """

    files: list
    topics: dict
    metadata: dict
    message_count: int
    start_ns: int
    end_ns: int
    complete: bool


def _decode_run_metadata(entries: dict) -> dict:
    out = {}
    for k, v in entries.items():
        try:
            out[k] = json.loads(v)
        except ValueError:
            out[k] = v
    return out


def bag_info(path) -> BagInfo:
    """Topics, counts, times and run metadata of a recording.

    Uses the summary section; a file without one (recorder killed) is scanned.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.

    Returns
    -------
    BagInfo
    """
    from mcap.reader import make_reader

    files = _mcap_files(path)
    topics: dict[str, list] = {}
    metadata: dict = {}
    total, start, end, complete = 0, None, None, True

    def add(channel, schema, count):
        qos = parse_qos_profiles(channel.metadata.get("offered_qos_profiles", ""))
        entry = topics.setdefault(channel.topic, [schema.name if schema else "", 0, qos])
        entry[1] += count

    for file in files:
        summary = None
        with open(file, "rb") as f:
            try:
                reader = make_reader(f)
                summary = reader.get_summary()
                if summary is not None and summary.statistics is not None:
                    for m in reader.iter_metadata():
                        if m.name == RUN_METADATA_NAME:
                            metadata.update(_decode_run_metadata(m.metadata))
            except (McapError, EOFError, struct.error, ValueError):
                summary = None
        if summary is not None and summary.statistics is not None:
            st = summary.statistics
            for cid, channel in summary.channels.items():
                add(channel, summary.schemas.get(channel.schema_id),
                    st.channel_message_counts.get(cid, 0))
            total += st.message_count
            if st.message_count:
                t0, t1 = st.message_start_time, st.message_end_time
                start = t0 if start is None else min(start, t0)
                end = t1 if end is None else max(end, t1)
            continue
        complete = False
        scan = _Scan()
        counts: dict[int, int] = {}
        for channel, message in _scan_records(file, scan, strict=False):
            counts[channel.id] = counts.get(channel.id, 0) + 1
            t = message.log_time
            start = t if start is None else min(start, t)
            end = t if end is None else max(end, t)
        for cid, channel in scan.channels.items():
            add(channel, scan.schemas.get(channel.schema_id), counts.get(cid, 0))
        total += sum(counts.values())
        for m in scan.metadata:
            if m.name == RUN_METADATA_NAME:
                metadata.update(_decode_run_metadata(m.metadata))
    return BagInfo(files, {k: TopicInfo(k, v[0], v[1], v[2]) for k, v in topics.items()},
                   metadata, total, start or 0, end or 0, complete)


# --------------------------------------------------------------------------- recovery


def default_recover_destination(src) -> Path:
    """Where :func:`recover` writes by default: ``<bag>_recovered`` beside the source."""
    p = Path(src)
    base = p.parent / (p.stem if p.is_file() else p.name)
    return base.with_name(base.name + "_recovered")


def recover(src, dst=None) -> dict:
    """Rewrite an unfinished recording (recorder killed) as a complete bag folder.

    Every message of every complete chunk is kept, with its channel, schema, QoS metadata and
    timestamps; the run metadata is copied; summary, indexes and ``metadata.yaml`` are written
    anew. A complete recording is copied unchanged in content.

    Parameters
    ----------
    src : str or path-like
        Bag folder or ``.mcap`` file.
    dst : str or path-like, optional
        New bag folder (must not hold a bag); default ``<src>_recovered`` beside ``src``.

    Returns
    -------
    dict
        ``output`` (folder), ``messages``, ``chunks`` (complete chunks read), ``topics``
        (messages per topic), ``complete`` (the source was already complete), ``stopped_at``
        (why reading ended early, empty when complete).
    """
    files = _mcap_files(src)
    for file in files:  # refuse what is not MCAP before creating anything
        with open(file, "rb") as f:
            head = f.read(len(_MAGIC))
        if not _MAGIC.startswith(head[: len(_MAGIC)]):
            raise McapError(f"{file} is not an MCAP file")
    dst = Path(dst) if dst is not None else default_recover_destination(src)
    writer = BagWriter(dst, flush_interval_s=float("inf"))
    chunks, complete, reasons = 0, True, []

    def copy_run_metadata(scan: _Scan) -> None:
        for m in scan.metadata:
            if m.name == RUN_METADATA_NAME and not writer.metadata:
                writer.metadata = _decode_run_metadata(m.metadata)
                writer._add_metadata(m.name, m.metadata)

    def topic_of(scan: _Scan, channel: Channel) -> _Topic:
        t = writer._topics.get(channel.topic)
        if t is None:
            schema = scan.schemas.get(channel.schema_id)
            t = writer._add_channel(channel.topic, schema.name if schema else "",
                                    schema.encoding if schema else "",
                                    schema.data if schema else b"", channel.metadata)
        return t

    try:
        for file in files:
            scan = _Scan()
            for channel, message in _scan_records(file, scan, strict=False):
                copy_run_metadata(scan)
                writer._append(topic_of(scan, channel), message.data, message.log_time,
                               message.publish_time, message.sequence)
            for channel in scan.channels.values():  # topics declared but never written
                topic_of(scan, channel)
            copy_run_metadata(scan)
            chunks += scan.chunks
            if not scan.complete:
                complete = False
                reasons.append(f"{file.name}: {scan.error}")
    finally:
        writer.close()
    return {"output": str(dst), "messages": writer.message_count, "chunks": chunks,
            "topics": writer.topic_counts(), "complete": complete,
            "stopped_at": "; ".join(reasons)}

"""Writing a recording: :class:`BagWriter`, streaming, crash tolerant (see :mod:`.layout`)."""
from __future__ import annotations

import math
import os
import queue
import struct
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, ChunkIndex, DataEnd, Footer, Header, Metadata, MetadataIndex,
                          Schema, Statistics, SummaryOffset)

from ..outputs import new_file
from .layout import (LIBRARY, MAGIC, ROS_DISTRO, ROSBAG2_VERSION, RUN_METADATA_NAME,
                     decode_run_metadata, encode_run_metadata, mark_unfinished)
from .qos import parse_qos_profiles, qos_profiles_yaml
from .ros_types import message_definition, split_type, type_description_hash

__all__ = ["BagWriter"]

# Message record: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")
# Message Index record: opcode, record length, channel id, byte length of the entries.
_INDEX_HEADER = struct.Struct("<BQHI")
# Chunk record up to the compression name: opcode, record length, start, end, uncompressed
# size, uncompressed CRC, length of the compression name.
_CHUNK_HEADER = struct.Struct("<BQQQQII")


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
        ``<folder-name>_0.mcap``, created exclusively, and until :meth:`close` has written
        ``metadata.yaml`` the folder holds the marker ``UNFINISHED``
        (:func:`~ltd_brake_ros.recording.layout.mark_unfinished`).
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
        run_entries = encode_run_metadata(dict(metadata or {}))  # fails before anything is created
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.path = self.folder / f"{self.folder.name}_0.mcap"
        for existing in (self.path, self.folder / "metadata.yaml"):
            if existing.exists():
                raise FileExistsError(f"{existing} exists: choose a new bag folder")
        self._marker = mark_unfinished(self.folder, self.path.name)
        try:
            self._file = open(self.path, "xb", buffering=0)  # noqa: SIM115 - closed in close()
        except BaseException:
            self._marker.unlink()
            raise
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
        Header(profile="ros2", library=LIBRARY).write(rb)
        self._submit(("raw", MAGIC + rb.end(), None))
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
        # the chunk first: once it is on disk its messages are recoverable, whether or not
        # its message indexes follow (a full disk may stop the file between the two)
        self._emit([head, data])
        self._on_disk += messages
        parts = []
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

    # ----------------------------------------------------------------- calling threads

    def _add_metadata(self, name: str, entries: dict[str, str]) -> None:
        rb = RecordBuilder()
        Metadata(name=name, metadata=dict(entries)).write(rb)
        self._submit(("raw", rb.end(), name))

    def _add_channel(self, topic: str, msg_type: str, encoding: str, schema_data: bytes,
                     channel_metadata: dict[str, str]) -> _Topic:
        # the caller holds the lock
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
        split_type(msg_type)
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

    # ----------------------------------------------------------------- copying a recording

    def copy_run_metadata(self, entries: dict[str, str]) -> None:
        """Store another recording's run information, unless this bag has some already.

        Parameters
        ----------
        entries : dict of str to str
            The entries of its ``ltd_brake_ros.run`` Metadata record (values JSON text).
        """
        if not self.metadata:
            self.metadata = decode_run_metadata(entries)
            self._add_metadata(RUN_METADATA_NAME, entries)

    def copy_channel(self, topic: str, schema_name: str, schema_encoding: str,
                     schema_data: bytes, channel_metadata: dict[str, str]) -> None:
        """Declare a topic exactly as another recording declared it (no-op if declared).

        Parameters
        ----------
        topic : str
        schema_name, schema_encoding : str
            ``pkg/msg/Type`` and ``ros2msg`` as recorded.
        schema_data : bytes
            The recorded message definition.
        channel_metadata : dict of str to str
            The recorded channel metadata (``offered_qos_profiles``, ``topic_type_hash``).
        """
        with self._lock:
            if topic not in self._topics:
                self._add_channel(topic, schema_name, schema_encoding, schema_data,
                                  channel_metadata)

    def copy_message(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int,
                     sequence: int) -> None:
        """Record a message of another recording with its times and sequence number.

        Chunks are sealed by size only (a copy has no wall-time deadline).

        Parameters
        ----------
        topic : str
            A topic declared with :meth:`copy_channel` or :meth:`add_topic`.
        data : bytes
        log_time_ns, publish_time_ns : int
            Recorded times [ns].
        sequence : int
            Recorded sequence number.
        """
        with self._lock:
            self._append(self._topics[topic], data, log_time_ns, publish_time_ns, sequence)

    def _append(self, t: _Topic, data, log: int, pub: int, seq: int) -> None:
        """Like :meth:`write` with an explicit sequence number; the caller holds the lock."""
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
        """Finish the file (summary, indexes, footer), write ``metadata.yaml`` and remove the
        ``UNFINISHED`` marker (which stays when finishing fails).

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
            with new_file(self.folder / "metadata.yaml", encoding="utf-8") as fh:
                fh.write(text)
            self._marker.unlink()  # finished: the folder is what ros2 bag record leaves

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
        return summary + rb.end() + MAGIC

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
        custom = encode_run_metadata(self.metadata) or None
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

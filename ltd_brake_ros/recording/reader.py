"""Reading a recording: messages in log-time order, what it holds, and a file cut short.

Every reader here is bounded and checked, whatever the file holds:

* a file is first *framed*: every record is measured against the file size before anything
  is read, chunk bodies are skipped (only their time span is read), so a file cut short ends
  cleanly at its last complete record and a damaged length field cannot make a reader
  allocate or wait;
* a chunk is decompressed to at most its stated size (itself at most :data:`MAX_CHUNK_BYTES`),
  checked against its CRC and its stated time span;
* messages come out in log-time order (MCAP's log time is authoritative), file order among
  equal times; a file whose chunks overlap in time is merged holding at most
  :data:`MAX_REORDER_BYTES` of messages;
* several files are read as one recording only if they are parts of one run (same run
  information, times that follow on, one type per topic);
* anything else that is wrong raises :class:`BagError`, naming the file (and record or topic)
  and the reason, in one line.
"""
from __future__ import annotations

import heapq
import io
import math
import os
import struct
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Metadata, Schema, Statistics

from ..inputs.schema import InputError, load_yaml
from .layout import MAGIC, RUN_METADATA_NAME, decode_run_metadata, unfinished
from .qos import parse_qos_profiles

__all__ = ["read_bag", "bag_info", "BagInfo", "TopicInfo", "BagError", "TruncatedBagWarning",
           "bag_files", "FileIndex", "index_file", "open_recording", "file_messages",
           "MAX_CHUNK_BYTES", "MAX_REORDER_BYTES"]

#: Largest uncompressed chunk read [bytes] (writers use 1 to 4 MiB).
MAX_CHUNK_BYTES = 256 << 20
#: Most message data held to put overlapping chunks in log-time order [bytes].
MAX_REORDER_BYTES = 256 << 20
# Python objects of one message held for sorting, beyond its payload [bytes] (measured: 337
# bytes for a 16-byte payload with CPython 3.11).
_HELD_OVERHEAD = 320
#: Largest record other than a chunk, attachment or message read whole [bytes].
MAX_RECORD_BYTES = 64 << 20
#: Largest ``metadata.yaml`` read [bytes] (rosbag2 writes a few kB).
MAX_METADATA_YAML_BYTES = 4 << 20

_HINT_ONE_FILE = "give one .mcap file instead of the folder to read it alone"


class BagError(InputError, McapError):
    """A recording that cannot be read as it is: names the file, the record or topic, and why.

    The message is one line: control characters from the file (a topic name, say) are shown
    escaped.

    Parameters
    ----------
    source : str or path-like
        The file (or bag folder) at fault.
    field : str
        Record, topic or ``metadata.yaml`` field; empty for the whole file.
    reason : str
        What is wrong, in words a user can act on.
    """

    def __init__(self, source, field: str, reason: str):
        super().__init__(_printable(str(source)), _printable(field), _printable(reason))


def _printable(text: str) -> str:
    """``text`` with every non-printable character escaped (``\\n``, ``\\x00``)."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class TruncatedBagWarning(UserWarning):
    """A recording ends before its summary (the recorder was killed); see :func:`recover`."""


# --------------------------------------------------------------------------- which files


def _listed_files(folder: Path, meta: Path) -> list[Path]:
    """The files ``metadata.yaml`` names, checked (rosbag2 lists them in order)."""
    if meta.stat().st_size > MAX_METADATA_YAML_BYTES:
        raise BagError(meta, "", f"larger than {MAX_METADATA_YAML_BYTES >> 20} MiB, not rosbag2 "
                                 f"metadata; {_HINT_ONE_FILE}")
    try:
        doc = load_yaml(meta)
    except InputError as exc:
        raise BagError(meta, exc.field, f"{exc.reason}; {_HINT_ONE_FILE}") from None
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        raise BagError(meta, "rosbag2_bagfile_information", "missing or not a mapping: not "
                       f"rosbag2 metadata; {_HINT_ONE_FILE}")
    names = info.get("relative_file_paths")
    if not isinstance(names, list) or not names or \
            not all(isinstance(n, str) and Path(n).name for n in names):
        raise BagError(meta, "rosbag2_bagfile_information.relative_file_paths",
                       f"must be a list of file names, got {names!r:.80}; {_HINT_ONE_FILE}")
    files = [folder / Path(n).name for n in names]
    for n, f in zip(names, files):
        if not f.is_file():
            raise BagError(meta, "rosbag2_bagfile_information.relative_file_paths",
                           f"names {n!r}, which is not a file in {folder}; {_HINT_ONE_FILE}")
    if len(set(files)) < len(files):
        raise BagError(meta, "rosbag2_bagfile_information.relative_file_paths",
                       f"names a file twice; {_HINT_ONE_FILE}")
    return files


def bag_files(path) -> list[Path]:
    """The MCAP files of a recording, in the order given by its ``metadata.yaml``.

    Parameters
    ----------
    path : str or path-like
        Bag folder (its ``metadata.yaml`` names the files; without one, every ``*.mcap`` in
        it, sorted by name) or one ``.mcap`` file.

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    BagError
        Nothing at ``path``, a folder without an ``.mcap`` file, or a ``metadata.yaml`` that is
        not rosbag2 metadata naming files of the folder.
    """
    p = Path(path)
    try:
        if p.is_file():
            return [p]
        if not p.is_dir():
            raise BagError(p, "", "no recording at this path: give a bag folder or an .mcap file")
        meta = p / "metadata.yaml"
        if meta.exists():
            return _listed_files(p, meta)
        files = sorted(f for f in p.glob("*.mcap") if f.is_file())
    except OSError as exc:
        raise BagError(exc.filename or p, "", f"cannot read: {exc.strerror}") from None
    if not files:
        raise BagError(p, "", "holds no .mcap file")
    return files


# --------------------------------------------------------------------------- framing a file


@dataclass(frozen=True)
class _Span:
    """A chunk, or a message outside chunks: where it is and its stated log-time span [ns]."""

    offset: int
    length: int
    start: int
    end: int
    chunk: bool


@dataclass
class FileIndex:
    """What framing one file found (:func:`index_file`).

    Attributes
    ----------
    path : pathlib.Path
    schemas, channels : dict of int to mcap record
    run_metadata : dict or None
        The run information (``ltd_brake_ros.run``), decoded.
    run_entries : dict of str to str or None
        The same as stored (each value JSON text).
    spans : list
        Chunks and loose messages in file order, with their stated time spans.
    statistics : mcap.records.Statistics or None
        Only when the summary section passes its CRC check.
    complete : bool
        The file has its footer and closing magic bytes.
    error : str
        Why the file ends early (empty when complete).
    """

    path: Path
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    run_metadata: dict | None = None
    run_entries: dict | None = None
    spans: list = field(default_factory=list)
    statistics: Statistics | None = None
    complete: bool = False
    error: str = ""
    _types: dict = field(default_factory=dict, repr=False)  # topic -> message type

    @property
    def chunk_count(self) -> int:
        """Complete chunks in the file."""
        return sum(s.chunk for s in self.spans)

    @property
    def time_span(self) -> tuple[int, int] | None:
        """First and last stated log time [ns], None without messages."""
        if not self.spans:
            return None
        return min(s.start for s in self.spans), max(s.end for s in self.spans)

    def _add_schema(self, s: Schema) -> None:
        known = self.schemas.setdefault(s.id, s)
        if known != s:
            raise ValueError(f"schema {s.id} is defined twice, differently")

    def _add_channel(self, c: Channel) -> None:
        known = self.channels.setdefault(c.id, c)
        if known != c:
            raise ValueError(f"channel {c.id} is defined twice, differently")
        if known is c:  # new: what readers and copies parse must parse
            try:
                parse_qos_profiles(c.metadata.get("offered_qos_profiles", ""))
            except ValueError as exc:
                del self.channels[c.id]
                raise ValueError(f"channel {c.id} ({c.topic}): {exc}") from None
        schema = self.schemas.get(c.schema_id)
        if schema is not None:
            other = self._types.setdefault(c.topic, schema.name)
            if other != schema.name:
                raise BagError(self.path, c.topic, f"recorded with two message types, {other} "
                                                   f"and {schema.name}: not one recording")

    def _add_metadata(self, m: Metadata) -> None:
        if m.name != RUN_METADATA_NAME:
            return
        run = decode_run_metadata(m.metadata)
        if self.run_metadata is not None and run != self.run_metadata:
            raise BagError(self.path, "", f"holds the information of two runs (two different "
                                          f"{RUN_METADATA_NAME} records): it is not one "
                                          f"recording ({_difference(self.run_metadata, run)})")
        self.run_metadata, self.run_entries = run, dict(m.metadata)

    def topic(self, channel_id: int) -> tuple[Channel, str]:
        """A channel and its message type name.

        Raises
        ------
        BagError
            The channel, or the schema it names, is not defined in the file.
        """
        channel = self.channels.get(channel_id)
        if channel is None:
            raise BagError(self.path, "", f"a message is on channel {channel_id}, which the file "
                                          "does not define (the file is damaged)")
        if channel.schema_id == 0:
            return channel, ""
        schema = self.schemas.get(channel.schema_id)
        if schema is None:
            raise BagError(self.path, channel.topic, f"its channel names schema "
                           f"{channel.schema_id}, which the file does not define")
        return channel, schema.name


_HEAD = struct.Struct("<BQ")
_U64x2 = struct.Struct("<QQ")
_MSG = struct.Struct("<HIQQ")
_FOOTER = struct.Struct("<QQI")
_SMALL = {Opcode.HEADER, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.METADATA, Opcode.STATISTICS,
          Opcode.FOOTER}


def _parse_small(opcode: int, body: bytes, index: FileIndex) -> None:
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.SCHEMA:
        index._add_schema(Schema.read(stream))
    elif opcode == Opcode.CHANNEL:
        index._add_channel(Channel.read(stream))
    elif opcode == Opcode.METADATA:
        index._add_metadata(Metadata.read(stream))


def index_file(path, *, strict: bool = True) -> FileIndex:
    """Frame one MCAP file: its schemas, channels, run information, chunks and state.

    Chunk bodies are not read (only their stated time spans), so this costs one small read per
    record.

    Parameters
    ----------
    path : str or path-like
    strict : bool, optional
        A complete record that does not parse raises :class:`BagError`; otherwise the file is
        treated as ending there (``error`` says why), as recovery wants.

    Returns
    -------
    FileIndex

    Raises
    ------
    BagError
        Not an MCAP file, unreadable, or (``strict``) damaged.
    """
    index = FileIndex(Path(path))
    try:
        with open(path, "rb") as f:
            _frame(f, os.fstat(f.fileno()).st_size, index, strict)
    except OSError as exc:
        raise BagError(path, "", f"cannot read: {exc.strerror or exc}") from None
    return index


def _frame(f, size: int, index: FileIndex, strict: bool) -> None:
    path = index.path
    magic = f.read(len(MAGIC))
    if magic != MAGIC:
        if len(magic) < len(MAGIC) and MAGIC.startswith(magic):
            index.error = "file ends inside the magic bytes"
            return
        raise BagError(path, "", "not an MCAP file (it does not start with the MCAP magic bytes)")
    pos = len(MAGIC)
    stats_at = None
    while True:
        head = f.read(9)
        if len(head) < 9:
            index.error = f"file ends at byte {pos + len(head)} before the footer"
            return
        opcode, length = _HEAD.unpack(head)
        if pos + 9 + length > size:
            index.error = (f"record at byte {pos} (opcode {opcode:#x}) needs {length} bytes, "
                           f"the file ends {size - pos - 9} bytes in")
            return
        if pos == len(MAGIC) and opcode != Opcode.HEADER:
            raise BagError(path, "", f"not an MCAP file (its first record has opcode {opcode:#x}, "
                                     "not a header)")
        at, pos = pos, pos + 9 + length
        try:
            if opcode in (Opcode.CHUNK, Opcode.MESSAGE):
                need = 16 if opcode == Opcode.CHUNK else _MSG.size
                if length < need:
                    raise ValueError(f"{length} bytes is too short for its kind")
                fields = f.read(need)
                if opcode == Opcode.CHUNK:
                    start, end = _U64x2.unpack(fields)
                else:
                    start = end = _MSG.unpack(fields)[2]
                if start > end:
                    raise ValueError(f"its time span ends ({end} ns) before it starts ({start} ns)")
                index.spans.append(_Span(at, length, start, end, opcode == Opcode.CHUNK))
                f.seek(pos)
            elif opcode in _SMALL:
                if length > MAX_RECORD_BYTES:
                    raise ValueError(f"{length} bytes is too long for its kind")
                body = f.read(length)
                if opcode == Opcode.FOOTER:
                    if f.read(len(MAGIC)) != MAGIC:
                        index.error = "file ends inside the closing magic bytes"
                        return
                    _check_summary(f, at, body, stats_at, index)
                    index.complete = True
                    return
                if opcode == Opcode.STATISTICS:  # a summary: unused unless its CRC checks
                    stats_at, index.statistics = at, _statistics(body)
                else:
                    _parse_small(opcode, body, index)
            else:  # indexes, attachments, summary offsets: rebuilt by writers, not needed
                f.seek(pos)
        except BagError:
            raise
        except (ValueError, struct.error, McapError, EOFError, UnicodeDecodeError) as exc:
            reason = f"bad record at byte {at} (opcode {opcode:#x}): {exc}"
            if strict:
                raise BagError(path, "", f"{reason} (the file is damaged)") from None
            index.error = reason
            return


def _statistics(body: bytes) -> Statistics | None:
    try:
        return Statistics.read(ReadDataStream(io.BytesIO(body)))
    except (struct.error, McapError, EOFError):
        return None


def _check_summary(f, footer_at: int, body: bytes, stats_at: int | None,
                   index: FileIndex) -> None:
    """Keep the statistics only if they lie in a summary section that passes its CRC check."""
    if stats_at is None or index.statistics is None or len(body) < _FOOTER.size:
        index.statistics = None
        return
    summary_start, offset_start, crc = _FOOTER.unpack_from(body)
    ok = 0 < summary_start <= stats_at < footer_at
    if ok and crc:
        f.seek(summary_start)
        value, left = 0, footer_at - summary_start
        while left > 0:
            block = f.read(min(left, 1 << 20))
            if not block:
                break
            value, left = zlib.crc32(block, value), left - len(block)
        ok = zlib.crc32(_HEAD.pack(Opcode.FOOTER, len(body)) + body[:16], value) == crc
    if not ok:
        index.statistics = None


# --------------------------------------------------------------------------- decoding chunks


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """``data`` decompressed to at most ``size`` + 1 bytes (a longer result is caught later)."""
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        try:
            return zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data)).read(size + 1)
        except zstandard.ZstdError as exc:
            raise ValueError(f"its zstd data does not decompress ({exc})") from None
    if compression == "lz4":
        import lz4.frame

        try:
            return lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
        except RuntimeError as exc:  # what lz4.frame raises for bad data
            raise ValueError(f"its lz4 data does not decompress ({exc})") from None
    raise ValueError(f"unknown chunk compression {compression!r}")


def _chunk_records(body: bytes) -> bytes:
    """The uncompressed records of a chunk, checked against its stated size and CRC."""
    if len(body) < 32:
        raise ValueError("too short for a chunk")
    size, crc, name_len = struct.unpack_from("<QII", body, 16)
    pos = 32 + name_len
    if pos + 8 > len(body):
        raise ValueError("its compression name runs past its end")
    compression = body[32:pos].decode()
    (data_len,) = struct.unpack_from("<Q", body, pos)
    pos += 8
    if pos + data_len > len(body):
        raise ValueError("its records run past its end")
    if size > MAX_CHUNK_BYTES:
        raise ValueError(f"it states {size} bytes uncompressed, more than the "
                         f"{MAX_CHUNK_BYTES >> 20} MiB a reader accepts")
    records = _decompress(compression, body[pos:pos + data_len], size)
    if len(records) != size:
        raise ValueError(f"it holds {len(records)} bytes uncompressed, not the {size} it states")
    if crc and zlib.crc32(records) != crc:
        raise ValueError("it fails its CRC check")
    return records


def _decode(f, span: _Span, index: FileIndex) -> list:
    """Messages of a chunk (or a loose message) in file order: ``(log, pub, seq, ch, data)``.

    Schemas and channels defined inside the chunk are added to ``index``.
    """
    f.seek(span.offset + 9)
    body = f.read(span.length)
    if len(body) < span.length:
        raise ValueError("the file got shorter while it was read")
    if not span.chunk:
        channel, seq, log, pub = _MSG.unpack_from(body)
        return [(log, pub, seq, channel, body[_MSG.size:])]
    records = _chunk_records(body)
    out = []
    pos, n = 0, len(records)
    while pos < n:
        if pos + 9 > n:
            raise ValueError("its last record is cut")
        opcode, length = _HEAD.unpack_from(records, pos)
        start, pos = pos + 9, pos + 9 + length
        if pos > n:
            raise ValueError(f"a record inside it needs {length} bytes, it has {n - start}")
        if opcode == Opcode.MESSAGE:
            if length < _MSG.size:
                raise ValueError("a message inside it is too short")
            channel, seq, log, pub = _MSG.unpack_from(records, start)
            if not span.start <= log <= span.end:
                raise ValueError(f"a message at {log} ns lies outside the time span it states "
                                 f"({span.start} to {span.end} ns)")
            out.append((log, pub, seq, channel, records[start + _MSG.size:pos]))
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            _parse_small(opcode, records[start:pos], index)
    return out


def file_messages(index: FileIndex, *, strict: bool = True,
                  ordered: bool = True) -> Iterator[tuple[Channel, str, int, int, int, bytes]]:
    """Messages of one framed file.

    Parameters
    ----------
    index : FileIndex
        From :func:`index_file`.
    strict : bool, optional
        A damaged chunk raises :class:`BagError`; otherwise reading ends there and
        ``index.error`` says why (recovery).
    ordered : bool, optional
        Log-time order (file order among equal times); False gives file order.

    Yields
    ------
    tuple
        ``(channel, msg_type, log_time_ns, publish_time_ns, sequence, data)``.

    Raises
    ------
    BagError
        A damaged chunk (``strict``), a message on an undefined channel, or chunks that
        overlap in time by more than :data:`MAX_REORDER_BYTES` of messages.
    """
    spans = index.spans
    # earliest stated start of every span from k on: what may still come before
    later = [math.inf] * (len(spans) + 1)
    for k in range(len(spans) - 1, -1, -1):
        later[k] = min(spans[k].start, later[k + 1])
    heap: list = []  # (log time, file order, message)
    held = pushed = 0  # bytes held, messages pushed
    types: dict = {}

    def emit(m):
        entry = types.get(m[3])
        if entry is None:
            entry = types[m[3]] = index.topic(m[3])
        return entry[0], entry[1], m[0], m[1], m[2], m[4]

    try:
        f = open(index.path, "rb")  # noqa: SIM115 - closed in finally
    except OSError as exc:
        raise BagError(index.path, "", f"cannot read: {exc.strerror or exc}") from None
    try:
        for k, span in enumerate(spans):
            try:
                msgs = _decode(f, span, index)
            except OSError as exc:
                raise BagError(index.path, "", f"cannot read: {exc.strerror or exc}") from None
            except BagError:
                raise
            except (ValueError, struct.error, McapError, EOFError, UnicodeDecodeError) as exc:
                what = "chunk" if span.chunk else "message"
                reason = f"bad {what} at byte {span.offset}: {exc}"
                if strict:
                    raise BagError(index.path, "", f"{reason} (the file is damaged; "
                                   "`ltd-brake recover` keeps what comes before it)") from None
                index.error = reason
                index.spans = spans[:k]
                return
            if not ordered:
                for m in msgs:
                    yield emit(m)
                continue
            bound = later[k + 1]
            if not heap and all(msgs[i][0] <= msgs[i + 1][0] for i in range(len(msgs) - 1)) \
                    and (not msgs or msgs[-1][0] <= bound):
                for m in msgs:  # the usual case: already in order
                    yield emit(m)
                continue
            for m in msgs:
                pushed += 1
                heapq.heappush(heap, (m[0], pushed, m))
                held += len(m[4]) + _HELD_OVERHEAD
            if held > MAX_REORDER_BYTES:
                raise BagError(index.path, "", "messages out of log-time order across more than "
                               f"{MAX_REORDER_BYTES >> 20} MiB of the file: too far apart to "
                               "sort while reading")
            while heap and heap[0][0] <= bound:
                m = heapq.heappop(heap)[2]
                held -= len(m[4]) + _HELD_OVERHEAD
                yield emit(m)
    finally:
        f.close()


# --------------------------------------------------------------------------- a recording


def _difference(a, b, where: str = "") -> str:
    """The first place two run informations differ, in a few words."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            if a.get(k) != b.get(k):
                return _difference(a.get(k), b.get(k), f"{where}.{k}" if where else str(k))
        return where
    return f"{where or 'run information'}: {a!r:.60} vs {b!r:.60}"


def _fmt_span(span) -> str:
    return f"t = {span[0] * 1e-9:.3f} to {span[1] * 1e-9:.3f} s"


def open_recording(path, *, strict: bool = True) -> list[FileIndex]:
    """Frame every file of a recording and check that they are parts of one run.

    Several files are one recording only when they hold the same run information (or none),
    declare each topic with one type, and follow on in time (each starts at or after the end
    of the one before). Files found without ``metadata.yaml`` are put in time order.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.
    strict : bool, optional
        See :func:`index_file`.

    Returns
    -------
    list of FileIndex
        In reading order.

    Raises
    ------
    BagError
        A file cannot be read, or the files are not parts of one run (the message names two
        of them and says how to read one).
    """
    files = bag_files(path)
    indexes = [index_file(f, strict=strict) for f in files]
    if len(indexes) < 2:
        return indexes
    p = Path(path)
    listed = (p / "metadata.yaml").exists()
    if not listed:
        indexes.sort(key=lambda i: (i.time_span or (math.inf, math.inf), i.path.name))
    where = f"metadata.yaml lists {len(files)} files" if listed else \
        f"{len(files)} .mcap files and no metadata.yaml"

    def refuse(a: FileIndex, b: FileIndex, why: str):
        raise BagError(p, "", f"{where}, and they are not parts of one run: {a.path.name} and "
                              f"{b.path.name} {why}; {_HINT_ONE_FILE}")

    first = indexes[0]
    types: dict[str, tuple[str, FileIndex]] = {}
    previous = None
    for ix in indexes:
        if ix.run_metadata != first.run_metadata:
            refuse(first, ix, "hold different run information ("
                   f"{_difference(first.run_metadata or {}, ix.run_metadata or {})})")
        for cid in ix.channels:
            channel, msg_type = ix.topic(cid)
            known = types.setdefault(channel.topic, (msg_type, ix))
            if known[0] != msg_type:
                refuse(known[1], ix, f"record {channel.topic} as {known[0] or 'no type'} and "
                                     f"{msg_type or 'no type'}")
        span = ix.time_span
        if span is not None:
            if previous is not None and span[0] < previous[1][1]:
                refuse(previous[0], ix, f"overlap in time ({_fmt_span(previous[1])} and "
                                        f"{_fmt_span(span)})")
            previous = (ix, span)
    return indexes


def _warn_truncated(index: FileIndex) -> None:
    warnings.warn(f"{index.path} ends early ({index.error}): the recorder did not finish it; "
                  "read up to its last complete chunk. `ltd-brake recover` rewrites it.",
                  TruncatedBagWarning, stacklevel=4)


def read_bag(path) -> Iterator[tuple[str, str, int, bytes]]:
    """Iterate over a recording's messages in log-time order.

    Streams: a chunk at a time, more only where chunks overlap in time. A file whose recorder
    was killed is read up to its last complete chunk, with a :class:`TruncatedBagWarning`.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.

    Yields
    ------
    tuple
        ``(topic, msg_type, log_time_ns, data)``; ``data`` is the CDR payload as recorded.

    Raises
    ------
    BagError
        The recording cannot be read as it is (see the module notes).
    """
    indexes = open_recording(path)
    for index in indexes:
        for channel, msg_type, log, _pub, _seq, data in file_messages(index):
            yield channel.topic, msg_type, log, data
        if not index.complete:
            _warn_truncated(index)
    left = unfinished(path)
    if left and all(ix.complete for ix in indexes):  # closed, but metadata.yaml never came
        warnings.warn(left, TruncatedBagWarning, stacklevel=2)


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
        Every file has its summary and the folder is not marked unfinished (False after a
        crash: see :func:`recover`).
    unfinished : str
        Why the folder is marked unfinished (:func:`~.layout.unfinished`), else empty.
    """

    files: list
    topics: dict
    metadata: dict
    message_count: int
    start_ns: int
    end_ns: int
    complete: bool
    unfinished: str = ""


def bag_info(path) -> BagInfo:
    """Topics, counts, times and run metadata of a recording.

    Counts come from the summary section when it passes its CRC check; a file without one
    (recorder killed) is read.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.

    Returns
    -------
    BagInfo

    Raises
    ------
    BagError
        The recording cannot be read as it is (see the module notes).
    """
    indexes = open_recording(path)
    topics: dict[str, list] = {}
    total, start, end = 0, None, None
    for ix in indexes:
        st = ix.statistics
        # the statistics only when they agree with themselves and name the file's channels
        # (a damaged summary of an unfinished file may not)
        if st is not None and st.message_count == sum(st.channel_message_counts.values()) \
                and set(st.channel_message_counts) <= set(ix.channels):
            counts = st.channel_message_counts
            if st.message_count:
                start = st.message_start_time if start is None else min(start,
                                                                         st.message_start_time)
                end = st.message_end_time if end is None else max(end, st.message_end_time)
        else:
            counts = {}
            for channel, _type, log, *_rest in file_messages(ix, ordered=False):
                counts[channel.id] = counts.get(channel.id, 0) + 1
                start = log if start is None else min(start, log)
                end = log if end is None else max(end, log)
        for cid in ix.channels:
            channel, msg_type = ix.topic(cid)
            qos = parse_qos_profiles(channel.metadata.get("offered_qos_profiles", ""))
            entry = topics.setdefault(channel.topic, [msg_type, 0, qos])
            entry[1] += counts.get(cid, 0)
        total += sum(counts.get(cid, 0) for cid in ix.channels)
    left = unfinished(path)
    return BagInfo([ix.path for ix in indexes],
                   {k: TopicInfo(k, v[0], v[1], v[2]) for k, v in topics.items()},
                   dict(indexes[0].run_metadata or {}), total, start or 0, end or 0,
                   all(ix.complete for ix in indexes) and not left, left)

"""Reading a recording: messages in recorded order, what it holds, and a file cut short."""
from __future__ import annotations

import io
import os
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk

from .layout import MAGIC, RUN_METADATA_NAME, decode_run_metadata
from .qos import parse_qos_profiles

__all__ = ["read_bag", "bag_info", "BagInfo", "TopicInfo", "TruncatedBagWarning",
           "bag_files", "FileScan", "scan_records"]


class TruncatedBagWarning(UserWarning):
    """A recording ends before its summary (the recorder was killed); see :func:`recover`."""


def bag_files(path) -> list[Path]:
    """The MCAP files of a recording, in order.

    Parameters
    ----------
    path : str or path-like
        Bag folder (its ``metadata.yaml`` names the files; else every ``*.mcap`` in it) or
        one ``.mcap`` file.

    Returns
    -------
    list of pathlib.Path

    Raises
    ------
    FileNotFoundError
        Nothing at ``path``, or a folder without an ``.mcap`` file.
    """
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
class FileScan:
    """State of a linear scan through one file."""

    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    metadata: list = field(default_factory=list)
    chunks: int = 0
    complete: bool = False
    error: str = ""


def scan_records(path: Path, scan: FileScan, *, strict: bool) -> Iterator[tuple[Channel, Message]]:
    """Yield (channel, message) in file order, one chunk in memory at a time.

    Every record is framed against the file size before it is parsed, so a file cut short
    ends the scan cleanly at its last complete record (``scan.complete`` stays False and
    ``scan.error`` says where). A complete record that does not parse or fails its CRC raises
    when ``strict``, otherwise it ends the scan too.
    """
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        magic = f.read(len(MAGIC))
        if magic != MAGIC:
            if len(magic) < len(MAGIC) and MAGIC.startswith(magic):
                scan.error = "file ends inside the magic bytes"
                return
            raise McapError(f"{path} is not an MCAP file")
        pos = len(MAGIC)
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
                if f.read(len(MAGIC)) != MAGIC:
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


def _iter_messages(path):
    for file in bag_files(path):
        scan = FileScan()
        for channel, message in scan_records(file, scan, strict=True):
            yield scan, channel, message
        if not scan.complete:
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

    files = bag_files(path)
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
                            metadata.update(decode_run_metadata(m.metadata))
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
        scan = FileScan()
        counts: dict[int, int] = {}
        for channel, message in scan_records(file, scan, strict=False):
            counts[channel.id] = counts.get(channel.id, 0) + 1
            t = message.log_time
            start = t if start is None else min(start, t)
            end = t if end is None else max(end, t)
        for cid, channel in scan.channels.items():
            add(channel, scan.schemas.get(channel.schema_id), counts.get(cid, 0))
        total += sum(counts.values())
        for m in scan.metadata:
            if m.name == RUN_METADATA_NAME:
                metadata.update(decode_run_metadata(m.metadata))
    return BagInfo(files, {k: TopicInfo(k, v[0], v[1], v[2]) for k, v in topics.items()},
                   metadata, total, start or 0, end or 0, complete)

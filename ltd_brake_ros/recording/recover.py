"""Recovery: a recording whose recorder was killed rewritten as a complete one."""
from __future__ import annotations

from pathlib import Path

from mcap.exceptions import McapError

from .layout import MAGIC, RUN_METADATA_NAME
from .reader import FileScan, bag_files, scan_records
from .writer import BagWriter

__all__ = ["recover", "default_recover_destination"]


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
    files = bag_files(src)
    for file in files:  # refuse what is not MCAP before creating anything
        with open(file, "rb") as f:
            head = f.read(len(MAGIC))
        if not MAGIC.startswith(head[: len(MAGIC)]):
            raise McapError(f"{file} is not an MCAP file")
    dst = Path(dst) if dst is not None else default_recover_destination(src)
    writer = BagWriter(dst, flush_interval_s=float("inf"))
    chunks, complete, reasons = 0, True, []
    copied: set[str] = set()  # topics declared in the new bag

    def copy_run_metadata(scan: FileScan) -> None:
        for m in scan.metadata:
            if m.name == RUN_METADATA_NAME:
                writer.copy_run_metadata(m.metadata)

    def copy_channel(scan: FileScan, channel) -> None:
        if channel.topic not in copied:
            schema = scan.schemas.get(channel.schema_id)
            writer.copy_channel(channel.topic, schema.name if schema else "",
                                schema.encoding if schema else "",
                                schema.data if schema else b"", channel.metadata)
            copied.add(channel.topic)

    try:
        for file in files:
            scan = FileScan()
            for channel, message in scan_records(file, scan, strict=False):
                copy_run_metadata(scan)
                copy_channel(scan, channel)
                writer.copy_message(channel.topic, message.data, message.log_time,
                                    message.publish_time, message.sequence)
            for channel in scan.channels.values():  # topics declared but never written
                copy_channel(scan, channel)
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

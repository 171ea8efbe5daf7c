"""Recovery: a recording whose recorder was killed rewritten as a complete one."""
from __future__ import annotations

import contextlib
from pathlib import Path

from .layout import UNFINISHED_NAME, unfinished
from .reader import BagError, file_messages, open_recording
from .writer import BagWriter

__all__ = ["recover", "default_recover_destination"]


def default_recover_destination(src) -> Path:
    """Where :func:`recover` writes by default: ``<bag>_recovered`` beside the source."""
    p = Path(src)
    base = p.parent / (p.stem if p.is_file() else p.name)
    return base.with_name(base.name + "_recovered")


def recover(src, dst=None) -> dict:
    """Rewrite an unfinished recording (recorder killed) as a complete bag folder.

    Every message of every complete chunk is kept, in file order, with its channel, schema,
    QoS metadata and timestamps; the run metadata is copied; summary, indexes and
    ``metadata.yaml`` are written anew. A complete recording is copied unchanged in content.
    Reading ends at the first damaged record. If writing fails (a full disk), what was
    written is removed: no half-written bag is left behind.

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
        (messages per topic), ``complete`` (the source was already complete, and its folder
        not marked unfinished), ``stopped_at`` (why reading ended early or the source is
        unfinished, empty when complete).

    Raises
    ------
    BagError
        The source is not MCAP, or not one run (checked before anything is created).
    FileExistsError
        ``dst`` holds a bag.
    OSError
        Writing failed.
    """
    indexes = open_recording(src, strict=False)
    left = unfinished(src)
    dst = Path(dst) if dst is not None else default_recover_destination(src)
    existed = dst.exists()
    writer = BagWriter(dst, flush_interval_s=float("inf"))
    chunks, complete, reasons = 0, True, []
    copied: dict[str, str] = {}  # topics declared in the new bag, with their types

    def copy_channel(ix, channel, msg_type: str) -> None:
        known = copied.get(channel.topic)
        if known is None:
            schema = ix.schemas.get(channel.schema_id)
            writer.copy_channel(channel.topic, msg_type, schema.encoding if schema else "",
                                schema.data if schema else b"", channel.metadata)
            copied[channel.topic] = msg_type
        elif known != msg_type:
            raise BagError(ix.path, channel.topic, f"recorded with two message types, {known} "
                                                   f"and {msg_type}: not one recording")

    try:
        for ix in indexes:
            if ix.run_entries:
                writer.copy_run_metadata(ix.run_entries)
            for channel, msg_type, log, pub, seq, data in file_messages(ix, strict=False,
                                                                        ordered=False):
                copy_channel(ix, channel, msg_type)
                writer.copy_message(channel.topic, data, log, pub, seq)
            for cid, channel in ix.channels.items():  # topics declared but never written
                copy_channel(ix, channel, ix.topic(cid)[1])
            chunks += ix.chunk_count
            if not ix.complete or ix.error:
                complete = False
                reasons.append(f"{ix.path.name}: {ix.error}")
        if left:
            complete = False
            reasons.append(left)
        writer.close()
    except BaseException:
        with contextlib.suppress(Exception):
            writer.close()
        for f in (writer.path, dst / "metadata.yaml", dst / UNFINISHED_NAME):
            with contextlib.suppress(OSError):
                f.unlink()
        if not existed:
            with contextlib.suppress(OSError):
                dst.rmdir()
        raise
    return {"output": str(dst), "messages": writer.message_count, "chunks": chunks,
            "topics": writer.topic_counts(), "complete": complete,
            "stopped_at": "; ".join(reasons)}

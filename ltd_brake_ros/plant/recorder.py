"""The recorder's lifecycle: one bag per run, flushed while idle, a write error never fatal.

The plant opens the bag at start-up, writes every message it publishes or receives, flushes
due chunks between chunks and while idle, and closes the bag when the run ends (shutdown or a
simulator failure). ``~/reset`` starts the next run in ``<base>_2``, ``<base>_3``, ... A write
error (a full disk) stops the recording, not the plant: the chunks already on disk stay
readable (``ltd-brake recover`` makes the file a complete bag).
"""
from __future__ import annotations

import math
from typing import Any, Callable, Sequence

from ..recording.bag import BagWriter
from .settings import StartupError


class Recorder:
    """Records the plant's messages to an MCAP bag folder, one folder per run.

    Parameters
    ----------
    base : str
        Folder of the first run; later runs get ``_2``, ``_3``, ... appended.
    topics : sequence of (str, str, str)
        Every topic the plant may write: fully qualified name, message type
        (``std_msgs/msg/Bool``) and ``offered_qos_profiles`` text.
    log : logger
        Has ``info`` and ``error`` (an rclpy or :mod:`logging` logger).
    metadata : dict, optional
        Run information stored in each bag.
    writer : callable, optional
        ``writer(folder, metadata=...)`` -> an object with the :class:`BagWriter` methods used
        here (tests pass a failing one).
    """

    def __init__(self, base: str, topics: Sequence[tuple[str, str, str]], log, *,
                 metadata: dict | None = None, writer: Callable[..., Any] = BagWriter):
        self.base = base
        self._topics = list(topics)
        self._log = log
        self._metadata = metadata
        self._make_writer = writer
        self._writer = None
        self._runs = 0
        #: Why the recording stopped (None while it works or once a run's bag was finished).
        self.error: str | None = None

    @property
    def active(self) -> bool:
        """True while a bag is open for writing."""
        return self._writer is not None

    @property
    def state(self) -> str:
        """The open bag's folder, else ``failed`` or ``finished``."""
        if self._writer is not None:
            return str(self._writer.folder)
        return "failed" if self.error else "finished"

    def open(self) -> None:
        """Open the next run's bag.

        Raises
        ------
        StartupError
            The folder cannot be written (parameter ``record_dir``).
        """
        self._runs += 1
        folder = self.base if self._runs == 1 else f"{self.base}_{self._runs}"
        rec = None
        try:
            rec = self._make_writer(folder, metadata=self._metadata)
            for topic, msg_type, qos in self._topics:
                rec.add_topic(topic, msg_type, qos)
        except BaseException as exc:
            # a half-opened bag (disk full, SIGINT at start-up) is closed: no writer thread
            # or open file is left behind, and the folder holds no unfinished file if it can
            # be helped
            if rec is not None:
                try:
                    rec.close()
                except OSError:
                    pass
            if isinstance(exc, (OSError, ValueError)):
                raise StartupError("record_dir", f"cannot record to {folder}: {exc}") from None
            raise
        self._writer = rec
        self.error = None
        self._log.info(f"recording to {rec.folder}")

    def reopen(self) -> None:
        """Finish the current run's bag (if still open) and start the next one.

        A bag that cannot be opened (the disk is still full) leaves the plant running without
        recording; :attr:`error` says why.
        """
        self.close()
        try:
            self.open()
        except StartupError as exc:
            self.error = exc.reason
            self._log.error(f"{exc}; the plant runs on without recording")

    def write(self, topic: str, data: bytes, stamp_ns: int) -> None:
        """Record serialized ``data`` on ``topic`` at simulated time ``stamp_ns`` [ns]."""
        if self._writer is None:
            return
        try:
            self._writer.write(topic, data, stamp_ns)
        except OSError as exc:
            self._failed(exc)

    def flush_if_due(self) -> None:
        """Hand the open chunk to the writer thread when the flush interval is over."""
        if self._writer is not None:
            try:
                self._writer.flush_if_due()
            except OSError as exc:
                self._failed(exc)

    def seconds_until_flush(self) -> float:
        """Wall time until the next flush is due [s] (``inf`` with no bag open)."""
        return self._writer.seconds_until_flush() if self._writer is not None else math.inf

    def close(self) -> None:
        """Finish the open bag (summary, ``metadata.yaml``); nothing if none is open."""
        rec, self._writer = self._writer, None
        if rec is None:
            return
        try:
            rec.close()
            self._log.info(f"recording finished: {rec.message_count} messages in {rec.folder}")
        except OSError as exc:
            self._writer = rec
            self._failed(exc)

    def _failed(self, exc: BaseException) -> None:
        # e.g. a full disk: stop recording, keep the plant running; complete chunks already on
        # disk stay readable (ltd-brake recover rewrites the file)
        rec, self._writer = self._writer, None
        self.error = f"{type(exc).__name__}: {exc}"
        self._log.error(
            f"recording to {rec.folder} stopped: {self.error}; the plant keeps running; "
            f"{rec.messages_on_disk} messages are on disk (ltd-brake recover {rec.folder} "
            "makes it a complete bag)")
        # release the writer thread and the file; after a write error close() writes nothing
        # more, so the complete chunks stay exactly as they are
        try:
            rec.close()
        except OSError:
            pass

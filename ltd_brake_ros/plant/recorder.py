"""The recorder's lifecycle: one bag per run, flushed while idle, a write error never fatal.

The plant opens the bag at start-up, writes every message it publishes or receives, flushes
due chunks between chunks and while idle, and closes the bag when the run ends (shutdown or a
simulator failure). A run is recorded only into a folder of its own: the first one into
``<base>``, which must not exist or be empty; ``~/reset`` starts the next run in the next free
``<base>_2``, ``<base>_3``, ... (a name an earlier run took is skipped). A write error (a full
disk) stops the recording, not the plant: the chunks already on disk stay readable
(``ltd-brake recover`` makes the file a complete bag).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Sequence

from ..recording.bag import BagWriter
from .settings import StartupError

#: Folder names ``<base>_k`` tried for the next run before giving up.
MAX_FOLDER_SEARCH = 1000


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
        self._suffix = 0  # of the last folder opened: 1 is ``base``, k > 1 is ``base_k``
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

    def check(self) -> None:
        """Refuse now a first run's folder that :meth:`open` would refuse for its contents.

        Raises
        ------
        StartupError
            ``base`` holds anything already (parameter ``record_dir``).
        """
        if not _free(self.base):
            raise StartupError("record_dir", f"{self.base} exists and is not empty: give a new "
                               "folder (a run is never recorded into another one's folder)")

    def open(self) -> None:
        """Open the first run's bag in ``base``.

        Raises
        ------
        StartupError
            ``base`` holds anything already, or cannot be written (parameter ``record_dir``).
        """
        self.check()
        self._writer = self._start(self.base)
        self._suffix, self.error = 1, None

    def reopen(self, topics: Sequence[tuple[str, str, str]] | None = None,
               metadata: dict | None = None) -> None:
        """Start the next run's bag in the next free ``<base>_k``, then finish the current one.

        Nothing changes when the new bag cannot be opened: the current bag (if any) stays open.

        Parameters
        ----------
        topics, metadata : optional
            The next run's, when they differ from the current run's (as in the constructor).

        Raises
        ------
        StartupError
            The new bag cannot be opened (parameter ``record_dir``, naming the folder).
        """
        first = self._suffix + 1
        suffix = next((k for k in range(first, first + MAX_FOLDER_SEARCH)
                       if _free(f"{self.base}_{k}")), None)
        if suffix is None:
            raise StartupError("record_dir", f"no free folder from {self.base}_{first} to "
                               f"{self.base}_{first + MAX_FOLDER_SEARCH - 1}")
        rec = self._start(f"{self.base}_{suffix}", topics, metadata)
        self.close()
        self._writer, self._suffix, self.error = rec, suffix, None
        self._topics = list(topics) if topics is not None else self._topics
        self._metadata = metadata if metadata is not None else self._metadata

    def _start(self, folder: str, topics=None, metadata=None):
        """A writer on ``folder`` with every topic declared (``topics`` and ``metadata``
        default to the current run's)."""
        rec = None
        try:
            rec = self._make_writer(folder, metadata=self._metadata if metadata is None
                                    else metadata)
            for topic, msg_type, qos in self._topics if topics is None else topics:
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
        self._log.info(f"recording to {rec.folder}")
        return rec

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


def _free(folder: str) -> bool:
    """True if ``folder`` does not exist or is an empty directory."""
    path = Path(folder)
    try:
        return not path.exists() or (path.is_dir() and next(path.iterdir(), None) is None)
    except OSError:
        return False  # unreadable: not ours to write into

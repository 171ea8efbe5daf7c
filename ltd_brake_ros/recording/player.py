"""Play a recording back in recorded order, paced by the wall clock; knows nothing of ROS."""
from __future__ import annotations

import threading
import time
from typing import Callable

from ..plant.pacing import Pacer
from .bag import read_bag

__all__ = ["Player"]

#: Longest single wait while playing [s]: pause, rate and stop requests take effect this fast.
POLL_S = 0.2


class Player:
    """Publishes recorded messages paced to the wall clock.

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file.
    publish : callable
        ``publish(topic, msg_type, log_time_ns, data)`` for every message, in recorded order.
    rate : float, optional
        Recorded time advances ``rate`` times faster than wall time; 0 = no waiting.
    loop : bool, optional
        Start again at the end.
    clock : callable, optional
        ``clock(log_time_ns)`` before the first message of every new recorded time.
    skip_topics : collection of str, optional
        Topics not replayed.
    start_paused : bool, optional
    monotonic : callable, optional
        Wall clock [s] (tests may pass their own).
    wait : callable, optional
        ``wait(event, timeout_s)``: block until ``event`` is set or ``timeout_s`` passed [s]
        (tests may pass their own, moving their clock).

    Raises
    ------
    ValueError
        ``rate`` is negative.
    """

    def __init__(self, path, publish: Callable, *, rate: float = 1.0, loop: bool = False,
                 clock: Callable[[int], None] | None = None, skip_topics=(),
                 start_paused: bool = False, monotonic: Callable[[], float] = time.monotonic,
                 wait: Callable[[threading.Event, float], bool] = threading.Event.wait):
        self.path = path
        self._publish = publish
        self._clock = clock
        self._skip = frozenset(skip_topics)
        self.loop = bool(loop)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._wait = wait
        # paced time = recorded time [s]
        self._pacer = Pacer(rate, monotonic=monotonic, paused=start_paused)
        self._restart = False
        self._stop = False
        #: Messages published since the start (all passes).
        self.published = 0
        #: Completed passes through the recording.
        self.passes = 0

    # ----------------------------------------------------------------- control (any thread)

    @property
    def paused(self) -> bool:
        """True while playback stands still."""
        return self._pacer.paused

    @property
    def rate(self) -> float:
        """Recorded seconds per wall second (0 = as fast as possible)."""
        return self._pacer.rate

    @property
    def stopped(self) -> bool:
        """True once :meth:`stop` was called."""
        return self._stop

    def position_ns(self) -> float:
        """Recorded time the playback has reached [ns]."""
        with self._lock:
            return self._pacer.position() * 1e9

    def pause(self, paused: bool) -> None:
        """Pause (True) or resume (False); recorded time stands still while paused."""
        with self._lock:
            self._pacer.pause(paused)
        self._wake.set()

    def set_rate(self, rate: float) -> None:
        """Change the rate from the current playback position on.

        Raises
        ------
        ValueError
            ``rate`` is negative.
        """
        with self._lock:
            self._pacer.set_rate(rate)
        self._wake.set()

    def restart(self) -> None:
        """Go back to the first message (the pause state is kept)."""
        with self._lock:
            self._restart = True
        self._wake.set()

    def stop(self) -> None:
        """End :meth:`run` as soon as possible."""
        self._stop = True
        self._wake.set()

    # ----------------------------------------------------------------- playback

    def _wait_until(self, log_ns: int) -> bool:
        """Block until ``log_ns`` is due; False if stopped or restarted meanwhile."""
        while True:
            if self._stop or self._restart:
                return False
            with self._lock:
                wait_s = self._pacer.seconds_until(log_ns * 1e-9)
            if wait_s <= 0.0:
                return True
            self._wait(self._wake, min(wait_s, POLL_S))
            self._wake.clear()

    def run(self) -> int:
        """Play until the end (or forever with ``loop``) or :meth:`stop`.

        Returns
        -------
        int
            Messages published.
        """
        while not self._stop:
            with self._lock:
                self._restart = False
            first = True
            last_clock = None
            messages = read_bag(self.path)
            try:
                for topic, msg_type, log_ns, data in messages:
                    if first:
                        with self._lock:
                            self._pacer.rebase(log_ns * 1e-9)
                        first = False
                    if not self._wait_until(log_ns):
                        break
                    if topic in self._skip:
                        continue
                    if self._clock is not None and log_ns != last_clock:
                        self._clock(log_ns)
                        last_clock = log_ns
                    self._publish(topic, msg_type, log_ns, data)
                    self.published += 1
                else:
                    self.passes += 1
                    if not self.loop:
                        return self.published
            finally:
                messages.close()
        return self.published

"""Wall-clock pacing: where paced time (simulated or recorded) stands at a wall-clock instant.

The one pacing helper of the package: the plant schedules its chunks with it, the replay player
its messages. Both take their clock as an argument, so pacing is tested with a fake clock.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Clock:
    """The wall clock a runtime reads and waits on.

    Attributes
    ----------
    monotonic : callable
        ``monotonic() -> float``: a monotonic time [s].
    sleep : callable
        ``sleep(seconds)``: block for that long [s].
    wait : callable
        ``wait(event, timeout_s) -> bool``: block until ``event`` is set or ``timeout_s``
        passed [s]; True if the event is set.
    """

    monotonic: Callable[[], float] = time.monotonic
    sleep: Callable[[float], None] = time.sleep
    wait: Callable[[threading.Event, float], bool] = threading.Event.wait


class Pacer:
    """Paced time advancing ``rate`` times as fast as the wall clock, with pause and rebase.

    Not thread-safe: callers on several threads hold their own lock.

    Parameters
    ----------
    rate : float, optional
        Paced seconds per wall second; 0 = no pacing, everything is due at once.
    monotonic : callable, optional
        Wall clock [s].
    paused : bool, optional
        Start paused (paced time stands still until :meth:`pause` ``(False)``).
    """

    def __init__(self, rate: float = 1.0, *, monotonic: Callable[[], float] = time.monotonic,
                 paused: bool = False):
        if not rate >= 0.0:
            raise ValueError(f"rate must be >= 0, got {rate}")
        self._now = monotonic
        self._rate = float(rate)
        self._base_wall = monotonic()
        self._base = 0.0
        self._paused_at: float | None = self._base_wall if paused else None

    @property
    def rate(self) -> float:
        """Paced seconds per wall second [-]."""
        return self._rate

    @property
    def paused(self) -> bool:
        """True while paced time stands still."""
        return self._paused_at is not None

    def position(self, now: float | None = None) -> float:
        """Paced time reached at wall time ``now`` (default: the clock's now) [s]."""
        now = self._now() if now is None else now
        if self._paused_at is not None:
            now = self._paused_at
        return self._base + (now - self._base_wall) * self._rate

    def due_at(self, position: float) -> float:
        """Wall time at which paced time reaches ``position`` [s].

        ``-inf`` without pacing (rate 0), ``inf`` while paused.
        """
        if self._paused_at is not None:
            return math.inf
        if self._rate <= 0.0:
            return -math.inf
        return self._base_wall + (position - self._base) / self._rate

    def seconds_until(self, position: float, now: float | None = None) -> float:
        """Wall time left until ``position`` is due, 0 if it is [s] (``inf`` while paused)."""
        now = self._now() if now is None else now
        return max(self.due_at(position) - now, 0.0)

    def rebase(self, position: float, now: float | None = None) -> None:
        """Let paced time be ``position`` at wall time ``now``; a pause starts again there."""
        now = self._now() if now is None else now
        self._base, self._base_wall = float(position), now
        if self._paused_at is not None:
            self._paused_at = now

    def pause(self, paused: bool, now: float | None = None) -> None:
        """Stop (True) or resume (False) paced time; paused wall time does not count."""
        now = self._now() if now is None else now
        if paused and self._paused_at is None:
            self._paused_at = now
        elif not paused and self._paused_at is not None:
            self._base_wall += now - self._paused_at
            self._paused_at = None

    def set_rate(self, rate: float, now: float | None = None) -> None:
        """Change the rate from the current position on.

        Raises
        ------
        ValueError
            ``rate`` is negative or not a number.
        """
        if not rate >= 0.0:
            raise ValueError(f"rate must be >= 0, got {rate}")
        now = self._now() if now is None else now
        anchor = self._paused_at if self._paused_at is not None else now
        self._base, self._base_wall = self.position(anchor), anchor
        self._rate = float(rate)

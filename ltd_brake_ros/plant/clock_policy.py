"""Who publishes the simulated time: the ``clock`` setting resolved against the other publishers
of ``/clock``, and the warning about a second publisher. No ROS: the node passes what its graph
shows (``(namespace, node name)`` of each publisher of its ``/clock``)."""
from __future__ import annotations

from typing import Callable, Iterable

from .pacing import Clock

__all__ = ["CLOCK_DISCOVERY_S", "CLOCK_DISCOVERY_MIN_S", "CLOCK_DISCOVERY_POLL_S",
           "CLOCK_WATCH_PERIOD_S", "ANOTHER_NODE", "ClockWatch", "other_publishers",
           "resolve_clock"]

#: Wall time between two looks for other ``/clock`` publishers while publishing it [s].
CLOCK_WATCH_PERIOD_S = 1.0
#: ``clock:=auto`` looks for another ``/clock`` publisher until this long after the node was
#: created, and at least CLOCK_DISCOVERY_MIN_S (DDS discovery of the other processes'
#: endpoints takes a moment, seconds on a busy machine) [s].
CLOCK_DISCOVERY_S = 3.0
CLOCK_DISCOVERY_MIN_S = 1.0
#: Wall time between two looks during that wait [s].
CLOCK_DISCOVERY_POLL_S = 0.05
#: A publisher whose endpoint was discovered before its node's name.
ANOTHER_NODE = "another node"


def other_publishers(me: tuple[str, str], publishers: Iterable[tuple[str, str]]) -> list[str]:
    """Fully qualified names of the publishers other than ``me``, sorted, each once.

    Parameters
    ----------
    me : (str, str)
        This node's namespace and name.
    publishers : iterable of (str, str)
        Namespace and node name of each publisher of the topic.
    """
    found = set()
    for namespace, name in publishers:
        if (namespace, name) == me:
            continue
        # an endpoint seen before its node's name
        found.add(ANOTHER_NODE if "_UNKNOWN_" in name else f"{namespace.rstrip('/')}/{name}")
    return sorted(found)


def resolve_clock(mode: str, lockstep: bool, others: Callable[[], list[str]], created_s: float,
                  topic: str, clock: Clock = Clock()) -> tuple[str, str | None]:
    """``publish``, ``follow`` or ``none`` for the ``clock`` setting (``auto`` resolved).

    ``auto`` waits for discovery (see CLOCK_DISCOVERY_S) and follows another publisher of
    ``/clock`` if there is one, else publishes.

    Parameters
    ----------
    mode : str
        ``auto``, ``publish``, ``follow`` or ``none``.
    lockstep : bool
        The plant was asked for lock-step (ignored when following).
    others : callable
        ``others()`` -> the other publishers of ``/clock`` now (see :func:`other_publishers`).
    created_s : float
        Monotonic time the node was created [s].
    topic : str
        The fully qualified clock topic (for the message).
    clock : Clock, optional
        Wall clock and sleep.

    Returns
    -------
    (str, str or None)
        The mode, and the line to log when ``auto`` chose to follow.
    """
    if mode != "auto":
        return mode, None
    deadline = max(created_s + CLOCK_DISCOVERY_S, clock.monotonic() + CLOCK_DISCOVERY_MIN_S)
    while not (found := others()) and clock.monotonic() < deadline:
        clock.sleep(CLOCK_DISCOVERY_POLL_S)
    if not found:
        return "publish", None
    named = clock.monotonic() + CLOCK_DISCOVERY_MIN_S  # its node's name follows shortly
    while found == [ANOTHER_NODE] and clock.monotonic() < named:
        clock.sleep(CLOCK_DISCOVERY_POLL_S)
        found = others() or found
    return "follow", (
        f"{topic} is published by {', '.join(found)}: following it, one simulated time for "
        f"both{' (lockstep ignored: that clock steps this train)' if lockstep else ''}; "
        "clock:=publish would publish a second clock")


class ClockWatch:
    """Warns once about each other node that publishes the clock a plant publishes.

    Parameters
    ----------
    topic : str
        The fully qualified clock topic.
    """

    def __init__(self, topic: str):
        self.topic = topic
        self.warned: set[str] = set()

    def check(self, others: list[str]) -> str | None:
        """The warning about the publishers in ``others`` not warned about yet, or None."""
        new = [name for name in others if name not in self.warned and name != ANOTHER_NODE]
        if not new:
            return None
        self.warned.update(new)
        return (f"{', '.join(new)} also publish(es) {self.topic}: time jumps back and forth for "
                "every node using it; start one plant with clock:=publish and the others with "
                "clock:=follow")

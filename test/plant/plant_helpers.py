"""A fake wall clock, a log that keeps its lines, a short train and a runner wired to lists."""
from __future__ import annotations

import functools
import threading
from dataclasses import dataclass, field

from ltd_brake_ros.inputs import consist_from_mapping
from ltd_brake_ros.plant.pacing import Clock
from ltd_brake_ros.plant.runner import PlantRunner
from ltd_brake_ros.plant.settings import PlantSettings
from ltd_brake_ros.simulator import Simulator

#: Initial speed of the short train [km/h]: an emergency stop takes about 7 s.
SPEED_KMH = 20.0


class FakeClock:
    """Wall time that moves only when the code under test sleeps or waits (or the test says)."""

    def __init__(self, start_s: float = 1000.0):
        self.t = start_s

    def monotonic(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds

    def wait(self, event: threading.Event, timeout_s: float) -> bool:
        if not event.is_set():
            self.t += timeout_s
        return event.is_set()

    def clock(self) -> Clock:
        """The :class:`Clock` the runtime is given."""
        return Clock(self.monotonic, self.sleep, self.wait)


class Log:
    """Keeps ``(level, text)`` for every line; the logger interface of rclpy and logging."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def __getattr__(self, level):
        if level not in ("debug", "info", "warning", "error", "fatal"):
            raise AttributeError(level)
        return lambda text: self.lines.append((level, text))

    def at(self, level: str) -> list[str]:
        """The lines logged at ``level``."""
        return [text for lvl, text in self.lines if lvl == level]


@functools.cache
def short_train():
    """E402B + 2 Shimmns of 50 t (3 vehicles, 2 couplers)."""
    return consist_from_mapping({"name": "short", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": 2, "mass_t": 50.0}]}, "<test>")


class CostlySimulator(Simulator):
    """A simulator whose every chunk costs ``cost_s(chunk index)`` of fake wall time."""

    def __init__(self, clock: FakeClock, cost_s=lambda k: 0.0, **kwargs):
        super().__init__(short_train(), SPEED_KMH, **kwargs)
        self.fake_clock, self.cost_s, self.advanced = clock, cost_s, 0

    def advance(self, duration_s, commands=None):
        self.fake_clock.t += self.cost_s(self.advanced)
        self.advanced += 1
        return super().advance(duration_s, commands)


@dataclass
class Plant:
    """A runner on a fake clock and what it published."""

    runner: PlantRunner
    clock: FakeClock
    log: Log
    #: (fake wall time, snapshot) of every published state
    states: list = field(default_factory=list)
    #: (fake wall time, PlantStatus) of every diagnostics report
    statuses: list = field(default_factory=list)
    #: (stamp_ns, name, value, message) of every handled input
    inputs: list = field(default_factory=list)

    def run_until(self, wall_s: float) -> None:
        """Poll and wait like the plant thread until the fake clock reaches ``wall_s``."""
        while self.clock.t < wall_s:
            timeout = self.runner.poll()
            if timeout > 0.0:
                self.clock.t = min(self.clock.t + timeout, wall_s)

    def polls(self, n: int) -> None:
        """Poll ``n`` times without letting wall time pass (except what chunks cost)."""
        for _ in range(n):
            self.runner.poll()

    def request(self, job) -> tuple[bool, str]:
        """Run a queued request on the (not threaded) plant and return its reply."""
        self.runner.poll()
        assert job.done.is_set()
        return job.result

    @property
    def stamps_ns(self) -> list[int]:
        return [round(s.time_s * 1e9) for _, s in self.states]


def make_plant(cost_s=lambda k: 0.0, recorder=None, log=None, **settings) -> Plant:
    """A :class:`Plant` on the short train, started (initial state published).

    With a ``recorder``, every published state is written to it as one message on
    ``/t/clock``, the way the node records what it publishes.
    """
    clock, log = FakeClock(), log or Log()
    sim = CostlySimulator(clock, cost_s)
    plant = Plant(None, clock, log)

    def publish_state(snap):
        plant.states.append((clock.t, snap))
        if recorder is not None and recorder.active:
            recorder.write("/t/clock", b"state", plant.runner.stamp_ns)

    plant.runner = PlantRunner(
        sim, PlantSettings(**settings), publish_state=publish_state,
        publish_status=lambda status: plant.statuses.append((clock.t, status)),
        input_handled=lambda name, value, msg: plant.inputs.append(
            (plant.runner.stamp_ns, name, value, msg)), log=log, recorder=recorder,
        labels={"brake_demand": "/t/brake_demand"}, clock=clock.clock())
    plant.runner.begin()
    return plant

"""What the plant runtime is told: chunk length, pace, mode and run policy."""
from __future__ import annotations

from dataclasses import dataclass

#: Largest accepted real-time factor [-].
MAX_REAL_TIME_FACTOR = 1000.0
#: Default lag behind the schedule that the plant still catches up [s wall]: ten 20 ms periods,
#: over twice the largest lag (55-87 ms) of a 1 000-wagon brake-pipe train at real-time factor 1
#: on a shared 2-core machine (README, "A 1 000-wagon train live").
DEFAULT_MAX_CATCH_UP_S = 0.2


class StartupError(Exception):
    """A setting value the plant cannot start with.

    Parameters
    ----------
    parameter : str
        Name of the offending setting (the node parameter).
    reason : str
        What is wrong, in words a user can act on.
    """

    def __init__(self, parameter: str, reason: str):
        self.parameter, self.reason = parameter, reason
        super().__init__(f"parameter {parameter}: {reason}")


@dataclass(frozen=True)
class PlantSettings:
    """How the plant advances and when it ends.

    Attributes
    ----------
    chunk_s : float
        Simulated time advanced and published per chunk [s].
    real_time_factor : float
        Simulated seconds per wall second; 0 = as fast as possible [-].
    max_catch_up_s : float
        Wall time a free-running plant may fall behind its schedule and still catch up, by
        advancing the next chunks at once (none before it is due); further behind, the
        schedule restarts from now and an overrun is counted; 0 = never catch up [s].
    lockstep : bool
        Advance only when asked (:meth:`PlantRunner.step`).
    steps_per_call : int
        Chunks advanced per step request.
    auto_brake_at_s : float
        Apply the emergency brake at the first chunk boundary at or after this simulated time
        [s]; negative = never.
    max_sim_time_s : float
        Finish once the simulated time reaches this [s]; negative = never.
    shutdown_after_stop_s : float
        Finish this long after the train stopped [s simulated]; negative = never.
    follow_clock : bool
        Advance to the times another plant's clock reports (:meth:`PlantRunner.follow`)
        instead of by itself; stepping and pausing are refused.
    publish_every : int
        Publish the state after every this many chunks when free-running or following (a
        step's last chunk and a reset are always published).
    """

    chunk_s: float = 0.02
    real_time_factor: float = 1.0
    max_catch_up_s: float = DEFAULT_MAX_CATCH_UP_S
    lockstep: bool = False
    steps_per_call: int = 1
    auto_brake_at_s: float = -1.0
    max_sim_time_s: float = -1.0
    shutdown_after_stop_s: float = -1.0
    follow_clock: bool = False
    publish_every: int = 1

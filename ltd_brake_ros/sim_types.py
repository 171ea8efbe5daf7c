"""What the simulator takes and gives: commands, snapshots, events, peaks and its state.

The value types of :mod:`ltd_brake_ros.simulator` (which re-exports them), apart so that the
simulator module holds the simulation itself. Sign conventions as there: vehicle 0 is the head;
speeds forward positive; coupler j (from 1 behind the head) draft positive, buff negative;
brake forces retarding, positive.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .inputs.commands import COMMAND_RANGES
from .physics import brakes as brakes_module
from .physics import kernel
from .physics.brakes.base import EMERGENCY

__all__ = ["Commands", "CouplerExcursions", "CouplerPeaks", "Event", "Excursion",
           "SimulationError", "SimulatorState", "Snapshot"]


class SimulationError(RuntimeError):
    """The integration could not proceed (a Newton iteration did not converge, a force was not
    finite, or a step failed with an arithmetic error), or a run did not end as asked (the
    train had not stopped in time); one line.

    Examples
    --------
    >>> from ltd_brake_ros import SimulationError, emergency_stop
    >>> try:
    ...     emergency_stop("scenario_6", 100.0, max_time_s=5.0)
    ... except SimulationError as exc:
    ...     print(exc)  # doctest: +SKIP
    the train had not stopped after 5 s
    """


@dataclass(frozen=True)
class Commands:
    """Driver and train-control inputs held constant over one chunk.

    Attributes
    ----------
    emergency : bool
        Emergency brake applied. A change from False to True starts the application at the
        start of the chunk (t_app counts from there); True to False releases.
    brake_demand : float
        Service brake demand, 0 (released) to 1 (full service force = the emergency maximum
        block force). Overridden by ``emergency``. Not validated against measurements.
    traction : float
        Traction (0 to 1) or dynamic-brake (-1 to 0) demand, as a fraction of the powered
        vehicles' available effort.
    overcharge : bool
        The release (no emergency, ``brake_demand`` 0) overcharges the brake pipe: the driver's
        brake valve of the brake-pipe model fills it above running pressure, which shortens
        the release of a long train; the empirical models release as usual. Held while
        braking, it acts again at the next release. A change of it alone is a new command.

    Raises
    ------
    ValueError
        A value is not finite or out of range, or a flag is not a bool (the message names the
        field).

    Examples
    --------
    >>> from ltd_brake_ros import Commands
    >>> Commands(brake_demand=0.4).emergency
    False
    """

    emergency: bool = False
    brake_demand: float = 0.0
    traction: float = 0.0
    overcharge: bool = False

    def __post_init__(self):
        if not isinstance(self.overcharge, (bool, np.bool_)):
            raise ValueError(f"overcharge must be true or false, got {self.overcharge!r}")
        for name, (lo, hi) in COMMAND_RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{name} must be between {lo:g} and {hi:g}, got {value}")


def _distinct(value: float, limit: float, digits: int) -> str:
    """``value`` with ``digits`` decimals, or as many more as it takes not to read as the
    ``limit`` it exceeds (up to 9)."""
    while digits < 9 and f"{value:.{digits}f}" == f"{limit:.{digits}f}":
        digits += 1
    return f"{value:.{digits}f}"


@dataclass(frozen=True)
class Event:
    """Something that happened during the run.

    Attributes
    ----------
    time_s : float
        Simulated time [s].
    kind : str
        ``brake_applied``, ``brake_released``; a stop's ``stop_started`` (``stop``, its
        number, ``command``, ``command_speed_kmh``), ``stop_abandoned`` (released before
        standstill), ``stopped`` (``stopping_distance_m``, ``stop_time_s`` and the peaks from
        the command), ``settled`` (``settled_time_s``; ``stop`` 0: a train at rest from the
        start), ``drive_off`` and ``stop_ended`` (``end``, ``verdicts`` and
        ``verdict_<criterion>``); ``coupler_out_of_lut`` or ``limit_exceeded`` (a coupler or
        vehicle first beyond a limit of :mod:`~ltd_brake_ros.verdicts`: ``criterion``,
        ``coupler`` or ``vehicle``, the force, demand, temperature or speed, the limit,
        ``speed_kmh``).
    detail : dict
        Kind-specific values (units in the keys).
    """

    time_s: float
    kind: str
    detail: dict = field(default_factory=dict)

    def describe(self) -> str:
        """One-line human description."""
        d = self.detail
        if self.kind == "stopped":
            return (f"t = {self.time_s:.2f} s: train stopped, stopping distance "
                    f"{d['stopping_distance_m']:.1f} m")
        if self.kind == "stop_started":
            return (f"t = {self.time_s:.2f} s: stop {d['stop']}: {d['command']} brake at "
                    f"{d['command_speed_kmh']:.1f} km/h")
        if self.kind == "stop_ended":
            return (f"t = {self.time_s:.2f} s: stop {d['stop']} ended by {d['end']}, verdicts "
                    f"{d['verdicts']}")
        if self.kind == "settled":
            return (f"t = {self.time_s:.2f} s: train settled, every vehicle at rest since "
                    f"t = {d['settled_time_s']:.2f} s")
        if self.kind == "coupler_out_of_lut":
            return (f"t = {self.time_s:.2f} s: coupler {d['coupler']} left the coupler table, "
                    f"{d['beyond_table_mm']:.1f} mm beyond its end within the chunk; forces "
                    "there are extrapolated with the end slopes")
        if self.kind == "limit_exceeded":
            element = "coupler" if "coupler" in d else "vehicle"
            if "force_kN" in d:
                what = (f"{_distinct(d['force_kN'], d['limit_kN'], 0)} kN, limit "
                        f"{d['limit_kN']:.0f} kN")
            elif "limit_kmh" in d:
                return (f"t = {self.time_s:.2f} s: {element} {d[element]} moved from rest "
                        f"without traction ({d['speed_kmh']:.3g} km/h): a runaway")
            elif "temperature_K" in d:
                what = (f"{_distinct(d['temperature_K'], d['limit_K'], 0)} K, limit "
                        f"{d['limit_K']:.0f} K")
            else:
                what = f"demand {_distinct(d['demand'], d['limit'], 3)}, limit {d['limit']:.3f}"
            return (f"t = {self.time_s:.2f} s: {element} {d[element]} beyond its "
                    f"{d['criterion'].replace('_', ' ')} limit ({what}) at "
                    f"{d['speed_kmh']:.1f} km/h")
        return f"t = {self.time_s:.2f} s: {self.kind.replace('_', ' ')}"


@dataclass(frozen=True)
class Snapshot:
    """State of the train at the end of a chunk.

    Attributes
    ----------
    time_s : float
        Simulated time [s].
    position_m : ndarray
        Chainage of each vehicle's centre; the head's front starts at 0 [m].
    speed_m_s : ndarray
        Speed of each vehicle, forward positive [m/s].
    brake_force_N : ndarray
        Air-brake retarding force of each vehicle, positive [N].
    traction_force_N : ndarray
        Traction (positive) or dynamic-brake (negative) force of each vehicle [N].
    block_force_N : ndarray
        Total force on the brake blocks/pads of each vehicle, F_B,tot [N].
    coupler_force_N : ndarray
        Force of couplers 1..n-1, draft positive, buff negative [N].
    events : tuple of Event
        Events that happened during this chunk.
    stopped : bool
        Every vehicle is at standstill (slower than the simulator's ``standstill_m_s``).
    extras : dict
        Further per-vehicle quantities (units in the keys): the brake model's (the brake-pipe
        model's pressures) and the temperature of each vehicle's brake blocks and wheels,
        ``block_temperature_K`` and ``wheel_temperature_K`` (:mod:`.physics.brakes.thermal`;
        NaN for vehicles without block brakes).

    Examples
    --------
    >>> run = emergency_stop("scenario_1", 60.0)       # doctest: +SKIP
    >>> snap = run.simulator.snapshot()                 # doctest: +SKIP
    >>> snap.stopped, snap.coupler_force_N.shape        # doctest: +SKIP
    (True, (10,))
    """

    time_s: float
    position_m: np.ndarray
    speed_m_s: np.ndarray
    brake_force_N: np.ndarray
    traction_force_N: np.ndarray
    block_force_N: np.ndarray
    coupler_force_N: np.ndarray
    events: tuple = ()
    stopped: bool = False
    extras: dict = field(default_factory=dict)


@dataclass(frozen=True)
class CouplerPeaks:
    """The largest draft and buff force of a run and where and when they occurred.

    Attributes
    ----------
    draft_N : float
        Largest draft (tension) force, >= 0 [N] (0 if no coupler was ever in draft).
    draft_coupler : int
        Coupler that carried it (1 = behind the head; 0 when the train has no coupler).
    draft_time_s : float
        When [s].
    buff_N : float
        Largest buff (compression) force, <= 0 [N].
    buff_coupler : int
        Coupler that carried it.
    buff_time_s : float
        When [s].
    """

    draft_N: float = 0.0
    draft_coupler: int = 0
    draft_time_s: float = 0.0
    buff_N: float = 0.0
    buff_coupler: int = 0
    buff_time_s: float = 0.0

    @classmethod
    def from_arrays(cls, draft_N, draft_time_s, buff_N, buff_time_s) -> "CouplerPeaks":
        """Summarise per-coupler running extremes.

        Parameters
        ----------
        draft_N, buff_N : array_like
            Largest draft (>= 0) and buff (<= 0) force of each coupler [N].
        draft_time_s, buff_time_s : array_like
            When each occurred [s].

        Returns
        -------
        CouplerPeaks
        """
        draft, buff = np.asarray(draft_N, float), np.asarray(buff_N, float)
        if draft.size == 0:
            return cls()
        jd, jb = int(np.argmax(draft)), int(np.argmin(buff))
        return cls(float(draft[jd]), jd + 1, float(np.asarray(draft_time_s)[jd]),
                   float(buff[jb]), jb + 1, float(np.asarray(buff_time_s)[jb]))


@dataclass(frozen=True)
class Excursion:
    """One coupler's largest excursion beyond the coupler model's valid range.

    Attributes
    ----------
    coupler : int
        Coupler number (1 = behind the head).
    beyond_range_mm : float
        How far its deflection went beyond the valid range (the coupler table's ends) [mm].
    time_s : float
        When that largest excursion occurred [s].
    first_time_s : float
        When the coupler first left the range [s].
    """

    coupler: int
    beyond_range_mm: float
    time_s: float
    first_time_s: float


@dataclass(frozen=True)
class CouplerExcursions:
    """Summary of the couplers that went beyond the coupler model's valid range.

    Long trains push hundreds of couplers past a coupler table's ends; this is the one place
    that counts them and ranks the worst, for a one-line warning instead of one per coupler.

    Attributes
    ----------
    count : int
        Couplers that went beyond the range.
    total : int
        Couplers of the train.
    worst : tuple of Excursion
        The largest excursions, largest first (at most the number asked for).
    """

    count: int = 0
    total: int = 0
    worst: tuple = ()

    @classmethod
    def from_arrays(cls, beyond_m, time_s, first_time_s, worst: int = 3) -> "CouplerExcursions":
        """Summarise per-coupler excursions.

        Parameters
        ----------
        beyond_m : array_like
            Largest excursion of each coupler beyond the valid range, 0 if none [m].
        time_s, first_time_s : array_like
            When it occurred and when the coupler first left the range [s].
        worst : int, optional
            How many of the largest to keep.

        Returns
        -------
        CouplerExcursions
        """
        beyond = np.asarray(beyond_m, float)
        out = np.flatnonzero(beyond > 0.0)
        ranked = out[np.argsort(-beyond[out], kind="stable")][: max(int(worst), 0)]
        t, t0 = np.asarray(time_s, float), np.asarray(first_time_s, float)
        return cls(int(out.size), int(beyond.size), tuple(
            Excursion(int(j) + 1, float(beyond[j]) * 1e3, float(t[j]), float(t0[j]))
            for j in ranked))

    def describe(self) -> str:
        """One line: how many couplers went beyond the range, and the worst."""
        if not self.count:
            return f"no coupler of {self.total} went beyond the coupler characteristic's range"
        worst = ", ".join(f"coupler {e.coupler} by {e.beyond_range_mm:.1f} mm at "
                          f"t = {e.time_s:.2f} s" for e in self.worst)
        return (f"{self.count} of {self.total} couplers went beyond the coupler "
                f"characteristic's range, where forces are extrapolated; worst: {worst}")


@dataclass
class SimulatorState:
    """Everything about a simulator that changes while it runs.

    Attributes
    ----------
    time_s : float
        Simulated time [s].
    last_step_s : float
        Last step size [s]; 0 restarts the integrator without history.
    kinematics : KinematicState
        Displacements, speeds, forces and the current window's running extremes (see
        :class:`~ltd_brake_ros.physics.kernel.KinematicState`).
    brakes : BrakeState
        The brake model's state.
    events : CommandEvents
        Brake commands issued (at the venting vehicle) that some vehicle has yet to receive.
    stats : ndarray
        Counters, one :data:`~ltd_brake_ros.physics.kernel.STATS_DTYPE` record.
    reported_out_of_range : ndarray of bool
        Couplers whose excursion beyond their valid range has been reported in this window.
    reported_out_of_range_count : int
        How many of them.
    brake_command : tuple of (float, int)
        Brake level and kind last commanded.
    emergency : bool
        The emergency brake is commanded.
    traction_demand : float
        Traction or dynamic-brake demand, -1 to 1.
    failed : bool
        A step failed; only a reset recovers.
    phase : int
        Where the run is: moving, braking, settling, at rest or after a runaway
        (:mod:`~ltd_brake_ros.stops`).
    stops : list of OpenStop
        The run's stops, the latest last (:mod:`~ltd_brake_ros.stops`).
    window : Window or None
        The part of the run judged now; ``closed`` the parts before it.
    closed : list of Window
    """

    time_s: float
    last_step_s: float
    kinematics: kernel.KinematicState
    brakes: brakes_module.BrakeState
    events: brakes_module.CommandEvents
    stats: np.ndarray
    reported_out_of_range: np.ndarray
    brake_command: tuple = (0.0, EMERGENCY)
    emergency: bool = False
    traction_demand: float = 0.0
    failed: bool = False
    reported_out_of_range_count: int = 0
    phase: int = 0
    stops: list = field(default_factory=list)
    window: object = None
    closed: list = field(default_factory=list)

    def copy(self) -> "SimulatorState":
        """An independent copy (arrays copied)."""
        stops = {id(s): s.copy() for s in self.stops}

        def window(w):
            new = w.copy()
            if w.stop is not None:
                new.stop = stops.get(id(w.stop), w.stop)
            return new
        return dataclasses.replace(
            self, kinematics=self.kinematics.copy(), brakes=self.brakes.copy(),
            events=self.events.copy(), stats=self.stats.copy(),
            reported_out_of_range=self.reported_out_of_range.copy(),
            stops=[stops[id(s)] for s in self.stops],
            window=None if self.window is None else window(self.window),
            closed=[window(w) for w in self.closed])

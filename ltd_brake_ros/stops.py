"""Stops and standstills of a run: each stop its own record, each judgment scoped to its part.

A run is cut into **windows**: one starts at t = 0, a new one at every brake command that
starts a stop (an emergency or service application while the train moves) and at every
drive-off (traction commanded from rest). The kernel's running records (coupler peaks and
excursions, brake work, brake-force and temperature peaks) are reset at each window's start,
so that a window's verdicts are its own; the run's are all windows' together
(:func:`~ltd_brake_ros.verdicts.merge`).

A stop follows its train through four **phases**, each watched on the integration steps by
the kernel (:data:`~ltd_brake_ros.physics.kernel.WATCH_STOP` ...):

1. *braking*, from the command to the first standstill (every vehicle slower than 1 mm/s
   going forward): the stopping distance and time, as the paper counts them; a brake released
   before it abandons the stop;
2. *settling*, until every vehicle has stayed within 1 mm/s either way for
   :data:`~ltd_brake_ros.physics.kernel.SETTLE_S` (recoil of the couplers included): the
   "settled" time is when that rest began;
3. *at rest*, until traction is commanded (a drive-off ends the stop): each chunk end judges
   every vehicle's force to hold against what it holds (``standstill_holding``), and any
   vehicle faster than 1 mm/s is a runaway (``runaway``: brake applied or released, without
   traction);
4. after a runaway the stop stays open, recording how fast its vehicles went, until traction
   or a new stop.

A train that starts at rest has a standstill without a stop: it is judged the same way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .physics.constants import KMH_PER_MS
from .physics.kernel import (REST_SINCE, WATCH_NONE, WATCH_REST, WATCH_SETTLE, WATCH_STOP)
from .sim_types import CouplerPeaks
from .verdicts import Verdicts

__all__ = ["Extremes", "StopRecord", "Window", "PHASE_AT_REST", "PHASE_BRAKING",
           "PHASE_MOVING", "PHASE_RUNAWAY", "PHASE_SETTLING", "WATCH_OF_PHASE"]

#: Phases of a run (see the module).
PHASE_MOVING, PHASE_BRAKING, PHASE_SETTLING, PHASE_AT_REST, PHASE_RUNAWAY = range(5)
#: What the kernel watches in each phase.
WATCH_OF_PHASE = (WATCH_NONE, WATCH_STOP, WATCH_SETTLE, WATCH_REST, WATCH_NONE)


class Extremes(NamedTuple):
    """The kernel's running records of one window (the fields of
    :class:`~ltd_brake_ros.physics.kernel.KinematicState` the verdicts read), copied when
    the window closes."""

    peak_draft_N: np.ndarray
    peak_draft_time_s: np.ndarray
    peak_buff_N: np.ndarray
    peak_buff_time_s: np.ndarray
    beyond_range_m: np.ndarray
    beyond_range_time_s: np.ndarray
    out_of_range_time_s: np.ndarray
    applied_work_J: np.ndarray
    applied_distance_m: np.ndarray
    peak_brake_fast_N: np.ndarray
    peak_brake_fast_time_s: np.ndarray
    peak_brake_fast_speed_m_s: np.ndarray
    peak_brake_slow_N: np.ndarray
    peak_brake_slow_time_s: np.ndarray
    peak_brake_slow_speed_m_s: np.ndarray
    peak_block_temperature_K: np.ndarray
    peak_block_temperature_time_s: np.ndarray
    peak_wheel_temperature_K: np.ndarray
    peak_wheel_temperature_time_s: np.ndarray

    @classmethod
    def of(cls, kin) -> "Extremes":
        """A copy of the records of a kernel state (or of another :class:`Extremes`)."""
        return cls(*(getattr(kin, name).copy() for name in cls._fields))


def reset_extremes(kin, t: float) -> None:
    """Start a window at time ``t`` [s]: the kernel's running records of ``kin`` anew, in
    place (the temperatures' peaks start from the temperatures now)."""
    for name in ("peak_draft_N", "peak_draft_time_s", "peak_buff_N", "peak_buff_time_s",
                 "beyond_range_m", "applied_work_J", "applied_distance_m", "peak_brake_fast_N",
                 "peak_brake_fast_time_s", "peak_brake_fast_speed_m_s", "peak_brake_slow_N",
                 "peak_brake_slow_time_s", "peak_brake_slow_speed_m_s"):
        getattr(kin, name)[:] = 0.0
    kin.beyond_range_time_s[:] = -1.0
    kin.out_of_range_time_s[:] = -1.0
    kin.step_control[2] = 0.0  # OUT_OF_RANGE: no coupler out of its range in this window
    for now, peak, when in ((kin.block_temperature_K, kin.peak_block_temperature_K,
                             kin.peak_block_temperature_time_s),
                            (kin.wheel_temperature_K, kin.peak_wheel_temperature_K,
                             kin.peak_wheel_temperature_time_s)):
        peak[:] = now
        when[:] = t


def merged_peaks(parts) -> tuple:
    """Per-coupler run records from the windows' (draft, its time, buff, its time, beyond the
    range, its time, first out of range), each the worst of any window."""
    draft, t_draft, buff, t_buff, beyond, t_beyond, t_out = (
        np.array(a, float) for a in parts[0])
    for p in parts[1:]:
        d, td, b, tb, e, te, to = (np.asarray(a, float) for a in p)
        more = d > draft
        draft, t_draft = np.where(more, d, draft), np.where(more, td, t_draft)
        more = b < buff
        buff, t_buff = np.where(more, b, buff), np.where(more, tb, t_buff)
        more = e > beyond
        beyond, t_beyond = np.where(more, e, beyond), np.where(more, te, t_beyond)
        t_out = np.where((t_out < 0.0) | ((to >= 0.0) & (to < t_out)), to, t_out)
    return draft, t_draft, buff, t_buff, beyond, t_beyond, t_out


@dataclass(frozen=True)
class StopRecord:
    """One stop of a run: from the brake command that led to it to the drive-off (or the end
    of the run).

    Attributes
    ----------
    number : int
        1 for the run's first stop.
    command : str
        ``emergency`` or ``service``: the application that started it.
    command_time_s : float
        When the brake was commanded [s].
    command_speed_kmh : float
        The head's speed then [km/h].
    stop_time_s : float or None
        When the train first stood still, every vehicle slower than 1 mm/s [s] (None: not
        yet).
    stopping_distance_m : float or None
        The head's travel from the command to then [m].
    settled_time_s : float or None
        Since when every vehicle has stayed within 1 mm/s either way, for at least 2 s [s]
        (None: not settled yet).
    end_time_s : float or None
        When the stop ended [s] (None: open).
    end : str
        ``open``, ``drive-off`` (traction from rest), ``runaway`` then a new stop or
        traction, or ``end of run``.
    peaks : CouplerPeaks
        The largest draft and buff force from the command to the first standstill (while
        braking: so far), where and when, as the paper's Tables 1-2 count them.
    verdicts : Verdicts
        The judgments of the stop (:mod:`~ltd_brake_ros.verdicts`): strength, travel and
        adhesion from the command to the stop's end (the couplers' recoil while settling
        included), holding and runaway from the standstill.

    Examples
    --------
    >>> from ltd_brake_ros import load_consist, run_commands
    >>> run = run_commands(load_consist("scenario_6"), 40.0, [   # doctest: +SKIP
    ...     {"t_s": 0, "brake_demand": 0.6},
    ...     {"t_s": 60, "brake_demand": 0.0, "traction": 1.0},
    ...     {"t_s": 150, "traction": 0.0, "emergency": True}])
    >>> [(s.command, round(s.stopping_distance_m, 1)) for s in run.stops]  # doctest: +SKIP
    [('service', 106.6), ('emergency', 43.9)]
    """

    number: int
    command: str
    command_time_s: float
    command_speed_kmh: float
    stop_time_s: float | None
    stopping_distance_m: float | None
    settled_time_s: float | None
    end_time_s: float | None
    end: str
    peaks: CouplerPeaks
    verdicts: Verdicts

    @property
    def stop_duration_s(self) -> float | None:
        """Time from the command to the first standstill [s] (None: not stopped)."""
        return None if self.stop_time_s is None else self.stop_time_s - self.command_time_s

    def describe(self) -> str:
        """One line: the command, the distance and times, the peaks and the verdict."""
        p = self.peaks
        if self.stop_time_s is None:
            where = "not stopped yet"
        else:
            where = (f"stopped in {self.stopping_distance_m:.1f} m and "
                     f"{self.stop_duration_s:.2f} s, "
                     + ("not settled" if self.settled_time_s is None else
                        f"settled at t = {self.settled_time_s:.2f} s"))
        return (f"stop {self.number}: {self.command} at t = {self.command_time_s:.2f} s, "
                f"{self.command_speed_kmh:.1f} km/h; {where}; peak draft "
                f"{p.draft_N / 1e3:.0f} kN at coupler {p.draft_coupler}, buff "
                f"{-p.buff_N / 1e3:.0f} kN at coupler {p.buff_coupler}; verdicts "
                f"{self.verdicts.status}"
                + ("" if self.end == "open" else f"; ended by {self.end}"
                   + ("" if self.end_time_s is None else f" at t = {self.end_time_s:.2f} s")))

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        p = self.peaks
        return {"number": self.number, "command": self.command,
                "command_time_s": self.command_time_s,
                "command_speed_kmh": self.command_speed_kmh, "stop_time_s": self.stop_time_s,
                "stop_duration_s": self.stop_duration_s,
                "stopping_distance_m": self.stopping_distance_m,
                "settled_time_s": self.settled_time_s, "end_time_s": self.end_time_s,
                "end": self.end, "peak_draft_kN": p.draft_N / 1e3,
                "peak_draft_coupler": p.draft_coupler, "peak_draft_time_s": p.draft_time_s,
                "peak_buff_kN": p.buff_N / 1e3, "peak_buff_coupler": p.buff_coupler,
                "peak_buff_time_s": p.buff_time_s, "verdicts": self.verdicts.as_dict()}


class Standstill:
    """A standstill of the train within a window: when it began and settled, what each
    vehicle had to hold, and any runaway.

    Attributes
    ----------
    start_s : float
        The first standstill (or 0 for a train that starts at rest) [s].
    settled_s : float or None
        Since when every vehicle has stayed within the standstill speed [s].
    need_N, capacity_N, need_time_s : ndarray or None
        Each vehicle's worst force to hold at rest, what it holds then, and when, judged at the
        chunk ends while settled (None: never judged).
    runaway_kmh, runaway_time_s : ndarray or None
        Each vehicle's largest speed after the train had settled, without traction
        commanded [km/h], and when it first moved [s] (-1: it did not); None: no runaway.
    """

    __slots__ = ("start_s", "settled_s", "need_N", "capacity_N", "need_time_s",
                 "runaway_kmh", "runaway_time_s")

    def __init__(self, start_s: float):
        self.start_s = float(start_s)
        self.settled_s: float | None = None
        self.need_N = self.capacity_N = self.need_time_s = None
        self.runaway_kmh = self.runaway_time_s = None

    def copy(self) -> "Standstill":
        """An independent copy."""
        new = Standstill(self.start_s)
        for name in self.__slots__:
            value = getattr(self, name)
            setattr(new, name, value.copy() if isinstance(value, np.ndarray) else value)
        return new

    def judge_rest(self, t: float, need_N: np.ndarray, capacity_N: np.ndarray,
                   tolerance_N: np.ndarray | float = 0.0) -> np.ndarray:
        """Take a chunk end at rest into account: each vehicle's force to hold [N] against what
        it holds [N] at time ``t`` [s], beyond it by more than ``tolerance_N`` (the accuracy of
        the forces) [N] a failure.

        Returns
        -------
        ndarray of bool
            Vehicles needing more than they hold for the first time.
        """
        need, cap = np.abs(np.asarray(need_N, float)), np.asarray(capacity_N, float)
        # within the tolerance a vehicle holds what it may: its need counts as its capacity
        need = np.where((need > cap) & (need <= cap + tolerance_N), cap, need)
        if self.need_N is None:
            self.need_N, self.capacity_N = need.copy(), cap.copy()
            self.need_time_s = np.full(need.size, float(t))
            return need > cap
        was = self.need_N > self.capacity_N
        worse = need * self.capacity_N > self.need_N * cap  # need / cap grew
        self.need_N[worse], self.capacity_N[worse] = need[worse], cap[worse]
        self.need_time_s[worse] = t
        return (need > cap) & ~was

    def moved(self, t: float, speed_m_s: np.ndarray, v_stop: float) -> np.ndarray:
        """Take a time ``t`` [s] after the train had settled into account, with each vehicle's
        speed [m/s]: the runaway records (any vehicle faster than ``v_stop`` [m/s]).

        Returns
        -------
        ndarray of bool
            Vehicles moving for the first time.
        """
        v = np.abs(np.asarray(speed_m_s, float))
        if self.runaway_kmh is None:
            self.runaway_kmh = np.zeros(v.size)
            self.runaway_time_s = np.full(v.size, -1.0)
        fast = v > v_stop
        first = fast & (self.runaway_time_s < 0.0)
        self.runaway_time_s[first] = t
        self.runaway_kmh = np.maximum(self.runaway_kmh, np.where(fast, v * KMH_PER_MS, 0.0))
        return first


class OpenStop:
    """A stop while it runs (:class:`StopRecord` is its frozen view)."""

    __slots__ = ("number", "command", "command_time_s", "command_speed_m_s", "command_head_m",
                 "stop_time_s", "stopping_distance_m", "end_time_s", "end", "peaks")

    def __init__(self, number: int, command: str, t: float, speed_m_s: float, head_m: float):
        self.number, self.command = number, command
        self.command_time_s, self.command_speed_m_s, self.command_head_m = (
            float(t), float(speed_m_s), float(head_m))
        self.stop_time_s = self.stopping_distance_m = self.end_time_s = None
        self.end = "open"
        self.peaks: CouplerPeaks | None = None  # from the command to the standstill

    def copy(self) -> "OpenStop":
        """An independent copy."""
        new = object.__new__(OpenStop)
        for name in self.__slots__:
            setattr(new, name, getattr(self, name))
        return new


class Window:
    """A part of a run judged on its own (see the module).

    Attributes
    ----------
    start_s : float
        When it began [s].
    watch : Watch
        Follows its limits (:class:`~ltd_brake_ros.verdicts.Watch`).
    stop : OpenStop or None
        The stop it belongs to (None: a part of the run without one).
    standstill : Standstill or None
        Its standstill, once the train stands.
    extremes : Extremes or None
        The kernel's records, copied when the window closed (None: open, the kernel holds
        them).
    end_s : float or None
        When it closed [s].
    verdicts : Verdicts or None
        A closed window's verdicts by the limits it was watched with, once asked for.
    """

    __slots__ = ("start_s", "watch", "stop", "standstill", "extremes", "end_s", "verdicts")

    def __init__(self, start_s: float, watch, stop: OpenStop | None = None):
        self.start_s, self.watch, self.stop = float(start_s), watch, stop
        self.standstill: Standstill | None = None
        self.extremes: Extremes | None = None
        self.end_s: float | None = None
        self.verdicts: Verdicts | None = None  # a closed window's, by the watched limits

    def copy(self) -> "Window":
        """An independent copy (its stop is copied by the state that holds it)."""
        new = object.__new__(Window)
        new.start_s, new.end_s, new.stop = self.start_s, self.end_s, self.stop
        new.watch = self.watch.copy()
        new.standstill = None if self.standstill is None else self.standstill.copy()
        new.extremes, new.verdicts = self.extremes, self.verdicts  # immutable once set
        return new

    def holding(self) -> tuple | None:
        """(force to hold, what is held, when) of each vehicle at rest, or None."""
        s = self.standstill
        if s is None or s.need_N is None:
            return None
        return s.need_N, s.capacity_N, s.need_time_s

    def runaway(self) -> tuple | None:
        """(largest speed after settling [km/h], when it first moved [s]) of each vehicle, or
        None when the train never settled in this window."""
        s = self.standstill
        if s is None or s.settled_s is None:
            return None
        if s.runaway_kmh is None:
            n = self.watch.limits.adhesion_limit.size
            return np.zeros(n), np.full(n, -1.0)
        return s.runaway_kmh, s.runaway_time_s


def start_rest(control: np.ndarray, t: float, speed_m_s: np.ndarray, v_stop: float) -> None:
    """Start watching a train settle at time ``t`` [s]: at rest since then if every vehicle is
    within ``v_stop`` [m/s] (the kernel's ``REST_SINCE`` record, in place)."""
    control[REST_SINCE] = t if bool((np.abs(speed_m_s) <= v_stop).all()) else -1.0


def phase_name(phase: int) -> str:
    """``moving``, ``braking``, ``settling``, ``at rest`` or ``runaway``."""
    return ("moving", "braking", "settling", "at rest", "runaway")[phase]


def finite_or_none(x: float | None) -> float | None:
    """``x`` if it is a finite number, else None."""
    return x if x is not None and math.isfinite(x) else None

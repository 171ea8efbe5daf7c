"""Analysis of a recorded run: the numbers a railway engineer asks first.

Plots are drawn by :mod:`.plots`, the arrays exported as CSV by :mod:`.export`.

The report reads only what the plant published (the recorded topics), so it gives the same
answer for a live ``sim_node`` run, a replayed one and an offline recording.

Topics used (any namespace; the first one holding ``vehicles/speed`` is analysed):

==============================  ===========================================================
``<ns>/vehicles/speed``         speed of each vehicle, head first [m/s]
``<ns>/vehicles/position``      chainage of each vehicle [m]
``<ns>/vehicles/brake_force``   air-brake retarding force of each vehicle [N]
``<ns>/couplers/force``         coupler force, coupler 1 behind the head; draft (tension)
                                positive, buff (compression) negative [N]
``<ns>/brake_command``          emergency brake command (std_msgs/Bool)
``<ns>/vehicles/brake_pipe_``   gauge brake-pipe and brake-cylinder pressure of each vehicle
``pressure``, ``<ns>/vehicles/  [Pa], published by a brake model with a pipe (optional)
brake_cylinder_pressure``
==============================  ===========================================================

Definitions: the emergency command is the first ``brake_command`` that is true, or
``driver_brake_valve`` in its ``emergency`` position (its record time), and the speed at it
the head's, interpolated between samples; the train has stopped at the first recorded ``vehicles/speed`` sample at or after the command in which no vehicle moves
forward faster than ``STANDSTILL_M_S`` (1 mm/s, as the simulator counts a stop: a vehicle
pulled back a few centimetres as the couplers relax has stopped); the stopping distance is
the head's position then minus its position at the command (interpolated between samples).
Peak forces are the extremes over the whole recording.

Samples are read in log-time order and checked (:mod:`.samples`): a plant topic of another
type, a payload that does not decode, a non-finite value, arrays that do not describe one train
or run information at odds with them end in :class:`~ltd_brake_ros.recording.reader.BagError`,
never in a report of part of the data.

Verdicts (:mod:`ltd_brake_ros.verdicts`) judge the recorded peaks by the limits in the run
information (``limits``, stored by the recorder); without them, the coupler criteria use the
standard defaults and adhesion is not assessed (the vehicle masses are unknown). The adhesion
records (mean utilised adhesion, demand above and below 30 km/h) and the couplers' travel
(deflections from the vehicles' positions, the first sample unloaded) are taken at the
recorded instants: the same definitions as the simulator's, sampled more coarsely.

The brake pipe, when recorded: pipe-pressure profiles along the train just before the pipe
first moves (some vehicle's pressure differs from its first sample, or from its sample at the
emergency command, by more than :data:`PIPE_ONSET_PA`), at :data:`PIPE_PROFILE_OFFSETS_S`
after that and at the end; the cylinder pressure of the head wagon and the tail over time; the
pressures at the end, and the time from the command until each of those cylinders first
reached 95 % of its final pressure (interpolated between samples; only for a cylinder that
holds at least :data:`APPLIED_PA` at the end).

The file is streamed: time series of the head and tail (a few numbers per sample) are kept,
the coupler heat map is reduced on the fly to at most a few thousand time bins (each holding
the force of largest magnitude in it, sign kept), the pipe to the few profiles above, and the
CSV export re-reads the file.
"""
from __future__ import annotations

import math
import warnings
from array import array
from dataclasses import dataclass, field

import numpy as np

from ..physics.brakes.thermal import Peaks
from ..physics.constants import KMH_PER_MS, STANDSTILL_M_S
from ..recording.cdr import decode_string
from ..recording.reader import BagError, TruncatedBagWarning, bag_info, read_bag
from ..simulator import CouplerPeaks
from ..verdicts import (CRITERIA, SampledDemand, TrainLimits, Verdicts,
                        default_coupler_limits, judge, limits_from_metadata)
from .samples import BRAKE_COMMAND, DESCRIPTION, STOPS, plant_samples

__all__ = ["RunReport", "analyse"]

_HEAT_BINS = 1500
#: Times of the pipe-pressure profiles kept, after the pipe first moves [s]: the emergency
#: wave crosses a 150 m train in about 0.6 s and a 1 000 m one in about 4 s (250-280 m/s), G
#: cylinders fill in 18-30 s (UIC 540), and a wave without acceleration chambers (90-180 m/s)
#: takes about a minute along 1 000 wagons.
PIPE_PROFILE_OFFSETS_S = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
#: Pipe-pressure change that counts as the pipe moving [Pa]: a tenth of the first service
#: step's reduction, 0.4 bar (UIC 540).
PIPE_ONSET_PA = 0.04e5
#: Cylinder pressure below which a cylinder counts as released, for the 95 % filling time
#: [Pa, gauge]: a tenth of the pressure of a first service step (about 1 bar, UIC 540).
APPLIED_PA = 0.1e5
#: Share of the final cylinder pressure whose first reaching is reported (UIC 540's filling
#: time is measured to 95 %).
FILLED = 0.95
_SIGN = ("coupler force: draft (tension) positive, buff (compression) negative; "
         "coupler 1 is behind the head")


# --------------------------------------------------------------------------- streaming pieces


class _Series:
    """Growing float64 columns (8 bytes a value)."""

    def __init__(self, *names):
        self.cols = {n: array("d") for n in names}

    def add(self, *values):
        for col, v in zip(self.cols.values(), values):
            col.append(v)

    def np(self, name) -> np.ndarray:
        return np.frombuffer(self.cols[name], dtype=float).copy() if self.cols[name] \
            else np.zeros(0)

    def __len__(self):
        return len(next(iter(self.cols.values())))


class _HeatMap:
    """Coupler force over time reduced to at most ``2 * max_bins`` bins, streaming.

    Each bin holds, per coupler, the sample of largest magnitude (sign kept), so peaks stay
    visible however long the run. When the bins fill, neighbours merge and the bin doubles.
    """

    def __init__(self, max_bins: int = _HEAT_BINS):
        self.max_bins = max_bins
        self.per_bin = 1
        self.values = None
        self.t0 = array("d")
        self.t1 = array("d")
        self.n = 0
        self._cur = None
        self._cur_n = 0

    def add(self, t: float, f: np.ndarray) -> None:
        """Add one sample (every sample the same length) at time ``t`` [s]."""
        if self._cur is None:
            self.values = np.zeros((2 * self.max_bins, f.size))
            self._cur = f.copy()
            self._cur_t0 = t
            self._cur_n = 1
        elif self._cur_n == 0:
            self._cur[:] = f
            self._cur_t0 = t
            self._cur_n = 1
        else:
            np.copyto(self._cur, f, where=np.abs(f) > np.abs(self._cur))
            self._cur_n += 1
        self._cur_t1 = t
        if self._cur_n >= self.per_bin:
            self._push()

    def _push(self) -> None:
        self.values[self.n] = self._cur
        self.t0.append(self._cur_t0)
        self.t1.append(self._cur_t1)
        self.n += 1
        self._cur_n = 0
        if self.n == self.values.shape[0]:  # full: merge neighbours, all of the same width
            a, b = self.values[0:self.n:2], self.values[1:self.n:2]
            self.values[: self.n // 2] = np.where(np.abs(b) > np.abs(a), b, a)
            self.t0 = self.t0[0::2]
            self.t1 = self.t1[1::2]
            self.n //= 2
            self.per_bin *= 2

    def result(self):
        if self._cur is not None and self._cur_n:
            self._push()
        if self.values is None:
            return np.zeros(0), np.zeros(0), np.zeros((0, 0))
        return (np.asarray(self.t0), np.asarray(self.t1), self.values[: self.n].copy())


# --------------------------------------------------------------------------- the report


@dataclass
class RunReport:
    """What :func:`analyse` found in a recording. Times are simulation times [s].

    Attributes
    ----------
    source : str
        The recording analysed.
    namespace : str
        Namespace of the analysed topics (``/train1``), ``""`` for the root.
    metadata : dict
        Run information stored by the recorder (consist summary, parameters, scenario).
    topics : dict of str to int
        Messages per recorded topic.
    complete : bool
        The recording was finished properly (False: read up to the last complete chunk).
    n_vehicles, n_couplers : int
    start_time_s, end_time_s : float
        First and last recorded sample.
    command_time_s : float or None
        First emergency command.
    command_speed_kmh : float or None
        Head speed at it [km/h].
    stop_time_s : float or None
        When the train stood still (see the module notes).
    stopping_time_s, stopping_distance_m : float or None
        From the command to the stop.
    peak_draft_kN, peak_buff_kN : float
        Largest draft (positive) and buff (negative) coupler force [kN].
    peak_draft_coupler, peak_buff_coupler : int
        Coupler number, 1 behind the head (0 when there are no couplers).
    peak_draft_time_s, peak_buff_time_s : float
    coupler_peak_draft_N, coupler_peak_buff_N : ndarray
        Per coupler along the train [N].
    coupler_peak_draft_time_s, coupler_peak_buff_time_s : ndarray
    speed_time_s, head_speed_m_s, tail_speed_m_s : ndarray
    brake_time_s, head_wagon_brake_force_N, tail_brake_force_N : ndarray
        Brake force of the first wagon behind the head vehicle and of the last vehicle.
    head_wagon_index : int
        Vehicle index (0 = head) of the "head wagon" plotted.
    heat_t0_s, heat_t1_s, heat_force_N : ndarray
        Coupler-force heat map: time span of each bin, and (bins x couplers) forces.
    pipe_distance_m : ndarray
        Each vehicle's distance behind the head at the first recorded position [m] (vehicle
        index when no positions were recorded); empty without a recorded brake pipe.
    pipe_profile_time_s, pipe_profile_Pa : ndarray
        Times of the kept pipe-pressure profiles [s] and (profiles x vehicles) gauge pressure
        [Pa] (see the module notes).
    cylinder_time_s, head_wagon_cylinder_Pa, tail_cylinder_Pa : ndarray
        Gauge cylinder pressure of the head wagon and the tail over time [Pa].
    pipe_reference_time_s : float or None
        Time the filling times count from: the command, else the first sample [s].
    head_pipe_end_Pa, tail_pipe_end_Pa : float or None
        Gauge pipe pressure at the head and the tail in the last sample [Pa].
    head_wagon_cylinder_end_Pa, tail_cylinder_end_Pa : float or None
        Gauge cylinder pressure in the last sample [Pa].
    head_wagon_fill_time_s, tail_fill_time_s : float or None
        From ``pipe_reference_time_s`` until the cylinder first reached 95 % of its final
        pressure [s] (None: released at the end, or never reached after the reference).
    limits : TrainLimits or None
        The limits the verdicts judge by.
    verdicts : Verdicts or None
        Strength and adhesion verdicts (None: no vehicle speeds recorded).
    temperature_time_s, hottest_block_K, hottest_wheel_K : ndarray
        The hottest vehicle's blocks and wheels over time [s, K] (empty: not recorded).
    temperatures : Peaks or None
        The hottest blocks and wheels of the run, which vehicle and when
        (:class:`~ltd_brake_ros.physics.brakes.thermal.Peaks`; None: not recorded).
    stops : list of dict
        Each stop the plant recorded on its stops topic (``train/stops``), in order, with the
        keys of :class:`~ltd_brake_ros.stops.StopRecord`'s JSON: ``number``, ``command``
        (``emergency`` or ``service``), ``command_time_s``, ``command_speed_kmh``,
        ``stop_time_s``, ``stop_duration_s`` and ``stopping_distance_m`` (None: not at a
        standstill), ``settled_time_s``, ``end_time_s``, ``end`` (``drive-off``, ``new stop``,
        ``end of run``, or ``open``: the recording ended within the stop), the peaks from the
        command to the standstill (``peak_draft_kN``, ``peak_draft_coupler``,
        ``peak_buff_kN``, ``peak_buff_coupler`` and their times), ``verdict`` (the stop's
        status; None while open) and ``criteria`` (criterion name to status). Empty for a
        recording without the topic.
    stamped : bool
        Times come from the stamped states (a recording by another recorder, e.g.
        ``ros2 bag record``), not from the log times.
    notes : list of str
        Where the time base and the run information came from, and what could not be
        recovered.
    """

    source: str
    namespace: str = ""
    metadata: dict = field(default_factory=dict)
    topics: dict = field(default_factory=dict)
    complete: bool = True
    n_vehicles: int = 0
    n_couplers: int = 0
    start_time_s: float = 0.0
    end_time_s: float = 0.0
    command_time_s: float | None = None
    command_speed_kmh: float | None = None
    stop_time_s: float | None = None
    stopping_time_s: float | None = None
    stopping_distance_m: float | None = None
    peak_draft_kN: float = 0.0
    peak_draft_coupler: int = 0
    peak_draft_time_s: float = 0.0
    peak_buff_kN: float = 0.0
    peak_buff_coupler: int = 0
    peak_buff_time_s: float = 0.0
    coupler_peak_draft_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coupler_peak_draft_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coupler_peak_buff_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coupler_peak_buff_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    speed_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_speed_m_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tail_speed_m_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    brake_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_wagon_brake_force_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tail_brake_force_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_wagon_index: int = 0
    heat_t0_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    heat_t1_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    heat_force_N: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    pipe_distance_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pipe_profile_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pipe_profile_Pa: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    cylinder_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head_wagon_cylinder_Pa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tail_cylinder_Pa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pipe_reference_time_s: float | None = None
    head_pipe_end_Pa: float | None = None
    tail_pipe_end_Pa: float | None = None
    head_wagon_cylinder_end_Pa: float | None = None
    tail_cylinder_end_Pa: float | None = None
    head_wagon_fill_time_s: float | None = None
    tail_fill_time_s: float | None = None
    limits: TrainLimits | None = None
    verdicts: Verdicts | None = None
    plots: list = field(default_factory=list)
    stamped: bool = False
    notes: list = field(default_factory=list)
    temperature_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hottest_block_K: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hottest_wheel_K: np.ndarray = field(default_factory=lambda: np.zeros(0))
    temperatures: Peaks | None = None
    stops: list = field(default_factory=list)

    @property
    def warnings(self) -> list[str]:
        """Where the recorded run left its models' validated ranges (from its run
        information)."""
        found = self.metadata.get("warnings")
        return [str(w) for w in found] if isinstance(found, list) else []

    @property
    def has_brake_pipe(self) -> bool:
        """A brake pipe was recorded (its profiles and cylinder pressures are here)."""
        return bool(self.pipe_profile_Pa.size)

    def as_dict(self) -> dict:
        """Scalars, consist summary and per-coupler peaks, JSON-serialisable."""
        keys = ("source", "namespace", "complete", "n_vehicles", "n_couplers", "start_time_s",
                "end_time_s", "command_time_s", "command_speed_kmh", "stop_time_s",
                "stopping_time_s",
                "stopping_distance_m", "peak_draft_kN", "peak_draft_coupler",
                "peak_draft_time_s", "peak_buff_kN", "peak_buff_coupler", "peak_buff_time_s")
        out = {k: getattr(self, k) for k in keys}
        out["metadata"] = self.metadata
        out["topics"] = self.topics
        out["coupler_peaks"] = {
            "coupler": list(range(1, self.n_couplers + 1)),
            "peak_draft_N": self.coupler_peak_draft_N.tolist(),
            "peak_draft_time_s": self.coupler_peak_draft_time_s.tolist(),
            "peak_buff_N": self.coupler_peak_buff_N.tolist(),
            "peak_buff_time_s": self.coupler_peak_buff_time_s.tolist()}
        out["verdicts"] = None if self.verdicts is None else self.verdicts.as_dict()
        out["brake_pipe"] = None if not self.has_brake_pipe else {
            k: getattr(self, k) for k in (
                "pipe_reference_time_s", "head_pipe_end_Pa", "tail_pipe_end_Pa",
                "head_wagon_cylinder_end_Pa", "tail_cylinder_end_Pa", "head_wagon_fill_time_s",
                "tail_fill_time_s", "head_wagon_index")}
        out["sign_convention"] = _SIGN
        out["plots"] = [str(p) for p in self.plots]
        out["warnings"] = self.warnings
        out["brake_heat"] = None if self.temperatures is None else self.temperatures.as_dict()
        out["stops"] = [dict(s) for s in self.stops]
        out["time_base"] = "state header stamps" if self.stamped else "log times"
        out["notes"] = list(self.notes)
        return out

    def describe(self) -> str:
        """Human-readable summary."""
        lines = [f"Run: {self.source}" + ("" if self.complete else
                                          "  (unfinished recording: read to its last "
                                          "complete chunk)")]
        c = self.metadata.get("consist")
        if isinstance(c, dict):
            parts = [str(c.get("name", "consist"))]
            for key, text in (("vehicles", "{} vehicles"), ("length_m", "{} m"),
                              ("mass_t", "{} t"), ("braked_weight_percent", "braked weight {} %")):
                if key in c:
                    parts.append(text.format(_shown(c[key], ".0f" if key == "vehicles" else ".1f")))
            lines.append("Consist: " + ", ".join(parts))
        else:
            lines.append(f"Consist: not recorded ({self.n_vehicles} vehicles in the data)")
        if "initial_speed_kmh" in self.metadata:
            lines.append(f"Initial speed: {_shown(self.metadata['initial_speed_kmh'], '.1f')} "
                         "km/h")
        if "scenario" in self.metadata:
            lines.append(f"Scenario: {self.metadata['scenario']}")
        lines.append(f"Recorded: t = {self.start_time_s:.2f} to {self.end_time_s:.2f} s, "
                     f"{sum(self.topics.values())} messages on {len(self.topics)} topics")
        if self.command_time_s is None:
            lines.append("Emergency command: none recorded")
        else:
            speed = "" if self.command_speed_kmh is None else \
                f" at {self.command_speed_kmh:.2f} km/h"
            lines.append(f"Emergency command: t = {self.command_time_s:.2f} s{speed}")
        if self.stop_time_s is None:
            if self.command_time_s is not None:
                lines.append("Stop: the train had not stopped when the recording ended")
        else:
            lines.append(f"Stopped: t = {self.stop_time_s:.2f} s; from the command: stopping "
                         f"distance {self.stopping_distance_m:.1f} m, stopping time "
                         f"{self.stopping_time_s:.2f} s")
        lines += [_describe_stop(s) for s in self.stops]
        if self.n_couplers:
            lines.append(f"Peak draft: {round(self.peak_draft_kN, 1) + 0.0:.1f} kN at coupler "
                         f"{self.peak_draft_coupler} (t = {self.peak_draft_time_s:.2f} s)")
            # + 0.0: a buff that rounds to nothing prints 0.0, not -0.0
            lines.append(f"Peak buff: {round(self.peak_buff_kN, 1) + 0.0:.1f} kN at coupler "
                         f"{self.peak_buff_coupler} (t = {self.peak_buff_time_s:.2f} s)")
            lines.append(f"Sign convention: {_SIGN}")
        if self.has_brake_pipe:
            lines += self._describe_pipe()
        if self.verdicts is not None:
            lines.append(f"Verdicts: {self.verdicts.status}" + (
                "  (NON-PHYSICAL: couplers beyond their travel)"
                if self.verdicts.non_physical else ""))
            lines += [f"  {line}" for line in self.verdicts.describe()]
        for p in self.plots:
            lines.append(f"Plot: {p}")
        if self.temperatures is not None:
            lines.append(f"Brake heat: {self.temperatures.describe()}")
        lines += [f"Warning: {w}" for w in self.warnings]
        lines += [f"Note: {note}" for note in self.notes]
        return "\n".join(lines)

    def _describe_pipe(self) -> list[str]:
        """The brake-pipe summary lines (pressures in bar, gauge)."""
        since = "the command" if self.command_time_s is not None else "the start"
        tail = max(self.n_vehicles - 1, 0)
        lines = [f"Brake pipe at the end (t = {self.end_time_s:.2f} s): "
                 f"{self.head_pipe_end_Pa / 1e5:.2f} bar at the head, "
                 f"{self.tail_pipe_end_Pa / 1e5:.2f} bar at the tail (gauge)"]
        for name, j, end, fill in (
                ("head wagon", self.head_wagon_index, self.head_wagon_cylinder_end_Pa,
                 self.head_wagon_fill_time_s),
                ("tail", tail, self.tail_cylinder_end_Pa, self.tail_fill_time_s)):
            text = f"Brake cylinder, {name} (vehicle {j}): {end / 1e5:.2f} bar at the end"
            if fill is not None:
                text += f"; 95 % of it {fill:.2f} s after {since}"
            lines.append(text)
        return lines


def _number(value) -> float | None:
    """``value`` if it is a finite real number (not a bool), else None."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return None
    try:
        number = float(value)
    except OverflowError:  # an int beyond float range
        return None
    return number if np.isfinite(number) else None


def _shown(value, spec: str) -> str:
    """A run-information value as text: a number formatted with ``spec``, anything else as is."""
    number = _number(value)
    return format(number, spec) if number is not None else f"{value!s:.40}"


def _time_base(path, info, ns: str) -> tuple[dict, bool, list]:
    """Run information, whether to read simulated time from the state stamps, and notes.

    A plant's own recording (``record:=true``, ``simulate --record``, ``campaign rerun``)
    stores its run information and logs every message at its simulated time. Another
    recorder (``ros2 bag record``) logs receive times: then time comes from the stamped
    states, and the run information from the latched train description if it was recorded.
    """
    import json

    if isinstance(info.metadata.get("consist"), dict):
        return info.metadata, False, []
    notes = []
    stamped = f"{ns}/vehicles/state" in info.topics
    if stamped:
        notes.append("not a plant's own recording: times are the simulated times stamped on "
                     f"{ns}/vehicles/state and {ns}/couplers/state, not the receive times")
    else:
        notes.append(f"no run information and no {ns}/vehicles/state: times are the log "
                     "times, which another recorder sets to receive times")
    metadata = dict(info.metadata)
    topic = f"{ns}/{DESCRIPTION}"
    if topic in info.topics:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TruncatedBagWarning)
            for name, _type, _log, data in read_bag(path):
                if name != topic:
                    continue
                try:
                    run = json.loads(decode_string(data)).get("run")
                except (ValueError, AttributeError):
                    run = None
                if isinstance(run, dict):
                    metadata.update(run)
                    notes.append(f"run information from {topic}")
                else:
                    notes.append(f"{topic} does not hold a train description: consist, limits "
                                 "and speed unknown")
                break
    else:
        notes.append(f"no {topic} recorded: consist, limits and initial speed unknown "
                     "(verdicts use the default limits)")
    return metadata, stamped, notes


#: Where a recording's at-rest checks are: in the plant's own verdicts of each stop.
_BY_STOP = " (the plant judged it at each stop: see the stops above)"


class _Stops:
    """Each stop's record, rebuilt from the plant's stop events (see :attr:`RunReport.stops`)."""

    _PEAKS = ("stopping_distance_m", "peak_draft_kN", "peak_draft_coupler", "peak_draft_time_s",
              "peak_buff_kN", "peak_buff_coupler", "peak_buff_time_s")

    def __init__(self):
        self.records: list[dict] = []
        self._open: dict[int, dict] = {}

    def add(self, t: float, event: dict) -> None:
        if _number(event.get("time_s")) is not None:
            t = float(event["time_s"])  # the event's own simulated time, not its chunk's end
        kind, number = event.get("event"), event.get("stop")
        if kind == "stop_started":
            rec = {"number": number, "command": event.get("command"), "command_time_s": t,
                   "command_speed_kmh": event.get("command_speed_kmh"), "stop_time_s": None,
                   "stop_duration_s": None, "stopping_distance_m": None,
                   "settled_time_s": None, "end_time_s": None, "end": "open",
                   **{k: None for k in self._PEAKS[1:]}, "verdict": None, "criteria": {}}
            self.records.append(rec)
            self._open[number] = rec
            return
        rec = self._open.get(number)
        if rec is None:  # an event of a stop that started before the recording did
            return
        if kind == "stop_abandoned":
            self.records.remove(rec)
            del self._open[number]
        elif kind == "stopped":
            rec["stop_time_s"] = t
            rec["stop_duration_s"] = event.get("stop_time_s")
            rec.update({k: event.get(k) for k in self._PEAKS})
        elif kind == "settled":
            rec["settled_time_s"] = event.get("settled_time_s")
        elif kind == "stop_ended":
            rec["end"], rec["end_time_s"] = event.get("end"), t
            rec["verdict"] = event.get("verdicts")
            rec["criteria"] = {k[len("verdict_"):]: v for k, v in event.items()
                               if k.startswith("verdict_")}
            del self._open[number]


def _describe_stop(s: dict) -> str:
    """One line of a recorded stop."""
    def num(key, fmt):
        value = s.get(key)
        return "?" if not isinstance(value, (int, float)) else format(value, fmt)

    text = (f"Stop {s['number']} ({s['command']}, t = {num('command_time_s', '.2f')} s at "
            f"{num('command_speed_kmh', '.1f')} km/h): ")
    if s["stop_time_s"] is None:
        text += "not at a standstill when it ended" if s["end"] != "open" else \
            "moving when the recording ended"
    else:
        text += (f"{num('stopping_distance_m', '.1f')} m in {num('stop_duration_s', '.2f')} s, "
                 f"peak draft {num('peak_draft_kN', '.1f')} kN, peak buff "
                 f"{num('peak_buff_kN', '.1f')} kN")
        if s["settled_time_s"] is not None:
            text += f", settled t = {num('settled_time_s', '.2f')} s"
    if s["end"] == "open":
        return text + "; open at the end of the recording"
    return text + f"; ended by {s['end']} (t = {num('end_time_s', '.2f')} s): {s['verdict']}"


def _find_namespace(path, topics, namespace: str | None) -> str:
    if namespace is not None:
        return namespace.rstrip("/")
    candidates = [t[: -len("/vehicles/speed")] for t in topics if t.endswith("/vehicles/speed")]
    if not candidates:
        raise BagError(path, "", "the recording has no <ns>/vehicles/speed topic: nothing to "
                                 "analyse")
    return candidates[0]


def analyse(path, namespace: str | None = None) -> RunReport:
    """Analyse a recorded run (streaming).

    Parameters
    ----------
    path : str or path-like
        Bag folder or ``.mcap`` file; an unfinished file is read to its last complete chunk.
    namespace : str, optional
        Namespace of the plant's topics (default: the first with ``vehicles/speed``).

    Returns
    -------
    RunReport

    Raises
    ------
    BagError
        The recording cannot be read, holds no vehicle speeds, or its plant topics hold what
        the plant never publishes (see :mod:`.samples`).
    """
    info = bag_info(path)
    ns = _find_namespace(path, info.topics, namespace)
    metadata, stamped, notes = _time_base(path, info, ns)
    if info.unfinished:
        notes.insert(0, info.unfinished)
    watch = None  # verdict tracking, once the train's size is known
    speed = _Series("t", "head", "tail", "vmax")
    pos = _Series("t", "head")
    brake = _Series("t", "head", "tail")
    heat = _HeatMap()
    draft = draft_t = buff = buff_t = None
    command_t = None
    n_vehicles = 0
    head_wagon = None
    first_position = None
    pipe = _Pipe()
    heat_watch = _Heat()
    stops = _Stops()
    for name, t, _log_ns, value in plant_samples(path, ns, stamped):
        if name == STOPS:
            stops.add(t, value)
        elif name == "vehicles/speed":
            n_vehicles = value.size
            speed.add(t, value[0], value[-1], float(value.max()))  # forward speed
            if watch is None:
                watch = _Watch(metadata, n_vehicles)
            watch.speed = value
        elif name == "vehicles/position":
            pos.add(t, value[0])
            if first_position is None:
                first_position = value
            if watch is not None:
                watch.positions(t, value)
        elif name == "vehicles/brake_force":
            if head_wagon is None:
                head_wagon = 1 if value.size > 1 else 0
            brake.add(t, value[head_wagon], value[-1])
            if watch is not None:
                watch.brake(t, value)
        elif name == "couplers/force":
            if not value.size:
                continue
            if draft is None:
                draft = np.zeros(value.size)
                buff = np.zeros(value.size)
                draft_t = np.zeros(value.size)
                buff_t = np.zeros(value.size)
            up = value > draft
            draft[up] = value[up]
            draft_t[up] = t
            down = value < buff
            buff[down] = value[down]
            buff_t[down] = t
            heat.add(t, value)
            if watch is not None:
                watch.couplers(t, value)
        elif name == BRAKE_COMMAND and command_t is None and value:
            command_t = t
            pipe.command()
        elif name == "vehicles/block_temperature":
            heat_watch.add("block", t, value)
        elif name == "vehicles/wheel_temperature":
            heat_watch.add("wheel", t, value)
        elif name == "vehicles/brake_pipe_pressure":
            pipe.pipe(t, value)
        elif name == "vehicles/brake_cylinder_pressure":
            pipe.cylinder(t, value)
    if not len(speed):
        raise BagError(path, f"{ns}/vehicles/speed", "no samples recorded: nothing to analyse")
    vehicles = metadata.get("consist", {}).get("vehicles") \
        if isinstance(metadata.get("consist"), dict) else None
    if _number(vehicles) is not None and vehicles != n_vehicles:
        raise BagError(path, f"{ns}/vehicles/speed", f"{n_vehicles} vehicles in the arrays, but "
                       f"the run information says {vehicles}: they are not of one run")
    if command_t is None:
        for key in ("emergency_time_s", "command_time_s"):
            if _number(metadata.get(key)) is not None:
                command_t = float(metadata[key])
                break
    if command_t is None:
        notes.append("no emergency command recorded (brake_command true or the driver's "
                     "brake valve at emergency): no stopping distance")
    ts, vmax = speed.np("t"), speed.np("vmax")
    rep = RunReport(source=str(path), namespace=ns, metadata=metadata,
                    topics={k: v.message_count for k, v in info.topics.items()},
                    complete=info.complete, n_vehicles=n_vehicles,
                    start_time_s=float(ts[0]) if stamped else info.start_ns * 1e-9,
                    end_time_s=float(ts[-1]) if stamped else info.end_ns * 1e-9,
                    stamped=stamped, notes=notes,
                    command_time_s=command_t, speed_time_s=ts,
                    head_speed_m_s=speed.np("head"), tail_speed_m_s=speed.np("tail"),
                    brake_time_s=brake.np("t"), head_wagon_brake_force_N=brake.np("head"),
                    tail_brake_force_N=brake.np("tail"), head_wagon_index=head_wagon or 0)
    if command_t is not None and ts.size:
        rep.command_speed_kmh = float(np.interp(command_t, ts, speed.np("head"))) * KMH_PER_MS
    if command_t is not None:
        after = np.flatnonzero((ts >= command_t - 1e-9) & (vmax <= STANDSTILL_M_S))
        if after.size:
            rep.stop_time_s = float(ts[after[0]])
            rep.stopping_time_s = rep.stop_time_s - command_t
            tp, xp = pos.np("t"), pos.np("head")
            if tp.size:
                rep.stopping_distance_m = float(
                    _head_position(tp, xp, ts, speed.np("head"), rep.stop_time_s)
                    - _head_position(tp, xp, ts, speed.np("head"), command_t))
    if draft is not None:
        rep.n_couplers = int(draft.size)
        rep.coupler_peak_draft_N, rep.coupler_peak_draft_time_s = draft, draft_t
        rep.coupler_peak_buff_N, rep.coupler_peak_buff_time_s = buff, buff_t
        peaks = CouplerPeaks.from_arrays(draft, draft_t, buff, buff_t)
        rep.peak_draft_kN, rep.peak_draft_coupler = peaks.draft_N / 1e3, peaks.draft_coupler
        rep.peak_draft_time_s = peaks.draft_time_s
        rep.peak_buff_kN, rep.peak_buff_coupler = peaks.buff_N / 1e3, peaks.buff_coupler
        rep.peak_buff_time_s = peaks.buff_time_s
        rep.heat_t0_s, rep.heat_t1_s, rep.heat_force_N = heat.result()
    rep.stops = stops.records
    pipe.result(rep, first_position,
                command_t if command_t is not None else rep.start_time_s)
    heat_watch.result(rep, metadata)
    if watch is not None and watch.fits(n_vehicles, rep.n_couplers):
        head = speed.np("head")

        def kmh(times):
            return np.interp(times, ts, head) * KMH_PER_MS
        rep.limits = watch.limits
        by_stop = _BY_STOP if any(s["verdict"] for s in rep.stops) else ""
        if rep.command_speed_kmh is not None:  # the stop starts at the brake command
            watch.sampled.command(rep.command_speed_kmh / KMH_PER_MS)
        rep.verdicts = judge(
            watch.limits, peak_draft_N=rep.coupler_peak_draft_N,
            peak_draft_time_s=rep.coupler_peak_draft_time_s,
            draft_speed_kmh=kmh(rep.coupler_peak_draft_time_s),
            peak_buff_N=rep.coupler_peak_buff_N, peak_buff_time_s=rep.coupler_peak_buff_time_s,
            buff_speed_kmh=kmh(rep.coupler_peak_buff_time_s),
            demand=watch.sampled.result() if watch.limits.adhesion_limit.size else None,
            rail_demand=watch.sampled.rail_demand() if watch.limits.adhesion_limit.size
            else None,
            travel_beyond_mm=watch.beyond_mm if watch._x0 is not None else None,
            travel_time_s=watch.beyond_t, travel_speed_kmh=watch.beyond_kmh,
            holding_reason="not assessed from a recording: it holds no brake state at rest"
            + by_stop, runaway_reason="not assessed from a recording: it holds no "
            "settling state" + by_stop,
            first_time_s=watch.first_time_s, wheel_temperature=heat_watch.peak.get("wheel"))
    return rep


class _Heat:
    """The brake-heat temperatures while the recording streams: the hottest vehicle in time
    and each vehicle's peak."""

    def __init__(self):
        self.series = {"block": _Series("t", "K"), "wheel": _Series("t", "K")}
        self.peak: dict = {}

    def add(self, which: str, t: float, value: np.ndarray) -> None:
        if not np.isfinite(value).any():
            return
        self.series[which].add(t, float(np.nanmax(value)))
        peak, when = self.peak.setdefault(which, (np.full(value.size, np.nan),
                                                  np.full(value.size, np.nan)))
        if peak.size != value.size:
            return  # the arrays' lengths are checked by the samples
        up = np.nan_to_num(value, nan=-np.inf) > np.nan_to_num(peak, nan=-np.inf)
        peak[up], when[up] = value[up], t

    def result(self, rep: "RunReport", metadata: dict) -> None:
        block, wheel = self.series["block"], self.series["wheel"]
        if not (len(block) and len(wheel)):
            return
        n = min(len(block), len(wheel))
        rep.temperature_time_s = block.np("t")[:n]
        rep.hottest_block_K, rep.hottest_wheel_K = block.np("K")[:n], wheel.np("K")[:n]
        ambient = metadata.get("ambient_temperature_K")
        rep.temperatures = Peaks.from_arrays(
            *self.peak["block"], *self.peak["wheel"],
            float(ambient) if _number(ambient) is not None else math.nan)


class _Pipe:
    """The brake pipe while the recording streams: a few profiles, two cylinders in time."""

    def __init__(self):
        self.first = None  # the first profile
        self.before = None  # the last profile before the pipe moved
        self.onset_s = None
        self.profiles: list = []  # (time [s], pressures [Pa]) from the onset on
        self.last = None
        self.ends = _Series("t", "head", "tail")
        self.cylinders = _Series("t", "head_wagon", "tail")

    def command(self) -> None:
        """The emergency command: the profiles start again from the pipe as it is now."""
        if self.last is not None:
            self.first = self.last[1]
            self.before = self.last
            self.onset_s = None
            self.profiles.clear()

    def pipe(self, t: float, value: np.ndarray) -> None:
        if self.first is None:
            self.first = value
        if self.onset_s is None:
            if float(np.abs(value - self.first).max()) <= PIPE_ONSET_PA:
                self.before = (t, value)
            else:
                self.onset_s = t
        if self.onset_s is not None and len(self.profiles) < len(PIPE_PROFILE_OFFSETS_S) and \
                t >= self.onset_s + PIPE_PROFILE_OFFSETS_S[len(self.profiles)] - 1e-9:
            self.profiles.append((t, value))
        self.last = (t, value)
        self.ends.add(t, value[0], value[-1])

    def cylinder(self, t: float, value: np.ndarray) -> None:
        # the head wagon as for the brake force: the first vehicle behind the head
        self.cylinders.add(t, value[1 if value.size > 1 else 0], value[-1])

    def result(self, rep: RunReport, first_position, reference_s: float) -> None:
        """Put what was kept into ``rep`` (nothing without a recorded pipe); the filling times
        count from ``reference_s`` [s]."""
        if self.last is None:
            return
        kept = [self.before] + self.profiles
        if kept[-1][0] < self.last[0]:
            kept.append(self.last)
        n = self.last[1].size
        rep.pipe_distance_m = (first_position[0] - first_position) if first_position is not None \
            else np.arange(n, dtype=float)
        rep.pipe_profile_time_s = np.array([t for t, _ in kept])
        rep.pipe_profile_Pa = np.array([p for _, p in kept])
        rep.pipe_reference_time_s = reference_s
        rep.head_pipe_end_Pa = float(self.ends.np("head")[-1])
        rep.tail_pipe_end_Pa = float(self.ends.np("tail")[-1])
        if not len(self.cylinders):
            return
        t = self.cylinders.np("t")
        rep.cylinder_time_s = t
        rep.head_wagon_cylinder_Pa = self.cylinders.np("head_wagon")
        rep.tail_cylinder_Pa = self.cylinders.np("tail")
        rep.head_wagon_cylinder_end_Pa = float(rep.head_wagon_cylinder_Pa[-1])
        rep.tail_cylinder_end_Pa = float(rep.tail_cylinder_Pa[-1])
        rep.head_wagon_fill_time_s = _fill_time(t, rep.head_wagon_cylinder_Pa, reference_s)
        rep.tail_fill_time_s = _fill_time(t, rep.tail_cylinder_Pa, reference_s)


def _fill_time(t: np.ndarray, p: np.ndarray, reference_s: float) -> float | None:
    """Time from ``reference_s`` until ``p`` first reached :data:`FILLED` of its last value
    [s], linear between samples; None if released at the end or never reached after it."""
    final = float(p[-1])
    if final < APPLIED_PA:
        return None
    after = np.flatnonzero(t >= reference_s - 1e-9)
    if not after.size:
        return None
    first = after[0]
    target = FILLED * final
    hit = np.flatnonzero(p[first:] >= target)
    if not hit.size:
        return None
    k = first + int(hit[0])
    if k == first:
        return float(t[k] - reference_s)
    t0, t1, p0, p1 = t[k - 1], t[k], p[k - 1], p[k]
    return float(t0 + (target - p0) / (p1 - p0) * (t1 - t0) - reference_s)


class _Watch:
    """Verdict tracking while the recording streams: first sample beyond each limit, each
    coupler's deflection against its travel, and each vehicle's adhesion records."""

    def __init__(self, metadata: dict, n_vehicles: int):
        self.limits = limits_from_metadata(metadata.get("limits"), n_vehicles) or \
            default_coupler_limits(n_vehicles)
        n, nc = self.limits.adhesion_limit.size, self.limits.draft_strength_N.size
        sizes = {"coupler": nc, "vehicle": n, "train": 1}
        self.first_time_s = {name: np.full(sizes[CRITERIA[name].element], -1.0)
                             for name in CRITERIA}
        self.sampled = SampledDemand(self.limits)
        self.speed = None
        self.position = None
        self._x0 = None  # the first positions: couplers start unloaded
        self.beyond_mm = np.zeros(nc)
        self.beyond_t = np.zeros(nc)
        self.beyond_kmh = np.full(nc, np.nan)

    def fits(self, n_vehicles: int, n_couplers: int) -> bool:
        """The limits are those of a train of this size (the arrays never changed size)."""
        return self.limits.draft_strength_N.size == n_couplers and \
            self.limits.adhesion_limit.size in (0, n_vehicles)

    def _first(self, name: str, t: float, over: np.ndarray) -> None:
        first = self.first_time_s[name]
        if over.shape == first.shape:
            first[over & (first < 0.0)] = t

    def couplers(self, t: float, force: np.ndarray) -> None:
        lim = self.limits
        if force.shape != lim.draft_strength_N.shape:
            return
        self._first("draft_strength", t, force > lim.draft_strength_N)
        self._first("buff_strength", t, -force > lim.buff_strength_N)
        self._first("endurable_lcf", t, -force > lim.endurable_lcf_N)
        self._first("buffer_limit_state", t, -force > lim.of("buffer_limit_state"))

    def positions(self, t: float, x: np.ndarray) -> None:
        self.position = x
        if self._x0 is None:
            self._x0 = x.copy()
        lo, hi = self.limits.travel_mm
        if x.shape != self._x0.shape or x.size != self.beyond_mm.size + 1:
            return
        d = (np.diff(-x) - np.diff(-self._x0)) * 1e3  # coupler deflections, draft positive
        beyond = np.maximum(np.maximum(d - hi, lo - d), 0.0)
        up = beyond > self.beyond_mm
        if up.any():
            self.beyond_mm[up] = beyond[up]
            self.beyond_t[up] = t
            if self.speed is not None and self.speed.size:
                self.beyond_kmh[up] = abs(float(self.speed[0])) * KMH_PER_MS
        self._first("coupler_travel", t, beyond > 0.0)

    def brake(self, t: float, force: np.ndarray) -> None:
        if self.speed is None or self.position is None:
            return
        self.sampled.add(t, self.speed, self.position, force)
        self.first_time_s["adhesion_demand"] = self.sampled.first_rail_s


def _head_position(tp, xp, ts, vs, t: float) -> float:
    """Head position at ``t``: interpolated, or extrapolated at the recorded speed."""
    if t < tp[0]:
        v = float(np.interp(tp[0], ts, vs)) if ts.size else 0.0
        return float(xp[0] - v * (tp[0] - t))
    if t > tp[-1]:
        v = float(np.interp(tp[-1], ts, vs)) if ts.size else 0.0
        return float(xp[-1] + v * (t - tp[-1]))
    return float(np.interp(t, tp, xp))

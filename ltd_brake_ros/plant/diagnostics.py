"""Diagnostics values of the plant: achieved pace, overruns, brake state, coupler peaks.

Computed without ROS; the node turns a :class:`PlantStatus` into a
``diagnostic_msgs/DiagnosticStatus`` about once per wall second.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..physics.constants import KMH_PER_MS
from ..recording.metadata import model_warnings
from ..simulator import Commands, Simulator
from ..verdicts import diagnostic_values

#: Severity levels, numbered as in ``diagnostic_msgs/DiagnosticStatus``.
OK, WARN, ERROR = 0, 1, 2
#: Wall time between two diagnostics reports [s].
DIAGNOSTICS_PERIOD_S = 1.0
#: Simulated time between two diagnostics reports of a plant the wall clock does not pace
#: (real_time_factor 0, lock-step, following a clock), besides the wall-time ones [s].
DIAGNOSTICS_SIM_PERIOD_S = 1.0


def format_fixed(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals, never ``-0.000`` (a negative zero or a tiny negative
    value rounds to ``0.000``).

    Parameters
    ----------
    value : float
    digits : int, optional

    Returns
    -------
    str
    """
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text


def format_general(value: float) -> str:
    """``value`` in ``%g`` form, never ``-0``."""
    return f"{value + 0.0:g}"


@dataclass(frozen=True)
class PlantStatus:
    """One diagnostics report.

    Attributes
    ----------
    level : int
        :data:`OK`, :data:`WARN` or :data:`ERROR`.
    message : str
        One line: the state, or what is wrong.
    values : dict of str to str
        Key/values in a fixed order (units in the keys).
    """

    level: int
    message: str
    values: dict


class PaceWindow:
    """Achieved real-time factor and overruns between two reports.

    Parameters
    ----------
    now : float
        Wall time the first window starts [s].
    """

    def __init__(self, now: float):
        self._wall, self._sim_s, self._overruns, self._rejected = now, 0.0, 0, 0
        self._peak_lag_s = 0.0

    def lag(self, lag_s: float) -> None:
        """Note how far behind its schedule the plant is after a chunk [s wall]."""
        self._peak_lag_s = max(self._peak_lag_s, lag_s)

    def take_peak_lag(self) -> float:
        """The largest lag noted since the previous call (0 if never behind) [s wall]."""
        peak, self._peak_lag_s = self._peak_lag_s, 0.0
        return peak

    def take_rejected(self, rejected: int) -> int:
        """Inputs rejected since the previous call, given the count since start-up."""
        new, self._rejected = rejected - self._rejected, rejected
        return new

    def restart(self, now: float, sim_s: float = 0.0) -> None:
        """Start the window again at wall time ``now`` and simulated time ``sim_s`` [s]."""
        self._wall, self._sim_s = now, sim_s

    def take(self, now: float, sim_s: float, overruns: int) -> tuple[float, int, float]:
        """Close the window at ``now`` and start the next one.

        Parameters
        ----------
        now : float
            Wall time [s].
        sim_s : float
            Simulated time reached [s].
        overruns : int
            Overruns counted since start-up.

        Returns
        -------
        achieved : float
            Simulated over wall time in the window (0 for an empty window) [-].
        new_overruns : int
            Overruns in the window.
        window_s : float
            Length of the window [s].
        """
        window_s = now - self._wall
        achieved = (sim_s - self._sim_s) / window_s if window_s > 0.0 else 0.0
        new = overruns - self._overruns
        self._wall, self._sim_s, self._overruns = now, sim_s, overruns
        return achieved, new, window_s


def plant_status(sim: Simulator, *, state: str, reason: str = "", achieved: float = 0.0,
                 window_s: float = 0.0, new_overruns: int = 0, chunks: int = 0,
                 overruns: int = 0, dropped_s: float = 0.0, lag_s: float = 0.0, peak_lag_s: float = 0.0,
                 real_time_factor: float = 0.0,
                 commands: Commands = Commands(), rejected: int = 0, new_rejected: int = 0,
                 handled: int = 0, resets: int = 0, recording: str = "off",
                 recording_error: str | None = None) -> PlantStatus:
    """The diagnostics report of the plant.

    Parameters
    ----------
    sim : Simulator
        The plant's simulator (time, brake command, speed, coupler peaks, stop).
    state : str
        ``failed``, ``finished``, ``following``, ``lockstep``, ``paused`` or ``running``.
    reason : str
        Why it failed or finished (the message then).
    achieved, window_s, new_overruns
        What :meth:`PaceWindow.take` returned.
    chunks, overruns : int
        Chunks advanced and overruns since start-up.
    dropped_s : float
        Lag given up by those overruns, summed [s wall].
    lag_s, peak_lag_s : float
        How far the plant is behind its schedule now, and at most in the window (what
        :meth:`PaceWindow.take_peak_lag` returned) [s wall].
    real_time_factor : float
        The set real-time factor [-].
    commands : Commands
        The inputs in force.
    rejected, handled : int
        Input messages rejected, and handled in all, since start-up.
    new_rejected : int
        Input messages rejected in the window (a WARN).
    resets : int
        Resets done since start-up.
    recording : str
        The bag folder, or ``off``, ``failed``, ``finished``.
    recording_error : str or None
        Why the recording stopped.

    Returns
    -------
    PlantStatus
    """
    if state == "failed":
        level, message = ERROR, reason
    elif state == "finished":
        level, message = OK, reason
    else:
        level, message = OK, state
        problems = []
        if new_overruns:
            problems.append(f"{new_overruns} chunk overrun(s)")
        if new_rejected:
            problems.append(f"{new_rejected} input(s) rejected")
        if problems:
            level, message = WARN, f"{' and '.join(problems)} in the last {window_s:.1f} s"
    peaks = sim.coupler_peaks()
    f3, g = format_fixed, format_general
    values = {
        "state": state,
        "sim_time_s": f3(sim.time_s),
        "real_time_factor": g(real_time_factor),
        "achieved_real_time_factor": f3(achieved),
        "chunks": str(chunks),
        "chunk_overruns": str(overruns),
        "schedule_dropped_s": f3(dropped_s),
        "schedule_lag_s": f3(lag_s),
        "peak_schedule_lag_s": f3(peak_lag_s),
        "emergency_command": "true" if commands.emergency else "false",
        "brake_command_time_s": "none" if sim.command_time_s is None
        else f3(sim.command_time_s),
        "head_speed_kmh": f3(float(sim.snapshot().speed_m_s[0]) * KMH_PER_MS),
        "peak_draft_kN": f3(peaks.draft_N / 1e3),
        "peak_draft_coupler": str(peaks.draft_coupler),
        "peak_buff_kN": f3(peaks.buff_N / 1e3),
        "peak_buff_coupler": str(peaks.buff_coupler),
        "couplers_beyond_lut": str(int((sim.lut_excursion_m != 0.0).sum())),
        "brake_demand": g(commands.brake_demand),
        "traction_command": g(commands.traction),
        "overcharge_command": "true" if commands.overcharge else "false",
        "rejected_inputs": str(rejected),
        "inputs_handled": str(handled),
        "resets": str(resets),
        "recording": recording,
    }
    # the judgments of the part of the run judged now (the latest stop, until a drive-off):
    # a limit exceeded is a WARN (the run goes on: the plant reports what a real train would
    # not survive); a drive-off starts afresh, the run's own status stays in run_verdicts
    verdicts = sim.current_verdicts()
    values.update(diagnostic_values(verdicts))
    values["run_verdicts"] = sim.verdicts().status
    if verdicts.status != "PASS" and level == OK:
        beyond = [c.name for c in verdicts.criteria if c.status in ("FAIL", "WARN")]
        level, message = WARN, f"{message}; limits exceeded: {', '.join(beyond)}"
    outside = model_warnings(sim)
    values["model_validity"] = outside[0] if outside else "inside the validated ranges"
    if outside and level == OK:
        level, message = WARN, f"{message}; outside a model's validated range"
    if recording_error:
        values["recording_error"] = recording_error
        if level == OK:
            level, message = WARN, "recording stopped"
    values["phase"] = sim.phase
    stops = sim.stops
    values["stops"] = str(len(stops))
    if stops:
        values["stop"] = stops[-1].describe()
    if sim.stopping_distance_m is not None:
        values["stopping_distance_m"] = f3(sim.stopping_distance_m)
        values["stop_time_s"] = f3(sim.stop_time_s - (sim.command_time_s or 0.0))
    if sim.settled_time_s is not None:
        values["settled_time_s"] = f3(sim.settled_time_s)
    if state == "failed":
        values["error"] = reason
    return PlantStatus(level, message, values)

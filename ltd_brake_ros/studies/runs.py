"""Whole runs: an emergency stop from speed, and the paper's validation table."""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, fields
from typing import Callable, NamedTuple

from ..inputs import (BrakeParams, CommandScript, Consist, CouplerLUT, Scenario, Track,
                     load_brake_params, load_coupler_lut, load_scenarios)
from ..physics.kernel import DEFAULT_TOLERANCE_M_S
from ..simulator import (Commands, CouplerExcursions, SimulationError, Simulator, Snapshot,
                         whole_steps)


class Progress(NamedTuple):
    """How far a run has come, reported after every chunk.

    Attributes
    ----------
    time_s : float
        Simulated time reached [s].
    fraction : float or None
        Share of the run done, 0 to 1; None when the end is not known in advance (a run
        until the train stops).
    wall_s : float
        Wall time since the run started [s].
    """

    time_s: float
    fraction: float | None
    wall_s: float


@dataclass(frozen=True)
class StopResult:
    """Summary of one emergency stop (units in the names).

    Coupler numbers count from 1 behind the head; buff forces are reported as negative values.
    ``couplers_beyond_lut`` and ``max_beyond_lut_mm`` head ``out_of_range``, the summary of
    the couplers that went beyond the coupler characteristic's range with the worst three.

    Attributes
    ----------
    consist : str
        The train's name.
    vehicles : int
        Vehicles in the train.
    train_length_m : float
        Length over buffers [m].
    train_mass_t : float
        Weight on rails [t].
    braked_weight_percent : float
        The train's braked-weight percentage lambda (Eq. 11) [%].
    initial_speed_kmh : float
        Speed at the start of the run [km/h].
    stopping_distance_m : float
        The head's travel from the brake command to the stop [m].
    stop_time_s : float
        Time from the brake command to the stop [s].
    settled_time_s : float or None
        Since when the train has been settled at rest, every vehicle within 1 mm/s for at
        least 2 s, the couplers' recoil over [s] (None: it did not settle within 60 s).
    peak_draft_kN : float
        Largest draft (tension) coupler force [kN], positive.
    peak_draft_coupler : int
        Coupler that had it (1 behind the head).
    peak_draft_time_s : float
        When [s] (simulated time since the start).
    peak_buff_kN : float
        Largest buff (compression) coupler force [kN], negative.
    peak_buff_coupler : int
        Coupler that had it.
    peak_buff_time_s : float
        When [s].
    couplers_beyond_lut : int
        Couplers that went beyond the range of their characteristic (their forces there are
        extrapolated).
    max_beyond_lut_mm : float
        The largest such excursion [mm] (0 when none).
    wall_time_s : float
        Wall time of the run [s] (the run's cost; varies between machines and runs).
    real_time_factor : float
        Simulated time over wall time [-].
    steps : int
        Accepted integration steps.
    newton_iterations : int
        Newton iterations over the run.
    newton_iterations_per_step : float
        Their mean per step [-].
    max_newton_iterations : int
        The most in one step.
    rejected_steps : int
        Steps the error control rejected and retried shorter.
    smallest_step_s : float
        Shortest accepted step [s].
    out_of_range : CouplerExcursions
        The couplers beyond their characteristic's range, the worst three with when and how
        far (:class:`~ltd_brake_ros.simulator.CouplerExcursions`).

    Examples
    --------
    >>> from ltd_brake_ros import emergency_stop
    >>> s = emergency_stop("scenario_6", 100.0).summary  # doctest: +SKIP
    >>> s.stopping_distance_m, s.peak_draft_kN, s.peak_draft_coupler  # doctest: +SKIP
    (489.2..., 173.4..., 1)
    >>> s.as_dict()["peak_buff_kN"]  # doctest: +SKIP
    """

    consist: str
    vehicles: int
    train_length_m: float
    train_mass_t: float
    braked_weight_percent: float
    initial_speed_kmh: float
    stopping_distance_m: float
    stop_time_s: float
    settled_time_s: float | None
    peak_draft_kN: float
    peak_draft_coupler: int
    peak_draft_time_s: float
    peak_buff_kN: float
    peak_buff_coupler: int
    peak_buff_time_s: float
    couplers_beyond_lut: int
    max_beyond_lut_mm: float
    wall_time_s: float
    real_time_factor: float
    steps: int
    newton_iterations: int
    newton_iterations_per_step: float
    max_newton_iterations: int
    rejected_steps: int
    smallest_step_s: float
    out_of_range: CouplerExcursions

    def __repr__(self) -> str:
        return (f"StopResult({self.consist}: {self.stopping_distance_m:.1f} m in "
                f"{self.stop_time_s:.2f} s from {self.initial_speed_kmh:g} km/h; peak draft "
                f"{self.peak_draft_kN:.1f} kN @{self.peak_draft_coupler}, buff "
                f"{self.peak_buff_kN:.1f} kN @{self.peak_buff_coupler}; {self.vehicles} "
                "vehicles; every field: .as_dict())")

    def _repr_html_(self) -> str:
        from .._display import html_table, number

        rows = [(k, number(v)) for k, v in self.as_dict().items() if not isinstance(v, dict)]
        return html_table(f"StopResult {self.consist}", rows, ["field", "value"])

    def as_dict(self) -> dict:
        """Plain dict for JSON output."""
        # the fields as they are (numbers and text) but the nested summary: asdict's deep
        # copy of every number costs more than the summary itself
        out = {name: getattr(self, name) for name in _STOP_FIELDS}
        out["out_of_range"] = asdict(self.out_of_range)
        return out


#: The fields of :class:`StopResult`, in order.
_STOP_FIELDS = tuple(f.name for f in fields(StopResult))
#: Grouped chunks of :func:`emergency_run`: a call spans at most :data:`MAX_GROUPED` chunks
#: and at most :data:`STOP_MARGIN` of the time to the stop predicted from the train's mean
#: deceleration, predicted only once that deceleration grows by at most :data:`DECEL_GROWTH`
#: per call (the brakes have applied).
MAX_GROUPED, STOP_MARGIN, DECEL_GROWTH = 16, 0.5, 1.5
#: A run to the stop goes on until the train has settled at rest (its couplers' recoil
#: over), at most this long after the standstill [s]: a train still moving then has not
#: settled (its holding verdicts say so).
SETTLE_MAX_S = 60.0


def stop_run_over(sim: Simulator) -> bool:
    """The run to a stop is over: the train has settled, or it stood still
    :data:`SETTLE_MAX_S` ago without settling."""
    return sim.settled_time_s is not None or (
        sim.stop_time_s is not None and sim.time_s - sim.stop_time_s >= SETTLE_MAX_S - 1e-9)


def emergency_stop(consist: Consist, speed_kmh: float, params: BrakeParams | None = None,
                   lut: CouplerLUT | None = None, track: Track | None = None, *,
                   step_s: float = 0.01, tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                   chunk_s: float = 1.0, max_time_s: float = 600.0,
                   on_chunk: Callable[[Snapshot], None] | None = None,
                   progress: Callable[[Progress], None] | None = None) -> StopResult:
    """Apply the emergency brake at t = 0 and integrate until the train has settled at rest.

    The run of :func:`emergency_run` (its wall time counts the simulator's construction);
    without ``on_chunk`` and ``progress`` its chunks are grouped while the stop is far (the
    same steps and summary, fewer calls).

    Parameters
    ----------
    consist : Consist
    speed_kmh : float
        Initial speed [km/h].
    params : BrakeParams, optional
    lut : CouplerLUT, optional
    track : Track, optional
        Track profile (default: level straight track).
    step_s : float, optional
        Nominal (largest) integration step [s].
    tolerance_m_s : float or None, optional
        Local error allowed per step in each vehicle's speed [m/s] (0 or None: fixed steps;
        see :class:`~ltd_brake_ros.simulator.Simulator`).
    chunk_s : float, optional
        Simulated time per :meth:`Simulator.advance` call [s].
    max_time_s : float, optional
        Give up (raise) if the train has not stopped by then [s].
    on_chunk : callable, optional
        Called with each :class:`~ltd_brake_ros.simulator.Snapshot`.
    progress : callable, optional
        Called with a :class:`Progress` after each chunk (``fraction`` None: the stop time is
        not known in advance).

    Returns
    -------
    StopResult

    Raises
    ------
    SimulationError
        A step failed, or the train did not stop within ``max_time_s``.
    """
    start = time.perf_counter()
    sim = emergency_run(consist, speed_kmh, params, lut, track, step_s=step_s,
                        tolerance_m_s=tolerance_m_s, chunk_s=chunk_s, max_time_s=max_time_s,
                        group=on_chunk is None and progress is None, on_chunk=on_chunk,
                        progress=progress)
    return summarize(sim, time.perf_counter() - start)


def emergency_run(consist: Consist, speed_kmh: float, params: BrakeParams | None = None,
                  lut: CouplerLUT | None = None, track: Track | None = None, *,
                  step_s: float = 0.01, tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                  chunk_s: float = 1.0, max_time_s: float = 600.0, group: bool = False,
                  on_chunk: Callable[[Snapshot], None] | None = None,
                  progress: Callable[[Progress], None] | None = None,
                  adhesion=None, rail=None,
                  on_start: Callable[[Simulator], None] | None = None) -> Simulator:
    """An emergency stop: the brake applied at t = 0, chunks of ``chunk_s`` to the stop.

    The one loop of an emergency stop (:func:`emergency_stop`, ``ltd-brake simulate``,
    campaigns). The run ends at the end of the chunk in which the train settled at rest (every
    vehicle within 1 mm/s for 2 s, the couplers' recoil over), at most :data:`SETTLE_MAX_S`
    after it first stood still.

    With ``group``, several chunks go into one
    :meth:`~ltd_brake_ros.simulator.Simulator.advance` call while the stop is still far (each
    call costs Python work besides its steps): a call spans at most :data:`STOP_MARGIN` of
    the time to the stop that the train's mean deceleration over the last call predicts, so
    the call in which the train stops is a single chunk, and only chunks whose steps are
    those of one chunk at a time are grouped. The steps, and everything the kernel tracks
    step by step (stop, distance, peaks and excursions of the couplers, counters), are
    those of one chunk per call; what the simulator samples at the end of a call (the
    adhesion demand of the verdicts, the head's speed at a coupler's peak, the events'
    snapshots) is then sampled at the grouped calls' ends (the deceleration only grows as
    the train slows down, with the friction coefficient of cast-iron blocks, so the
    prediction is safe).

    Parameters
    ----------
    consist : Consist
    speed_kmh : float
        Initial speed [km/h].
    params, lut, track : optional
        Model inputs (defaults: paper parameters, shipped table, level track).
    step_s : float, optional
        Nominal (largest) integration step [s].
    tolerance_m_s : float or None, optional
        Local error allowed per step in each vehicle's speed [m/s] (0 or None: fixed steps).
    chunk_s : float, optional
        Simulated time per chunk [s].
    max_time_s : float, optional
        Give up (raise) if the train has not stopped by then [s].
    group : bool, optional
        Group chunks while the stop is far (see above).
    on_chunk : callable, optional
        Called with the :class:`~ltd_brake_ros.simulator.Snapshot` of each call.
    progress : callable, optional
        Called with a :class:`Progress` after each call (``fraction`` None).
    adhesion : optional
        The rail's adhesion condition for wheel slide (see
        :class:`~ltd_brake_ros.simulator.Simulator`; default: off).
    rail : optional
        The rail condition the adhesion demand is judged against (default: ``adhesion``'s,
        else dry).
    on_start : callable, optional
        Called with the simulator before its first chunk (its state at t = 0).

    Returns
    -------
    Simulator
        At the end of the chunk in which the train settled.

    Raises
    ------
    SimulationError
        A step failed, or the train had not stopped after ``max_time_s``.
    """
    whole_steps(chunk_s, step_s, "chunk_s")
    sim = Simulator(consist, speed_kmh, params, lut or load_coupler_lut(), track, step_s=step_s,
                    tolerance_m_s=tolerance_m_s, adhesion=adhesion, rail=rail)
    if on_start:
        on_start(sim)
    start = time.perf_counter()
    commands: Commands | None = Commands(emergency=True)
    if group:
        mass = sim.mass_kg
        total_kg = float(mass.sum())
        speed = float(mass @ sim.snapshot().speed_m_s) / total_kg  # mean speed [m/s]
    decel, grouped = math.nan, 1
    while True:
        span = grouped * chunk_s
        snap = sim.advance(span, commands)
        commands = None  # held
        _report(snap, None, start, on_chunk, progress)
        if stop_run_over(sim):
            return sim
        if sim.time_s >= max_time_s and sim.stop_time_s is None:  # stopped: it settles
            raise SimulationError(f"the train had not stopped after {max_time_s:g} s")
        if not group:
            continue
        now = float(mass @ snap.speed_m_s) / total_kg
        last, decel, speed = decel, (speed - now) / span, now
        grouped = 1
        # braking, no longer building up (NaN: False); once stopped, settling goes chunk by
        # chunk (its couplers' recoil is no deceleration to predict from)
        if 0.0 < decel <= DECEL_GROWTH * last and sim.stop_time_s is None:
            left = int((max_time_s - sim.time_s) / chunk_s + 1e-9)  # whole chunks to the end
            grouped = max(1, min(MAX_GROUPED, left,
                                 int(STOP_MARGIN * now / decel / chunk_s)))
            if grouped > 1 and not _grouping_keeps_steps(grouped, chunk_s, sim.step_s):
                grouped = 1


def _grouping_keeps_steps(k: int, chunk_s: float, step_s: float) -> bool:
    """True if one call of ``k`` chunks takes the nominal steps of ``k`` calls of one chunk
    (:meth:`~ltd_brake_ros.simulator.Simulator.advance` splits a call into equal steps)."""
    one = math.ceil(chunk_s / step_s - 1e-9)
    span = k * chunk_s
    steps = math.ceil(span / step_s - 1e-9)
    return steps == k * one and span / steps == chunk_s / one


def scripted_run(consist: Consist, speed_kmh: float, script: CommandScript,
                 params: BrakeParams | None = None, lut: CouplerLUT | None = None,
                 track: Track | None = None, *, step_s: float = 0.01,
                 tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S, chunk_s: float = 0.1,
                 max_time_s: float = 3600.0, on_chunk: Callable[[Snapshot], None] | None = None,
                 progress: Callable[[Progress], None] | None = None,
                 adhesion=None, rail=None,
                 on_start: Callable[[Simulator], None] | None = None) -> Simulator:
    """Run a train under a timed command script.

    The inputs change at chunk boundaries (every ``chunk_s``), as they would when a controller
    drives the ROS node at that rate.

    Parameters
    ----------
    consist : Consist
    speed_kmh : float
        Initial speed [km/h].
    script : CommandScript
    params, lut, track : optional
        Model inputs (defaults: paper parameters, shipped table, level track).
    step_s, chunk_s : float, optional
        Nominal integration step and command-update interval [s].
    tolerance_m_s : float or None, optional
        Local error allowed per step in each vehicle's speed [m/s] (0 or None: fixed steps).
    max_time_s : float, optional
        Upper bound when the script has no duration and the train does not stop [s].
    on_chunk : callable, optional
        Called with each :class:`~ltd_brake_ros.simulator.Snapshot`.
    adhesion : optional
        The rail's adhesion condition for wheel slide (default: off).
    rail : optional
        The rail condition the adhesion demand is judged against (default: ``adhesion``'s,
        else dry).
    progress : callable, optional
        Called with a :class:`Progress` after each chunk (``fraction`` of the script's
        duration; None without one).
    on_start : callable, optional
        Called with the simulator before its first chunk (its state at t = 0).

    Returns
    -------
    Simulator
        The simulator at the end of the run (its counters, peaks and events describe it).
    """
    whole_steps(chunk_s, step_s, "chunk_s")
    sim = Simulator(consist, speed_kmh, params, lut or load_coupler_lut(), track, step_s=step_s,
                    tolerance_m_s=tolerance_m_s, adhesion=adhesion, rail=rail)
    if on_start:
        on_start(sim)
    end = script.duration_s if script.duration_s is not None else max_time_s
    end = math.ceil(end / step_s - 1e-6) * step_s  # the last chunk: whole steps too
    state: dict = {}
    k = 0
    start = time.perf_counter()
    while sim.time_s < end - 1e-9:
        while k < len(script.steps) and script.steps[k][0] <= sim.time_s + 1e-9:
            state.update(script.steps[k][1])
            k += 1
        left = end - sim.time_s
        snap = sim.advance(chunk_s if left > chunk_s - 1e-6 * step_s else
                           max(1, round(left / step_s)) * step_s, Commands(**state))
        _report(snap, script.duration_s, start, on_chunk, progress)
        if script.duration_s is None and k == len(script.steps) and stop_run_over(sim):
            break  # every command given and the train settled after its last stop
    return sim


def _report(snap: Snapshot, end_s: float | None, start: float, on_chunk, progress) -> None:
    """Hand a chunk's snapshot and the run's progress (towards ``end_s``, if known) on."""
    if on_chunk:
        on_chunk(snap)
    if progress:
        progress(Progress(snap.time_s, None if end_s is None else min(snap.time_s / end_s, 1.0),
                          time.perf_counter() - start))


def summarize(sim: Simulator, wall_s: float) -> StopResult:
    """Build a :class:`StopResult` from a simulator that has stopped.

    Parameters
    ----------
    sim : Simulator
    wall_s : float
        Wall time the run took [s].

    Returns
    -------
    StopResult
    """
    peaks = sim.stop_peaks
    beyond = sim.coupler_excursions()
    stats = sim.stats
    stop_t = sim.stop_time_s - sim.command_time_s
    return StopResult(
        consist=sim.consist.name, vehicles=sim.n, train_length_m=sim.consist.length_m,
        train_mass_t=sim.consist.mass_kg / 1e3,
        braked_weight_percent=sim.braked_weight_percent(),
        initial_speed_kmh=sim.speed_kmh, stopping_distance_m=float(sim.stopping_distance_m),
        stop_time_s=float(stop_t), settled_time_s=sim.settled_time_s,
        peak_draft_kN=peaks.draft_N / 1e3, peak_draft_coupler=peaks.draft_coupler,
        peak_draft_time_s=peaks.draft_time_s,
        peak_buff_kN=peaks.buff_N / 1e3, peak_buff_coupler=peaks.buff_coupler,
        peak_buff_time_s=peaks.buff_time_s,
        couplers_beyond_lut=beyond.count,
        max_beyond_lut_mm=beyond.worst[0].beyond_range_mm if beyond.worst else 0.0,
        wall_time_s=wall_s, real_time_factor=sim.time_s / wall_s if wall_s > 0 else float("inf"),
        steps=stats.steps, newton_iterations=stats.newton_iterations,
        newton_iterations_per_step=stats.newton_iterations / max(stats.steps, 1),
        max_newton_iterations=stats.max_newton_iterations,
        rejected_steps=stats.rejected_steps, smallest_step_s=stats.smallest_step_s,
        out_of_range=beyond)


@dataclass(frozen=True)
class ValidationRow:
    """One row of Tables 1-2 beside our result."""

    scenario: Scenario
    result: StopResult

    @property
    def distance_error_percent(self) -> float:
        """Our stopping distance against the LTDPoliTo column [%]."""
        ref = self.scenario.paper["ltdpolito_m"]
        return 100.0 * (self.result.stopping_distance_m - ref) / ref

    @property
    def uic_error_percent(self) -> float | None:
        """Our stopping distance against the UIC 544-1 column [%] (None at 50 km/h)."""
        ref = self.scenario.paper.get("uic_m")
        return None if ref is None else 100.0 * (self.result.stopping_distance_m - ref) / ref


def validate(params: BrakeParams | None = None, lut: CouplerLUT | None = None,
             scenarios: list[int] | None = None, *, step_s: float = 0.01,
             workers: int = 1) -> list[ValidationRow]:
    """Run the paper's scenarios and pair each with its published values.

    Parameters
    ----------
    params : BrakeParams, optional
    lut : CouplerLUT, optional
    scenarios : list of int, optional
        Scenario numbers (default: all 12).
    step_s : float, optional
        Integration step [s].
    workers : int, optional
        Processes to run scenarios in parallel (1 = in this process).

    Returns
    -------
    list of ValidationRow
    """
    from .parallel import map_jobs  # process pools: not needed by a single run

    params = params or load_brake_params()
    lut = lut or load_coupler_lut()
    catalogue = load_scenarios()
    chosen = [catalogue[k] for k in (scenarios or sorted(catalogue))]
    jobs = [(s.consist_file, s.speed_kmh, params, lut, step_s) for s in chosen]
    results = map_jobs(_run_job, jobs, workers)
    return [ValidationRow(s, r) for s, r in zip(chosen, results)]


def _run_job(job) -> StopResult:
    from ..inputs import load_consist

    consist_file, speed, params, lut, step_s = job
    return emergency_stop(load_consist(consist_file), speed, params, lut, step_s=step_s)

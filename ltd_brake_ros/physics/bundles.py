"""The kernel's named bundles: what a train compiles to, the inputs held over a chunk, the
mutable state, options, counters and work arrays (typing.NamedTuple of arrays and scalars,
which numba compiles like structs).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import brakes
from . import couplers
from .brakes import friction, thermal


#: Kernel return codes.
OK, NEWTON_FAILED, STOPPED, NOT_FINITE, SETTLED, MOVED = 0, 1, 2, 3, 4, 5
#: What the step loop watches at the end of each nominal step (its ``watch`` argument):
#: nothing; the stop (every vehicle slower than the standstill speed going forward: returns
#: ``STOPPED``); the settling after it (every vehicle's speed within the standstill speed for
#: :data:`SETTLE_S` without a break: ``SETTLED``); the train at rest (a vehicle faster than
#: the standstill speed either way: ``MOVED``).
WATCH_NONE, WATCH_STOP, WATCH_SETTLE, WATCH_REST = 0, 1, 2, 3
#: A train has settled once every vehicle has stayed within the standstill speed this long [s].
SETTLE_S = 2.0


#: Default local error allowed per step in each vehicle's speed [m/s].
DEFAULT_TOLERANCE_M_S = 1e-3


#: Default Newton residual tolerance relative to each vehicle's weight: a residual of
#: r m g left in a step of beta h moves the vehicle's speed by about r g beta h, 7e-8 m/s
#: for 10 ms steps, four orders of magnitude below the error control's tolerance (tighter
#: only costs iterations: 1e-9 took 10-17 % more on the paper's scenarios 1, 6 and 12 for
#: changes of at most 2e-7 of their peak forces).
DEFAULT_NEWTON_RTOL = 1e-6


class TrainArrays(NamedTuple):
    """Per-vehicle data of the train, head first (built once).

    Attributes
    ----------
    mass_kg : ndarray
        Weight on rails M [kg].
    meff_kg : ndarray
        rho * M, with the rotating-mass factor of Eq. 1 [kg].
    axles : ndarray
        Axle count.
    centre_offset_m : ndarray
        Distance of each vehicle's centre behind the head's front [m].
    resist : float
        1 with running resistance (Eq. 2), 0 without.
    """

    mass_kg: np.ndarray
    meff_kg: np.ndarray
    axles: np.ndarray
    centre_offset_m: np.ndarray
    resist: float


class TractionArrays(NamedTuple):
    """Traction and dynamic-brake limits of each vehicle (zeros for unpowered ones).

    Attributes
    ----------
    max_force_N, max_power_W : ndarray
        Traction limits [N], [W].
    brake_max_force_N, brake_max_power_W : ndarray
        Dynamic-brake limits [N], [W].
    rate_limit_N_s : ndarray
        Largest change of the applied force per second [N/s].
    time_constant_s : ndarray
        Lag between demand and applied force [s].
    fade_speed_m_s : ndarray
        Below this speed the dynamic brake fades linearly to zero [m/s].
    """

    max_force_N: np.ndarray
    max_power_W: np.ndarray
    brake_max_force_N: np.ndarray
    brake_max_power_W: np.ndarray
    rate_limit_N_s: np.ndarray
    time_constant_s: np.ndarray
    fade_speed_m_s: np.ndarray


class TrackArrays(NamedTuple):
    """Track profile: sections from given chainages.

    Attributes
    ----------
    start_chainage_m : float
        Chainage of the head's front at t = 0 [m].
    sections : ndarray, shape (3, sections)
        Rows :data:`SECTION_START` (start of each section [m]), :data:`GRADIENT` (uphill
        positive [per mille]) and :data:`CURVE` (curve resistance [N/kN]).
    """

    start_chainage_m: float
    sections: np.ndarray


#: Rows of ``TrackArrays.sections``.
SECTION_START, GRADIENT, CURVE = 0, 1, 2


class TrainModel(NamedTuple):
    """Everything compiled once for a train: the bundles of each part of the model."""

    train: TrainArrays
    friction: friction.FrictionArrays
    brakes: brakes.BrakeArrays
    couplers: couplers.CouplerArrays
    traction: TractionArrays
    track: TrackArrays
    thermal: thermal.ThermalArrays


class Inputs(NamedTuple):
    """Inputs held over a chunk.

    Attributes
    ----------
    traction_demand : float
        -1 (full dynamic brake) to 1 (full traction).
    external_force_N : ndarray
        Additional external force on each vehicle, forward positive [N].
    """

    traction_demand: float
    external_force_N: np.ndarray


class KinematicState(NamedTuple):
    """The integrator's mutable state (arrays updated in place).

    Attributes
    ----------
    x_m, v_m_s : ndarray
        Displacement [m] and speed [m/s] of each vehicle now.
    x_prev_m, v_prev_m_s : ndarray
        The same one step back (BDF2 history).
    stuck : ndarray of bool
        Vehicles inside the standstill band |v| <= v_stick.
    traction_force_N : ndarray
        Applied traction (positive) or dynamic-brake force [N].
    coupler_force_N : ndarray
        Force of each coupler at the end of the last step, draft positive [N].
    brake_force_N : ndarray
        Retarding force of each vehicle's brake at the end of the last step [N].
    peak_draft_N, peak_draft_time_s, peak_buff_N, peak_buff_time_s : ndarray
        Running extreme coupler forces [N] and their times [s].
    beyond_range_m : ndarray
        Largest excursion beyond the coupler model's valid range, per coupler [m].
    out_of_range_time_s : ndarray
        First time each coupler was out of its range [s] (-1: never).
    beyond_range_time_s : ndarray
        Time of each coupler's largest excursion [s] (-1: never out of range).
    accel_m_s2 : ndarray
        Acceleration of each vehicle at the end of the last step, the step's own derivative
        [m/s^2] (the error estimate's predictor uses it).
    peak_brake_fast_N, peak_brake_fast_time_s, peak_brake_fast_speed_m_s : ndarray
        Each vehicle's largest brake force while faster than
        :data:`ADHESION_SPLIT_SPEED_M_S` [N], when [s] and at what speed [m/s].
    peak_brake_slow_N, peak_brake_slow_time_s, peak_brake_slow_speed_m_s : ndarray
        The same while slower, still moving forward (faster than the standstill speed).
    slide_time_s, slide_first_s : ndarray
        How long each vehicle's wheels slid in all [s] (brake force capped by the rail's
        adhesion, or wheelsets locked, :mod:`.brakes.wheel_slide`) and when they first did [s]
        (-1: never).
    slide_locked : ndarray of bool
        Each vehicle's wheelsets locked (sliding) at the end of the last step
        (:mod:`.brakes.wheel_slide`).
    applied_work_J, applied_distance_m : ndarray
        Work of each vehicle's brake at the rails [J] (less what decelerated its rotating
        masses) and the distance it ran [m] while its brake was fully
        applied (retarding-force scale at least :data:`FULL_APPLICATION` of its full value) and
        it ran at :data:`MEAN_ADHESION_MIN_SPEED_M_S` or faster: their ratio over m g is the
        mean utilised adhesion of a braking calculation (:mod:`ltd_brake_ros.verdicts`).
    block_temperature_K, wheel_temperature_K : ndarray
        Temperature of each vehicle's brake blocks and wheels at the end of the kernel's last
        call [K] (NaN: no block brakes), from ``block_updated_K`` and ``wheel_updated_K``,
        the same at the last update of :mod:`.brakes.thermal`.
    peak_block_temperature_K, peak_block_temperature_time_s : ndarray
        Their largest value at an update [K] and when [s]; ``peak_wheel_temperature_K``,
        ``peak_wheel_temperature_time_s`` the same of the wheels.
    heat_work_J, heat_distance_m : ndarray
        Work of each vehicle's brake (retarding force times distance) [J] and the distance it
        ran [m] since the last update.
    brake_energy_J : ndarray
        Work of each vehicle's brake up to the last update [J].
    heat_clock_s : ndarray, shape (2,)
        Time of the last update and of the next grid time [s] (:func:`.brakes.thermal.advance`).
    step_control : ndarray, shape (4,)
        Entry :data:`NEXT_STEP`: the step the error control proposes next [s] (0: the nominal
        step); entry :data:`ACCEL_VALID`: 1 once ``accel_m_s2`` holds a step's derivative;
        entry :data:`OUT_OF_RANGE`: how many couplers have left their valid range (those with
        ``out_of_range_time_s`` >= 0), so that a caller needs no pass over the train to know;
        entry :data:`REST_SINCE`: since when every vehicle has been within the standstill
        speed, while the step loop watches a train settle [s] (-1: not at rest).
    """

    x_m: np.ndarray
    v_m_s: np.ndarray
    x_prev_m: np.ndarray
    v_prev_m_s: np.ndarray
    stuck: np.ndarray
    traction_force_N: np.ndarray
    coupler_force_N: np.ndarray
    brake_force_N: np.ndarray
    peak_draft_N: np.ndarray
    peak_draft_time_s: np.ndarray
    peak_buff_N: np.ndarray
    peak_buff_time_s: np.ndarray
    beyond_range_m: np.ndarray
    out_of_range_time_s: np.ndarray
    beyond_range_time_s: np.ndarray
    accel_m_s2: np.ndarray
    step_control: np.ndarray
    applied_work_J: np.ndarray
    applied_distance_m: np.ndarray
    peak_brake_fast_N: np.ndarray
    peak_brake_fast_time_s: np.ndarray
    peak_brake_fast_speed_m_s: np.ndarray
    peak_brake_slow_N: np.ndarray
    peak_brake_slow_time_s: np.ndarray
    peak_brake_slow_speed_m_s: np.ndarray
    slide_time_s: np.ndarray
    slide_first_s: np.ndarray
    slide_locked: np.ndarray
    block_temperature_K: np.ndarray
    wheel_temperature_K: np.ndarray
    block_updated_K: np.ndarray
    wheel_updated_K: np.ndarray
    peak_block_temperature_K: np.ndarray
    peak_block_temperature_time_s: np.ndarray
    peak_wheel_temperature_K: np.ndarray
    peak_wheel_temperature_time_s: np.ndarray
    heat_work_J: np.ndarray
    heat_distance_m: np.ndarray
    brake_energy_J: np.ndarray
    heat_clock_s: np.ndarray

    @classmethod
    def initial(cls, n: int, speed_m_s: float,
                temperature_K: np.ndarray | None = None) -> "KinematicState":
        """Every vehicle at ``speed_m_s`` [m/s], couplers unloaded, nothing recorded yet;
        blocks and wheels at ``temperature_K`` (per vehicle [K]; default NaN: none)."""
        nc = max(n - 1, 1)
        v = np.full(n, speed_m_s)
        temp = np.full(n, np.nan) if temperature_K is None else np.array(temperature_K, float)
        return cls(np.zeros(n), v, np.zeros(n), np.full(n, speed_m_s), v == 0.0, np.zeros(n),
                   np.zeros(nc), np.zeros(n), np.zeros(nc), np.zeros(nc), np.zeros(nc),
                   np.zeros(nc), np.zeros(nc), np.full(nc, -1.0), np.full(nc, -1.0),
                   np.zeros(n), np.array([0.0, 0.0, 0.0, -1.0]), np.zeros(n), np.zeros(n),
                   *(np.zeros(n) for _ in range(6)), np.zeros(n), np.full(n, -1.0),
                   np.zeros(n, np.bool_),
                   temp, temp.copy(), temp.copy(), temp.copy(), temp.copy(), np.zeros(n),
                   temp.copy(), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(2))

    def copy(self) -> "KinematicState":
        """An independent copy."""
        return KinematicState(*(a.copy() for a in self))


#: Entries of ``KinematicState.step_control``.
NEXT_STEP, ACCEL_VALID, OUT_OF_RANGE, REST_SINCE = 0, 1, 2, 3


#: A brake counts as fully applied from this fraction of its full retarding-force scale on
#: (the braked part of a stop in a mean-value brake calculation, EN 14531-1) [-].
FULL_APPLICATION = 0.95


#: The braked part of a stop ends below this speed, as braking calculations count it: 5 km/h
#: [m/s].
MEAN_ADHESION_MIN_SPEED_M_S = 5.0 / 3.6


#: The brake forces' peaks are kept apart above and below this speed: adhesion demand is
#: judged above it, and only reported below it, where block friction rises steeply
#: (30 km/h) [m/s].
ADHESION_SPLIT_SPEED_M_S = 30.0 / 3.6


class Options(NamedTuple):
    """Numerical settings.

    Attributes
    ----------
    max_newton_iter : int
        Newton iterations allowed per step.
    newton_rtol : float
        Residual tolerance relative to each vehicle's weight.
    standstill_m_s : float
        Speed below which a vehicle counts as standing (for the stop watch) [m/s].
    stick_band_m_s : float
        Half-width of the standstill band of brake and running resistance [m/s].
    tolerance_m_s : float
        Local error allowed per step in each vehicle's speed [m/s]; 0 takes every nominal
        step whole (fixed steps, no error control).
    local_steps : bool
        Under error control, let trains of at least :data:`LOCAL_MIN_VEHICLES` vehicles
        sub-step only the vehicles that need it (local time stepping, :func:`_refine_all`);
        False: a step too long for any vehicle is retried shorter for the whole train.
    """

    max_newton_iter: int
    newton_rtol: float
    standstill_m_s: float
    stick_band_m_s: float
    tolerance_m_s: float = 0.0
    local_steps: bool = True


class Stats(NamedTuple):
    """What the integration cost, counted since the last reset.

    Attributes
    ----------
    steps : int
        Integration steps.
    newton_iterations : int
        Newton iterations (linear solves).
    max_newton_iterations : int
        Most iterations any single step needed.
    band_cutbacks : int
        Newton updates shortened to land inside a coupler's steep band.
    standstill_projections : int
        Vehicles put at rest instead of jumping across their standstill band.
    line_searches : int
        Newton updates shortened by the exact line search.
    rejected_steps : int
        Steps tried and rejected by the error control (or after a Newton iteration that did
        not converge), then retried shorter.
    smallest_step_s : float
        Shortest step taken [s], local sub-steps included (0 before the first).
    refined_steps : int
        Steps accepted for the whole train after sub-stepping only the vehicles whose error
        estimate exceeded the tolerance (local time stepping, :func:`_refine`).
    local_steps, local_rejected_steps : int
        Sub-steps of those vehicles taken and rejected.
    """

    steps: int = 0
    newton_iterations: int = 0
    max_newton_iterations: int = 0
    band_cutbacks: int = 0
    standstill_projections: int = 0
    line_searches: int = 0
    rejected_steps: int = 0
    smallest_step_s: float = 0.0
    refined_steps: int = 0
    local_steps: int = 0
    local_rejected_steps: int = 0


#: Record the kernel counts into (one field per :class:`Stats` field).
STATS_DTYPE = np.dtype([(name, np.float64 if name == "smallest_step_s" else np.int64)
                        for name in Stats._fields])


def new_stats() -> np.ndarray:
    """A zeroed counter record (an array of one :data:`STATS_DTYPE` element; a record array,
    whose element the plain-Python kernels can count into by field name as compiled ones do)."""
    return np.zeros(1, STATS_DTYPE).view(np.recarray)


def read_stats(record: np.ndarray) -> Stats:
    """The counters of a record as :class:`Stats`."""
    return Stats(*record[0].tolist())


def counters(stats):
    """The counter record of ``stats``: the element of a :func:`new_stats` array, or a record
    itself (the kernel takes either; the array is the cheaper argument from Python: numba
    unboxes a record through the buffer protocol, about a microsecond a call)."""
    return stats[0] if isinstance(stats, np.ndarray) else stats


try:  # pragma: no cover - exercised implicitly
    from numba import types as _types
    from numba.extending import overload as _overload
except ImportError:  # pragma: no cover
    pass
else:
    @_overload(counters)
    def _counters(stats):
        if isinstance(stats, _types.Array):
            return lambda stats: stats[0]
        return lambda stats: stats


class _Step(NamedTuple):
    """What one implicit step's residual needs, fixed within the step."""

    xhat: np.ndarray
    vhat: np.ndarray
    bh: np.ndarray  # one element: beta * step [s] (an array, so the bundle is built once)
    fx: np.ndarray
    meff: np.ndarray
    tol: np.ndarray
    res_a: np.ndarray
    fa_scale: np.ndarray
    slide: np.ndarray  # sliding-friction factor of each vehicle over the step (wheel_slide)
    rcurve: np.ndarray
    resist: float
    v_stick: float


class _Work(NamedTuple):
    """Outputs of a residual evaluation: residual, Jacobian pieces, forces; and each coupler's
    table segment, where the next evaluation looks its deflection up first."""

    g: np.ndarray
    diag: np.ndarray
    cj: np.ndarray
    fc: np.ndarray
    fair: np.ndarray
    segment: np.ndarray


class _Local(NamedTuple):
    """Arrays of local time stepping (:func:`_refine`), indexed like the train's: each window
    uses the entries of its vehicles and couplers."""

    x: np.ndarray
    v: np.ndarray
    xp: np.ndarray
    vp: np.ndarray
    acc: np.ndarray
    u: np.ndarray
    xhat: np.ndarray
    vhat: np.ndarray
    meff: np.ndarray
    tol: np.ndarray
    fx: np.ndarray
    stuck: np.ndarray
    stuck_new: np.ndarray
    bh: np.ndarray
    work: _Work
    peak_draft: np.ndarray
    t_draft: np.ndarray
    peak_buff: np.ndarray
    t_buff: np.ndarray
    beyond: np.ndarray
    t_out: np.ndarray
    t_beyond: np.ndarray
    new_out: np.ndarray  # one element: couplers that left their range in the window
    err: np.ndarray
    windows: np.ndarray  # (n, 2): first and last vehicle of each window
    top: np.ndarray


class _Workspace(NamedTuple):
    """Arrays of :func:`run_loop` (:func:`new_workspace`)."""

    u: np.ndarray
    xhat: np.ndarray
    vhat: np.ndarray
    stuck0: np.ndarray
    stuck1: np.ndarray
    fa_scale: np.ndarray
    tol: np.ndarray
    res_a: np.ndarray
    fx: np.ndarray
    fgrade: np.ndarray
    rcurve: np.ndarray
    bh_step: np.ndarray
    slide: np.ndarray
    work: _Work
    scratch: "_Scratch"
    save_fb: np.ndarray
    save_lvl: np.ndarray
    save_kind: np.ndarray
    save_next: np.ndarray
    save_extra: np.ndarray
    save_ftr: np.ndarray
    local: "_Local"
    full_on: np.ndarray  # FULL_APPLICATION x each vehicle's full retarding-force scale [N]
    rotating: np.ndarray  # (rho - 1) M of each vehicle: its rotating masses [kg]


class _Scratch(NamedTuple):
    """Work arrays of the Newton iteration: trial speeds, update, Thomas scratch, line search."""

    ut: np.ndarray
    du: np.ndarray
    dwork: np.ndarray
    trial: _Work

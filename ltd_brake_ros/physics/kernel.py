"""Compiled integration kernel: variable-step BDF2 with local error control for the train ODE.

The caller divides time into nominal steps (at most its ``step_s``); each nominal step is taken
whole when the local error estimate of the new speeds (BDF2 against a quadratic predictor,
Milne's device) holds the tolerance, else in shorter sub-steps that end exactly on it. With a
tolerance of 0 every nominal step is one step (fixed steps).

In a long train the estimate seldom fails for more than a few vehicles at once: those whose
couplers switch between Eq. 3's curves or reach an end stop in the step (braked from the head,
1 000 wagons: about 20 of 1 001 vehicles for a 10 ms step). Local time stepping
(:func:`_refine_all`) then keeps the whole train's step for the others and sub-steps only
windows around those vehicles, their neighbours outside following the train's step; the step
stands when every window holds the tolerance and passes its neighbours the momentum the train's
step gave them, else the whole train retries shorter.

Each step eliminates the positions (x_{n+1} = xhat + beta*h*u), leaving a nonlinear system in the
new speeds u whose Jacobian is tridiagonal and symmetric positive definite (every coupler model
is non-decreasing in deflection and rate, see :mod:`.couplers`). It is solved by Newton's method
with these safeguards:

* brake and running resistance oppose the motion with their full value outside a narrow
  standstill band |v| <= v_stick and grow linearly inside it, so that they hold a stopped
  vehicle against any smaller force (it creeps at most at v_stick times the force ratio);
* a Newton update that would carry a coupler's deflection speed across the whole steep band of
  its model (Eq. 3's |rate| <= v_th) is shortened so that it lands inside the band, and one
  that would carry a vehicle's speed across its standstill band puts that vehicle at rest
  (plain Newton 2-cycles on both bands);
* after a few iterations without convergence (rare: several vehicles and couplers crossing
  bands together), each update is shortened by an exact line search on the step's convex
  potential, which converges from anywhere;
* a step is accepted only when every residual is below the Newton tolerance; otherwise it is
  retried shorter (under error control, down to the shortest sub-step) or the kernel returns
  a failure code and the caller raises.

The brake model advances the block forces exactly over each step (:mod:`.brakes`); the friction
law turns them into retarding forces.

Everything is passed in named bundles (typing.NamedTuple of arrays and scalars, which numba
compiles like structs): :class:`TrainModel` (compiled once), :class:`Inputs` (per chunk),
:class:`KinematicState` plus the brake model's state and the command events (mutable, updated
in place), a :data:`STATS_DTYPE` record of counters and :class:`Options`.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from . import brakes, couplers
from .brakes import adhesion, friction
from .constants import KMH_PER_MS
from .equations import (HAVE_NUMBA, jit, jit_inline, jit_step, lut_segment,
                        resistance_coefficients)

#: Kernel return codes.
OK, NEWTON_FAILED, STOPPED, NOT_FINITE = 0, 1, 2, 3

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
        adhesion, :mod:`.brakes.adhesion`) and when they first did [s] (-1: never).
    applied_work_J, applied_distance_m : ndarray
        Work of each vehicle's brake at the rails [J] (less what decelerated its rotating
        masses) and the distance it ran [m] while its brake was fully
        applied (retarding-force scale at least :data:`FULL_APPLICATION` of its full value) and
        it ran at :data:`MEAN_ADHESION_MIN_SPEED_M_S` or faster: their ratio over m g is the
        mean utilised adhesion of a braking calculation (:mod:`ltd_brake_ros.verdicts`).
    step_control : ndarray, shape (3,)
        Entry :data:`NEXT_STEP`: the step the error control proposes next [s] (0: the nominal
        step); entry :data:`ACCEL_VALID`: 1 once ``accel_m_s2`` holds a step's derivative;
        entry :data:`OUT_OF_RANGE`: how many couplers have left their valid range (those with
        ``out_of_range_time_s`` >= 0), so that a caller needs no pass over the train to know.
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

    @classmethod
    def initial(cls, n: int, speed_m_s: float) -> "KinematicState":
        """Every vehicle at ``speed_m_s`` [m/s], couplers unloaded, nothing recorded yet."""
        nc = max(n - 1, 1)
        v = np.full(n, speed_m_s)
        return cls(np.zeros(n), v, np.zeros(n), np.full(n, speed_m_s), v == 0.0, np.zeros(n),
                   np.zeros(nc), np.zeros(n), np.zeros(nc), np.zeros(nc), np.zeros(nc),
                   np.zeros(nc), np.zeros(nc), np.full(nc, -1.0), np.full(nc, -1.0),
                   np.zeros(n), np.zeros(3), np.zeros(n), np.zeros(n),
                   *(np.zeros(n) for _ in range(6)), np.zeros(n), np.full(n, -1.0))

    def copy(self) -> "KinematicState":
        """An independent copy."""
        return KinematicState(*(a.copy() for a in self))


#: Entries of ``KinematicState.step_control``.
NEXT_STEP, ACCEL_VALID, OUT_OF_RANGE = 0, 1, 2
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
    """A zeroed counter record (an array of one :data:`STATS_DTYPE` element)."""
    return np.zeros(1, STATS_DTYPE)


def read_stats(record: np.ndarray) -> Stats:
    """The counters of a record as :class:`Stats`."""
    return Stats(*record[0].tolist())


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
    rcurve: np.ndarray
    resist: float
    v_stick: float
    hold: np.ndarray  # standstill holding capacity of each vehicle at rest, else 0 [N]


class _Work(NamedTuple):
    """Outputs of a residual evaluation: residual, Jacobian pieces, forces; and each coupler's
    table segment, where the next evaluation looks its deflection up first."""

    g: np.ndarray
    diag: np.ndarray
    cj: np.ndarray
    fc: np.ndarray
    fair: np.ndarray
    segment: np.ndarray


@jit_step
def advance_traction(h, cmd, v, ftr, tr):
    """Advance the applied traction/dynamic-brake force of powered vehicles (in place).

    The demanded force is ``cmd * min(F_max, P/|v|)`` (traction, forward) or, for cmd < 0,
    ``cmd * min(F_db, P_db/|v|)`` against the motion, fading linearly to zero below the fade
    speed. The applied force follows it with a first-order lag and a rate limit.

    Parameters
    ----------
    h : float
        Step [s].
    cmd : float
        Demand, -1 (full dynamic brake) to 1 (full traction).
    v : ndarray
        Speeds [m/s].
    ftr : ndarray
        Applied force, forward positive [N]; updated.
    tr : TractionArrays
    """
    fmax, pmax = tr.max_force_N, tr.max_power_W
    db_fmax, db_pmax, fade = tr.brake_max_force_N, tr.brake_max_power_W, tr.fade_speed_m_s
    for i in range(ftr.shape[0]):
        if fmax[i] <= 0.0 and db_fmax[i] <= 0.0:
            continue
        spd = abs(v[i])
        if cmd >= 0.0:
            avail = fmax[i] if spd * fmax[i] <= pmax[i] else pmax[i] / spd
            target = cmd * avail
        else:
            avail = db_fmax[i] if spd * db_fmax[i] <= db_pmax[i] else db_pmax[i] / spd
            if spd < fade[i]:
                avail *= spd / fade[i]
            target = cmd * avail * (1.0 if v[i] >= 0.0 else -1.0)
        gap = ftr[i] - target
        if gap != 0.0:  # (at the target: the same sum without the exponential)
            gap *= math.exp(-h / tr.time_constant_s[i])
        lagged = target + gap
        dmax = tr.rate_limit_N_s[i] * h
        change = min(max(lagged - ftr[i], -dmax), dmax)
        ftr[i] += change


@jit_step
def track_forces(x, train, track, fgrade, rcurve):
    """Gradient force and curve resistance of each vehicle at its own chainage (in place).

    Parameters
    ----------
    x : ndarray
        Displacements [m].
    train : TrainArrays
    track : TrackArrays
    fgrade : ndarray
        Out: gravity component along the track, forward positive [N].
    rcurve : ndarray
        Out: curve resistance magnitude [N].
    """
    sections, start, offset = track.sections, track.start_chainage_m, train.centre_offset_m
    mass = train.mass_kg
    for i in range(x.shape[0]):
        # before the first section start, the first section applies
        k = max(lut_segment(sections, start + x[i] - offset[i]), 0)
        weight_kN = mass[i] * 9.81 / 1000.0
        fgrade[i] = -weight_kN * sections[GRADIENT, k]
        rcurve[i] = weight_kN * sections[CURVE, k]


@jit_inline
def _retarding(i, speed, res_a, rcurve, resist, kind, fa_scale, adh, weight):
    """Brake force, running + curve resistance (magnitudes, N) and d(total)/d(speed).

    ``res_a`` holds the Eq. 2 coefficients per vehicle; ``fa_scale`` the brake force per unit
    of Karwatzki's speed factor (blocks) or the disc brake force, fixed within a step; ``adh``
    the rail's adhesion table (empty: no cap), which caps the brake force at mu(v) m g
    (``weight``: m g) when the wheels would slide.
    """
    v_kmh = KMH_PER_MS * speed
    fr = (res_a[i, 0] + (res_a[i, 1] + res_a[i, 2] * v_kmh) * v_kmh + rcurve[i]) * resist
    dfr = (res_a[i, 1] + 2.0 * res_a[i, 2] * v_kmh) * KMH_PER_MS * resist
    fa, dfa = friction.retarding_force(kind[i], speed, fa_scale[i])
    if adh.shape[1] > 0 and fa > 0.0:
        mu, dmu = adhesion.mu_of(adh, speed)
        if fa > mu * weight[i]:  # the wheels slide: sliding friction, the available adhesion
            fa, dfa = mu * weight[i], dmu * weight[i]
    return fa, fr, dfa + dfr


#: Newton iterations with the cheap safeguards before the line search takes over.
FAST_ITERATIONS = 4


@jit_step
def _slope(step, u, du, ut, s, cp, fr_arrays, trial):
    """Directional derivative g(u + step*du) . du of the step's potential."""
    for i in range(u.shape[0]):
        ut[i] = u[i] + step * du[i]
    _residual(ut, s, cp, fr_arrays, trial)
    g = trial.g
    acc = 0.0
    for i in range(u.shape[0]):
        acc += g[i] * du[i]
    return acc


@jit_step
def _line_search(u, du, ut, s, cp, fr_arrays, trial):
    """Step length minimising the step's convex potential along du (root of its slope).

    Regula falsi (Illinois) on the slope, which is monotone along the line; a 1e-3 bracket is
    plenty, the next Newton iteration corrects the rest.
    """
    fhi = _slope(1.0, u, du, ut, s, cp, fr_arrays, trial)
    if fhi <= 0.0:
        return 1.0
    flo = _slope(0.0, u, du, ut, s, cp, fr_arrays, trial)
    lo, hi = 0.0, 1.0
    side = 0
    for _ in range(30):
        if hi - lo < 1e-3 * hi:
            break
        mid = (lo * fhi - hi * flo) / (fhi - flo)
        if not (lo < mid < hi):
            mid = 0.5 * (lo + hi)
        fmid = _slope(mid, u, du, ut, s, cp, fr_arrays, trial)
        if fmid == 0.0:
            return mid
        if fmid > 0.0:
            hi, fhi = mid, fmid
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo = mid, fmid
            if side == -1:
                fhi *= 0.5
            side = -1
    return lo if lo > 0.0 else hi


@jit_step
def _residual(u, s, cp, fr_arrays, w):
    """Residual g(u) of the implicit step and the pieces of its Jacobian (into ``w``).

    g_i = rho_i M_i (u_i - vhat_i) / (beta h) - (coupler, external and retarding forces on i).
    ``w.diag`` receives the vehicle terms of the Jacobian's diagonal and ``w.cj`` each
    coupler's d(force)/d(rate); returns True when every |g_i| is within the tolerance.
    """
    # bundle fields bound once: the loops below then touch plain arrays only
    xhat, vhat, bh, fx, meff, tol = s.xhat, s.vhat, s.bh[0], s.fx, s.meff, s.tol
    res_a, fa_scale, rcurve, resist, v_stick = s.res_a, s.fa_scale, s.rcurve, s.resist, s.v_stick
    hold = s.hold
    kind, adh, weight = fr_arrays.kind, fr_arrays.adhesion, fr_arrays.weight_N
    model, table, coef = cp.model, cp.table, cp.coef
    g, diag, cj, fc, fair = w.g, w.diag, w.cj, w.fc, w.fair
    seg = w.segment
    n = u.shape[0]
    nc = n - 1
    inv_bh = 1.0 / bh
    converged = True
    for i in range(n):
        g0 = meff[i] * (u[i] - vhat[i]) * inv_bh - fx[i]
        if i < nc:
            # the coupler behind vehicle i (one pass: its force is at hand for both ends)
            rate = u[i] - u[i + 1]
            d = xhat[i] - xhat[i + 1] + bh * rate
            f, kd, kr, seg[i] = couplers.force_near(model, table, coef, d, rate, seg[i])
            fc[i] = f
            cj[i] = bh * kd + kr
            g0 += f
        if i > 0:
            g0 -= fc[i - 1]
        spd = abs(u[i])
        fa, fr, dr = _retarding(i, spd, res_a, rcurve, resist, kind, fa_scale, adh, weight)
        total = fa + fr
        if hold[i] > total:
            # at rest at the step's start and held beyond the kinetic force: the force grows
            # linearly to the holding capacity across the standstill band and stays there
            # beyond it (monotone: the vehicle breaks away only if the step needs more)
            if spd > v_stick:
                g[i] = g0 + (hold[i] if u[i] > 0.0 else -hold[i])
                diag[i] = meff[i] * inv_bh
                fair[i] = fa
            else:
                g[i] = g0 + hold[i] * u[i] / v_stick
                diag[i] = meff[i] * inv_bh + hold[i] / v_stick
                fair[i] = fa * spd / v_stick
        elif spd > v_stick:
            sg = 1.0 if u[i] > 0.0 else -1.0
            g[i] = g0 + sg * total
            diag[i] = meff[i] * inv_bh + dr
            fair[i] = fa
        else:
            # standstill band: friction grows linearly up to its full value at |u| = v_stick
            # and holds the vehicle against any smaller force
            g[i] = g0 + total * u[i] / v_stick
            diag[i] = meff[i] * inv_bh + (total + dr * spd) / v_stick
            fair[i] = fa * spd / v_stick
        if not abs(g[i]) <= tol[i]:  # also catches NaN
            converged = False
    return converged


@jit_step
def _all_finite(a):
    """True when every element of ``a`` is finite."""
    for value in a:
        if not math.isfinite(value):
            return False
    return True


@jit_step
def _solve_tridiagonal(dvec, cj, g, dwork, du):
    """Solve J du = -g, J = diag(dvec) + sum over couplers of cj * (e_j - e_j+1)(e_j - e_j+1)^T.

    J is tridiagonal, symmetric positive definite (an M-matrix): Gaussian elimination needs no
    pivoting. It runs from both ends towards the middle row (a twisted factorization), so the
    two halves' recurrences, each a chain of dependent divisions, overlap; assembly and
    elimination are one pass, and ``dwork`` keeps the reciprocal pivots for the
    back-substitution.
    """
    n = dvec.shape[0]
    mid = n // 2
    # top rows 0..mid-1 downwards and bottom rows n-1..mid+1 upwards; s* is the coupling to
    # the next row over the last pivot, y* the last eliminated right-hand side
    s_top = y_top = s_bot = y_bot = 0.0
    for k in range(mid):
        c_up = cj[k - 1] if k > 0 else 0.0
        c_dn = cj[k]
        inv = 1.0 / (dvec[k] + c_up + c_dn - c_up * s_top)
        y_top = s_top * y_top - g[k]
        dwork[k] = inv
        du[k] = y_top
        s_top = c_dn * inv
        j = n - 1 - k
        if j > mid:
            c_up = cj[j - 1]
            c_dn = cj[j] if j < n - 1 else 0.0
            inv = 1.0 / (dvec[j] + c_up + c_dn - c_dn * s_bot)
            y_bot = s_bot * y_bot - g[j]
            dwork[j] = inv
            du[j] = y_bot
            s_bot = c_up * inv
    c_up = cj[mid - 1] if mid > 0 else 0.0
    c_dn = cj[mid] if mid < n - 1 else 0.0
    du[mid] = ((s_top * y_top + s_bot * y_bot - g[mid])
               / (dvec[mid] + c_up + c_dn - c_up * s_top - c_dn * s_bot))
    for k in range(1, mid + 1):  # mid >= n - 1 - mid
        i = mid - k
        du[i] = (du[i] + cj[i] * du[i + 1]) * dwork[i]
        j = mid + k
        if j < n:
            du[j] = (du[j] + cj[j - 1] * du[j - 1]) * dwork[j]


@jit_inline
def _bdf2(hs, hp):
    """Variable-step BDF2 for a step of ``hs`` after one of ``hp`` [s] (0: backward Euler):
    the step ratio w and c1, c2, beta of x_new = c1 x - c2 x_prev + beta hs v_new."""
    if hp > 0.0:
        w = hs / hp
        return (w, (1.0 + w) ** 2 / (1.0 + 2.0 * w), w * w / (1.0 + 2.0 * w),
                (1.0 + w) / (1.0 + 2.0 * w))
    return 0.0, 1.0, 0.0, 1.0


@jit_inline
def _substep(prop, tc, t_end):
    """The sub-step from ``tc`` towards ``t_end`` [s] for a proposal of ``prop`` [s] (0 or
    beyond the rest: the rest; over half the rest: two even pieces rather than a sliver):
    its length, end and whether it is the last."""
    rem = t_end - tc
    if prop <= 0.0 or prop >= rem:
        return rem, t_end, True
    if prop > 0.5 * rem:
        return 0.5 * rem, tc + 0.5 * rem, False
    return prop, tc + prop, False


#: Shortest step the error control may take, as a fraction of the nominal step.
MIN_STEP_FRACTION = 2.0 ** -12
#: Safety factor and the bounds of the step-size change after an error estimate.
SAFETY, MAX_GROWTH, MAX_SHRINK = 0.9, 2.0, 0.2
#: Step-size factor after a Newton iteration that did not converge.
NEWTON_SHRINK = 0.25
#: An error ratio below which :func:`_step_factor` surely grows the step (:func:`_next_step`;
#: it grows for ratios up to SAFETY ** 3 = 0.729 at order 2 and 0.81 at order 1).
GROWS_SURELY = 0.7


@jit
def _step_factor(ratio, order, rejected, after_rejection):
    """Factor on the step just tried that gives the next one (step-size controller).

    A rejected step is retried ``SAFETY / ratio`` as long (at least :data:`MAX_SHRINK`): an
    estimate beyond the tolerance is almost always a kink inside the step (a coupler switching
    between its Eq. 3 curves or reaching an end stop), where the local error falls in
    proportion to the step (measured on long trains: exponent 0.75-0.8), not with its cube as
    in smooth motion; the smooth rule ``ratio ** (-1 / (order + 1))`` would retry too long
    and be rejected again. After an accepted step the next grows by the smooth rule, at most
    :data:`MAX_GROWTH`, and not at all straight after a rejection (no accept/reject cycle).

    Parameters
    ----------
    ratio : float
        Error estimate over the tolerance (0: no estimate).
    order : float
        Order of the step's method (1 after a restart, else 2).
    rejected : bool
        The step was rejected.
    after_rejection : bool
        The step was the retry of a rejected one.

    Returns
    -------
    float
        Next step over this one.
    """
    if rejected:
        return max(MAX_SHRINK, SAFETY / ratio)
    grow = MAX_GROWTH
    if ratio > 0.0:
        grow = min(MAX_GROWTH, SAFETY * ratio ** (-1.0 / (order + 1.0)))
    if after_rejection:
        grow = min(grow, 1.0)
    return grow


@jit
def _next_step(hs, h_max, ratio, order, after_rejection):
    """The step proposed after an accepted one of ``hs`` seconds: ``hs`` times
    :func:`_step_factor`, at most ``h_max`` [s].

    A step already at ``h_max`` whose estimate is below :data:`GROWS_SURELY` stays there
    without the controller's power (the same result: the controller would grow it).
    """
    if hs >= h_max and ratio < GROWS_SURELY and not after_rejection:
        return h_max
    return min(hs * _step_factor(ratio, order, False, after_rejection), h_max)


@jit_inline
def _milne(hs, hp):
    """Milne's factor (1+w)/(2+3w) (1/2 after a restart, hp = 0) and the predictor's
    coefficient (hs/hp)^2 (0: the line) of :func:`_error_ratio`."""
    if hp > 0.0:
        w = hs / hp
        return (1.0 + w) / (2.0 + 3.0 * w), hs * hs / (hp * hp)
    return 0.5, 0.0


@jit_step
def _error_ratio(u, v, vp, a, stuck, stuck0, hs, hp, tolerance):
    """Largest local error estimate of the new speeds over the tolerance (Milne's device).

    The predictor is the quadratic through v(t - hp) and v(t) with slope a(t) (after a
    restart, hp = 0 and a backward-Euler step: the line v + hs a). With the leading error
    terms of variable-step BDF2, C_c = (1+w)^2 / (6 w (1+2w)) hs^3 v''', and of that
    predictor, C_p = (1+w) / (6 w) hs^3 v''' (w = hs / hp), the corrector's error is
    C_c / (C_c + C_p) = (1+w) / (2+3w) of their difference; 1/2 for backward Euler against
    the explicit Euler line. Vehicles inside, entering or leaving the standstill band are left
    out: the friction's kink there is resolved by the band, not by the step. A coupler crossing
    Eq. 3's band is not: its switch between the loading and unloading curves changes the
    forces by as much as an end stop, and short steps resolve it.
    """
    k, cq = _milne(hs, hp)
    worst = 0.0
    for i in range(u.shape[0]):  # branch-free: the compiler vectorises it
        q = v[i] + a[i] * hs + cq * (vp[i] - v[i] + a[i] * hp)  # cq = 0: the line
        e = abs(u[i] - q)
        e = 0.0 if stuck[i] or stuck0[i] else e
        worst = max(worst, e)
    return k * worst / tolerance


@jit_inline
def _record_coupler(j, f, d, t, xlo, xhi, peak_draft, t_draft, peak_buff, t_buff, beyond,
                    t_out, t_beyond, counter, slot):
    """Record coupler ``j``'s force ``f`` [N] and deflection ``d`` [m] at time ``t`` [s]: its
    peaks and its excursion beyond the valid range [xlo, xhi] (``counter[slot]`` counts the
    couplers that leave it for the first time)."""
    if f > peak_draft[j]:
        peak_draft[j] = f
        t_draft[j] = t
    if f < peak_buff[j]:
        peak_buff[j] = f
        t_buff[j] = t
    out = d - xhi if d > xhi else (xlo - d if d < xlo else 0.0)
    if out > 0.0:
        if t_out[j] < 0.0:
            t_out[j] = t
            counter[slot] += 1.0
        if out > beyond[j]:
            beyond[j] = out
            t_beyond[j] = t


#: Local time stepping (:func:`_refine`) in trains of at least this many vehicles (in shorter
#: ones the vehicles beyond the tolerance are a large part of the train: it steps shorter whole).
LOCAL_MIN_VEHICLES = 64
#: Vehicles added to a window on each side of those beyond the tolerance (and the largest gap
#: between two such groups that one window spans is twice as many).
LOCAL_MARGIN = 2
#: At most this many more vehicles on each side, to end a window at a coupler outside Eq. 3's
#: band (whose force does not depend on the deflection rate).
LOCAL_EXTEND = 8
#: The windows of a step cover at most this fraction of the train (else it steps shorter whole).
LOCAL_MAX_FRACTION = 0.25
#: Largest difference of momentum a window's end coupler may pass to its neighbour outside,
#: against the whole train's step, as a fraction of the tolerance times that neighbour's mass.
LOCAL_CONSISTENCY = 0.5
#: Sub-steps (taken and rejected) a window may try in one step before the train steps shorter.
LOCAL_MAX_TRIES = 4096
#: Step-size factor after a step whose windows failed (:func:`_refine_all`).
LOCAL_SHRINK = 0.5
#: Vehicles a window grows by on a side whose end coupler disagrees with the train's step, at
#: most LOCAL_WIDENINGS times (twice as many each time).
LOCAL_WIDEN, LOCAL_WIDENINGS = 8, 5
#: Results of :func:`_refine`: sub-stepped; failed; the end coupler at the front or rear (bits)
#: disagrees with the whole train's step.
WINDOW_OK, WINDOW_FAILED, WINDOW_FRONT, WINDOW_REAR = 0, 1, 2, 4
#: A step whose Newton iteration has not converged may still be kept for the vehicles whose
#: residual moves their speed by less than this fraction of the tolerance (the others are
#: sub-stepped).
LOCAL_RESIDUAL = 0.01
#: Error estimate (over the tolerance) given to a vehicle whose Newton residual has not
#: converged in a step (its window's first sub-step is then :data:`SAFETY` / this as long).
UNCONVERGED_ERROR = 2.0
#: Mass standing for a window's neighbours outside, whose motion is prescribed [kg].
PRESCRIBED_MASS_KG = 1e30


@jit_step
def _vehicle_errors(u, v, vp, a, stuck, stuck0, hs, hp, tolerance, out):
    """Each vehicle's error estimate over the tolerance, the terms of :func:`_error_ratio`
    (into ``out``)."""
    k, cq = _milne(hs, hp)
    for i in range(u.shape[0]):
        q = v[i] + a[i] * hs + cq * (vp[i] - v[i] + a[i] * hp)
        e = abs(u[i] - q)
        e = 0.0 if stuck[i] or stuck0[i] else e
        out[i] = k * e / tolerance


#: After local time stepping, the next step for the whole train is the one that about this
#: share of its vehicles would need to sub-step again.
LOCAL_TARGET_SHARE = 0.03


@jit_step
def _largest(values, k, top):
    """The ``k``-th largest of ``values`` (``top``: work array of at least ``k`` entries)."""
    filled = 0
    for x in values:
        if filled < k:
            j = filled
            filled += 1
        elif x > top[k - 1]:
            j = k - 1
        else:
            continue
        while j > 0 and top[j - 1] < x:  # insertion, largest first
            top[j] = top[j - 1]
            j -= 1
        top[j] = x
    return top[filled - 1]


@jit_step
def _find_windows(err, v, u, band, windows, max_vehicles):
    """Windows of vehicles to sub-step: those whose ``err`` exceeds 1, with
    :data:`LOCAL_MARGIN` more on each side, ended at couplers outside the band (at most
    :data:`LOCAL_EXTEND` more), merged where they touch. Returns how many (rows of
    ``windows``: first and last vehicle), or 0 when they would cover more than
    ``max_vehicles`` vehicles."""
    n = err.shape[0]
    count = 0
    total = 0
    i = 0
    while i < n:
        if not err[i] > 1.0:
            i += 1
            continue
        lo = i
        hi = i
        j = i + 1
        while j < n and j <= hi + 2 * LOCAL_MARGIN + 1:
            if err[j] > 1.0:
                hi = j
            j += 1
        i = j
        lo = max(lo - LOCAL_MARGIN, 0)
        hi = min(hi + LOCAL_MARGIN, n - 1)
        for _ in range(LOCAL_EXTEND):
            if lo == 0 or (abs(v[lo - 1] - v[lo]) > band and abs(u[lo - 1] - u[lo]) > band):
                break
            lo -= 1
        for _ in range(LOCAL_EXTEND):
            if hi == n - 1 or (abs(v[hi] - v[hi + 1]) > band and abs(u[hi] - u[hi + 1]) > band):
                break
            hi += 1
        if count > 0 and lo <= windows[count - 1, 1] + 1:
            total -= windows[count - 1, 1] - windows[count - 1, 0] + 1
            lo = min(lo, windows[count - 1, 0])
            windows[count - 1, 0] = lo
            windows[count - 1, 1] = hi
        else:
            windows[count, 0] = lo
            windows[count, 1] = hi
            count += 1
        total += hi - lo + 1
        if total > max_vehicles:
            return 0
    return count


@jit_inline
def _hermite(x0, v0, x1, v1, h, s):
    """Position and speed at the fraction ``s`` of a step of ``h`` [s] on the cubic through
    (x0, v0) at its start and (x1, v1) at its end."""
    s2 = s * s
    s3 = s2 * s
    x = ((2.0 * s3 - 3.0 * s2 + 1.0) * x0 + (s3 - 2.0 * s2 + s) * h * v0
         + (3.0 * s2 - 2.0 * s3) * x1 + (s3 - s2) * h * v1)
    v = ((6.0 * s2 - 6.0 * s) * (x0 - x1) / h + (3.0 * s2 - 4.0 * s + 1.0) * v0
         + (3.0 * s2 - 2.0 * s) * v1)
    return x, v


@jit_step
def _copy_records(a, b, draft, t_draft, buff, t_buff, beyond, t_out, t_beyond, draft_to,
                  t_draft_to, buff_to, t_buff_to, beyond_to, t_out_to, t_beyond_to):
    """Copy couplers a to b - 1's peaks and excursions (:func:`_record_coupler`'s arrays)."""
    for g in range(a, b):
        draft_to[g] = draft[g]
        t_draft_to[g] = t_draft[g]
        buff_to[g] = buff[g]
        t_buff_to[g] = t_buff[g]
        beyond_to[g] = beyond[g]
        t_out_to[g] = t_out[g]
        t_beyond_to[g] = t_beyond[g]


@jit_step
def _refine(lo, hi, h, tc, hs, hp, first_factor, model, state, ws, s, u, options, stats):
    """Sub-step vehicles ``lo`` to ``hi`` alone over the step [tc, tc + hs] the whole train
    has just tried (speeds ``u``, positions ``s.xhat + s.bh * u``), into ``ws.local``.

    Their neighbours outside move as the whole train's step has them (a cubic between its
    ends, through the prescribed-motion mass :data:`PRESCRIBED_MASS_KG`); the window's
    forces, the brake's force scales and the external forces are those of the step, held.
    Its sub-steps run the step's error control on the window's vehicles (first one
    ``first_factor`` of the step). Peaks and excursions of its couplers go to the window's
    copies. Returns :data:`WINDOW_OK` when every sub-step held the tolerance and the momentum
    the end couplers passed to the neighbours outside differs from the whole step's by at
    most :data:`LOCAL_CONSISTENCY` of the tolerance (trapezoidal impulses);
    :data:`WINDOW_FAILED` when a sub-step could not be taken; else the bits
    :data:`WINDOW_FRONT` / :data:`WINDOW_REAR` of the ends that disagree.
    """
    train, fr, cp = model.train, model.friction, model.couplers
    x, v, xp, vp, acc, stuck = (state.x_m, state.v_m_s, state.x_prev_m, state.v_prev_m_s,
                                state.accel_m_s2, state.stuck)
    loc = ws.local
    n = x.shape[0]
    a = max(lo - 1, 0)
    b = min(hi + 1, n - 1)
    m = b - a + 1
    front = lo > 0
    rear = hi < n - 1
    i0 = lo - a
    i1 = hi - a + 1  # inner vehicles: [i0, i1) of the window's arrays
    wx, wv, wxp, wvp = loc.x[a:b + 1], loc.v[a:b + 1], loc.xp[a:b + 1], loc.vp[a:b + 1]
    wacc = loc.acc[a:b + 1]
    wu, wxhat, wvhat = loc.u[a:b + 1], loc.xhat[a:b + 1], loc.vhat[a:b + 1]
    wmeff, wtol, wfx = loc.meff[a:b + 1], loc.tol[a:b + 1], loc.fx[a:b + 1]
    wst, wst1 = loc.stuck[a:b + 1], loc.stuck_new[a:b + 1]
    lw, sc = loc.work, ws.scratch
    work = _Work(lw.g[a:b + 1], lw.diag[a:b + 1], lw.cj[a:b], lw.fc[a:b], lw.fair[a:b + 1],
                 ws.work.segment[a:b])
    tr = sc.trial
    scratch = _Scratch(sc.ut[a:b + 1], sc.du[a:b + 1], sc.dwork[a:b + 1],
                       _Work(tr.g[a:b + 1], tr.diag[a:b + 1], tr.cj[a:b], tr.fc[a:b],
                             tr.fair[a:b + 1], tr.segment[a:b]))
    frw = friction.FrictionArrays(fr.kind[a:b + 1], fr.blocks[a:b + 1], fr.arrangement[a:b + 1],
                                  fr.mu_disc[a:b + 1], fr.force_max_N[a:b + 1],
                                  fr.full_scale_N[a:b + 1], fr.weight_N[a:b + 1], fr.adhesion)
    step = _Step(wxhat, wvhat, loc.bh, wfx, wmeff, wtol, s.res_a[a:b + 1], s.fa_scale[a:b + 1],
                 s.rcurve[a:b + 1], s.resist, s.v_stick, s.hold[a:b + 1])
    wfc = work.fc
    for k in range(m):
        g = a + k
        wx[k] = x[g]
        wv[k] = v[g]
        wxp[k] = xp[g]
        wvp[k] = vp[g]
        wacc[k] = acc[g]
        wst[k] = stuck[g]
        wmeff[k] = train.meff_kg[g]
        wtol[k] = ws.tol[g]
        wfx[k] = ws.fx[g]
    _copy_records(a, b, state.peak_draft_N, state.peak_draft_time_s, state.peak_buff_N,
                  state.peak_buff_time_s, state.beyond_range_m, state.out_of_range_time_s,
                  state.beyond_range_time_s, loc.peak_draft, loc.t_draft, loc.peak_buff,
                  loc.t_buff, loc.beyond, loc.t_out, loc.t_beyond)
    if front:
        wmeff[0] = PRESCRIBED_MASS_KG
        wtol[0] = math.inf
        wfx[0] = 0.0
    if rear:
        wmeff[m - 1] = PRESCRIBED_MASS_KG
        wtol[m - 1] = math.inf
        wfx[m - 1] = 0.0
    # the end couplers' forces at the step's start, and the momentum they pass in the window
    bh_c = s.bh[0]
    f_front = f_rear = 0.0
    if front:
        f_front = couplers.force(cp.model, cp.table, cp.coef, x[a] - x[a + 1],
                                 v[a] - v[a + 1])[0]
    if rear:
        f_rear = couplers.force(cp.model, cp.table, cp.coef, x[b - 1] - x[b],
                                v[b - 1] - v[b])[0]
    start_front, start_rear = f_front, f_rear
    imp_front = imp_rear = 0.0
    tolerance = options.tolerance_m_s
    v_stick = options.stick_band_m_s
    h_min = h * MIN_STEP_FRACTION
    t1 = tc + hs
    tau = tc
    hw = hs * first_factor
    hpw = hp
    retried = False
    tries = 0
    while True:
        hk, tau1, last = _substep(hw, tau, t1)
        wr, c1, c2, beta = _bdf2(hk, hpw)
        bhk = beta * hk
        loc.bh[0] = bhk
        for k in range(m):
            wxhat[k] = c1 * wx[k] - c2 * wxp[k]
            wvhat[k] = c1 * wv[k] - c2 * wvp[k]
            wu[k] = wv[k] + wr * (wv[k] - wvp[k])
            if wu[k] * wv[k] <= 0.0:
                wu[k] = wv[k]
        frac = (tau1 - tc) / hs
        if front:
            xb, vb = _hermite(x[a], v[a], s.xhat[a] + bh_c * u[a], u[a], hs, frac)
            wu[0] = vb
            wvhat[0] = vb
            wxhat[0] = xb - bhk * vb
        if rear:
            xb, vb = _hermite(x[b], v[b], s.xhat[b] + bh_c * u[b], u[b], hs, frac)
            wu[m - 1] = vb
            wvhat[m - 1] = vb
            wxhat[m - 1] = xb - bhk * vb
        code = _newton(wu, step, cp, frw, work, scratch,
                       FAST_ITERATIONS if hk > h_min else options.max_newton_iter, stats)
        tries += 1
        if code == NOT_FINITE:
            return WINDOW_FAILED
        bad = code == NEWTON_FAILED
        if bad and hk <= h_min:
            return WINDOW_FAILED
        ratio = 0.0
        order = 2.0 if hpw > 0.0 else 1.0
        if not bad:
            for k in range(i0, i1):
                wst1[k] = abs(wu[k]) <= v_stick
            ratio = _error_ratio(wu[i0:i1], wv[i0:i1], wvp[i0:i1], wacc[i0:i1], wst1[i0:i1],
                                 wst[i0:i1], hk, hpw, tolerance)
            bad = ratio > 1.0 and hk > h_min
        if bad:
            stats.local_rejected_steps += 1
            if tries >= LOCAL_MAX_TRIES:
                return WINDOW_FAILED
            shrink = NEWTON_SHRINK if code == NEWTON_FAILED else _step_factor(ratio, order, True,
                                                                                retried)
            hw = max(hk * shrink, h_min)
            retried = True
            continue
        # ---- accept the sub-step
        hw = _next_step(hk, hs, ratio, order, retried)
        retried = False
        stats.local_steps += 1
        if hk < stats.smallest_step_s:
            stats.smallest_step_s = hk
        kink = False
        for k in range(m):
            wacc[k] = (wu[k] - wvhat[k]) / bhk
            wxp[k] = wx[k]
            wvp[k] = wv[k]
            wx[k] = wxhat[k] + bhk * wu[k]
            wv[k] = wu[k]
        for k in range(i0, i1):
            kink |= wst1[k] != wst[k]
            wst[k] = wst1[k]
        for k in range(m - 1):
            _record_coupler(a + k, wfc[k], wx[k] - wx[k + 1], tau1, cp.valid_lo_m,
                            cp.valid_hi_m, loc.peak_draft, loc.t_draft, loc.peak_buff,
                            loc.t_buff, loc.beyond, loc.t_out, loc.t_beyond, loc.new_out, 0)
        if front:
            imp_front += 0.5 * hk * (f_front + wfc[0])
            f_front = wfc[0]
        if rear:
            imp_rear += 0.5 * hk * (f_rear + wfc[m - 2])
            f_rear = wfc[m - 2]
        hpw = 0.0 if kink else hk
        tau = tau1
        if last:
            break
    # the neighbours outside took the momentum of the whole train's step: it must agree
    fc = ws.work.fc
    result = WINDOW_OK
    if front and abs(imp_front - 0.5 * hs * (start_front + fc[a])) > (
            LOCAL_CONSISTENCY * tolerance * train.meff_kg[a]):
        result |= WINDOW_FRONT
    if rear and abs(imp_rear - 0.5 * hs * (start_rear + fc[b - 1])) > (
            LOCAL_CONSISTENCY * tolerance * train.meff_kg[b]):
        result |= WINDOW_REAR
    return result


@jit_step
def _commit(lo, hi, state, ws, u, stuck1):
    """Put window ``lo``-``hi``'s sub-stepped result into the whole train's step (its speeds,
    and positions, accelerations, brake and coupler forces as the accept pass derives them),
    and its couplers' peaks and excursions into the state."""
    loc = ws.local
    n = u.shape[0]
    a = max(lo - 1, 0)
    b = min(hi + 1, n - 1)
    bh = ws.bh_step[0]
    for g in range(lo, hi + 1):
        u[g] = loc.v[g]
        ws.xhat[g] = loc.x[g] - bh * u[g]
        ws.vhat[g] = u[g] - bh * loc.acc[g]
        ws.work.fair[g] = loc.work.fair[g]
        stuck1[g] = loc.stuck[g]
    for g in range(a, b):
        ws.work.fc[g] = loc.work.fc[g]
    _copy_records(a, b, loc.peak_draft, loc.t_draft, loc.peak_buff, loc.t_buff, loc.beyond,
                  loc.t_out, loc.t_beyond, state.peak_draft_N, state.peak_draft_time_s,
                  state.peak_buff_N, state.peak_buff_time_s, state.beyond_range_m,
                  state.out_of_range_time_s, state.beyond_range_time_s)


@jit_step
def _refine_all(h, tc, hs, hp, unconverged, model, state, ws, s, u, stuck1, options, stats):
    """Local time stepping of a rejected step: sub-step only the windows of vehicles whose
    estimate exceeds the tolerance (:func:`_find_windows`, :func:`_refine`) and keep the
    whole train's step for the others.

    Returns the largest error estimate over the tolerance outside the windows (for the next
    step's size), or -1 when the train must step shorter whole (windows too large, or one
    failed); then nothing of the state has changed.
    """
    loc = ws.local
    n = u.shape[0]
    _vehicle_errors(u, state.v_m_s, state.v_prev_m_s, state.accel_m_s2, stuck1, ws.stuck0,
                    hs, hp, options.tolerance_m_s, loc.err)
    if unconverged:
        # the vehicles whose residual would still move their speed by more than
        # LOCAL_RESIDUAL of the tolerance over the step (r beta h / m_eff) go to the windows
        g = ws.work.g
        meff = model.train.meff_kg
        scale = LOCAL_RESIDUAL * options.tolerance_m_s / ws.bh_step[0]
        for i in range(n):
            if not abs(g[i]) <= max(ws.tol[i], scale * meff[i]):
                loc.err[i] = max(loc.err[i], UNCONVERGED_ERROR)
    count = _find_windows(loc.err, state.v_m_s, u, model.couplers.band_m_s, loc.windows,
                          int(LOCAL_MAX_FRACTION * n))
    if count == 0:
        return -1.0
    order = 2.0 if hp > 0.0 else 1.0
    loc.new_out[0] = 0.0
    for k in range(count):
        lo, hi = loc.windows[k, 0], loc.windows[k, 1]
        worst = 0.0
        for g in range(lo, hi + 1):
            worst = max(worst, loc.err[g])
        first = _step_factor(worst, order, True, False)
        result = _refine(lo, hi, h, tc, hs, hp, first, model, state, ws, s, u, options, stats)
        widen = LOCAL_WIDEN
        for _ in range(LOCAL_WIDENINGS):
            if result == WINDOW_OK or result == WINDOW_FAILED:
                break
            # an end coupler passed another momentum than the train's step: widen the window
            # on that side (short of the windows either side) and sub-step it again
            low = loc.windows[k - 1, 1] + 2 if k > 0 else 0
            high = loc.windows[k + 1, 0] - 2 if k + 1 < count else n - 1
            wider_lo = max(lo - widen, low) if result & WINDOW_FRONT else lo
            wider_hi = min(hi + widen, high) if result & WINDOW_REAR else hi
            if wider_lo == lo and wider_hi == hi:
                break
            lo, hi = wider_lo, wider_hi
            loc.windows[k, 0] = lo
            loc.windows[k, 1] = hi
            result = _refine(lo, hi, h, tc, hs, hp, first, model, state, ws, s, u, options,
                             stats)
            widen *= 2
        if result != WINDOW_OK:
            return -1.0
    # the next step's size: the error estimate that LOCAL_TARGET_SHARE of the train exceeds
    # (those vehicles will be sub-stepped again)
    outside = _largest(loc.err, max(int(LOCAL_TARGET_SHARE * n), 1), loc.top)
    for k in range(count):
        _commit(loc.windows[k, 0], loc.windows[k, 1], state, ws, u, stuck1)
    state.step_control[OUT_OF_RANGE] += loc.new_out[0]
    stats.refined_steps += 1
    return outside


@jit
def run_steps(nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
              watch_stop):
    """Advance the train ``nsteps`` nominal steps of ``h`` seconds (state updated in place).

    With ``options.tolerance_m_s`` > 0 each nominal step is taken whole when the local error
    estimate (:func:`_error_ratio`) holds the tolerance, else in shorter sub-steps: a step
    whose estimate exceeds it (or whose Newton iteration does not converge) is rejected and
    retried shorter (in a long train with ``options.local_steps``, only the vehicles that
    need it, :func:`_refine_all`), and after each accepted step the next may grow by up to
    :data:`MAX_GROWTH`, never beyond the nominal step (:func:`_step_factor`). Sub-steps end
    exactly on the nominal step's end and the proposal carries over in
    ``state.step_control``: the same nominal steps give the same result however they are
    grouped into calls. With tolerance 0 every nominal step is one step.

    Parameters
    ----------
    nsteps : int
    h : float
        Nominal step [s].
    t : float
        Time at the start [s].
    hp : float
        Previous step [s]; 0 starts with a backward-Euler step (no history).
    model : TrainModel
        The compiled train.
    inputs : Inputs
        Traction demand and external forces over the chunk.
    state : KinematicState
        Updated in place.
    brake_state : BrakeState
        The brake model's state, updated in place.
    events : CommandEvents
        Brake commands issued at the head.
    stats : STATS_DTYPE record
        Counters, incremented.
    options : Options
    watch_stop : bool
        Return ``STOPPED`` right after the first nominal step that leaves every vehicle slower
        than ``options.standstill_m_s``.

    Returns
    -------
    code : int
        ``OK``, ``NEWTON_FAILED``, ``NOT_FINITE`` (a force or its residual became infinite or
        NaN) or ``STOPPED``.
    t : float
        Time reached [s]: the end of the last nominal step completed, or the start of the
        step that failed.
    hp : float
        Last step size [s].
    done : int
        Nominal steps completed.
    """
    ws = new_workspace(model, state, brake_state, options)
    return run_loop(nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
                     watch_stop, ws)


@jit
def new_workspace(model, state, brake_state, options):
    """The work arrays of :func:`run_loop` for a train, its state and options.

    One workspace serves every call of :func:`run_loop` with the same ``model``, ``state``
    (its coupler forces are the workspace's), ``brake_state`` and ``options``; a call leaves
    nothing in it that changes the next call's results.

    Parameters
    ----------
    model : TrainModel
    state : KinematicState
    brake_state : BrakeState
    options : Options

    Returns
    -------
    _Workspace
    """
    n = state.x_m.shape[0]
    nc = max(n - 1, 1)
    mass, axles = model.train.mass_kg, model.train.axles
    tol = np.empty(n)
    res_a = np.empty((n, 3))
    for i in range(n):
        tol[i] = options.newton_rtol * mass[i] * 9.81
        a0, a1, a2 = resistance_coefficients(mass[i], axles[i])
        res_a[i, 0] = a0
        res_a[i, 1] = a1
        res_a[i, 2] = a2
    fb = brake_state.force_N
    return _Workspace(
        np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_), np.empty(n, np.bool_),
        np.empty(n), tol, res_a, np.empty(n), np.empty(n), np.empty(n), np.empty(1),
        _Work(np.empty(n), np.empty(n), np.empty(nc), state.coupler_force_N, np.empty(n),
              np.zeros(nc, np.int64)),
        _Scratch(np.empty(n), np.empty(n), np.empty(n),
                 _Work(np.empty(n), np.empty(n), np.empty(nc), np.empty(nc), np.empty(n),
                       np.zeros(nc, np.int64))),
        np.empty_like(fb), np.empty_like(brake_state.level),
        np.empty_like(brake_state.level_kind), np.empty_like(brake_state.next_event),
        np.empty_like(brake_state.extra), np.empty_like(state.traction_force_N),
        _Local(np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
               np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
               np.empty(n, np.bool_), np.empty(n, np.bool_), np.empty(1),
               _Work(np.empty(n), np.empty(n), np.empty(nc), np.empty(nc), np.empty(n),
                     np.zeros(nc, np.int64)),
               np.empty(nc), np.empty(nc), np.empty(nc), np.empty(nc), np.empty(nc),
               np.empty(nc), np.empty(nc), np.zeros(1), np.empty(n), np.zeros((n, 2), np.int64),
               np.empty(n)), np.zeros(n))


@jit_step
def _copy_undo(fb, lvl, kind, nxt, extra, ftr, fb_to, lvl_to, kind_to, nxt_to, extra_to, ftr_to):
    """Copy what a rejected step must undo: the brake state's arrays and the applied traction."""
    for i in range(fb.shape[0]):
        fb_to[i] = fb[i]
        lvl_to[i] = lvl[i]
        kind_to[i] = kind[i]
        nxt_to[i] = nxt[i]
        ftr_to[i] = ftr[i]
        for j in range(extra.shape[1]):
            extra_to[i, j] = extra[i, j]


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
    work: _Work
    scratch: "_Scratch"
    save_fb: np.ndarray
    save_lvl: np.ndarray
    save_kind: np.ndarray
    save_next: np.ndarray
    save_extra: np.ndarray
    save_ftr: np.ndarray
    local: "_Local"
    hold: np.ndarray


@jit_step
def run_loop(nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
             watch_stop, ws):
    """The step loop of :func:`run_steps` (same arguments and results, plus its workspace
    ``ws`` from :func:`new_workspace`, which a caller may keep for its next call).

    Without reference counting: it allocates nothing, and numba would otherwise count a
    reference to every array of every bundle it touches or passes on, each step (and, called
    from Python, to each of the arguments' arrays).
    """
    # bundle fields bound once: the loops below then touch plain arrays only
    train = model.train
    fr_arrays = model.friction
    cp = model.couplers
    x, v, xp, vp, stuck = state.x_m, state.v_m_s, state.x_prev_m, state.v_prev_m_s, state.stuck
    ftr, fbrake, fc = state.traction_force_N, state.brake_force_N, state.coupler_force_N
    peak_draft, t_draft = state.peak_draft_N, state.peak_draft_time_s
    peak_buff, t_buff = state.peak_buff_N, state.peak_buff_time_s
    lut_out, t_lut_out = state.beyond_range_m, state.out_of_range_time_s
    t_lut_max = state.beyond_range_time_s
    acc, control = state.accel_m_s2, state.step_control
    fext = inputs.external_force_N
    fb = brake_state.force_N
    kind, blocks, arrangement, mu_disc = (fr_arrays.kind, fr_arrays.blocks, fr_arrays.arrangement,
                                          fr_arrays.mu_disc)
    v_stick = options.stick_band_m_s
    v_stop = options.standstill_m_s
    tolerance = options.tolerance_m_s
    adaptive = tolerance > 0.0
    h_min = h * MIN_STEP_FRACTION
    n = x.shape[0]
    nc = n - 1
    u, xhat, vhat, stuck0, stuck1 = ws.u, ws.xhat, ws.vhat, ws.stuck0, ws.stuck1
    fa_scale, tol, res_a, fx = ws.fa_scale, ws.tol, ws.res_a, ws.fx
    fgrade, rcurve, bh_step = ws.fgrade, ws.rcurve, ws.bh_step
    w, scratch = ws.work, ws.scratch
    fair = w.fair
    full_scale = fr_arrays.full_scale_N
    meff, mass = train.meff_kg, train.mass_kg
    applied_work, applied_dist = state.applied_work_J, state.applied_distance_m
    pk_fast, pk_fast_t, pk_fast_v = (state.peak_brake_fast_N, state.peak_brake_fast_time_s,
                                     state.peak_brake_fast_speed_m_s)
    pk_slow, pk_slow_t, pk_slow_v = (state.peak_brake_slow_N, state.peak_brake_slow_time_s,
                                     state.peak_brake_slow_speed_m_s)
    adh, weight = fr_arrays.adhesion, fr_arrays.weight_N
    slide_on = adh.shape[1] > 0
    slide_t, slide_first = state.slide_time_s, state.slide_first_s
    xlo = cp.valid_lo_m
    xhi = cp.valid_hi_m
    # what a rejected step undoes: the brake model's state and the applied traction
    save_fb, save_lvl, save_kind = ws.save_fb, ws.save_lvl, ws.save_kind
    save_next, save_extra, save_ftr = ws.save_next, ws.save_extra, ws.save_ftr
    lvl, lkind, nxt, extra = (brake_state.level, brake_state.level_kind, brake_state.next_event,
                              brake_state.extra)
    hold = ws.hold
    fmax = fr_arrays.force_max_N
    s = _Step(xhat, vhat, bh_step, fx, train.meff_kg, tol, res_a, fa_scale, rcurve,
              train.resist, v_stick, hold)
    retried = False  # the step being tried follows a rejection
    local = adaptive and options.local_steps and n >= LOCAL_MIN_VEHICLES
    # on a track of one section every vehicle's gradient and curve forces stay as they are
    fixed_track = model.track.sections.shape[1] == 1
    if fixed_track:
        track_forces(x, train, model.track, fgrade, rcurve)
    for _step in range(nsteps):
        t_end = t + h
        tc = t
        while True:
            # ---- the sub-step [tc, t1] of the nominal step [t, t_end]
            prop = control[NEXT_STEP]
            if not adaptive or (tc == t and (prop <= 0.0 or prop >= h)):
                hs, t1, last = h, t_end, True
            else:
                hs, t1, last = _substep(prop, tc, t_end)
            if adaptive:
                _copy_undo(fb, lvl, lkind, nxt, extra, ftr,
                           save_fb, save_lvl, save_kind, save_next, save_extra, save_ftr)
            brakes.advance(model.brakes, brake_state, events, tc, t1)
            # traction and track forces vary slowly: taken at the start of the step
            advance_traction(hs, inputs.traction_demand, v, ftr, model.traction)
            if not fixed_track:
                track_forces(x, train, model.track, fgrade, rcurve)
            for i in range(n):
                fx[i] = fext[i] + ftr[i] + fgrade[i]
            friction.force_scales(kind, blocks, arrangement, mu_disc, fb, fa_scale)
            w_ratio, c1, c2, beta = _bdf2(hs, hp)
            bh = beta * hs
            for i in range(n):
                stuck0[i] = stuck[i]
                # a vehicle at rest holds up to its standstill capacity (braked: adhesion)
                hold[i] = friction.standstill_capacity(fb[i], fmax[i], mass[i]) if stuck[i] \
                    else 0.0
                xhat[i] = c1 * x[i] - c2 * xp[i]
                vhat[i] = c1 * v[i] - c2 * vp[i]
                u[i] = v[i] + w_ratio * (v[i] - vp[i])
                if u[i] * v[i] <= 0.0:
                    u[i] = v[i]  # never extrapolate through standstill
            bh_step[0] = bh
            # with local time stepping, a step whose iteration converges slowly (couplers
            # crossing bands) leaves the vehicles it has not converged to their sub-steps
            refine = local and hs > h_min and control[ACCEL_VALID] > 0.0
            code = _newton(u, s, cp, fr_arrays, w, scratch,
                           FAST_ITERATIONS if refine else options.max_newton_iter, stats)
            if code == NOT_FINITE:
                return NOT_FINITE, tc, hp, _step
            reject = code == NEWTON_FAILED
            if reject and not (adaptive and hs > h_min):
                return NEWTON_FAILED, tc, hp, _step
            for i in range(n):
                stuck1[i] = abs(u[i]) <= v_stick
            ratio = 0.0
            order = 2.0 if hp > 0.0 else 1.0
            if adaptive and not reject and control[ACCEL_VALID] > 0.0:
                ratio = _error_ratio(u, v, vp, acc, stuck1, stuck0, hs, hp, tolerance)
                reject = ratio > 1.0 and hs > h_min
            if reject and refine:
                # sub-step only the vehicles that need it, if they are few
                outside = _refine_all(h, tc, hs, hp, code == NEWTON_FAILED, model, state, ws, s,
                                      u, stuck1, options, stats)
                if outside >= 0.0:
                    reject = False
                    code = OK
                    ratio = outside
            if reject:
                # undo the step's changes to the state and retry shorter
                _copy_undo(save_fb, save_lvl, save_kind, save_next, save_extra, save_ftr,
                           fb, lvl, lkind, nxt, extra, ftr)
                stats.rejected_steps += 1
                if refine:
                    # the windows failed: most of the train held the step
                    shrink = LOCAL_SHRINK
                elif code == NEWTON_FAILED:
                    shrink = NEWTON_SHRINK
                else:
                    shrink = _step_factor(ratio, order, True, retried)
                control[NEXT_STEP] = max(hs * shrink, h_min)
                retried = True
                continue
            # ---- accept
            if adaptive:
                control[NEXT_STEP] = _next_step(hs, h, ratio, order, retried)
                retried = False
            stats.steps += 1
            if stats.smallest_step_s == 0.0 or hs < stats.smallest_step_s:
                stats.smallest_step_s = hs
            tc = t1
            for i in range(n):  # a loop of its own: the compiler vectorises the division
                acc[i] = (u[i] - vhat[i]) / bh
            # a vehicle that entered or left the standstill band has a kink in its speed: the
            # BDF2 history would extrapolate across it (and push a just-stopped vehicle
            # backwards), so the next step restarts with backward Euler
            kink = False
            for i in range(n):
                kink |= stuck1[i] != stuck0[i]
                stuck[i] = stuck1[i]
                xp[i] = x[i]
                vp[i] = v[i]
                x[i] = xhat[i] + bh * u[i]
                v[i] = u[i]
                fbrake[i] = fair[i]
                if slide_on and u[i] > v_stick and fair[i] > 0.0:
                    mu, _dmu = adhesion.mu_of(adh, u[i])
                    if fair[i] >= mu * weight[i] * (1.0 - 1e-12):  # capped: sliding
                        slide_t[i] += hs
                        if slide_first[i] < 0.0:
                            slide_first[i] = tc - hs
                # the brake force's peaks while moving, apart above and below 30 km/h
                if u[i] > ADHESION_SPLIT_SPEED_M_S:
                    if fair[i] > pk_fast[i]:
                        pk_fast[i] = fair[i]
                        pk_fast_t[i] = tc
                        pk_fast_v[i] = u[i]
                elif u[i] > v_stop and fair[i] > pk_slow[i]:
                    pk_slow[i] = fair[i]
                    pk_slow_t[i] = tc
                    pk_slow_v[i] = u[i]
                if (u[i] >= MEAN_ADHESION_MIN_SPEED_M_S
                        and fa_scale[i] >= FULL_APPLICATION * full_scale[i] > 0.0):
                    # the rails take the brake force less what decelerates the rotating
                    # masses, (rho - 1) M a (EN 14531-1's mean required adhesion)
                    dx = x[i] - xp[i]
                    applied_work[i] += (fair[i] + (meff[i] - mass[i]) * acc[i]) * dx
                    applied_dist[i] += dx
                if i == 0:
                    continue
                # the coupler ahead of vehicle i, now that both its ends have moved: peaks
                # and excursions beyond its valid range
                _record_coupler(i - 1, fc[i - 1], x[i - 1] - x[i], tc, xlo, xhi, peak_draft,
                                t_draft, peak_buff, t_buff, lut_out, t_lut_out, t_lut_max,
                                control, OUT_OF_RANGE)
            control[ACCEL_VALID] = 1.0
            hp = 0.0 if kink else hs
            if last:
                break
        t = t_end
        if watch_stop:
            all_stopped = True
            for i in range(n):
                if v[i] > v_stop:  # still moving forward (a vehicle rolling back has stopped)
                    all_stopped = False
                    break
            if all_stopped:
                return STOPPED, t, hp, _step + 1
    return OK, t, hp, nsteps


class _Scratch(NamedTuple):
    """Work arrays of the Newton iteration: trial speeds, update, Thomas scratch, line search."""

    ut: np.ndarray
    du: np.ndarray
    dwork: np.ndarray
    trial: _Work


@jit_step
def _newton(u, s, cp, fr_arrays, w, scratch, max_iter, stats):
    """Solve the step's equations for the new speeds ``u`` (in place) by Newton's method.

    Returns ``OK``, ``NEWTON_FAILED`` after ``max_iter`` iterations without convergence, or
    ``NOT_FINITE``.
    """
    g, diag, cj, fc = w.g, w.diag, w.cj, w.fc
    ut, du, dtmp, trial = scratch.ut, scratch.du, scratch.dwork, scratch.trial
    cp_model, cp_table, cp_coef, band = cp.model, cp.table, cp.coef, cp.band_m_s
    xhat, bh, v_stick = s.xhat, s.bh[0], s.v_stick
    n = u.shape[0]
    nc = n - 1
    it = 0
    while True:
        converged = _residual(u, s, cp, fr_arrays, w)
        if converged:
            break
        if not _all_finite(g):
            # a NaN or infinite force cannot be iterated away: fail at once
            stats.newton_iterations += it
            return NOT_FINITE
        if it >= max_iter:
            stats.newton_iterations += it
            return NEWTON_FAILED
        it += 1
        _solve_tridiagonal(diag, cj, g, dtmp, du)
        alpha = 1.0
        if it <= FAST_ITERATIONS and band > 0.0:
            # a coupler whose deflection speed would jump across its whole steep band
            # most likely ends inside it: solve again with that coupler on the band's line
            again = False
            for j in range(nc):
                r0 = u[j] - u[j + 1]
                r1 = r0 + du[j] - du[j + 1]
                if r0 * r1 < 0.0 and abs(r0) > band and abs(r1) > band:
                    d = xhat[j] - xhat[j + 1] + bh * r0
                    fm, kd, kr = couplers.force(cp_model, cp_table, cp_coef, d, 0.0)
                    shift = fm + kr * r0 - fc[j]  # band line at r0 minus actual force
                    g[j] += shift
                    g[j + 1] -= shift
                    cj[j] = bh * kd + kr
                    again = True
            if again:
                _solve_tridiagonal(diag, cj, g, dtmp, du)
                # cheap safeguard: do not let a coupler jump across its whole steep band
                # (without a coupler about to, none can: alpha stays 1)
                for j in range(nc):
                    r0 = u[j] - u[j + 1]
                    r1 = r0 + du[j] - du[j + 1]
                    if r0 * r1 < 0.0 and abs(r0) > band and abs(r1) > band:
                        a = r0 / (r0 - r1)
                        if a < alpha:
                            alpha = a
        if it <= FAST_ITERATIONS:
            # cheap safeguards, enough for almost every step: the band's above, and no
            # vehicle's jump across its standstill band
            if alpha < 1.0:
                stats.band_cutbacks += 1
            for i in range(n):
                u1 = u[i] + alpha * du[i]
                if u1 * u[i] < 0.0 and abs(u[i]) > v_stick and abs(u1) > v_stick:
                    u1 = 0.0
                    stats.standstill_projections += 1
                u[i] = u1
        else:
            # globally convergent fallback: g is the gradient of a convex potential and du
            # a descent direction, so minimise along du exactly (the directional
            # derivative is monotone along the line: find its root by bisection)
            stats.line_searches += 1
            alpha = _line_search(u, du, ut, s, cp, fr_arrays, trial)
            for i in range(n):
                u[i] += alpha * du[i]
    stats.newton_iterations += it
    if it > stats.max_newton_iterations:
        stats.max_newton_iterations = it
    return OK


def bind_run_steps(*args):
    """:func:`run_steps` compiled for the types of ``args``, callable without numba's dispatch.

    Numba types every argument of every call, recursively through the bundles (about 60
    arrays for a train), which costs more than a short chunk's physics; the returned callable
    skips that. Call it only with arguments of the same types (the same bundles, arrays of
    the same dtype, dimension and C layout).

    Parameters
    ----------
    *args
        A valid argument list of :func:`run_steps` (it is not run).

    Returns
    -------
    callable
        Same arguments and results as :func:`run_steps`.
    """
    return _bind(run_steps, args)


def bind_run_loop(*args):
    """:func:`run_loop` compiled for the types of ``args``, as :func:`bind_run_steps`.

    The cheapest call per chunk: no workspace to allocate, and no reference counting of the
    arguments' arrays (about 90 with the workspace; counted, they cost twice as much).

    Parameters
    ----------
    *args
        A valid argument list of :func:`run_loop` (it is not run).

    Returns
    -------
    callable
        Same arguments and results as :func:`run_loop`.
    """
    return _bind(run_loop, args)


def _bind(fn, args):
    """``fn`` compiled for the types of ``args`` (see :func:`bind_run_steps`)."""
    if not HAVE_NUMBA:  # pragma: no cover - plain Python has no dispatch to skip
        return fn
    key = _layout_key(args)
    key = None if key is None else (fn.__name__, key)
    bound = _BOUND.get(key) if key is not None else None
    if bound is None:
        bound = fn.compile(tuple(fn.typeof_pyval(a) for a in args))
        if key is not None:
            _BOUND[key] = bound
    return bound


#: :func:`bind_run_steps` and :func:`bind_run_loop` by function and the layout of the
#: arguments (numba types them slowly: ~1 ms).
_BOUND: dict = {}


def _layout_key(value):
    """What numba's type of ``value`` depends on, built without numba (None: not known here).

    Arrays: dtype, dimension, contiguity, writeability and alignment (numba's layout and
    read-only flag); named tuples: their class and fields'; plain bool, int and float: the
    class (numba types every Python int as int64, every float as float64).
    """
    if isinstance(value, np.ndarray):
        f = value.flags
        return (value.dtype, value.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if isinstance(value, tuple):
        keys = tuple(_layout_key(v) for v in value)
        return None if None in keys else (type(value), keys)
    if type(value) in (bool, float) or (type(value) is int and -2**63 <= value < 2**63):
        return type(value)
    if isinstance(value, np.void):  # a record of a structured array
        return (np.void, value.dtype)
    return None


# run_steps compiles the brake and coupler models into itself: numba's cache of it must go when
# any of their sources changes, not only this file
brakes.refresh_stale_caches(globals(), brakes.SOURCES_STAMP)

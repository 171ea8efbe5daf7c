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
law turns them into retarding forces, whose work heats the blocks and wheels
(:mod:`.brakes.thermal`, advanced on its own grid of simulated time). With an adhesion
condition each vehicle's wheelsets roll (the force capped at the adhesion) or are locked
(sliding friction), a state decided between steps and fixed within each
(:mod:`.brakes.wheel_slide`), so that a step's equations stay continuous and monotone.

Everything is passed in named bundles (typing.NamedTuple of arrays and scalars, which numba
compiles like structs): :class:`TrainModel` (compiled once), :class:`Inputs` (per chunk),
:class:`KinematicState` plus the brake model's state and the command events (mutable, updated
in place), a :data:`STATS_DTYPE` record of counters and :class:`Options`.
"""
from __future__ import annotations

import math

import numpy as np

from . import brakes
from .brakes import friction, thermal, wheel_slide
from .equations import (HAVE_NUMBA, jit_step, jit_step_inner, lut_segment, plain, plain_now,
                        renamed_copy, resistance_coefficients)
from .bundles import (ACCEL_VALID, ADHESION_SPLIT_SPEED_M_S, CURVE, DEFAULT_NEWTON_RTOL,
                      DEFAULT_TOLERANCE_M_S, FULL_APPLICATION, GRADIENT, MOVED, NEWTON_FAILED,
                      NEXT_STEP, NOT_FINITE, OK, OUT_OF_RANGE, REST_SINCE, SECTION_START,
                      SETTLE_S, SETTLED, STATS_DTYPE, STOPPED, WATCH_NONE, WATCH_REST,
                      WATCH_SETTLE, WATCH_STOP, Inputs, KinematicState,
                      MEAN_ADHESION_MIN_SPEED_M_S, Options, Stats, TrackArrays, TractionArrays,
                      TrainArrays, TrainModel, _Local, _Scratch, _Step, _Work, _Workspace,
                      counters, new_stats, read_stats)
from .step_control import (MIN_STEP_FRACTION, NEWTON_SHRINK, _bdf2, _error_ratio, _next_step,
                           _record_coupler, _step_factor, _substep)
from .newton import FAST_ITERATIONS, _newton
from .local_steps import LOCAL_MIN_VEHICLES, LOCAL_SHRINK, _refine_all

#: What :func:`run_loop` calls to advance the brakes and to sub-step part of the train: every
#: model (the branch of ``arrays.model``) and local time stepping; :func:`loop_for` compiles it
#: with one model's ``advance`` and, where local steps cannot run, without them.
advance_brakes = brakes.advance
refine_all = _refine_all

#: The kernel's interface (the bundles and constants from :mod:`.bundles`, and what this module
#: defines), as its callers use it.
__all__ = ["ACCEL_VALID", "ADHESION_SPLIT_SPEED_M_S", "CURVE", "DEFAULT_NEWTON_RTOL",
           "DEFAULT_TOLERANCE_M_S", "FULL_APPLICATION", "GRADIENT", "Inputs", "KinematicState",
           "LOCAL_MIN_VEHICLES", "MEAN_ADHESION_MIN_SPEED_M_S", "MOVED", "NEWTON_FAILED",
           "NEXT_STEP", "NOT_FINITE", "OK", "OUT_OF_RANGE", "Options", "REST_SINCE",
           "SECTION_START", "SETTLED", "SETTLE_S", "STATS_DTYPE", "STOPPED", "Stats",
           "TrackArrays", "TractionArrays", "TrainArrays", "TrainModel", "WATCH_NONE",
           "WATCH_REST", "WATCH_SETTLE", "WATCH_STOP",
           "advance_traction", "bind_run_loop", "local_steps_run", "loop_for", "new_stats",
           "new_workspace", "read_stats", "run_loop", "run_steps", "track_forces"]


@jit_step_inner
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


def run_steps(nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
              watch):
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
    stats : ndarray or record
        Counters, incremented: a :func:`new_stats` array (the cheaper argument) or its
        :data:`STATS_DTYPE` record.
    options : Options
    watch : int
        What to watch at the end of each nominal step (:data:`WATCH_NONE`,
        :data:`WATCH_STOP`, :data:`WATCH_SETTLE`, :data:`WATCH_REST`): return ``STOPPED``
        right after the first nominal step that leaves every vehicle slower than
        ``options.standstill_m_s`` going forward; ``SETTLED`` once every vehicle's speed has
        stayed within it for :data:`SETTLE_S` (since ``state.step_control[REST_SINCE]``, which
        the caller sets to -1 when it starts watching); ``MOVED`` after the first nominal step
        that leaves a vehicle faster than it either way.

    Returns
    -------
    code : int
        ``OK``, ``NEWTON_FAILED``, ``NOT_FINITE`` (a force or its residual became infinite or
        NaN), ``STOPPED``, ``SETTLED`` or ``MOVED``.
    t : float
        Time reached [s]: the end of the last nominal step completed, or the start of the
        step that failed.
    hp : float
        Last step size [s].
    done : int
        Nominal steps completed.
    """
    ws = new_workspace(model, state, brake_state, options)
    args = (nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
            watch, ws)
    return loop_for(model, state, options)(*args)


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
    tol = options.newton_rtol * mass * 9.81
    res_a = np.array([resistance_coefficients(m, a) for m, a in zip(mass, axles)],
                     dtype=np.float64).reshape(n, 3)
    fb = brake_state.force_N
    return _Workspace(
        np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_), np.empty(n, np.bool_),
        np.empty(n), tol, res_a, np.empty(n), np.empty(n), np.empty(n), np.empty(1), np.zeros(n),
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
               np.empty(n)),
        # per-vehicle constants of the accept pass's records
        FULL_APPLICATION * model.friction.full_scale_N, model.train.meff_kg - mass)


@jit_step_inner
def _watch(watch, v, v_stop, t, control):
    """The end of a nominal step at ``t`` [s] as :func:`run_steps`'s ``watch`` sees it: ``OK``
    or the code to return (``control[REST_SINCE]`` updated while watching a train settle)."""
    if watch == WATCH_STOP:
        for i in range(v.shape[0]):
            if v[i] > v_stop:  # still moving forward (a vehicle rolling back has stopped)
                return OK
        return STOPPED
    still = True
    for i in range(v.shape[0]):
        if abs(v[i]) > v_stop:
            still = False
            break
    if watch == WATCH_REST:
        return OK if still else MOVED
    if not still:
        control[REST_SINCE] = -1.0
    elif control[REST_SINCE] < 0.0:
        control[REST_SINCE] = t
    elif t - control[REST_SINCE] >= SETTLE_S - 1e-9:
        return SETTLED
    return OK


@jit_step_inner
def _brake_records(tc, v_stop, u, fair, x, xp, acc, fa_scale, full_on, rotating, pk_fast,
                   pk_fast_t, pk_fast_v, pk_slow, pk_slow_t, pk_slow_v, applied_work,
                   applied_dist):
    """The accept pass's records of each vehicle's brake at the end of a step at ``tc`` [s]
    (in place): its force's peaks while moving, apart above and below 30 km/h (when, at what
    speed), and its work at the rails while fully applied (the mean utilised adhesion).

    Without branches (each record keeps its value or takes the new one): the compiler
    vectorises the passes.
    """
    for i in range(u.shape[0]):
        f, s, pk, pt, pv = fair[i], u[i], pk_fast[i], pk_fast_t[i], pk_fast_v[i]
        new = (s > ADHESION_SPLIT_SPEED_M_S) & (f > pk)
        pk_fast[i] = f if new else pk
        pk_fast_t[i] = tc if new else pt
        pk_fast_v[i] = s if new else pv
    for i in range(u.shape[0]):
        f, s, pk, pt, pv = fair[i], u[i], pk_slow[i], pk_slow_t[i], pk_slow_v[i]
        new = (s <= ADHESION_SPLIT_SPEED_M_S) & (s > v_stop) & (f > pk)
        pk_slow[i] = f if new else pk
        pk_slow_t[i] = tc if new else pt
        pk_slow_v[i] = s if new else pv
    for i in range(u.shape[0]):
        # the rails take the brake force less what decelerates the rotating masses,
        # (rho - 1) M a (EN 14531-1's mean required adhesion)
        on = ((u[i] >= MEAN_ADHESION_MIN_SPEED_M_S) & (fa_scale[i] >= full_on[i])
              & (full_on[i] > 0.0))
        dx = x[i] - xp[i]
        work = (fair[i] + rotating[i] * acc[i]) * dx
        aw, ad = applied_work[i], applied_dist[i]
        applied_work[i] = aw + work if on else aw
        applied_dist[i] = ad + dx if on else ad


@jit_step_inner
def _copy_undo(fb, lvl, kind, nxt, extra, ftr, fb_to, lvl_to, kind_to, nxt_to, extra_to, ftr_to):
    """Copy what a rejected step must undo: the brake state's arrays and the applied traction
    (a pass of its own for each array: the compiler turns each into block copies)."""
    for i in range(fb.shape[0]):
        fb_to[i] = fb[i]
    for i in range(fb.shape[0]):
        lvl_to[i] = lvl[i]
    for i in range(fb.shape[0]):
        kind_to[i] = kind[i]
    for i in range(fb.shape[0]):
        nxt_to[i] = nxt[i]
    for i in range(fb.shape[0]):
        ftr_to[i] = ftr[i]
    for i in range(extra.shape[0]):
        for j in range(extra.shape[1]):
            extra_to[i, j] = extra[i, j]


@jit_step
def run_loop(nsteps, h, t, hp, model, inputs, state, brake_state, events, stats, options,
             watch, ws):
    """The step loop of :func:`run_steps` (same arguments and results, plus its workspace
    ``ws`` from :func:`new_workspace`, which a caller may keep for its next call).

    Without reference counting: it allocates nothing, and numba would otherwise count a
    reference to every array of every bundle it touches or passes on, each step (and, called
    from Python, to each of the arguments' arrays).
    """
    # bundle fields bound once: the loops below then touch plain arrays only
    stats = counters(stats)
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
    full_on, rotating = ws.full_on, ws.rotating
    applied_work, applied_dist = state.applied_work_J, state.applied_distance_m
    pk_fast, pk_fast_t, pk_fast_v = (state.peak_brake_fast_N, state.peak_brake_fast_time_s,
                                     state.peak_brake_fast_speed_m_s)
    pk_slow, pk_slow_t, pk_slow_v = (state.peak_brake_slow_N, state.peak_brake_slow_time_s,
                                     state.peak_brake_slow_speed_m_s)
    # wheel slide (with an adhesion condition): each step's sliding factors, the locked flags
    slide_on = fr_arrays.adhesion.shape[1] > 0
    slide, locked = ws.slide, state.slide_locked
    heat_work, heat_dist = state.heat_work_J, state.heat_distance_m
    heat_clock = state.heat_clock_s
    slide_t, slide_first = state.slide_time_s, state.slide_first_s
    xlo = cp.valid_lo_m
    xhi = cp.valid_hi_m
    # what a rejected step undoes: the brake model's state and the applied traction
    save_fb, save_lvl, save_kind = ws.save_fb, ws.save_lvl, ws.save_kind
    save_next, save_extra, save_ftr = ws.save_next, ws.save_extra, ws.save_ftr
    lvl, lkind, nxt, extra = (brake_state.level, brake_state.level_kind, brake_state.next_event,
                              brake_state.extra)
    s = _Step(xhat, vhat, bh_step, fx, train.meff_kg, tol, res_a, fa_scale, slide, rcurve,
              train.resist, v_stick)
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
            advance_brakes(model.brakes, brake_state, events, tc, t1)
            # traction and track forces vary slowly: taken at the start of the step
            advance_traction(hs, inputs.traction_demand, v, ftr, model.traction)
            if not fixed_track:
                track_forces(x, train, model.track, fgrade, rcurve)
            for i in range(n):
                fx[i] = fext[i] + ftr[i] + fgrade[i]
            friction.force_scales(kind, blocks, arrangement, mu_disc, fb, fa_scale)
            if slide_on and wheel_slide.step_factors(locked, v, fa_scale, fr_arrays, slide):
                hp = 0.0  # a wheelset rolls again: its force jumps at the step's start
            w_ratio, c1, c2, beta = _bdf2(hs, hp)
            bh = beta * hs
            for i in range(n):
                stuck0[i] = stuck[i]
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
                outside = refine_all(h, tc, hs, hp, code == NEWTON_FAILED, model, state, ws, s,
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
            # the new state, each array in a pass of its own (the compiler vectorises them)
            for i in range(n):
                xp[i] = x[i]
                x[i] = xhat[i] + bh * u[i]
            for i in range(n):
                vp[i] = v[i]
                v[i] = u[i]
            for i in range(n):
                fbrake[i] = fair[i]
            # each coupler, now that both its ends have moved: peaks and excursions beyond its
            # valid range
            for i in range(1, n):
                _record_coupler(i - 1, fc[i - 1], x[i - 1] - x[i], tc, xlo, xhi, peak_draft,
                                t_draft, peak_buff, t_buff, lut_out, t_lut_out, t_lut_max,
                                control, OUT_OF_RANGE)
            # the brake's records of the step
            if slide_on:
                for i in range(n):
                    # the brake's work heats its blocks and wheels (brakes.thermal), but not
                    # while they are locked: the blocks do not rub
                    ran = abs(x[i] - xp[i])
                    if not slide[i] > 0.0:
                        heat_work[i] += fair[i] * ran
                    heat_dist[i] += ran
                    slid, changed = wheel_slide.after_step(i, abs(u[i]), fair[i], slide,
                                                           fr_arrays, v_stick, locked)
                    kink |= changed  # its force jumps at the next step's start
                    if slid:
                        slide_t[i] += hs
                        if slide_first[i] < 0.0:
                            slide_first[i] = tc - hs
            else:
                for i in range(n):
                    ran = abs(x[i] - xp[i])
                    heat_work[i] += fair[i] * ran
                    heat_dist[i] += ran
            _brake_records(tc, v_stop, u, fair, x, xp, acc, fa_scale, full_on, rotating,
                           pk_fast, pk_fast_t, pk_fast_v, pk_slow, pk_slow_t, pk_slow_v,
                           applied_work, applied_dist)
            control[ACCEL_VALID] = 1.0
            if tc >= heat_clock[1]:  # a grid time of the temperatures reached
                thermal.advance(model.thermal, state, fb, tc)
            hp = 0.0 if kink else hs
            if last:
                break
        t = t_end
        if watch != WATCH_NONE:
            found = _watch(watch, v, v_stop, t, control)
            if found != OK:
                thermal.current(model.thermal, state, fb, t, state.block_temperature_K,
                                state.wheel_temperature_K)
                return found, t, hp, _step + 1
    # the temperatures now, for the caller's snapshot
    thermal.current(model.thermal, state, fb, t, state.block_temperature_K,
                    state.wheel_temperature_K)
    return OK, t, hp, nsteps


def bind_run_loop(*args):
    """:func:`run_loop` compiled for the types of ``args``, callable without numba's dispatch
    (the loop of :func:`loop_for` the arguments' train and options).

    numba types every argument of every call, recursively through the bundles (about 60
    arrays for a train), which costs more than a short chunk's physics; the returned callable
    skips that. Call it only with arguments of the same types (the same bundles, arrays of the
    same dtype, dimension and C layout). The cheapest call per chunk: no workspace to
    allocate, and no reference counting of the arguments' arrays (about 90 with the
    workspace; counted, they cost twice as much).

    Parameters
    ----------
    *args
        A valid argument list of :func:`run_loop` (it is not run).

    Returns
    -------
    callable
        Same arguments and results as :func:`run_loop`.
    """
    return _bind(loop_for(args[4], args[6], args[10]), args)


@jit_step_inner
def _no_local_steps(h, t, hs, hp, newton_failed, model, state, ws, s, u, stuck, options,
                    stats):
    """:func:`_refine_all` of a train that never sub-steps a part of itself: no window holds
    (the whole train retries shorter)."""
    return -1.0


#: The brake models' ``advance`` by model ID.
_ADVANCE = {m.ID: m.advance for m in brakes.MODELS.values()}
#: :func:`run_loop` specialised by :func:`loop_for`, by (brake model ID, local steps).
_LOOPS: dict = {}


def loop_for(model, state, options):
    """:func:`run_loop` specialised for a train: its brake model's ``advance`` called
    directly, and local time stepping compiled in only where it can run.

    The general loop compiles every registered brake model and the local steps into itself;
    each specialisation compiles only what its runs use (a third of the first run's compile
    time for a short train) and has its own disk cache.

    Parameters
    ----------
    model : TrainModel
    state : KinematicState
    options : Options

    Returns
    -------
    numba dispatcher
        Same arguments and results as :func:`run_loop`.
    """
    return _loop(int(model.brakes.model), local_steps_run(
        state.x_m.shape[0], options.local_steps, options.tolerance_m_s))


def local_steps_run(n_vehicles: int, local_steps: bool = True,
                    tolerance_m_s: float = DEFAULT_TOLERANCE_M_S) -> bool:
    """Whether a train's runs can sub-step part of the train (:func:`_refine_all`).

    Parameters
    ----------
    n_vehicles : int
    local_steps : bool, optional
        :attr:`Options.local_steps`.
    tolerance_m_s : float, optional
        :attr:`Options.tolerance_m_s` [m/s]; 0 is fixed steps.

    Returns
    -------
    bool
    """
    return bool(local_steps and tolerance_m_s > 0.0 and n_vehicles >= LOCAL_MIN_VEHICLES)


def _loop(brake_model: int, local: bool):
    """:func:`loop_for` by brake model ID and whether local steps can run."""
    key = (brake_model, local)
    loop = _LOOPS.get(key)
    if loop is not None:
        return loop
    if not HAVE_NUMBA:  # pragma: no cover - plain Python compiles nothing it does not run
        loop = _LOOPS[key] = run_loop
        return loop
    loop = jit_step(renamed_copy(
        run_loop.py_func, f"run_loop_brakes{brake_model}{'_local' if local else ''}",
        advance_brakes=_ADVANCE[brake_model],
        refine_all=_refine_all if local else _no_local_steps))
    brakes.refresh_stale_cache(loop, brakes.SOURCES_STAMP)
    _LOOPS[key] = loop
    return loop


def _bind(fn, args):
    """``fn`` compiled for the types of ``args`` (see :func:`bind_run_loop`)."""
    if not HAVE_NUMBA:  # pragma: no cover - plain Python has no dispatch to skip
        return fn
    if plain_now():  # while the kernels compile elsewhere (bound anew once they are ready)
        return plain(fn)
    key = _layout_key(args)
    key = None if key is None else (fn.py_func.__qualname__, key)
    bound = _BOUND.get(key) if key is not None else None
    if bound is None:
        bound = fn.compile(tuple(fn.typeof_pyval(a) for a in args))
        if key is not None:
            _BOUND[key] = bound
    return bound


#: :func:`bind_run_loop` by function and the layout of the
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

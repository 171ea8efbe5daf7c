"""Local time stepping for long trains: sub-steps only around the vehicles whose error estimate
fails, their neighbours following the whole train's step (see :mod:`.kernel`).
"""
from __future__ import annotations

import math

from . import brakes
from . import couplers
from .brakes import friction
from .equations import jit_inline, jit_step_inner
from .bundles import NEWTON_FAILED, NOT_FINITE, OUT_OF_RANGE, _Scratch, _Step, _Work
from .step_control import (MIN_STEP_FRACTION, NEWTON_SHRINK, _bdf2, _error_ratio, _milne,
                           _next_step, _record_coupler, _step_factor, _substep)
from .newton import FAST_ITERATIONS, _newton


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


@jit_step_inner
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


@jit_step_inner
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


@jit_step_inner
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


@jit_step_inner
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


@jit_step_inner
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
                                  fr.full_scale_N[a:b + 1], fr.weight_N[a:b + 1], fr.adhesion,
                                  fr.sliding_ratio)
    # the wheelsets' slide states are the whole train's step's (held, like its forces)
    step = _Step(wxhat, wvhat, loc.bh, wfx, wmeff, wtol, s.res_a[a:b + 1], s.fa_scale[a:b + 1],
                 s.slide[a:b + 1], s.rcurve[a:b + 1], s.resist, s.v_stick)
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


@jit_step_inner
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


@jit_step_inner
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


# compiled with the brake and coupler models inlined: numba's cache of it must go when any
# of their sources changes, not only this file
brakes.refresh_stale_caches(globals(), brakes.SOURCES_STAMP)

"""Compiled integration kernel: fixed-step variable-coefficient BDF2 for the train ODE.

Each step eliminates the positions (x_{n+1} = xhat + beta*h*u), leaving a nonlinear system in the
new speeds u whose Jacobian is tridiagonal and symmetric positive definite. It is solved by
Newton's method with these safeguards:

* brake and running resistance oppose the motion with their full value outside a narrow
  standstill band |v| <= v_stick and grow linearly inside it, so that they hold a stopped
  vehicle against any smaller force (it creeps at most at v_stick times the force ratio);
* a Newton update that would carry a coupler's deflection speed across the whole Eq. 3 band
  |rate| <= v_th is shortened so that it lands inside the band, and one that would carry a
  vehicle's speed across its standstill band puts that vehicle at rest (plain Newton
  2-cycles on both bands);
* after a few iterations without convergence (rare: several vehicles and couplers crossing
  bands together), each update is shortened by an exact line search on the step's convex
  potential, which converges from anywhere;
* a step is accepted only when every residual is below the tolerance; otherwise the kernel
  returns a failure code and the caller raises.

The brake block force of each vehicle relaxes exponentially towards a piecewise-constant target
(level of the last command it has received x its maximum force), integrated exactly, which is
Eq. 5 for an emergency application.
"""
from __future__ import annotations

import math

import numpy as np

from .equations import (BRAKE_BLOCKS, BRAKE_DISC, KMH_PER_MS, block_force_factor, coupler_force,
                      jit, karwatzki_speed_factor, lut_segment, resistance_coefficients)

#: Kernel return codes.
OK, NEWTON_FAILED, STOPPED = 0, 1, 2


@jit
def _relax(force, target, dt, tau_apply, tau_release):
    tau = tau_apply if target > force else tau_release
    return target + (force - target) * math.exp(-dt / tau)


@jit
def advance_brakes(t0, t1, fb, lvl, lkind, nxt, delay, fmax, tau_emergency, tau_service,
                   tau_release, ev_t, ev_lvl, ev_kind, n_ev):
    """Advance every vehicle's block force exactly from t0 to t1 (in place).

    Each vehicle relaxes exponentially towards ``level * fmax``, where the level is that of
    the last command event it has received (event time + its delay). An increase follows the
    application time constant of the event's kind (0 emergency, 1 service), a decrease the
    release time constant. For an emergency application from rest this is Eq. 5.

    Parameters
    ----------
    t0, t1 : float
        Step start and end [s].
    fb : ndarray
        Block force of each vehicle at t0, replaced by the value at t1 [N].
    lvl, lkind : ndarray
        Level (0-1) and kind of the command each vehicle currently follows.
    nxt : ndarray of int
        Index of the next command event each vehicle has not yet received.
    delay : ndarray
        t_app + t_del of each vehicle [s] (Eq. 5-6).
    fmax : ndarray
        Maximum block force of each vehicle, 1000 * sum(F_dyn) [N].
    tau_emergency, tau_service, tau_release : ndarray
        Time constants of each vehicle [s] (Eq. 7 for the emergency one).
    ev_t, ev_lvl, ev_kind : ndarray
        Command events: time [s], level and kind.
    n_ev : int
        Number of valid events.
    """
    for i in range(fb.shape[0]):
        t = t0
        f = fb[i]
        while nxt[i] < n_ev and ev_t[nxt[i]] + delay[i] <= t1:
            te = max(ev_t[nxt[i]] + delay[i], t)
            ta = tau_emergency[i] if lkind[i] == 0 else tau_service[i]
            f = _relax(f, lvl[i] * fmax[i], te - t, ta, tau_release[i])
            t = te
            lvl[i] = ev_lvl[nxt[i]]
            lkind[i] = ev_kind[nxt[i]]
            nxt[i] += 1
        ta = tau_emergency[i] if lkind[i] == 0 else tau_service[i]
        fb[i] = _relax(f, lvl[i] * fmax[i], t1 - t, ta, tau_release[i])


@jit
def advance_traction(h, cmd, v, ftr, fmax, pmax, db_fmax, db_pmax, rate, tau, fade):
    """Advance the applied traction/dynamic-brake force of powered vehicles (in place).

    The demanded force is ``cmd * min(F_max, P/|v|)`` (traction, forward) or, for cmd < 0,
    ``cmd * min(F_db, P_db/|v|)`` against the motion, fading linearly to zero below ``fade``.
    The applied force follows it with a first-order lag and a rate limit.

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
    fmax, pmax, db_fmax, db_pmax : ndarray
        Traction and dynamic-brake limits [N], [W] (0 for unpowered vehicles).
    rate, tau, fade : ndarray
        Rate limit [N/s], lag [s], dynamic-brake fade speed [m/s].
    """
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
        lagged = target + (ftr[i] - target) * math.exp(-h / tau[i])
        dmax = rate[i] * h
        change = min(max(lagged - ftr[i], -dmax), dmax)
        ftr[i] += change


@jit
def track_forces(x, offset, start, mass, tk_s, tk_grad, tk_rc, fgrade, rcurve):
    """Gradient force and curve resistance of each vehicle at its own chainage (in place).

    Parameters
    ----------
    x : ndarray
        Displacements [m].
    offset : ndarray
        Distance of each vehicle's centre behind the head's front [m].
    start : float
        Chainage of the head's front at t = 0 [m].
    mass : ndarray
        [kg].
    tk_s, tk_grad, tk_rc : ndarray
        Section starts [m], gradients [per mille, uphill positive], curve resistance [N/kN].
    fgrade : ndarray
        Out: gravity component along the track, forward positive [N].
    rcurve : ndarray
        Out: curve resistance magnitude [N].
    """
    for i in range(x.shape[0]):
        # before the first section start, the first section applies
        k = max(lut_segment(tk_s, start + x[i] - offset[i]), 0)
        weight_kN = mass[i] * 9.81 / 1000.0
        fgrade[i] = -weight_kN * tk_grad[k]
        rcurve[i] = weight_kN * tk_rc[k]


@jit
def _retarding(i, speed, res_a, kind, fa_scale, rcurve, resist):
    """Brake force, running + curve resistance (magnitudes, N) and d(total)/d(speed).

    ``res_a`` holds the Eq. 2 coefficients per vehicle; ``fa_scale`` the brake force per unit
    of Karwatzki's speed factor (blocks) or the disc brake force, fixed within a step.
    """
    v_kmh = KMH_PER_MS * speed
    fr = (res_a[i, 0] + (res_a[i, 1] + res_a[i, 2] * v_kmh) * v_kmh + rcurve[i]) * resist
    dfr = (res_a[i, 1] + 2.0 * res_a[i, 2] * v_kmh) * KMH_PER_MS * resist
    if kind[i] == BRAKE_BLOCKS:
        f, df = karwatzki_speed_factor(speed)
        return f * fa_scale[i], fr, df * fa_scale[i] + dfr
    return fa_scale[i], fr, dfr


#: Newton iterations with the cheap safeguards before the line search takes over.
FAST_ITERATIONS = 4


@jit
def _slope(step, u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale, resist,
           rcurve, xs, f_load, f_unload, v_th, v_stick, dgt, cjt, fct, fat):
    """Directional derivative g(u + step*du) . du of the step's potential."""
    for i in range(u.shape[0]):
        ut[i] = u[i] + step * du[i]
    _residual(ut, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale, resist, rcurve, xs,
              f_load, f_unload, v_th, v_stick, gt, dgt, cjt, fct, fat)
    acc = 0.0
    for i in range(u.shape[0]):
        acc += gt[i] * du[i]
    return acc


@jit
def _line_search(u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale, resist,
                 rcurve, xs, f_load, f_unload, v_th, v_stick, dgt, cjt, fct, fat):
    """Step length minimising the step's convex potential along du (root of its slope).

    Regula falsi (Illinois) on the slope, which is monotone along the line; a 1e-3 bracket is
    plenty, the next Newton iteration corrects the rest.
    """
    fhi = _slope(1.0, u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale,
                 resist, rcurve, xs, f_load, f_unload, v_th, v_stick, dgt, cjt, fct, fat)
    if fhi <= 0.0:
        return 1.0
    flo = _slope(0.0, u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale,
                 resist, rcurve, xs, f_load, f_unload, v_th, v_stick, dgt, cjt, fct, fat)
    lo, hi = 0.0, 1.0
    side = 0
    for _ in range(30):
        if hi - lo < 1e-3 * hi:
            break
        mid = (lo * fhi - hi * flo) / (fhi - flo)
        if not (lo < mid < hi):
            mid = 0.5 * (lo + hi)
        fmid = _slope(mid, u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale,
                      resist, rcurve, xs, f_load, f_unload, v_th, v_stick, dgt, cjt, fct, fat)
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


@jit
def _residual(u, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale, resist, rcurve, xs,
              f_load, f_unload, v_th, v_stick, g, diag, cj, fc, fair):
    """Residual g(u) of the implicit step and the pieces of its Jacobian (in place).

    g_i = rho_i M_i (u_i - vhat_i) / (beta h) - (coupler, external and retarding forces on i).
    ``diag`` receives the vehicle terms of the Jacobian's diagonal and ``cj`` each coupler's
    d(force)/d(rate); returns True when every |g_i| is within the tolerance.
    """
    n = u.shape[0]
    nc = n - 1
    for j in range(nc):
        rate = u[j] - u[j + 1]
        d = xhat[j] - xhat[j + 1] + bh * rate
        f, kd, kr, _seg, _band = coupler_force(d, rate, xs, f_load, f_unload, v_th)
        fc[j] = f
        cj[j] = bh * kd + kr
    converged = True
    for i in range(n):
        g0 = meff[i] * (u[i] - vhat[i]) / bh - fx[i]
        if i < nc:
            g0 += fc[i]
        if i > 0:
            g0 -= fc[i - 1]
        spd = abs(u[i])
        fa, fr, dr = _retarding(i, spd, res_a, kind, fa_scale, rcurve, resist)
        total = fa + fr
        if spd > v_stick:
            sg = 1.0 if u[i] > 0.0 else -1.0
            g[i] = g0 + sg * total
            diag[i] = meff[i] / bh + dr
            fair[i] = fa
        else:
            # standstill band: friction grows linearly up to its full value at |u| = v_stick
            # and holds the vehicle against any smaller force
            g[i] = g0 + total * u[i] / v_stick
            diag[i] = meff[i] / bh + (total + dr * spd) / v_stick
            fair[i] = fa * spd / v_stick
        if not abs(g[i]) <= tol[i]:  # also catches NaN
            converged = False
    return converged


@jit
def _all_finite(a):
    """True when every element of ``a`` is finite."""
    for value in a:
        if not math.isfinite(value):
            return False
    return True


@jit
def _solve_tridiagonal(dvec, cj, g, off, dwork, du):
    """Solve J du = -g, J = diag(dvec) + sum over couplers of cj * (e_j - e_j+1)(e_j - e_j+1)^T.

    J is tridiagonal, symmetric positive definite (an M-matrix): the Thomas algorithm needs no
    pivoting. ``off`` and ``dwork`` are scratch arrays.
    """
    n = dvec.shape[0]
    for i in range(n):
        dwork[i] = dvec[i]
        du[i] = -g[i]
    for j in range(n - 1):
        off[j] = -cj[j]
        dwork[j] += cj[j]
        dwork[j + 1] += cj[j]
    for i in range(1, n):
        m = off[i - 1] / dwork[i - 1]
        dwork[i] -= m * off[i - 1]
        du[i] -= m * du[i - 1]
    du[n - 1] /= dwork[n - 1]
    for i in range(n - 2, -1, -1):
        du[i] = (du[i] - off[i] * du[i + 1]) / dwork[i]


@jit
def run_steps(nsteps, h, t, hp,
              x, v, xp, vp, stuck,
              meff, mass, axles, kind, blocks, arrangement, mu_disc, fext, resist,
              xs, f_load, f_unload, v_th,
              fb, lvl, lkind, nxt, delay, fmax, tau_emergency, tau_service, tau_release,
              ev_t, ev_lvl, ev_kind, n_ev,
              tr_cmd, ftr, tr_fmax, tr_pmax, db_fmax, db_pmax, tr_rate, tr_tau, tr_fade,
              offset, start, tk_s, tk_grad, tk_rc,
              fc, fbrake, peak_draft, t_draft, peak_buff, t_buff, lut_out, t_lut_out,
              stats, max_iter, rtol, watch_stop, v_stop, v_stick):
    """Advance the train ``nsteps`` steps of ``h`` seconds (all arrays updated in place).

    Parameters
    ----------
    nsteps : int
    h : float
        Step [s].
    t : float
        Time at the start [s].
    hp : float
        Previous step [s]; 0 starts with a backward-Euler step (no history).
    x, v, xp, vp : ndarray
        Displacements [m] and speeds [m/s] now and one step back.
    stuck : ndarray of bool
        Out: vehicles inside the standstill band |v| <= v_stick.
    meff, mass, axles : ndarray
        rho*M [kg], M [kg], axle count.
    kind, blocks, arrangement, mu_disc : ndarray
        Brake description per vehicle.
    fext : ndarray
        Additional external force, forward positive [N].
    resist : float
        1 with running resistance, 0 without.
    xs, f_load, f_unload, v_th
        Coupler LUT [m], [N], [N] and Eq. 3 threshold [m/s].
    fb, lvl, lkind, nxt, delay, fmax, tau_emergency, tau_service, tau_release, ev_t, ev_lvl,
    ev_kind, n_ev
        Brake state and command events, see :func:`advance_brakes`.
    tr_cmd, ftr, tr_fmax, tr_pmax, db_fmax, db_pmax, tr_rate, tr_tau, tr_fade
        Traction demand and state, see :func:`advance_traction`.
    offset, start, tk_s, tk_grad, tk_rc
        Geometry and track profile, see :func:`track_forces`.
    fc, fbrake : ndarray
        Out: coupler forces [N] and brake (retarding) forces [N] at the end.
    peak_draft, t_draft, peak_buff, t_buff : ndarray
        Running extreme coupler forces [N] and their times [s].
    lut_out, t_lut_out : ndarray
        Largest excursion beyond the LUT per coupler [m] and the first time out (-1 never).
    stats : ndarray of int
        [steps, Newton iterations, most iterations in one step, coupler-band cut-backs,
        standstill-band projections, line searches].
    max_iter : int
        Newton iterations allowed per step.
    rtol : float
        Residual tolerance relative to each vehicle's weight.
    watch_stop : bool
        Return ``STOPPED`` right after the first step that leaves every vehicle at standstill.
    v_stop : float
        Speed below which a vehicle counts as standing for ``watch_stop`` [m/s].
    v_stick : float
        Half-width of the standstill band of brake and running resistance [m/s].

    Returns
    -------
    code : int
        ``OK``, ``NEWTON_FAILED`` or ``STOPPED``.
    t : float
        Time reached [s].
    hp : float
        Last step size [s].
    done : int
        Steps completed.
    """
    n = x.shape[0]
    nc = n - 1
    u = np.empty(n)
    g = np.empty(n)
    diag = np.empty(n)
    off = np.empty(max(nc, 1))
    cj = np.empty(max(nc, 1))
    du = np.empty(n)
    xhat = np.empty(n)
    vhat = np.empty(n)
    fair = np.empty(n)
    stuck0 = np.empty(n, np.bool_)
    dtmp = np.empty(n)
    fa_scale = np.empty(n)
    tol = np.empty(n)
    res_a = np.empty((n, 3))
    for i in range(n):
        tol[i] = rtol * mass[i] * 9.81
        a0, a1, a2 = resistance_coefficients(mass[i], axles[i])
        res_a[i, 0] = a0
        res_a[i, 1] = a1
        res_a[i, 2] = a2
    ut = np.empty(n)
    gt = np.empty(n)
    dgt = np.empty(n)
    cjt = np.empty(max(nc, 1))
    fct = np.empty(max(nc, 1))
    fat = np.empty(n)
    fx = np.empty(n)
    fgrade = np.empty(n)
    rcurve = np.empty(n)
    xlo = xs[0]
    xhi = xs[xs.shape[0] - 1]
    for _step in range(nsteps):
        t1 = t + h
        advance_brakes(t, t1, fb, lvl, lkind, nxt, delay, fmax, tau_emergency, tau_service,
                       tau_release, ev_t, ev_lvl, ev_kind, n_ev)
        # traction and track forces vary slowly: taken at the start of the step
        advance_traction(h, tr_cmd, v, ftr, tr_fmax, tr_pmax, db_fmax, db_pmax, tr_rate, tr_tau,
                         tr_fade)
        track_forces(x, offset, start, mass, tk_s, tk_grad, tk_rc, fgrade, rcurve)
        for i in range(n):
            fx[i] = fext[i] + ftr[i] + fgrade[i]
            if kind[i] == BRAKE_BLOCKS:
                # Karwatzki's block-force factor is fixed within the step (Eq. 9)
                fa_scale[i] = fb[i] * block_force_factor(fb[i] / (1000.0 * blocks[i]),
                                                         arrangement[i])
            elif kind[i] == BRAKE_DISC:
                fa_scale[i] = mu_disc[i] * fb[i]
            else:
                fa_scale[i] = 0.0
        if hp > 0.0:
            w = h / hp
            c1 = (1.0 + w) ** 2 / (1.0 + 2.0 * w)
            c2 = w * w / (1.0 + 2.0 * w)
            beta = (1.0 + w) / (1.0 + 2.0 * w)
        else:
            w, c1, c2, beta = 0.0, 1.0, 0.0, 1.0
        bh = beta * h
        for i in range(n):
            stuck0[i] = stuck[i]
            xhat[i] = c1 * x[i] - c2 * xp[i]
            vhat[i] = c1 * v[i] - c2 * vp[i]
            u[i] = v[i] + w * (v[i] - vp[i])
            if u[i] * v[i] <= 0.0:
                u[i] = v[i]  # never extrapolate through standstill
        it = 0
        while True:
            converged = _residual(u, xhat, vhat, bh, fx, meff, tol, res_a, kind, fa_scale,
                                  resist, rcurve, xs, f_load, f_unload, v_th, v_stick, g, diag,
                                  cj, fc, fair)
            if converged:
                break
            if it >= max_iter or not _all_finite(g):
                # a NaN or infinite force cannot be iterated away: fail at once
                stats[1] += it
                return NEWTON_FAILED, t, hp, _step
            it += 1
            _solve_tridiagonal(diag, cj, g, off, dtmp, du)
            if it <= FAST_ITERATIONS:
                # a coupler whose deflection speed would jump across its whole Eq. 3 band most
                # likely ends inside it: solve again with that coupler on the band's line
                again = False
                for j in range(nc):
                    r0 = u[j] - u[j + 1]
                    r1 = r0 + du[j] - du[j + 1]
                    if r0 * r1 < 0.0 and abs(r0) > v_th and abs(r1) > v_th:
                        d = xhat[j] - xhat[j + 1] + bh * r0
                        fm, kd, kr, _seg, _band = coupler_force(d, 0.0, xs, f_load, f_unload, v_th)
                        shift = fm + kr * r0 - fc[j]  # band line at r0 minus actual force
                        g[j] += shift
                        g[j + 1] -= shift
                        cj[j] = bh * kd + kr
                        again = True
                if again:
                    _solve_tridiagonal(diag, cj, g, off, dtmp, du)
            if it <= FAST_ITERATIONS:
                # cheap safeguards, enough for almost every step: do not let a coupler jump
                # across the whole hysteresis band, nor a vehicle across its standstill band
                alpha = 1.0
                for j in range(nc):
                    r0 = u[j] - u[j + 1]
                    r1 = r0 + du[j] - du[j + 1]
                    if r0 * r1 < 0.0 and abs(r0) > v_th and abs(r1) > v_th:
                        a = r0 / (r0 - r1)
                        if a < alpha:
                            alpha = a
                if alpha < 1.0:
                    stats[3] += 1
                for i in range(n):
                    u1 = u[i] + alpha * du[i]
                    if u1 * u[i] < 0.0 and abs(u[i]) > v_stick and abs(u1) > v_stick:
                        u1 = 0.0
                        stats[4] += 1
                    u[i] = u1
            else:
                # globally convergent fallback: g is the gradient of a convex potential and du
                # a descent direction, so minimise along du exactly (the directional
                # derivative is monotone along the line: find its root by bisection)
                stats[5] += 1
                alpha = _line_search(u, du, ut, gt, xhat, vhat, bh, fx, meff, tol, res_a, kind,
                                     fa_scale, resist, rcurve, xs, f_load, f_unload, v_th,
                                     v_stick, dgt, cjt, fct, fat)
                for i in range(n):
                    u[i] += alpha * du[i]
        for i in range(n):
            stuck[i] = abs(u[i]) <= v_stick
        stats[0] += 1
        stats[1] += it
        if it > stats[2]:
            stats[2] = it
        for i in range(n):
            xp[i] = x[i]
            vp[i] = v[i]
            x[i] = xhat[i] + bh * u[i]
            v[i] = u[i]
            fbrake[i] = fair[i]
        # a vehicle that entered or left the standstill band has a kink in its speed: the BDF2
        # history would extrapolate across it (and push a just-stopped vehicle backwards), so
        # the next step restarts with backward Euler
        hp = h
        for i in range(n):
            if stuck[i] != stuck0[i]:
                hp = 0.0
                break
        t = t1
        for j in range(nc):
            f = fc[j]
            if f > peak_draft[j]:
                peak_draft[j] = f
                t_draft[j] = t
            if f < peak_buff[j]:
                peak_buff[j] = f
                t_buff[j] = t
            d = x[j] - x[j + 1]
            out = d - xhi if d > xhi else (xlo - d if d < xlo else 0.0)
            if out > 0.0:
                if t_lut_out[j] < 0.0:
                    t_lut_out[j] = t
                if out > lut_out[j]:
                    lut_out[j] = out
        if watch_stop:
            all_stopped = True
            for i in range(n):
                if abs(v[i]) > v_stop:
                    all_stopped = False
                    break
            if all_stopped:
                return STOPPED, t, hp, _step + 1
    return OK, t, hp, nsteps

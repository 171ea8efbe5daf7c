"""Compiled integration kernel: fixed-step variable-coefficient BDF2 for the train ODE.

Each step eliminates the positions (x_{n+1} = xhat + beta*h*u), leaving a nonlinear system in the
new speeds u whose Jacobian is tridiagonal and symmetric positive definite. It is solved by
Newton's method with three safeguards:

* standstill is exact, not regularised: a vehicle whose speed would change sign inside a step
  sticks at zero, and the brake and running resistance then act as static friction that holds
  it until the other forces exceed them (no creeping, no chattering);
* a Newton update that would carry a coupler's deflection speed across the whole Eq. 3 band
  |rate| <= v_th is shortened so that it lands inside the band (plain Newton 2-cycles there);
* a step is accepted only when every residual is below the tolerance; otherwise the kernel
  returns a failure code and the caller raises.

The brake block force of each vehicle relaxes exponentially towards a piecewise-constant target
(level of the last command it has received x its maximum force), integrated exactly, which is
Eq. 5 for an emergency application.
"""
from __future__ import annotations

import math

import numpy as np

from .physics import (BRAKE_BLOCKS, BRAKE_DISC, block_mu, coupler_force, jit, resistance_N)

#: Kernel return codes.
OK, NEWTON_FAILED, STOPPED = 0, 1, 2


@jit
def _relax(force, target, dt, tau_apply, tau_release):
    tau = tau_apply if target > force else tau_release
    return target + (force - target) * math.exp(-dt / tau)


@jit
def advance_brakes(t0, t1, fb, lvl, nxt, delay, fmax, ev_t, ev_lvl, n_ev, tau_apply, tau_release):
    """Advance every vehicle's block force exactly from t0 to t1 (in place).

    Parameters
    ----------
    t0, t1 : float
        Step start and end [s].
    fb : ndarray
        Block force of each vehicle at t0, replaced by the value at t1 [N].
    lvl : ndarray
        Command level (0-1) each vehicle currently follows.
    nxt : ndarray of int
        Index of the next command event each vehicle has not yet received.
    delay : ndarray
        t_app + t_del of each vehicle [s] (Eq. 5-6).
    fmax : ndarray
        Maximum block force of each vehicle, 1000 * sum(F_dyn) [N].
    ev_t, ev_lvl : ndarray
        Command events: time [s] and level.
    n_ev : int
        Number of valid events.
    tau_apply, tau_release : float
        Time constants [s].
    """
    for i in range(fb.shape[0]):
        t = t0
        f = fb[i]
        while nxt[i] < n_ev and ev_t[nxt[i]] + delay[i] <= t1:
            te = max(ev_t[nxt[i]] + delay[i], t)
            f = _relax(f, lvl[i] * fmax[i], te - t, tau_apply, tau_release)
            t = te
            lvl[i] = ev_lvl[nxt[i]]
            nxt[i] += 1
        fb[i] = _relax(f, lvl[i] * fmax[i], t1 - t, tau_apply, tau_release)


@jit
def _retarding(i, speed, mass, axles, kind, blocks, arrangement, mu_disc, fb, resist):
    """Brake force, running resistance (magnitudes, N) and d(total)/d(speed) of vehicle i."""
    fr, dfr = resistance_N(mass[i], axles[i], speed)
    fr *= resist
    dfr *= resist
    if kind[i] == BRAKE_BLOCKS:
        mu, dmu = block_mu(speed, fb[i] / (1000.0 * blocks[i]), arrangement[i])
        return mu * fb[i], fr, dmu * fb[i] + dfr
    if kind[i] == BRAKE_DISC:
        return mu_disc[i] * fb[i], fr, dfr
    return 0.0, fr, dfr


@jit
def run_steps(nsteps, h, t, hp,
              x, v, xp, vp, stuck, sgn,
              meff, mass, axles, kind, blocks, arrangement, mu_disc, fext, resist,
              xs, f_load, f_unload, v_th,
              fb, lvl, nxt, delay, fmax, ev_t, ev_lvl, n_ev, tau_apply, tau_release,
              fc, fbrake, peak_draft, t_draft, peak_buff, t_buff, lut_out, t_lut_out,
              stats, max_iter, rtol, watch_stop, v_stop):
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
        Vehicles held at standstill by static friction.
    sgn : ndarray
        Direction of motion (+1/-1) of sliding vehicles.
    meff, mass, axles : ndarray
        rho*M [kg], M [kg], axle count.
    kind, blocks, arrangement, mu_disc : ndarray
        Brake description per vehicle.
    fext : ndarray
        External force (traction, grade), forward positive [N].
    resist : float
        1 with running resistance, 0 without.
    xs, f_load, f_unload, v_th
        Coupler LUT [m], [N], [N] and Eq. 3 threshold [m/s].
    fb, lvl, nxt, delay, fmax, ev_t, ev_lvl, n_ev, tau_apply, tau_release
        Brake state and command events, see :func:`advance_brakes`.
    fc, fbrake : ndarray
        Out: coupler forces [N] and brake (retarding) forces [N] at the end.
    peak_draft, t_draft, peak_buff, t_buff : ndarray
        Running extreme coupler forces [N] and their times [s].
    lut_out, t_lut_out : ndarray
        Largest excursion beyond the LUT per coupler [m] and the first time out (-1 never).
    stats : ndarray of int
        [steps, newton iterations, max iterations in one step, band cut-backs, releases].
    max_iter : int
        Newton iterations allowed per step.
    rtol : float
        Residual tolerance relative to each vehicle's weight.
    watch_stop : bool
        Return ``STOPPED`` right after the first step that leaves every vehicle at standstill.
    v_stop : float
        Speed below which a vehicle counts as standing for ``watch_stop`` [m/s].

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
    xlo = xs[0]
    xhi = xs[xs.shape[0] - 1]
    for _step in range(nsteps):
        t1 = t + h
        advance_brakes(t, t1, fb, lvl, nxt, delay, fmax, ev_t, ev_lvl, n_ev, tau_apply,
                       tau_release)
        if hp > 0.0:
            w = h / hp
            c1 = (1.0 + w) ** 2 / (1.0 + 2.0 * w)
            c2 = w * w / (1.0 + 2.0 * w)
            beta = (1.0 + w) / (1.0 + 2.0 * w)
        else:
            w, c1, c2, beta = 0.0, 1.0, 0.0, 1.0
        bh = beta * h
        for i in range(n):
            xhat[i] = c1 * x[i] - c2 * xp[i]
            vhat[i] = c1 * v[i] - c2 * vp[i]
            if stuck[i]:
                u[i] = 0.0
            else:
                guess = v[i] + w * (v[i] - vp[i])
                u[i] = guess if guess * sgn[i] > 0.0 else v[i]
        converged = False
        it = 0
        while True:
            for j in range(nc):
                rate = u[j] - u[j + 1]
                d = xhat[j] - xhat[j + 1] + bh * rate
                f, kd, kr, _seg, _band = coupler_force(d, rate, xs, f_load, f_unload, v_th)
                fc[j] = f
                cj[j] = bh * kd + kr
            converged = True
            for i in range(n):
                g0 = meff[i] * (u[i] - vhat[i]) / bh - fext[i]
                if i < nc:
                    g0 += fc[i]
                if i > 0:
                    g0 -= fc[i - 1]
                tol = rtol * mass[i] * 9.81
                fa, fr, dr = _retarding(i, abs(u[i]), mass, axles, kind, blocks, arrangement,
                                        mu_disc, fb, resist)
                if stuck[i]:
                    if abs(g0) > fa + fr + tol:
                        # static friction cannot hold it: it starts sliding against g0
                        stuck[i] = False
                        sgn[i] = -1.0 if g0 > 0.0 else 1.0
                        stats[4] += 1
                        converged = False
                        g[i] = g0 + sgn[i] * (fa + fr)
                        diag[i] = meff[i] / bh + dr
                    else:
                        fair[i] = 0.0 if fa + fr <= 0.0 else abs(g0) * fa / (fa + fr)
                        g[i] = 0.0
                        diag[i] = 1.0
                else:
                    fair[i] = fa
                    g[i] = g0 + sgn[i] * (fa + fr)
                    diag[i] = meff[i] / bh + dr
                    if abs(g[i]) > tol:
                        converged = False
            if converged:
                break
            if it >= max_iter:
                stats[1] += it
                return NEWTON_FAILED, t, hp, _step
            it += 1
            # tridiagonal SPD system J du = -g; rows of stuck vehicles are identity rows
            for j in range(nc):
                if stuck[j] or stuck[j + 1]:
                    off[j] = 0.0
                else:
                    off[j] = -cj[j]
                if not stuck[j]:
                    diag[j] += cj[j]
                if not stuck[j + 1]:
                    diag[j + 1] += cj[j]
            # Thomas algorithm (no pivoting needed: the matrix is SPD)
            for i in range(n):
                du[i] = -g[i]
            for i in range(1, n):
                m = off[i - 1] / diag[i - 1]
                diag[i] -= m * off[i - 1]
                du[i] -= m * du[i - 1]
            du[n - 1] /= diag[n - 1]
            for i in range(n - 2, -1, -1):
                du[i] = (du[i] - off[i] * du[i + 1]) / diag[i]
            # do not let a coupler jump across the whole hysteresis band in one update
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
                if stuck[i]:
                    continue
                u[i] += alpha * du[i]
                if u[i] * sgn[i] <= 0.0:
                    # the speed would reverse inside the step: it stops here instead
                    u[i] = 0.0
                    stuck[i] = True
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
        hp = h
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

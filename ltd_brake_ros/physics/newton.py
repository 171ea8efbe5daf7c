"""The implicit step's equations and their Newton solve: residual and tridiagonal Jacobian,
the safeguards (standstill band, Eq. 3's band), the exact line search on the convex potential.
"""
from __future__ import annotations

import math

from . import brakes
from . import couplers
from .brakes import adhesion
from .brakes import friction
from .constants import KMH_PER_MS
from .equations import jit_inline, jit_step_inner
from .bundles import NEWTON_FAILED, NOT_FINITE, OK


@jit_inline
def _retarding(i, speed, res_a, rcurve, resist, kind, fa_scale, adh, weight, slide):
    """Brake force, running + curve resistance (magnitudes, N) and d(total)/d(speed).

    ``res_a`` holds the Eq. 2 coefficients per vehicle; ``fa_scale`` the brake force per unit
    of Karwatzki's speed factor (blocks) or the disc brake force, fixed within a step; ``adh``
    the rail's adhesion table (empty: no cap), which caps the brake force of rolling wheelsets
    at mu(v) m g (``weight``: m g); ``slide`` the step's sliding factor k of locked wheelsets
    (0: rolling), whose force is k mu(v) m g (:mod:`.brakes.wheel_slide`). Either is a
    continuous function of the speed within a step.
    """
    v_kmh = KMH_PER_MS * speed
    fr = (res_a[i, 0] + (res_a[i, 1] + res_a[i, 2] * v_kmh) * v_kmh + rcurve[i]) * resist
    dfr = (res_a[i, 1] + 2.0 * res_a[i, 2] * v_kmh) * KMH_PER_MS * resist
    fa, dfa = friction.retarding_force(kind[i], speed, fa_scale[i])
    if adh.shape[1] > 0 and fa > 0.0:
        mu, dmu = adhesion.mu_of(adh, speed)
        if slide[i] > 0.0:  # locked: the rail's sliding friction
            fa, dfa = slide[i] * mu * weight[i], slide[i] * dmu * weight[i]
        elif fa > mu * weight[i]:  # rolling at the adhesion limit
            fa, dfa = mu * weight[i], dmu * weight[i]
    return fa, fr, dfa + dfr


#: Newton iterations with the cheap safeguards before the line search takes over.
FAST_ITERATIONS = 4


@jit_step_inner
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


@jit_step_inner
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


@jit_step_inner
def _residual(u, s, cp, fr_arrays, w):
    """Residual g(u) of the implicit step and the pieces of its Jacobian (into ``w``).

    g_i = rho_i M_i (u_i - vhat_i) / (beta h) - (coupler, external and retarding forces on i).
    ``w.diag`` receives the vehicle terms of the Jacobian's diagonal and ``w.cj`` each
    coupler's d(force)/d(rate); returns True when every |g_i| is within the tolerance.
    """
    # bundle fields bound once: the loops below then touch plain arrays only
    xhat, vhat, bh, fx, meff, tol = s.xhat, s.vhat, s.bh[0], s.fx, s.meff, s.tol
    res_a, fa_scale, rcurve, resist, v_stick = s.res_a, s.fa_scale, s.rcurve, s.resist, s.v_stick
    slide = s.slide
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
        fa, fr, dr = _retarding(i, spd, res_a, rcurve, resist, kind, fa_scale, adh, weight,
                                slide)
        total = fa + fr
        if spd > v_stick:
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


@jit_step_inner
def _all_finite(a):
    """True when every element of ``a`` is finite."""
    for value in a:
        if not math.isfinite(value):
            return False
    return True


@jit_step_inner
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


@jit_step_inner
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


# compiled with the brake and coupler models inlined: numba's cache of it must go when any
# of their sources changes, not only this file
brakes.refresh_stale_caches(globals(), brakes.SOURCES_STAMP)

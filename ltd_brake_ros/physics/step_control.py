"""Error control of the kernel's steps: variable-step BDF2 coefficients, Milne's error estimate
against the quadratic predictor, the step-size controller, and each coupler's running records.
"""
from __future__ import annotations

from . import brakes
from .equations import jit_inline, jit_inner, jit_step_inner


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


@jit_inner
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


@jit_inner
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


@jit_step_inner
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


# compiled with the brake and coupler models inlined: numba's cache of it must go when any
# of their sources changes, not only this file
brakes.refresh_stale_caches(globals(), brakes.SOURCES_STAMP)

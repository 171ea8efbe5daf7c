"""Wheel slide under an adhesion condition: each vehicle's wheelsets rolling or locked.

The state is a flag per vehicle, kept with the kernel's records of accepted steps
(``KinematicState.slide_locked``) and fixed within each step, so that every step's equations
stay continuous and monotone in the speeds (see :mod:`ltd_brake_ros.physics.kernel`) and the
results do not depend on how a run is cut into chunks:

* **rolling**: the brake force is capped at the available adhesion, mu(v) m g
  (:mod:`.adhesion`); a step whose force the cap has bounded locks the wheelsets at its end;
* **locked**: the wheelsets slide and the rail takes the sliding friction k mu(v) m g
  (k the condition's ``sliding_ratio``); they roll again from the first step whose brake
  holds them no more, its static friction force (the kinetic law at rest with the step's force
  scale, :func:`.friction.retarding_force` at speed 0) below that sliding force. A vehicle at
  rest does not slide.

The blocks of a locked wheelset do not rub on its wheel: its brake does no work then (the
kernel heats no block with it).
"""
from __future__ import annotations

from ..equations import jit_inline, jit_step_inner
from . import adhesion, friction

__all__ = ["after_step", "step_factors"]


@jit_step_inner
def step_factors(locked, v, fa_scale, fr, slide):
    """Each vehicle's sliding-friction factor over a step (into ``slide``): the condition's
    sliding ratio k while its wheelsets stay locked, else 0 (rolling).

    Parameters
    ----------
    locked : ndarray of bool
        Wheelsets locked at the end of the last accepted step.
    v : ndarray
        Speeds at the step's start [m/s].
    fa_scale : ndarray
        The step's retarding-force scales (:func:`.friction.force_scales`) [N].
    fr : FrictionArrays
    slide : ndarray
        Out: k or 0 per vehicle.

    Returns
    -------
    bool
        Some vehicle's wheelsets roll again from this step (its force changes at the start).
    """
    k = fr.sliding_ratio
    table, kind, weight = fr.adhesion, fr.kind, fr.weight_N
    released = False
    for i in range(v.shape[0]):
        f = 0.0
        if locked[i]:
            static, _ds = friction.retarding_force(kind[i], 0.0, fa_scale[i])
            mu, _dmu = adhesion.mu_of(table, abs(v[i]))
            if static >= k * mu * weight[i]:
                f = k
            else:
                released = True
        slide[i] = f
    return released


@jit_inline
def after_step(i, speed, force, slide, fr, v_stick, locked):
    """Vehicle ``i``'s wheelsets after an accepted step: locked (it slid: locked over the step,
    or rolling with its brake force capped by the adhesion) unless it ended at rest.

    Parameters
    ----------
    i : int
    speed : float
        Its speed magnitude at the step's end [m/s].
    force : float
        Its retarding brake force over the step [N].
    slide : ndarray
        The step's factors (:func:`step_factors`).
    fr : FrictionArrays
    v_stick : float
        Half-width of the standstill band [m/s].
    locked : ndarray of bool
        Updated.

    Returns
    -------
    slid : bool
        Its wheelsets slid in the step.
    changed : bool
        Their state changed (the force jumps at the next step's start).
    """
    slid = slide[i] > 0.0
    if not slid and speed > v_stick and force > 0.0:
        mu, _dmu = adhesion.mu_of(fr.adhesion, speed)
        slid = force >= mu * fr.weight_N[i] * (1.0 - 1e-12)  # capped
    now = slid and speed > v_stick
    changed = now != locked[i]
    locked[i] = now
    return slid, changed

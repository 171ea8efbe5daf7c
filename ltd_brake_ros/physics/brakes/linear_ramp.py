"""A toy brake model: the block force ramps linearly to its target, with the paper's delays.

The command reaches each vehicle as in Eq. 6 (t_app + distance from the venting vehicle / v_air,
:func:`~.base.vent_delay_s`); from then on the block
force moves towards level x full force at a constant rate, the full force in ``t_fill_s`` when
applying and in ``t_release_s`` when releasing. Not validated against measurements: it shows
what a second brake model needs (one file and one registry line) and gives contract tests a
model with another shape of rise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..equations import jit_step_inner
from ..parameters import Fittable, parameter
from .base import BrakeArrays, released_state, vent_delay_s

NAME = "linear_ramp"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 1

#: Columns of ``BrakeArrays.coef``: rates of application and release [N/s].
RATE_APPLY, RATE_RELEASE = 0, 1


@dataclass(frozen=True)
class Params:
    """Parameters of the linear-ramp brake.

    Attributes
    ----------
    t_app_s : float
        Delay between the command and the start of the ramp at the venting vehicle [s].
    v_air_m_s : float
        Propagation speed of the command along the train (Eq. 6) [m/s].
    t_fill_s : float
        Time of a ramp from released to the full force [s].
    t_release_s : float
        Time of a ramp from the full force to released [s].
    simultaneous : bool
        The command reaches every vehicle at once.
    """

    t_app_s: float = parameter(1.0, "delay between command and the start of the ramp [s]",
                               lo=0.0, hi=60.0)
    v_air_m_s: float = parameter(200.0, "propagation speed of the command along the train "
                                 "[m/s]", lo=0.0, lo_open=True, hi=400.0)
    t_fill_s: float = parameter(5.0, "ramp time from released to the full force [s]",
                                lo=0.0, lo_open=True, hi=300.0)
    t_release_s: float = parameter(15.0, "ramp time from the full force to released [s]",
                                   lo=0.0, lo_open=True, hi=600.0)
    simultaneous: bool = parameter(False, "the command reaches every vehicle at once")


#: Parameters calibration may fit, by short name.
FITTABLE = {
    "t_app": Fittable("t_app_s", "s", 0.0, 5.0, 1.0,
                      "delay from the command to the start of the ramp at the venting vehicle"),
    "v_air": Fittable("v_air_m_s", "m/s", 100.0, 340.0, 200.0,
                      "propagation speed of the command along the train"),
    "t_fill": Fittable("t_fill_s", "s", 1.0, 30.0, 5.0,
                       "ramp time from released to the full force"),
}


def compile(consist, params: Params, force_max_N: np.ndarray) -> BrakeArrays:  # noqa: A001
    """Per-vehicle delays and ramp rates of a train.

    Parameters
    ----------
    consist : Consist
        The train, head first.
    params : Params
    force_max_N : ndarray
        Full block force of each vehicle [N].

    Returns
    -------
    BrakeArrays
        ``coef`` columns :data:`RATE_APPLY`, :data:`RATE_RELEASE` [N/s].
    """
    delay = vent_delay_s(consist, params.t_app_s, params.v_air_m_s, params.simultaneous)
    fmax = np.ascontiguousarray(force_max_N, float)
    coef = np.empty((fmax.size, 2))
    coef[:, RATE_APPLY] = fmax / params.t_fill_s
    coef[:, RATE_RELEASE] = fmax / params.t_release_s
    return BrakeArrays(ID, delay, fmax, coef)


def initial_state(arrays: BrakeArrays):
    """Released brakes, no command received."""
    return released_state(arrays.delay_s.shape[0])


@jit_step_inner
def _ramp(force, target, dt, rate_apply, rate_release):
    if target > force:
        return min(target, force + rate_apply * dt)
    return max(target, force - rate_release * dt)


@jit_step_inner
def advance(arrays, state, events, t0, t1):
    """Advance every vehicle's block force exactly from t0 to t1 [s] (state updated in place)."""
    fb, lvl, lkind, nxt = state.force_N, state.level, state.level_kind, state.next_event
    delay, fmax, coef = arrays.delay_s, arrays.force_max_N, arrays.coef
    ev_t, ev_lvl, ev_kind, n_ev = events.time_s, events.level, events.kind, events.count
    for i in range(fb.shape[0]):
        t = t0
        f = fb[i]
        while nxt[i] < n_ev and ev_t[nxt[i]] + delay[i] <= t1:
            te = max(ev_t[nxt[i]] + delay[i], t)
            f = _ramp(f, lvl[i] * fmax[i], te - t, coef[i, RATE_APPLY], coef[i, RATE_RELEASE])
            t = te
            lvl[i] = ev_lvl[nxt[i]]
            lkind[i] = ev_kind[nxt[i]]
            nxt[i] += 1
        fb[i] = _ramp(f, lvl[i] * fmax[i], t1 - t, coef[i, RATE_APPLY], coef[i, RATE_RELEASE])


def snapshot_extras(arrays: BrakeArrays, state) -> dict:
    """Model quantities a snapshot shows beyond the block forces: none."""
    return {}

"""The paper's empirical UIC air brake: delays and exponential filling, Eq. 5-7.

Each vehicle's block force relaxes exponentially towards a piecewise-constant target, the level
of the last command it has received times its full force. The command reaches vehicle i
t_app + t_del,i after it was issued (Eq. 6, t_del = distance from the venting vehicle / v_air,
:func:`~.base.vent_delay_s`). A rise follows
the filling time constant tau = t_fill / ln 20 (Eq. 7: 95 % after t_fill), a fall the release
one. The relaxation is integrated exactly, so for an emergency application from rest this is
Eq. 5, F = F_max (1 - exp(-(t - t_cmd - t_app - t_del) / tau)), for any step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..equations import jit, jit_inline, jit_step_inner
from ..parameters import Fittable, parameter
from .base import EMERGENCY, BrakeArrays, CompileError, released_state, vent_delay_s

NAME = "uic_empirical"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 0

#: Columns of ``BrakeArrays.coef``: time constants of an emergency application, a service
#: application and a release [s].
TAU_EMERGENCY, TAU_SERVICE, TAU_RELEASE = 0, 1, 2

LN20 = math.log(20.0)


@dataclass(frozen=True)
class Params:
    """Parameters of the empirical UIC air brake (Eq. 5-7, Table 3).

    Attributes
    ----------
    t_app_s : float
        Delay between the command and the brake-cylinder pressure rise [s].
    v_air_m_s : float
        Propagation speed of the brake-pipe pressure drop (Eq. 6) [m/s].
    t_fill_s : float
        Brake-cylinder filling time; time constant tau = t_fill / ln 20 (Eq. 7) [s].
    t_release_s : float
        Release time in P: block force decays with tau = t_release / ln 20 (not in the
        paper) [s].
    t_fill_G_s : float
        Brake-cylinder filling time of vehicles in G (UIC 540: 18-30 s) [s]. Not validated.
    t_release_G_s : float
        Release time of vehicles in G (UIC 540: 45-60 s) [s]. Not validated.
    t_service_fill_s : float
        Filling time of a service application in P; G vehicles scale it by
        t_fill_G / t_fill. A default for experiments, not validated [s].
    simultaneous : bool
        The command reaches every vehicle at once (t_del = 0 in Eq. 6), as with
        electronically controlled pneumatic brakes or radio distributed power; the paper's
        model is for a brake pipe vented at one vehicle only. Not validated.
    """

    t_app_s: float = parameter(1.0, "delay between command and brake-cylinder pressure rise [s]",
                               lo=0.0, hi=60.0)
    v_air_m_s: float = parameter(200.0, "propagation speed of the brake-pipe pressure drop [m/s]",
                                 lo=0.0, lo_open=True, hi=400.0)
    t_fill_s: float = parameter(5.0, "brake-cylinder filling time, tau = t_fill / ln 20 "
                                "(Eq. 7) [s]", lo=0.0, lo_open=True, hi=300.0)
    t_release_s: float = parameter(15.0, "release: block force decays with tau = t_release / "
                                   "ln 20 (not in the paper) [s]", lo=0.0, lo_open=True, hi=600.0)
    t_fill_G_s: float = parameter(25.0, "brake-cylinder filling time in G (UIC 540) [s]",
                                  lo=0.0, lo_open=True, hi=300.0)
    t_release_G_s: float = parameter(50.0, "release time in G (UIC 540) [s]",
                                     lo=0.0, lo_open=True, hi=600.0)
    t_service_fill_s: float = parameter(7.0, "filling time of a service application in P [s]",
                                        lo=0.0, lo_open=True, hi=300.0)
    simultaneous: bool = parameter(False, "the command reaches every vehicle at once "
                                   "(t_del = 0 in Eq. 6)")

    @property
    def tau_apply_s(self) -> float:
        """Time constant of the exponential rise, Eq. 7 [s]."""
        return self.t_fill_s / LN20

    @property
    def tau_release_s(self) -> float:
        """Time constant of the exponential release [s]."""
        return self.t_release_s / LN20


#: Parameters calibration may fit, by short name.
FITTABLE = {
    "t_app": Fittable("t_app_s", "s", 0.0, 5.0, 1.0,
                      "delay from the command to the pressure rise at the venting vehicle"),
    # a brake pipe propagates an emergency at 90-180 m/s without acceleration chambers and
    # 250-280 m/s with them (UIC 540); 340 m/s, sound in free air, is out of reach
    "v_air": Fittable("v_air_m_s", "m/s", 90.0, 290.0, 200.0,
                      "propagation speed of the brake-pipe pressure drop (Eq. 6)"),
    "t_fill": Fittable("t_fill_s", "s", 2.0, 30.0, 5.0,
                       "brake-cylinder filling time, tau = t_fill / ln 20 (Eq. 7)"),
}


#: The model's validated range: the longest train [m]. The paper validates it on trains of up to
#: 424 m (Tables 1-2: E402B + up to 32 Shimmns); 500 m keeps that span with a margin and stays
#: below the 700 m of European freight trains, where the build-up of the brake along the
#: train is what the model (one propagation speed, one filling time per brake position, Eq.
#: 5-7) does not follow. UIC 544-1's correction for long trains is a rule for stopping
#: distances, cited for them only: it does not validate the in-train forces.
MAX_LENGTH_M = 500.0


def validity(consist, p: Params) -> list[str]:
    """Where a run of this train leaves the model's validated range (empty: inside it).

    Parameters
    ----------
    consist : Consist
    p : Params

    Returns
    -------
    list of str
        One sentence per reason.
    """
    length = float(sum(v.length_m for v in consist.vehicles))
    if length <= MAX_LENGTH_M:
        return []
    return [f"empirical brake model outside its validated range: a {length:.0f} m train, "
            f"beyond the {MAX_LENGTH_M:.0f} m it is validated for (the paper's trains reach "
            "424 m); delays, build-up and in-train forces there are an extrapolation"]


def check_fields(p: Params) -> None:
    """Combinations no UIC distributor has: G must fill and release more slowly than P
    (UIC 540: P fills in 3-5 s and releases in 15-20 s, G in 18-30 s and 45-60 s).

    Raises
    ------
    CompileError
    """
    if p.t_fill_G_s < p.t_fill_s:
        raise CompileError("t_fill_G_s", f"{p.t_fill_G_s:g} s is shorter than t_fill_s "
                           f"({p.t_fill_s:g} s): a G distributor fills more slowly than P "
                           "(UIC 540)")
    if p.t_release_G_s < p.t_release_s:
        raise CompileError("t_release_G_s", f"{p.t_release_G_s:g} s is shorter than "
                           f"t_release_s ({p.t_release_s:g} s): a G distributor releases more "
                           "slowly than P (UIC 540)")
    if p.simultaneous and p.v_air_m_s != Params.v_air_m_s:
        raise CompileError("v_air_m_s", "has no effect with simultaneous: true (the command "
                           "reaches every vehicle at once); remove one of the two")


def compile(consist, params: Params, force_max_N: np.ndarray) -> BrakeArrays:  # noqa: A001
    """Per-vehicle delays and time constants of a train.

    Parameters
    ----------
    consist : Consist
        The train, head first (vehicle lengths, venting vehicle and brake positions).
    params : Params
    force_max_N : ndarray
        Full block force of each vehicle [N] (zeros: brakes switched off).

    Returns
    -------
    BrakeArrays
        ``coef`` columns :data:`TAU_EMERGENCY`, :data:`TAU_SERVICE`, :data:`TAU_RELEASE`.
    """
    vs = consist.vehicles
    delay = vent_delay_s(consist, params.t_app_s, params.v_air_m_s, params.simultaneous)
    # brake position: G fills (and releases) slower; service applications scale alike
    in_g = np.array([v.brake_position == "G" for v in vs])
    fill = np.where(in_g, params.t_fill_G_s, params.t_fill_s)
    coef = np.empty((len(vs), 3))
    coef[:, TAU_EMERGENCY] = fill / LN20
    coef[:, TAU_SERVICE] = params.t_service_fill_s * fill / params.t_fill_s / LN20
    coef[:, TAU_RELEASE] = np.where(in_g, params.t_release_G_s, params.t_release_s) / LN20
    return BrakeArrays(ID, delay, np.ascontiguousarray(force_max_N, float), coef)


def initial_state(arrays: BrakeArrays):
    """Released brakes, no command received (no state beyond the common one)."""
    return released_state(arrays.delay_s.shape[0])


@jit_inline
def _relax(force, target, decay):
    """The force after relaxing towards ``target`` by the factor ``decay`` = exp(-dt/tau)."""
    return target + (force - target) * decay


@jit_inline
def _tau(force, target, tau_apply, tau_release):
    """Time constant of a relaxation: application when the force rises, else release [s]."""
    return tau_apply if target > force else tau_release


@jit_step_inner
def advance(arrays, state, events, t0, t1):
    """Advance every vehicle's block force exactly from t0 to t1 [s] (state updated in place).

    Each vehicle relaxes exponentially towards ``level * force_max``, where the level is that
    of the last command event it has received (event time + its delay). An increase follows
    the application time constant of the event's kind, a decrease the release time constant.
    """
    fb, lvl, lkind, nxt = state.force_N, state.level, state.level_kind, state.next_event
    delay, fmax, coef = arrays.delay_s, arrays.force_max_N, arrays.coef
    ev_t, ev_lvl, ev_kind, n_ev = events.time_s, events.level, events.kind, events.count
    # vehicles share their time constants: the step's decay factor is computed once for each
    # run of vehicles with the same interval and time constant
    last_dt, last_tau, decay = math.nan, math.nan, 1.0
    for i in range(fb.shape[0]):
        t = t0
        f = fb[i]
        while nxt[i] < n_ev and ev_t[nxt[i]] + delay[i] <= t1:
            te = max(ev_t[nxt[i]] + delay[i], t)
            ta = coef[i, TAU_EMERGENCY] if lkind[i] == EMERGENCY else coef[i, TAU_SERVICE]
            target = lvl[i] * fmax[i]
            tau = _tau(f, target, ta, coef[i, TAU_RELEASE])
            f = _relax(f, target, math.exp(-(te - t) / tau))
            t = te
            lvl[i] = ev_lvl[nxt[i]]
            lkind[i] = ev_kind[nxt[i]]
            nxt[i] += 1
        ta = coef[i, TAU_EMERGENCY] if lkind[i] == EMERGENCY else coef[i, TAU_SERVICE]
        target = lvl[i] * fmax[i]
        tau = _tau(f, target, ta, coef[i, TAU_RELEASE])
        dt = t1 - t
        if dt != last_dt or tau != last_tau:
            last_dt, last_tau = dt, tau
            decay = math.exp(-dt / tau)
        fb[i] = _relax(f, target, decay)


def snapshot_extras(arrays: BrakeArrays, state) -> dict:
    """Model quantities a snapshot shows beyond the block forces: none."""
    return {}


@jit
def rise_fraction(t_since_onset_s, tau_s):
    """Fraction of the maximum block force reached, Eq. 5 (0 before the onset).

    Parameters
    ----------
    t_since_onset_s : float
        t - t_cmd - t_app - t_del [s].
    tau_s : float
        Time constant, Eq. 7 [s].

    Returns
    -------
    float
    """
    if t_since_onset_s <= 0.0:
        return 0.0
    return 1.0 - math.exp(-t_since_onset_s / tau_s)

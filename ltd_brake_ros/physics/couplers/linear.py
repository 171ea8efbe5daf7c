"""Linear spring-damper coupler, optionally with slack.

F = k * s(d) + c * rate, where s(d) is the deflection beyond the slack (0 inside |d| <= slack,
d - slack above, d + slack below): a linear draw gear and buffers of equal stiffness with a
viscous damper in parallel (the Kelvin-Voigt idealisation). Force and its derivatives are
continuous in the rate and non-decreasing in deflection and rate, as the contract requires.
Beyond ``slack_m + travel_m`` the gear would be solid; the force keeps its slope there and the
simulator reports the excursion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import parameters
from ..equations import jit_inline
from ..parameters import REQUIRED, Fittable, parameter
from .base import MAX_STIFFNESS_N_M, CouplerArrays, buffer_end_force_field

NAME = "linear"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 1

#: Entries of ``CouplerArrays.coef``: stiffness [N/m], damping [N s/m], slack [m].
STIFFNESS, DAMPING, SLACK = 0, 1, 2


@dataclass(frozen=True)
class Params:
    """Parameters of a linear spring-damper coupler (files give them in kN and mm).

    Attributes
    ----------
    stiffness_N_m : float
        Spring stiffness beyond the slack [N/m] (file: ``stiffness_kN_per_mm``).
    damping_N_s_m : float
        Viscous damping [N s/m] (file: ``damping_kN_s_per_m``).
    slack_m : float
        Free play either side of the neutral position [m] (file: ``slack_mm``).
    travel_m : float
        Spring travel beyond the slack, either way [m] (file: ``travel_mm``; inf: unbounded).
    draft_strength_N, buff_strength_N : float
        Largest draft and buff force the coupling withstands, magnitudes [N] (files:
        ``draft_strength_kN``, ``buff_strength_kN``; inf: unknown).
    buffer_end_force_N : float
        Declared end force of one side buffer [N] (file: ``buffer_end_force_kN``; NaN:
        not declared, :data:`.base.DEFAULT_BUFFER_END_FORCE_N` assumed): beyond twice it per
        coupling the run is marked non-physical.
    source : str
        File the values came from.
    """

    stiffness_N_m: float = parameter(REQUIRED, "stiffness beyond the slack [kN/mm]",
                                     lo=0.0, lo_open=True, hi=MAX_STIFFNESS_N_M / 1e6,
                                     key="stiffness_kN_per_mm", scale=1e6)
    damping_N_s_m: float = parameter(0.0, "viscous damping [kN s/m]", lo=0.0, hi=1e5,
                                     key="damping_kN_s_per_m", scale=1e3)
    slack_m: float = parameter(0.0, "free play either side of neutral [mm]", lo=0.0, hi=500.0,
                               key="slack_mm", scale=1e-3)
    travel_m: float = parameter(math.inf, "spring travel beyond the slack [mm]", lo=0.0,
                                lo_open=True, key="travel_mm", scale=1e-3)
    draft_strength_N: float = parameter(math.inf, "largest draft force withstood [kN]", lo=0.0,
                                        lo_open=True, key="draft_strength_kN", scale=1e3)
    buff_strength_N: float = parameter(math.inf, "largest buff force withstood, magnitude [kN]",
                                       lo=0.0, lo_open=True, key="buff_strength_kN", scale=1e3)
    buffer_end_force_N: float = buffer_end_force_field()
    source: str = ""


#: Parameters calibration may fit (to peak coupler forces), by short name: the stiffness from
#: 1 to 100 kN/mm (the secant stiffness of the Fig. 4 buffer-hook reconstruction is 1.6 kN/mm
#: at 50 mm draft and 2.4 kN/mm at 100 mm buff), the damping up to 1000 kN s/m and the slack
#: up to 50 mm either way (screw-coupling play).
FITTABLE = {
    "stiffness": Fittable("stiffness_N_m", "N/m", 1e6, 1e8, 2e7,
                          "spring stiffness beyond the slack"),
    "damping": Fittable("damping_N_s_m", "N s/m", 0.0, 1e6, 2e5, "viscous damping"),
    "slack": Fittable("slack_m", "m", 0.0, 0.05, 0.01, "free play either side of neutral"),
}


def compile(params: Params) -> CouplerArrays:  # noqa: A001 - the contract's name
    """The constants as arrays, once every field is finite and within its declared range.

    Parameters
    ----------
    params : Params

    Returns
    -------
    CouplerArrays
        ``coef`` entries :data:`STIFFNESS`, :data:`DAMPING`, :data:`SLACK`; no band; valid
        within the slack plus the travel.

    Raises
    ------
    CompileError
        A field is not finite (the travel and strengths may be inf) or out of its range.
    """
    parameters.check(params)
    coef = np.array([params.stiffness_N_m, params.damping_N_s_m, params.slack_m], float)
    reach = float(params.slack_m + params.travel_m)
    return CouplerArrays(ID, np.zeros((0, 0)), coef, 0.0, -reach, reach)


@jit_inline
def force(table, coef, defl_m, rate_m_s):
    """Coupler force [N, draft positive], d/d(deflection) [N/m] and d/d(rate) [N/(m/s)]."""
    k = coef[STIFFNESS]
    c = coef[DAMPING]
    slack = coef[SLACK]
    if defl_m > slack:
        spring, kd = k * (defl_m - slack), k
    elif defl_m < -slack:
        spring, kd = k * (defl_m + slack), k
    else:
        spring, kd = 0.0, 0.0
    return spring + c * rate_m_s, kd, c

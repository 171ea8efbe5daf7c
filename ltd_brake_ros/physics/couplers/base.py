"""What every coupler model shares: the bundle the kernel passes, the bounds of a plausible
coupling.

See the contract in :mod:`ltd_brake_ros.physics.couplers`.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..parameters import parameter

# Bounds of a plausible coupling characteristic. Beyond them a value is a unit error (N or daN
# in a kN column, m in a mm column), and forces or slopes that reach the kernel's Newton solve
# unbounded can end in a division by zero.

#: Largest force [N]: ten times the 2000 kN longitudinal compressive proof load of a freight
#: wagon body at buffer height (EN 12663-2) and far above any draw gear's breaking strength.
MAX_FORCE_N = 20e6
#: Largest deflection either way [m]: ten times a side buffer's 105 mm stroke (the paper's
#: buffers, UIC 526-1 category A).
MAX_DEFLECTION_M = 1.0
#: Largest stiffness [N/m] (10 000 kN/mm): twenty times the axial stiffness of a wagon's whole
#: steel underframe (E A / L = 210 GPa x 0.02 m^2 / 10 m, about 420 kN/mm).
MAX_STIFFNESS_N_M = 1e10


#: Side buffers of one coupling interface that share a buff force in parallel (left and right;
#: the two buffers of a side, one on each vehicle, are in series and carry the same force).
BUFFER_SIDES = 2
#: End force of one freight side buffer of category A or B when its coupler file declares none
#: [N]: 1.0 MN, assumed, not verified. A freight side buffer is solid at roughly 0.6-1.0 MN: the
#: UIC's service tests of longitudinal forces used "590 kN buffers" (ORE B36 RP 8, catalogue
#: record only) and a category-A buffer's 30 kJ over 105 mm on a progressive ring-spring curve
#: reaches about 0.67-1.05 MN at full stroke (arithmetic on secondary-source category
#: energies); the upper end is taken so that no fine train is marked beyond its limit state.
DEFAULT_BUFFER_END_FORCE_N = 1.0e6
#: Where :data:`DEFAULT_BUFFER_END_FORCE_N` comes from, as outputs print it.
DEFAULT_BUFFER_END_FORCE_ORIGIN = ("1000 kN per buffer, freight category A/B (assumed, not "
                                   "verified: solid at roughly 0.6-1.0 MN; ORE B36 service tests "
                                   "used 590 kN buffers)")


def buffer_end_force_field():
    """The ``buffer_end_force_N`` field every coupler model's ``Params`` declares.

    The end force of one side buffer, its limit state: beyond twice it per coupling (both
    buffers of a side solid) the vehicles' underframes carry the force, which is then a limit
    state, not an elastic buffer force. It belongs to the buffer's category, independent of
    the force curve; NaN (omitted from the file) takes :data:`DEFAULT_BUFFER_END_FORCE_N`
    with a warning.
    """
    return parameter(math.nan, "end force of one side buffer, its category's [kN] (omitted: "
                     f"{DEFAULT_BUFFER_END_FORCE_N / 1e3:.0f} kN, assumed)", lo=0.0,
                     lo_open=True, hi=MAX_FORCE_N / 1e3, key="buffer_end_force_kN",
                     scale=1e3)


def buffer_end_force_N(params) -> float:
    """The declared end force of one side buffer of a coupler model's ``Params`` [N]
    (:data:`DEFAULT_BUFFER_END_FORCE_N` where none is declared)."""
    value = float(getattr(params, "buffer_end_force_N", math.nan))
    return value if math.isfinite(value) else DEFAULT_BUFFER_END_FORCE_N


def buffer_end_force_declared(params) -> bool:
    """Whether a coupler model's ``Params`` declares its buffers' end force."""
    return math.isfinite(float(getattr(params, "buffer_end_force_N", math.nan)))


class CouplerArrays(NamedTuple):
    """A coupler model compiled once (every coupler of the train has it), never mutated.

    Attributes
    ----------
    model : int
        Registry id of the model (selects its branch of the one jitted dispatch).
    table : ndarray, shape (rows, points)
        The model's tables, rows named by the model (shape (0, 0) for none).
    coef : ndarray
        The model's constants, entries named by the model.
    band_m_s : float
        Half-width of the steep band in deflection rate where the force changes fast with
        the rate (Eq. 3's v_th), which the kernel's safeguard must not let a Newton update
        jump across; 0 for none [m/s].
    valid_lo_m, valid_hi_m : float
        Range of deflections the characteristic is valid for (outside it the force is
        extrapolated); infinite when unbounded [m].
    """

    model: int
    table: np.ndarray
    coef: np.ndarray
    band_m_s: float
    valid_lo_m: float
    valid_hi_m: float

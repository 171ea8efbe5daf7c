"""What every coupler model shares: the bundle the kernel passes, the bounds of a plausible
coupling.

See the contract in :mod:`ltd_brake_ros.physics.couplers`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

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

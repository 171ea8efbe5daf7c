"""What every coupler model shares: the bundle the kernel passes.

See the contract in :mod:`ltd_brake_ros.physics.couplers`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


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

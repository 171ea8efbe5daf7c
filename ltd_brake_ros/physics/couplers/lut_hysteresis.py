"""Coupler with loading and unloading curves from a look-up table, Eq. 3.

F = (F_L + F_U)/2 + |F_L - F_U|/2 * clip(rate / v_th, -1, 1), the curves interpolated linearly
in the table and extrapolated with their end slopes: loading follows one curve, unloading the
other, and the force moves between them over a band of deflection rates |rate| <= v_th.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..equations import jit_inline, lut_segment
from .base import CouplerArrays

NAME = "lut_hysteresis"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 0

#: Rows of ``CouplerArrays.table``: deflection [m], loading and unloading force [N].
DEFLECTION, LOADING, UNLOADING = 0, 1, 2
#: Entry of ``CouplerArrays.coef``: the threshold speed v_th [m/s].
V_TH = 0


@dataclass(frozen=True)
class Params:
    """Loading/unloading impedance of one coupling interface (Eq. 3).

    Attributes
    ----------
    deflection_m : tuple of float
        Strictly increasing deflections, draft positive [m].
    loading_N, unloading_N : tuple of float
        Forces of the loading and unloading curves at those deflections, draft positive [N];
        neither decreases with deflection.
    v_th_m_s : float
        Eq. 3 threshold speed between the curves [m/s].
    source : str
        File the table came from.
    draft_strength_N, buff_strength_N : float
        Largest draft and buff force the coupling withstands, magnitudes [N] (inf: unknown).
    """

    deflection_m: tuple[float, ...]
    loading_N: tuple[float, ...]
    unloading_N: tuple[float, ...]
    v_th_m_s: float = 1e-4
    source: str = ""
    draft_strength_N: float = math.inf
    buff_strength_N: float = math.inf


#: Parameters calibration may fit: none (a table is not fitted by distances).
FITTABLE: dict = {}


def compile(params: Params) -> CouplerArrays:  # noqa: A001 - the contract's name
    """The table as arrays.

    Parameters
    ----------
    params : Params

    Returns
    -------
    CouplerArrays
        ``table`` rows :data:`DEFLECTION`, :data:`LOADING`, :data:`UNLOADING`; ``coef``
        [v_th]; the valid range is the table's.
    """
    table = np.array([params.deflection_m, params.loading_N, params.unloading_N], float)
    return CouplerArrays(ID, table, np.array([float(params.v_th_m_s)]), float(params.v_th_m_s),
                         float(table[DEFLECTION, 0]), float(table[DEFLECTION, -1]))


@jit_inline
def force(table, coef, defl_m, rate_m_s):
    """Coupler force [N, draft positive], d/d(deflection) [N/m] and d/d(rate) [N/(m/s)]."""
    f, kd, kr, _seg, _band = eq3(table, coef[V_TH], defl_m, rate_m_s)
    return f, kd, kr


@jit_inline
def eq3(table, v_th, defl_m, rate_m_s):
    """Coupler force with hysteresis, Eq. 3, and its partial derivatives.

    F = (F_L + F_U)/2 + |F_L - F_U|/2 * clip(rate / v_th, -1, 1), linear interpolation in the
    table and extrapolation with the end slopes.

    Parameters
    ----------
    table : ndarray, shape (3, m)
        Rows :data:`DEFLECTION` [m], :data:`LOADING` and :data:`UNLOADING` [N].
    v_th : float
        Threshold speed [m/s].
    defl_m : float
        Deflection x_front - x_rear, draft positive [m].
    rate_m_s : float
        Deflection speed [m/s].

    Returns
    -------
    force_N : float
        Draft positive [N].
    dforce_ddefl : float
        [N/m].
    dforce_drate : float
        [N/(m/s)].
    segment : int
        Table segment (see :func:`~ltd_brake_ros.physics.equations.lut_segment`).
    band : int
        -1 unloading/loading below the band, 0 inside |rate| <= v_th, +1 above.
    """
    seg = lut_segment(table, defl_m)
    n = table.shape[1]
    k = min(max(seg, 0), n - 2)
    x0 = table[DEFLECTION, k]
    dx = table[DEFLECTION, k + 1] - x0
    sl = (table[LOADING, k + 1] - table[LOADING, k]) / dx
    su = (table[UNLOADING, k + 1] - table[UNLOADING, k]) / dx
    fl = table[LOADING, k] + sl * (defl_m - x0)
    fu = table[UNLOADING, k] + su * (defl_m - x0)
    diff = fl - fu
    r = rate_m_s / v_th
    if r > 1.0:
        c, band = 1.0, 1
    elif r < -1.0:
        c, band = -1.0, -1
    else:
        c, band = r, 0
    sgn = 1.0 if diff >= 0.0 else -1.0
    f = 0.5 * (fl + fu) + 0.5 * abs(diff) * c
    dfd = 0.5 * (sl + su) + 0.5 * sgn * (sl - su) * c
    dfr = 0.5 * abs(diff) / v_th if band == 0 else 0.0
    return f, dfd, dfr, seg, band


def coupler_force(defl_m, rate_m_s, xs, f_load, f_unload, v_th):
    """Eq. 3 (see :func:`eq3`) for a table given as three sequences, from Python.

    Parameters
    ----------
    defl_m, rate_m_s : float
        Deflection, draft positive [m], and its rate [m/s].
    xs, f_load, f_unload : array_like
        Table deflections [m] and loading/unloading forces [N].
    v_th : float
        Threshold speed [m/s].

    Returns
    -------
    force_N, dforce_ddefl, dforce_drate, segment, band
        As :func:`eq3`.
    """
    table = np.array([xs, f_load, f_unload], float)
    return eq3(table, float(v_th), float(defl_m), float(rate_m_s))

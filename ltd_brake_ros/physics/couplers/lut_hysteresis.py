"""Coupler with loading and unloading curves from a look-up table, Eq. 3.

F = (F_L + F_U)/2 + |F_L - F_U|/2 * clip(rate / v_th, -1, 1), the curves interpolated linearly
in the table and extrapolated with their end slopes: loading follows one curve, unloading the
other, and the force moves between them over a band of deflection rates |rate| <= v_th.

Four scalars reshape the tabulated curves, each on one side (buff: deflection < 0, draft: > 0)
so that calibration can fit them (:data:`FITTABLE`): a scale s of both curves and a scale h of
the gap between them,

    F_L = s * F_L,table,    F_U = s * (F_L,table - h * (F_L,table - F_U,table)),

so that h = 0 makes the side elastic and h = 1 keeps the table's dissipation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import parameters
from ..equations import jit_inline, jit_inner, lut_segment_near
from ..parameters import REQUIRED, CompileError, Fittable, parameter
from .base import MAX_DEFLECTION_M, MAX_FORCE_N, MAX_STIFFNESS_N_M, CouplerArrays, buffer_end_force_field

NAME = "lut_hysteresis"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 0

#: Rows of ``CouplerArrays.table``: deflection [m], loading and unloading force [N], and the
#: slopes of the loading and unloading curves over the segment that starts at each point
#: [N/m] (the last point repeats the last segment's), computed once rather than per force.
DEFLECTION, LOADING, UNLOADING, LOADING_SLOPE, UNLOADING_SLOPE = 0, 1, 2, 3, 4
#: Entries of ``CouplerArrays.coef``: the threshold speed v_th [m/s] and its reciprocal
#: [s/m] (the force multiplies by it rather than divide).
V_TH, INV_V_TH = 0, 1


@dataclass(frozen=True)
class Params:
    """Loading/unloading impedance of one coupling interface (Eq. 3).

    Attributes
    ----------
    deflection_m : tuple of float
        Strictly increasing deflections from buff (negative) through 0 to draft (positive) [m]
        (file: ``deflection_mm``).
    loading_N, unloading_N : tuple of float
        Forces of the loading and unloading curves at those deflections, draft positive [N]
        (files: ``loading_kN``, ``unloading_kN``); see :func:`check` for what they must meet.
    v_th_m_s : float
        Eq. 3 threshold speed between the curves [m/s] (file: ``v_th_mm_s``).
    source : str
        File the table came from.
    draft_strength_N, buff_strength_N : float
        Largest draft and buff force the coupling withstands, magnitudes [N] (files:
        ``draft_strength_kN``, ``buff_strength_kN``; inf: unknown).
    buff_travel_m : float
        Buff deflection of the interface at which the buffers go solid [m] (file:
        ``buff_travel_mm``; inf: the table's end): the valid range ends there, and a run
        beyond it is marked non-physical.
    buffer_end_force_N : float
        Declared end force of one side buffer [N] (file: ``buffer_end_force_kN``; NaN: not
        declared, :data:`.base.DEFAULT_BUFFER_END_FORCE_N` assumed): beyond twice it per
        coupling (both buffers of a side solid) the run is marked non-physical.
    buff_scale, draft_scale : float
        Scale of both curves in buff (deflection < 0) and in draft (deflection > 0) [-].
    buff_hysteresis, draft_hysteresis : float
        Scale of the gap between the loading and unloading curves in buff and in draft
        (0: elastic) [-].

    Examples
    --------
    >>> from ltd_brake_ros import load_coupler
    >>> lut = load_coupler("couplers/buffer_hook_pugi.yaml")
    >>> lut.deflection_m[0] < 0.0 < lut.deflection_m[-1]
    True
    """

    deflection_m: tuple[float, ...] = parameter(
        REQUIRED, "table deflections, draft positive [mm]", key="deflection_mm", scale=1e-3,
        sequence=True)
    loading_N: tuple[float, ...] = parameter(
        REQUIRED, "loading-curve force at each deflection, draft positive [kN]",
        key="loading_kN", scale=1e3, sequence=True)
    unloading_N: tuple[float, ...] = parameter(
        REQUIRED, "unloading-curve force at each deflection, draft positive [kN]",
        key="unloading_kN", scale=1e3, sequence=True)
    # Eq. 3 divides by v_th: below 1 um/s its rate derivative |F_L - F_U|/(2 v_th) would exceed
    # 1e13 N s/m, stiffer than any coupling and beyond what the Newton solve resolves
    v_th_m_s: float = parameter(1e-4, "Eq. 3 threshold speed between the curves [mm/s]",
                                lo=1e-3, hi=1e4, key="v_th_mm_s", scale=1e-3)
    source: str = ""
    draft_strength_N: float = parameter(math.inf, "largest draft force withstood [kN]", lo=0.0,
                                        lo_open=True, key="draft_strength_kN", scale=1e3)
    buff_strength_N: float = parameter(math.inf, "largest buff force withstood, magnitude [kN]",
                                       lo=0.0, lo_open=True, key="buff_strength_kN", scale=1e3)
    buff_scale: float = parameter(1.0, "scale of both curves in buff (deflection < 0) [-]",
                                  lo=0.0, lo_open=True, hi=20.0)
    draft_scale: float = parameter(1.0, "scale of both curves in draft (deflection > 0) [-]",
                                   lo=0.0, lo_open=True, hi=20.0)
    buff_hysteresis: float = parameter(1.0, "scale of the gap between the loading and unloading "
                                       "curves in buff (0: elastic) [-]", lo=0.0, hi=20.0)
    draft_hysteresis: float = parameter(1.0, "scale of the gap between the loading and "
                                        "unloading curves in draft (0: elastic) [-]",
                                        lo=0.0, hi=20.0)
    buff_travel_m: float = parameter(math.inf, "buff travel of the interface before it is "
                                     "solid, e.g. two 105 mm buffers: 210 [mm] (inf: the "
                                     "table's end)", lo=0.0, lo_open=True, key="buff_travel_mm",
                                     scale=1e-3)
    buffer_end_force_N: float = buffer_end_force_field()


#: Buffers of one coupling interface that a buff deflection compresses in series (one on each
#: vehicle), and sides in parallel (left and right), as the shipped table describes it.
BUFFERS_IN_SERIES, BUFFER_SIDES = 2, 2
#: Stroke of one side buffer [m] (the paper's buffers; UIC 526-1, EN 15551).
BUFFER_STROKE_M = 0.105
#: Energy a side buffer of 105 mm stroke absorbs, by category of UIC 526-1 / EN 15551 [J]:
#: A 30 kJ, B 50 kJ, C 70 kJ.
BUFFER_ENERGY_J = {"A": 30e3, "B": 50e3, "C": 70e3}
#: Energy per buffer the loading curve of the shipped Fig. 4 reconstruction stores over the
#: stroke (buff_scale 1): 85.9 kJ per interface, four buffers [J].
RECONSTRUCTION_BUFFER_ENERGY_J = 21.47e3

#: Parameters calibration may fit, by short name. The buff scale is bounded by the energy one
#: buffer stores over its 105 mm stroke, from category A (30 kJ) to C (70 kJ) of UIC 526-1 /
#: EN 15551, relative to the 21.5 kJ of the shipped Fig. 4 reconstruction (see
#: :func:`buffer_energy_J`); the draft scale within a factor two of the reconstruction of the
#: draw gear; the hysteresis scales keep the unloading force between 20 % and 80 % of the
#: loading force (the reconstruction: 50 % in buff, 60 % in draft), the range from elastomer
#: to ring-spring energy absorbers.
FITTABLE = {
    "buff_scale": Fittable("buff_scale", "-", BUFFER_ENERGY_J["A"] / RECONSTRUCTION_BUFFER_ENERGY_J,
                           BUFFER_ENERGY_J["C"] / RECONSTRUCTION_BUFFER_ENERGY_J, 1.0,
                           "scale of the buff side of both curves (buffer energy, UIC 526-1)"),
    "draft_scale": Fittable("draft_scale", "-", 0.5, 2.0, 1.0,
                            "scale of the draft side of both curves (draw gear)"),
    "buff_hysteresis": Fittable("buff_hysteresis", "-", 0.4, 1.6, 1.0,
                                "scale of the loading-unloading gap in buff (dissipation)"),
    "draft_hysteresis": Fittable("draft_hysteresis", "-", 0.5, 2.0, 1.0,
                                 "scale of the loading-unloading gap in draft (dissipation)"),
}


def curves(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The curves the simulation uses: the table reshaped by the side scales.

    Parameters
    ----------
    params : Params

    Returns
    -------
    deflection_m, loading_N, unloading_N : ndarray
        F_L = s F_L,table and F_U = s (F_L,table - h (F_L,table - F_U,table)), with s and h the
        buff values where the deflection is negative and the draft values elsewhere.
    """
    d = np.asarray(params.deflection_m, float)
    fl = np.asarray(params.loading_N, float)
    fu = np.asarray(params.unloading_N, float)
    buff = d < 0.0
    s = np.where(buff, params.buff_scale, params.draft_scale)
    h = np.where(buff, params.buff_hysteresis, params.draft_hysteresis)
    # h = 1 keeps the table's unloading curve exactly (fl - (fl - fu) may round)
    return d, s * fl, s * np.where(h == 1.0, fu, fl - h * (fl - fu))


def buffer_energy_J(params: Params, stroke_m: float = BUFFER_STROKE_M) -> float:
    """Energy one side buffer stores on the loading curve over its stroke [J].

    The buff side of an interface compresses :data:`BUFFERS_IN_SERIES` buffers on each of
    :data:`BUFFER_SIDES` sides: the interface's loading curve integrated from 0 to
    -``BUFFERS_IN_SERIES * stroke_m``, divided by the number of buffers.

    Parameters
    ----------
    params : Params
    stroke_m : float, optional
        Stroke of one buffer [m].

    Returns
    -------
    float
    """
    d, fl, _ = curves(params)
    end = -BUFFERS_IN_SERIES * stroke_m
    x = np.union1d(d[(d > end) & (d < 0.0)], [end, 0.0])
    f = np.interp(x, d, fl)
    work = -float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))
    return work / (BUFFERS_IN_SERIES * BUFFER_SIDES)


def compile(params: Params) -> CouplerArrays:  # noqa: A001 - the contract's name
    """The table as arrays, once :func:`check` has passed.

    Parameters
    ----------
    params : Params

    Returns
    -------
    CouplerArrays
        ``table`` from :func:`table_of`; ``coef`` entries :data:`V_TH`,
        :data:`INV_V_TH`; the valid range is the table's, in buff no further than
        ``buff_travel_m``.

    Raises
    ------
    CompileError
        A precondition of :func:`check` does not hold.
    """
    check(params)
    table = table_of(*curves(params))
    v_th = float(params.v_th_m_s)
    return CouplerArrays(ID, table, np.array([v_th, 1.0 / v_th]), v_th,
                         max(float(table[DEFLECTION, 0]), -float(params.buff_travel_m)),
                         float(table[DEFLECTION, -1]))


def table_of(deflection_m, loading_N, unloading_N) -> np.ndarray:
    """The table :func:`eq3` interpolates: the curves and the slopes of their segments.

    Parameters
    ----------
    deflection_m : array_like
        Strictly increasing deflections [m].
    loading_N, unloading_N : array_like
        The curves' forces at those deflections [N].

    Returns
    -------
    ndarray, shape (5, m)
        Rows :data:`DEFLECTION`, :data:`LOADING`, :data:`UNLOADING`, :data:`LOADING_SLOPE` and
        :data:`UNLOADING_SLOPE`.
    """
    d, fl, fu = (np.asarray(a, float) for a in (deflection_m, loading_N, unloading_N))
    table = np.empty((5, d.size))
    table[DEFLECTION], table[LOADING], table[UNLOADING] = d, fl, fu
    dx = d[1:] - d[:-1]
    for row, curve in ((LOADING_SLOPE, fl), (UNLOADING_SLOPE, fu)):
        table[row, :-1] = (curve[1:] - curve[:-1]) / dx
        table[row, -1] = table[row, -2]
    return table


def check(params: Params) -> None:
    """Check the physical preconditions of a table (file units in the messages).

    Within the table (beyond it the force is extrapolated and the simulator reports the
    excursion):

    * the declared fields are finite and in range
      (:func:`~ltd_brake_ros.physics.parameters.check`): v_th of 1e-3 to 1e4 mm/s, positive
      strengths;
    * at least two points, one force of each curve per deflection;
    * deflections strictly increasing, within +-``MAX_DEFLECTION_M`` (:mod:`.base`), from buff
      (negative) through 0 to draft (positive): the couplers start unloaded at 0;
    * forces within +-``MAX_FORCE_N``, of the deflection's sign (draft pulls, buff pushes);
    * each curve non-decreasing in deflection, no steeper than ``MAX_STIFFNESS_N_M``, and not
      flat: the contract's monotonicity, so that the Eq. 3 force is non-decreasing in
      deflection and rate;
    * unloading no larger than loading in magnitude (|F_U| <= |F_L|): a coupling gives back at
      most the energy it absorbed.

    Parameters
    ----------
    params : Params

    Raises
    ------
    CompileError
        For the first precondition that fails, naming the file's field and point.
    """
    parameters.check(params)
    key = {name: parameters.file_key(Params, name)
           for name in ("deflection_m", "loading_N", "unloading_N")}
    d = params.deflection_m
    if len(d) < 2:
        raise CompileError(key["deflection_m"], f"needs at least 2 points, got {len(d)}")
    for name in ("loading_N", "unloading_N"):
        if len(getattr(params, name)) != len(d):
            raise CompileError(key[name], f"has {len(getattr(params, name))} values but "
                               f"{key['deflection_m']} has {len(d)}")
    mm = [x * 1e3 for x in d]  # file units, for the messages only
    for i, x in enumerate(d):
        if abs(x) > MAX_DEFLECTION_M:
            raise CompileError(f"{key['deflection_m']}[{i}]", f"{mm[i]:g} mm is outside "
                               f"{-MAX_DEFLECTION_M * 1e3:g} to {MAX_DEFLECTION_M * 1e3:g} mm, "
                               "ten times a buffer's stroke (deflections are in mm)")
        if i and not x > d[i - 1]:
            raise CompileError(f"{key['deflection_m']}[{i}]", "must be strictly increasing "
                               f"({mm[i - 1]:g} then {mm[i]:g})")
    if not d[0] < 0.0 < d[-1]:
        raise CompileError(key["deflection_m"], "must run from buff (negative) to draft "
                           f"(positive) through 0 mm, got {mm[0]:g} to {mm[-1]:g} mm: the "
                           "couplers start unloaded at 0 mm")
    _check_curves(d, {"loading_N": params.loading_N, "unloading_N": params.unloading_N},
                  key, mm)
    scales = {f: getattr(params, f) for f in ("buff_scale", "draft_scale", "buff_hysteresis",
                                               "draft_hysteresis")}
    if any(v != 1.0 for v in scales.values()):
        _, fl, fu = curves(params)
        changed = ", ".join(f"{k} {v:g}" for k, v in scales.items() if v != 1.0)
        try:
            _check_curves(d, {"loading_N": tuple(fl), "unloading_N": tuple(fu)}, key, mm)
        except CompileError as exc:
            field = next(k for k, v in scales.items() if v != 1.0)
            raise CompileError(field, f"the table reshaped by {changed} is not a coupling: "
                               f"{exc.field}: {exc.reason}") from None


def _check_curves(d, columns: dict, key: dict, mm: list) -> None:
    """Force bounds, signs, monotonicity, stiffness and energy balance of the two curves."""
    for name in ("loading_N", "unloading_N"):
        f = columns[name]
        kn = [y * 1e-3 for y in f]
        for i, y in enumerate(f):
            where = f"{key[name]}[{i}]"
            if abs(y) > MAX_FORCE_N:
                raise CompileError(where, f"{kn[i]:g} kN is outside {-MAX_FORCE_N * 1e-3:g} to "
                                   f"{MAX_FORCE_N * 1e-3:g} kN, ten times a freight wagon's "
                                   "proof load (forces are in kN)")
            if y * d[i] < 0.0:
                raise CompileError(where, f"{kn[i]:g} kN at {mm[i]:g} mm has the wrong sign: "
                                   "draft (deflection > 0) pulls with a force >= 0, buff (< 0) "
                                   "pushes with a force <= 0")
            if not i:
                continue
            if y < f[i - 1]:
                raise CompileError(where, f"must not decrease with deflection ({kn[i - 1]:g} "
                                   f"then {kn[i]:g} kN): a coupler never pulls back harder "
                                   "when compressed further")
            slope = (y - f[i - 1]) / (d[i] - d[i - 1])
            if slope > MAX_STIFFNESS_N_M:
                raise CompileError(where, f"rises {slope * 1e-6:.4g} kN/mm from {mm[i - 1]:g} to "
                                   f"{mm[i]:g} mm, stiffer than {MAX_STIFFNESS_N_M * 1e-6:g} "
                                   "kN/mm (twenty times a wagon's whole underframe)")
        if f[0] == f[-1]:
            raise CompileError(key[name], "is flat: the coupler would have no stiffness")
    for i, (fl, fu) in enumerate(zip(columns["loading_N"], columns["unloading_N"])):
        if abs(fu) > abs(fl):
            raise CompileError(f"{key['unloading_N']}[{i}]", f"{fu * 1e-3:g} kN exceeds the "
                               f"loading curve's {fl * 1e-3:g} kN in magnitude at {mm[i]:g} mm: "
                               "the coupling would give back more energy than it absorbed "
                               "(columns swapped?)")


@jit_inline
def force(table, coef, defl_m, rate_m_s):
    """Coupler force [N, draft positive], d/d(deflection) [N/m] and d/d(rate) [N/(m/s)]."""
    f, kd, kr, _seg, _band = eq3(table, coef[INV_V_TH], defl_m, rate_m_s, -1)
    return f, kd, kr


@jit_inline
def force_near(table, coef, defl_m, rate_m_s, segment):
    """:func:`force`, looking the deflection up from table segment ``segment`` first; also
    returns the segment it lies in (the next lookup's guess)."""
    f, kd, kr, seg, _band = eq3(table, coef[INV_V_TH], defl_m, rate_m_s, segment)
    return f, kd, kr, seg


@jit_inner
def eq3(table, inv_v_th, defl_m, rate_m_s, guess):
    """Coupler force with hysteresis, Eq. 3, and its partial derivatives.

    F = (F_L + F_U)/2 + |F_L - F_U|/2 * clip(rate / v_th, -1, 1), linear interpolation in the
    table and extrapolation with the end slopes.

    Parameters
    ----------
    table : ndarray, shape (5, m)
        From :func:`table_of`.
    inv_v_th : float
        1 / v_th, the reciprocal of the threshold speed [s/m].
    defl_m : float
        Deflection x_front - x_rear, draft positive [m].
    rate_m_s : float
        Deflection speed [m/s].
    guess : int
        Table segment to try first (see
        :func:`~ltd_brake_ros.physics.equations.lut_segment_near`; -1: none).

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
    seg = lut_segment_near(table, defl_m, guess)
    n = table.shape[1]
    k = min(max(seg, 0), n - 2)
    x0 = table[DEFLECTION, k]
    sl = table[LOADING_SLOPE, k]
    su = table[UNLOADING_SLOPE, k]
    fl = table[LOADING, k] + sl * (defl_m - x0)
    fu = table[UNLOADING, k] + su * (defl_m - x0)
    diff = fl - fu
    r = rate_m_s * inv_v_th
    if r > 1.0:
        c, band = 1.0, 1
    elif r < -1.0:
        c, band = -1.0, -1
    else:
        c, band = r, 0
    sgn = 1.0 if diff >= 0.0 else -1.0
    f = 0.5 * (fl + fu) + 0.5 * abs(diff) * c
    dfd = 0.5 * (sl + su) + 0.5 * sgn * (sl - su) * c
    dfr = 0.5 * abs(diff) * inv_v_th if band == 0 else 0.0
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
    table = table_of(xs, f_load, f_unload)
    return eq3(table, 1.0 / float(v_th), float(defl_m), float(rate_m_s), -1)

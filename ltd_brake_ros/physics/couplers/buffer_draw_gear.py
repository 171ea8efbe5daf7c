"""Side buffers and a draw gear with a solid end: a physical buffer-and-draw-gear coupling.

One coupling interface between two vehicles (deflection d, draft positive):

* **Buff** (d < 0): two side buffers in series (one on each vehicle) on each of the two sides,
  each of stroke s_b = 105 mm (EN 15551 / UIC 526-1 wagon buffers). The two buffers of a side
  share the deflection, so each compresses x = |d| / 2 and the interface pushes with
  2 F_b(x), with the loading characteristic of one buffer

      F_b(x) = F_0 + (F_e - F_0) (x / s_b)^p,   0 < x <= s_b,

  preload F_0, a progressive shape p, and the end force F_e that gives the buffer the energy E
  over its stroke, E = F_0 s_b + (F_e - F_0) s_b / (p + 1). E names its category: at least
  30 kJ (A), 50 kJ (B), 70 kJ (C) per buffer (EN 15551 / UIC 526-1 as summarised by secondary
  sources; low confidence). The dynamic characteristic unloads at (1 - D_b) of the loading
  force: D_b is the share of the absorbed energy the buffer dissipates (ring springs and
  elastomers, 0.2-0.8).
* **Draft** (d > 0): the screw coupling tightened so that the buffers just touch at d = 0 (no
  slack), pulling through the two draw-hook springs in series: preload F_d0, then linear at
  the interface stiffness k_d over the draw gear's travel s_d; unloading at (1 - D_d).
* **Solid end**: beyond the buffers' stroke (d < -2 s_b) and the draw gear's travel
  (d > s_d) the force rises with the stiffness of the vehicles' structure, k_s (about the axial
  stiffness of a wagon underframe, E A / L = 210 GPa x 0.02 m^2 / 10 m ~ 420 kN/mm: an
  estimate), and stops dissipating. The valid range ends there: a run that goes beyond it is
  reported by the simulator and marked non-physical by the verdicts.

Loading and unloading are joined by Eq. 3's smoothing in the deflection rate (threshold
v_th), as the paper's coupler: the characteristic is compiled into the look-up table of
:mod:`.lut_hysteresis` and evaluated by its force function, so every safeguard of the kernel
applies unchanged. Velocity-dependent damping is not modelled: no source reached gives buffer
or draw-gear damping coefficients, and the paper's hysteresis already carries the dissipation.

Values not verified in a standard's text (preloads, shapes, draw-gear stiffness and travel)
are assumptions, fitted within physical bounds to the paper's peak forces where the file says
so.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import parameters
from ..parameters import CompileError, Fittable, parameter
from . import lut_hysteresis
from .base import MAX_FORCE_N, MAX_STIFFNESS_N_M, CouplerArrays, buffer_end_force_field

NAME = "buffer_draw_gear"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 2

#: Minimum energy one buffer absorbs over its stroke, by category (EN 15551 / UIC 526-1 as
#: summarised by secondary sources; low confidence) [J].
CATEGORY_ENERGY_J = {"A": 30e3, "B": 50e3, "C": 70e3}
#: Buffers in series on a side, and sides, of one interface.
BUFFERS_IN_SERIES, SIDES = 2, 2
#: Points of each buffer's loading curve in the compiled table.
_BUFFER_POINTS = 16
#: Deflection of the preload steps either side of 0 [m].
_PRELOAD_STEP_M = 1e-3
#: How far beyond the travel the table carries the solid end (it extrapolates with the same
#: slope beyond) [m].
_SOLID_SPAN_M = 0.02


@dataclass(frozen=True)
class Params:
    """Parameters of a buffer-and-draw-gear coupling (files give them in kN, mm and kJ).

    Attributes
    ----------
    buffer_stroke_m : float
        Stroke of one side buffer [m] (file: ``buffer_stroke_mm``).
    buffer_energy_J : float
        Energy one buffer absorbs on loading over its stroke [J] (file: ``buffer_energy_kJ``);
        its category: :func:`category`.
    buffer_preload_N : float
        Force one buffer needs to start moving [N] (file: ``buffer_preload_kN``).
    buffer_shape : float
        Exponent p of the buffer's progressive characteristic [-].
    buffer_dissipation : float
        Share of the absorbed energy a buffer dissipates, D_b [-].
    draw_preload_N : float
        Preload of the draw-hook springs [N] (file: ``draw_preload_kN``).
    draw_stiffness_N_m : float
        Stiffness of the draw gear (two hook springs in series) [N/m] (file:
        ``draw_stiffness_kN_per_mm``).
    draw_travel_m : float
        Travel of the draw gear before it is solid [m] (file: ``draw_travel_mm``).
    draw_dissipation : float
        Share of the absorbed energy the draw gear dissipates, D_d [-].
    solid_stiffness_N_m : float
        Stiffness beyond the travel, the vehicles' structure [N/m] (file:
        ``solid_stiffness_kN_per_mm``).
    v_th_m_s : float
        Eq. 3 threshold speed between loading and unloading [m/s] (file: ``v_th_mm_s``).
    draft_strength_N, buff_strength_N : float
        Largest draft and buff force the coupling withstands [N] (inf: unknown).
    buffer_end_force_N : float
        Declared end force of one side buffer, its category's [N] (file:
        ``buffer_end_force_kN``; NaN: not declared, :data:`.base.DEFAULT_BUFFER_END_FORCE_N`
        assumed), independent of the curve's :attr:`curve_end_force_N`: beyond twice it per
        coupling the run is marked non-physical.
    source : str
        File the values came from.
    """

    buffer_stroke_m: float = parameter(0.105, "stroke of one side buffer [mm]", lo=50.0,
                                       hi=200.0, key="buffer_stroke_mm", scale=1e-3)
    buffer_energy_J: float = parameter(40e3, "energy one buffer absorbs over its stroke [kJ]",
                                       lo=30.0, hi=150.0, key="buffer_energy_kJ", scale=1e3)
    buffer_preload_N: float = parameter(30e3, "force one buffer needs to start moving [kN]",
                                        lo=0.0, hi=200.0, key="buffer_preload_kN", scale=1e3)
    buffer_shape: float = parameter(3.0, "exponent of the buffer's progressive curve [-]",
                                    lo=1.0, hi=8.0)
    buffer_dissipation: float = parameter(0.5, "share of the absorbed energy a buffer "
                                          "dissipates [-]", lo=0.0, hi=0.9)
    draw_preload_N: float = parameter(20e3, "preload of the draw-hook springs [kN]", lo=0.0,
                                      hi=200.0, key="draw_preload_kN", scale=1e3)
    draw_stiffness_N_m: float = parameter(2e6, "draw-gear stiffness, two hook springs in "
                                          "series [kN/mm]", lo=0.1, hi=50.0,
                                          key="draw_stiffness_kN_per_mm", scale=1e6)
    draw_travel_m: float = parameter(0.11, "draw-gear travel before it is solid [mm]", lo=10.0,
                                     hi=300.0, key="draw_travel_mm", scale=1e-3)
    draw_dissipation: float = parameter(0.4, "share of the absorbed energy the draw gear "
                                        "dissipates [-]", lo=0.0, hi=0.9)
    solid_stiffness_N_m: float = parameter(4.2e8, "stiffness beyond the travel, the vehicles' "
                                           "structure [kN/mm]", lo=10.0,
                                           hi=MAX_STIFFNESS_N_M / 1e6,
                                           key="solid_stiffness_kN_per_mm", scale=1e6)
    v_th_m_s: float = parameter(1e-4, "Eq. 3 threshold speed between the curves [mm/s]",
                                lo=1e-3, hi=1e4, key="v_th_mm_s", scale=1e-3)
    draft_strength_N: float = parameter(math.inf, "largest draft force withstood [kN]", lo=0.0,
                                        lo_open=True, key="draft_strength_kN", scale=1e3)
    buff_strength_N: float = parameter(math.inf, "largest buff force withstood, magnitude [kN]",
                                       lo=0.0, lo_open=True, key="buff_strength_kN", scale=1e3)
    buffer_end_force_N: float = buffer_end_force_field()
    source: str = ""

    @property
    def curve_end_force_N(self) -> float:
        """Force of one buffer at the end of its stroke on its curve, F_e [N]."""
        s, p, f0 = self.buffer_stroke_m, self.buffer_shape, self.buffer_preload_N
        return f0 + (self.buffer_energy_J - f0 * s) * (p + 1.0) / s

    @property
    def solid_end_force_N(self) -> float:
        """Buff force of the interface where its buffers go solid [N] (magnitude)."""
        return SIDES * self.curve_end_force_N

    @property
    def draft_end_force_N(self) -> float:
        """Draft force of the interface where the draw gear goes solid [N]."""
        return self.draw_preload_N + self.draw_stiffness_N_m * self.draw_travel_m


#: Parameters calibration may fit, by short name, within physical bounds: the buffer energy
#: from category A's 30 kJ to 100 kJ (beyond C's 70 kJ), its shape from a nearly linear
#: (1.5) to a steeply progressive (6) characteristic, the dissipation of buffers and draw gear
#: from 20 % to 80 % (elastomer to ring spring), the draw gear's stiffness from 0.5 to 5 kN/mm.
FITTABLE = {
    "buffer_energy": Fittable("buffer_energy_J", "J", 30e3, 100e3, 40e3,
                              "energy one buffer absorbs over its stroke (its category)"),
    "buffer_shape": Fittable("buffer_shape", "-", 1.5, 6.0, 3.0,
                             "exponent of the buffer's progressive characteristic"),
    "buffer_dissipation": Fittable("buffer_dissipation", "-", 0.2, 0.8, 0.5,
                                   "share of the absorbed energy a buffer dissipates"),
    "draw_stiffness": Fittable("draw_stiffness_N_m", "N/m", 0.5e6, 5e6, 2e6,
                               "draw-gear stiffness (two hook springs in series)"),
    "draw_dissipation": Fittable("draw_dissipation", "-", 0.2, 0.8, 0.4,
                                 "share of the absorbed energy the draw gear dissipates"),
}


def category(params: Params) -> str:
    """The buffer category its energy over the stroke puts it in: ``A``, ``B`` or ``C``."""
    found = [c for c, e in CATEGORY_ENERGY_J.items() if params.buffer_energy_J >= e - 1e-6]
    return found[-1] if found else "below A"


def curves(params: Params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interface's loading and unloading curves, solid ends included.

    Parameters
    ----------
    params : Params

    Returns
    -------
    deflection_m, loading_N, unloading_N : ndarray
        Draft positive; the first and last segments are the solid ends.
    """
    s, p, f0, fe = (params.buffer_stroke_m, params.buffer_shape, params.buffer_preload_N,
                    params.curve_end_force_N)
    x = s * np.linspace(0.0, 1.0, _BUFFER_POINTS)[1:] ** 0.5  # denser where the curve bends
    fb = f0 + (fe - f0) * (x / s) ** p
    step = _PRELOAD_STEP_M
    # buff, from the solid end to the preload step (deflection increasing)
    d_buff = np.concatenate(([-BUFFERS_IN_SERIES * s - _SOLID_SPAN_M],
                             -BUFFERS_IN_SERIES * x[::-1], [-step]))
    load_buff = -SIDES * np.concatenate(([fe + params.solid_stiffness_N_m * _SOLID_SPAN_M / SIDES],
                                         fb[::-1], [f0]))
    keep_b = 1.0 - params.buffer_dissipation
    unload_buff = np.concatenate(([load_buff[0] - (1.0 - keep_b) * load_buff[1]],
                                  keep_b * load_buff[1:]))
    # draft: preload step, the linear draw gear, its solid end
    ds, kd, fd0 = params.draw_travel_m, params.draw_stiffness_N_m, params.draw_preload_N
    d_draft = np.array([step, ds, ds + _SOLID_SPAN_M])
    fd_end = fd0 + kd * ds
    load_draft = np.array([fd0 + kd * step, fd_end, fd_end + params.solid_stiffness_N_m *
                           _SOLID_SPAN_M])
    keep_d = 1.0 - params.draw_dissipation
    unload_draft = np.array([keep_d * load_draft[0], keep_d * fd_end,
                             keep_d * fd_end + params.solid_stiffness_N_m * _SOLID_SPAN_M])
    d = np.concatenate((d_buff, [0.0], d_draft))
    fl = np.concatenate((load_buff, [0.0], load_draft))
    fu = np.concatenate((unload_buff, [0.0], unload_draft))
    return d, fl, fu


def buffer_energy_J(params: Params) -> float:
    """Energy one buffer absorbs over its stroke on the compiled loading curve [J] (the
    table's piecewise-linear integral: within 1 % of ``buffer_energy_J``)."""
    d, fl, _ = curves(params)
    end = -BUFFERS_IN_SERIES * params.buffer_stroke_m
    keep = (d >= end - 1e-12) & (d <= 0.0)
    x, f = d[keep], fl[keep]
    work = -float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))
    return work / (BUFFERS_IN_SERIES * SIDES)


def check(params: Params) -> None:
    """Check the preconditions (file units in the messages).

    * every declared field finite and in range (:func:`~..parameters.check`);
    * the energy over the stroke at least the preload's share, F_0 s_b (a characteristic that
      does not fall), and at least category A's 30 kJ;
    * forces within ``MAX_FORCE_N`` and slopes within ``MAX_STIFFNESS_N_M`` (:mod:`.base`).

    Raises
    ------
    CompileError
        Naming the file's field.
    """
    parameters.check(params)
    if params.buffer_energy_J <= params.buffer_preload_N * params.buffer_stroke_m:
        raise CompileError("buffer_energy_kJ", f"{params.buffer_energy_J / 1e3:g} kJ is no more "
                           "than the preload's share over the stroke (buffer_preload_kN x "
                           "buffer_stroke_mm): the characteristic would fall")
    if params.buffer_energy_J < CATEGORY_ENERGY_J["A"] - 1e-6:
        raise CompileError("buffer_energy_kJ", f"{params.buffer_energy_J / 1e3:g} kJ is below "
                           "category A's 30 kJ (EN 15551 / UIC 526-1)")
    d, fl, fu = curves(params)
    if np.abs(fl).max() > MAX_FORCE_N:
        raise CompileError("buffer_energy_kJ", f"the buffers' end force "
                           f"{params.curve_end_force_N / 1e3:.0f} kN is beyond "
                           f"{MAX_FORCE_N / 1e3:.0f} kN per interface")
    slope = np.diff(fl) / np.diff(d)
    if slope.max() > MAX_STIFFNESS_N_M:
        raise CompileError("buffer_shape", f"the characteristic is steeper than "
                           f"{MAX_STIFFNESS_N_M / 1e6:g} kN/mm")


def compile(params: Params) -> CouplerArrays:  # noqa: A001 - the contract's name
    """The characteristic as a :mod:`.lut_hysteresis` table, valid up to the solid ends.

    Parameters
    ----------
    params : Params

    Returns
    -------
    CouplerArrays
        ``table`` as :func:`.lut_hysteresis.table_of` builds it; ``coef`` its Eq. 3
        threshold; the valid range from the buffers' solid end (-2 s_b) to the draw gear's
        (s_d).

    Raises
    ------
    CompileError
        A precondition of :func:`check` does not hold.
    """
    check(params)
    table = lut_hysteresis.table_of(*curves(params))
    v_th = float(params.v_th_m_s)
    return CouplerArrays(ID, table, np.array([v_th, 1.0 / v_th]), v_th,
                         -BUFFERS_IN_SERIES * float(params.buffer_stroke_m),
                         float(params.draw_travel_m))

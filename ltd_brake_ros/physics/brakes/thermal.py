"""Brake-block and wheel temperature of tread-braked vehicles: a lumped model, shared by every
brake model (it reads the retarding force the simulator already has, not a model's internals).

Each wheel of a vehicle with block brakes is two nodes: the wheel, and its blocks (all blocks
of a vehicle share its brake force equally, all its wheels the heat). The friction power of a
wheel, P = F_B v / wheels (retarding force times speed), enters the blocks and the wheel split
by the thermal effusivities weighted with the contact areas (Charron's partition with areas,
as in Limpert, *Brake Design and Safety*, SAE; medium: the formula as recalled, not checked in
the book here):

    gamma = 1 / (1 + (e_block / e_wheel) (A_contact / A_swept)),  e = sqrt(k rho c),

A_contact the blocks' friction faces, A_swept the tread band they sweep (pi D times the block
width): about 0.90 into the wheel for one P10 block per 920 mm wheel. While the brake is
applied the blocks also pass heat to the wheel by conduction over half their thickness; both
nodes lose heat to the air with h(v) = h0 + b v^0.8 (h0: natural convection and radiation at
rest; b from the fully turbulent flat-plate correlation Nu = 0.037 Re^0.8 Pr^(1/3) over the
body's length, Incropera & DeWitt, *Fundamentals of Heat and Mass Transfer*, ch. 7):

    C_b dT_b/dt = (1 - gamma) P - G_c (T_b - T_w) - G_b(v) (T_b - T_a)
    C_w dT_w/dt =  gamma P      + G_c (T_b - T_w) - G_w(v) (T_w - T_a)

Linear with constant coefficients over an interval of constant P and v, the system is
integrated exactly (2x2 matrix exponential) on a fixed grid of simulated time: the kernel adds
each accepted step's brake work and distance per vehicle, and at the first step ending on or
after a grid time (every ``update_interval_s``) advances the temperatures over the interval
with its mean power and speed. The result depends on the steps only, not on how a run is cut
into chunks; at the end of each of its calls the kernel brings them to that time for the
snapshot (:func:`current`, the updates untouched).

Not modelled: friction fade (no temperature or energy law of P10 cast-iron friction was
found: Karwatzki's law, Eq. 9, has none, and TrainDy has no block thermal model), rail chill
(it cools the wheel considerably in long drag braking, Vernersson & Lundén 2007: leaving it
out overestimates the wheel's temperature) and the temperature gradients inside the wheel
(T_w is the wheel's mean temperature; its tread and rim are hotter). Disc-braked and unbraked
vehicles carry no temperature (NaN).

Not validated (:data:`VALIDATION`, printed with every result): no published drag-braking case
with measured rim temperatures (30-45 min at 30-50 kW per wheel) was found to check it against.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..equations import jit_inline, jit_step_inner
from ..parameters import parameter

__all__ = ["Params", "Peaks", "ThermalArrays", "VALIDATION", "advance", "compile", "current",
           "initial_temperatures", "speed_coefficient", "wheel_share"]

#: The model's validation, printed and written with its results: no published drag-braking
#: case with numbers (rim temperatures after 30-45 min at 30-50 kW per wheel) was found.
VALIDATION = "not validated"

# --- materials and air: every constant with its source and confidence

#: Steel of the wheel: AISI 1042 (0.42 % C) at 300 K, density [kg/m^3], specific heat
#: [J/(kg K)], conductivity [W/(m K)] (Incropera & DeWitt, Table A.1; high for the table,
#: medium as a stand-in for wheel steel ER7, at most 0.52 % C; the heat capacity rises with
#: temperature, some 15-20 % by 300 C, not modelled).
STEEL_DENSITY, STEEL_HEAT, STEEL_CONDUCTIVITY = 7840.0, 460.0, 50.7
#: Phosphoric grey cast iron of P10 blocks, density [kg/m^3], specific heat [J/(kg K)],
#: conductivity [W/(m K)]: typical grey cast-iron values (handbook ranges 7100-7300,
#: 460-540, 45-55; medium, not measured on P10).
IRON_DENSITY, IRON_HEAT, IRON_CONDUCTIVITY = 7200.0, 500.0, 48.0
#: Air at 300 K: conductivity [W/(m K)], kinematic viscosity [m^2/s], Prandtl number
#: (Incropera & DeWitt, Table A.4; high).
AIR_CONDUCTIVITY, AIR_VISCOSITY, AIR_PRANDTL = 0.0263, 15.89e-6, 0.707
#: Fully turbulent flat plate, mean Nusselt number Nu_L = 0.037 Re_L^0.8 Pr^(1/3)
#: (Incropera & DeWitt, ch. 7; high for the correlation, low to medium for a wheel in a
#: bogie: shielding and the wheel's rotation are not in it).
TURBULENT_PLATE, REYNOLDS_EXPONENT = 0.037, 0.8


@dataclass(frozen=True)
class Params:
    """Parameters of the brake-block and wheel temperature model (see the module).

    Geometry defaults: a 920 mm freight wheel (the freight-wagon TSI's thermal reference
    case) with one P10 Bg block of 320 x 80 mm (TrainDy's Bg friction area, 25 600 mm^2).
    Every field may be given in a brake-parameter file.
    """

    ambient_temperature_K: float = parameter(
        293.15, "ambient air and initial temperature of blocks and wheels (20 C, TrainDy's "
        "default environment) [K]", lo=200.0, hi=330.0)
    wheel_mass_kg: float = parameter(
        350.0, "mass of one wheel, the wheel node (a 920 mm monobloc freight wheel; "
        "estimate, low) [kg]", lo=50.0, hi=2000.0)
    wheel_diameter_m: float = parameter(
        0.92, "wheel diameter: the tread band the blocks sweep, and the length of the "
        "convection correlation (TSI reference case: 920 mm) [m]", lo=0.3, hi=1.6)
    wheel_cooling_area_m2: float = parameter(
        1.5, "surface of one wheel cooled by the air: both faces and the tread of a 920 mm "
        "wheel (from its dimensions; medium) [m2]", lo=0.05, hi=10.0)
    block_mass_kg: float = parameter(
        10.0, "mass of one brake block (320 x 80 x 55 mm of cast iron; a worn block is "
        "lighter; low) [kg]", lo=0.5, hi=100.0)
    block_face_area_m2: float = parameter(
        0.0256, "friction face of one block (Bg, 320 x 80 mm: TrainDy's area) [m2]",
        lo=1e-3, hi=0.2)
    block_width_m: float = parameter(
        0.08, "width of a block's friction face, the tread band it sweeps [m]",
        lo=0.02, hi=0.3)
    block_thickness_m: float = parameter(
        0.055, "thickness of a block: it conducts heat to the wheel over half of it while "
        "applied (new block, estimate; low) [m]", lo=0.005, hi=0.2)
    block_cooling_area_m2: float = parameter(
        0.07, "surface of one block cooled by the air: back and sides (from its dimensions; "
        "low) [m2]", lo=0.005, hi=1.0)
    still_air_W_m2K: float = parameter(
        15.0, "heat-transfer coefficient at rest, h0: natural convection (~5) and radiation "
        "of oxidised steel linearised at 150-250 C (~10) (assumed; low) [W/(m2 K)]",
        lo=0.0, lo_open=True, hi=200.0)
    update_interval_s: float = parameter(
        1.0, "grid of simulated time on which the temperatures are advanced, exactly for the "
        "interval's mean power and speed (numerical; minutes of thermal time constant) [s]",
        lo=0.01, hi=10.0)


def speed_coefficient(length_m: float) -> float:
    """b of h = h0 + b v^0.8 for a body of ``length_m`` in the air stream [W/(m^2 K (m/s)^0.8)].

    The fully turbulent flat-plate correlation Nu_L = 0.037 Re_L^0.8 Pr^(1/3) with air at
    300 K: b = 0.037 k Pr^(1/3) nu^-0.8 L^-0.2; 6.1 for a 920 mm wheel, so that
    h = 15 + 65 = 80 W/(m^2 K) at 70 km/h.
    """
    return (TURBULENT_PLATE * AIR_CONDUCTIVITY * AIR_PRANDTL ** (1.0 / 3.0)
            / (AIR_VISCOSITY ** REYNOLDS_EXPONENT * length_m ** (1.0 - REYNOLDS_EXPONENT)))


def wheel_share(params: Params, blocks_per_wheel: float) -> float:
    """Share of the friction heat that enters the wheel, gamma [-] (see the module).

    Parameters
    ----------
    params : Params
    blocks_per_wheel : float
        Blocks braking one wheel (Bg: 1, Bgu: 2).

    Returns
    -------
    float
        0.90 for one Bg block on a 920 mm wheel, 0.82 for two.
    """
    e_wheel = math.sqrt(STEEL_CONDUCTIVITY * STEEL_DENSITY * STEEL_HEAT)
    e_block = math.sqrt(IRON_CONDUCTIVITY * IRON_DENSITY * IRON_HEAT)
    contact = blocks_per_wheel * params.block_face_area_m2
    swept = math.pi * params.wheel_diameter_m * params.block_width_m
    return 1.0 / (1.0 + e_block / e_wheel * contact / swept)


class ThermalArrays(NamedTuple):
    """The temperature model compiled for one train: per-vehicle values of one of its wheels
    and that wheel's blocks, built once, never mutated.

    Attributes
    ----------
    on : ndarray of bool
        The vehicle has block brakes (the others carry no temperature).
    wheels : ndarray
        Wheels of each vehicle, which share its brake work.
    wheel_share : ndarray
        gamma, share of the friction heat entering the wheel [-].
    block_capacity_J_K, wheel_capacity_J_K : ndarray
        Heat capacity of a wheel's blocks and of the wheel [J/K].
    contact_W_K : ndarray
        Conductance from the blocks to the wheel while applied [W/K].
    block_still_W_K, block_speed_W_K : ndarray
        Conductance of the blocks to the air, h0 A and b A [W/K], [W/(K (m/s)^0.8)].
    wheel_still_W_K, wheel_speed_W_K : ndarray
        The same of the wheel.
    ambient_K : float
        Air temperature [K].
    interval_s : float
        Update grid [s].
    """

    on: np.ndarray
    wheels: np.ndarray
    wheel_share: np.ndarray
    block_capacity_J_K: np.ndarray
    wheel_capacity_J_K: np.ndarray
    contact_W_K: np.ndarray
    block_still_W_K: np.ndarray
    block_speed_W_K: np.ndarray
    wheel_still_W_K: np.ndarray
    wheel_speed_W_K: np.ndarray
    ambient_K: float
    interval_s: float


def compile(consist, params: Params) -> ThermalArrays:  # noqa: A001
    """The temperature model of a train.

    Parameters
    ----------
    consist : Consist
        The train; vehicles whose ``brake`` is a block brake get temperatures (their
        ``blocks`` spread over 2 x ``axles`` wheels).
    params : Params

    Returns
    -------
    ThermalArrays
    """
    n = len(consist.vehicles)
    rows = np.zeros((9, n))
    on = np.zeros(n, np.bool_)
    b_wheel = speed_coefficient(params.wheel_diameter_m)
    b_block = speed_coefficient(params.block_face_area_m2 / params.block_width_m)
    # conduction over half the block's thickness, face to mean temperature
    contact = IRON_CONDUCTIVITY * params.block_face_area_m2 / (0.5 * params.block_thickness_m)
    for i, v in enumerate(consist.vehicles):
        wheels = 2.0 * max(int(v.axles), 1)
        rows[0, i] = wheels
        if getattr(v.brake, "type", "none") != "blocks":
            continue
        on[i] = True
        k = float(v.brake.blocks) / wheels  # blocks per wheel
        rows[1:, i] = (wheel_share(params, k),
                       k * params.block_mass_kg * IRON_HEAT,
                       params.wheel_mass_kg * STEEL_HEAT,
                       k * contact,
                       k * params.block_cooling_area_m2 * params.still_air_W_m2K,
                       k * params.block_cooling_area_m2 * b_block,
                       params.wheel_cooling_area_m2 * params.still_air_W_m2K,
                       params.wheel_cooling_area_m2 * b_wheel)
    return ThermalArrays(on, *(np.ascontiguousarray(r) for r in rows),
                         float(params.ambient_temperature_K), float(params.update_interval_s))


def initial_temperatures(arrays: ThermalArrays) -> np.ndarray:
    """Blocks and wheels at the air's temperature, NaN for vehicles without block brakes [K]."""
    return np.where(arrays.on, arrays.ambient_K, np.nan)


@jit_inline
def _step(arrays, i, power_W, speed_m_s, applied, dt, t_block, t_wheel):
    """Temperatures of vehicle ``i``'s blocks and wheel after ``dt`` seconds of constant
    power per wheel and speed, from ``t_block``, ``t_wheel`` [K] (exact)."""
    vf = speed_m_s ** REYNOLDS_EXPONENT if speed_m_s > 0.0 else 0.0
    gb = arrays.block_still_W_K[i] + arrays.block_speed_W_K[i] * vf
    gw = arrays.wheel_still_W_K[i] + arrays.wheel_speed_W_K[i] * vf
    gc = arrays.contact_W_K[i] if applied else 0.0
    cb, cw = arrays.block_capacity_J_K[i], arrays.wheel_capacity_J_K[i]
    share = arrays.wheel_share[i]
    # x' = M x + s for x = T - T_a
    m11, m12 = -(gc + gb) / cb, gc / cb
    m21, m22 = gc / cw, -(gc + gw) / cw
    s1, s2 = (1.0 - share) * power_W / cb, share * power_W / cw
    det = m11 * m22 - m12 * m21  # > 0: both nodes lose heat to the air
    # steady state x* = -M^-1 s
    x1 = (m12 * s2 - m22 * s1) / det
    x2 = (m21 * s1 - m11 * s2) / det
    d1 = t_block - arrays.ambient_K - x1
    d2 = t_wheel - arrays.ambient_K - x2
    # exp(M dt) = e^(l2 dt) I + phi (M - l2 I), phi = (e^(l1 dt) - e^(l2 dt)) / (l1 - l2)
    half = 0.5 * (m11 + m22)
    root = math.sqrt(0.25 * (m11 - m22) ** 2 + m12 * m21)
    l1, l2 = half + root, half - root
    e2 = math.exp(l2 * dt)
    gap = (l1 - l2) * dt
    if gap > 1.0:
        phi = (math.exp(l1 * dt) - e2) / (l1 - l2)
    elif gap > 0.0:
        phi = e2 * math.expm1(gap) / (l1 - l2)
    else:
        phi = e2 * dt
    y1 = e2 * d1 + phi * ((m11 - l2) * d1 + m12 * d2)
    y2 = e2 * d2 + phi * (m21 * d1 + (m22 - l2) * d2)
    return arrays.ambient_K + x1 + y1, arrays.ambient_K + x2 + y2


@jit_step_inner
def current(arrays, state, block_force_N, t, out_block, out_wheel):
    """Block and wheel temperature of every vehicle at time ``t`` [s], the brake work since
    the last update taken in (into ``out_block``, ``out_wheel`` [K]; the state untouched).

    Parameters
    ----------
    arrays : ThermalArrays
    state : KinematicState
        The kernel's state (temperatures at the last update, the work and distance since,
        the update clock).
    block_force_N : ndarray
        Block force of each vehicle now [N] (> 0: the blocks touch the wheel).
    t : float
        Time [s], not before the last update.
    out_block, out_wheel : ndarray
        Out [K].
    """
    tb, tw = state.block_updated_K, state.wheel_updated_K
    dt = t - state.heat_clock_s[0]
    for i in range(tb.shape[0]):
        out_block[i] = tb[i]
        out_wheel[i] = tw[i]
        if dt > 0.0 and arrays.on[i]:
            out_block[i], out_wheel[i] = _step(
                arrays, i, state.heat_work_J[i] / (arrays.wheels[i] * dt),
                state.heat_distance_m[i] / dt, block_force_N[i] > 0.0, dt, tb[i], tw[i])


@jit_step_inner
def advance(arrays, state, block_force_N, t):
    """Advance the temperatures to time ``t`` [s] over the interval since the last update,
    with its brake work and distance, and restart the interval (the kernel's call, in place).

    Parameters
    ----------
    arrays : ThermalArrays
    state : KinematicState
        Temperatures, their peaks, the work, distance and energy records, the clock
        (``heat_clock_s``: last update, next grid time).
    block_force_N : ndarray
        Block force of each vehicle now [N].
    t : float
        Time [s].
    """
    clock = state.heat_clock_s
    if t > clock[0]:
        tb, tw = state.block_updated_K, state.wheel_updated_K
        current(arrays, state, block_force_N, t, tb, tw)
        pb, pbt = state.peak_block_temperature_K, state.peak_block_temperature_time_s
        pw, pwt = state.peak_wheel_temperature_K, state.peak_wheel_temperature_time_s
        work, dist, energy = state.heat_work_J, state.heat_distance_m, state.brake_energy_J
        for i in range(tb.shape[0]):
            energy[i] += work[i]
            work[i] = 0.0
            dist[i] = 0.0
            if tb[i] > pb[i]:
                pb[i] = tb[i]
                pbt[i] = t
            if tw[i] > pw[i]:
                pw[i] = tw[i]
                pwt[i] = t
        clock[0] = t
    clock[1] = (math.floor(t / arrays.interval_s) + 1.0) * arrays.interval_s


@dataclass(frozen=True)
class Peaks:
    """The hottest blocks and wheel of a run, which vehicle and when.

    Attributes
    ----------
    block_K, wheel_K : float
        Peak temperature of a vehicle's blocks and of its wheels [K] (NaN: no vehicle with
        block brakes).
    block_vehicle, wheel_vehicle : int
        Vehicle (0 at the head), -1 when none.
    block_time_s, wheel_time_s : float
        When [s].
    ambient_K : float
        Air temperature, where every block and wheel started [K].
    """

    block_K: float = math.nan
    block_vehicle: int = -1
    block_time_s: float = math.nan
    wheel_K: float = math.nan
    wheel_vehicle: int = -1
    wheel_time_s: float = math.nan
    ambient_K: float = math.nan

    @classmethod
    def from_arrays(cls, block_K, block_time_s, wheel_K, wheel_time_s,
                    ambient_K: float) -> "Peaks":
        """Summarise per-vehicle peaks [K] and their times [s] (NaN: not modelled)."""
        out = {}
        for name, temp, when in (("block", block_K, block_time_s),
                                 ("wheel", wheel_K, wheel_time_s)):
            temp = np.asarray(temp, float)
            if temp.size and np.isfinite(temp).any():
                i = int(np.nanargmax(temp))
                out.update({f"{name}_K": float(temp[i]), f"{name}_vehicle": i,
                            f"{name}_time_s": float(np.asarray(when, float)[i])})
        return cls(**out, ambient_K=float(ambient_K))

    def as_dict(self) -> dict:
        """JSON-serialisable, flat keys with units (None where there is no block brake), and
        ``heat_model``: :data:`VALIDATION`."""
        def num(x):
            return x if math.isfinite(x) else None
        return {"peak_block_temperature_K": num(self.block_K),
                "peak_block_temperature_vehicle": None if self.block_vehicle < 0
                else self.block_vehicle,
                "peak_block_temperature_time_s": num(self.block_time_s),
                "peak_wheel_temperature_K": num(self.wheel_K),
                "peak_wheel_temperature_vehicle": None if self.wheel_vehicle < 0
                else self.wheel_vehicle,
                "peak_wheel_temperature_time_s": num(self.wheel_time_s),
                "ambient_temperature_K": num(self.ambient_K),
                "heat_model": VALIDATION}

    def describe(self) -> str:
        """One line: the hottest blocks and wheel (in C), which vehicle, when; the model
        :data:`VALIDATION`."""
        if self.block_vehicle < 0:
            return "no vehicle with block brakes"
        return (f"blocks {self.block_K - 273.15:.0f} C at vehicle {self.block_vehicle} "
                f"(t = {self.block_time_s:.1f} s), wheels {self.wheel_K - 273.15:.0f} C at "
                f"vehicle {self.wheel_vehicle} (t = {self.wheel_time_s:.1f} s); air "
                f"{self.ambient_K - 273.15:.0f} C; heat model {VALIDATION}")

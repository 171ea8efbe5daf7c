"""Friction between blocks (or pads) and wheels: Eq. 4 inverted, Eq. 8-10.

The per-vehicle friction arrays are compiled here, once, for every user (the simulator and the
reference solver): brake kind, blocks, arrangement, disc friction and the full block force that
Eq. 4 gives for each vehicle's braked weight. Every brake model drives the block force; this
module turns it into the retarding force at the wheels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..constants import G, KMH_PER_MS
from ..equations import jit, jit_inline, jit_vector
from ..parameters import Fittable, parameter
from . import adhesion as adhesion_module
from .base import CompileError

#: Brake kinds in the compiled arrays.
BRAKE_NONE, BRAKE_BLOCKS, BRAKE_DISC = 0, 1, 2
#: Block arrangements in the compiled arrays.
ARR_BG, ARR_BGU = 0, 1

# Published P10 fit for Bgu blocks, mu = e^{-0.017 F}(0.18 - 0.09 e^{-V/25.7})
# + 0.381 e^{-V/25.7} - 0.022 (F in kN, V in km/h), averaged over 0-100 km/h:
# mean = e^{-0.017 F} * _BGU_A + _BGU_B.
_EXP_MEAN = 25.7 / 100.0 * (1.0 - math.exp(-100.0 / 25.7))
_BGU_A = 0.18 - 0.09 * _EXP_MEAN
_BGU_B = 0.381 * _EXP_MEAN - 0.022


@dataclass(frozen=True)
class Params:
    """Friction parameters shared by every brake model (Eq. 4, 8-10).

    Attributes
    ----------
    k0 : float
        Scale of the reconstructed UIC 544-1 k factor of cast-iron blocks [-].
    k_loco : float
        Constant k factor of Eq. 4 for disc-braked locomotives [-].
    mu_eff : float
        Effective disc friction coefficient of Eq. 10 [-].
    """

    k0: float = parameter(2.72, "scale of the UIC 544-1 k factor for cast-iron blocks "
                          "(reconstructed) [-]", lo=0.0, lo_open=True, hi=100.0)
    k_loco: float = parameter(3.54, "constant k factor of Eq. 4 for disc-braked locomotives [-]",
                              lo=0.0, lo_open=True, hi=100.0)
    mu_eff: float = parameter(0.264, "effective disc friction coefficient of Eq. 10 [-]",
                              lo=0.0, lo_open=True, hi=1.0)


#: Parameters calibration may fit, by short name.
FITTABLE = {
    # k0 > 0; the lower bound only keeps the block forces finite
    "k0": Fittable("k0", "-", 0.01, 100.0, 2.7,
                   "scale of the UIC 544-1 k factor of cast-iron blocks"),
    "k_loco": Fittable("k_loco", "-", 0.01, 100.0, 3.5,
                       "constant k factor of the disc-braked locomotive (Eq. 4)"),
    "mu_eff": Fittable("mu_eff", "-", 0.01, 1.0, 0.25,
                       "effective disc friction coefficient of the locomotive (Eq. 10)"),
}


class FrictionArrays(NamedTuple):
    """Per-vehicle friction data of one train: built once by :func:`compile`, never mutated.

    Attributes
    ----------
    kind : ndarray of int
        ``BRAKE_NONE``, ``BRAKE_BLOCKS`` or ``BRAKE_DISC``.
    blocks : ndarray
        Number of blocks (1 where there are none).
    arrangement : ndarray of int
        ``ARR_BG`` or ``ARR_BGU``.
    mu_disc : ndarray
        Disc friction coefficient (0 where there is no disc brake).
    force_max_N : ndarray
        Full block force, 1000 * sum(F_dyn) from Eq. 4 for the braked weight [N].
    full_scale_N : ndarray
        :func:`force_scale` at the full block force: the retarding force per unit of
        Karwatzki's speed factor (blocks) or the disc brake force of a fully applied brake [N]
        (0 where there is no brake).
    weight_N : ndarray
        m g of each vehicle [N].
    adhesion : ndarray, shape (2, k)
        The rail's available adhesion, speed [m/s] and mu [-] (:mod:`.adhesion`); k = 0: the
        brake force is not capped (no wheel slide).
    sliding_ratio : float
        Sliding friction of a locked wheelset over the available adhesion [-]
        (:mod:`.wheel_slide`).
    """

    kind: np.ndarray
    blocks: np.ndarray
    arrangement: np.ndarray
    mu_disc: np.ndarray
    force_max_N: np.ndarray
    full_scale_N: np.ndarray
    weight_N: np.ndarray
    adhesion: np.ndarray
    sliding_ratio: float


def compile(consist, params: Params, adhesion=None) -> FrictionArrays:  # noqa: A001
    """Per-vehicle friction arrays of a train.

    Parameters
    ----------
    consist : Consist
        The train; each vehicle's ``brake`` is a block brake (``type == "blocks"``), a disc
        brake (``type == "disc"``) or ``None``.
    params : Params
        k-factor scale and the locomotives' defaults.
    adhesion : AdhesionCondition, optional
        The rail's adhesion condition (:mod:`.adhesion`; default: off, no wheel slide).

    Returns
    -------
    FrictionArrays

    Raises
    ------
    CompileError
        Eq. 4 cannot be inverted for a vehicle's braked weight.
    """
    n = len(consist.vehicles)
    kind = np.zeros(n, np.int64)
    blocks = np.ones(n)
    arrangement = np.zeros(n, np.int64)
    mu_disc = np.zeros(n)
    force_max = np.zeros(n)
    for i, v in enumerate(consist.vehicles):
        b = v.brake
        brake_type = getattr(b, "type", "none")
        if brake_type == "blocks":
            kind[i] = BRAKE_BLOCKS
            blocks[i] = b.blocks
            arrangement[i] = ARR_BGU if b.arrangement == "Bgu" else ARR_BG
            s = sum_block_force_kN(v.braked_weight_t, float(b.blocks), params.k0,
                                   int(arrangement[i]))
            if not math.isfinite(s):
                raise CompileError(f"vehicles[{i}].brake",
                                   "Eq. 4 could not be inverted for this braked weight")
            force_max[i] = 1000.0 * s
        elif brake_type == "disc":
            kind[i] = BRAKE_DISC
            mu_disc[i] = b.mu_eff if b.mu_eff is not None else params.mu_eff
            k = b.k if b.k is not None else params.k_loco
            force_max[i] = 1000.0 * v.braked_weight_t * 9.81 / k
    full_scale = np.array([force_scale(kind[i], blocks[i], arrangement[i], mu_disc[i],
                                       force_max[i]) for i in range(n)], float)
    weight = np.array([v.mass_kg for v in consist.vehicles], float) * G
    cond = adhesion if adhesion is not None else adhesion_module.OFF
    return FrictionArrays(kind, blocks, arrangement, mu_disc, force_max, full_scale, weight,
                          np.ascontiguousarray(cond.table, dtype=float),
                          float(cond.sliding_ratio))


@jit_inline
def force_scale(kind, blocks, arrangement, mu_disc, block_force_N):
    """Retarding force per unit of Karwatzki's speed factor (blocks), or the disc brake force,
    of one vehicle for a block force held over a step [N] (Eq. 8-10).

    Parameters are the vehicle's entries of :class:`FrictionArrays` and its block force [N].
    """
    if kind == BRAKE_BLOCKS:
        # Karwatzki's block-force factor is fixed within the step (Eq. 9)
        return block_force_N * block_force_factor(block_force_N / (1000.0 * blocks), arrangement)
    if kind == BRAKE_DISC:
        return mu_disc * block_force_N
    return 0.0


@jit_vector
def force_scales(kind, blocks, arrangement, mu_disc, block_force_N, out):
    """:func:`force_scale` of every vehicle (into ``out``), the same values.

    The Bg blocks' factor (Eq. 9), three dependent divisions per vehicle, is computed for
    every vehicle in one loop without branches, which the compiler vectorises (IEEE division
    gives the same result whether scalar or not; the divisors are never zero: at least one
    block); the other kinds then overwrite theirs.

    Parameters
    ----------
    kind, blocks, arrangement, mu_disc : ndarray
        The train's :class:`FrictionArrays` entries.
    block_force_N : ndarray
        Block force of each vehicle held over the step [N].
    out : ndarray
        Out: retarding force per unit of Karwatzki's speed factor (blocks) or the disc brake
        force [N].
    """
    n = block_force_N.shape[0]
    for i in range(n):
        f = block_force_N[i]
        f_t = f / (1000.0 * blocks[i]) / G
        out[i] = f * ((16.0 * f_t + 100.0) / (80.0 * f_t + 100.0))
    for i in range(n):
        if kind[i] != BRAKE_BLOCKS or arrangement[i] != ARR_BG:
            out[i] = force_scale(kind[i], blocks[i], arrangement[i], mu_disc[i],
                                 block_force_N[i])


@jit_inline
def retarding_force(kind, speed_m_s, scale):
    """Retarding force of one vehicle [N] and its derivative [N/(m/s)] at a speed magnitude.

    ``kind`` is the vehicle's brake kind, ``scale`` comes from :func:`force_scale`.
    """
    if kind == BRAKE_BLOCKS:
        f, df = karwatzki_speed_factor(speed_m_s)
        return f * scale, df * scale
    return scale, 0.0


# --------------------------------------------------------------------------- equations


@jit
def block_force_factor(block_force_kN, arrangement):
    """Block-force dependence of cast-iron friction and of the UIC k factor (phi(0) = 1).

    Bg: the force factor of Karwatzki's law (Eq. 9). Bgu: mean over 0-100 km/h of a published
    P10 fit for Bgu blocks, normalised at zero force (shape only, confidence M).

    Parameters
    ----------
    block_force_kN : float
        Force on one block [kN].
    arrangement : int
        ``ARR_BG`` or ``ARR_BGU``.

    Returns
    -------
    float
    """
    if arrangement == ARR_BGU:
        return (_BGU_A * math.exp(-0.017 * block_force_kN) + _BGU_B) / (_BGU_A + _BGU_B)
    f_t = block_force_kN / G
    return (16.0 * f_t + 100.0) / (80.0 * f_t + 100.0)


@jit
def karwatzki_mu(speed_kmh, block_force_kN):
    """Friction coefficient of P10 cast-iron blocks, Karwatzki's law (Eq. 9).

    Parameters
    ----------
    speed_kmh : float
        Running speed [km/h].
    block_force_kN : float
        Force on one block [kN].

    Returns
    -------
    float
        mu_B [-]; e.g. 0.0864 at 30 kN and 100 km/h.
    """
    return 0.6 * (speed_kmh + 100.0) / (5.0 * speed_kmh + 100.0) * block_force_factor(
        block_force_kN, ARR_BG)


@jit
def karwatzki_speed_factor(speed_m_s):
    """Speed part of Karwatzki's law, 0.6 (V+100)/(5V+100), and its derivative.

    Parameters
    ----------
    speed_m_s : float
        Speed magnitude [m/s].

    Returns
    -------
    factor : float
    dfactor_dspeed : float
        [1/(m/s)].
    """
    v = KMH_PER_MS * speed_m_s
    inv = 1.0 / (5.0 * v + 100.0)
    return 0.6 * (v + 100.0) * inv, -240.0 * inv * inv * KMH_PER_MS


@jit
def block_mu(speed_m_s, block_force_kN, arrangement):
    """Cast-iron friction coefficient for a block arrangement, and d(mu)/d(speed).

    Parameters
    ----------
    speed_m_s : float
        Speed magnitude [m/s].
    block_force_kN : float
        Force on one block [kN].
    arrangement : int
        ``ARR_BG`` or ``ARR_BGU``.

    Returns
    -------
    mu : float
    dmu_dspeed : float
        [1/(m/s)].
    """
    phi = block_force_factor(block_force_kN, arrangement)
    f, df = karwatzki_speed_factor(speed_m_s)
    return f * phi, df * phi


@jit
def k_factor(block_force_kN, k0, arrangement):
    """UIC 544-1 k factor of cast-iron blocks (Fig. 1), reconstructed as k0 * phi(F).

    Parameters
    ----------
    block_force_kN : float
        Force on one block [kN].
    k0 : float
        Scale (the k factor at vanishing block force).
    arrangement : int
        ``ARR_BG`` or ``ARR_BGU``.

    Returns
    -------
    float
    """
    return k0 * block_force_factor(block_force_kN, arrangement)


@jit
def braked_weight_t(sum_block_force_kN, blocks, k0, arrangement):
    """Braked weight from the sum of block forces, Eq. 4: B = k * sum(F) / g.

    Parameters
    ----------
    sum_block_force_kN : float
        Sum of all block forces [kN].
    blocks : float
        Number of blocks.
    k0 : float
        k-factor scale.
    arrangement : int
        ``ARR_BG`` or ``ARR_BGU``.

    Returns
    -------
    float
        Braked weight [t].
    """
    return k_factor(sum_block_force_kN / blocks, k0, arrangement) * sum_block_force_kN / G


@jit
def sum_block_force_kN(braked_weight, blocks, k0, arrangement):
    """Invert Eq. 4 for the sum of block forces by Newton's method.

    Parameters
    ----------
    braked_weight : float
        Braked weight [t].
    blocks : float
        Number of blocks.
    k0 : float
        k-factor scale.
    arrangement : int
        ``ARR_BG`` or ``ARR_BGU``.

    Returns
    -------
    float
        Sum of all block forces [kN]; NaN if the iteration does not converge.
    """
    target = braked_weight
    s = braked_weight * G / k0  # k = k0 at zero force: a lower bound of the solution
    for _ in range(100):
        r = braked_weight_t(s, blocks, k0, arrangement) - target
        ds = 1e-6 * max(s, 1.0)
        dr = (braked_weight_t(s + ds, blocks, k0, arrangement) - target - r) / ds
        step = r / dr
        s -= step
        if s <= 0.0:
            s = 1e-9
        if abs(step) <= 1e-12 * s:
            return s
    return math.nan

"""Equations of the model, one function each (no ROS, no state).

Scalar functions are compiled with numba so that the integration kernel and the reference
right-hand side share them; they run as plain Python where numba is absent. Units are SI unless
the name says otherwise (``_kmh``, ``_kN``, ``_t``).
"""
from __future__ import annotations

import math

import numpy as np

try:  # pragma: no cover - exercised implicitly
    from numba import njit

    def jit(fn):
        """Compile ``fn`` with numba (cached on disk)."""
        return njit(cache=True, nogil=True)(fn)

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - fallback keeps the package usable, only slower
    def jit(fn):
        """No-op stand-in for the numba decorator."""
        return fn

    HAVE_NUMBA = False

from .constants import G, KMH_PER_MS  # noqa: F401 (re-exported)

# Published P10 fit for Bgu blocks, mu = e^{-0.017 F}(0.18 - 0.09 e^{-V/25.7})
# + 0.381 e^{-V/25.7} - 0.022 (F in kN, V in km/h), averaged over 0-100 km/h:
# mean = e^{-0.017 F} * _BGU_A + _BGU_B.
_EXP_MEAN = 25.7 / 100.0 * (1.0 - math.exp(-100.0 / 25.7))
_BGU_A = 0.18 - 0.09 * _EXP_MEAN
_BGU_B = 0.381 * _EXP_MEAN - 0.022

#: Brake kinds in the compiled arrays.
BRAKE_NONE, BRAKE_BLOCKS, BRAKE_DISC = 0, 1, 2
#: Block arrangements in the compiled arrays.
ARR_BG, ARR_BGU = 0, 1


@jit
def resistance_coefficients(mass_kg, axles):
    """Coefficients of Eq. 2 written as F = a0 + a1*V + a2*V^2 (V in km/h).

    Parameters
    ----------
    mass_kg : float
        Weight on rails [kg].
    axles : float
        Number of axles.

    Returns
    -------
    a0 : float
        [N].
    a1 : float
        [N/(km/h)].
    a2 : float
        [N/(km/h)^2].
    """
    q_ax = mass_kg / 1000.0 / axles
    m_t = mass_kg / 1000.0
    return m_t * (2.943 + 89.2 / q_ax), m_t * 0.0306, m_t * 0.122 / (q_ax * axles)


@jit
def resistance_N(mass_kg, axles, speed_m_s):
    """Running resistance, Eq. 2, and its derivative.

    F = M/1000 * (2.943 + 89.2/Q_ax + 0.0306 V + 0.122 V^2 / (Q_ax N_ax)), Q_ax in t, V in km/h.

    Parameters
    ----------
    mass_kg : float
        Weight on rails [kg].
    axles : float
        Number of axles.
    speed_m_s : float
        Speed magnitude [m/s] (>= 0).

    Returns
    -------
    force_N : float
        Resistance magnitude [N].
    dforce_dspeed : float
        Derivative with respect to speed [N/(m/s)].
    """
    a0, a1, a2 = resistance_coefficients(mass_kg, axles)
    v_kmh = KMH_PER_MS * speed_m_s
    return a0 + (a1 + a2 * v_kmh) * v_kmh, (a1 + 2.0 * a2 * v_kmh) * KMH_PER_MS


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
    den = 5.0 * v + 100.0
    return 0.6 * (v + 100.0) / den, -240.0 / (den * den) * KMH_PER_MS


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


@jit
def lut_segment(xs, x):
    """Index k of the LUT segment [xs[k], xs[k+1]] holding x; -1 below, len-1 above."""
    n = xs.shape[0]
    if x < xs[0]:
        return -1
    if x >= xs[n - 1]:
        return n - 1
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@jit
def coupler_force(defl_m, rate_m_s, xs, f_load, f_unload, v_th):
    """Coupler force with hysteresis, Eq. 3, and its partial derivatives.

    F = (F_L + F_U)/2 + |F_L - F_U|/2 * clip(rate / v_th, -1, 1), linear interpolation in the
    LUT and extrapolation with the end slopes.

    Parameters
    ----------
    defl_m : float
        Deflection x_front - x_rear, draft positive [m].
    rate_m_s : float
        Deflection speed [m/s].
    xs, f_load, f_unload : ndarray
        LUT deflections [m] and loading/unloading forces [N].
    v_th : float
        Threshold speed [m/s].

    Returns
    -------
    force_N : float
        Draft positive [N].
    dforce_ddefl : float
        [N/m].
    dforce_drate : float
        [N/(m/s)].
    segment : int
        LUT segment (see :func:`lut_segment`).
    band : int
        -1 unloading/loading below the band, 0 inside |rate| <= v_th, +1 above.
    """
    seg = lut_segment(xs, defl_m)
    n = xs.shape[0]
    k = min(max(seg, 0), n - 2)
    dx = xs[k + 1] - xs[k]
    sl = (f_load[k + 1] - f_load[k]) / dx
    su = (f_unload[k + 1] - f_unload[k]) / dx
    fl = f_load[k] + sl * (defl_m - xs[k])
    fu = f_unload[k] + su * (defl_m - xs[k])
    diff = fl - fu
    r = rate_m_s / v_th
    if r > 1.0:
        c, band = 1.0, 1
    elif r < -1.0:
        c, band = -1.0, -1
    else:
        c, band = r, 0
    sgn = 1.0 if diff >= 0.0 else -1.0
    force = 0.5 * (fl + fu) + 0.5 * abs(diff) * c
    dfd = 0.5 * (sl + su) + 0.5 * sgn * (sl - su) * c
    dfr = 0.5 * abs(diff) / v_th if band == 0 else 0.0
    return force, dfd, dfr, seg, band


@jit
def curve_resistance_N_per_kN(radius_m):
    """Curve resistance per unit weight, Roeckl's formula for standard gauge.

    r = 650 / (R - 55) for R >= 300 m, 500 / (R - 30) for R < 300 m [N/kN]; 0 on straight
    track (R = 0).

    Parameters
    ----------
    radius_m : float
        Curve radius [m] (0 = straight).

    Returns
    -------
    float
        [N/kN], numerically the same as per mille of equivalent gradient.
    """
    if radius_m <= 0.0:
        return 0.0
    if radius_m >= 300.0:
        return 650.0 / (radius_m - 55.0)
    return 500.0 / (radius_m - 30.0)


def k_uic(train_length_m: float) -> float:
    """Length correction of the braked-weight percentage (Eq. 11).

    1 up to 500 m; 0.95 for 501-600 m; 0.90 above 600 m (a national operating rule for trains
    braked in P, confidence M).

    Parameters
    ----------
    train_length_m : float

    Returns
    -------
    float
    """
    if train_length_m <= 500.0:
        return 1.0
    return 0.95 if train_length_m <= 600.0 else 0.90


def train_braked_weight_percent(braked_weights_t, masses_t, train_length_m: float) -> float:
    """Train braked-weight percentage lambda, Eq. 11.

    Parameters
    ----------
    braked_weights_t : array_like
        Braked weight of every vehicle [t] (0 for unbraked ones).
    masses_t : array_like
        Weight on rails of every vehicle [t].
    train_length_m : float
        Length over buffers [m].

    Returns
    -------
    float
        lambda [%].
    """
    return k_uic(train_length_m) * float(np.sum(braked_weights_t)) / float(np.sum(masses_t)) * 100.0

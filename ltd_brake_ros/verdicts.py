"""Verdicts on a run: coupler strength and travel, endurable compressive force, adhesion.

One table, one row per criterion. Each criterion states what it assesses, over which part of
the run (its scope) and by what source; its status is PASS, its severity when a limit is
exceeded (FAIL, WARN or INFO), or ``not assessed``, and it names every coupler or vehicle
beyond its limit (by how much, when, at what speed):

======================  ==========  ======================================================
``draft_strength``      FAIL        each coupler's draft force against the breaking load of
                                    the draw gear (all speeds)
``buff_strength``       FAIL        each coupler's buff force against the compressive
                                    strength of the vehicle ends (all speeds)
``endurable_lcf``       FAIL        buff force against the endurable longitudinal compressive
                                    force of the two vehicles (EN 15839); not assessed unless
                                    a consist gives one
``coupler_travel``      FAIL        each coupler's deflection against the coupler model's
                                    travel (a buffer's solid end, a table's last point):
                                    beyond it the forces are not physical and the run is
                                    marked so
``adhesion``            FAIL        each vehicle's mean utilised adhesion over the braked
                                    part of a stop from 100 km/h or more (full application
                                    to 5 km/h) against its limit, 0.12 for a vehicle without
                                    wheel-slide protection
``adhesion_at_speed``   WARN        each vehicle's instantaneous adhesion demand above
                                    30 km/h against 0.15
``adhesion_low_speed``  INFO        the largest instantaneous demand below 30 km/h (never a
                                    failure: block friction peaks as the wheels slow down;
                                    noted where it exceeds a wet rail's adhesion)
``standstill_holding``  FAIL        after the stop, the force each vehicle must hold (coupler
                                    forces, grade) against what its brake holds at rest
======================  ==========  ======================================================

Adhesion demand is the air brake's retarding force over the vehicle's weight, m g; its mean
over a stop (EN 14531-1's mean-value calculation) subtracts what decelerates the rotating
masses, ((rho - 1) M a), and weights by distance: the brake's work at the rails over the
distance run while the brake is fully applied (:data:`~.physics.kernel.FULL_APPLICATION`) and
the vehicle runs at 5 km/h or faster. The kinetic brake force is never evaluated at rest: a
stopped, braked wheel holds, it demands no sliding adhesion.

Limits of coupler j (joining vehicles j - 1 and j, vehicles numbered from 0 at the head): the
smaller of the two vehicles' ``limits`` in the consist file, else the coupler model's
(``draft_strength_kN``/``buff_strength_kN`` of the coupler file), else the defaults below.
Every default names its source and whether its value was verified in the source's text.

The simulator (:class:`Watch`) raises an event when a limit is first exceeded; ``ltd-brake
simulate``, the run report (:func:`judge` on recorded samples), the campaign flags
(:func:`flags`) and the plant's diagnostics (:func:`diagnostic_values`) use this module alike.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .physics.brakes import friction
from .physics.constants import G, KMH_PER_MS
from .physics.equations import jit
from .physics.kernel import FULL_APPLICATION, MEAN_ADHESION_MIN_SPEED_M_S

__all__ = ["ADHESION_AT_SPEED_LIMIT", "ADHESION_LIMIT", "ADHESION_LIMIT_WSP",
           "ADHESION_SPEED_KMH", "BUFF_STRENGTH_N", "CRITERIA", "DRAFT_STRENGTH_N",
           "MEAN_ADHESION_MIN_INITIAL_KMH", "Criterion", "Exceedance", "Rule", "TrainLimits",
           "Verdicts", "Watch", "default_coupler_limits", "diagnostic_values", "flags", "judge",
           "limits_from_metadata", "limits_metadata", "SampledDemand", "VehicleDemand",
           "train_limits", "wet_rail_adhesion"]

#: Default draft strength of a coupling [N]: the minimum breaking load of the standard screw
#: coupling, 850 kN (UIC 520/826 as summarised by secondary sources; not verified in the
#: standard's text), below EN 15566's lowest draw-gear category, 1.0 MN (verified in the
#: standard's summary): the weaker part breaks.
DRAFT_STRENGTH_N = 850e3
#: Default buff strength of a coupling [N]: the longitudinal compressive proof load of a
#: freight wagon body at buffer height, 2000 kN (EN 12663-2; the value and its category name
#: are not verified in the standard's text).
BUFF_STRENGTH_N = 2000e3
#: Default limit of the mean utilised adhesion of a vehicle without wheel-slide protection
#: [-]: 0.12, the demand above which freight wagons with tread brakes need wheel-slide
#: protection (WAG TSI, Regulation (EU) 321/2013, as summarised; not verified in its text),
#: judged on the mean of a braking calculation (EN 14531-1, secondary source).
ADHESION_LIMIT = 0.12
#: Default limit of the mean utilised adhesion of a vehicle with wheel-slide protection [-]:
#: 0.15, the adhesion a braking calculation may assume (TSI LOC&PAS, Regulation (EU)
#: 1302/2014, 4.2.4.6.1, for locomotives and passenger stock: an analogy for wagons; not
#: verified in its text).
ADHESION_LIMIT_WSP = 0.15
#: Instantaneous adhesion demand that earns a warning above :data:`ADHESION_SPEED_KMH` [-]
#: (the same TSI LOC&PAS value, not verified in its text).
ADHESION_AT_SPEED_LIMIT = 0.15
#: Speed below which the instantaneous demand is information only [km/h]: cast-iron block
#: friction (Karwatzki, Eq. 8) rises steeply at low speed, where a stop's braked part ends.
ADHESION_SPEED_KMH = 30.0
#: Mean utilised adhesion is judged on stops from this speed or faster [km/h]: mean-value
#: brake calculations start from the reference speeds of the braked weight, 100 and 120 km/h
#: (UIC 544-1); a stop from lower speeds runs on the steep low-speed part of the block
#: friction and says nothing of the brake's design (its mean is shown, not judged).
MEAN_ADHESION_MIN_INITIAL_KMH = 100.0
#: Least distance of the braked part for a mean to be computed [m].
MEAN_ADHESION_MIN_DISTANCE_M = 1.0
#: Sampled vehicles this slow are at rest: no adhesion demand is taken from them [m/s]
#: (the simulator's standstill speed).
STANDSTILL_SAMPLE_M_S = 1e-3
#: Wet-rail adhesion as a fraction of dry (Koffman 1948, secondary source: ~0.6).
WET_RAIL_FACTOR = 0.6


def wet_rail_adhesion(speed_kmh):
    """Available adhesion on a wet rail [-]: Curtius-Kniffler's dry curve x 0.6.

    mu = 0.6 (7.5 / (v + 44) + 0.161), v in km/h (Curtius-Kniffler, a traction curve quoted by
    secondary sources; wet/dry ratio after Koffman 1948, secondary source). Used only to
    annotate the low-speed demand; about 0.20 at rest, 0.15 at 30 km/h.

    Parameters
    ----------
    speed_kmh : float or ndarray
        Speed [km/h].

    Returns
    -------
    float or ndarray
    """
    return WET_RAIL_FACTOR * (7.5 / (np.asarray(speed_kmh, float) + 44.0) + 0.161)


class Rule(NamedTuple):
    """What a criterion assesses.

    Attributes
    ----------
    title : str
    quantity : str
        What is compared with the limit.
    element : str
        ``coupler`` (numbered from 1 behind the head) or ``vehicle`` (from 0 at the head).
    unit : str
        ``kN``, ``mm`` or ``-``.
    severity : str
        Status when a limit is exceeded: ``FAIL``, ``WARN`` or ``INFO``.
    scope : str
        The part of the run and the vehicles the criterion applies to.
    """

    title: str
    quantity: str
    element: str
    unit: str
    severity: str
    scope: str


#: Criteria in table order.
CRITERIA = {
    "draft_strength": Rule("Coupler draft strength", "draft force", "coupler", "kN", "FAIL",
                           "every coupler, all speeds"),
    "buff_strength": Rule("Coupler buff strength", "buff force", "coupler", "kN", "FAIL",
                          "every coupler, all speeds"),
    "endurable_lcf": Rule("Endurable longitudinal compressive force", "buff force", "coupler",
                          "kN", "FAIL", "couplers of vehicles that give one, all speeds"),
    "coupler_travel": Rule("Within the coupler's travel", "deflection beyond the travel",
                           "coupler", "mm", "FAIL", "every coupler, all speeds"),
    "adhesion": Rule("Mean utilised adhesion", "mean brake force at the rails / weight",
                     "vehicle", "-", "FAIL",
                     f"braked vehicles, stops from {MEAN_ADHESION_MIN_INITIAL_KMH:.0f} km/h or "
                     "more, from full application to 5 km/h"),
    "adhesion_at_speed": Rule("Adhesion demand at speed", "brake force / weight", "vehicle",
                              "-", "WARN", f"braked vehicles above {ADHESION_SPEED_KMH:.0f} km/h"),
    "adhesion_low_speed": Rule("Adhesion demand at low speed", "brake force / weight",
                               "vehicle", "-", "INFO",
                               f"braked vehicles below {ADHESION_SPEED_KMH:.0f} km/h, moving"),
    "standstill_holding": Rule("Holding at rest", "force to hold (couplers, grade)", "vehicle",
                               "kN", "FAIL", "every vehicle after the train has stopped"),
}
_DEFAULT_ORIGIN = {
    "draft_strength": "default 850 kN: screw coupling breaking load (UIC 520/826 via secondary "
                      "sources, not verified; EN 15566 draw-gear categories 1.0/1.2/1.5 MN)",
    "buff_strength": "default 2000 kN: wagon body compressive proof load (EN 12663-2, not "
                     "verified in its text)",
    "endurable_lcf": "not given (EN 15839: a property of each vehicle; set limits."
                     "endurable_lcf_kN in the consist)",
    "adhesion": "default 0.12 without wheel-slide protection (WAG TSI, Reg. 321/2013, not "
                "verified in its text), 0.15 with it (TSI LOC&PAS 4.2.4.6.1, not verified); "
                "mean of a braking calculation (EN 14531-1)",
    "adhesion_at_speed": "0.15: adhesion a braking calculation may assume (TSI LOC&PAS "
                         "4.2.4.6.1, locomotives and passenger stock; not verified in its text)",
    "adhesion_low_speed": "information: a wet rail's adhesion, Curtius-Kniffler x 0.6 "
                          "(secondary sources), never a failure",
    "coupler_travel": "the coupler model's valid range",
    "standstill_holding": "what a vehicle at rest holds: its kinetic brake force at rest, or "
                          "with the brake applied 0.30 m g at full application (dry-rail "
                          "adhesion at rest, secondary sources; the clamped brake assumed to "
                          "hold the wheel)",
}


@dataclass(frozen=True)
class TrainLimits:
    """The limits of one train, per coupler and per vehicle.

    Attributes
    ----------
    draft_strength_N, buff_strength_N : ndarray
        Per coupler (coupler 1 first), magnitudes [N].
    endurable_lcf_N : ndarray
        Per coupler, magnitude [N]; inf where no vehicle gives one (not assessed).
    adhesion_limit : ndarray
        Limit of each vehicle's mean utilised adhesion, head first [-].
    weight_N : ndarray
        Per vehicle, m g [N].
    origin : dict of str to str
        Where each criterion's limits come from.
    braked : ndarray of bool
        Per vehicle: it has an air brake (unbraked vehicles demand no adhesion).
    blocks : ndarray of bool
        Per vehicle: its brake is a block (tread) brake, whose force follows Karwatzki's speed
        factor.
    full_scale_N : ndarray
        Per vehicle, the retarding-force scale of a fully applied brake
        (:attr:`~.physics.brakes.friction.FrictionArrays.full_scale_N`) [N]; 0 where unknown.
    rotating_mass_kg : ndarray
        Per vehicle, (rho - 1) M [kg].
    travel_mm : tuple of float
        The coupler model's valid deflections, (buff end, draft end) [mm] (inf: unbounded).
    """

    draft_strength_N: np.ndarray
    buff_strength_N: np.ndarray
    endurable_lcf_N: np.ndarray
    adhesion_limit: np.ndarray
    weight_N: np.ndarray
    origin: dict = field(default_factory=dict)
    braked: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    blocks: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    full_scale_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rotating_mass_kg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    travel_mm: tuple = (-math.inf, math.inf)

    def of(self, criterion: str) -> np.ndarray:
        """The per-coupler or per-vehicle limits of a criterion."""
        n = self.adhesion_limit.size
        return {"draft_strength": self.draft_strength_N, "buff_strength": self.buff_strength_N,
                "endurable_lcf": self.endurable_lcf_N, "adhesion": self.adhesion_limit,
                "coupler_travel": np.zeros(self.draft_strength_N.size),
                "adhesion_at_speed": np.full(n, ADHESION_AT_SPEED_LIMIT),
                "adhesion_low_speed": np.full(n, math.inf),
                "standstill_holding": np.full(n, math.inf)}[criterion]


def _coupler_limit(per_vehicle: list, model_value: float, default: float):
    """Per-coupler limit: smaller of the two vehicles' values, else the model's, else default."""
    out, origins = [], set()
    for a, b in zip(per_vehicle[:-1], per_vehicle[1:]):
        given = [x for x in (a, b) if x is not None]
        if given:
            out.append(min(given))
            origins.add("consist")
        elif math.isfinite(model_value):
            out.append(model_value)
            origins.add("coupler file")
        else:
            out.append(default)
            origins.add("default")
    return np.array(out, float), origins


def _origin_text(criterion: str, origins: set) -> str:
    parts = []
    if "consist" in origins:
        parts.append("consist limits")
    if "coupler file" in origins:
        parts.append("coupler file")
    if "default" in origins:
        parts.append(_DEFAULT_ORIGIN[criterion])
    return "; ".join(parts) or "no coupler"


def train_limits(consist, coupler_params=None, *, adhesion_limit: float | None = None,
                 friction_arrays=None, coupler_arrays=None) -> TrainLimits:
    """The limits of a train: consist ``limits``, the coupler model's, the defaults.

    Parameters
    ----------
    consist : Consist
    coupler_params : dataclass, optional
        A coupler model's ``Params`` (its ``draft_strength_N``/``buff_strength_N``, inf when
        unknown).
    adhesion_limit : float, optional
        Mean-adhesion limit of every vehicle whose consist entry gives none (default:
        :data:`ADHESION_LIMIT`, or :data:`ADHESION_LIMIT_WSP` for a vehicle with wheel-slide
        protection).
    friction_arrays : FrictionArrays, optional
        The train's compiled friction law: the full retarding-force scale of each brake, which
        a recording's report needs to find the braked part of a stop.
    coupler_arrays : CouplerArrays, optional
        The compiled coupler model: its valid range, the travel the couplers are judged by.

    Returns
    -------
    TrainLimits
    """
    lims = [v.limits for v in consist.vehicles]
    draft, o_draft = _coupler_limit([x.draft_strength_N for x in lims],
                                    float(getattr(coupler_params, "draft_strength_N", math.inf)),
                                    DRAFT_STRENGTH_N)
    buff, o_buff = _coupler_limit([x.buff_strength_N for x in lims],
                                  float(getattr(coupler_params, "buff_strength_N", math.inf)),
                                  BUFF_STRENGTH_N)
    lcf, o_lcf = _coupler_limit([x.endurable_lcf_N for x in lims], math.inf, math.inf)

    def default(x):
        if adhesion_limit is not None:
            return float(adhesion_limit)
        return ADHESION_LIMIT_WSP if getattr(x, "wheel_slide_protection", False) \
            else ADHESION_LIMIT
    adhesion = np.array([default(x) if x.adhesion_limit is None else x.adhesion_limit
                         for x in lims], float)
    o_adh = {"consist" if x.adhesion_limit is not None else "default" for x in lims}
    travel = (-math.inf, math.inf)
    o_travel = "no coupler"
    if coupler_arrays is not None:
        travel = (float(coupler_arrays.valid_lo_m) * 1e3, float(coupler_arrays.valid_hi_m) * 1e3)
        end = getattr(coupler_params, "solid_end_force_N", None)
        o_travel = (f"buffers' solid end and draw gear's stroke, {travel[0]:.0f} to "
                    f"{travel[1]:.0f} mm (beyond: the body's stiffness, forces not physical)"
                    if end is not None else
                    f"the coupler characteristic's valid range, {travel[0]:.0f} to "
                    f"{travel[1]:.0f} mm (beyond: the buffers solid or the curves "
                    "extrapolated, forces not physical)")
    origin = {"draft_strength": _origin_text("draft_strength", o_draft),
              "buff_strength": _origin_text("buff_strength", o_buff),
              "endurable_lcf": _origin_text("endurable_lcf", o_lcf),
              "coupler_travel": o_travel,
              "adhesion": (_origin_text("adhesion", o_adh) if adhesion_limit is None else
                           "campaign file" + ("; consist limits" if "consist" in o_adh else "")),
              "adhesion_at_speed": _DEFAULT_ORIGIN["adhesion_at_speed"],
              "adhesion_low_speed": _DEFAULT_ORIGIN["adhesion_low_speed"],
              "standstill_holding": _DEFAULT_ORIGIN["standstill_holding"]}
    vs = consist.vehicles
    weight = np.array([v.mass_kg for v in vs], float) * G
    braked = np.array([getattr(v.brake, "type", "none") in ("blocks", "disc") for v in vs])
    blocks = np.array([getattr(v.brake, "type", "none") == "blocks" for v in vs])
    full = (np.asarray(friction_arrays.full_scale_N, float).copy() if friction_arrays is not None
            else np.zeros(len(vs)))
    rot = np.array([(v.inertia_factor - 1.0) * v.mass_kg for v in vs], float)
    return TrainLimits(draft, buff, lcf, adhesion, weight, origin, braked, blocks, full, rot,
                       travel)


def limits_metadata(limits: TrainLimits) -> dict:
    """The limits as JSON-serialisable run information (kN, t, mm), for a recording.

    Parameters
    ----------
    limits : TrainLimits

    Returns
    -------
    dict
        Read back by :func:`limits_from_metadata`.
    """
    def kn(a):
        return [None if not math.isfinite(x) else x / 1e3 for x in a.tolist()]
    return {"draft_strength_kN": kn(limits.draft_strength_N),
            "buff_strength_kN": kn(limits.buff_strength_N),
            "endurable_lcf_kN": kn(limits.endurable_lcf_N),
            "adhesion_limit": limits.adhesion_limit.tolist(),
            "mass_t": (limits.weight_N / G / 1e3).tolist(),
            "braked": limits.braked.tolist(), "block_brake": limits.blocks.tolist(),
            "full_brake_scale_kN": (limits.full_scale_N / 1e3).tolist(),
            "rotating_mass_t": (limits.rotating_mass_kg / 1e3).tolist(),
            "coupler_travel_mm": [None if not math.isfinite(x) else x
                                  for x in limits.travel_mm],
            "origin": dict(limits.origin)}


def limits_from_metadata(meta, n_vehicles: int) -> TrainLimits | None:
    """Limits stored by :func:`limits_metadata`, or None when absent or not of this train.

    Recordings made before the brakes' full scale was stored carry no way to find the braked
    part of a stop: their mean adhesion is not assessed.

    Parameters
    ----------
    meta : object
        The ``limits`` entry of a recording's run information.
    n_vehicles : int
        Vehicles in the recorded arrays.

    Returns
    -------
    TrainLimits or None
    """
    if not isinstance(meta, dict):
        return None
    try:
        def arr(key, n, scale=1.0, positive=True):
            values = meta[key]
            if not isinstance(values, list) or len(values) != n:
                raise ValueError(key)
            out = np.array([math.inf if x is None else float(x) * scale for x in values])
            if np.isnan(out).any() or (positive and (out <= 0.0).any()) or (out < 0.0).any():
                raise ValueError(key)
            return out

        def flags_of(key, n):
            values = meta[key]
            if not isinstance(values, list) or len(values) != n or \
                    not all(isinstance(x, bool) for x in values):
                raise ValueError(key)
            return np.array(values, bool)
        nc = max(n_vehicles - 1, 0)
        origin = meta.get("origin")
        if all(k in meta for k in ("braked", "block_brake", "full_brake_scale_kN",
                                   "rotating_mass_t")):
            braked, blocks = flags_of("braked", n_vehicles), flags_of("block_brake", n_vehicles)
            full = arr("full_brake_scale_kN", n_vehicles, 1e3, positive=False)
            rot = arr("rotating_mass_t", n_vehicles, 1e3, positive=False)
        else:
            braked, blocks = np.zeros(n_vehicles, bool), np.zeros(n_vehicles, bool)
            full, rot = np.zeros(n_vehicles), np.zeros(n_vehicles)
        travel = (-math.inf, math.inf)
        t = meta.get("coupler_travel_mm")
        if isinstance(t, list) and len(t) == 2:
            lo = -math.inf if t[0] is None else float(t[0])
            hi = math.inf if t[1] is None else float(t[1])
            if not (lo < 0.0 < hi):
                raise ValueError("coupler_travel_mm")
            travel = (lo, hi)
        return TrainLimits(arr("draft_strength_kN", nc, 1e3), arr("buff_strength_kN", nc, 1e3),
                           arr("endurable_lcf_kN", nc, 1e3), arr("adhesion_limit", n_vehicles),
                           arr("mass_t", n_vehicles, 1e3 * G),
                           {str(k): str(v) for k, v in origin.items()}
                           if isinstance(origin, dict) else {}, braked, blocks, full, rot,
                           travel)
    except (KeyError, TypeError, ValueError, OverflowError):
        return None


def default_coupler_limits(n_vehicles: int) -> TrainLimits:
    """Default coupler limits of a train whose vehicles are not known (no adhesion limits).

    Parameters
    ----------
    n_vehicles : int

    Returns
    -------
    TrainLimits
        Zero-length adhesion limits and weights: the adhesion criteria are not assessed.
    """
    nc = max(n_vehicles - 1, 0)
    none = "not assessed: the recording holds no vehicle masses"
    return TrainLimits(np.full(nc, DRAFT_STRENGTH_N), np.full(nc, BUFF_STRENGTH_N),
                       np.full(nc, math.inf), np.zeros(0), np.zeros(0),
                       {"draft_strength": _DEFAULT_ORIGIN["draft_strength"],
                        "buff_strength": _DEFAULT_ORIGIN["buff_strength"],
                        "endurable_lcf": _DEFAULT_ORIGIN["endurable_lcf"],
                        "coupler_travel": "not assessed: the recording holds no coupler travel",
                        "adhesion": none, "adhesion_at_speed": none,
                        "adhesion_low_speed": none, "standstill_holding": none})


class SampledDemand:
    """Adhesion records of a run from its sampled state (a recording), sample by sample.

    The same definitions as the simulator's (see the module), at the recorded instants: the
    mean is distance-weighted over the intervals that end at a sample where the brake is
    fully applied (its retarding force over Karwatzki's speed factor, for block brakes, at
    least :data:`~.physics.kernel.FULL_APPLICATION` of the full scale) and the vehicle runs at
    5 km/h or faster, the rotating masses' share subtracted; the instantaneous demand is
    sampled while moving.

    Parameters
    ----------
    limits : TrainLimits
    """

    def __init__(self, limits: TrainLimits):
        self.limits = limits
        n = limits.adhesion_limit.size
        self.demand = VehicleDemand.empty(n)
        self.first_at_speed_s = np.full(n, -1.0)
        self._work = np.zeros(n)
        self._dist = np.zeros(n)
        self._prev: tuple | None = None

    def command(self, speed_m_s: float) -> None:
        """The brake command, with the head at ``speed_m_s`` [m/s]."""
        if not math.isfinite(self.demand.initial_speed_kmh):
            self.demand.initial_speed_kmh = abs(float(speed_m_s)) * KMH_PER_MS

    def add(self, t: float, speed_m_s, position_m, brake_force_N) -> None:
        """One sample of every vehicle's speed [m/s], position [m] and brake force [N]."""
        lim, d = self.limits, self.demand
        v = np.asarray(speed_m_s, float)
        if v.shape != lim.weight_N.shape:
            return
        f = np.abs(np.asarray(brake_force_N, float))
        _scan_vehicles(t, v, f, lim.weight_N, ADHESION_SPEED_KMH / KMH_PER_MS,
                       STANDSTILL_SAMPLE_M_S, ADHESION_AT_SPEED_LIMIT, d.at_speed,
                       d.at_speed_time_s, d.at_speed_kmh, self.first_at_speed_s, d.low_speed,
                       d.low_speed_time_s, d.low_speed_kmh)
        fast = np.abs(v) >= MEAN_ADHESION_MIN_SPEED_M_S
        d.mean_end_time_s[fast] = t
        d.mean_end_speed_kmh[fast] = np.abs(v[fast]) * KMH_PER_MS
        x = np.asarray(position_m, float)
        if x.shape != v.shape:
            return
        if self._prev is not None and lim.full_scale_N.size == v.size:
            xp, vp = self._prev
            v_kmh = np.abs(v) * KMH_PER_MS
            kar = np.where(lim.blocks, 0.6 * (v_kmh + 100.0) / (5.0 * v_kmh + 100.0), 1.0)
            on = fast & (lim.full_scale_N > 0.0) & (f / kar >= FULL_APPLICATION * lim.full_scale_N)
            dx = x - xp
            self._work += np.where(on, f * dx + lim.rotating_mass_kg * 0.5 * (v * v - vp * vp),
                                   0.0)
            self._dist += np.where(on, dx, 0.0)
        self._prev = (x, v)

    def result(self) -> VehicleDemand:
        """The records so far."""
        d = self.demand
        with np.errstate(invalid="ignore", divide="ignore"):
            d.mean = np.where(self._dist >= MEAN_ADHESION_MIN_DISTANCE_M,
                              self._work / self._dist / self.limits.weight_N, np.nan)
        d.mean_distance_m = self._dist.copy()
        return d


# --------------------------------------------------------------------------- the verdicts


def _amount(unit: str, value: float, limit: float) -> str:
    if unit == "kN":
        return (f"{value / 1e3:.0f} kN > {limit / 1e3:.0f} kN "
                f"(+{(value - limit) / 1e3:.0f} kN, +{100.0 * (value - limit) / limit:.0f} %)")
    if unit == "mm":
        return f"{value:.1f} mm"
    if not math.isfinite(limit):
        return f"{value:.3f}"
    return f"{value:.3f} > {limit:.3f} (+{value - limit:.3f})"


@dataclass(frozen=True)
class Exceedance:
    """One coupler or vehicle beyond its limit.

    Attributes
    ----------
    criterion : str
        A key of :data:`CRITERIA`.
    element : str
        ``coupler`` (numbered from 1 behind the head) or ``vehicle`` (from 0 at the head).
    number : int
    value : float
        Its worst force magnitude [N], excursion [mm] or adhesion demand [-].
    limit : float
        Its limit, same unit.
    time_s : float
        When the worst occurred [s] (a mean: when its braked part ended).
    speed_kmh : float
        Speed then (a coupler: the head's; a vehicle: its own) [km/h].
    first_time_s : float
        When it was first seen beyond the limit [s] (resolution: the simulator's chunks, or
        the recorded samples).
    """

    criterion: str
    element: str
    number: int
    value: float
    limit: float
    time_s: float
    speed_kmh: float
    first_time_s: float

    @property
    def excess(self) -> float:
        """By how much the limit was exceeded (value - limit), same unit."""
        return self.value - self.limit

    def describe(self) -> str:
        """One line: which, by how much, when, at what speed."""
        rule = CRITERIA[self.criterion]
        speed = f", {self.speed_kmh:.1f} km/h" if math.isfinite(self.speed_kmh) else ""
        return (f"{self.element} {self.number}: {rule.quantity} "
                f"{_amount(rule.unit, self.value, self.limit)} at t = {self.time_s:.2f} s"
                f"{speed} (first at t = {self.first_time_s:.2f} s)")

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        unit = CRITERIA[self.criterion].unit
        scale, suffix = {"kN": (1e-3, "_kN"), "mm": (1.0, "_mm")}.get(unit, (1.0, ""))
        return {"criterion": self.criterion, self.element: self.number,
                f"value{suffix}": self.value * scale, f"limit{suffix}": self.limit * scale,
                f"excess{suffix}": self.excess * scale, "time_s": self.time_s,
                "speed_kmh": self.speed_kmh if math.isfinite(self.speed_kmh) else None,
                "first_time_s": self.first_time_s}


@dataclass(frozen=True)
class Criterion:
    """One row of the verdicts table.

    Attributes
    ----------
    name : str
        A key of :data:`CRITERIA`.
    assessed : bool
        Limits were given and the run reached the criterion's scope (False: not assessed).
    limit_min, limit_max : float
        Range of the limits over the train [N], [mm] or [-].
    origin : str
        Where the limits come from (their source), or why the criterion was not assessed.
    worst_value : float
        Largest value over the train [N], [mm] or [-].
    worst_number : int
        Coupler or vehicle that had it.
    worst_time_s : float
    exceedances : tuple of Exceedance
        Every coupler or vehicle beyond its limit, worst excess (relative) first.
    note : str
        What the value means beyond PASS/FAIL (e.g. a wet rail's adhesion exceeded).
    """

    name: str
    assessed: bool
    limit_min: float
    limit_max: float
    origin: str
    worst_value: float
    worst_number: int
    worst_time_s: float
    exceedances: tuple = ()
    note: str = ""

    @property
    def rule(self) -> Rule:
        """What the criterion assesses and where."""
        return CRITERIA[self.name]

    @property
    def passed(self) -> bool | None:
        """True: none beyond (or beyond only a WARN or INFO limit); False: a FAIL criterion
        exceeded; None: not assessed."""
        if not self.assessed:
            return None
        return not (self.exceedances and self.rule.severity == "FAIL")

    @property
    def status(self) -> str:
        """``PASS``, ``FAIL``, ``WARN``, ``INFO`` or ``not assessed``."""
        if not self.assessed:
            return "not assessed"
        if self.rule.severity == "INFO":
            return "INFO"
        return self.rule.severity if self.exceedances else "PASS"

    def _limit_text(self) -> str:
        unit = self.rule.unit
        f = (lambda x: f"{x / 1e3:.0f} kN") if unit == "kN" else (lambda x: f"{x:.3g}")
        if unit == "mm":
            return "the travel"
        if self.limit_min == self.limit_max:
            return f(self.limit_min)
        return f"{f(self.limit_min)} to {f(self.limit_max)}"

    def describe(self, most: int | None = 5) -> list[str]:
        """The row, its scope and source, and its exceedances, one line each (the ``most``
        worst; None: all)."""
        rule = self.rule
        if not self.assessed:
            return [f"{self.status:<4}  {rule.title}: {self.origin}"]
        unit = rule.unit
        worst = (f"{self.worst_value / 1e3:.0f} kN" if unit == "kN" else
                 f"{self.worst_value:.1f} mm" if unit == "mm" else f"{self.worst_value:.3f}")
        limit = "" if rule.severity == "INFO" else f"limit {self._limit_text()}; "
        if unit == "mm" and not self.exceedances:
            lines = [f"{self.status:<4}  {rule.title} ({rule.scope}): no coupler went beyond its "
                     "travel"]
        else:
            lines = [f"{self.status:<4}  {rule.title} ({rule.scope}): {limit}worst "
                     f"{rule.quantity} {worst} at {rule.element} {self.worst_number} "
                     f"(t = {self.worst_time_s:.2f} s)" + (f"; {self.note}" if self.note else "")]
        lines.append(f"        source: {self.origin}")
        if rule.severity != "INFO":
            shown = self.exceedances if most is None else self.exceedances[:most]
            lines += [f"        {e.describe()}" for e in shown]
            if len(shown) < len(self.exceedances):
                lines.append(f"        ... and {len(self.exceedances) - len(shown)} more "
                             f"{rule.element}s beyond their limit")
        return lines

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        rule = self.rule
        scale, unit = {"kN": (1e-3, "_kN"), "mm": (1.0, "_mm")}.get(rule.unit, (1.0, ""))

        def num(x):
            return x * scale if math.isfinite(x) else None
        return {"criterion": self.name, "title": rule.title, "status": self.status,
                "severity": rule.severity, "scope": rule.scope,
                f"limit_min{unit}": num(self.limit_min), f"limit_max{unit}": num(self.limit_max),
                "origin": self.origin, f"worst{unit}": num(self.worst_value),
                f"worst_{rule.element}": self.worst_number,
                "worst_time_s": self.worst_time_s, "note": self.note,
                "exceedances": [e.as_dict() for e in self.exceedances]}


@dataclass(frozen=True)
class Verdicts:
    """The verdicts table of a run.

    Attributes
    ----------
    criteria : tuple of Criterion
        In :data:`CRITERIA` order.
    """

    criteria: tuple

    @property
    def passed(self) -> bool:
        """No assessed FAIL criterion failed."""
        return all(c.passed is not False for c in self.criteria)

    @property
    def status(self) -> str:
        """``FAIL`` (a FAIL criterion exceeded), ``WARN`` (a WARN criterion exceeded) or
        ``PASS``."""
        if not self.passed:
            return "FAIL"
        return "WARN" if any(c.status == "WARN" for c in self.criteria) else "PASS"

    @property
    def non_physical(self) -> bool:
        """A coupler went beyond its travel: the forces of the run are not physical."""
        return any(c.name == "coupler_travel" and c.exceedances for c in self.criteria)

    def __getitem__(self, name: str) -> Criterion:
        return next(c for c in self.criteria if c.name == name)

    def describe(self, most: int | None = 5) -> list[str]:
        """The table as text lines (per criterion the ``most`` worst exceedances)."""
        lines = [line for c in self.criteria for line in c.describe(most)]
        if self.non_physical:
            lines.append("NON-PHYSICAL: couplers went beyond their travel; the forces beyond it "
                         "are not results")
        return lines

    def as_dict(self) -> dict:
        """JSON-serialisable."""
        return {"passed": self.passed, "status": self.status,
                "non_physical": self.non_physical,
                "criteria": [c.as_dict() for c in self.criteria]}


def _criterion(name, values, limits, times, speeds, first, element_base, origin,
               assessed=None, note="") -> Criterion:
    finite = np.isfinite(limits) if assessed is None else np.asarray(assessed, bool)
    ok = finite & np.isfinite(values)
    if values.size == 0 or not ok.any():
        return Criterion(name, False, math.inf, math.inf, origin, 0.0, 0, 0.0)
    k = int(np.argmax(np.where(ok, values, -np.inf)))
    lim_ok = np.isfinite(limits) & ok
    over = np.flatnonzero(lim_ok & (values > limits))
    rel = (values[over] - limits[over]) / np.where(limits[over] > 0.0, limits[over], 1.0)
    over = over[np.argsort(-rel, kind="stable")]
    element = CRITERIA[name].element
    first_seen = np.where(first[over] >= 0.0, first[over], times[over])
    ex = tuple(Exceedance(name, element, *row) for row in zip(
        (over + element_base).tolist(), values[over].tolist(), limits[over].tolist(),
        times[over].tolist(), speeds[over].tolist(), first_seen.tolist()))
    shown = limits[lim_ok] if lim_ok.any() else np.array([math.inf])
    return Criterion(name, True, float(shown.min()), float(shown.max()), origin,
                     float(values[k]), k + element_base, float(times[k]), ex, note)


@dataclass
class VehicleDemand:
    """Per-vehicle adhesion records of a run, as :func:`judge` takes them.

    Attributes
    ----------
    mean, mean_distance_m, mean_end_time_s, mean_end_speed_kmh : ndarray
        Mean utilised adhesion [-] (NaN: no braked part), the distance it is taken over [m],
        when and at what speed the braked part ended [s], [km/h].
    initial_speed_kmh : float
        The head's speed at the brake command [km/h] (NaN: no command).
    at_speed, at_speed_time_s, at_speed_kmh : ndarray
        Largest instantaneous demand above :data:`ADHESION_SPEED_KMH` [-], when, at what speed.
    low_speed, low_speed_time_s, low_speed_kmh : ndarray
        The same below it, moving.
    """

    mean: np.ndarray
    mean_distance_m: np.ndarray
    mean_end_time_s: np.ndarray
    mean_end_speed_kmh: np.ndarray
    initial_speed_kmh: float
    at_speed: np.ndarray
    at_speed_time_s: np.ndarray
    at_speed_kmh: np.ndarray
    low_speed: np.ndarray
    low_speed_time_s: np.ndarray
    low_speed_kmh: np.ndarray

    @classmethod
    def empty(cls, n: int) -> "VehicleDemand":
        """Nothing recorded yet for ``n`` vehicles."""
        z = np.zeros
        return cls(np.full(n, np.nan), z(n), z(n), z(n), math.nan, z(n), z(n), z(n), z(n),
                   z(n), z(n))


def judge(limits: TrainLimits, *, peak_draft_N, peak_draft_time_s, draft_speed_kmh,
          peak_buff_N, peak_buff_time_s, buff_speed_kmh, demand: VehicleDemand | None = None,
          travel_beyond_mm=None, travel_time_s=None, travel_speed_kmh=None,
          holding=None, holding_reason: str = "not assessed: the train has not stopped",
          first_time_s: dict | None = None) -> Verdicts:
    """The verdicts table from a run's per-coupler peaks and per-vehicle adhesion records.

    Parameters
    ----------
    limits : TrainLimits
    peak_draft_N, peak_buff_N : array_like
        Largest draft (>= 0) and buff (<= 0) force of each coupler [N].
    peak_draft_time_s, peak_buff_time_s : array_like
        When [s].
    draft_speed_kmh, buff_speed_kmh : array_like
        Speed at those times [km/h].
    demand : VehicleDemand, optional
        Adhesion records (omitted: the adhesion criteria are not assessed).
    travel_beyond_mm, travel_time_s, travel_speed_kmh : array_like, optional
        Largest excursion of each coupler beyond its travel [mm] (0: none), when, the head's
        speed then (omitted: the travel is not assessed).
    holding : tuple of array_like, optional
        (force to hold [N], what the vehicle holds [N], when [s]) of each vehicle at its
        worst moment at rest after the stop (omitted: not assessed, ``holding_reason``).
    holding_reason : str, optional
        Why holding is not assessed when ``holding`` is omitted.
    first_time_s : dict, optional
        Criterion -> per-element time each was first seen beyond its limit [s] (-1: never;
        default: the time of the worst).

    Returns
    -------
    Verdicts
    """
    first_time_s = first_time_s or {}
    draft = np.asarray(peak_draft_N, float)
    buff = -np.asarray(peak_buff_N, float)
    origin = limits.origin

    def first(name, n):
        return np.asarray(first_time_s.get(name, np.full(n, -1.0)), float)
    rows = [_criterion("draft_strength", draft, limits.draft_strength_N,
                       np.asarray(peak_draft_time_s, float), np.asarray(draft_speed_kmh, float),
                       first("draft_strength", draft.size), 1,
                       origin.get("draft_strength", ""))]
    for name in ("buff_strength", "endurable_lcf"):
        rows.append(_criterion(name, buff, limits.of(name), np.asarray(peak_buff_time_s, float),
                               np.asarray(buff_speed_kmh, float), first(name, buff.size), 1,
                               origin.get(name, "")))
    if travel_beyond_mm is None or not any(map(math.isfinite, limits.travel_mm)):
        rows.append(Criterion("coupler_travel", False, math.inf, math.inf, origin.get(
            "coupler_travel", "not assessed: the coupler's travel is not known"), 0.0, 0, 0.0))
    else:
        beyond = np.asarray(travel_beyond_mm, float)
        rows.append(_criterion("coupler_travel", beyond, np.zeros(beyond.size),
                               np.asarray(travel_time_s, float),
                               np.asarray(travel_speed_kmh, float),
                               first("coupler_travel", beyond.size), 1,
                               origin.get("coupler_travel", "")))
    rows += _adhesion_rows(limits, demand, first)
    if holding is None:
        rows.append(Criterion("standstill_holding", False, math.inf, math.inf,
                              holding_reason if limits.adhesion_limit.size else origin.get(
                                  "standstill_holding", "not assessed"), 0.0, 0, 0.0))
    else:
        need, cap, t = (np.asarray(a, float) for a in holding)
        rows.append(_criterion("standstill_holding", need, cap, t, np.zeros(need.size),
                               first("standstill_holding", need.size), 0,
                               origin.get("standstill_holding", "")))
    return Verdicts(tuple(rows))


def _adhesion_rows(limits: TrainLimits, d: VehicleDemand | None, first) -> list[Criterion]:
    n = limits.adhesion_limit.size
    names = ("adhesion", "adhesion_at_speed", "adhesion_low_speed")
    if d is None or n == 0:
        return [Criterion(name, False, math.inf, math.inf,
                          limits.origin.get(name, "not assessed"), 0.0, 0, 0.0)
                for name in names]
    braked = limits.braked if limits.braked.size == n else np.ones(n, bool)
    origin = limits.origin
    rows = []
    # mean utilised adhesion: stops from the calculation's reference speed on
    mean = np.asarray(d.mean, float)
    if not math.isfinite(d.initial_speed_kmh) or not np.isfinite(mean[braked]).any():
        rows.append(Criterion("adhesion", False, math.inf, math.inf,
                              "not assessed: no braked part of a stop (full application above "
                              "5 km/h)", 0.0, 0, 0.0))
    elif d.initial_speed_kmh < MEAN_ADHESION_MIN_INITIAL_KMH - 0.5:
        k = int(np.nanargmax(np.where(braked, mean, np.nan)))
        rows.append(Criterion("adhesion", False, math.inf, math.inf,
                              f"not judged: a stop from {d.initial_speed_kmh:.0f} km/h, below the "
                              f"{MEAN_ADHESION_MIN_INITIAL_KMH:.0f} km/h of mean-value brake "
                              f"calculations (largest mean {mean[k]:.3f} at vehicle {k})",
                              float(mean[k]), k, float(d.mean_end_time_s[k])))
    else:
        rows.append(_criterion("adhesion", mean, limits.adhesion_limit, d.mean_end_time_s,
                               d.mean_end_speed_kmh, first("adhesion", n), 0,
                               origin.get("adhesion", ""), assessed=braked & np.isfinite(mean)))
    seen = np.asarray(d.at_speed_time_s) > 0.0
    rows.append(_criterion("adhesion_at_speed", np.asarray(d.at_speed, float),
                           np.full(n, ADHESION_AT_SPEED_LIMIT), np.asarray(d.at_speed_time_s),
                           np.asarray(d.at_speed_kmh), first("adhesion_at_speed", n), 0,
                           origin.get("adhesion_at_speed", ""), assessed=braked & seen))
    low = np.asarray(d.low_speed, float)
    seen = np.asarray(d.low_speed_time_s) > 0.0
    note = ""
    if (braked & seen).any():
        k = int(np.argmax(np.where(braked & seen, low, -np.inf)))
        wet = float(wet_rail_adhesion(d.low_speed_kmh[k]))
        if low[k] > wet:
            note = (f"above a wet rail's {wet:.3f} at {d.low_speed_kmh[k]:.2g} km/h: wheel "
                    "slide likely on a wet rail")
    rows.append(_criterion("adhesion_low_speed", low, np.full(n, math.inf),
                           np.asarray(d.low_speed_time_s), np.asarray(d.low_speed_kmh),
                           first("adhesion_low_speed", n), 0,
                           origin.get("adhesion_low_speed", ""), assessed=braked & seen,
                           note=note))
    return rows


def diagnostic_values(verdicts: Verdicts) -> dict:
    """Key/values of the verdicts for a ``diagnostic_msgs/DiagnosticStatus`` (strings).

    Parameters
    ----------
    verdicts : Verdicts
        E.g. :meth:`Simulator.verdicts() <ltd_brake_ros.simulator.Simulator.verdicts>`.

    Returns
    -------
    dict of str to str
        ``verdicts`` (``PASS``/``WARN``/``FAIL``), then per criterion ``verdict_<name>``: its
        status and, beyond a limit, how many couplers or vehicles and the worst.
    """
    out = {"verdicts": verdicts.status}
    for c in verdicts.criteria:
        text = c.status
        if c.exceedances and c.rule.severity != "INFO":
            text += (f": {len(c.exceedances)} {c.rule.element}(s) beyond the limit, worst "
                     f"{c.exceedances[0].describe()}")
        elif c.status == "INFO":
            text += f": largest {c.worst_value:.3f} at {c.rule.element} {c.worst_number}" + (
                f"; {c.note}" if c.note else "")
        out[f"verdict_{c.name}"] = text
    return out


#: Campaign flag of each FAIL criterion.
FLAG_NAMES = {"draft_strength": "draft_ok", "buff_strength": "buff_ok",
              "endurable_lcf": "lcf_ok", "coupler_travel": "travel_ok", "adhesion": "adhesion_ok",
              "standstill_holding": "holding_ok"}


def flags(verdicts: Verdicts) -> dict:
    """Campaign flags: ``<criterion>_ok`` for the FAIL criteria (True: passed).

    Parameters
    ----------
    verdicts : Verdicts

    Returns
    -------
    dict of str to bool
        ``draft_ok``, ``buff_ok``, ``lcf_ok``, ``travel_ok``, ``adhesion_ok`` (the mean
        utilised adhesion), ``holding_ok``; a criterion not assessed counts as passed.
    """
    return {FLAG_NAMES[c.name]: c.passed is not False for c in verdicts.criteria
            if c.name in FLAG_NAMES}


# --------------------------------------------------------------------------- during a run


@jit
def _scan(t0, v0, t1, v1, nc, peak_draft, t_draft, peak_buff, t_buff, draft_lim, buff_lim,
          lcf_lim, seen_draft, seen_buff, draft_kmh, buff_kmh, first_draft, first_buff,
          first_lcf):
    """The couplers' part of one chunk of :class:`Watch` in one pass (arrays updated in
    place). Returns the number of limits exceeded for the first time."""
    span = t1 - t0
    new = 0
    for j in range(nc):
        p = peak_draft[j]
        if p > draft_lim[j]:
            if p > seen_draft[j]:  # the worst moved into this chunk: the head's speed then
                seen_draft[j] = p
                a = (t_draft[j] - t0) / span if span > 0.0 else 1.0
                draft_kmh[j] = (v0 + (v1 - v0) * a) * KMH_PER_MS
            if first_draft[j] < 0.0:
                first_draft[j] = t_draft[j]
                new += 1
        b = -peak_buff[j]
        if b > buff_lim[j] or b > lcf_lim[j]:
            if b > seen_buff[j]:
                seen_buff[j] = b
                a = (t_buff[j] - t0) / span if span > 0.0 else 1.0
                buff_kmh[j] = (v0 + (v1 - v0) * a) * KMH_PER_MS
            if b > buff_lim[j] and first_buff[j] < 0.0:
                first_buff[j] = t_buff[j]
                new += 1
            if b > lcf_lim[j] and first_lcf[j] < 0.0:
                first_lcf[j] = t_buff[j]
                new += 1
    return new


@jit
def _scan_vehicles(t1, speed, brake, weight, v_split, v_rest, limit, at_speed, at_t, at_kmh,
                   first_at, low, low_t, low_kmh):
    """The vehicles' part of one chunk of :class:`Watch`: instantaneous adhesion demand at
    the chunk's end, above and below ``v_split`` [m/s], never at rest (``v_rest``). Returns
    the number of vehicles beyond ``limit`` at speed for the first time."""
    new = 0
    for i in range(brake.shape[0]):
        v = abs(speed[i])
        if v <= v_rest or weight[i] <= 0.0:
            continue
        d = abs(brake[i]) / weight[i]
        if v > v_split:
            if d > at_speed[i]:
                at_speed[i] = d
                at_t[i] = t1
                at_kmh[i] = v * KMH_PER_MS
            if d > limit and first_at[i] < 0.0:
                first_at[i] = t1
                new += 1
        elif d > low[i]:
            low[i] = d
            low_t[i] = t1
            low_kmh[i] = v * KMH_PER_MS
    return new


class Watch:
    """Follows a running simulation for :class:`~ltd_brake_ros.simulator.Simulator`.

    Coupler peaks and excursions are the kernel's running extremes, and so is each vehicle's
    brake work while fully applied (the mean utilised adhesion); once per chunk one compiled
    pass (:meth:`check`) adds the first exceedance of each limit, the head's speed at each
    exceeding coupler's worst (interpolated within the chunk) and each vehicle's largest
    instantaneous adhesion demand at the chunk's end, above and below 30 km/h.

    Parameters
    ----------
    limits : TrainLimits
    standstill_m_s : float, optional
        Vehicles this slow are at rest: no adhesion demand is sampled from them [m/s].
    """

    def __init__(self, limits: TrainLimits, standstill_m_s: float = 1e-3):
        self.limits = limits
        nc, n = limits.draft_strength_N.size, limits.adhesion_limit.size
        self.first_time_s = {name: np.full(nc if CRITERIA[name].element == "coupler" else n,
                                           -1.0) for name in CRITERIA}
        self._reported = {name: np.zeros(a.size, bool) for name, a in self.first_time_s.items()}
        self.draft_speed_kmh = np.zeros(nc)
        self.buff_speed_kmh = np.zeros(nc)
        self._draft_seen = np.zeros(nc)
        self._buff_seen = np.zeros(nc)
        self.demand = VehicleDemand.empty(n)
        self.standstill_m_s = float(standstill_m_s)
        self._at_speed_force_N = ADHESION_AT_SPEED_LIMIT * limits.weight_N
        # when each vehicle's braked part ended (its speed fell below 5 km/h), and at what speed
        self._mean_end_t = np.zeros(n)
        self._mean_end_kmh = np.zeros(n)
        # at rest after the stop: each vehicle's worst force to hold against what it holds
        self._hold: tuple | None = None

    def copy(self) -> "Watch":
        """An independent copy (the limits are shared: never mutated)."""
        new = object.__new__(Watch)
        for k, v in self.__dict__.items():
            if isinstance(v, dict):
                v = {n: a.copy() for n, a in v.items()}
            elif isinstance(v, np.ndarray):
                v = v.copy()
            elif isinstance(v, tuple) and k == "_hold":
                v = tuple(a.copy() for a in v)
            elif isinstance(v, VehicleDemand):
                v = VehicleDemand(*(x.copy() if isinstance(x, np.ndarray) else x
                                    for x in v.__dict__.values()))
            new.__dict__[k] = v
        return new

    def check(self, t0: float, v0: float, t1: float, v1: float, kin, vehicle_speed_m_s,
              brake_force_N) -> list[tuple]:
        """Take one chunk into account.

        Parameters
        ----------
        t0, v0, t1, v1 : float
            Start and end of the chunk [s] and the head's speed then [m/s].
        kin : KinematicState
            The kernel's state at the end of the chunk (running coupler peaks).
        vehicle_speed_m_s, brake_force_N : ndarray
            Each vehicle's speed [m/s] and air-brake force [N] at the end of the chunk.

        Returns
        -------
        list of (time_s, detail)
            Limits exceeded for the first time in this chunk (see :meth:`event_detail`).
        """
        lim, first, d = self.limits, self.first_time_s, self.demand
        new = _scan(t0, v0, t1, v1, self._draft_seen.size, kin.peak_draft_N,
                    kin.peak_draft_time_s, kin.peak_buff_N, kin.peak_buff_time_s,
                    lim.draft_strength_N, lim.buff_strength_N, lim.endurable_lcf_N,
                    self._draft_seen, self._buff_seen, self.draft_speed_kmh,
                    self.buff_speed_kmh, first["draft_strength"], first["buff_strength"],
                    first["endurable_lcf"])
        n = lim.weight_N.size
        if n == vehicle_speed_m_s.size:
            # the kernel keeps each vehicle's brake-force peak above 30 km/h: first seen
            # beyond the limit at the peak that the chunk's end shows
            first_at = first["adhesion_at_speed"]
            over = (kin.peak_brake_fast_N[:n] > self._at_speed_force_N) & (first_at < 0.0)
            if over.any():
                first_at[over] = kin.peak_brake_fast_time_s[:n][over]
                new += int(over.sum())
            # the end of each vehicle's braked part: the last chunk end it ran at 5 km/h+
            fast = np.abs(vehicle_speed_m_s) >= MEAN_ADHESION_MIN_SPEED_M_S
            if fast.any():
                self._mean_end_t[fast] = t1
                self._mean_end_kmh[fast] = np.abs(vehicle_speed_m_s[fast]) * KMH_PER_MS
        return self._events(kin) if new else []

    def at_rest(self, t: float, need_N, capacity_N) -> list[tuple]:
        """Take the train at rest into account: each vehicle's force to hold [N] (couplers,
        grade, other external forces) against what it holds [N], at time ``t`` [s].

        Returns
        -------
        list of (time_s, detail)
            Vehicles first seen needing more than they hold.
        """
        need = np.abs(np.asarray(need_N, float))
        cap = np.asarray(capacity_N, float)
        if self._hold is None:
            self._hold = (need.copy(), cap.copy(), np.full(need.size, float(t)))
        h_need, h_cap, h_t = self._hold
        worse = need * h_cap > h_need * cap  # need / cap grew (cap > 0 for any vehicle)
        h_need[worse], h_cap[worse], h_t[worse] = need[worse], cap[worse], t
        first = self.first_time_s["standstill_holding"]
        new = (need > cap) & (first < 0.0)
        out = []
        for i in np.flatnonzero(new):
            first[i] = t
            out.append((float(t), {"criterion": "standstill_holding", "vehicle": int(i),
                                   "force_kN": float(need[i]) / 1e3,
                                   "limit_kN": float(cap[i]) / 1e3, "speed_kmh": 0.0}))
        return out

    def start(self, speed_m_s: float) -> None:
        """The brake command came, with the head at ``speed_m_s`` [m/s]."""
        if not math.isfinite(self.demand.initial_speed_kmh):
            self.demand.initial_speed_kmh = abs(float(speed_m_s)) * KMH_PER_MS

    def _events(self, kin) -> list[tuple]:
        """The limits first exceeded since the last call, as (time_s, detail)."""
        out = []
        nc = self._draft_seen.size
        d = self.demand_of(kin)
        values = {"draft_strength": kin.peak_draft_N[:nc], "buff_strength": -kin.peak_buff_N[:nc],
                  "endurable_lcf": -kin.peak_buff_N[:nc], "adhesion_at_speed": d.at_speed}
        speeds = {"draft_strength": self.draft_speed_kmh, "buff_strength": self.buff_speed_kmh,
                  "endurable_lcf": self.buff_speed_kmh, "adhesion_at_speed": d.at_speed_kmh}
        for name in values:
            first, done = self.first_time_s[name], self._reported[name]
            for j in np.flatnonzero((first >= 0.0) & ~done):
                done[j] = True
                out.append((float(first[j]), self.event_detail(
                    name, int(j), float(values[name][j]), float(self.limits.of(name)[j]),
                    float(speeds[name][j]))))
        return out

    @staticmethod
    def event_detail(name: str, index: int, value: float, limit: float,
                     speed_kmh: float) -> dict:
        """Detail of a ``limit_exceeded`` event (units in the keys)."""
        rule = CRITERIA[name]
        number = index + (1 if rule.element == "coupler" else 0)
        if rule.unit == "kN":
            return {"criterion": name, rule.element: number, "force_kN": value / 1e3,
                    "limit_kN": limit / 1e3, "speed_kmh": speed_kmh}
        return {"criterion": name, rule.element: number, "demand": value, "limit": limit,
                "speed_kmh": speed_kmh}

    def demand_of(self, kin) -> VehicleDemand:
        """The adhesion records so far, from the kernel's running records: the brake's work
        while fully applied (the mean) and its peaks above and below 30 km/h."""
        d = self.demand
        n = d.at_speed.size
        w = self.limits.weight_N
        work = np.asarray(kin.applied_work_J[:n], float)
        dist = np.asarray(kin.applied_distance_m[:n], float)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(dist >= MEAN_ADHESION_MIN_DISTANCE_M, work / dist / w, np.nan)
        return VehicleDemand(mean, dist, self._mean_end_t, self._mean_end_kmh,
                             d.initial_speed_kmh, kin.peak_brake_fast_N[:n] / w,
                             kin.peak_brake_fast_time_s[:n].copy(),
                             kin.peak_brake_fast_speed_m_s[:n] * KMH_PER_MS,
                             kin.peak_brake_slow_N[:n] / w,
                             kin.peak_brake_slow_time_s[:n].copy(),
                             kin.peak_brake_slow_speed_m_s[:n] * KMH_PER_MS)

    def verdicts(self, kin, limits: TrainLimits | None = None) -> Verdicts:
        """The verdicts table so far.

        Parameters
        ----------
        kin : KinematicState
            The kernel's state (running coupler peaks and excursions, brake work).
        limits : TrainLimits, optional
            Other limits to judge the same run by (default: the watched ones); first times
            and coupler speeds are then known only where the watched limits were exceeded too.

        Returns
        -------
        Verdicts
        """
        nc = self._draft_seen.size
        other = limits is not None and limits is not self.limits
        lim = limits or self.limits
        beyond = np.asarray(kin.beyond_range_m[:nc], float) * 1e3
        t_beyond = np.asarray(kin.beyond_range_time_s[:nc], float)
        return judge(lim, peak_draft_N=kin.peak_draft_N[:nc],
                     peak_draft_time_s=kin.peak_draft_time_s[:nc],
                     draft_speed_kmh=self.draft_speed_kmh, peak_buff_N=kin.peak_buff_N[:nc],
                     peak_buff_time_s=kin.peak_buff_time_s[:nc],
                     buff_speed_kmh=self.buff_speed_kmh,
                     demand=self.demand_of(kin) if lim.adhesion_limit.size else None,
                     travel_beyond_mm=beyond, travel_time_s=np.maximum(t_beyond, 0.0),
                     travel_speed_kmh=np.full(nc, math.nan), holding=self._hold,
                     first_time_s=None if other else dict(
                         self.first_time_s, coupler_travel=np.asarray(
                             kin.out_of_range_time_s[:nc], float)))

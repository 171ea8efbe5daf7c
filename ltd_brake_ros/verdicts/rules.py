"""The rules the verdicts apply: each criterion's limit, scope and source, and a train's limits."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..physics.constants import G

__all__ = ["ADHESION_AT_SPEED_LIMIT", "ADHESION_LIMIT", "ADHESION_LIMIT_WSP",
           "ADHESION_SPEED_KMH", "BUFF_STRENGTH_N", "CRITERIA", "DEFAULT_MAX_SPEED_KMH",
           "DESIGN_END_KMH", "DRAFT_STRENGTH_N", "design_adhesion",
           "MEAN_ADHESION_MIN_DISTANCE_M", "MEAN_ADHESION_MIN_INITIAL_KMH", "REST_ADHESION",
           "STANDSTILL_SAMPLE_M_S", "Rule", "TrainLimits", "WHEEL_TEMPERATURE_LIMIT_K",
           "default_coupler_limits", "limits_from_metadata", "limits_metadata", "train_limits",
           "wet_rail_adhesion"]

#: Default draft strength of a coupling [N]: the minimum breaking load of the standard screw
#: coupling, 850 kN (UIC 520/826 as summarised by secondary sources; not verified in the
#: standard's text), below EN 15566's lowest draw-gear category, 1.0 MN (verified in the
#: standard's summary): the weaker part breaks.
DRAFT_STRENGTH_N = 850e3
#: Default buff strength of a coupling [N]: the longitudinal compressive proof load of a
#: freight wagon body at buffer height, 2000 kN for category F-I (EN 12663-2:2010, Table 2,
#: read in a DIN copy; category F-II: 1200 kN).
BUFF_STRENGTH_N = 2000e3
#: Default limit of the mean utilised adhesion of a vehicle without wheel-slide protection
#: [-]: 0.12, above which tread-braked units need wheel-slide protection (TSI LOC&PAS,
#: Regulation (EU) 1302/2014, 4.2.4.6.2, read in its German text; the WAG TSI's clause for
#: wagons, Regulation (EU) 321/2013, not read: a lecture's summary gives the same 0.12),
#: judged on the mean of a braking calculation (EN 14531-1's mean-value method).
ADHESION_LIMIT = 0.12
#: Default limit of the mean utilised adhesion of a vehicle with wheel-slide protection [-]:
#: 0.15, the braking adhesion a calculation may assume at 30-250 km/h (TSI LOC&PAS 4.2.4.6.1,
#: read in its German text, for locomotives and passenger stock: for wagons an analogy, not
#: verified; no source for freight found).
ADHESION_LIMIT_WSP = 0.15
#: Declared maximum speed of a vehicle that declares none [km/h]: 100, the "S" marking of
#: European freight wagons (secondary sources; medium), the speed of the design check's stop.
DEFAULT_MAX_SPEED_KMH = 100.0
#: The braked part of a stop ends at this speed, as braking calculations count it [km/h].
DESIGN_END_KMH = 5.0
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
#: Adhesion of the rail a vehicle at rest may use to hold [-]: 0.12, what a parking-brake
#: calculation may assume at most (TSI LOC&PAS, Regulation (EU) 1302/2014, 4.2.4.6.1, read in
#: its German text: locomotives and passenger stock, an analogy for wagons).
REST_ADHESION = 0.12
#: Static friction of a brake at rest, taken equal to its kinetic friction law at v = 0
#: (Karwatzki's speed factor 0.6 for P10 blocks, Eq. 9; the disc's mu_eff, Eq. 10): no
#: static friction coefficient of P10 blocks or of disc pads was found; an assumption, not
#: verified.
STATIC_FRICTION_ORIGIN = ("static brake friction taken as the kinetic law at rest (not "
                          "verified: no static coefficient of P10 blocks or disc pads found)")
#: Wet-rail adhesion as a fraction of dry (Koffman 1948, secondary source: ~0.6).
WET_RAIL_FACTOR = 0.6
#: Wheel temperature (the lumped model's mean wheel temperature) that earns a warning on a
#: tread-braked vehicle [K]: 350 C. No limit could be verified: EN 13979-1's thermomechanical
#: assessment is about deformation and fracture under braking (its summary), no temperature
#: limit retrieved from it, and the literature found (Johnson et al. 1977, Donzella et al.
#: 1998, RTRI 2024, Megna & Bracciali 2025) reports tensile rim stresses after severe drag
#: braking without a number retrieved here. A conservative value chosen (low): 50 K above the
#: 299 C this model computes for the freight-wagon TSI's thermal reference case (45 kW per
#: wheel for 34 min, which the wheels are designed to withstand); a braking clearly beyond it
#: warns.
WHEEL_TEMPERATURE_LIMIT_K = 623.15


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
        ``coupler`` (numbered from 1 behind the head), ``vehicle`` (from 0 at the head) or
        ``train`` (the whole train, number 0).
    unit : str
        ``kN``, ``mm``, ``K``, ``km/h`` or ``-``.
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
    "buffer_limit_state": Rule("Within the buffers' end force", "buff force", "coupler", "kN",
                               "FAIL", "every coupler, all speeds"),
    "coupler_travel": Rule("Within the coupler's travel", "deflection beyond the travel",
                           "coupler", "mm", "FAIL", "every coupler, all speeds"),
    "adhesion": Rule("Mean utilised adhesion by design", "mean brake force at the rails / "
                     "weight", "vehicle", "-", "FAIL",
                     "every braked vehicle, whatever the run: a stop from its maximum speed at "
                     "full application to 5 km/h, by EN 14531-1's mean-value method"),
    "adhesion_demand": Rule("Adhesion demand against the rail", "brake force / weight",
                            "vehicle", "-", "WARN",
                            "braked vehicles while moving, step by step as EN 14531-2 scopes "
                            "adhesion requirements, against the declared rail condition"),
    "standstill_holding": Rule("Holding at rest", "force to hold (grade, external forces)",
                               "train", "kN", "FAIL", "the train once it has settled at rest, "
                               "until traction is commanded"),
    "runaway": Rule("No movement from rest without traction", "speed from rest", "vehicle",
                    "km/h", "FAIL", "every vehicle once the train has settled at rest (every "
                    "vehicle within 1 mm/s for 2 s), until traction is commanded, brake "
                    "applied or released"),
    "wheel_temperature": Rule("Wheel temperature, indicative", "mean wheel temperature",
                              "vehicle", "K", "WARN", "vehicles with block brakes, all speeds"),
}
_DEFAULT_ORIGIN = {
    "draft_strength": "default 850 kN: screw coupling breaking load (UIC 520/826 via secondary "
                      "sources, not verified; EN 15566 draw-gear categories 1.0/1.2/1.5 MN)",
    "buff_strength": "default 2000 kN: wagon body compressive proof load at buffer height, "
                     "category F-I (EN 12663-2:2010 Table 2, read in a DIN copy; F-II wagons: "
                     "1200 kN, set buff_strength_kN)",
    "endurable_lcf": "not given (EN 15839: a property of each vehicle; set limits."
                     "endurable_lcf_kN in the consist)",
    "adhesion": "default 0.12 without wheel-slide protection (TSI LOC&PAS 4.2.4.6.2's trigger "
                "for tread-braked units; the WAG TSI's clause not read), 0.15 with it (LOC&PAS "
                "analogy, not verified); the vehicle braked alone, (F - (rho - 1) M a) / (M g) "
                "distance-weighted; maximum speed the vehicle's, else 100 km/h ('S' marking, "
                "assumed)",
    "adhesion_demand": "the rail's available adhesion of the declared condition (wheel slide "
                       "expected beyond it: a warning, never a failure; the run is not "
                       "changed)",
    "coupler_travel": "the coupler model's valid range",
    "buffer_limit_state": "not assessed: the coupler model's buffer end force is not known",
    "standstill_holding": "what the train holds at rest, as a parking-brake calculation adds "
                          "it up: each vehicle the static friction of its brake, at most the "
                          "rail's adhesion at rest, 0.12 m g (the most a parking-brake "
                          "calculation may assume, TSI LOC&PAS 4.2.4.6.1: an analogy for "
                          "wagons), plus its running resistance at rest (Eq. 2); "
                          + STATIC_FRICTION_ORIGIN,
    "runaway": "a train at rest moves only under traction: any vehicle faster than the "
               "standstill speed, 1 mm/s, after the train has settled is a runaway",
    "wheel_temperature": "indicative: 623 K (350 C), a value chosen, not a verified limit (no "
                         "criterion retrieved from EN 13979-1's thermomechanical assessment); "
                         "50 K above this model's 572 K for the freight-wagon TSI's thermal "
                         "reference case (45 kW per wheel for 34 min); the heat model is not "
                         "validated (no published drag-braking case with rim temperatures "
                         "found), lumped, the tread and rim are hotter, rail chill not "
                         "modelled",
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
    wheel_temperature_K : ndarray
        Per vehicle, the wheel temperature that earns a warning [K]; inf where not assessed
        (no block brakes; empty: none assessed).
    design_adhesion : ndarray
        Per vehicle, the mean utilised adhesion of a stop from its maximum speed at full
        application (:func:`design_adhesion`) [-]; NaN where unbraked (empty: not known).
    max_speed_kmh : ndarray
        Per vehicle, the maximum speed of that stop [km/h].
    rail : str
        The declared rail condition the demand is judged against (``dry``, ``wet``, ...).
    rail_table : ndarray, shape (2, k)
        Its available adhesion: speed [m/s] and mu [-] (:mod:`~.physics.brakes.adhesion`).
    buffer_limit_N : ndarray
        Per coupler, the buffers' limit state: twice the declared end force of one side buffer
        [N] (:func:`~ltd_brake_ros.physics.couplers.buffer_limit`); beyond it the run is
        non-physical (empty: not assessed).
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
    wheel_temperature_K: np.ndarray = field(default_factory=lambda: np.zeros(0))
    buffer_limit_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    design_adhesion: np.ndarray = field(default_factory=lambda: np.zeros(0))
    max_speed_kmh: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rail: str = "dry"
    rail_table: np.ndarray = field(default_factory=lambda: _rail("dry").table)

    def of(self, criterion: str) -> np.ndarray:
        """The per-coupler or per-vehicle limits of a criterion."""
        n = self.adhesion_limit.size
        return {"draft_strength": self.draft_strength_N, "buff_strength": self.buff_strength_N,
                "endurable_lcf": self.endurable_lcf_N, "adhesion": self.adhesion_limit,
                "coupler_travel": np.zeros(self.draft_strength_N.size),
                "buffer_limit_state": (self.buffer_limit_N
                                       if self.buffer_limit_N.size == self.draft_strength_N.size
                                       else np.full(self.draft_strength_N.size, math.inf)),
                "adhesion_demand": np.full(n, math.nan),
                "standstill_holding": np.full(1, math.inf),
                "runaway": np.full(n, STANDSTILL_SAMPLE_M_S * 3.6),
                "wheel_temperature": (self.wheel_temperature_K
                                      if self.wheel_temperature_K.size == n
                                      else np.full(n, math.inf))}[criterion]


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


def _rail(name):
    """The adhesion condition named (:func:`~ltd_brake_ros.physics.brakes.adhesion.condition`,
    or a condition; None or ``off``: a dry rail, the default of the run check)."""
    from ..physics.brakes import adhesion

    try:
        cond = adhesion.condition(name)
    except ValueError:  # a curve file's name stored in a recording: its table is not
        cond = adhesion.OFF
    return cond if cond.on else adhesion.CONDITIONS["dry"]


def design_adhesion(consist, friction_arrays) -> tuple[np.ndarray, np.ndarray]:
    """Each braked vehicle's mean utilised adhesion of a stop from its maximum speed, by the
    mean-value method: the vehicle braked alone at full application from its maximum speed
    to :data:`DESIGN_END_KMH`, its retarding force F(v) from the friction law (Karwatzki's
    speed factor for P10 blocks, Eq. 9; constant for discs, Eq. 10).

    The rails take the brake force less what decelerates the rotating masses, F - (rho - 1) M
    a, with a = F / (rho M) braked alone; distance-weighted over the stop, the mean is the
    equivalent deceleration over g: (v1^2 - v2^2) / (2 g s), s = int rho M v / F(v) dv.

    Parameters
    ----------
    consist : Consist
    friction_arrays : FrictionArrays
        The train's compiled friction law (its ``full_scale_N`` and ``kind``).

    Returns
    -------
    tau : ndarray
        [-]; NaN where the vehicle is unbraked.
    max_speed_kmh : ndarray
        The maximum speed each stop starts from (the vehicle's, else
        :data:`DEFAULT_MAX_SPEED_KMH`) [km/h].
    """
    from ..physics.brakes import friction

    vs = consist.vehicles
    vmax = np.array([v.max_speed_kmh or DEFAULT_MAX_SPEED_KMH for v in vs], float)
    tau = np.full(len(vs), np.nan)
    scale = np.asarray(friction_arrays.full_scale_N, float)
    kind = np.asarray(friction_arrays.kind)
    for i, v in enumerate(vs):
        if scale[i] <= 0.0 or vmax[i] <= DESIGN_END_KMH:
            continue
        kmh = np.linspace(DESIGN_END_KMH, vmax[i], 2001)
        f = scale[i] * (0.6 * (kmh + 100.0) / (5.0 * kmh + 100.0)
                        if kind[i] == friction.BRAKE_BLOCKS else np.ones_like(kmh))
        ms = kmh / 3.6
        y = v.inertia_factor * v.mass_kg * ms / f
        s = float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(ms)))
        tau[i] = (ms[-1] ** 2 - ms[0] ** 2) / (2.0 * G * s)
    return tau, vmax


def train_limits(consist, coupler_params=None, *, adhesion_limit: float | None = None,
                 friction_arrays=None, coupler_arrays=None,
                 rail: str | None = None) -> TrainLimits:
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
    rail : str, optional
        The rail condition the adhesion demand is judged against (default ``dry``).

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
    nc = max(len(consist.vehicles) - 1, 0)
    buffer_limit, o_buffer = np.zeros(0), _DEFAULT_ORIGIN["buffer_limit_state"]
    if coupler_params is not None:
        from ..physics import couplers

        state = couplers.buffer_limit(coupler_params, coupler_arrays)
        buffer_limit, o_buffer = np.full(nc, state.coupling_force_N), state.origin
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
              "buffer_limit_state": o_buffer,
              "adhesion": (_origin_text("adhesion", o_adh) if adhesion_limit is None else
                           "campaign file" + ("; consist limits" if "consist" in o_adh else "")),
              "adhesion_demand": "",
              "standstill_holding": _DEFAULT_ORIGIN["standstill_holding"],
              "runaway": _DEFAULT_ORIGIN["runaway"],
              "wheel_temperature": _DEFAULT_ORIGIN["wheel_temperature"]}
    vs = consist.vehicles
    weight = np.array([v.mass_kg for v in vs], float) * G
    braked = np.array([getattr(v.brake, "type", "none") in ("blocks", "disc") for v in vs])
    blocks = np.array([getattr(v.brake, "type", "none") == "blocks" for v in vs])
    full = (np.asarray(friction_arrays.full_scale_N, float).copy() if friction_arrays is not None
            else np.zeros(len(vs)))
    rot = np.array([(v.inertia_factor - 1.0) * v.mass_kg for v in vs], float)
    wheel = np.where(blocks, WHEEL_TEMPERATURE_LIMIT_K, math.inf)
    cond = _rail(rail)
    origin["adhesion_demand"] = (f"{cond.name} rail: {cond.source}; "
                                 + _DEFAULT_ORIGIN["adhesion_demand"])
    design, vmax = (design_adhesion(consist, friction_arrays) if friction_arrays is not None
                    else (np.zeros(0), np.zeros(0)))
    return TrainLimits(draft, buff, lcf, adhesion, weight, origin, braked, blocks, full, rot,
                       travel, wheel, buffer_limit, design, vmax, cond.name, cond.table)


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
            "wheel_temperature_K": [None if not math.isfinite(x) else x
                                    for x in limits.wheel_temperature_K.tolist()],
            "buffer_limit_kN": kn(limits.buffer_limit_N),
            "design_adhesion": [None if not math.isfinite(x) else x
                                for x in limits.design_adhesion.tolist()],
            "max_speed_kmh": limits.max_speed_kmh.tolist(), "rail": limits.rail,
            "rail_adhesion": np.asarray(limits.rail_table, float).tolist(),
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
        # recordings made before the wheels' limit was stored: the criterion is not assessed
        hot = arr("wheel_temperature_K", n_vehicles) if "wheel_temperature_K" in meta \
            else np.zeros(0)
        # recordings made before the buffers' limit state was stored: not assessed
        buffers = arr("buffer_limit_kN", nc, 1e3) if "buffer_limit_kN" in meta else np.zeros(0)
        # the adhesion design check: recordings made before it was stored do not assess it
        design, vmax = np.zeros(0), np.zeros(0)
        if "design_adhesion" in meta and "max_speed_kmh" in meta:
            values = meta["design_adhesion"]
            if not isinstance(values, list) or len(values) != n_vehicles:
                raise ValueError("design_adhesion")
            design = np.array([math.nan if x is None else float(x) for x in values])
            vmax = arr("max_speed_kmh", n_vehicles)
        rail_name, rail_table = "dry", _rail("dry").table
        if "rail" in meta and "rail_adhesion" in meta:
            rail_table = np.array(meta["rail_adhesion"], float)
            if rail_table.ndim != 2 or rail_table.shape[0] != 2 or not rail_table.shape[1] \
                    or not np.isfinite(rail_table).all() or (rail_table[1] <= 0.0).any():
                raise ValueError("rail_adhesion")
            rail_name = str(meta["rail"])
        return TrainLimits(arr("draft_strength_kN", nc, 1e3), arr("buff_strength_kN", nc, 1e3),
                           arr("endurable_lcf_kN", nc, 1e3), arr("adhesion_limit", n_vehicles),
                           arr("mass_t", n_vehicles, 1e3 * G),
                           {str(k): str(v) for k, v in origin.items()}
                           if isinstance(origin, dict) else {}, braked, blocks, full, rot,
                           travel, hot, buffers, design, vmax, rail_name, rail_table)
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
                        "buffer_limit_state": "not assessed: the recording holds no buffer end "
                                              "force",
                        "adhesion": none, "adhesion_demand": none,
                        "standstill_holding": none, "runaway": none,
                        "wheel_temperature": none})

"""Verdicts on a run: coupler strength, endurable compressive force and adhesion demand.

One table, one row per criterion, each PASS, FAIL or not assessed, naming every coupler or
vehicle beyond its limit (by how much, when, at what speed):

==================  =========================================================================
``draft_strength``  each coupler's draft force against the breaking load of the draw gear
``buff_strength``   each coupler's buff force against the compressive strength of the ends
``endurable_lcf``   each coupler's buff force against the endurable longitudinal compressive
                    force of the two vehicles it joins (EN 15839, from the UIC 530-2 tests);
                    not assessed unless a consist gives one
``adhesion``        each vehicle's air-brake force / (m g) against its adhesion limit
==================  =========================================================================

Limits of coupler j (joining vehicles j - 1 and j, vehicles numbered from 0 at the head): the
smaller of the two vehicles' ``limits`` in the consist file, else the coupler model's
(``draft_strength_kN``/``buff_strength_kN`` of the coupler file), else the defaults below.

The adhesion demand of a block-braked vehicle grows as it slows (Karwatzki's speed factor, Eq. 8)
and under an emergency application its block force only rises, so it peaks as the vehicle comes
to rest: the simulator evaluates it then, at the block forces of the stop and speed -> 0
(:func:`adhesion_demand_at_rest`), besides at the end of every chunk.

The simulator (:class:`Watch`) raises an event when a limit is first exceeded; ``ltd-brake
simulate``, the run report (:func:`judge` on recorded peaks), the campaign flags (:func:`flags`)
and the plant's diagnostics (:func:`diagnostic_values`) use this module alike.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .physics.brakes import friction
from .physics.constants import G, KMH_PER_MS
from .physics.equations import jit

__all__ = ["ADHESION_LIMIT", "BUFF_STRENGTH_N", "CRITERIA", "DRAFT_STRENGTH_N", "Criterion",
           "Exceedance", "TrainLimits", "Verdicts", "Watch", "adhesion_demand_at_rest",
           "default_coupler_limits", "diagnostic_values", "flags", "judge",
           "limits_from_metadata", "limits_metadata", "train_limits"]

#: Default draft strength of a coupling [N]: the minimum breaking load of the standard screw
#: coupling, 850 kN (EN 15566, UIC 520), below the draw hook's 1000 kN: the weaker part breaks.
DRAFT_STRENGTH_N = 850e3
#: Default buff strength of a coupling [N]: the longitudinal compressive proof load of a
#: freight wagon body at buffer height, 2000 kN (EN 12663-2, category F-II).
BUFF_STRENGTH_N = 2000e3
#: Default adhesion limit [-]: the largest wheel-rail adhesion a braking-performance
#: calculation may assume, 0.15 (TSI LOC&PAS, Regulation (EU) 1302/2014, 4.2.4.6.1).
ADHESION_LIMIT = 0.15

#: Criteria in table order: name -> (title, what is compared, element, unit).
CRITERIA = {
    "draft_strength": ("Coupler draft strength", "draft force", "coupler", "kN"),
    "buff_strength": ("Coupler buff strength", "buff force", "coupler", "kN"),
    "endurable_lcf": ("Endurable longitudinal compressive force", "buff force", "coupler",
                      "kN"),
    "adhesion": ("Adhesion demand of the air brake", "brake force / weight", "vehicle", "-"),
}
_DEFAULT_ORIGIN = {
    "draft_strength": "default: screw coupling breaking load (EN 15566, UIC 520)",
    "buff_strength": "default: wagon body compressive proof load (EN 12663-2, F-II)",
    "endurable_lcf": "not given (EN 15839: a property of each vehicle; set limits."
                     "endurable_lcf_kN in the consist)",
    "adhesion": "default: adhesion a braking calculation may assume (TSI LOC&PAS 4.2.4.6.1)",
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
        Per vehicle, head first [-].
    weight_N : ndarray
        Per vehicle, m g [N].
    origin : dict of str to str
        Where each criterion's limits come from.
    """

    draft_strength_N: np.ndarray
    buff_strength_N: np.ndarray
    endurable_lcf_N: np.ndarray
    adhesion_limit: np.ndarray
    weight_N: np.ndarray
    origin: dict = field(default_factory=dict)

    def of(self, criterion: str) -> np.ndarray:
        """The per-coupler or per-vehicle limits of a criterion."""
        return {"draft_strength": self.draft_strength_N, "buff_strength": self.buff_strength_N,
                "endurable_lcf": self.endurable_lcf_N,
                "adhesion": self.adhesion_limit}[criterion]


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


def train_limits(consist, coupler_params=None, *, adhesion_limit: float | None = None
                 ) -> TrainLimits:
    """The limits of a train: consist ``limits``, the coupler model's, the defaults.

    Parameters
    ----------
    consist : Consist
    coupler_params : dataclass, optional
        A coupler model's ``Params`` (its ``draft_strength_N``/``buff_strength_N``, inf when
        unknown).
    adhesion_limit : float, optional
        Adhesion limit of every vehicle whose consist entry gives none (default
        :data:`ADHESION_LIMIT`).

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
    default_adhesion = ADHESION_LIMIT if adhesion_limit is None else float(adhesion_limit)
    adhesion = np.array([default_adhesion if x.adhesion_limit is None else x.adhesion_limit
                         for x in lims], float)
    o_adh = {"consist" if x.adhesion_limit is not None else "default" for x in lims}
    origin = {"draft_strength": _origin_text("draft_strength", o_draft),
              "buff_strength": _origin_text("buff_strength", o_buff),
              "endurable_lcf": _origin_text("endurable_lcf", o_lcf),
              "adhesion": (_origin_text("adhesion", o_adh) if adhesion_limit is None else
                           "campaign file" + ("; consist limits" if "consist" in o_adh else ""))}
    weight = np.array([v.mass_kg for v in consist.vehicles], float) * G
    return TrainLimits(draft, buff, lcf, adhesion, weight, origin)


def limits_metadata(limits: TrainLimits) -> dict:
    """The limits as JSON-serialisable run information (kN, t), for a recording.

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
            "mass_t": (limits.weight_N / G / 1e3).tolist(), "origin": dict(limits.origin)}


def limits_from_metadata(meta, n_vehicles: int) -> TrainLimits | None:
    """Limits stored by :func:`limits_metadata`, or None when absent or not of this train.

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
        def arr(key, n, scale=1.0):
            values = meta[key]
            if not isinstance(values, list) or len(values) != n:
                raise ValueError(key)
            out = np.array([math.inf if x is None else float(x) * scale for x in values])
            if np.isnan(out).any() or (out <= 0.0).any():
                raise ValueError(key)
            return out
        nc = max(n_vehicles - 1, 0)
        origin = meta.get("origin")
        return TrainLimits(arr("draft_strength_kN", nc, 1e3), arr("buff_strength_kN", nc, 1e3),
                           arr("endurable_lcf_kN", nc, 1e3), arr("adhesion_limit", n_vehicles),
                           arr("mass_t", n_vehicles, 1e3 * G),
                           {str(k): str(v) for k, v in origin.items()}
                           if isinstance(origin, dict) else {})
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
        Zero-length adhesion limits and weights: the adhesion criterion is not assessed.
    """
    nc = max(n_vehicles - 1, 0)
    return TrainLimits(np.full(nc, DRAFT_STRENGTH_N), np.full(nc, BUFF_STRENGTH_N),
                       np.full(nc, math.inf), np.zeros(0), np.zeros(0),
                       {"draft_strength": _DEFAULT_ORIGIN["draft_strength"],
                        "buff_strength": _DEFAULT_ORIGIN["buff_strength"],
                        "endurable_lcf": _DEFAULT_ORIGIN["endurable_lcf"],
                        "adhesion": "not assessed: the recording holds no vehicle masses"})


def adhesion_demand_at_rest(friction_arrays, block_force_N, weight_N) -> np.ndarray:
    """Each vehicle's adhesion demand as its speed tends to 0 at the given block forces [-].

    Parameters
    ----------
    friction_arrays : friction.FrictionArrays
        The train's compiled friction law (:func:`friction.compile`).
    block_force_N : array_like
        Block force of each vehicle, F_B,tot [N].
    weight_N : array_like
        Weight of each vehicle, m g [N].

    Returns
    -------
    ndarray
        Air-brake force at v -> 0 over m g, head first.
    """
    fr = friction_arrays
    fb = np.asarray(block_force_N, float)
    force = np.array([friction.retarding_force(
        fr.kind[i], 0.0, friction.force_scale(fr.kind[i], fr.blocks[i], fr.arrangement[i],
                                              fr.mu_disc[i], fb[i]))[0]
        for i in range(fb.size)])
    return force / np.asarray(weight_N, float)


# --------------------------------------------------------------------------- the verdicts


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
        Its worst force magnitude [N] or adhesion demand [-].
    limit : float
        Its limit, same unit.
    time_s : float
        When the worst occurred [s].
    speed_kmh : float
        Speed then (a coupler: the head's; a vehicle: its own; 0 at rest) [km/h].
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
        unit = CRITERIA[self.criterion][3]
        if unit == "kN":
            amount = (f"{self.value / 1e3:.0f} kN > {self.limit / 1e3:.0f} kN "
                      f"(+{self.excess / 1e3:.0f} kN, +{100.0 * self.excess / self.limit:.0f} %)")
        else:
            amount = f"{self.value:.3f} > {self.limit:.3f} (+{self.excess:.3f})"
        return (f"{self.element} {self.number}: {CRITERIA[self.criterion][1]} {amount} at "
                f"t = {self.time_s:.2f} s, {self.speed_kmh:.1f} km/h (first at "
                f"t = {self.first_time_s:.2f} s)")

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        scale, unit = (1e-3, "_kN") if CRITERIA[self.criterion][3] == "kN" else (1.0, "")
        return {"criterion": self.criterion, self.element: self.number,
                f"value{unit}": self.value * scale, f"limit{unit}": self.limit * scale,
                f"excess{unit}": self.excess * scale, "time_s": self.time_s,
                "speed_kmh": self.speed_kmh, "first_time_s": self.first_time_s}


@dataclass(frozen=True)
class Criterion:
    """One row of the verdicts table.

    Attributes
    ----------
    name : str
        A key of :data:`CRITERIA`.
    assessed : bool
        Limits were given (False: not assessed, e.g. no endurable compressive force).
    limit_min, limit_max : float
        Range of the limits over the train [N] or [-].
    origin : str
        Where the limits come from.
    worst_value : float
        Largest value over the train [N] or [-].
    worst_number : int
        Coupler or vehicle that had it.
    worst_time_s : float
    exceedances : tuple of Exceedance
        Every coupler or vehicle beyond its limit, worst excess (relative) first.
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

    @property
    def passed(self) -> bool | None:
        """True: none beyond; False: some; None: not assessed."""
        return None if not self.assessed else not self.exceedances

    @property
    def status(self) -> str:
        """``PASS``, ``FAIL`` or ``not assessed``."""
        return {True: "PASS", False: "FAIL", None: "not assessed"}[self.passed]

    def _limit_text(self) -> str:
        unit = CRITERIA[self.name][3]
        f = (lambda x: f"{x / 1e3:.0f} kN") if unit == "kN" else (lambda x: f"{x:.3g}")
        if self.limit_min == self.limit_max:
            return f(self.limit_min)
        return f"{f(self.limit_min)} to {f(self.limit_max)}"

    def describe(self, most: int | None = 5) -> list[str]:
        """The row and its exceedances, one line each (the ``most`` worst; None: all)."""
        title, quantity, element, unit = CRITERIA[self.name]
        if not self.assessed:
            return [f"{self.status:<4}  {title}: {self.origin}"]
        worst = (f"{self.worst_value / 1e3:.0f} kN" if unit == "kN"
                 else f"{self.worst_value:.3f}")
        lines = [f"{self.status:<4}  {title}: limit {self._limit_text()} ({self.origin}); "
                 f"worst {quantity} {worst} at {element} {self.worst_number} "
                 f"(t = {self.worst_time_s:.2f} s)"]
        shown = self.exceedances if most is None else self.exceedances[:most]
        lines += [f"        {e.describe()}" for e in shown]
        if len(shown) < len(self.exceedances):
            lines.append(f"        ... and {len(self.exceedances) - len(shown)} more "
                         f"{element}s beyond their limit")
        return lines

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        scale, unit = (1e-3, "_kN") if CRITERIA[self.name][3] == "kN" else (1.0, "")

        def num(x):
            return x * scale if math.isfinite(x) else None
        return {"criterion": self.name, "title": CRITERIA[self.name][0], "status": self.status,
                f"limit_min{unit}": num(self.limit_min), f"limit_max{unit}": num(self.limit_max),
                "origin": self.origin, f"worst{unit}": num(self.worst_value),
                f"worst_{CRITERIA[self.name][2]}": self.worst_number,
                "worst_time_s": self.worst_time_s,
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
        """No assessed criterion failed."""
        return all(c.passed is not False for c in self.criteria)

    def __getitem__(self, name: str) -> Criterion:
        return next(c for c in self.criteria if c.name == name)

    def describe(self, most: int | None = 5) -> list[str]:
        """The table as text lines (per criterion the ``most`` worst exceedances)."""
        return [line for c in self.criteria for line in c.describe(most)]

    def as_dict(self) -> dict:
        """JSON-serialisable."""
        return {"passed": self.passed, "criteria": [c.as_dict() for c in self.criteria]}


def _criterion(name, values, limits, times, speeds, first, element_base, origin) -> Criterion:
    finite = np.isfinite(limits)
    if values.size == 0 or not finite.any():
        return Criterion(name, False, math.inf, math.inf, origin, 0.0, 0, 0.0)
    k = int(np.argmax(values))
    over = np.flatnonzero(finite & (values > limits))
    rel = (values[over] - limits[over]) / limits[over]
    over = over[np.argsort(-rel, kind="stable")]
    element = CRITERIA[name][2]
    first_seen = np.where(first[over] >= 0.0, first[over], times[over])
    ex = tuple(Exceedance(name, element, *row) for row in zip(
        (over + element_base).tolist(), values[over].tolist(), limits[over].tolist(),
        times[over].tolist(), speeds[over].tolist(), first_seen.tolist()))
    return Criterion(name, True, float(limits[finite].min()), float(limits[finite].max()),
                     origin, float(values[k]), k + element_base, float(times[k]), ex)


def judge(limits: TrainLimits, *, peak_draft_N, peak_draft_time_s, draft_speed_kmh,
          peak_buff_N, peak_buff_time_s, buff_speed_kmh, adhesion_demand=None,
          adhesion_time_s=None, adhesion_speed_kmh=None, first_time_s: dict | None = None
          ) -> Verdicts:
    """The verdicts table from a run's per-coupler peaks and per-vehicle adhesion demand.

    Parameters
    ----------
    limits : TrainLimits
    peak_draft_N, peak_buff_N : array_like
        Largest draft (>= 0) and buff (<= 0) force of each coupler [N].
    peak_draft_time_s, peak_buff_time_s : array_like
        When [s].
    draft_speed_kmh, buff_speed_kmh : array_like
        Speed at those times [km/h].
    adhesion_demand, adhesion_time_s, adhesion_speed_kmh : array_like, optional
        Largest adhesion demand of each vehicle [-], when [s] and at what speed [km/h]
        (omitted: the criterion is not assessed).
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

    def first(name, n):
        return np.asarray(first_time_s.get(name, np.full(n, -1.0)), float)
    rows = [_criterion("draft_strength", draft, limits.draft_strength_N,
                       np.asarray(peak_draft_time_s, float), np.asarray(draft_speed_kmh, float),
                       first("draft_strength", draft.size), 1, limits.origin.get(
                           "draft_strength", ""))]
    for name in ("buff_strength", "endurable_lcf"):
        rows.append(_criterion(name, buff, limits.of(name), np.asarray(peak_buff_time_s, float),
                               np.asarray(buff_speed_kmh, float), first(name, buff.size), 1,
                               limits.origin.get(name, "")))
    if adhesion_demand is None or limits.adhesion_limit.size == 0:
        rows.append(Criterion("adhesion", False, math.inf, math.inf,
                              limits.origin.get("adhesion", "not assessed"), 0.0, 0, 0.0))
    else:
        demand = np.asarray(adhesion_demand, float)
        rows.append(_criterion("adhesion", demand, limits.adhesion_limit,
                               np.asarray(adhesion_time_s, float),
                               np.asarray(adhesion_speed_kmh, float),
                               first("adhesion", demand.size), 0,
                               limits.origin.get("adhesion", "")))
    return Verdicts(tuple(rows))


def diagnostic_values(verdicts: Verdicts) -> dict:
    """Key/values of the verdicts for a ``diagnostic_msgs/DiagnosticStatus`` (strings).

    Parameters
    ----------
    verdicts : Verdicts
        E.g. :meth:`Simulator.verdicts() <ltd_brake_ros.simulator.Simulator.verdicts>`.

    Returns
    -------
    dict of str to str
        ``verdicts`` (``PASS``/``FAIL``), then per criterion ``verdict_<name>``: its status
        and, on FAIL, how many couplers or vehicles are beyond their limit and the worst.
    """
    out = {"verdicts": "PASS" if verdicts.passed else "FAIL"}
    for c in verdicts.criteria:
        text = c.status
        if c.exceedances:
            text += (f": {len(c.exceedances)} {CRITERIA[c.name][2]}(s) beyond the limit, worst "
                     f"{c.exceedances[0].describe()}")
        out[f"verdict_{c.name}"] = text
    return out


def flags(verdicts: Verdicts) -> dict:
    """Campaign flags: ``<criterion>_ok`` for the assessed criteria (True: passed).

    Parameters
    ----------
    verdicts : Verdicts

    Returns
    -------
    dict of str to bool
        ``draft_ok``, ``buff_ok``, ``lcf_ok``, ``adhesion_ok``; a criterion not assessed
        counts as passed.
    """
    short = {"draft_strength": "draft_ok", "buff_strength": "buff_ok",
             "endurable_lcf": "lcf_ok", "adhesion": "adhesion_ok"}
    return {short[c.name]: c.passed is not False for c in verdicts.criteria}


# --------------------------------------------------------------------------- during a run


@jit
def _scan(t0, v0, t1, v1, nc, peak_draft, t_draft, peak_buff, t_buff, draft_lim, buff_lim,
          lcf_lim, seen_draft, seen_buff, draft_kmh, buff_kmh, first_draft, first_buff,
          first_lcf, speed, brake, weight, adh_force_lim, adhesion, adh_t, adh_kmh, first_adh):
    """One chunk of :class:`Watch` in one pass (arrays updated in place).

    Returns the number of limits exceeded for the first time.
    """
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
    for i in range(brake.shape[0]):
        f = abs(brake[i])
        d = f / weight[i]
        if d > adhesion[i]:
            adhesion[i] = d
            adh_t[i] = t1
            adh_kmh[i] = abs(speed[i]) * KMH_PER_MS
        if f > adh_force_lim[i] and first_adh[i] < 0.0:
            first_adh[i] = t1
            new += 1
    return new


class Watch:
    """Follows a running simulation for :class:`~ltd_brake_ros.simulator.Simulator`.

    Coupler peaks are the kernel's running extremes; once per chunk one compiled pass
    (:meth:`check`) adds the first exceedance of each limit, the head's speed at each
    exceeding coupler's worst (interpolated within the chunk) and each vehicle's largest
    adhesion demand (at the chunk ends, and as the train comes to rest: :meth:`at_rest`).

    Parameters
    ----------
    limits : TrainLimits
    """

    def __init__(self, limits: TrainLimits):
        self.limits = limits
        nc, n = limits.draft_strength_N.size, limits.adhesion_limit.size
        self.first_time_s = {name: np.full(n if name == "adhesion" else nc, -1.0)
                             for name in CRITERIA}
        self._reported = {name: np.zeros(n if name == "adhesion" else nc, bool)
                          for name in CRITERIA}
        self.draft_speed_kmh = np.zeros(nc)
        self.buff_speed_kmh = np.zeros(nc)
        self._draft_seen = np.zeros(nc)
        self._buff_seen = np.zeros(nc)
        self.adhesion = np.zeros(n)
        self.adhesion_time_s = np.zeros(n)
        self.adhesion_speed_kmh = np.zeros(n)
        self._adhesion_force_N = limits.adhesion_limit * limits.weight_N
        self._no_weight = np.ones(n)

    def copy(self) -> "Watch":
        """An independent copy (the limits are shared: never mutated)."""
        new = object.__new__(Watch)
        new.__dict__.update({k: ({n: a.copy() for n, a in v.items()} if isinstance(v, dict)
                                 else v.copy() if isinstance(v, np.ndarray) else v)
                             for k, v in self.__dict__.items()})
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
        lim, first = self.limits, self.first_time_s
        new = _scan(t0, v0, t1, v1, self._draft_seen.size, kin.peak_draft_N,
                    kin.peak_draft_time_s, kin.peak_buff_N, kin.peak_buff_time_s,
                    lim.draft_strength_N, lim.buff_strength_N, lim.endurable_lcf_N,
                    self._draft_seen, self._buff_seen, self.draft_speed_kmh,
                    self.buff_speed_kmh, first["draft_strength"], first["buff_strength"],
                    first["endurable_lcf"], vehicle_speed_m_s, brake_force_N, lim.weight_N,
                    self._adhesion_force_N, self.adhesion, self.adhesion_time_s,
                    self.adhesion_speed_kmh, first["adhesion"])
        return self._events(kin) if new else []

    def _events(self, kin) -> list[tuple]:
        """The limits first exceeded since the last call, as (time_s, detail) (kin None:
        adhesion only)."""
        out = []
        nc = self._draft_seen.size
        values = {"adhesion": self.adhesion}
        if kin is not None:
            values.update({"draft_strength": kin.peak_draft_N[:nc],
                           "buff_strength": -kin.peak_buff_N[:nc],
                           "endurable_lcf": -kin.peak_buff_N[:nc]})
        speeds = {"draft_strength": self.draft_speed_kmh, "buff_strength": self.buff_speed_kmh,
                  "endurable_lcf": self.buff_speed_kmh, "adhesion": self.adhesion_speed_kmh}
        for name in values:
            first, done = self.first_time_s[name], self._reported[name]
            for j in np.flatnonzero((first >= 0.0) & ~done):
                done[j] = True
                out.append((float(first[j]), self.event_detail(
                    name, int(j), float(values[name][j]), float(self.limits.of(name)[j]),
                    float(speeds[name][j]))))
        return out

    def at_rest(self, t: float, demand_at_rest) -> list[tuple]:
        """Take the adhesion demand as the train comes to rest into account (see module).

        Parameters
        ----------
        t : float
            When the train stopped [s].
        demand_at_rest : ndarray
            :func:`adhesion_demand_at_rest` at the stop.

        Returns
        -------
        list of (time_s, detail)
            As :meth:`check`.
        """
        demand = np.asarray(demand_at_rest, float)
        new = _scan(t, 0.0, t, 0.0, 0, self._draft_seen, self._draft_seen, self._buff_seen,
                    self._buff_seen, self._draft_seen, self._draft_seen, self._draft_seen,
                    self._draft_seen, self._buff_seen, self.draft_speed_kmh,
                    self.buff_speed_kmh, self.first_time_s["draft_strength"],
                    self.first_time_s["buff_strength"], self.first_time_s["endurable_lcf"],
                    np.zeros(demand.size), demand, self._no_weight,
                    self.limits.adhesion_limit, self.adhesion, self.adhesion_time_s,
                    self.adhesion_speed_kmh, self.first_time_s["adhesion"])
        return self._events(None) if new else []

    @staticmethod
    def event_detail(name: str, index: int, value: float, limit: float,
                     speed_kmh: float) -> dict:
        """Detail of a ``limit_exceeded`` event (units in the keys)."""
        element = CRITERIA[name][2]
        number = index + (1 if element == "coupler" else 0)
        if CRITERIA[name][3] == "kN":
            return {"criterion": name, element: number, "force_kN": value / 1e3,
                    "limit_kN": limit / 1e3, "speed_kmh": speed_kmh}
        return {"criterion": name, element: number, "demand": value, "limit": limit,
                "speed_kmh": speed_kmh}

    def verdicts(self, kin, limits: TrainLimits | None = None) -> Verdicts:
        """The verdicts table so far.

        Parameters
        ----------
        kin : KinematicState
            The kernel's state (running coupler peaks).
        limits : TrainLimits, optional
            Other limits to judge the same run by (default: the watched ones); first times
            and coupler speeds are then known only where the watched limits were exceeded too.

        Returns
        -------
        Verdicts
        """
        nc = self._draft_seen.size
        other = limits is not None and limits is not self.limits
        return judge(limits or self.limits, peak_draft_N=kin.peak_draft_N[:nc],
                     peak_draft_time_s=kin.peak_draft_time_s[:nc],
                     draft_speed_kmh=self.draft_speed_kmh, peak_buff_N=kin.peak_buff_N[:nc],
                     peak_buff_time_s=kin.peak_buff_time_s[:nc],
                     buff_speed_kmh=self.buff_speed_kmh, adhesion_demand=self.adhesion,
                     adhesion_time_s=self.adhesion_time_s,
                     adhesion_speed_kmh=self.adhesion_speed_kmh,
                     first_time_s=None if other else self.first_time_s)

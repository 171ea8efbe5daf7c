"""The verdicts table of a run: its criteria, their exceedances, and what other outputs take."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .rules import CRITERIA, Rule, TrainLimits

__all__ = ["Criterion", "Exceedance", "FLAG_NAMES", "NON_PHYSICAL_CRITERIA", "VehicleDemand",
           "Verdicts", "diagnostic_values", "flags", "judge", "merge"]

#: The criteria whose exceedance marks a run non-physical, in order of precedence: a coupling
#: beyond its buffers' limit state, or beyond its coupler model's travel.
NON_PHYSICAL_CRITERIA = ("buffer_limit_state", "coupler_travel")


#: Shown scale, fewest decimals and suffix of each criterion unit (a ratio: three places).
_SHOWN = {"kN": (1e-3, 0, " kN"), "K": (1.0, 0, " K"), "": (1.0, 3, "")}
#: Most decimals a value is shown with.
_MAX_DECIMALS = 12


def _decimals(value: float, limit: float, least: int) -> int:
    """Decimals (``least`` or more) with which a value beyond its limit reads as beyond it:
    value above limit, a positive difference, and a non-zero limit not shown as zero."""
    d = least
    if not (math.isfinite(value) and math.isfinite(limit) and value > limit):
        return d
    while d < _MAX_DECIMALS and (round(value, d) <= round(limit, d)
                                 or round(value - limit, d) <= 0.0
                                 or (limit != 0.0 and round(limit, d) == 0.0)):
        d += 1
    return d


def _percent(excess: float, limit: float) -> str:
    """``, +x %`` of the excess over a non-zero limit, with a non-zero figure; else ``""``."""
    if limit == 0.0 or not math.isfinite(limit):
        return ""
    p = 100.0 * excess / abs(limit)
    d = 0
    while d < _MAX_DECIMALS and round(p, d) <= 0.0:
        d += 1
    return f", +{p:.{d}f} %"


def _amount(unit: str, value: float, limit: float) -> str:
    if unit == "mm":
        return f"{value:.1f} mm"
    if unit == "km/h":
        return f"{value:.3g} km/h from rest"
    if not math.isfinite(limit):
        return f"{value:.3f}"
    scale, least, suffix = _SHOWN.get(unit, _SHOWN[""])
    v, lim = value * scale, limit * scale
    d = _decimals(v, lim, least)
    margin = _percent(v - lim, lim) if unit == "kN" else ""
    return f"{v:.{d}f}{suffix} > {lim:.{d}f}{suffix} (+{v - lim:.{d}f}{suffix}{margin})"


#: JSON scale and key suffix of each criterion unit (``-``: none).
_UNITS = {"kN": (1e-3, "_kN"), "mm": (1.0, "_mm"), "K": (1.0, "_K"), "km/h": (1.0, "_kmh")}


@dataclass(frozen=True)
class Exceedance:
    """One coupler or vehicle beyond its limit.

    Attributes
    ----------
    criterion : str
        A key of :data:`CRITERIA`.
    element : str
        ``coupler`` (numbered from 1 behind the head), ``vehicle`` (from 0 at the head) or
        ``train`` (the whole train, number 0).
    number : int
    value : float
        Its worst force magnitude [N], excursion [mm], adhesion demand [-] or temperature [K].
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
        # a vehicle that moves is never shown at 0.0 km/h: below 1 km/h, two digits that count
        v = self.speed_kmh
        speed = ("" if not math.isfinite(v) else f", {v:.1f} km/h" if v >= 1.0 or v == 0.0
                 else f", {v:.2g} km/h")
        who = "train" if self.element == "train" else f"{self.element} {self.number}"
        if not math.isfinite(self.time_s):  # not of a moment: a design check
            return f"{who}: {rule.quantity} {_amount(rule.unit, self.value, self.limit)}{speed}"
        return (f"{who}: {rule.quantity} "
                f"{_amount(rule.unit, self.value, self.limit)} at t = {self.time_s:.2f} s"
                f"{speed} (first at t = {self.first_time_s:.2f} s)")

    def as_dict(self) -> dict:
        """JSON-serialisable, units in the keys."""
        unit = CRITERIA[self.criterion].unit
        scale, suffix = _UNITS.get(unit, (1.0, ""))
        return {"criterion": self.criterion, self.element: self.number,
                f"value{suffix}": self.value * scale, f"limit{suffix}": self.limit * scale,
                f"excess{suffix}": self.excess * scale,
                "time_s": self.time_s if math.isfinite(self.time_s) else None,
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

    def rule_speed_text(self) -> str:
        """The speed a design check's worst value was computed from (its exceedances'), as
        text."""
        return next((f"{e.speed_kmh:.0f} km/h" for e in self.exceedances
                     if e.number == self.worst_number), "its maximum speed")

    def _shown_decimals(self) -> int:
        """Decimals of the row's worst value and limits: enough to show a worst value beyond
        the highest limit beyond it (:func:`_decimals`)."""
        scale, least, _ = _SHOWN.get(self.rule.unit, _SHOWN[""])
        return _decimals(self.worst_value * scale, self.limit_max * scale, least) \
            if self.exceedances else least

    def _limit_text(self) -> str:
        unit = self.rule.unit
        d = self._shown_decimals()
        f = ((lambda x: f"{x / 1e3:.{d}f} kN") if unit == "kN" else
             (lambda x: f"{x:.{d}f} K") if unit == "K" else
             (lambda x: f"{x:.3g}") if not self.exceedances else (lambda x: f"{x:.{d}f}"))
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
        d = self._shown_decimals()
        worst = (f"{self.worst_value / 1e3:.{d}f} kN" if unit == "kN" else
                 f"{self.worst_value:.1f} mm" if unit == "mm" else
                 f"{self.worst_value:.3g} km/h" if unit == "km/h" else
                 f"{self.worst_value:.{d}f} K ({self.worst_value - 273.15:.{d}f} C)"
                 if unit == "K" else f"{self.worst_value:.{d}f}")
        limit = "" if rule.severity == "INFO" else f"limit {self._limit_text()}; "
        if unit == "mm" and not self.exceedances:
            lines = [f"{self.status:<4}  {rule.title} ({rule.scope}): no coupler went beyond its "
                     "travel"]
        elif unit == "km/h" and not self.exceedances:
            lines = [f"{self.status:<4}  {rule.title} ({rule.scope}): no vehicle moved from "
                     "rest"]
        else:
            lines = [f"{self.status:<4}  {rule.title} ({rule.scope}): {limit}worst "
                     f"{rule.quantity} {worst}"
                     + ("" if rule.element == "train" else
                        f" at {rule.element} {self.worst_number}") + " "
                     + (f"(t = {self.worst_time_s:.2f} s)" if math.isfinite(self.worst_time_s)
                        else f"(a stop from {self.rule_speed_text()})")
                     + (f"; {self.note}" if self.note else "")]
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
        scale, unit = _UNITS.get(rule.unit, (1.0, ""))

        def num(x):
            return x * scale if math.isfinite(x) else None
        return {"criterion": self.name, "title": rule.title, "status": self.status,
                "severity": rule.severity, "scope": rule.scope,
                f"limit_min{unit}": num(self.limit_min), f"limit_max{unit}": num(self.limit_max),
                "origin": self.origin, f"worst{unit}": num(self.worst_value),
                f"worst_{rule.element}": self.worst_number,
                "worst_time_s": self.worst_time_s if math.isfinite(self.worst_time_s) else None,
                "note": self.note,
                "exceedances": [e.as_dict() for e in self.exceedances]}


@dataclass(frozen=True)
class Verdicts:
    """The verdicts table of a run.

    Attributes
    ----------
    criteria : tuple of Criterion
        In :data:`CRITERIA` order.

    Examples
    --------
    >>> run = emergency_stop("scenario_6", 100.0)  # doctest: +SKIP
    >>> run.verdicts.status, run.verdicts["draft_strength"].status  # doctest: +SKIP
    ('PASS', 'PASS')
    >>> print("\\n".join(run.verdicts.describe()))  # doctest: +SKIP
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
        """A coupling went beyond its buffers' limit state or its coupler model's travel: the
        forces of the run there are not physical."""
        return any(c.name in NON_PHYSICAL_CRITERIA and c.exceedances for c in self.criteria)

    @property
    def non_physical_detail(self) -> dict | None:
        """The run's non-physical mark: the first coupling beyond a limit state, when, its
        worst force or excursion, and how many couplings went beyond (None: none did).

        Returns
        -------
        dict or None
            ``criterion``, ``coupler``, ``time_s`` (when it first went beyond [s]),
            ``force_kN`` and ``limit_kN`` (its worst buff force and the limit; None for an
            excursion beyond the travel, then ``beyond_mm``), ``couplings`` (how many went
            beyond either).
        """
        rows = [c for c in self.criteria if c.name in NON_PHYSICAL_CRITERIA and c.exceedances]
        if not rows:
            return None
        first = min((e for c in rows for e in c.exceedances),
                    key=lambda e: (e.first_time_s, NON_PHYSICAL_CRITERIA.index(e.criterion)))
        force = CRITERIA[first.criterion].unit == "kN"
        return {"criterion": first.criterion, "coupler": first.number,
                "time_s": first.first_time_s,
                "force_kN": first.value / 1e3 if force else None,
                "limit_kN": first.limit / 1e3 if force else None,
                "beyond_mm": None if force else first.value,
                "couplings": len({e.number for c in rows for e in c.exceedances})}

    @property
    def non_physical_line(self) -> str | None:
        """:attr:`non_physical_detail` as one line (None: the run is physical)."""
        d = self.non_physical_detail
        if d is None:
            return None
        if d["force_kN"] is not None:
            what = (f"beyond twice its buffers' end force ({d['limit_kN']:.0f} kN) first, at "
                    f"t = {d['time_s']:.2f} s (worst {d['force_kN']:.0f} kN)")
        else:
            what = (f"beyond its coupler model's travel first, at t = {d['time_s']:.2f} s "
                    f"(worst {d['beyond_mm']:.1f} mm)")
        return (f"NON-PHYSICAL: coupling {d['coupler']} went {what}; {d['couplings']} "
                f"coupling(s) did: the forces there are a limit state (buffers solid, the "
                "underframes loaded), not results")

    def __getitem__(self, name: str) -> Criterion:
        return next(c for c in self.criteria if c.name == name)

    def __eq__(self, other) -> bool:
        """The same table: every criterion's fields, a time that is no moment (NaN, a design
        check's) equal to itself."""
        return isinstance(other, Verdicts) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def _key(self) -> str:
        import json

        return json.dumps(self.as_dict(), sort_keys=True)

    def describe(self, most: int | None = 5) -> list[str]:
        """The table as text lines (per criterion the ``most`` worst exceedances)."""
        lines = [line for c in self.criteria for line in c.describe(most)]
        if self.non_physical:
            lines.append(self.non_physical_line)
        return lines

    def __repr__(self) -> str:
        return (f"Verdicts({self.status}: " + ", ".join(f"{c.name} {c.status or 'not assessed'}"
                                                        for c in self.criteria)
                + "; .describe() for the sources)")

    def _repr_html_(self) -> str:
        from .._display import html_table, number

        rows = [(c.name, c.status or "not assessed", number(c.worst_value), c.worst_number,
                 number(c.limit_min), c.origin) for c in self.criteria]
        return html_table(f"Verdicts: {self.status}", rows,
                          ["criterion", "status", "worst", "at", "limit (lowest)", "source"])

    def as_dict(self) -> dict:
        """JSON-serialisable."""
        return {"passed": self.passed, "status": self.status,
                "non_physical": self.non_physical,
                "non_physical_detail": self.non_physical_detail,
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
          holding=None, holding_reason: str = "not assessed: the train has not settled at rest",
          first_time_s: dict | None = None, wheel_temperature=None, runaway=None,
          rail_demand=None,
          runaway_reason: str = "not assessed: the train has not settled at rest") -> Verdicts:
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
        The run's adhesion records (its mean utilised adhesion is noted beside the design
        check, :attr:`TrainLimits.design_adhesion`).
    travel_beyond_mm, travel_time_s, travel_speed_kmh : array_like, optional
        Largest excursion of each coupler beyond its travel [mm] (0: none), when, the head's
        speed then (omitted: the travel is not assessed).
    holding : tuple of array_like, optional
        (force to hold [N], what the vehicle holds [N], when [s]) of each vehicle at its
        worst moment settled at rest (omitted: not assessed, ``holding_reason``).
    holding_reason : str, optional
        Why holding is not assessed when ``holding`` is omitted.
    first_time_s : dict, optional
        Criterion -> per-element time each was first seen beyond its limit [s] (-1: never;
        default: the time of the worst).
    wheel_temperature : tuple of array_like, optional
        (peak wheel temperature [K], when [s]) of each vehicle, NaN where it has no block
        brakes (omitted: not assessed).
    rail_demand : tuple of array_like, optional
        (adhesion demand [-], the rail's available adhesion then [-], when [s], at what speed
        [km/h]) of each vehicle at its largest demand relative to the rail, when -1: never
        braked while moving (omitted: the run check is not assessed).
    runaway : tuple of array_like, optional
        (largest speed after the train had settled, without traction [km/h], when it first
        moved [s], -1: never) of each vehicle (omitted: not assessed, the train never
        settled, ``runaway_reason``).
    runaway_reason : str, optional
        Why the runaway check is not assessed when ``runaway`` is omitted.

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
    for name in ("buff_strength", "endurable_lcf", "buffer_limit_state"):
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
    rows += _adhesion_rows(limits, demand, first, rail_demand)
    if holding is None:
        rows.append(Criterion("standstill_holding", False, math.inf, math.inf,
                              holding_reason if limits.adhesion_limit.size else origin.get(
                                  "standstill_holding", "not assessed"), 0.0, 0, 0.0))
    else:
        need, cap, t = (np.asarray(a, float) for a in holding)
        rows.append(_criterion("standstill_holding", need, cap, t, np.zeros(need.size),
                               first("standstill_holding", need.size), 0,
                               origin.get("standstill_holding", "")))
    if runaway is None or not limits.adhesion_limit.size:
        rows.append(Criterion("runaway", False, math.inf, math.inf,
                              runaway_reason if limits.adhesion_limit.size else
                              origin.get("runaway", "not assessed"), 0.0, 0, 0.0))
    else:
        speed, t = (np.asarray(a, float) for a in runaway)
        rows.append(_criterion("runaway", speed, limits.of("runaway"),
                               np.where(t >= 0.0, t, 0.0), speed, np.asarray(t, float), 0,
                               origin.get("runaway", "")))
    rows.append(_temperature_row(limits, wheel_temperature, first))
    return Verdicts(tuple(rows))


def _temperature_row(limits: TrainLimits, wheel_temperature, first) -> Criterion:
    """The wheel-temperature row: each tread-braked vehicle's peak against its limit."""
    name = "wheel_temperature"
    n = limits.adhesion_limit.size
    if wheel_temperature is None or n == 0:
        return Criterion(name, False, math.inf, math.inf,
                         "not assessed: no wheel temperatures (a recording without the "
                         "vehicles/wheel_temperature topic)", 0.0, 0, 0.0)
    peak, when = (np.asarray(a, float) for a in wheel_temperature)
    lim = limits.of(name)
    assessed = np.isfinite(peak) & np.isfinite(lim)
    if peak.size != n or not assessed.any():
        return Criterion(name, False, math.inf, math.inf,
                         "not assessed: no vehicle with block brakes", 0.0, 0, 0.0)
    return _criterion(name, peak, lim, when, np.full(n, math.nan), first(name, n), 0,
                      limits.origin.get(name, ""), assessed=assessed)


def _adhesion_rows(limits: TrainLimits, d: VehicleDemand | None, first,
                   rail_demand=None) -> list[Criterion]:
    """The adhesion design check (every run, the vehicles' own stops from their maximum
    speed) and the run check (the demand against the declared rail)."""
    n = limits.adhesion_limit.size
    origin = limits.origin
    if n == 0:
        return [Criterion(name, False, math.inf, math.inf, origin.get(name, "not assessed"),
                          0.0, 0, 0.0) for name in ("adhesion", "adhesion_demand")]
    braked = limits.braked if limits.braked.size == n else np.ones(n, bool)
    rows = []
    design = np.asarray(limits.design_adhesion, float)
    note = ""
    if d is not None and math.isfinite(d.initial_speed_kmh):
        mean = np.where(braked, np.asarray(d.mean, float), np.nan)
        if np.isfinite(mean).any():
            k = int(np.nanargmax(mean))
            note = (f"this run's stop from {d.initial_speed_kmh:.0f} km/h: largest mean "
                    f"{mean[k]:.3f} at vehicle {k}")
    if design.size != n or not np.isfinite(design[braked]).any():
        rows.append(Criterion("adhesion", False, math.inf, math.inf,
                              "not assessed: no braked vehicle's stop computed (a recording "
                              "made before the design check was stored)"
                              if design.size != n else "not assessed: no braked vehicle",
                              0.0, 0, 0.0))
    else:
        rows.append(_criterion("adhesion", design, limits.adhesion_limit, np.full(n, math.nan),
                               np.asarray(limits.max_speed_kmh, float), first("adhesion", n), 0,
                               origin.get("adhesion", ""), assessed=braked & np.isfinite(design),
                               note=note))
    if rail_demand is None:
        rows.append(Criterion("adhesion_demand", False, math.inf, math.inf,
                              "not assessed: no braked vehicle moved under its brake",
                              0.0, 0, 0.0))
    else:
        tau, mu, when, kmh = (np.asarray(a, float) for a in rail_demand)
        seen = braked & (when >= 0.0) & np.isfinite(mu)
        row = _criterion("adhesion_demand", tau, mu, when, kmh, first("adhesion_demand", n), 0,
                         origin.get("adhesion_demand", ""), assessed=seen)
        if row.exceedances:
            row = dataclasses.replace(row, note=f"wheel slide expected on a {limits.rail} rail")
        rows.append(row)
    return rows


def merge(tables) -> Verdicts:
    """One table of several parts of a run (its stops and the rest), each judged apart.

    Per criterion: the worst value over the parts, every coupler or vehicle beyond its limit
    in any part (its worst excess, first seen at its earliest), the range of the limits; a
    criterion is assessed where any part assessed it.

    Parameters
    ----------
    tables : sequence of Verdicts
        In time order, with the same criteria.

    Returns
    -------
    Verdicts
    """
    tables = list(tables)
    if len(tables) == 1:
        return tables[0]
    rows = []
    for name in (c.name for c in tables[0].criteria):
        parts = [t[name] for t in tables]
        judged = [c for c in parts if c.assessed]
        if not judged:
            # not assessed anywhere: the last part's reason (the freshest), keeping a
            # largest value shown as information (a mean not judged)
            shown = max(parts, key=lambda c: c.worst_value)
            rows.append(dataclasses.replace(parts[-1], worst_value=shown.worst_value,
                                            worst_number=shown.worst_number,
                                            worst_time_s=shown.worst_time_s))
            continue
        worst = max(judged, key=lambda c: c.worst_value)
        by_element: dict[int, Exceedance] = {}
        for c in judged:
            for e in c.exceedances:
                old = by_element.get(e.number)
                if old is None:
                    by_element[e.number] = e
                    continue
                first = min(old.first_time_s, e.first_time_s)
                keep = e if e.excess > old.excess else old
                by_element[e.number] = dataclasses.replace(keep, first_time_s=first)
        ex = sorted(by_element.values(), key=lambda e: -(e.excess / e.limit if e.limit > 0.0
                                                         else e.excess))
        notes = [c.note for c in judged if c.note]
        rows.append(Criterion(name, True, min(c.limit_min for c in judged),
                              max(c.limit_max for c in judged), worst.origin,
                              worst.worst_value, worst.worst_number, worst.worst_time_s,
                              tuple(ex), worst.note or (notes[-1] if notes else "")))
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
        ``verdicts`` (``PASS``/``WARN``/``FAIL``), then per criterion ``verdict_<name>``: its
        status and, beyond a limit, how many couplers or vehicles and the worst.
    """
    out = {"verdicts": verdicts.status}
    if verdicts.non_physical:
        out["non_physical"] = verdicts.non_physical_line
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
              "endurable_lcf": "lcf_ok", "coupler_travel": "travel_ok",
              "buffer_limit_state": "buffers_ok", "adhesion": "adhesion_ok",
              "standstill_holding": "holding_ok", "runaway": "runaway_ok"}


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

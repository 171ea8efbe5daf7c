"""Verdicts as a run goes: the simulator's watch, and the same records from a recording."""
from __future__ import annotations

import math

import numpy as np

from ..physics.brakes import adhesion
from ..physics.constants import KMH_PER_MS
from ..physics.equations import jit, jit_inline, jit_step
from ..physics.kernel import FULL_APPLICATION, MEAN_ADHESION_MIN_SPEED_M_S
from .rules import (ADHESION_AT_SPEED_LIMIT, ADHESION_SPEED_KMH, CRITERIA,
                    MEAN_ADHESION_MIN_DISTANCE_M, STANDSTILL_SAMPLE_M_S, TrainLimits)
from .table import VehicleDemand, Verdicts, judge

__all__ = ["SampledDemand", "Watch"]


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
        # the run check, as :class:`Watch` keeps it (see there)
        self.first_rail_s = np.full(n, -1.0)
        self._rail = (np.zeros(n), np.zeros(n), np.full(n, np.nan), np.full(n, -1.0),
                      np.zeros(n))
        self._rail_table = np.ascontiguousarray(limits.rail_table, float)
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
        ratio, tau, mu, when, kmh = self._rail
        _rail_scan(np.full(v.size, float(t)), v, f, lim.weight_N, self._rail_table,
                   STANDSTILL_SAMPLE_M_S, ratio, tau, mu, when, kmh, self.first_rail_s)
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

    def rail_demand(self) -> tuple:
        """The run check from the samples (as :meth:`Watch.rail_demand`)."""
        return self._rail[1:]

    def result(self) -> VehicleDemand:
        """The records so far."""
        d = self.demand
        with np.errstate(invalid="ignore", divide="ignore"):
            d.mean = np.where(self._dist >= MEAN_ADHESION_MIN_DISTANCE_M,
                              self._work / self._dist / self.limits.weight_N, np.nan)
        d.mean_distance_m = self._dist.copy()
        return d


@jit_step
def _scan(t0, v0, t1, v1, nc, peak_draft, t_draft, peak_buff, t_buff, draft_lim, buff_lim,
          lcf_lim, state_lim, seen_draft, seen_buff, draft_kmh, buff_kmh, first_draft,
          first_buff, first_lcf, first_state):
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
        if b > buff_lim[j] or b > lcf_lim[j] or b > state_lim[j]:
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
            if b > state_lim[j] and first_state[j] < 0.0:
                first_state[j] = t_buff[j]
                new += 1
    return new


@jit_inline
def _rail_sample(i, when, speed, force, weight, table, v_rest, ratio, tau, mu, t, kmh, first):
    """Vehicle ``i``'s sample at ``when`` [s] (its speed [m/s] and brake force [N]) in the run
    check of :func:`_rail_scan`: 1 if it is beyond the rail's adhesion for the first time, else
    0."""
    v = abs(speed)
    if v <= v_rest or weight[i] <= 0.0 or force <= 0.0 or when <= 0.0:
        return 0
    m, _dm = adhesion.mu_of(table, v)
    d = force / weight[i]
    r = d / m
    if r > ratio[i]:
        ratio[i], tau[i], mu[i], t[i], kmh[i] = r, d, m, when, v * KMH_PER_MS
    if r > 1.0 and first[i] < 0.0:
        first[i] = when
        return 1
    return 0


@jit
def _rail_scan(when, speed, force, weight, table, v_rest, ratio, tau, mu, t, kmh, first):
    """The run check at one sample of each vehicle (its own time, speed [m/s] and brake force
    [N]): its demand against the rail's available adhesion, records updated in place.
    Returns the number of vehicles beyond the rail's adhesion for the first time."""
    new = 0
    for i in range(force.shape[0]):
        new += _rail_sample(i, when[i], speed[i], force[i], weight, table, v_rest, ratio, tau,
                            mu, t, kmh, first)
    return new


@jit_step
def _chunk_vehicles(t1, speed, force, fast_t, fast_v, fast_f, slow_t, slow_v, slow_f, weight,
                    table, v_rest, ratio, tau, mu, t, kmh, first, end_t, end_kmh, checked_to):
    """The vehicles' part of one chunk of :class:`Watch` in one pass (records updated in
    place): the run check at the chunk's end (``t1`` [s], each vehicle's ``speed`` [m/s] and
    ``force`` [N]) and at the kernel's peaks of the brake force above (``fast_*``: when,
    speed, force) and below 30 km/h (``slow_*``), each vehicle's samples in that order; and
    the end of its braked part (``end_t``, ``end_kmh``: the last chunk end it ran at 5 km/h or
    faster, and its speed then). A peak no later than ``checked_to`` [s], the end of the last
    chunk checked, was checked then as it is (the kernel sets a peak's time to that of the
    step that changes it): checked again, it would change nothing. Returns the number of
    vehicles beyond the rail's adhesion for the first time."""
    new = 0
    for i in range(weight.shape[0]):
        new += _rail_sample(i, t1, speed[i], force[i], weight, table, v_rest, ratio, tau, mu, t,
                            kmh, first)
        if fast_t[i] > checked_to:
            new += _rail_sample(i, fast_t[i], fast_v[i], fast_f[i], weight, table, v_rest,
                                ratio, tau, mu, t, kmh, first)
        if slow_t[i] > checked_to:
            new += _rail_sample(i, slow_t[i], slow_v[i], slow_f[i], weight, table, v_rest,
                                ratio, tau, mu, t, kmh, first)
        v = abs(speed[i])
        if v >= MEAN_ADHESION_MIN_SPEED_M_S:
            end_t[i] = t1
            end_kmh[i] = v * KMH_PER_MS
    return new


@jit_step
def _check_chunk(t0, v0, t1, v1, nc, peak_draft, t_draft, peak_buff, t_buff, draft_lim,
                 buff_lim, lcf_lim, state_lim, seen_draft, seen_buff, draft_kmh, buff_kmh,
                 first_draft, first_buff, first_lcf, first_state, vehicles, heat_updated, speed,
                 force, fast_t, fast_v, fast_f, slow_t, slow_v, slow_f, weight, table, v_rest,
                 ratio, tau, mu, t, kmh, first, end_t, end_kmh, checked_to, wheel_peak,
                 wheel_lim, first_hot, wheel_kmh):
    """One chunk of :class:`Watch` in one call: the couplers (:func:`_scan`) and, with
    ``vehicles``, the vehicles (:func:`_chunk_vehicles`) and, with ``heat_updated`` (the
    temperatures were updated since the last check), each wheel's temperature peak first
    beyond its limit (at the chunk's end ``t1`` and its speed then). Returns the number of
    limits exceeded for the first time."""
    new = _scan(t0, v0, t1, v1, nc, peak_draft, t_draft, peak_buff, t_buff, draft_lim,
                buff_lim, lcf_lim, state_lim, seen_draft, seen_buff, draft_kmh, buff_kmh,
                first_draft, first_buff, first_lcf, first_state)
    if vehicles:
        new += _chunk_vehicles(t1, speed, force, fast_t, fast_v, fast_f, slow_t, slow_v,
                               slow_f, weight, table, v_rest, ratio, tau, mu, t, kmh, first,
                               end_t, end_kmh, checked_to)
        if heat_updated:
            for i in range(weight.shape[0]):
                if wheel_peak[i] > wheel_lim[i] and first_hot[i] < 0.0:
                    first_hot[i] = t1
                    wheel_kmh[i] = abs(speed[i]) * KMH_PER_MS
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
        sizes = {"coupler": nc, "vehicle": n, "train": 1}
        self.first_time_s = {name: np.full(sizes[CRITERIA[name].element], -1.0)
                             for name in CRITERIA}
        self._reported = {name: np.zeros(a.size, bool) for name, a in self.first_time_s.items()}
        self.draft_speed_kmh = np.zeros(nc)
        self.buff_speed_kmh = np.zeros(nc)
        self._draft_seen = np.zeros(nc)
        self._buff_seen = np.zeros(nc)
        self.demand = VehicleDemand.empty(n)
        self.standstill_m_s = float(standstill_m_s)
        self._buffer_limit_N = np.ascontiguousarray(limits.of("buffer_limit_state"), float)
        # the run check: each vehicle's largest demand relative to the rail's adhesion, the
        # demand and the rail's adhesion then, when (-1: never braked while moving) and at
        # what speed
        self._rail_ratio = np.zeros(n)
        self._rail_tau, self._rail_mu = np.zeros(n), np.full(n, np.nan)
        self._rail_t, self._rail_kmh = np.full(n, -1.0), np.zeros(n)
        self._rail_table = np.ascontiguousarray(limits.rail_table, float)
        # when each vehicle's braked part ended (its speed fell below 5 km/h), and at what speed
        self._mean_end_t = np.zeros(n)
        self._mean_end_kmh = np.zeros(n)
        # each vehicle's wheel-temperature limit, and its speed when first beyond it
        self._wheel_limit_K = np.ascontiguousarray(limits.of("wheel_temperature"), float)
        self._wheel_kmh = np.full(n, np.nan)
        self._heat_update_s = -1.0  # the temperature peaks' last update seen
        self._checked_to = -math.inf  # the end of the last chunk checked [s]

    def copy(self) -> "Watch":
        """An independent copy (the limits are shared: never mutated)."""
        new = object.__new__(Watch)
        for k, v in self.__dict__.items():
            if isinstance(v, dict):
                v = {n: a.copy() for n, a in v.items()}
            elif isinstance(v, np.ndarray):
                v = v.copy()
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
        lim, first = self.limits, self.first_time_s
        vehicles = lim.weight_N.size == vehicle_speed_m_s.size
        # the wheels' temperature peaks change at their updates only (brakes.thermal, every
        # second or so): first seen beyond the limit at the end of the chunk of an update
        heat_updated = bool(vehicles and kin.heat_clock_s[0] != self._heat_update_s)
        if heat_updated:
            self._heat_update_s = float(kin.heat_clock_s[0])
        # the couplers; the demand against the rail at the chunk's end and at the kernel's
        # peaks of the brake force above and below 30 km/h (each at its own speed and time);
        # the end of each vehicle's braked part (the last chunk end it ran at 5 km/h+); the
        # wheels' temperatures: one compiled call
        new = _check_chunk(
            t0, v0, t1, v1, self._draft_seen.size, kin.peak_draft_N, kin.peak_draft_time_s,
            kin.peak_buff_N, kin.peak_buff_time_s, lim.draft_strength_N, lim.buff_strength_N,
            lim.endurable_lcf_N, self._buffer_limit_N, self._draft_seen, self._buff_seen,
            self.draft_speed_kmh, self.buff_speed_kmh, first["draft_strength"],
            first["buff_strength"], first["endurable_lcf"], first["buffer_limit_state"],
            vehicles, heat_updated, vehicle_speed_m_s, brake_force_N,
            kin.peak_brake_fast_time_s, kin.peak_brake_fast_speed_m_s, kin.peak_brake_fast_N,
            kin.peak_brake_slow_time_s, kin.peak_brake_slow_speed_m_s, kin.peak_brake_slow_N,
            lim.weight_N, self._rail_table, self.standstill_m_s, self._rail_ratio,
            self._rail_tau, self._rail_mu, self._rail_t, self._rail_kmh,
            first["adhesion_demand"], self._mean_end_t, self._mean_end_kmh, self._checked_to,
            kin.peak_wheel_temperature_K, self._wheel_limit_K, first["wheel_temperature"],
            self._wheel_kmh)
        if vehicles:
            self._checked_to = float(t1)
        return self._events(kin) if new else []

    def rail_demand(self) -> tuple:
        """Each vehicle's largest adhesion demand relative to the rail's available adhesion:
        (demand [-], the rail's adhesion then [-], when [s], -1: never braked while moving,
        at what speed [km/h])."""
        return self._rail_tau, self._rail_mu, self._rail_t, self._rail_kmh

    def start(self, speed_m_s: float) -> None:
        """The brake command came, with the head at ``speed_m_s`` [m/s]."""
        if not math.isfinite(self.demand.initial_speed_kmh):
            self.demand.initial_speed_kmh = abs(float(speed_m_s)) * KMH_PER_MS

    def _events(self, kin) -> list[tuple]:
        """The limits first exceeded since the last call, as (time_s, detail)."""
        out = []
        nc = self._draft_seen.size
        n = self._rail_tau.size
        values = {"draft_strength": kin.peak_draft_N[:nc], "buff_strength": -kin.peak_buff_N[:nc],
                  "endurable_lcf": -kin.peak_buff_N[:nc],
                  "buffer_limit_state": -kin.peak_buff_N[:nc], "adhesion_demand": self._rail_tau,
                  "wheel_temperature": kin.peak_wheel_temperature_K[:n]}
        speeds = {"draft_strength": self.draft_speed_kmh, "buff_strength": self.buff_speed_kmh,
                  "endurable_lcf": self.buff_speed_kmh,
                  "buffer_limit_state": self.buff_speed_kmh, "adhesion_demand": self._rail_kmh,
                  "wheel_temperature": self._wheel_kmh}
        for name in values:
            first, done = self.first_time_s[name], self._reported[name]
            limit = self._rail_mu if name == "adhesion_demand" else self.limits.of(name)
            for j in np.flatnonzero((first >= 0.0) & ~done):
                done[j] = True
                out.append((float(first[j]), self.event_detail(
                    name, int(j), float(values[name][j]), float(limit[j]),
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
        if rule.unit == "K":
            return {"criterion": name, rule.element: number, "temperature_K": value,
                    "limit_K": limit, "speed_kmh": speed_kmh}
        if rule.unit == "km/h":  # a speed from rest: the value is the speed
            return {"criterion": name, rule.element: number, "speed_kmh": value,
                    "limit_kmh": limit}
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

    def verdicts(self, kin, limits: TrainLimits | None = None, wheel_temperature=None,
                 holding=None, runaway=None) -> Verdicts:
        """The verdicts table so far.

        Parameters
        ----------
        kin : KinematicState
            The kernel's state (running coupler peaks and excursions, brake work, the wheels'
            temperature peaks).
        limits : TrainLimits, optional
            Other limits to judge the same run by (default: the watched ones); first times
            and coupler speeds are then known only where the watched limits were exceeded too.
        wheel_temperature : tuple of ndarray, optional
            Each vehicle's peak wheel temperature [K] and when [s] (default: the kernel's
            peaks at its updates).
        holding, runaway : tuple of ndarray, optional
            The standstill's records (:func:`~ltd_brake_ros.verdicts.judge`; omitted: not
            assessed).

        Returns
        -------
        Verdicts
        """
        nc = self._draft_seen.size
        other = limits is not None and limits is not self.limits
        lim = limits or self.limits
        beyond = np.asarray(kin.beyond_range_m[:nc], float) * 1e3
        t_beyond = np.asarray(kin.beyond_range_time_s[:nc], float)
        n = self.demand.at_speed.size
        if wheel_temperature is None:
            wheel_temperature = (kin.peak_wheel_temperature_K[:n],
                                 kin.peak_wheel_temperature_time_s[:n])
        return judge(lim, peak_draft_N=kin.peak_draft_N[:nc],
                     peak_draft_time_s=kin.peak_draft_time_s[:nc],
                     draft_speed_kmh=self.draft_speed_kmh, peak_buff_N=kin.peak_buff_N[:nc],
                     peak_buff_time_s=kin.peak_buff_time_s[:nc],
                     buff_speed_kmh=self.buff_speed_kmh,
                     demand=self.demand_of(kin) if lim.adhesion_limit.size else None,
                     travel_beyond_mm=beyond, travel_time_s=np.maximum(t_beyond, 0.0),
                     travel_speed_kmh=np.full(nc, math.nan), holding=holding,
                     runaway=runaway, wheel_temperature=wheel_temperature,
                     # the demand was judged against the watched limits' rail
                     rail_demand=self.rail_demand() if np.array_equal(
                         lim.rail_table, self.limits.rail_table) else None,
                     first_time_s=None if other else dict(
                         self.first_time_s, coupler_travel=np.asarray(
                             kin.out_of_range_time_s[:nc], float)))

"""The simulator: owns time and state, advances the train in chunks.

Contract
--------
1. Build it from validated inputs (:class:`~ltd_brake_ros.inputs.Consist`,
   :class:`~ltd_brake_ros.inputs.BrakeParams`, :class:`~ltd_brake_ros.inputs.CouplerLUT`) and an
   initial speed; every vehicle starts at that speed with unloaded couplers.
2. :meth:`Simulator.advance` integrates one chunk of simulated time under the given
   :class:`Commands` and returns a :class:`Snapshot`. Chunks of any length give the same result
   as one long call, within the integrator tolerance (exactly the same when both are multiples
   of the step).
3. A step whose Newton iteration does not converge raises :class:`SimulationError`; the state is
   left at the start of the failed chunk's last good step and :meth:`reset` recovers.
4. Counters (``steps``, ``newton_iterations``, ...) report what the integration cost.

Sign conventions: vehicle 0 is the head; speeds forward positive; coupler j (numbered from 1
behind the head) carries force draft/tension positive, buff negative; brake forces are
retarding forces, positive.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .physics import kernel
from .inputs.commands import COMMAND_RANGES
from .inputs import BlockBrake, BrakeParams, Consist, CouplerLUT, DiscBrake, InputError, Track
from .physics.constants import STANDSTILL_M_S
from .physics import (ARR_BG, ARR_BGU, BRAKE_BLOCKS, BRAKE_DISC, BRAKE_NONE, KMH_PER_MS,
                      curve_resistance_N_per_kN, sum_block_force_kN, train_braked_weight_percent)

LN20 = math.log(20.0)


class SimulationError(RuntimeError):
    """The integration could not proceed (a Newton iteration did not converge)."""


@dataclass(frozen=True)
class Commands:
    """Driver and train-control inputs held constant over one chunk.

    Attributes
    ----------
    emergency : bool
        Emergency brake applied. A change from False to True starts the application at the
        start of the chunk (t_app counts from there); True to False releases.
    brake_demand : float
        Service brake demand, 0 (released) to 1 (full service force = the emergency maximum
        block force). Overridden by ``emergency``. Not validated against measurements.
    traction : float
        Traction (0 to 1) or dynamic-brake (-1 to 0) demand, as a fraction of the powered
        vehicles' available effort.

    Raises
    ------
    ValueError
        A value is not finite or out of range (the message names the field).
    """

    emergency: bool = False
    brake_demand: float = 0.0
    traction: float = 0.0

    def __post_init__(self):
        for name, (lo, hi) in COMMAND_RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{name} must be between {lo:g} and {hi:g}, got {value}")


@dataclass(frozen=True)
class Event:
    """Something that happened during the run.

    Attributes
    ----------
    time_s : float
        Simulated time [s].
    kind : str
        ``brake_applied``, ``brake_released``, ``stopped`` or ``coupler_out_of_lut``.
    detail : dict
        Kind-specific values (units in the keys).
    """

    time_s: float
    kind: str
    detail: dict = field(default_factory=dict)

    def describe(self) -> str:
        """One-line human description."""
        d = self.detail
        if self.kind == "stopped":
            return (f"t = {self.time_s:.2f} s: train stopped, stopping distance "
                    f"{d['stopping_distance_m']:.1f} m")
        if self.kind == "coupler_out_of_lut":
            return (f"t = {self.time_s:.2f} s: coupler {d['coupler']} left the coupler table, "
                    f"{d['beyond_table_mm']:.1f} mm beyond its end within the chunk; forces "
                    "there are extrapolated with the end slopes")
        return f"t = {self.time_s:.2f} s: {self.kind.replace('_', ' ')}"


@dataclass(frozen=True)
class Snapshot:
    """State of the train at the end of a chunk.

    Attributes
    ----------
    time_s : float
        Simulated time [s].
    position_m : ndarray
        Chainage of each vehicle's centre; the head's front starts at 0 [m].
    speed_m_s : ndarray
        Speed of each vehicle, forward positive [m/s].
    brake_force_N : ndarray
        Air-brake retarding force of each vehicle, positive [N].
    traction_force_N : ndarray
        Traction (positive) or dynamic-brake (negative) force of each vehicle [N].
    block_force_N : ndarray
        Total force on the brake blocks/pads of each vehicle, F_B,tot [N].
    coupler_force_N : ndarray
        Force of couplers 1..n-1, draft positive, buff negative [N].
    events : tuple of Event
        Events that happened during this chunk.
    stopped : bool
        Every vehicle is at standstill (slower than the simulator's ``standstill_m_s``).
    """

    time_s: float
    position_m: np.ndarray
    speed_m_s: np.ndarray
    brake_force_N: np.ndarray
    traction_force_N: np.ndarray
    block_force_N: np.ndarray
    coupler_force_N: np.ndarray
    events: tuple = ()
    stopped: bool = False


@dataclass(frozen=True)
class CouplerPeaks:
    """The largest draft and buff force of a run and where and when they occurred.

    Attributes
    ----------
    draft_N : float
        Largest draft (tension) force, >= 0 [N] (0 if no coupler was ever in draft).
    draft_coupler : int
        Coupler that carried it (1 = behind the head; 0 when the train has no coupler).
    draft_time_s : float
        When [s].
    buff_N : float
        Largest buff (compression) force, <= 0 [N].
    buff_coupler : int
        Coupler that carried it.
    buff_time_s : float
        When [s].
    """

    draft_N: float = 0.0
    draft_coupler: int = 0
    draft_time_s: float = 0.0
    buff_N: float = 0.0
    buff_coupler: int = 0
    buff_time_s: float = 0.0

    @classmethod
    def from_arrays(cls, draft_N, draft_time_s, buff_N, buff_time_s) -> "CouplerPeaks":
        """Summarise per-coupler running extremes.

        Parameters
        ----------
        draft_N, buff_N : array_like
            Largest draft (>= 0) and buff (<= 0) force of each coupler [N].
        draft_time_s, buff_time_s : array_like
            When each occurred [s].

        Returns
        -------
        CouplerPeaks
        """
        draft, buff = np.asarray(draft_N, float), np.asarray(buff_N, float)
        if draft.size == 0:
            return cls()
        jd, jb = int(np.argmax(draft)), int(np.argmin(buff))
        return cls(float(draft[jd]), jd + 1, float(np.asarray(draft_time_s)[jd]),
                   float(buff[jb]), jb + 1, float(np.asarray(buff_time_s)[jb]))


class Simulator:
    """Longitudinal dynamics of one train under the empirical UIC air brake.

    Parameters
    ----------
    consist : Consist
        The train, head first.
    speed_kmh : float
        Initial speed of every vehicle [km/h].
    params : BrakeParams, optional
        Brake-model parameters (default: Table 3 and the paper's K0).
    lut : CouplerLUT
        Coupler characteristic (default: the shipped buffer-hook table).
    track : Track, optional
        Track profile (default: level straight track).
    step_s : float, optional
        Largest integration step [s]; chunks are split into equal steps no longer than this.
    resistance : bool, optional
        Apply running resistance, Eq. 2.
    brakes : bool, optional
        Apply air-brake forces (False keeps the brake state but no force reaches the wheels).
    max_newton_iter : int, optional
        Newton iterations allowed per step before the step counts as failed.
    newton_rtol : float, optional
        Residual tolerance, relative to each vehicle's weight.
    standstill_m_s : float, optional
        The train counts as stopped once every vehicle is slower than this [m/s].
    stick_band_m_s : float, optional
        Half-width of the standstill band [m/s]: brake and running resistance reach their full
        value at this speed and hold a stopped vehicle against any smaller force; it creeps at
        most at this speed times (force / holding force).
    """

    def __init__(self, consist: Consist, speed_kmh: float, params: BrakeParams | None = None,
                 lut: CouplerLUT | None = None, track: Track | None = None, *,
                 step_s: float = 0.01,
                 resistance: bool = True, brakes: bool = True, max_newton_iter: int = 100,
                 newton_rtol: float = 1e-9, standstill_m_s: float = STANDSTILL_M_S,
                 stick_band_m_s: float = 1e-5):
        if lut is None:
            from .inputs import load_coupler_lut

            lut = load_coupler_lut()
        params = params or BrakeParams()
        if not (math.isfinite(speed_kmh) and 0.0 <= speed_kmh <= 400.0):
            raise InputError("speed_kmh", "", f"must be between 0 and 400 km/h, got {speed_kmh}")
        if not (math.isfinite(step_s) and 1e-5 <= step_s <= 0.5):
            raise InputError("step_s", "", f"must be between 1e-5 and 0.5 s, got {step_s}")
        self.consist, self.params, self.lut = consist, params, lut
        self.track = track or Track()
        self.speed_kmh = float(speed_kmh)
        self.step_s = float(step_s)
        self.max_newton_iter = int(max_newton_iter)
        self.newton_rtol = float(newton_rtol)
        self.standstill_m_s = float(standstill_m_s)
        self.stick_band_m_s = float(stick_band_m_s)
        self._resist = 1.0 if resistance else 0.0
        self._brakes = bool(brakes)
        vs = consist.vehicles
        n = len(vs)
        self.n = n
        self.mass_kg = np.array([v.mass_kg for v in vs])
        self.length_m = np.array([v.length_m for v in vs])
        self._meff = self.mass_kg * np.array([v.inertia_factor for v in vs])
        self._axles = np.array([float(v.axles) for v in vs])
        self._kind = np.zeros(n, np.int64)
        self._blocks = np.ones(n)
        self._arr = np.zeros(n, np.int64)
        self._mu_disc = np.zeros(n)
        #: Maximum block force of each vehicle, 1000 * sum(F_dyn) (Eq. 4 inverted) [N].
        self.max_block_force_N = np.zeros(n)
        for i, v in enumerate(vs):
            b = v.brake
            if isinstance(b, BlockBrake):
                self._kind[i] = BRAKE_BLOCKS
                self._blocks[i] = b.blocks
                self._arr[i] = ARR_BGU if b.arrangement == "Bgu" else ARR_BG
                s = sum_block_force_kN(v.braked_weight_t, float(b.blocks), params.k0,
                                       int(self._arr[i]))
                if not math.isfinite(s):
                    raise InputError(consist.source, f"vehicles[{i}].brake",
                                     "Eq. 4 could not be inverted for this braked weight")
                self.max_block_force_N[i] = 1000.0 * s
            elif isinstance(b, DiscBrake):
                self._kind[i] = BRAKE_DISC
                self._mu_disc[i] = b.mu_eff if b.mu_eff is not None else params.mu_eff
                k = b.k if b.k is not None else params.k_loco
                self.max_block_force_N[i] = 1000.0 * v.braked_weight_t * 9.81 / k
            else:
                self._kind[i] = BRAKE_NONE
        # vehicle centres behind the head's front [m]; Eq. 6 delay from the head's centre
        front = np.concatenate(([0.0], np.cumsum(self.length_m)[:-1]))
        self._centre_offset_m = front + 0.5 * self.length_m
        distance = self._centre_offset_m - self._centre_offset_m[0]
        self.brake_delay_s = params.t_app_s + (0.0 * distance if params.simultaneous
                                               else distance / params.v_air_m_s)
        self._fmax = self.max_block_force_N if self._brakes else np.zeros(n)
        # brake position: G fills (and releases) slower; service applications scale alike
        in_g = np.array([v.brake_position == "G" for v in vs])
        fill = np.where(in_g, params.t_fill_G_s, params.t_fill_s)
        self._tau_emergency = fill / LN20
        self._tau_service = params.t_service_fill_s * fill / params.t_fill_s / LN20
        self._tau_release = np.where(in_g, params.t_release_G_s, params.t_release_s) / LN20
        # traction and dynamic brake of powered vehicles (zeros elsewhere)
        tr = [v.traction for v in vs]
        self._tr = {name: np.array([getattr(t, name) if t else 0.0 for t in tr])
                    for name in ("max_force_N", "max_power_W", "brake_max_force_N",
                                 "brake_max_power_W", "rate_limit_N_s", "time_constant_s",
                                 "fade_speed_m_s")}
        self._tr["time_constant_s"][self._tr["time_constant_s"] <= 0] = 1.0
        self._tr["fade_speed_m_s"][self._tr["fade_speed_m_s"] <= 0] = 1.0
        tk = self.track
        self._tk_s = np.asarray(tk.chainage_m, float)
        self._tk_grad = np.asarray(tk.gradient_permille, float)
        self._tk_rc = np.array([curve_resistance_N_per_kN(r) for r in tk.radius_m])
        xs = np.asarray(lut.deflection_m, float)
        self._xs, self._fl, self._fu = xs, np.asarray(lut.loading_N, float), np.asarray(
            lut.unloading_N, float)
        self.fext_N = np.zeros(n)
        self.reset()

    # ------------------------------------------------------------------ state

    def reset(self) -> Snapshot:
        """Return to the initial state: initial speed, brake released, time 0.

        Returns
        -------
        Snapshot
        """
        n = self.n
        v0 = self.speed_kmh / KMH_PER_MS
        self.time_s = 0.0
        self._hp = 0.0
        self._x = np.zeros(n)
        self._v = np.full(n, v0)
        self._xp = np.zeros(n)
        self._vp = np.full(n, v0)
        self._stuck = self._v == 0.0
        self._fb = np.zeros(n)
        self._lvl = np.zeros(n)
        self._lkind = np.zeros(n, np.int64)
        self._nxt = np.zeros(n, np.int64)
        self._ev_t = np.zeros(8)
        self._ev_lvl = np.zeros(8)
        self._ev_kind = np.zeros(8, np.int64)
        self._n_ev = 0
        self._level = (0.0, 0)  # brake level and kind last commanded
        self._ftr = np.zeros(n)
        self._traction_cmd = 0.0
        self._fc = np.zeros(max(n - 1, 1))
        self._fbrake = np.zeros(n)
        nc = max(n - 1, 1)
        self._peak_draft = np.zeros(nc)
        self._t_draft = np.zeros(nc)
        self._peak_buff = np.zeros(nc)
        self._t_buff = np.zeros(nc)
        self._lut_out = np.zeros(nc)
        self._t_lut_out = np.full(nc, -1.0)
        self._stats = np.zeros(6, np.int64)
        self._emergency = False
        self.command_time_s: float | None = None
        self._x_cmd = 0.0
        self.stop_time_s: float | None = None
        self.stopping_distance_m: float | None = None
        self._reported_lut = np.zeros(nc, bool)
        self._failed = False
        return self.snapshot()

    @property
    def steps(self) -> int:
        """Integration steps taken since the last reset."""
        return int(self._stats[0])

    @property
    def newton_iterations(self) -> int:
        """Newton iterations (linear solves) since the last reset."""
        return int(self._stats[1])

    @property
    def max_newton_iterations(self) -> int:
        """Most Newton iterations any single step needed."""
        return int(self._stats[2])

    @property
    def stopped(self) -> bool:
        """True when every vehicle is slower than ``standstill_m_s``."""
        return bool(np.all(np.abs(self._v) <= self.standstill_m_s))

    @property
    def peak_draft_N(self) -> np.ndarray:
        """Largest draft (tension) force per coupler so far [N] (0 if never in draft)."""
        return self._peak_draft[: self.n - 1].copy()

    @property
    def peak_buff_N(self) -> np.ndarray:
        """Largest buff (compression) force per coupler so far, negative [N]."""
        return self._peak_buff[: self.n - 1].copy()

    @property
    def peak_draft_time_s(self) -> np.ndarray:
        """Time of each coupler's peak draft force [s]."""
        return self._t_draft[: self.n - 1].copy()

    @property
    def peak_buff_time_s(self) -> np.ndarray:
        """Time of each coupler's peak buff force [s]."""
        return self._t_buff[: self.n - 1].copy()

    @property
    def lut_excursion_m(self) -> np.ndarray:
        """Largest deflection beyond the coupler table per coupler [m] (0 if never)."""
        return self._lut_out[: self.n - 1].copy()

    def coupler_peaks(self) -> CouplerPeaks:
        """Largest draft and buff force since the last reset, where and when.

        Returns
        -------
        CouplerPeaks
        """
        return CouplerPeaks.from_arrays(self.peak_draft_N, self.peak_draft_time_s,
                                        self.peak_buff_N, self.peak_buff_time_s)

    def braked_weight_percent(self) -> float:
        """Train braked-weight percentage lambda_train, Eq. 11 [%]."""
        return train_braked_weight_percent([v.braked_weight_t for v in self.consist.vehicles],
                                           self.mass_kg / 1000.0, self.consist.length_m)

    def snapshot(self, events: tuple = ()) -> Snapshot:
        """Current state as a :class:`Snapshot`.

        Parameters
        ----------
        events : tuple of Event, optional
            Events to attach.

        Returns
        -------
        Snapshot
        """
        n = self.n
        return Snapshot(self.time_s, self.track.start_chainage_m + self._x - self._centre_offset_m,
                        self._v.copy(), self._fbrake.copy() if self._brakes else np.zeros(n),
                        self._ftr.copy(), self._fb.copy(), self._fc[: n - 1].copy(),
                        tuple(events), self.stopped)

    # ------------------------------------------------------------------ integration

    def _add_event(self, level: float, kind: int) -> None:
        # drop events every vehicle has already received
        done = int(self._nxt.min())
        if done:
            m = self._n_ev - done
            self._ev_t[:m] = self._ev_t[done:self._n_ev].copy()
            self._ev_lvl[:m] = self._ev_lvl[done:self._n_ev].copy()
            self._ev_kind[:m] = self._ev_kind[done:self._n_ev].copy()
            self._n_ev = m
            self._nxt -= done
        if self._n_ev == self._ev_t.size:
            self._ev_t = np.concatenate((self._ev_t, np.zeros(self._ev_t.size)))
            self._ev_lvl = np.concatenate((self._ev_lvl, np.zeros(self._ev_lvl.size)))
            self._ev_kind = np.concatenate((self._ev_kind, np.zeros(self._ev_kind.size, np.int64)))
        self._ev_t[self._n_ev] = self.time_s
        self._ev_lvl[self._n_ev] = level
        self._ev_kind[self._n_ev] = kind
        self._n_ev += 1

    def _apply_commands(self, commands: Commands, events: list) -> None:
        if (commands.emergency or commands.brake_demand > 0.0) and self.command_time_s is None:
            # the stopping distance counts from the brake command that leads to the stop
            self.command_time_s = self.time_s
            self._x_cmd = float(self._x[0])
        if commands.emergency and not self._emergency:
            self._emergency = True
            events.append(Event(self.time_s, "brake_applied"))
        elif not commands.emergency and self._emergency:
            self._emergency = False
            events.append(Event(self.time_s, "brake_released"))
        level = (1.0, 0) if self._emergency else (float(commands.brake_demand), 1)
        if level[0] == 0.0 and self.stop_time_s is None:
            self.command_time_s = None  # released before standstill: a new stop counts anew
        if level != self._level:
            self._level = level
            self._add_event(*level)
        self._traction_cmd = float(commands.traction)

    def advance(self, duration_s: float, commands: Commands | None = None) -> Snapshot:
        """Integrate one chunk of simulated time.

        Parameters
        ----------
        duration_s : float
            Simulated time to advance [s] (> 0).
        commands : Commands, optional
            Inputs for this chunk; ``None`` keeps the previous ones.

        Returns
        -------
        Snapshot
            State at the end of the chunk, with the events that happened in it.

        Raises
        ------
        SimulationError
            A step did not converge.
        """
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ValueError(f"duration_s must be a positive finite number, got {duration_s}")
        if self._failed:
            raise SimulationError("the simulator stopped after a failed step; call reset()")
        events: list[Event] = []
        if commands is not None:
            self._apply_commands(commands, events)
        nsteps = max(1, math.ceil(duration_s / self.step_s - 1e-9))
        h = duration_s / nsteps
        remaining = nsteps
        tr = self._tr
        while remaining:
            watch = self.stop_time_s is None and self.command_time_s is not None
            code, t, hp, done = kernel.run_steps(
                remaining, h, self.time_s, self._hp, self._x, self._v, self._xp, self._vp,
                self._stuck, self._meff, self.mass_kg, self._axles, self._kind,
                self._blocks, self._arr, self._mu_disc, self.fext_N, self._resist,
                self._xs, self._fl, self._fu, self.lut.v_th_m_s,
                self._fb, self._lvl, self._lkind, self._nxt, self.brake_delay_s, self._fmax,
                self._tau_emergency, self._tau_service, self._tau_release,
                self._ev_t, self._ev_lvl, self._ev_kind, self._n_ev,
                self._traction_cmd, self._ftr, tr["max_force_N"], tr["max_power_W"],
                tr["brake_max_force_N"], tr["brake_max_power_W"], tr["rate_limit_N_s"],
                tr["time_constant_s"], tr["fade_speed_m_s"],
                self._centre_offset_m, self.track.start_chainage_m, self._tk_s, self._tk_grad,
                self._tk_rc,
                self._fc, self._fbrake, self._peak_draft, self._t_draft, self._peak_buff,
                self._t_buff, self._lut_out, self._t_lut_out, self._stats,
                self.max_newton_iter, self.newton_rtol, watch, self.standstill_m_s,
                self.stick_band_m_s)
            self.time_s, self._hp = t, hp
            remaining -= done
            if code == kernel.NEWTON_FAILED:
                self._failed = True
                raise SimulationError(
                    f"Newton iteration did not converge within {self.max_newton_iter} "
                    f"iterations in the step starting at t = {t:.4f} s (step {h:.4g} s)")
            if code == kernel.STOPPED:
                self.stop_time_s = self.time_s
                self.stopping_distance_m = float(self._x[0]) - self._x_cmd
                events.append(Event(self.time_s, "stopped", {
                    "stopping_distance_m": self.stopping_distance_m,
                    "stop_time_s": self.time_s - self.command_time_s}))
        self._report_lut_exits(events)
        return self.snapshot(tuple(events))

    def _report_lut_exits(self, events: list) -> None:
        nc = self.n - 1
        new = (self._t_lut_out[:nc] >= 0.0) & ~self._reported_lut[:nc]
        for j in np.flatnonzero(new):
            self._reported_lut[j] = True
            d = float(self._x[j] - self._x[j + 1])
            events.append(Event(float(self._t_lut_out[j]), "coupler_out_of_lut", {
                "coupler": int(j) + 1, "deflection_mm": d * 1e3,
                "beyond_table_mm": float(self._lut_out[j]) * 1e3}))

"""The simulator: owns time and state, advances the train in chunks.

Contract
--------
1. Build it from validated inputs (:class:`~ltd_brake_ros.inputs.Consist`,
   :class:`~ltd_brake_ros.inputs.BrakeParams` naming a brake model, the parameters of a coupler
   model such as :class:`~ltd_brake_ros.inputs.CouplerLUT`) and an initial speed; every vehicle
   starts at that speed with unloaded couplers. The models are compiled once into
   :attr:`Simulator.model`.
2. :meth:`Simulator.advance` integrates one chunk of simulated time under the given
   :class:`Commands` and returns a :class:`Snapshot`. A chunk is a whole number of steps
   (:func:`whole_steps` refuses others), and chunks give the same result as one long call, to
   the last bit.
3. A step whose Newton iteration does not converge, that meets a force that is not finite, or
   that fails with an arithmetic error raises :class:`SimulationError` with one line; the
   simulator then refuses to advance until :meth:`reset`.
4. Everything that changes lives in one :class:`SimulatorState`; :meth:`Simulator.reset`
   replaces it by a new initial one. :attr:`Simulator.stats` reports what the
   integration cost.
5. The train is judged against its strength and adhesion limits as it runs
   (:mod:`~ltd_brake_ros.verdicts`): a ``limit_exceeded`` event when a coupler or vehicle
   first goes beyond one, the whole table from :meth:`Simulator.verdicts`.

Sign conventions: vehicle 0 is the head; speeds forward positive; coupler j (numbered from 1
behind the head) carries force draft/tension positive, buff negative; brake forces are
retarding forces, positive.
"""
from __future__ import annotations

import math

import numpy as np

from .inputs import BrakeParams, Consist, CouplerLUT, InputError, Track, default_brake_params
from .physics import brakes as brakes_module
from .physics import kernel
from .physics.brakes import adhesion as adhesion_module
from .physics.brakes import friction, thermal
from .physics.brakes.base import EMERGENCY, OVERCHARGE, SERVICE
from .physics.constants import KMH_PER_MS, STANDSTILL_M_S
from .physics.equations import (is_plain, plain_now, resistance_coefficients,
                                train_braked_weight_percent)
from .physics.kernel import Stats  # noqa: F401 (part of this module's interface)
from . import stops
from .compiled import compiled_train
from .verdicts import REST_ADHESION, TrainLimits, VehicleDemand, Verdicts, Watch
from .verdicts import merge as merge_verdicts


#: The dtype the kernel takes forces in.
_FLOAT64 = np.dtype(np.float64)


# the value types, part of this module's interface
from .sim_types import (Commands, CouplerExcursions, CouplerPeaks, Event,  # noqa: E402,F401
                        Excursion, SimulationError, SimulatorState, Snapshot)


def whole_steps(duration_s: float, step_s: float, name: str = "duration_s") -> int:
    """The number of integration steps in a chunk, which must be whole.

    A chunk that is not a whole number of steps is integrated in shorter steps, and its
    results then differ from one long call (by centimetres of distance and tenths of a kN):
    the simulator refuses it instead.

    Parameters
    ----------
    duration_s : float
        The chunk [s].
    step_s : float
        The nominal integration step [s].
    name : str, optional
        What the chunk is called where it comes from, for the message.

    Returns
    -------
    int

    Raises
    ------
    InputError
        One line naming ``name`` (a ``ValueError``), when the chunk is not a whole number of
        steps (to a relative 1e-6).
    """
    k = round(duration_s / step_s)
    if k < 1 or abs(duration_s - k * step_s) > 1e-6 * step_s:
        raise InputError(name, "", f"{duration_s:g} s is not a whole number of integration "
                         f"steps of {step_s:g} s: chunks of other lengths change the results; "
                         "give a multiple of the step")
    return k


class Simulator:
    """Longitudinal dynamics of one train under an air-brake model.

    Parameters
    ----------
    consist : Consist
        The train, head first.
    speed_kmh : float
        Initial speed of every vehicle [km/h].
    params : BrakeParams, optional
        Brake model and its parameters (default:
        :func:`~ltd_brake_ros.inputs.default_brake_params`, the paper's empirical model with
        Table 3 and its K0 for trains within its range, the UIC brake pipe beyond).
    lut : dataclass, optional
        Parameters of a registered coupler model, e.g. a :class:`CouplerLUT` (default: the
        shipped buffer-hook table).
    track : Track, optional
        Track profile (default: level straight track).
    step_s : float, optional
        Nominal (largest) integration step [s]; chunks are split into equal nominal steps no
        longer than this.
    tolerance_m_s : float or None, optional
        Local error allowed per step in each vehicle's speed [m/s]: a nominal step whose
        error estimate exceeds it is taken in shorter sub-steps (default
        :data:`~ltd_brake_ros.physics.kernel.DEFAULT_TOLERANCE_M_S`); 0 or None takes every
        nominal step whole (fixed steps).
    local_steps : bool, optional
        Under error control, let long trains (at least
        :data:`~ltd_brake_ros.physics.kernel.LOCAL_MIN_VEHICLES` vehicles) take short
        sub-steps only in the groups of vehicles whose error estimate needs them, the rest of
        the train keeping the longer step (local time stepping; default True). False retries
        the whole train shorter instead.
    resistance : bool, optional
        Apply running resistance, Eq. 2.
    brakes : bool, optional
        Apply air-brake forces (False keeps the brake state but no force reaches the wheels).
    max_newton_iter : int, optional
        Newton iterations allowed per step before the step counts as failed.
    newton_rtol : float, optional
        Residual tolerance, relative to each vehicle's weight (default
        :data:`~ltd_brake_ros.physics.kernel.DEFAULT_NEWTON_RTOL`).
    standstill_m_s : float, optional
        The train counts as stopped once every vehicle is slower than this [m/s].
    stick_band_m_s : float, optional
        Half-width of the standstill band [m/s]: brake and running resistance reach their full
        value at this speed and hold a stopped vehicle against any smaller force; it creeps at
        most at this speed times (force / holding force).
    adhesion : str, float or AdhesionCondition, optional
        The rail's adhesion condition for wheel slide (:mod:`.physics.brakes.adhesion`:
        ``dry``, ``wet``, ``low``, a number, or a curve from
        :func:`~ltd_brake_ros.inputs.adhesion.load_adhesion`); default: off, the brake force
        is never capped, as in the paper's method.
    rail : str, float or AdhesionCondition, optional
        The rail condition the adhesion demand is judged against (a warning, never a change
        of the run; same forms as ``adhesion``); default: ``adhesion`` when given, else a dry
        rail.

    Attributes
    ----------
    model : TrainModel
        The train compiled for the kernel: per-vehicle arrays of every part of the model
        (read them, do not change them).
    fext_N : ndarray
        Additional external force on each vehicle, forward positive [N]; an input that may be
        changed between chunks.
    limits : TrainLimits
        Strength and adhesion limits of the train (consist ``limits``, the coupler model's,
        the standard defaults: :func:`~ltd_brake_ros.verdicts.train_limits`); an event is
        raised when one is first exceeded, :meth:`verdicts` tells all.
    model_warnings : tuple of str
        Where the run leaves its models' validated ranges (empty: inside them;
        :func:`~ltd_brake_ros.inputs.model_warnings`): every output of a run repeats them.

    Examples
    --------
    >>> from ltd_brake_ros import Commands, Simulator, load_brake_params, load_consist, load_coupler
    >>> sim = Simulator(load_consist("scenario_1"), 60.0, load_brake_params(), load_coupler())  # doctest: +SKIP
    >>> snap = sim.advance(1.0, Commands(emergency=True))  # doctest: +SKIP
    >>> snap.speed_m_s[0] < 60 / 3.6                        # doctest: +SKIP
    True
    """

    def __init__(self, consist: Consist, speed_kmh: float, params: BrakeParams | None = None,
                 lut: CouplerLUT | None = None, track: Track | None = None, *,
                 step_s: float = 0.01,
                 resistance: bool = True, brakes: bool = True, max_newton_iter: int = 100,
                 newton_rtol: float = kernel.DEFAULT_NEWTON_RTOL,
                 standstill_m_s: float = STANDSTILL_M_S, stick_band_m_s: float = 1e-5,
                 tolerance_m_s: float | None = kernel.DEFAULT_TOLERANCE_M_S,
                 local_steps: bool = True, adhesion=None, rail=None):
        if lut is None:
            from .inputs import load_coupler_lut

            lut = load_coupler_lut()
        params = params or default_brake_params(consist)
        if not (math.isfinite(speed_kmh) and 0.0 <= speed_kmh <= 400.0):
            raise InputError("speed_kmh", "", f"must be between 0 and 400 km/h, got {speed_kmh}")
        if not (math.isfinite(step_s) and 1e-5 <= step_s <= 0.5):
            raise InputError("step_s", "", f"must be between 1e-5 and 0.5 s, got {step_s}")
        tolerance_m_s = 0.0 if tolerance_m_s is None else tolerance_m_s
        if not (math.isfinite(tolerance_m_s) and 0.0 <= tolerance_m_s <= 1.0):
            raise InputError("tolerance_m_s", "", "must be between 0 (fixed steps) and 1 m/s, "
                             f"got {tolerance_m_s}")
        self.consist, self.params, self.lut = consist, params, lut
        self.track = track or Track()
        self.speed_kmh = float(speed_kmh)
        self.step_s = float(step_s)
        self.tolerance_m_s = float(tolerance_m_s)
        self.local_steps = bool(local_steps)
        self.max_newton_iter = int(max_newton_iter)
        self.newton_rtol = float(newton_rtol)
        self.standstill_m_s = float(standstill_m_s)
        self.stick_band_m_s = float(stick_band_m_s)
        self._brakes = bool(brakes)
        try:
            self.adhesion = adhesion_module.condition(adhesion)
        except ValueError as exc:
            raise InputError("adhesion", "", str(exc)) from None
        try:
            self.rail = adhesion_module.condition(rail) if rail is not None else (
                self.adhesion if self.adhesion.on else adhesion_module.CONDITIONS["dry"])
        except ValueError as exc:
            raise InputError("rail", "", str(exc)) from None
        compiled = self._compiled = compiled_train(consist, params, lut, self.track,
                                              bool(resistance), self._brakes, self.adhesion,
                                              self.rail)
        self.model = compiled.model
        self._brake_model = brakes_module.model_of(params.pneumatic)
        self._options = kernel.Options(self.max_newton_iter, self.newton_rtol,
                                       self.standstill_m_s, self.stick_band_m_s,
                                       self.tolerance_m_s, self.local_steps)
        self.fext_N = np.zeros(self.n)
        # running resistance at rest, Eq. 2's constant term [N] (the holding judgment's)
        self._rest_resistance = np.array([resistance_coefficients(m, a)[0] for m, a in zip(
            self.model.train.mass_kg, self.model.train.axles)], float)
        self.limits: TrainLimits = compiled.limits
        self.model_warnings: tuple = compiled.warnings
        # what the state at time 0 is built from, anew at each reset (as cheap as a copy)
        self._initial = (self.n, self.speed_kmh / KMH_PER_MS, self.model.brakes, self.limits,
                         thermal.initial_temperatures(self.model.thermal))
        self._state = self._initial_state()
        self._workspace: tuple | None = None  # (kinematics, brake state, the kernel's workspace)
        self._inputs: kernel.Inputs | None = None  # the last chunk's
        #: Simulated time advanced with the kernels as plain Python [s] (a first run whose
        #: kernels compiled meanwhile, :mod:`~ltd_brake_ros.first_run`).
        self.plain_python_s = 0.0
        if compiled.run_loop is None or is_plain(compiled.run_loop) != plain_now():
            self._bind_kernel()
        else:  # bound for this model's arguments: the same types for every simulator of it
            self._run_loop, self._bound_model = compiled.run_loop, self.model

    # ------------------------------------------------------------------ state

    def reset(self) -> Snapshot:
        """Return to the initial state: initial speed, brake released, time 0.

        Returns
        -------
        Snapshot
        """
        self._state = self._initial_state()
        self.plain_python_s = 0.0
        return self.snapshot()

    def _initial_state(self) -> SimulatorState:
        """A new state at time 0: the initial speed, brakes released, nothing counted."""
        n, v0_m_s, brakes, limits, temperature_K = self._initial
        st = SimulatorState(
            0.0, 0.0, kernel.KinematicState.initial(n, v0_m_s, temperature_K),
            self._brake_model.initial_state(brakes), brakes_module.CommandEvents.empty(),
            kernel.new_stats(), np.zeros(max(n - 1, 1), bool))
        st.window = stops.Window(0.0, Watch(limits, self.standstill_m_s))
        if v0_m_s == 0.0:  # at rest from the start: a standstill without a stop
            st.phase = stops.PHASE_SETTLING
            st.window.standstill = stops.Standstill(0.0)
            st.kinematics.step_control[kernel.REST_SINCE] = 0.0
        return st

    @property
    def state(self) -> SimulatorState:
        """A copy of the current state (changing it changes nothing)."""
        return self._state.copy()

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return self.model.train.mass_kg.shape[0]

    @property
    def mass_kg(self) -> np.ndarray:
        """Weight on rails of each vehicle [kg]."""
        return self.model.train.mass_kg

    @property
    def length_m(self) -> np.ndarray:
        """Length over buffers of each vehicle [m]."""
        return np.array([v.length_m for v in self.consist.vehicles])

    @property
    def max_block_force_N(self) -> np.ndarray:
        """Full block force of each vehicle, 1000 * sum(F_dyn) (Eq. 4 inverted) [N]."""
        return self.model.friction.force_max_N

    @property
    def brake_delay_s(self) -> np.ndarray:
        """When a brake command reaches each vehicle, after it was issued [s] (Eq. 6 from the
        venting vehicle, :attr:`Consist.venting_vehicle <ltd_brake_ros.inputs.Consist>`)."""
        return self.model.brakes.delay_s

    @property
    def time_s(self) -> float:
        """Simulated time [s]."""
        return self._state.time_s

    @property
    def _stop(self) -> stops.OpenStop | None:
        """The latest stop (None: none yet)."""
        st = self._state
        return st.stops[-1] if st.stops else None

    @property
    def command_time_s(self) -> float | None:
        """Time of the brake command the latest stop's distance counts from [s] (None:
        none)."""
        stop = self._stop
        return None if stop is None else stop.command_time_s

    @property
    def command_speed_kmh(self) -> float | None:
        """Head speed at the brake command of the latest stop [km/h] (None: none)."""
        stop = self._stop
        return None if stop is None else stop.command_speed_m_s * KMH_PER_MS

    @property
    def stop_time_s(self) -> float | None:
        """When the train first stood still in the latest stop [s] (None: not yet)."""
        stop = self._stop
        return None if stop is None else stop.stop_time_s

    @property
    def stopping_distance_m(self) -> float | None:
        """Head's travel from the latest stop's brake command to its standstill [m] (None:
        not stopped yet)."""
        stop = self._stop
        return None if stop is None else stop.stopping_distance_m

    @property
    def stop_peaks(self) -> CouplerPeaks | None:
        """The largest draft and buff force of the latest stop from its command to its first
        standstill (while braking: so far), as the paper's Tables 1-2 count them (None: no
        stop)."""
        stop = self._stop
        if stop is None:
            return None
        if stop.peaks is not None:
            return stop.peaks
        return self._window_peaks([self._state.window])

    @property
    def settled_time_s(self) -> float | None:
        """Since when the train has been settled at rest, every vehicle within the standstill
        speed for at least :data:`~ltd_brake_ros.physics.kernel.SETTLE_S` [s] (None: not
        settled; it moves, or it stopped and still settles)."""
        st = self._state
        rest = st.window.standstill
        if rest is None or st.phase not in (stops.PHASE_AT_REST, stops.PHASE_RUNAWAY):
            return None
        return rest.settled_s

    @property
    def phase(self) -> str:
        """Where the run is: ``moving``, ``braking`` (a stop's command given), ``settling``
        (stood still, not yet settled), ``at rest`` (settled) or ``runaway`` (moved from
        rest without traction)."""
        return stops.phase_name(self._state.phase)

    @property
    def stops(self) -> tuple:
        """Every stop of the run so far, the latest open, as
        :class:`~ltd_brake_ros.stops.StopRecord` (each with its peaks and verdicts).

        Returns
        -------
        tuple of StopRecord
        """
        st = self._state
        by_stop = {id(w.stop): w for w in [*st.closed, st.window] if w.stop is not None}
        out = []
        for stop in st.stops:
            windows = [w for w in [*st.closed, st.window] if w.stop is stop]
            last = by_stop[id(stop)]
            rest = last.standstill
            out.append(stops.StopRecord(
                stop.number, stop.command, stop.command_time_s,
                stop.command_speed_m_s * KMH_PER_MS, stop.stop_time_s,
                stop.stopping_distance_m, None if rest is None else rest.settled_s,
                stop.end_time_s, stop.end,
                stop.peaks if stop.peaks is not None else self._window_peaks(windows),
                merge_verdicts([self._window_verdicts(w) for w in windows])))
        return tuple(out)

    def end_events(self) -> list[Event]:
        """What a recording of the run ends with: a ``stop_ended`` event (``end`` ``end of
        run``) with the verdicts so far of a stop still open, else nothing. The run is not
        changed: it may go on.

        Returns
        -------
        list of Event
        """
        found = self.stops
        if not found or found[-1].end != "open":
            return []
        last = found[-1]
        return [Event(self.time_s, "stop_ended", {
            "stop": last.number, "end": "end of run", "verdicts": last.verdicts.status,
            **{f"verdict_{c.name}": c.status for c in last.verdicts.criteria}})]

    @property
    def distance_travelled_m(self) -> float:
        """Head's displacement since time 0 [m]."""
        return float(self._state.kinematics.x_m[0])

    @property
    def stats(self) -> Stats:
        """What the integration cost since the last reset."""
        return kernel.read_stats(self._state.stats)

    @property
    def steps(self) -> int:
        """Integration steps taken since the last reset."""
        return int(self._state.stats[0]["steps"])

    @property
    def newton_iterations(self) -> int:
        """Newton iterations (linear solves) since the last reset."""
        return int(self._state.stats[0]["newton_iterations"])

    @property
    def max_newton_iterations(self) -> int:
        """Most Newton iterations any single step needed."""
        return int(self._state.stats[0]["max_newton_iterations"])

    @property
    def stopped(self) -> bool:
        """True when every vehicle is slower than ``standstill_m_s``."""
        v = self._state.kinematics.v_m_s
        if abs(v[0]) > self.standstill_m_s:
            return False  # the head still moves (the usual case, without a pass over the train)
        return bool((np.abs(v) <= self.standstill_m_s).all())

    def _run_peaks(self) -> tuple:
        """The run's per-coupler records, the worst of every window: (draft, its time, buff,
        its time, beyond the range, its time, first out of range), arrays of n - 1."""
        st, nc = self._state, self.n - 1
        k = st.kinematics
        now = (k.peak_draft_N[:nc], k.peak_draft_time_s[:nc], k.peak_buff_N[:nc],
               k.peak_buff_time_s[:nc], k.beyond_range_m[:nc], k.beyond_range_time_s[:nc],
               k.out_of_range_time_s[:nc])
        if not st.closed:
            return tuple(a.copy() for a in now)
        return stops.merged_peaks([self._window_records(w) for w in st.closed] + [now])

    def _window_records(self, w: stops.Window) -> tuple:
        """:meth:`_run_peaks`' records of one window."""
        nc = self.n - 1
        e = self._state.kinematics if w.extremes is None else w.extremes
        return (e.peak_draft_N[:nc], e.peak_draft_time_s[:nc], e.peak_buff_N[:nc],
                e.peak_buff_time_s[:nc], e.beyond_range_m[:nc], e.beyond_range_time_s[:nc],
                e.out_of_range_time_s[:nc])

    def _window_peaks(self, windows: list) -> CouplerPeaks:
        """The largest draft and buff force of some windows."""
        d, td, b, tb, *_ = stops.merged_peaks([self._window_records(w) for w in windows])
        return CouplerPeaks.from_arrays(d, td, b, tb)

    @property
    def peak_draft_N(self) -> np.ndarray:
        """Largest draft (tension) force per coupler so far [N] (0 if never in draft)."""
        return self._run_peaks()[0]

    @property
    def peak_buff_N(self) -> np.ndarray:
        """Largest buff (compression) force per coupler so far, negative [N]."""
        return self._run_peaks()[2]

    @property
    def peak_draft_time_s(self) -> np.ndarray:
        """Time of each coupler's peak draft force [s]."""
        return self._run_peaks()[1]

    @property
    def peak_buff_time_s(self) -> np.ndarray:
        """Time of each coupler's peak buff force [s]."""
        return self._run_peaks()[3]

    @property
    def lut_excursion_m(self) -> np.ndarray:
        """Largest deflection beyond the coupler model's valid range per coupler [m] (0 if
        never)."""
        return self._run_peaks()[4]

    def coupler_peaks(self) -> CouplerPeaks:
        """Largest draft and buff force since the last reset, where and when.

        Returns
        -------
        CouplerPeaks
        """
        d, td, b, tb, *_ = self._run_peaks()
        return CouplerPeaks.from_arrays(d, td, b, tb)

    def coupler_excursions(self, worst: int = 3) -> CouplerExcursions:
        """Couplers that went beyond the coupler model's valid range since the last reset.

        Parameters
        ----------
        worst : int, optional
            How many of the largest excursions to list.

        Returns
        -------
        CouplerExcursions
        """
        *_, beyond, t_beyond, t_out = self._run_peaks()
        return CouplerExcursions.from_arrays(beyond, t_beyond, t_out, worst)

    def verdicts(self, limits: TrainLimits | None = None) -> Verdicts:
        """Strength, adhesion and holding verdicts since the last reset, every stop's and the
        rest of the run's together (:mod:`~ltd_brake_ros.verdicts`; each stop's own:
        :attr:`stops`).

        Parameters
        ----------
        limits : TrainLimits, optional
            Judge by other limits (default :attr:`limits`).

        Returns
        -------
        Verdicts
        """
        st = self._state
        return merge_verdicts([self._window_verdicts(w, limits)
                               for w in [*st.closed, st.window]])

    def current_verdicts(self) -> Verdicts:
        """The verdicts of the part of the run judged now: the latest stop's, from its command,
        until a drive-off; then the run's since the drive-off (:mod:`~ltd_brake_ros.stops`).

        Returns
        -------
        Verdicts
        """
        return self._window_verdicts(self._state.window)

    def _window_verdicts(self, w: stops.Window, limits: TrainLimits | None = None) -> Verdicts:
        """The verdicts of one window (a closed window's, by the watched limits, kept)."""
        if w.extremes is not None and limits is None and w.verdicts is not None:
            return w.verdicts
        e = self._state.kinematics if w.extremes is None else w.extremes
        peaks = self._temperature_peaks(e if w.extremes is not None else None)
        table = w.watch.verdicts(e, limits, wheel_temperature=(peaks[2], peaks[3]),
                                 holding=w.holding(), runaway=w.runaway())
        if w.extremes is not None and limits is None:
            w.verdicts = table
        return table

    def adhesion_records(self) -> VehicleDemand:
        """Each vehicle's adhesion records since the last reset: mean utilised adhesion over
        the braked part of the stop, largest demand above and below 30 km/h
        (:class:`~ltd_brake_ros.verdicts.VehicleDemand`).

        Returns
        -------
        VehicleDemand
        """
        return self._state.window.watch.demand_of(self._state.kinematics)

    def wheel_slides(self) -> list[dict]:
        """Vehicles whose wheels slid since the last reset (with an adhesion condition).

        Returns
        -------
        list of dict
            Per vehicle that slid, head first: ``vehicle`` (0 at the head), ``first_s`` (when
            it first slid [s]) and ``duration_s`` (how long in all [s]).
        """
        k = self._state.kinematics
        return [{"vehicle": int(i), "first_s": float(k.slide_first_s[i]),
                 "duration_s": float(k.slide_time_s[i])}
                for i in np.flatnonzero(k.slide_first_s[: self.n] >= 0.0)]

    def temperatures(self) -> tuple[np.ndarray, np.ndarray]:
        """Temperature of each vehicle's brake blocks and of its wheels now
        (:mod:`.physics.brakes.thermal`).

        Returns
        -------
        block_K, wheel_K : ndarray
            [K]; NaN for vehicles without block brakes.
        """
        k = self._state.kinematics  # the kernel brings them to the end of each call
        return k.block_temperature_K.copy(), k.wheel_temperature_K.copy()

    @property
    def brake_energy_J(self) -> np.ndarray:
        """Work of each vehicle's friction brake since the last reset, retarding force times
        distance: the heat its blocks and wheels (or discs) took [J]."""
        k = self._state.kinematics
        return k.brake_energy_J + k.heat_work_J

    def _temperature_peaks(self, closed: stops.Extremes | None = None) -> tuple:
        """Per-vehicle peaks of block and wheel temperature [K] and their times [s] of the
        current window (the updates' and now) or of a ``closed`` one's records."""
        if closed is not None:
            return (closed.peak_block_temperature_K, closed.peak_block_temperature_time_s,
                    closed.peak_wheel_temperature_K, closed.peak_wheel_temperature_time_s)
        k, t = self._state.kinematics, self._state.time_s
        out = []
        for now, peak, when in ((k.block_temperature_K, k.peak_block_temperature_K,
                                 k.peak_block_temperature_time_s),
                                (k.wheel_temperature_K, k.peak_wheel_temperature_K,
                                 k.peak_wheel_temperature_time_s)):
            hotter = now > peak
            out += [np.where(hotter, now, peak), np.where(hotter, t, when)]
        return tuple(out)

    def brake_temperatures(self) -> thermal.Peaks:
        """The hottest brake blocks and wheels since the last reset, which vehicle and when.

        Returns
        -------
        Peaks
            :class:`~ltd_brake_ros.physics.brakes.thermal.Peaks`.
        """
        st = self._state
        parts = [self._temperature_peaks(w.extremes) for w in st.closed]
        peaks = list(self._temperature_peaks())
        for part in parts:  # the hottest of every window
            for k in (0, 2):
                hotter = part[k] > peaks[k]
                peaks[k] = np.where(hotter, part[k], peaks[k])
                peaks[k + 1] = np.where(hotter, part[k + 1], peaks[k + 1])
        return thermal.Peaks.from_arrays(*peaks, self.model.thermal.ambient_K)

    def braked_weight_percent(self) -> float:
        """Train braked-weight percentage lambda_train, Eq. 11 [%]."""
        compiled = self._compiled
        if compiled.model is not self.model or compiled.consist is not self.consist:
            return self._braked_weight_percent()  # a train put in by hand
        if compiled.braked_weight_percent is None:  # the same for every simulator of it
            compiled.braked_weight_percent = self._braked_weight_percent()
        return compiled.braked_weight_percent

    def _braked_weight_percent(self) -> float:
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
        st = self._state
        k = st.kinematics
        v = k.v_m_s
        n = v.shape[0]
        # the fields set directly: the same object as Snapshot(...) builds, without the frozen
        # dataclass's per-field checks (a snapshot per chunk)
        snap = object.__new__(Snapshot)
        snap.__dict__.update(
            time_s=st.time_s,
            position_m=self.track.start_chainage_m + k.x_m - self.model.train.centre_offset_m,
            speed_m_s=v.copy(),
            brake_force_N=k.brake_force_N.copy() if self._brakes else np.zeros(n),
            traction_force_N=k.traction_force_N.copy(), block_force_N=st.brakes.force_N.copy(),
            coupler_force_N=k.coupler_force_N[: n - 1].copy(), events=tuple(events),
            stopped=self.stopped, extras=self._extras())
        return snap

    def _extras(self) -> dict:
        """The snapshot's further quantities: the brake model's and the temperatures."""
        st = self._state
        extras = self._brake_model.snapshot_extras(self.model.brakes, st.brakes)
        k = st.kinematics
        extras["block_temperature_K"] = k.block_temperature_K.copy()
        extras["wheel_temperature_K"] = k.wheel_temperature_K.copy()
        return extras

    # ------------------------------------------------------------------ integration

    def _add_event(self, level: float, kind: int) -> None:
        st = self._state
        # drop events every vehicle has already received
        received = int(st.brakes.next_event.min())
        st.events = st.events.appended(st.time_s, level, kind, received)
        if received:
            st.brakes.next_event[:] -= received

    def _apply_commands(self, commands: Commands, events: list) -> None:
        st = self._state
        k = st.kinematics
        if commands.traction > 0.0 and st.phase in (stops.PHASE_SETTLING, stops.PHASE_AT_REST,
                                                    stops.PHASE_RUNAWAY):
            # traction from rest: a drive-off ends the stop and its holding
            stop = st.window.stop
            if stop is not None:
                stop.end_time_s, stop.end = st.time_s, "drive-off"
            events.append(Event(st.time_s, "drive_off"))
            self._open_window(None, events)
            st.phase = stops.PHASE_MOVING
        braking = commands.emergency or commands.brake_demand > 0.0
        if braking and st.phase in (stops.PHASE_MOVING, stops.PHASE_RUNAWAY):
            # a brake command while the train moves starts a stop: its distance counts from
            # here
            previous = st.window.stop
            if previous is not None and previous.end == "open":
                previous.end_time_s, previous.end = st.time_s, "new stop"
            stop = stops.OpenStop(len(st.stops) + 1,
                                  "emergency" if commands.emergency else "service", st.time_s,
                                  float(k.v_m_s[0]), float(k.x_m[0]))
            st.stops.append(stop)
            self._open_window(stop, events)
            events.append(Event(st.time_s, "stop_started", {
                "stop": stop.number, "command": stop.command,
                "command_speed_kmh": stop.command_speed_m_s * KMH_PER_MS}))
            st.window.watch.start(stop.command_speed_m_s)
            st.phase = stops.PHASE_BRAKING
        if commands.emergency and not st.emergency:
            st.emergency = True
            events.append(Event(st.time_s, "brake_applied"))
        elif not commands.emergency and st.emergency:
            st.emergency = False
            events.append(Event(st.time_s, "brake_released"))
        if st.emergency:
            level = (1.0, EMERGENCY)
        elif commands.overcharge and commands.brake_demand == 0.0:
            level = (0.0, OVERCHARGE)
        else:
            level = (float(commands.brake_demand), SERVICE)
        if level[0] == 0.0 and st.phase == stops.PHASE_BRAKING:
            # released before standstill: no stop (a new command counts anew)
            events.append(Event(st.time_s, "stop_abandoned", {"stop": st.stops[-1].number}))
            st.stops.pop()
            st.window.stop = None
            st.phase = stops.PHASE_MOVING
        if level != st.brake_command:
            st.brake_command = level
            self._add_event(*level)
        st.traction_demand = float(commands.traction)

    def _open_window(self, stop: stops.OpenStop | None, events: list) -> None:
        """Close the window judged now and start another at this time (see
        :mod:`~ltd_brake_ros.stops`); an empty one (no time, no standstill) is dropped. A
        closed stop's window ends with a ``stop_ended`` event carrying its verdicts."""
        st = self._state
        w, k, t = st.window, st.kinematics, st.time_s
        if t > w.start_s or w.standstill is not None:
            w.extremes, w.end_s = stops.Extremes.of(k), t
            st.closed.append(w)
            if w.stop is not None:
                table = self._window_verdicts(w)
                events.append(Event(t, "stop_ended", {
                    "stop": w.stop.number, "end": w.stop.end, "verdicts": table.status,
                    **{f"verdict_{c.name}": c.status for c in table.criteria}}))
        stops.reset_extremes(k, t)
        st.reported_out_of_range[:] = False
        st.reported_out_of_range_count = 0
        st.window = stops.Window(t, Watch(self.limits, self.standstill_m_s), stop)

    def advance(self, duration_s: float, commands: Commands | None = None) -> Snapshot:
        """Integrate one chunk of simulated time.

        Parameters
        ----------
        duration_s : float
            Simulated time to advance [s]: a whole number of steps (:func:`whole_steps`).
        commands : Commands, optional
            Inputs for this chunk; ``None`` keeps the previous ones.

        Returns
        -------
        Snapshot
            State at the end of the chunk, with the events that happened in it.

        Raises
        ------
        ValueError
            ``duration_s`` is not a positive whole number of steps (one line).
        SimulationError
            A step did not converge, met a force that is not finite, or failed with an
            arithmetic error (one line; the simulator then needs :meth:`reset`).
        """
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ValueError(f"duration_s must be a positive finite number, got {duration_s}")
        st = self._state
        if st.failed:
            raise SimulationError("the simulator stopped after a failed step; call reset()")
        events: list[Event] = []
        t0, v0 = st.time_s, float(st.kinematics.v_m_s[0])
        if commands is not None:
            self._apply_commands(commands, events)
        nsteps = whole_steps(duration_s, self.step_s)
        h = duration_s / nsteps
        remaining = nsteps
        inputs = self._inputs
        fext = self.fext_N
        if (inputs is None or inputs.external_force_N is not fext or fext.shape != (self.n,)
                or fext.dtype is not _FLOAT64 or inputs.traction_demand != st.traction_demand):
            # new inputs (the same array, changed in place, needs no new bundle)
            inputs = self._inputs = kernel.Inputs(st.traction_demand, self._external_forces())
        plain_loop = is_plain(self._run_loop)
        if self.model is not self._bound_model or plain_loop != plain_now():
            # a model put in by hand may have other array types; plain-Python kernels give
            # way to compiled ones when these are ready
            self._bind_kernel()
            plain_loop = is_plain(self._run_loop)
        ws = self._workspace
        if ws is None or ws[0] is not st.kinematics or ws[1] is not st.brakes:
            ws = self._new_workspace()
        ws = ws[2]
        while remaining:
            try:
                code, t, hp, done = self._run_loop(
                    remaining, h, st.time_s, st.last_step_s, self.model, inputs, st.kinematics,
                    st.brakes, st.events, st.stats, self._options,
                    stops.WATCH_OF_PHASE[st.phase], ws)
            except ArithmeticError as exc:
                # e.g. a division by zero in the compiled kernel; the state is part-way
                # through a step, so only a reset recovers
                st.failed = True
                raise SimulationError(
                    f"arithmetic failure ({type(exc).__name__}: {exc}) in a step after "
                    f"t = {st.time_s:.4f} s (step {h:.4g} s): a force or stiffness of the "
                    "inputs is beyond what the integrator resolves") from None
            if plain_loop:
                self.plain_python_s += t - st.time_s
            st.time_s, st.last_step_s = t, hp
            remaining -= done
            if code == kernel.NEWTON_FAILED:
                st.failed = True
                raise SimulationError(
                    f"Newton iteration did not converge within {self.max_newton_iter} "
                    f"iterations in the step starting at t = {t:.4f} s (step {h:.4g} s)")
            if code == kernel.NOT_FINITE:
                st.failed = True
                raise SimulationError(
                    f"a force is not finite (inf or NaN) in the step starting at t = {t:.4f} s: "
                    "check the external forces and the model parameters")
            if code != kernel.OK:
                self._phase_change(code, events)
        self._report_out_of_range(events)
        k = st.kinematics
        w = st.window
        events += [Event(t, "limit_exceeded", d) for t, d in w.watch.check(
            t0, v0, st.time_s, float(k.v_m_s[0]), k, k.v_m_s, k.brake_force_N)]
        if st.phase == stops.PHASE_AT_REST:
            events += [Event(t, "limit_exceeded", d) for t, d in self._holding()]
        elif st.phase == stops.PHASE_RUNAWAY:
            events += self._runaway(st.time_s)
        return self.snapshot(tuple(events))

    def _phase_change(self, code: int, events: list) -> None:
        """What the kernel found at the end of a step: the stop, the train settled, or a
        vehicle moving from rest (:mod:`~ltd_brake_ros.stops`)."""
        st = self._state
        k, t = st.kinematics, st.time_s
        if code == kernel.STOPPED:
            stop = st.window.stop
            stop.stop_time_s = t
            stop.stopping_distance_m = float(k.x_m[0]) - stop.command_head_m
            nc = self.n - 1
            stop.peaks = p = CouplerPeaks.from_arrays(
                k.peak_draft_N[:nc], k.peak_draft_time_s[:nc], k.peak_buff_N[:nc],
                k.peak_buff_time_s[:nc])
            events.append(Event(t, "stopped", {
                "stop": stop.number, "stopping_distance_m": stop.stopping_distance_m,
                "stop_time_s": t - stop.command_time_s, "peak_draft_kN": p.draft_N / 1e3,
                "peak_draft_coupler": p.draft_coupler, "peak_draft_time_s": p.draft_time_s,
                "peak_buff_kN": p.buff_N / 1e3, "peak_buff_coupler": p.buff_coupler,
                "peak_buff_time_s": p.buff_time_s}))
            st.window.standstill = stops.Standstill(t)
            stops.start_rest(k.step_control, t, k.v_m_s, self.standstill_m_s)
            st.phase = stops.PHASE_SETTLING
        elif code == kernel.SETTLED:
            rest = st.window.standstill
            rest.settled_s = float(k.step_control[kernel.REST_SINCE])
            stop = st.window.stop
            events.append(Event(t, "settled", {
                "stop": 0 if stop is None else stop.number, "settled_time_s": rest.settled_s}))
            st.phase = stops.PHASE_AT_REST
        elif code == kernel.MOVED:  # from rest, without traction (traction ends the phase)
            st.phase = stops.PHASE_RUNAWAY
            events += self._runaway(t)

    def _runaway(self, t: float) -> list:
        """Vehicles moving after the train had settled, without traction: the runaway
        records, and an event for each vehicle that moves for the first time."""
        st = self._state
        k = st.kinematics
        first = st.window.standstill.moved(t, k.v_m_s, self.standstill_m_s)
        out = []
        for i in np.flatnonzero(first):
            speed = abs(float(k.v_m_s[i])) * KMH_PER_MS
            out.append(Event(t, "limit_exceeded", Watch.event_detail(
                "runaway", int(i), speed, self.standstill_m_s * KMH_PER_MS, speed)))
        return out

    def warm_up(self) -> None:
        """Load (or compile, on the first run after installing) every compiled function a run
        calls: the step loop, the verdicts' scans and the check at rest. The state is left as
        it was; a process that warms one simulator up runs every later one of the same train
        without start-up cost."""
        saved = self._state.copy()
        try:
            self.advance(self.step_s)
            self._rest_forces()
        finally:
            self._state = saved
            self._workspace = None

    def _holding(self) -> list[tuple]:
        """The train settled at rest: each vehicle's force to hold against what it holds
        (:meth:`_rest_forces`); vehicles first needing more, as ``limit_exceeded`` details."""
        st = self._state
        need, capacity, tolerance = (np.array([a.sum()]) for a in self._rest_forces())
        if st.window.standstill.judge_rest(st.time_s, need, capacity, tolerance)[0]:
            return [(st.time_s, {"criterion": "standstill_holding", "train": 0,
                                 "force_kN": abs(float(need[0])) / 1e3,
                                 "limit_kN": float(capacity[0]) / 1e3, "speed_kmh": 0.0})]
        return []

    def _rest_forces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each vehicle's share of the force the train must hold at rest (grade, external and
        traction forces: the couplers' forces are inner forces of the train, which the
        vehicles share out among themselves by sliding a little), what it holds (the static
        friction of its brake, the kinetic law at rest, at most the rail's adhesion at rest,
        plus its running resistance at rest) and the integrator's force tolerance [N]."""
        st, m = self._state, self.model
        k, n = st.kinematics, self.n
        fgrade, rcurve = np.zeros(n), np.zeros(n)
        kernel.track_forces(k.x_m, m.train, m.track, fgrade, rcurve)
        need = fgrade + self.fext_N + k.traction_force_N
        fr = m.friction
        scale = np.zeros(n)
        friction.force_scales(fr.kind, fr.blocks, fr.arrangement, fr.mu_disc, st.brakes.force_N,
                              scale)
        static = np.where(fr.kind == friction.BRAKE_BLOCKS,
                          friction.karwatzki_speed_factor(0.0)[0] * scale, scale)
        rest = (self._rest_resistance + rcurve) * m.train.resist
        capacity = np.minimum(static, REST_ADHESION * fr.weight_N) + rest
        return need, capacity, self.newton_rtol * fr.weight_N

    def _bind_kernel(self) -> None:
        """Compile (or load from the cache) the kernel's step loop for this train's bundles
        now, callable without numba typing every bundle on every chunk."""
        self._run_loop = kernel.bind_run_loop(*self._kernel_arguments(),
                                              self._new_workspace()[2])
        self._bound_model = self.model
        if self.model is self._compiled.model:
            self._compiled.run_loop = self._run_loop

    def _kernel_arguments(self) -> tuple:
        """Arguments of :func:`~ltd_brake_ros.physics.kernel.run_steps` for one step now."""
        st = self._state
        return (1, self.step_s, st.time_s, st.last_step_s, self.model,
                kernel.Inputs(st.traction_demand, self.fext_N), st.kinematics, st.brakes,
                st.events, st.stats, self._options, kernel.WATCH_NONE)

    def _new_workspace(self) -> tuple:
        """The kernel's work arrays for the current state and model, kept for the next chunks
        (a reset or a new model needs new ones)."""
        st = self._state
        self._workspace = (st.kinematics, st.brakes, kernel.new_workspace(
            self.model, st.kinematics, st.brakes, self._options))
        return self._workspace

    def _external_forces(self) -> np.ndarray:
        """:attr:`fext_N` as the kernel takes it: n contiguous floats [N].

        Raises
        ------
        ValueError
            It does not hold one force per vehicle.
        """
        f = self.fext_N
        if not (type(f) is np.ndarray and f.dtype == np.float64 and f.flags.c_contiguous):
            f = self.fext_N = np.ascontiguousarray(f, dtype=float)
        if f.shape != (self.n,):
            raise ValueError(f"fext_N must hold one force per vehicle ({self.n}), got shape "
                             f"{f.shape}")
        return f

    def _report_out_of_range(self, events: list) -> None:
        nc = self.n - 1
        st = self._state
        k = st.kinematics
        left = int(k.step_control[kernel.OUT_OF_RANGE])  # couplers that have left their range
        if nc <= 0 or left <= st.reported_out_of_range_count:
            return  # none has left it since the last report
        st.reported_out_of_range_count = left
        reported = st.reported_out_of_range
        new = (k.out_of_range_time_s[:nc] >= 0.0) & ~reported[:nc]
        for j in np.flatnonzero(new):
            reported[j] = True
            d = float(k.x_m[j] - k.x_m[j + 1])
            events.append(Event(float(k.out_of_range_time_s[j]), "coupler_out_of_lut", {
                "coupler": int(j) + 1, "deflection_mm": d * 1e3,
                "beyond_table_mm": float(k.beyond_range_m[j]) * 1e3}))

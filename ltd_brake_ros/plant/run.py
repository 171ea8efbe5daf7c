"""A run of the plant: what its run-defining settings resolve to (inputs, simulator, plant
settings), its one-line description and recording metadata, the brake model's extra state
topics, and the run a reset with newly set values builds. No ROS: the node passes its
parameter values (a dict by parameter name)."""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable

from ..inputs import InputError
from ..physics.kernel import DEFAULT_TOLERANCE_M_S
from ..recording.metadata import model_warnings, run_metadata
from ..recording.plant_topics import extra_topic
from ..run_spec import RunSpec, RunSpecError, resolve_run_spec
from ..simulator import SimulationError, Simulator, whole_steps
from .settings import PlantSettings, StartupError

__all__ = ["RUN_INPUT_PARAMETERS", "RUN_SPEC_PARAMETERS", "PlantRun", "reset_run",
           "load_plant_inputs", "build_simulator", "check_run_inputs", "plant_settings"]

#: Node parameter of each run-spec input, for error messages.
RUN_SPEC_PARAMETERS = {"consist": "consist", "speed_kmh": "initial_speed_kmh",
                       "brake_params": "brake_params_file", "coupler_lut": "coupler_lut_file",
                       "track": "track_file"}


def load_plant_inputs(consist: str, initial_speed_kmh: float, brake_params_file: str = "",
                      coupler_lut_file: str = "", track_file: str = "",
                      start_chainage_m: float = 0.0) -> RunSpec:
    """Resolve and validate the node's input parameters (see :func:`resolve_run_spec`).

    Parameters
    ----------
    consist : str
        Consist YAML file, or scenario name/number (``scenario_6``, ``6``).
    initial_speed_kmh : float
        Initial speed [km/h]; negative takes the scenario's speed.
    brake_params_file, coupler_lut_file, track_file : str
        Files; empty strings take the shipped defaults (level straight track).
    start_chainage_m : float
        Chainage of the head's front at t = 0 [m].

    Returns
    -------
    RunSpec

    Raises
    ------
    StartupError
        Naming the parameter and the reason.
    """
    try:
        # -1: not set, the scenario's speed (the parameter's documented default)
        speed = None if initial_speed_kmh == -1.0 else initial_speed_kmh
        return resolve_run_spec(consist, speed_kmh=speed,
                                params_file=brake_params_file, lut_file=coupler_lut_file,
                                track_file=track_file, start_chainage_m=start_chainage_m)
    except RunSpecError as exc:
        raise StartupError(RUN_SPEC_PARAMETERS[exc.input_name], exc.detail) from None


#: Node parameters that name the train and its inputs (validated together when one is set).
RUN_INPUT_PARAMETERS = ("consist", "initial_speed_kmh", "brake_params_file", "coupler_lut_file",
                        "track_file", "start_chainage_m")


def check_run_inputs(values: dict[str, Any]) -> str | None:
    """Why the run-input parameter ``values`` do not make a train, or None.

    What a reset would build from them is loaded and checked (files parse, the scenario
    exists, the combination is valid); nothing is compiled or started.

    Parameters
    ----------
    values : dict
        Every name of :data:`RUN_INPUT_PARAMETERS` with its value.

    Returns
    -------
    str or None
        ``"<parameter>: <reason>"``.
    """
    try:
        load_plant_inputs(*(values[name] for name in RUN_INPUT_PARAMETERS))
    except StartupError as exc:
        return f"{exc.parameter}: {exc.reason}"
    return None


def build_simulator(spec: RunSpec, chunk_s: float,
                    tolerance_m_s: float = DEFAULT_TOLERANCE_M_S, say=None) -> Simulator:
    """The simulator of ``spec``, its compiled kernel loaded (one chunk run, then reset).

    Loading the kernel here keeps it from making the first chunk late.

    Parameters
    ----------
    spec : RunSpec
    chunk_s : float
        Chunk the plant advances [s].
    tolerance_m_s : float, optional
        The integrator's local error per step in speed [m/s]; 0 = fixed steps.
    say : callable, optional
        Told, when the kernels compile here (a first run), the compile's estimated duration
        before and its measured one after (:func:`~ltd_brake_ros.first_run.measured`).

    Raises
    ------
    StartupError
        The inputs do not make a train (naming ``initial_speed_kmh`` or ``consist``).
    """
    if say is None:
        return _build_simulator(spec, chunk_s, tolerance_m_s)
    from ..first_run import measured

    with measured(dict(consist=spec.consist, params=spec.params,
                       tolerance_m_s=tolerance_m_s), say):
        return _build_simulator(spec, chunk_s, tolerance_m_s)


def _build_simulator(spec: RunSpec, chunk_s: float, tolerance_m_s: float) -> Simulator:
    try:
        sim = Simulator(spec.consist, spec.speed_kmh, spec.params, spec.lut, spec.track,
                        tolerance_m_s=tolerance_m_s)
    except InputError as exc:
        name = {"speed_kmh": "initial_speed_kmh", "tolerance_m_s": "tolerance_m_s"}.get(
            str(exc.source), "consist")
        raise StartupError(name, str(exc)) from None
    try:
        whole_steps(chunk_s, sim.step_s, "chunk_s")
    except ValueError as exc:
        raise StartupError("chunk_s", str(exc)) from None
    try:
        sim.advance(chunk_s)
    except SimulationError:
        pass  # the run meets it again and reports it
    sim.reset()
    return sim


def plant_settings(values: dict[str, Any], follow_clock: bool = False) -> PlantSettings:
    """The plant runtime's settings from the declared parameter values.

    Parameters
    ----------
    values : dict
        Parameter values by name.
    follow_clock : bool, optional
        The plant follows another plant's clock (the ``clock`` parameter, resolved).
    """
    return PlantSettings(follow_clock=follow_clock,
                         **{f.name: values[f.name] for f in fields(PlantSettings)
                            if f.name != "follow_clock"})


@dataclass(frozen=True)
class PlantRun:
    """One run of the plant, built from parameter values (see :meth:`build`).

    Attributes
    ----------
    values : dict
        Every parameter value by name (``consist``, ``initial_speed_kmh``, ``chunk_s``, ...).
    spec : RunSpec
        The resolved inputs.
    sim : Simulator
        Its simulator, kernel loaded, at the initial state.
    """

    values: dict
    spec: RunSpec
    sim: Simulator

    @classmethod
    def build(cls, values: dict[str, Any], say=None) -> "PlantRun":
        """The run the parameter ``values`` describe.

        ``say`` is told about a compile of its kernels (:func:`build_simulator`).

        Raises
        ------
        StartupError
            An input is unusable (naming the parameter).
        """
        v = values
        spec = load_plant_inputs(v["consist"], v["initial_speed_kmh"], v["brake_params_file"],
                                 v["coupler_lut_file"], v["track_file"], v["start_chainage_m"])
        return cls(dict(values), spec, build_simulator(spec, v["chunk_s"], v["tolerance_m_s"],
                                                       say=say))

    def rebuilt(self, changes: dict[str, Any], say=None) -> "PlantRun | None":
        """The run a reset starts with the run-defining values ``changes`` now set.

        Parameters
        ----------
        changes : dict
            Parameter values by name (those set since, and the others unchanged).
        say : callable, optional
            Told about a compile of the new run's kernels (:func:`build_simulator`).

        Returns
        -------
        PlantRun or None
            A new run, or None when ``changes`` are this run's values (the reset restarts it).

        Raises
        ------
        StartupError
            The new values do not make a run (this one goes on).
        """
        if all(self.values.get(name) == value for name, value in changes.items()):
            return None
        return PlantRun.build(self.values | changes, say=say)

    def settings(self, follow_clock: bool = False) -> PlantSettings:
        """The plant settings of the run (see :func:`plant_settings`)."""
        return plant_settings(self.values, follow_clock)

    def describe(self) -> str:
        """One line: train, vehicles, length, mass, origin and speed."""
        c, spec = self.spec.consist, self.spec
        return (f"{c.name}: {c.n} vehicles, {c.length_m:.0f} m, {c.mass_kg / 1e3:.0f} t "
                f"({spec.origin}) at {spec.speed_kmh:g} km/h")

    def metadata(self) -> dict:
        """The run information a recording of it stores."""
        spec = self.spec
        return run_metadata(self.sim, scenario=spec.origin, parameters=dict(self.values),
                            brake_params=str(spec.params.source),
                            coupler_lut=str(spec.lut.source), track=str(spec.track.source))

    def extra_topics(self) -> list[str]:
        """Topics of the brake model's further per-vehicle quantities (``vehicles/...``)."""
        return [extra_topic(key) for key in self.sim.snapshot().extras]

    def start_line(self, settings: PlantSettings, clock_mode: str) -> str:
        """The line a plant logs when it starts: the run, chunk, pace or mode, and clock.

        Parameters
        ----------
        settings : PlantSettings
            The settings in force.
        clock_mode : str
            ``publish``, ``follow`` or ``none`` (resolved).
        """
        s = settings
        mode = "following /clock" if s.follow_clock else "lock-step" if s.lockstep else \
            f"real_time_factor {s.real_time_factor:g}"
        clock = {"publish": "publishes /clock", "follow": "", "none": "no /clock"}[clock_mode]
        return (f"{self.describe()}; chunk {s.chunk_s:g} s, {mode}"
                + (f", {clock}" if clock else ""))


def reset_run(runner, run: PlantRun, values: dict[str, Any],
              prepare: Callable[[PlantRun], list], log,
              hold: bool = False) -> tuple[bool, str, PlantRun]:
    """Reset a plant, to a new run when run-defining values were set since ``run`` was built.

    Parameters
    ----------
    runner : PlantRunner
        The plant (waited for: call from a thread other than the plant's).
    run : PlantRun
        The run in force.
    values : dict
        The run-defining parameter values now set, by name.
    prepare : callable
        ``prepare(new_run) -> topics``, before a new run starts: the host makes ready what the
        run publishes (the brake model's extra state) and returns the topics its recording
        declares (see :meth:`~.runner.PlantRunner.reset`).
    log : logger
    hold : bool, optional
        Hold at t = 0 afterwards (a stop, see :meth:`~.runner.PlantRunner.reset`).

    Returns
    -------
    (bool, str, PlantRun)
        Success, the reply, and the run in force after it (``run`` unless a new one started).
        New values that do not make a run refuse the reset, naming the parameter; the old
        run goes on.
    """
    try:
        new = run.rebuilt(values, say=log.info)  # a new train may compile its kernels
    except StartupError as exc:
        text = (f"not reset: parameter {exc.parameter}: {exc.reason}; the run goes on as it "
                "was")
        log.error(text)
        return False, text, run
    if new is None:
        return (*runner.result(runner.reset(hold=hold)), run)
    topics = prepare(new)
    recording = None if runner.recorder is None else (topics, new.metadata())
    ok, text = runner.result(runner.reset((new.sim, new.settings(runner.settings.follow_clock)),
                                          recording, hold))
    if not ok:
        return False, text, run
    log.info(f"new run: {new.describe()}")
    for line in model_warnings(new.sim):
        log.warning(line)
    return True, f"{text}; new run: {new.describe()}", new

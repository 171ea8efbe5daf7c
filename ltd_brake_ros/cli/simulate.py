"""``ltd-brake simulate``: one emergency stop, or one command script, and its summary."""
from __future__ import annotations

import argparse

from .options import (CONVENTIONS, SHORTEST_CHUNK_S, add_run_spec_options, json_by_key,
                      run_spec)


def model_warnings(sim) -> list[str]:
    """Where the run leaves its models' validated ranges (imported when a run needs it)."""
    from ..recording.metadata import model_warnings as warnings_of

    return warnings_of(sim)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``simulate`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "simulate", help="one emergency stop: distance, time, peak coupler forces",
        description="Apply the emergency brake at t = 0 and integrate until the train stands "
                    "still. Prints lambda_train (Eq. 11), the speed at the brake command, the "
                    "stopping distance and time from it, the peak draft and buff forces with "
                    "their coupler numbers, the hottest brake blocks and wheels, the strength, "
                    "adhesion and temperature verdicts and the cost.",
        epilog=CONVENTIONS + "\nfirst run:\n  the first run after installing starts at "
               "once with the simulation kernels as plain Python\n  (the same numbers, "
               "slower) while they compile in the background (15-45 s, said with\n  an "
               "estimate) for later runs; LTD_BRAKE_FIRST_RUN=wait compiles them before the\n"
               "  run instead\n"
               "\nexamples:\n  ltd-brake simulate --scenario 6\n"
               "  ltd-brake simulate --consist my_train.yaml --speed-kmh 80 --json\n"
               "  ltd-brake simulate --scenario 6 --params brake_params/uic_brake_pipe.yaml "
               "--record runs/s6_pipe\n",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_spec_options(p)
    p.add_argument("--commands", metavar="FILE",
                   help="command script (t_s -> traction -1..1, brake_demand 0..1, emergency); "
                        "without it the emergency brake is applied at t = 0")
    p.add_argument("--json", action="store_true", help="print one JSON object (units in the keys)")
    p.add_argument("--record", metavar="DIR",
                   help="record the run into DIR (a new rosbag2/MCAP folder) with the topics of "
                        f"a sim_node recording, a state every {RECORD_CHUNK_S:g} s (the "
                        "emergency stop is then advanced in chunks of that length); "
                        "ltd-brake report DIR analyses it")
    p.add_argument("--adhesion", metavar="COND",
                   help="model wheel slide: cap each vehicle's brake force at the rail's "
                        "adhesion mu(v) m g; a brake that asks more locks its wheelsets, which "
                        "then slide at 0.4 mu m g (not verified) until the brake's static "
                        "friction falls below that: dry (Curtius-Kniffler 7.5/(V+44)+0.161), "
                        "wet (0.6 x dry), low (0.47 x dry, 0.10 at 100 km/h, not verified), a "
                        "number (constant mu), or a YAML file with speed_kmh, mu and source "
                        "lists; default: off, as in the paper's method")
    p.add_argument("--band", metavar="FILE", nargs="?", const="",
                   help="also run the stop under every member of a model-form band (every "
                        "brake model x every coupler model of FILE, default the shipped "
                        "bands/model_form.yaml) and print each key number as nominal [min, "
                        "max] with the members that gave each end, each member inside or "
                        "outside its models' ranges, and the band's verdict (PASS only if "
                        "every member inside its range passes; model-dependent where they "
                        "disagree; NON-PHYSICAL if any member is); not with --commands, "
                        "--record or --timeseries")
    p.add_argument("--rail", metavar="COND",
                   help="the rail condition the adhesion demand is judged against (a "
                        "warning, never a change of the run): dry, wet, low, a number or a "
                        "curve file as for --adhesion; default: --adhesion's, else dry")
    p.add_argument("--timeseries", metavar="FILE",
                   help="write every vehicle's and coupler's history, a sample every "
                        f"{RECORD_CHUNK_S:g} s, to FILE in long (tidy) form: time_s, element "
                        "(vehicle/coupler), number, quantity, unit, value; .parquet (needs "
                        "pyarrow) or .csv by the suffix; an existing FILE is refused")
    p.set_defaults(func=run)
    return p


def _band(args: argparse.Namespace, spec):
    """The ``--band`` of a stop: every member's run, and the nominal member's simulator."""
    from ..inputs.band import load_band
    from ..studies.band import run_band

    from ..inputs import InputError

    if _adhesion(args) is not None or args.rail:
        raise InputError("command line", "--band", "runs each member as the paper's method "
                         "does: not with --adhesion or --rail")
    return run_band(spec.consist, spec.speed_kmh, spec.params, spec.lut, spec.track,
                    band=load_band(args.band or None), step_s=args.step_s,
                    tolerance_m_s=tolerance(args), chunk_s=CHUNK_S, max_time_s=MAX_TIME_S)


def _rail(args: argparse.Namespace):
    """The ``--rail`` condition (None: the default)."""
    return _condition(getattr(args, "rail", None), "--rail")


def _adhesion(args: argparse.Namespace):
    """The ``--adhesion`` condition (None: off), a file read and checked here."""
    return _condition(getattr(args, "adhesion", None), "--adhesion")


def _condition(spec, option: str):
    """An adhesion condition of the command line (None: not given), a file read and checked
    here."""
    from ..inputs.adhesion import adhesion_condition

    return adhesion_condition(spec, "command line", option)


def _start_up(args, spec, params, lut, adhesion) -> float:
    """Load the simulation kernels before the timed run, or on the first run start compiling
    them (in the background while the run starts as plain Python, else here), saying so on
    stderr; returns the seconds it took."""
    import sys
    import time

    from ..first_run import prepare

    def say(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    start = time.perf_counter()
    # the same train as the run's: the run then takes this compiled model and bound step loop
    prepare(dict(consist=spec.consist, speed_kmh=spec.speed_kmh, params=params, lut=lut,
                 track=spec.track, adhesion=adhesion, step_s=args.step_s,
                 tolerance_m_s=tolerance(args)), say)
    return time.perf_counter() - start


def _timeseries(args: argparse.Namespace):
    """The sampler of ``--timeseries`` (None without it), the file checked before the run."""
    from pathlib import Path

    from ..inputs import InputError

    if not getattr(args, "timeseries", None):
        return None
    path = Path(args.timeseries)
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise InputError("command line", "--timeseries",
                         f"{path}: give a .parquet or .csv file")
    if path.exists():
        raise InputError("command line", "--timeseries",
                         f"{path} exists: choose a new file (nothing is overwritten)")
    if not path.parent.is_dir():
        raise InputError("command line", "--timeseries",
                         f"{path.parent} is not a folder")
    from ..api import _Sampler

    return _Sampler()


def _write_timeseries(args, sampler, sim, speed_kmh: float) -> None:
    from ..api import _attrs

    if sampler is not None:
        import sys

        series = sampler.series(sim, _attrs(sim, speed_kmh))
        series.write(args.timeseries)
        print(f"time series: {series.time_s.size} samples of {sim.n} vehicles written to "
              f"{args.timeseries}", file=sys.stderr)


def _chunk(rec, sampler, default_s: float) -> float:
    """Chunk length: the recording's or the time series' sample interval when sampling."""
    return RECORD_CHUNK_S if sampler is not None else rec.chunk_s(default_s)


def _on_chunk(rec, sampler, events: list):
    def on_chunk(snap):
        events.extend(snap.events)
        if sampler is not None:
            sampler(snap)
    return rec.after(on_chunk)


#: Simulated time per chunk of an emergency stop [s], and when to give up if the train has not
#: stopped [s] (as :func:`~ltd_brake_ros.studies.runs.emergency_stop`).
CHUNK_S, MAX_TIME_S = 1.0, 600.0
#: Simulated time between recorded states with ``--record`` [s]: the command-update interval
#: of a script run, so a recorded script run is the run without the recording.
RECORD_CHUNK_S = SHORTEST_CHUNK_S


def run(args: argparse.Namespace) -> int:
    """Run one emergency stop (or the ``--commands`` script) and print its summary."""
    import time

    from ..inputs import CommandScript, InputError
    from ..studies.runs import emergency_run, summarize

    if args.scenario is None and args.consist is None:
        raise InputError("command line", "--scenario/--consist",
                         "give a scenario number or a consist file")
    spec = run_spec(args)
    if args.commands:
        return _run_script(args, spec)
    if spec.speed_kmh <= 0.0:  # a command script may start at rest; a stop needs a speed
        raise InputError("command line", "--speed-kmh", "an emergency stop needs a speed above "
                         "0 km/h (a run of --commands may start at rest)")
    params, lut = spec.params, spec.lut
    if args.band is not None:
        for option, given in (("--record", args.record), ("--timeseries", args.timeseries)):
            if given:
                raise InputError("command line", "--band", f"runs every member of the band: "
                                 f"not with {option}")
    events = []
    sampler = _timeseries(args)
    startup_s = _start_up(args, spec, params, lut, _adhesion(args))
    # the recording's commands: the emergency brake at t = 0
    script = CommandScript(((0.0, {"emergency": True}),))
    with _Progress() as progress, _Recording(args, spec, script) as rec:
        start = time.perf_counter()  # the run and its recording, not opening the folder
        # recorded or sampled: chunk by chunk; else several chunks a call while the stop is far
        # (the same steps and verdicts: the kernel keeps the peaks; the first times of the
        # limit events then come at the calls' ends)
        band = None
        if args.band is not None:
            band, sim = _band(args, spec)
        else:
            sim = emergency_run(spec.consist, spec.speed_kmh, params, lut, spec.track,
                                adhesion=_adhesion(args), rail=_rail(args),
                                step_s=args.step_s, tolerance_m_s=tolerance(args),
                                chunk_s=_chunk(rec, sampler, CHUNK_S), max_time_s=MAX_TIME_S,
                                group=sampler is None and not rec.recording,
                                on_chunk=_on_chunk(rec, sampler, events), progress=progress,
                                on_start=sampler and sampler.start)
            rec.end(sim)
    res = summarize(sim, time.perf_counter() - start)
    _write_timeseries(args, sampler, sim, spec.speed_kmh)
    verdicts = sim.verdicts()
    lut_events = [e for e in events if e.kind == "coupler_out_of_lut"]
    if args.json:
        out = res.as_dict()
        out["params_file"] = params.source
        out["lut_file"] = lut.source
        out["brake_command_time_s"] = sim.command_time_s
        out["brake_command_speed_kmh"] = sim.command_speed_kmh
        out["venting_vehicle"] = spec.consist.venting_vehicle
        out["couplers_out_of_lut"] = [dict(e.detail, time_s=e.time_s) for e in lut_events]
        out["limits_exceeded"] = _limit_events(events)
        out["verdicts"] = verdicts.as_dict()
        out["non_physical"] = verdicts.non_physical
        out["stops"] = [s.as_dict() for s in sim.stops]
        if band is not None:
            out["band"] = band.as_dict()
        out["startup_s"] = startup_s
        out["plain_python_s"] = sim.plain_python_s
        out.update(sim.adhesion.as_dict())
        out["wheel_slides"] = sim.wheel_slides()
        out["warnings"] = model_warnings(sim)
        out.update(sim.brake_temperatures().as_dict())
        print(json_by_key(out))
        return 0
    print(f"train            {res.consist}: {res.vehicles} vehicles, {res.train_length_m:.1f} m, "
          f"{res.train_mass_t:.0f} t")
    print(f"braked weight    lambda_train = {res.braked_weight_percent:.1f} % (Eq. 11)")
    print(f"initial speed    {res.initial_speed_kmh:g} km/h")
    print(f"brake command    emergency at t = {sim.command_time_s:.2f} s, "
          f"{sim.command_speed_kmh:.2f} km/h; brake pipe vented at vehicle "
          f"{spec.consist.venting_vehicle}")
    print(f"stopping         {res.stopping_distance_m:.1f} m (the head's travel), every vehicle "
          f"at rest {res.stop_time_s:.2f} s after the brake command; "
          + ("not settled" if res.settled_time_s is None else
             f"settled from t = {res.settled_time_s:.2f} s (couplers' recoil over)"))
    print(f"peak draft       {res.peak_draft_kN:.1f} kN at coupler {res.peak_draft_coupler} "
          f"(t = {res.peak_draft_time_s:.2f} s; command to standstill)")
    print(f"peak buff        {res.peak_buff_kN:.1f} kN at coupler {res.peak_buff_coupler} "
          f"(t = {res.peak_buff_time_s:.2f} s; command to standstill)")
    if res.out_of_range.count:
        print(f"warning          {res.out_of_range.describe()}")
    for line in model_warnings(sim):
        print(f"warning          {line}")
    _print_slides(sim)
    _print_heat(sim)
    _print_verdicts(verdicts)
    if band is not None:
        print("\n".join(band.describe()))
    print(f"start-up         {startup_s:.2f} s {_start_up_part(sim)}")
    print(f"cost             {res.wall_time_s * 1e3:.0f} ms wall, {res.real_time_factor:.0f}x "
          f"real time{_plain_part(sim)}, {res.steps} steps ({res.rejected_steps} rejected, "
          f"shortest {res.smallest_step_s * 1e3:.2g} ms), {res.newton_iterations_per_step:.2f} "
          "Newton iterations per step")
    return 0


def _start_up_part(sim) -> str:
    """What the start-up of the cost line was."""
    if sim.plain_python_s > 0.0:
        return "(the simulation kernels compile in the background: a first run)"
    return "(compiling or loading the simulation kernels, once per process)"


def _plain_part(sim) -> str:
    """How much of the run ran its kernels as plain Python (a first run), for the cost line."""
    if sim.plain_python_s <= 0.0:
        return ""
    part = ("all of it" if sim.plain_python_s >= sim.time_s - 1e-9 else
            f"the first {sim.plain_python_s:.1f} s of {sim.time_s:.1f} s")
    return f" (kernels as plain Python while they compiled: {part})"


def tolerance(args: argparse.Namespace) -> float:
    """The ``--tolerance-m-s`` of a run, or the simulator's default [m/s] (the simulator
    checks its range)."""
    from ..physics.kernel import DEFAULT_TOLERANCE_M_S

    return DEFAULT_TOLERANCE_M_S if args.tolerance_m_s is None else args.tolerance_m_s


def _run_script(args: argparse.Namespace, spec) -> int:
    """Run a command script and print what happened."""
    import time

    from ..inputs import load_command_script
    from ..physics.constants import KMH_PER_MS
    from ..studies.runs import scripted_run

    script = load_command_script(args.commands)
    events = []
    sampler = _timeseries(args)
    _start_up(args, spec, spec.params, spec.lut, _adhesion(args))

    with _Progress() as progress, _Recording(args, spec, script) as rec:
        start = time.perf_counter()  # the run and its recording, not opening the folder
        sim = scripted_run(spec.consist, spec.speed_kmh, script, spec.params, spec.lut,
                           spec.track, adhesion=_adhesion(args), rail=_rail(args),
                           step_s=args.step_s, tolerance_m_s=tolerance(args),
                           chunk_s=_chunk(rec, sampler, RECORD_CHUNK_S),
                           on_chunk=_on_chunk(rec, sampler, events), progress=progress,
                           on_start=sampler and sampler.start)
        rec.end(sim)
    wall = time.perf_counter() - start
    _write_timeseries(args, sampler, sim, spec.speed_kmh)
    snap = sim.snapshot()
    peaks = sim.coupler_peaks()
    out = {
        "consist": spec.consist.name, "vehicles": spec.consist.n,
        "commands_file": script.source,
        "duration_s": sim.time_s, "final_speed_kmh": float(snap.speed_m_s[0]) * KMH_PER_MS,
        "brake_command_time_s": sim.command_time_s,
        "brake_command_speed_kmh": sim.command_speed_kmh,
        "distance_travelled_m": sim.distance_travelled_m,
        "stopping_distance_m": sim.stopping_distance_m,
        "stop_time_s": None if sim.stop_time_s is None else sim.stop_time_s - sim.command_time_s,
        "peak_draft_kN": peaks.draft_N / 1e3, "peak_draft_coupler": peaks.draft_coupler,
        "peak_buff_kN": peaks.buff_N / 1e3, "peak_buff_coupler": peaks.buff_coupler,
        "events": [dict(e.detail, kind=e.kind, time_s=e.time_s) for e in events],
        "wall_time_s": wall, "real_time_factor": sim.time_s / wall if wall > 0 else None,
        "plain_python_s": sim.plain_python_s,
        "verdicts": sim.verdicts().as_dict(),
        "stops": [s.as_dict() for s in sim.stops],
        **sim.adhesion.as_dict(), "wheel_slides": sim.wheel_slides(),
        "warnings": model_warnings(sim),
        **sim.brake_temperatures().as_dict(),
    }
    if args.json:
        print(json_by_key(out))
        return 0
    print(f"train            {spec.consist.name}: {spec.consist.n} vehicles; "
          f"script {script.source}")
    print(f"ran              {sim.time_s:.1f} s, {out['distance_travelled_m']:.1f} m, final "
          f"speed {out['final_speed_kmh']:.1f} km/h")
    for stop in sim.stops:
        print(f"stop             {stop.describe()}")
    for e in events:
        if e.kind not in ("coupler_out_of_lut", "limit_exceeded"):
            print(f"event            {e.describe()}")
    beyond = sim.coupler_excursions()
    if beyond.count:
        print(f"warning          {beyond.describe()}")
    for line in model_warnings(sim):
        print(f"warning          {line}")
    print(f"peak draft       {out['peak_draft_kN']:.1f} kN at coupler {peaks.draft_coupler}")
    print(f"peak buff        {out['peak_buff_kN']:.1f} kN at coupler {peaks.buff_coupler}")
    _print_slides(sim)
    _print_heat(sim)
    _print_verdicts(sim.verdicts())
    print(f"cost             {wall * 1e3:.0f} ms wall, {out['real_time_factor']:.0f}x real "
          f"time{_plain_part(sim)}")
    return 0


def _limit_events(events) -> list[dict]:
    """The ``limit_exceeded`` events of a run, as JSON."""
    return [dict(e.detail, time_s=e.time_s) for e in events if e.kind == "limit_exceeded"]


def _print_slides(sim) -> None:
    """One line on wheel slide when an adhesion condition is set."""
    if not sim.adhesion.on:
        return
    slides = sim.wheel_slides()
    cond = sim.adhesion
    text = (f"wheel slide      adhesion {cond.name} ({cond.source}), locked wheelsets slide at "
            f"{cond.sliding_ratio:g} x mu ({cond.sliding_source}): ")
    if not slides:
        print(text + "no wheel slid")
        return
    worst = max(slides, key=lambda s: s["duration_s"])
    print(text + f"{len(slides)} vehicles slid, longest vehicle {worst['vehicle']} for "
          f"{worst['duration_s']:.2f} s from t = {worst['first_s']:.2f} s")


def _print_heat(sim) -> None:
    """One line on the hottest brake blocks and wheels (mean temperatures of the lumped
    model, :mod:`~ltd_brake_ros.physics.brakes.thermal`)."""
    print(f"brake heat       {sim.brake_temperatures().describe()}")


def _print_verdicts(verdicts) -> None:
    """The verdicts table, one line per criterion and per coupler or vehicle beyond a limit."""
    lines = verdicts.describe()
    print(f"verdicts         {verdicts.status}"
          + ("  (NON-PHYSICAL: see the last line)" if verdicts.non_physical else ""))
    for line in lines:
        print(f"  {line}")


class _Progress:
    """Progress of a long run on stderr (a terminal only, after 2 s of wall time); as a
    context, the callback of a run, None when stderr is no terminal."""

    #: Wall time before progress is shown [s].
    AFTER_S = 2.0

    def __init__(self):
        import sys

        self._stream = sys.stderr
        self._shown = False
        self._enabled = self._stream.isatty()

    def __enter__(self) -> "_Progress | None":
        # nothing to call back without a terminal
        return self if self._enabled else None

    def __call__(self, p) -> None:
        if not self._enabled or p.wall_s < self.AFTER_S:
            return
        done = f" ({100.0 * p.fraction:.0f} %)" if p.fraction is not None else ""
        self._stream.write(f"\r  simulated {p.time_s:.0f} s{done}, {p.wall_s:.0f} s wall ")
        self._stream.flush()
        self._shown = True

    def __exit__(self, *exc) -> None:
        if self._shown:
            self._stream.write("\r\033[K")
            self._stream.flush()


class _Recording:
    """The ``--record`` folder of a run: the states, ``/clock`` and the script's commands.

    Written as ``sim_node`` records a run
    (:func:`~ltd_brake_ros.recording.plant_topics.plant_topics` in the root namespace,
    :class:`~ltd_brake_ros.recording.plant_topics.StateEncoder`, so a
    brake model's extras such as the brake-pipe pressures are recorded too), with the run
    information of :func:`~ltd_brake_ros.recording.metadata.run_metadata`. Each command is
    recorded at the chunk boundary where :func:`~ltd_brake_ros.studies.runs.scripted_run`
    applies it. Without ``--record`` it does nothing.
    """

    def __init__(self, args: argparse.Namespace, spec, script):
        self._folder = getattr(args, "record", None)
        self._args, self._spec, self._script = args, spec, script
        self._rec = self._encoder = None
        self._next = 0  # first script step not recorded yet

    @property
    def recording(self) -> bool:
        """A recording was asked for."""
        return bool(self._folder)

    def chunk_s(self, default_s: float) -> float:
        """Chunk length of the run [s]: :data:`RECORD_CHUNK_S` when recording."""
        return RECORD_CHUNK_S if self._folder else default_s

    def after(self, on_chunk):
        """``on_chunk`` that records the chunk's state first."""
        if not self._folder:
            return on_chunk

        def both(snap):
            self._state(snap)
            on_chunk(snap)
        return both

    def __enter__(self) -> "_Recording":
        if not self._folder:
            return self
        import logging

        from ..inputs import InputError
        from ..plant.recorder import Recorder
        from ..plant.settings import StartupError
        from ..recording.metadata import run_metadata, train_description
        from ..recording.plant_topics import StateEncoder, plant_topics
        from ..simulator import Simulator

        spec = self._spec
        # the run's simulator before its first chunk: the train layout, extras and t = 0 state
        sim = Simulator(spec.consist, spec.speed_kmh, spec.params, spec.lut, spec.track,
                        step_s=self._args.step_s, tolerance_m_s=tolerance(self._args))
        snap = sim.snapshot()
        extras = tuple(snap.extras)
        emergency = any(step.get("emergency") for _, step in self._script.steps)
        meta = run_metadata(sim, scenario=self._args.scenario,
                            brake_params=str(spec.params.source),
                            coupler_lut=str(spec.lut.source),
                            **({"commands_file": str(self._script.source)}
                               if self._args.commands else {}),
                            **({"command_time_s": next(
                                t for t, step in self._script.steps if step.get("emergency"))}
                               if emergency else {}))
        self._encoder = StateEncoder(sim.n, sim.model.train.centre_offset_m, extras=extras,
                                     description=train_description(sim, meta))
        rec = Recorder(str(self._folder), plant_topics("/", extras), logging.getLogger(__name__),
                       metadata=meta)
        try:
            rec.check()
            rec.open()
        except StartupError as exc:
            raise InputError("command line", "--record", exc.reason) from None
        except (LookupError, ImportError) as exc:  # the message definitions written in the file
            raise InputError("command line", "--record", f"{exc}: a recording needs std_msgs, "
                             "sensor_msgs and rosgraph_msgs installed") from None
        self._rec = rec
        self._state(snap)
        return self

    def _state(self, snap) -> None:
        from ..recording.plant_topics import command_messages, qualify

        t_ns = round(snap.time_s * 1e9)  # the node's stamp of a state
        steps = self._script.steps
        # the commands the next chunk applies, then the state they start from
        while self._next < len(steps) and steps[self._next][0] <= snap.time_s + 1e-9:
            for topic, data in command_messages(steps[self._next][1]):
                self._rec.write(qualify("/", topic), data, t_ns)
            self._next += 1
        for topic, data in self._encoder.encode(snap, t_ns):
            self._rec.write(qualify("/", topic), data, t_ns)

    def end(self, sim) -> None:
        """Record how the run ends: the verdicts of a stop still open
        (:meth:`~ltd_brake_ros.simulator.Simulator.end_events`)."""
        if self._rec is None:
            return
        from ..recording.plant_topics import StateEncoder, qualify

        t_ns = round(sim.time_s * 1e9)
        for topic, data in StateEncoder.encode_events(sim.end_events()):
            self._rec.write(qualify("/", topic), data, t_ns)

    def __exit__(self, *exc) -> None:
        if self._rec is None:
            return
        self._rec.close()
        if self._rec.error:
            from ..inputs import InputError

            raise InputError("command line", "--record", f"recording {self._folder} failed: "
                             f"{self._rec.error}")

"""``ltd-brake simulate``: one emergency stop, or one command script, and its summary."""
from __future__ import annotations

import argparse
import json

from ..inputs import InputError
from .options import CONVENTIONS, add_run_spec_options, run_spec


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``simulate`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "simulate", help="one emergency stop: distance, time, peak coupler forces",
        description="Apply the emergency brake at t = 0 and integrate until the train stands "
                    "still. Prints lambda_train (Eq. 11), the speed at the brake command, the "
                    "stopping distance and time from it, the peak draft and buff forces with "
                    "their coupler numbers, the strength and adhesion verdicts and the cost.",
        epilog=CONVENTIONS + "\nexamples:\n  ltd-brake simulate --scenario 6\n"
               "  ltd-brake simulate --consist my_train.yaml --speed-kmh 80 --json\n",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_spec_options(p)
    p.add_argument("--commands", metavar="FILE",
                   help="command script (t_s -> traction -1..1, brake_demand 0..1, emergency); "
                        "without it the emergency brake is applied at t = 0")
    p.add_argument("--json", action="store_true", help="print one JSON object (units in the keys)")
    p.set_defaults(func=run)
    return p


#: Simulated time per chunk of an emergency stop [s], and when to give up if the train has not
#: stopped [s] (as :func:`~ltd_brake_ros.studies.runs.emergency_stop`).
CHUNK_S, MAX_TIME_S = 1.0, 600.0


def run(args: argparse.Namespace) -> int:
    """Run one emergency stop (or the ``--commands`` script) and print its summary."""
    import time

    from ..inputs import CommandScript
    from ..simulator import SimulationError
    from ..studies.runs import scripted_run, summarize

    if args.scenario is None and args.consist is None:
        raise InputError("command line", "--scenario/--consist",
                         "give a scenario number or a consist file")
    spec = run_spec(args)
    if args.commands:
        return _run_script(args, spec)
    params, lut = spec.params, spec.lut
    events = []
    # the emergency stop as a one-command script, so that the simulator (and its verdicts)
    # outlives the run; the chunks are those of emergency_stop, and so are the results
    start = time.perf_counter()
    with _Progress() as progress:
        sim = scripted_run(spec.consist, spec.speed_kmh,
                           CommandScript(((0.0, {"emergency": True}),)), params, lut,
                           spec.track, step_s=args.step_s, tolerance_m_s=tolerance(args),
                           chunk_s=CHUNK_S, max_time_s=MAX_TIME_S,
                           on_chunk=lambda s: events.extend(s.events), progress=progress)
    if sim.stop_time_s is None:
        raise SimulationError(f"the train had not stopped after {MAX_TIME_S:g} s")
    res = summarize(sim, time.perf_counter() - start)
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
        print(json.dumps(out, indent=2))
        return 0
    print(f"train            {res.consist}: {res.vehicles} vehicles, {res.train_length_m:.1f} m, "
          f"{res.train_mass_t:.0f} t")
    print(f"braked weight    lambda_train = {res.braked_weight_percent:.1f} % (Eq. 11)")
    print(f"initial speed    {res.initial_speed_kmh:g} km/h")
    print(f"brake command    emergency at t = {sim.command_time_s:.2f} s, "
          f"{sim.command_speed_kmh:.2f} km/h; brake pipe vented at vehicle "
          f"{spec.consist.venting_vehicle}")
    print(f"stopping         {res.stopping_distance_m:.1f} m in {res.stop_time_s:.2f} s from "
          "the brake command")
    print(f"peak draft       {res.peak_draft_kN:.1f} kN at coupler {res.peak_draft_coupler} "
          f"(t = {res.peak_draft_time_s:.2f} s)")
    print(f"peak buff        {res.peak_buff_kN:.1f} kN at coupler {res.peak_buff_coupler} "
          f"(t = {res.peak_buff_time_s:.2f} s)")
    if res.out_of_range.count:
        print(f"warning          {res.out_of_range.describe()}")
    _print_verdicts(verdicts)
    print(f"cost             {res.wall_time_s * 1e3:.0f} ms wall, {res.real_time_factor:.0f}x "
          f"real time, {res.steps} steps ({res.rejected_steps} rejected, shortest "
          f"{res.smallest_step_s * 1e3:.2g} ms), {res.newton_iterations_per_step:.2f} Newton "
          "iterations per step")
    return 0


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

    start = time.perf_counter()
    with _Progress() as progress:
        sim = scripted_run(spec.consist, spec.speed_kmh, script, spec.params, spec.lut,
                           spec.track, step_s=args.step_s, tolerance_m_s=tolerance(args),
                           on_chunk=lambda s: events.extend(s.events), progress=progress)
    wall = time.perf_counter() - start
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
        "verdicts": sim.verdicts().as_dict(),
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"train            {spec.consist.name}: {spec.consist.n} vehicles; "
          f"script {script.source}")
    print(f"ran              {sim.time_s:.1f} s, {out['distance_travelled_m']:.1f} m, final "
          f"speed {out['final_speed_kmh']:.1f} km/h")
    if sim.command_time_s is not None:
        print(f"brake command    t = {sim.command_time_s:.2f} s, {sim.command_speed_kmh:.2f} km/h"
              + ("" if sim.stopping_distance_m is None else
                 f"; stopped {sim.stopping_distance_m:.1f} m further"))
    for e in events:
        if e.kind not in ("coupler_out_of_lut", "limit_exceeded"):
            print(f"event            {e.describe()}")
    beyond = sim.coupler_excursions()
    if beyond.count:
        print(f"warning          {beyond.describe()}")
    print(f"peak draft       {out['peak_draft_kN']:.1f} kN at coupler {peaks.draft_coupler}")
    print(f"peak buff        {out['peak_buff_kN']:.1f} kN at coupler {peaks.buff_coupler}")
    _print_verdicts(sim.verdicts())
    print(f"cost             {wall * 1e3:.0f} ms wall, {out['real_time_factor']:.0f}x real time")
    return 0


def _limit_events(events) -> list[dict]:
    """The ``limit_exceeded`` events of a run, as JSON."""
    return [dict(e.detail, time_s=e.time_s) for e in events if e.kind == "limit_exceeded"]


def _print_verdicts(verdicts) -> None:
    """The verdicts table, one line per criterion and per coupler or vehicle beyond a limit."""
    lines = verdicts.describe()
    print(f"verdicts         {'PASS' if verdicts.passed else 'FAIL'}")
    for line in lines:
        print(f"  {line}")


class _Progress:
    """Progress of a long run on stderr (a terminal only, after 2 s of wall time)."""

    #: Wall time before progress is shown [s].
    AFTER_S = 2.0

    def __init__(self):
        import sys

        self._stream = sys.stderr
        self._shown = False
        self._enabled = self._stream.isatty()

    def __enter__(self) -> "_Progress":
        return self

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

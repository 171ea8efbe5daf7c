"""``ltd-brake``: the command-line tool (simulate, validate, ...).

Every subcommand prints a helpful error and exits non-zero on bad input, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from ..inputs import InputError

CONVENTIONS = """\
units and signs:
  speeds in km/h on the command line, SI (m, s, N) in files and JSON unless the key says
  otherwise (e.g. peak_draft_kN); coupler 1 is the coupler behind the head vehicle; draft
  (tension) forces are positive, buff (compression) forces negative; the stopping distance is
  the head's travel from the emergency command to standstill (every vehicle < 1 mm/s).
"""


def _add_model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--params", metavar="FILE",
                   help="brake-parameter YAML (t_app_s, v_air_m_s, t_fill_s, k0, k_loco, "
                        "mu_eff); default: config/brake_params/paper.yaml (Table 3)")
    p.add_argument("--lut", metavar="FILE",
                   help="coupler LUT YAML (deflection_mm, loading_kN, unloading_kN); default: "
                        "the reconstructed buffer-hook table config/couplers/buffer_hook_pugi.yaml")
    p.add_argument("--v-th-mm-s", type=float, metavar="MM_S",
                   help="Eq. 3 threshold speed between loading and unloading curves [mm/s] "
                        "(default: the LUT file's, 0.1)")
    p.add_argument("--step-s", type=float, default=0.01, metavar="S",
                   help="integration step [s] (default 0.01)")


def _model(args):
    from ..inputs import load_brake_params, load_coupler_lut

    return load_brake_params(args.params), load_coupler_lut(args.lut, args.v_th_mm_s)


#: Command-line option of each run-spec input, for error messages.
RUN_SPEC_OPTIONS = {"consist": "--scenario/--consist", "speed_kmh": "--speed-kmh",
                    "brake_params": "--params", "coupler_lut": "--lut", "track": "--track"}


def _run_spec(args):
    from ..run_spec import RunSpecError, resolve_run_spec

    try:
        return resolve_run_spec(args.consist, scenario=args.scenario, speed_kmh=args.speed_kmh,
                                params_file=args.params, lut_file=args.lut,
                                v_th_mm_s=args.v_th_mm_s, track_file=args.track,
                                start_chainage_m=args.start_chainage_m)
    except RunSpecError as exc:
        if exc.source != exc.input_name:
            raise  # a file's error names the file and field
        raise InputError("command line", RUN_SPEC_OPTIONS[exc.input_name], exc.reason) from None


def cmd_simulate(args) -> int:
    """Run one emergency stop and print its summary."""
    from ..studies.runs import emergency_stop

    if args.scenario is None and args.consist is None:
        raise InputError("command line", "--scenario/--consist", "give a scenario number or a consist file")
    spec = _run_spec(args)
    consist, speed, params, lut = spec.consist, spec.speed_kmh, spec.params, spec.lut
    track = spec.track
    if args.commands:
        return _simulate_script(args, consist, speed, params, lut, track)
    events = []
    res = emergency_stop(consist, speed, params, lut, track, step_s=args.step_s,
                         on_chunk=lambda s: events.extend(s.events))
    lut_events = [e for e in events if e.kind == "coupler_out_of_lut"]
    if args.json:
        out = res.as_dict()
        out["params_file"] = params.source
        out["lut_file"] = lut.source
        out["couplers_out_of_lut"] = [dict(e.detail, time_s=e.time_s) for e in lut_events]
        print(json.dumps(out, indent=2))
        return 0
    print(f"train            {res.consist}: {res.vehicles} vehicles, {res.train_length_m:.1f} m, "
          f"{res.train_mass_t:.0f} t")
    print(f"braked weight    lambda_train = {res.braked_weight_percent:.1f} % (Eq. 11)")
    print(f"initial speed    {res.initial_speed_kmh:g} km/h, emergency brake at t = 0")
    print(f"stopping         {res.stopping_distance_m:.1f} m in {res.stop_time_s:.2f} s")
    print(f"peak draft       {res.peak_draft_kN:.1f} kN at coupler {res.peak_draft_coupler} "
          f"(t = {res.peak_draft_time_s:.2f} s)")
    print(f"peak buff        {res.peak_buff_kN:.1f} kN at coupler {res.peak_buff_coupler} "
          f"(t = {res.peak_buff_time_s:.2f} s)")
    for e in lut_events:
        print(f"warning          {e.describe()}")
    if res.couplers_beyond_lut:
        print(f"warning          {res.couplers_beyond_lut} couplers left the coupler table, "
              f"by up to {res.max_beyond_lut_mm:.1f} mm")
    print(f"cost             {res.wall_time_s * 1e3:.0f} ms wall, {res.real_time_factor:.0f}x "
          f"real time, {res.steps} steps, {res.newton_iterations_per_step:.2f} Newton "
          "iterations per step")
    return 0


def _simulate_script(args, consist, speed, params, lut, track) -> int:
    """Run a command script and print what happened."""
    import time

    import numpy as np

    from ..inputs import load_command_script
    from ..studies.runs import scripted_run

    script = load_command_script(args.commands)
    events = []
    head = {"t": [], "v": []}

    def collect(snap):
        events.extend(snap.events)

    start = time.perf_counter()
    sim = scripted_run(consist, speed, script, params, lut, track, step_s=args.step_s,
                       on_chunk=collect)
    wall = time.perf_counter() - start
    snap = sim.snapshot()
    draft, buff = sim.peak_draft_N, sim.peak_buff_N
    jd = int(np.argmax(draft)) if draft.size else 0
    jb = int(np.argmin(buff)) if buff.size else 0
    out = {
        "consist": consist.name, "vehicles": consist.n, "commands_file": script.source,
        "duration_s": sim.time_s, "final_speed_kmh": float(snap.speed_m_s[0]) * 3.6,
        "distance_travelled_m": float(sim._x[0]),
        "stopping_distance_m": sim.stopping_distance_m,
        "stop_time_s": None if sim.stop_time_s is None else sim.stop_time_s - sim.command_time_s,
        "peak_draft_kN": float(draft[jd]) / 1e3 if draft.size else 0.0,
        "peak_draft_coupler": jd + 1,
        "peak_buff_kN": float(buff[jb]) / 1e3 if buff.size else 0.0,
        "peak_buff_coupler": jb + 1,
        "events": [dict(e.detail, kind=e.kind, time_s=e.time_s) for e in events],
        "wall_time_s": wall, "real_time_factor": sim.time_s / wall if wall > 0 else None,
    }
    del head
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"train            {consist.name}: {consist.n} vehicles; script {script.source}")
    print(f"ran              {sim.time_s:.1f} s, {out['distance_travelled_m']:.1f} m, final "
          f"speed {out['final_speed_kmh']:.1f} km/h")
    for e in events:
        print(f"event            {e.describe()}")
    print(f"peak draft       {out['peak_draft_kN']:.1f} kN at coupler {jd + 1}")
    print(f"peak buff        {out['peak_buff_kN']:.1f} kN at coupler {jb + 1}")
    print(f"cost             {wall * 1e3:.0f} ms wall, {out['real_time_factor']:.0f}x real time")
    return 0


def _fmt(value, spec: str) -> str:
    return "NA" if value is None else format(value, spec)


def validation_table(rows) -> str:
    """Markdown table of Tables 1-2 beside our results.

    Parameters
    ----------
    rows : list of ValidationRow

    Returns
    -------
    str
    """
    head = ("| No. | train | V0 km/h | λ % | UIC m | Pugi m | LTDPoliTo m | ours m | vs LTDPoliTo | "
            "vs UIC | draft kN@c paper | ours | buff kN@c paper | ours |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        p, q = r.scenario.paper, r.result
        uic_err = r.uic_error_percent
        lines.append(
            f"| {r.scenario.number} | {q.consist} "
            f"| {q.initial_speed_kmh:g} | {q.braked_weight_percent:.1f} | {_fmt(p.get('uic_m'), '.1f')} "
            f"| {p['pugi_m']:g} | {p['ltdpolito_m']:.1f} | {q.stopping_distance_m:.1f} "
            f"| {r.distance_error_percent:+.2f} % | {'NA' if uic_err is None else f'{uic_err:+.2f} %'} "
            f"| {p['draft_kN']}@{p['draft_coupler']} | {q.peak_draft_kN:.0f}@{q.peak_draft_coupler} "
            f"| {p['buff_kN']}@{p['buff_coupler']} | {-q.peak_buff_kN:.0f}@{q.peak_buff_coupler} |")
    return "\n".join(lines)


def cmd_validate(args) -> int:
    """Print the paper's Tables 1-2 beside our results."""
    from ..studies.runs import validate

    params, lut = _model(args)
    scenarios = _parse_scenarios(args.scenarios) if args.scenarios else None
    rows = validate(params, lut, scenarios, step_s=args.step_s,
                    workers=args.jobs or os.cpu_count() or 1)
    if args.json:
        print(json.dumps([dict(scenario=r.scenario.number, paper=r.scenario.paper,
                               ours=r.result.as_dict(),
                               distance_error_vs_ltdpolito_percent=r.distance_error_percent,
                               distance_error_vs_uic_percent=r.uic_error_percent)
                          for r in rows], indent=2))
        return 0
    print(f"brake parameters: {params.source}; coupler table: {lut.source}")
    print(validation_table(rows))
    errs100 = [abs(r.distance_error_percent) for r in rows if r.scenario.speed_kmh == 100]
    errs50 = [abs(r.distance_error_percent) for r in rows if r.scenario.speed_kmh == 50]
    uic = [abs(r.uic_error_percent) for r in rows if r.uic_error_percent is not None]
    print()
    if errs100:
        print(f"largest stopping-distance error vs LTDPoliTo at 100 km/h: {max(errs100):.2f} %")
    if errs50:
        print(f"largest stopping-distance error vs LTDPoliTo at 50 km/h:  {max(errs50):.2f} %")
    if uic:
        print(f"largest stopping-distance error vs UIC 544-1 at 100 km/h: {max(uic):.2f} %")
    print("buff forces are listed as magnitudes; lambda is recomputed by Eq. 11 "
          "(row 4 prints 117.4 % in the paper, a typo for 115.1 %)")
    return 0


def _parse_scenarios(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                out.extend(range(int(a), int(b) + 1))
            elif part:
                out.append(int(part))
        except ValueError:
            raise InputError("command line", "--scenarios",
                             f"expected numbers and ranges like 1-6,9, got {text!r}") from None
    return out


def build_parser() -> argparse.ArgumentParser:
    """The ``ltd-brake`` argument parser.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
        prog="ltd-brake",
        description="Freight-train emergency braking: longitudinal train dynamics with the "
                    "empirical UIC braked-weight air-brake model (Bosso, Magelli, Zampieri et al.).",
        epilog=CONVENTIONS, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser(
        "simulate", help="one emergency stop: distance, time, peak coupler forces",
        description="Apply the emergency brake at t = 0 and integrate until the train stands "
                    "still. Prints lambda_train (Eq. 11), the stopping distance and time, the "
                    "peak draft and buff forces with their coupler numbers, and the cost.",
        epilog=CONVENTIONS + "\nexamples:\n  ltd-brake simulate --scenario 6\n"
               "  ltd-brake simulate --consist my_train.yaml --speed-kmh 80 --json\n",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", metavar="N",
                   help="run N of the paper's Tables 1-2 (1-12): composition and initial speed")
    p.add_argument("--consist", metavar="FILE",
                   help="consist YAML (vehicles from the head); overrides the scenario's train")
    p.add_argument("--speed-kmh", type=float, metavar="KMH",
                   help="initial speed [km/h] (default: the scenario's, else 100)")
    _add_model_options(p)
    p.add_argument("--track", metavar="FILE",
                   help="track profile, YAML (sections: from_m, gradient_permille uphill "
                        "positive, radius_m) or CSV (chainage_m,gradient_permille,radius_m); "
                        "default: level straight track")
    p.add_argument("--start-chainage-m", type=float, metavar="M",
                   help="chainage of the head's front at t = 0 [m] (default: the track file's)")
    p.add_argument("--commands", metavar="FILE",
                   help="command script (t_s -> traction -1..1, brake_demand 0..1, emergency); "
                        "without it the emergency brake is applied at t = 0")
    p.add_argument("--json", action="store_true", help="print one JSON object (units in the keys)")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "validate", help="the paper's Tables 1-2 side by side with ours",
        description="Run the 12 scenarios of Tables 1-2 and print the UIC 544-1, Pugi and "
                    "LTDPoliTo stopping distances, ours and the error, and the peak coupler "
                    "forces with their positions.",
        epilog=CONVENTIONS, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenarios", metavar="LIST", help="subset, e.g. 1-6 or 2,6,12 (default: all)")
    p.add_argument("--jobs", type=int, metavar="N", help="parallel processes (default: all cores)")
    _add_model_options(p)
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.set_defaults(func=cmd_validate)

    from ..studies.calibration import add_parser as add_calibrate_parser
    from ..analysis.report import add_parsers as add_report_parsers

    add_calibrate_parser(sub)
    add_report_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ltd-brake``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 success, 2 bad input, 3 simulation failure.
    """
    from ..simulator import SimulationError

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except InputError as exc:
        print(f"ltd-brake {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"ltd-brake {args.command}: simulation failed: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"ltd-brake {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

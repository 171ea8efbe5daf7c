"""``ltd-brake calibrate``: fit brake-model parameters to reference stopping distances, or
coupler parameters to the paper's peak in-train forces."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .options import (add_model_options, check_output_file, load_model, parse_scenarios,
                      positive_int)

HELP = """\
Fit brake-model parameters so that simulated emergency stopping distances match reference
distances, by bounded nonlinear least squares on the relative errors (S_sim - S_ref) / S_ref;
or (--target forces) coupler parameters so that the peak draft and buff forces match the
paper's Tables 1-2. Prints the targets before and after, the leave-one-train-out errors (each
train predicted by the values fitted to the others), the fitted values with 95 % confidence
intervals and their correlation matrix, and warns about parameters the chosen trains cannot
determine. Of two parameters the targets cannot tell apart, the one listed later in --fit is
held at its start value (--params/--lut, or --set) and the rest fitted again.
"""

EPILOG = """\
targets:
  uic     UIC 544-1 emergency stopping distances from 100 km/h (the only speed with UIC
          values): Table 1's UIC column for the paper's trains (scenarios 1-6), and the UIC
          curve S = C/lambda + D (C = 50752 m %, D = 53.45 m, lambda by Eq. 11) for every
          train added with --consist. Extra trains of other lengths or braked-weight
          percentages help separate v_air (length-dependent) from t_app and t_fill.
  paper   the LTDPoliTo column of Tables 1-2 (the paper's own model), at 100 or 50 km/h.
  forces  the peak draft and buff forces of Tables 1-2 (every run unless --speed-kmh or
          --scenarios choose), fitting coupler parameters: errors in fractions of the
          targets (draft +/-10 %, buff +/-20 %), coupler positions beyond +/-2 and
          LTDPoliTo distances beyond 0.1 % (100 km/h) / 0.7 % (50 km/h) as penalties.
          --out writes a coupler file (--lut); the brake parameters (--params) stay.

parameters (--fit) of the {model} brake model, with the bounds of the fit:
{parameters}
  Parameters not fitted keep their --params values. A parameter file that names another
  brake model (model: ...) offers that model's parameters.

parameters (--fit, --target forces) of the {coupler} coupler model:
{coupler_parameters}
  The buff scale is bounded by the energy one buffer stores over its 105 mm stroke, UIC
  526-1 / EN 15551 category A (30 kJ) to C (70 kJ), relative to the 21.5 kJ of the Fig. 4
  reconstruction (config/couplers/buffer_hook_fig4.yaml).

a parameter file is written (--out) only when no fitted value sits on a bound (the bound, not
the data, would set it): narrow what is fitted, or give --allow-on-bound.

units: speeds in km/h, distances in m, times in s. The confidence intervals are 95 %,
Student t with (targets - parameters) degrees of freedom, from (J^T J)^-1 s^2 at the optimum.

examples:
  ltd-brake calibrate --target uic --fit t_app,v_air,k0 --bounds v_air=250:290 --out my_uic.yaml
  ltd-brake calibrate --target paper --speed-kmh 50 --fit k0
  ltd-brake calibrate --target forces --lut couplers/buffer_hook_fig4.yaml --out my_coupler.yaml
  ltd-brake validate --params my_uic.yaml --lut my_coupler.yaml
"""

#: Default --fit of each target.
DEFAULT_FIT = {"uic": "t_app,v_air,t_fill,k0", "paper": "t_app,v_air,t_fill,k0",
               "forces": "buff_scale,draft_scale,buff_hysteresis,draft_hysteresis"}


def _rows(table) -> str:
    return "\n".join(f"  {p.name:<16} {'[' + p.unit + ']':<6} "
                     f"{f'{p.lower:.3g} to {p.upper:.3g}':<13} {p.meaning}"
                     for p in table.values())


def _epilog() -> str:
    from ..physics.brakes import DEFAULT_MODEL
    from ..physics.couplers import DEFAULT_MODEL as COUPLER_MODEL
    from ..studies.calibration import coupler_fit_parameters, fit_parameters

    return EPILOG.format(model=DEFAULT_MODEL, parameters=_rows(fit_parameters(DEFAULT_MODEL)),
                         coupler=COUPLER_MODEL,
                         coupler_parameters=_rows(coupler_fit_parameters(COUPLER_MODEL)))


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Fills in the parameter tables of :data:`EPILOG` when the help is shown: they come from
    the brake and coupler models, which building the parser does not import."""

    def add_text(self, text):
        super().add_text(_epilog() if text is EPILOG else text)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``calibrate`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "calibrate", help="fit brake parameters to UIC 544-1 or the paper's distances, "
                          "coupler parameters to the paper's peak forces",
        description=HELP, epilog=EPILOG, formatter_class=_HelpFormatter)
    p.add_argument("--target", choices=("uic", "paper", "forces"), default="uic",
                   help="reference: uic (UIC 544-1 distances, 100 km/h only), paper "
                        "(LTDPoliTo distances) or forces (peak forces of Tables 1-2, coupler "
                        "parameters); default uic")
    p.add_argument("--speed-kmh", type=float, metavar="KMH",
                   help="initial speed [km/h]: the rows of Tables 1-2 to fit (default 100; "
                        "--target forces: every row)")
    p.add_argument("--fit", metavar="LIST",
                   help="comma-separated parameters to fit, in order of priority (default "
                        "t_app,v_air,t_fill,k0; --target forces: buff_scale,draft_scale,"
                        "buff_hysteresis,draft_hysteresis)")
    p.add_argument("--bounds", metavar="LIST",
                   help="narrower bounds of fitted parameters, e.g. v_air=250:290 (units as "
                        "in the table below)")
    p.add_argument("--set", metavar="LIST", dest="set_values",
                   help="start values (and the values held when not fitted) overriding the "
                        "--params/--lut file, e.g. t_fill=4")
    p.add_argument("--keep-correlated", action="store_true",
                   help="fit every --fit parameter even when the targets cannot tell two apart")
    p.add_argument("--no-cross-validation", action="store_true",
                   help="skip the leave-one-train-out refits")
    p.add_argument("--allow-on-bound", action="store_true",
                   help="write --out even when a fitted value sits on a bound")
    p.add_argument("--allow-unconverged", action="store_true",
                   help="write --out even when the fit did not converge (the file says so in "
                        "its first line)")
    p.add_argument("--draft-limit-kn", type=float, metavar="KN",
                   help="--target forces: also keep the peak draft of the light long trains "
                        "that snatch as they stop (E402B + 34-40 Shimmns from 40-50 km/h) "
                        "below this force [kN], e.g. 500")
    p.add_argument("--scenarios", metavar="LIST",
                   help="rows of Tables 1-2, e.g. 1-6 or 1,3,5 (default: all at --speed-kmh)")
    p.add_argument("--consist", action="append", metavar="FILE",
                   help="add a train (consist YAML) with the UIC curve as its target; "
                        "repeatable; --target uic only")
    add_model_options(p)
    p.add_argument("--max-nfev", type=int, default=60, metavar="N",
                   help="most residual evaluations of the optimiser (default 60)")
    p.add_argument("--jobs", type=int, metavar="N",
                   help="parallel processes (default: all cores)")
    p.add_argument("--out", metavar="FILE",
                   help="write the fitted parameters as a brake-parameter YAML for "
                        "simulate/validate/sim_node (--params); never one of the input files")
    p.add_argument("--force", action="store_true",
                   help="let --out replace an existing file (never an input)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


def command_line(args: argparse.Namespace, fit) -> str:
    """The canonical ``ltd-brake calibrate`` command for parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
    fit : list of FitParameter
        The parameters fitted, as parsed from ``--fit``.

    Returns
    -------
    str
    """
    parts = ["ltd-brake calibrate", f"--target {args.target}"]
    if args.speed_kmh is not None:
        parts.append(f"--speed-kmh {args.speed_kmh:g}")
    parts.append("--fit " + ",".join(p.name for p in fit))
    if args.bounds:
        parts.append(f"--bounds {args.bounds}")
    if args.set_values:
        parts.append(f"--set {args.set_values}")
    if args.keep_correlated:
        parts.append("--keep-correlated")
    if args.scenarios:
        parts.append(f"--scenarios {args.scenarios}")
    parts += [f"--consist {c}" for c in args.consist or ()]
    if args.params:
        parts.append(f"--params {args.params}")
    if args.lut:
        parts.append(f"--lut {args.lut}")
    if args.v_th_mm_s is not None:
        parts.append(f"--v-th-mm-s {args.v_th_mm_s:g}")
    if args.step_s != 0.01:
        parts.append(f"--step-s {args.step_s:g}")
    if args.max_nfev != 60:
        parts.append(f"--max-nfev {args.max_nfev}")
    if args.allow_on_bound:
        parts.append("--allow-on-bound")
    if getattr(args, "allow_unconverged", False):
        parts.append("--allow-unconverged")
    if getattr(args, "draft_limit_kn", None) is not None:
        parts.append(f"--draft-limit-kn {args.draft_limit_kn:g}")
    if args.out:
        parts.append(f"--out {args.out}")
    return " ".join(parts)


def _write(path: str, text: str, force: bool = False) -> None:
    """Write a parameter file: a full disk leaves no truncated file behind, and an existing
    file is replaced only with ``--force`` (one that appeared during the fit is refused)."""
    from ..inputs import InputError
    from ..outputs import write_new, write_replacing

    try:
        (write_replacing if force else write_new)(Path(path).expanduser(), text)
    except OSError as exc:
        raise InputError(path, "", f"cannot write: {exc.strerror or exc}") from None


def _finish(args: argparse.Namespace, cal, file_text) -> int:
    """Print the warnings; write ``--out`` unless a fitted value sits on a bound."""
    from ..inputs import InputError

    if cal.warnings:
        print()
        for w in cal.warnings:
            print(f"warning: {w}")
    if args.out and cal.at_bound and not args.allow_on_bound:
        raise InputError("command line", "--out", f"not written: {', '.join(cal.at_bound)} "
                         "ended on a bound, so the bound, not the data, sets it; fit fewer "
                         "parameters, hold it with --set, or give --allow-on-bound")
    converged = cal.converged
    if args.out and not converged and not args.allow_unconverged:
        raise InputError("command line", "--out", "not written: the fit did not converge "
                         f"({cal.message or 'no message'}); raise --max-nfev, "
                         "fit fewer parameters, or give --allow-unconverged")
    if args.out:
        text = file_text(cal, command_line(args, cal.fit))
        if not converged:
            text = ("# NOT CONVERGED: the optimiser stopped before the fit converged "
                    f"({cal.message}); these values are not a calibration.\n"
                    + text)
        _write(args.out, text, force=args.force)
        print()
        print(f"wrote {args.out}")
    return 0


def _print_common(cal) -> None:
    from ..studies.calibration import correlation_table, parameters_table

    print()
    print(parameters_table(cal))
    print()
    print("correlation of the fitted values:")
    print(correlation_table(cal))


def _progress(args, total: int):
    from tqdm import tqdm

    # the total is the evaluation budget: a fit that converges ends before the bar is full
    return tqdm(total=total, desc="calibrating", file=sys.stderr, leave=False,
                disable=args.quiet or not sys.stderr.isatty(),
                bar_format="{desc}: {percentage:3.0f}% of budget |{bar}| {n_fmt}/{total_fmt} "
                           "stops [{elapsed}{postfix}]")


def _compile_first(args, params, lut, cases) -> None:
    """Compile here, announced, the kernels of the fit's trains (its workers then load them)."""
    from ..first_run import compile_here

    compile_here((dict(consist=consist, speed_kmh=speed, params=params, lut=lut,
                       step_s=args.step_s) for consist, speed in cases),
                 lambda line: print(line, file=sys.stderr, flush=True))


def run_forces(args: argparse.Namespace) -> int:
    """``ltd-brake calibrate --target forces``: fit coupler parameters to the peak forces."""
    from dataclasses import replace

    from ..inputs import InputError, load_scenarios
    from ..physics import couplers
    from ..studies.calibration import (DistanceEvaluator, calibrate_couplers, coupler_file_text,
                                       display_path, force_summary_lines, force_table,
                                       limit_lines, parse_fit, parse_values, snatch_trains,
                                       with_bounds)

    brake, lut = load_model(args)
    model = couplers.model_of(lut).NAME
    fit = parse_fit(args.fit or DEFAULT_FIT["forces"], model, part="coupler")
    fit = with_bounds(fit, args.bounds or "")
    if args.set_values:
        lut = replace(lut, **parse_values(args.set_values, model, part="coupler"))
        try:
            couplers.compile(lut)
        except couplers.CompileError as exc:
            raise InputError("command line", "--set", f"{exc.field}: {exc.reason}") from None
    if args.consist:
        raise InputError("command line", "--consist", "--target forces fits the paper's runs "
                         "(--scenarios); extra trains have no reference forces")
    catalogue = load_scenarios()
    numbers = parse_scenarios(args.scenarios) if args.scenarios else sorted(catalogue)
    for k in numbers:
        if k not in catalogue:
            raise InputError("command line", "--scenarios", f"unknown scenario {k}; Tables 1-2 "
                             f"have {min(catalogue)}-{max(catalogue)}")
    if args.speed_kmh is not None:
        numbers = [k for k in numbers if catalogue[k].speed_kmh == args.speed_kmh]
        if not numbers:
            raise InputError("command line", "--speed-kmh", f"no run of Tables 1-2 at "
                             f"{args.speed_kmh:g} km/h")
    scenarios = [catalogue[k] for k in numbers]
    limits = []
    if args.draft_limit_kn is not None:
        if not args.draft_limit_kn > 0:
            raise InputError("command line", "--draft-limit-kn",
                             f"must be a positive force, got {args.draft_limit_kn:g}")
        limits = snatch_trains()
    _compile_first(args, brake, lut, [(s.consist(), s.speed_kmh) for s in scenarios] + limits)
    budget = (args.max_nfev * (len(fit) + 1) + 2 * len(fit) + 2) * (len(scenarios) + len(limits))
    bar = _progress(args, budget)
    try:
        with DistanceEvaluator([(s.consist(), s.speed_kmh) for s in scenarios] + limits, lut,
                               step_s=args.step_s, workers=args.jobs, progress=bar) as ev:
            cal = calibrate_couplers(scenarios, fit, lut, brake, step_s=args.step_s,
                                     progress=bar, max_nfev=args.max_nfev, evaluator=ev,
                                     keep_correlated=args.keep_correlated,
                                     cross_validate=not args.no_cross_validation,
                                     limits=limits,
                                     draft_limit_N=1e3 * (args.draft_limit_kn or 500.0))
    finally:
        bar.close()
    print(f"calibration of the {model} coupler against the peak forces of Tables 1-2: "
          f"{len(scenarios)} runs, fitting {', '.join(p.name for p in cal.fit)}; start values "
          f"{display_path(lut.source)}; brake parameters {display_path(brake.source)}")
    print(f"{cal.nfev} residual evaluations, {cal.runs} emergency stops; {cal.message}")
    print()
    print(force_table(cal))
    print()
    print("\n".join(force_summary_lines(cal)))
    if cal.limits:
        print()
        print("\n".join(limit_lines(cal)))
    _print_common(cal)
    return _finish(args, cal, coupler_file_text)


def run(args: argparse.Namespace) -> int:
    """Run ``ltd-brake calibrate``: fit, report, optionally write a parameter file."""
    from dataclasses import replace

    import numpy as np

    from ..inputs import InputError, load_consist
    from ..physics.parameters import check
    from ..studies.calibration import (UIC_SPEED_KMH, DistanceEvaluator, build_targets,
                                       calibrate, companion_rows, companion_table, display_path,
                                       parameter_file_text, parse_fit, parse_values,
                                       summary_lines, targets_table, with_bounds)

    positive_int(args.max_nfev, "--max-nfev")
    positive_int(args.jobs, "--jobs")
    if args.out:  # refused before the fit, not after minutes of it
        check_output_file(args.out, "--out", force=args.force,
                          inputs=(args.params, args.lut, *(args.consist or ())))
    if args.target == "forces":
        return run_forces(args)
    # --params gives the start values, the fields not fitted and the model the names belong to
    start, lut = load_model(args)
    fit = with_bounds(parse_fit(args.fit or DEFAULT_FIT[args.target], start.model),
                      args.bounds or "")
    if args.set_values:
        try:
            start = replace(start, **parse_values(args.set_values, start.model))
            for part in (start.pneumatic, start.friction):
                check(part)
        except ValueError as exc:
            raise InputError("command line", "--set", str(exc)) from None
    scenarios = parse_scenarios(args.scenarios) if args.scenarios else None
    extra = [load_consist(c) for c in args.consist or ()]
    speed = UIC_SPEED_KMH if args.speed_kmh is None else args.speed_kmh
    targets = build_targets(args.target, speed, scenarios, extra)
    side = companion_rows(targets)
    side_cases = [(s.consist(), s.speed_kmh) for s in side]
    cases = [(t.consist, t.speed_kmh) for t in targets] + side_cases
    _compile_first(args, start, lut, cases)
    budget = (args.max_nfev * (len(fit) + 1) + 2 * len(fit) + 2) * len(targets) + 2 * len(side)
    bar = _progress(args, budget)
    try:
        with DistanceEvaluator(cases, lut, step_s=args.step_s, workers=args.jobs,
                               progress=bar) as ev:
            cal = calibrate(targets, fit, start, lut, step_s=args.step_s, progress=bar,
                            max_nfev=args.max_nfev, evaluator=ev,
                            keep_correlated=args.keep_correlated,
                            cross_validate=not args.no_cross_validation)
            side_m = (ev.distances([cal.start, cal.params], range(len(targets), len(cases)))
                      if side else np.empty((2, 0)))
            runs = ev.runs
    finally:
        bar.close()
    what = {"uic": "UIC 544-1", "paper": "the LTDPoliTo column"}[args.target]
    print(f"calibration against {what} at {speed:g} km/h: {len(targets)} targets, "
          f"fitting {', '.join(p.name for p in cal.fit)}; start values "
          f"{display_path(start.source)}")
    print(f"{cal.nfev} residual evaluations, {runs} emergency stops; {cal.message}")
    print()
    print(targets_table(cal))
    print()
    print("\n".join(summary_lines(cal)))
    _print_common(cal)
    if side:
        print()
        print("not fitted: the same trains at other speeds (Tables 1-2)")
        print(companion_table(side, side_m[0], side_m[1]))
    return _finish(args, cal, parameter_file_text)

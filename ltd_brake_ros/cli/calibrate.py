"""``ltd-brake calibrate``: fit brake-model parameters to reference stopping distances."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..inputs import InputError
from ..physics.brakes import DEFAULT_MODEL
from ..recording.output import checked_output
from ..studies.calibration import UIC_SPEED_KMH, fit_parameters, parse_fit
from .options import add_model_options, load_model, parse_scenarios, positive_int

HELP = """\
Fit brake-model parameters so that simulated emergency stopping distances match reference
distances, by bounded nonlinear least squares on the relative errors (S_sim - S_ref) / S_ref.
Prints the targets before and after, the fitted values with 95 % confidence intervals and
their correlation matrix, and warns about parameters the chosen trains cannot determine.
"""

EPILOG = """\
targets:
  uic     UIC 544-1 emergency stopping distances from 100 km/h (the only speed with UIC
          values): Table 1's UIC column for the paper's trains (scenarios 1-6), and the UIC
          curve S = C/lambda + D (C = 50752 m %, D = 53.45 m, lambda by Eq. 11) for every
          train added with --consist. Extra trains of other lengths or braked-weight
          percentages help separate v_air (length-dependent) from t_app and t_fill.
  paper   the LTDPoliTo column of Tables 1-2 (the paper's own model), at 100 or 50 km/h.

parameters (--fit) of the {model} brake model, with the bounds of the fit:
{parameters}
  Parameters not fitted keep their --params values. A parameter file that names another
  brake model (model: ...) offers that model's parameters.

units: speeds in km/h, distances in m, times in s. The confidence intervals are 95 %,
Student t with (targets - parameters) degrees of freedom, from (J^T J)^-1 s^2 at the optimum.

examples:
  ltd-brake calibrate --target uic --fit t_app,v_air,t_fill,k0 --out my_uic.yaml
  ltd-brake calibrate --target paper --speed-kmh 50 --fit k0
  ltd-brake validate --params my_uic.yaml
"""


def _epilog() -> str:
    rows = [f"  {p.name:<7} {'[' + p.unit + ']':<6} {f'{p.lower:g} to {p.upper:g}':<13} "
            f"{p.meaning}" for p in fit_parameters(DEFAULT_MODEL).values()]
    return EPILOG.format(model=DEFAULT_MODEL, parameters="\n".join(rows))


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``calibrate`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "calibrate", help="fit brake parameters to UIC 544-1 or the paper's distances",
        description=HELP, epilog=_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--target", choices=("uic", "paper"), default="uic",
                   help="reference distances: uic (UIC 544-1, 100 km/h only) or paper "
                        "(LTDPoliTo column); default uic")
    p.add_argument("--speed-kmh", type=float, default=UIC_SPEED_KMH, metavar="KMH",
                   help="initial speed [km/h]: the rows of Tables 1-2 to fit (default 100)")
    p.add_argument("--fit", default="t_app,v_air,t_fill,k0", metavar="LIST",
                   help="comma-separated parameters to fit (default t_app,v_air,t_fill,k0)")
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
                        "simulate/validate/sim_node (--params)")
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
    parts = ["ltd-brake calibrate", f"--target {args.target}", f"--speed-kmh {args.speed_kmh:g}",
             "--fit " + ",".join(p.name for p in fit)]
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
    if args.out:
        parts.append(f"--out {args.out}")
    return " ".join(parts)


def run(args: argparse.Namespace) -> int:
    """Run ``ltd-brake calibrate``: fit, report, optionally write a parameter file."""
    import numpy as np
    from tqdm import tqdm

    from ..inputs import load_consist
    from ..studies.calibration import (DistanceEvaluator, build_targets, calibrate,
                                       companion_rows, companion_table, correlation_table,
                                       display_path, parameter_file_text, parameters_table,
                                       summary_lines, targets_table)

    # --params gives the start values, the fields not fitted and the model the names belong to
    start, lut = load_model(args)
    fit = parse_fit(args.fit, start.model)
    positive_int(args.max_nfev, "--max-nfev")
    positive_int(args.jobs, "--jobs")
    if args.out and not Path(args.out).expanduser().resolve().parent.is_dir():
        raise InputError("command line", "--out", f"directory of {args.out} does not exist")
    scenarios = parse_scenarios(args.scenarios) if args.scenarios else None
    extra = [load_consist(c) for c in args.consist or ()]
    targets = build_targets(args.target, args.speed_kmh, scenarios, extra)
    side = companion_rows(targets)
    side_cases = [(s.consist(), s.speed_kmh) for s in side]
    cases = [(t.consist, t.speed_kmh) for t in targets] + side_cases
    budget = (args.max_nfev * (len(fit) + 1) + 2) * len(targets) + 2 * len(side)
    # the total is the evaluation budget: a fit that converges ends before the bar is full
    bar = tqdm(total=budget, desc="calibrating", file=sys.stderr, leave=False,
               disable=args.quiet or not sys.stderr.isatty(),
               bar_format="{desc}: {percentage:3.0f}% of budget |{bar}| {n_fmt}/{total_fmt} "
                          "stops [{elapsed}{postfix}]")
    try:
        with DistanceEvaluator(cases, lut, step_s=args.step_s, workers=args.jobs,
                               progress=bar) as ev:
            cal = calibrate(targets, fit, start, lut, step_s=args.step_s, progress=bar,
                            max_nfev=args.max_nfev, evaluator=ev)
            side_m = (ev.distances([cal.start, cal.params], range(len(targets), len(cases)))
                      if side else np.empty((2, 0)))
            runs = ev.runs
    finally:
        bar.close()
    what = {"uic": "UIC 544-1", "paper": "the LTDPoliTo column"}[args.target]
    print(f"calibration against {what} at {args.speed_kmh:g} km/h: {len(targets)} targets, "
          f"fitting {', '.join(p.name for p in fit)}; start values {display_path(start.source)}")
    print(f"{cal.nfev} residual evaluations, {runs} emergency stops; {cal.message}")
    print()
    print(targets_table(cal))
    print()
    print("\n".join(summary_lines(cal)))
    print()
    print(parameters_table(cal))
    print()
    print("correlation of the fitted values:")
    print(correlation_table(cal))
    if side:
        print()
        print("not fitted: the same trains at other speeds (Tables 1-2)")
        print(companion_table(side, side_m[0], side_m[1]))
    if cal.warnings:
        print()
        for w in cal.warnings:
            print(f"warning: {w}")
    if args.out:
        text = parameter_file_text(cal, command_line(args, fit))
        try:  # a full disk leaves no truncated parameter file behind
            with checked_output(Path(args.out).expanduser(), encoding="utf-8") as fh:
                fh.write(text)
        except OSError as exc:
            raise InputError(args.out, "", f"cannot write: {exc.strerror or exc}") from None
        print()
        print(f"wrote {args.out}")
    return 0

"""``ltd-brake report``: analyse a recorded run, write its plots and, on request, CSV."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .options import CONVENTIONS

DESCRIPTION = """\
Analyse a recorded run (bag folder or .mcap): emergency command time, stopping distance and
time, peak draft and buff force with coupler number and time; writes PNG plots (speed, brake
force, peak force per coupler, coupler force map; with a brake pipe recorded, the pipe pressure
along the train and the head-wagon and tail cylinder pressures, with their 95 % filling times)
and, with --csv, the arrays in SI units.
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``report`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    ap = subparsers.add_parser(
        "report", help="analyse a recorded run: distance, peak forces, plots",
        description=DESCRIPTION,
        epilog=CONVENTIONS + "\nexamples:\n  ltd-brake report runs/demo_20250101-120000\n"
               "  ltd-brake report run_0.mcap --csv --json\n",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", help="bag folder or .mcap file")
    ap.add_argument("--out", help="directory for plots and CSV (default: RUN/report, or "
                                  "<file>_report beside a .mcap file)")
    ap.add_argument("--csv", action="store_true", help="also export the arrays as CSV")
    ap.add_argument("--json", action="store_true", help="print the numbers as JSON")
    ap.add_argument("--namespace", help="namespace of the plant's topics (default: found)")
    ap.set_defaults(func=run)
    return ap


def _default_outdir(run: Path) -> Path:
    return run / "report" if run.is_dir() else run.with_name(run.stem + "_report")


def run(args: argparse.Namespace) -> int:
    """Analyse the recording, write the plots (and CSV), print the numbers.

    Raises
    ------
    InputError
        The recording cannot be read or holds no plant topics; the output cannot be written.
    """
    from ..analysis.export import write_csv
    from ..analysis.plots import write_plots
    from ..analysis.report import analyse
    from ..inputs import InputError
    from ..recording.reader import BagError

    run_path = Path(args.run)
    try:
        rep = analyse(run_path, args.namespace)
    except BagError as exc:
        raise InputError("command line", "RUN", str(exc)) from None
    if not rep.complete:  # read as it is: said on stderr, whatever the output's form
        why = next((n for n in rep.notes if "unfinished" in n),
                   f"{run_path} is unfinished: read to its last complete chunk")
        print(f"ltd-brake report: warning: {why}", file=sys.stderr)
    out = Path(args.out) if args.out else _default_outdir(run_path)
    if out.exists() and not out.is_dir():
        raise InputError("command line", "--out", f"{out} is a file; give a folder for the "
                                                  "plots and CSV")
    try:
        plots = write_plots(rep, out)
        csvs = write_csv(rep, out) if args.csv else []
    except BagError as exc:
        raise InputError("command line", "RUN", str(exc)) from None
    except OSError as exc:
        raise InputError("command line", "--out", f"cannot write to {out}: {exc}") from None
    if args.json:
        d = rep.as_dict()
        d["plots"] = [str(p) for p in plots]
        d["csv"] = [str(p) for p in csvs]
        print(json.dumps(d, indent=2))
    else:
        print(rep.describe())
        print(f"plots: {len(plots)} PNG files in {out}")
        if csvs:
            print(f"CSV: {len(csvs)} files in {out}")
    return 0

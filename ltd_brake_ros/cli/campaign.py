"""``ltd-brake campaign``: run a statistical campaign, report on its results."""
from __future__ import annotations

import argparse
import sys

from .options import positive_int


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``campaign`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "campaign", help="thousands of randomised trains: run, report",
        description="Statistical campaigns: randomised train families under one manoeuvre, "
                    "results in a Parquet folder, quantiles and the relative approach.")
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    r = sub.add_parser("run", help="run (or complete) a campaign into a results folder",
                       description="Run every run of a campaign file that the results folder "
                                   "does not hold yet: re-running the same command after an "
                                   "interruption completes only what is missing.")
    r.add_argument("file", metavar="FILE", help="campaign YAML file")
    r.add_argument("--out", required=True, metavar="DIR", help="results folder")
    r.add_argument("--jobs", type=int, metavar="N",
                   help="local worker processes (default: all cores; 1: in this process)")
    r.add_argument("--dask", metavar="ADDRESS",
                   help="run on Dask distributed: tcp://host:port of a scheduler, or local:N to "
                        "start a local cluster of N worker processes")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=run)
    q = sub.add_parser("report", help="quantiles, exceedances, worst runs, plots, verdicts",
                       description="Summarise a results folder; with --against, compare it with "
                                   "a reference family's folder (the relative approach).")
    q.add_argument("dir", metavar="DIR", help="results folder")
    q.add_argument("--against", metavar="REF_DIR", help="results folder of the reference family")
    q.add_argument("--threshold", action="append", default=[], metavar="KPI=VALUE",
                   help="exceedance probability of KPI above VALUE (repeatable), e.g. "
                        "abs_peak_buff_kN=400")
    q.add_argument("--quantile", type=float, default=0.99, metavar="Q",
                   help="quantile the relative approach compares (default 0.99)")
    q.add_argument("--confidence", type=float, default=0.95, metavar="C",
                   help="confidence of the bootstrap intervals and verdicts (default 0.95)")
    q.add_argument("--worst", type=int, default=5, metavar="N", help="worst runs listed (default 5)")
    q.add_argument("--plots", metavar="DIR", help="write CDF and histogram PNGs here")
    q.add_argument("--json", action="store_true", help="print JSON instead of text")
    q.set_defaults(func=report)
    return p


def _require_extra(dask: bool = False) -> None:
    """One line instead of a traceback when the ``campaign`` extra is not installed."""
    from importlib.util import find_spec

    from ..inputs import InputError

    missing = [m for m in ("pyarrow",) + (("distributed",) if dask else ())
               if find_spec(m) is None]
    if missing:
        raise InputError(" and ".join(missing), "", "not installed; campaigns need it: pip "
                         "install 'ltd_brake_ros[campaign]'")


def run(args: argparse.Namespace) -> int:
    """Run the missing batches of a campaign."""
    _require_extra(dask=bool(args.dask))
    from tqdm import tqdm

    from ..inputs.campaign import load_campaign
    from ..studies.campaign_exec import make_executor, missing_batches, run_campaign

    positive_int(args.jobs, "--jobs")
    c = load_campaign(args.file)
    todo = missing_batches(c, args.out)
    per_train = len(c.manoeuvres)  # a row (a run) per train and manoeuvre
    done_runs = per_train * (c.runs - sum(min(c.batch_size, c.runs - b * c.batch_size)
                                          for b in todo))
    with make_executor(args.jobs, args.dask) as executor:
        bar = tqdm(total=per_train * c.runs, initial=done_runs, unit="run", desc=c.name,
                   file=sys.stderr,
                   disable=args.quiet, smoothing=0.1)
        failed = [0]

        def progress(runs: int, n_failed: int) -> None:
            failed[0] += n_failed
            bar.set_postfix(failed=failed[0], refresh=False)
            bar.update(runs)

        try:
            summary = run_campaign(c, args.out, executor, progress=progress)
        finally:
            bar.close()
    print(f"{c.name}: {summary['runs']} runs in {summary['batches']} batches "
          f"({summary['failed']} failed), {summary['skipped']} batches already done, "
          f"{executor.workers} workers; results in {args.out}")
    return 0


def report(args: argparse.Namespace) -> int:
    """Print the campaign report."""
    _require_extra()
    import json

    from ..analysis.campaign_report import campaign_report, format_report, parse_thresholds
    from ..inputs import InputError

    if not 0.0 < args.quantile < 1.0:
        raise InputError("--quantile", "", f"must be between 0 and 1, got {args.quantile}")
    if not 0.5 <= args.confidence < 1.0:
        raise InputError("--confidence", "", f"must be in [0.5, 1), got {args.confidence}")
    positive_int(args.worst, "--worst")
    rep = campaign_report(args.dir, against=args.against,
                          thresholds=parse_thresholds(args.threshold), quantile=args.quantile,
                          confidence=args.confidence, worst=args.worst, plots=args.plots)
    print(json.dumps(rep, indent=2, default=float) if args.json else format_report(rep))
    failed = [v for sec in rep["manoeuvres"].values() for v in sec["relative"]
              if v["verdict"] == "FAIL"]
    return 1 if failed else 0

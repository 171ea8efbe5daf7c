"""``ltd-brake campaign``: run a statistical campaign, report on its results, list their
columns."""
from __future__ import annotations

import argparse
import sys

from .options import check_output_file, positive_int


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``campaign`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    p = subparsers.add_parser(
        "campaign", help="thousands of randomised trains: run, report, rerun, schema",
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
    q = sub.add_parser(
        "report", help="quantiles, exceedances, worst runs, plots, relative approach",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Summarise a results folder; with --against, compare it with a reference "
                    "family's folder (the relative approach of UIC 421).",
        epilog="relative approach: for each KPI, the interval of the family's worsening of\n"
               "its --quantile against the reference (relative to the reference's quantile,\n"
               "in the KPI's worse direction: peak_buff_kN is negative, more negative is\n"
               "worse) gives 'not worse' (the interval lies below --margin), 'worse' (above\n"
               "it) or 'inconclusive' (it holds the margin, or fewer than 20 runs lie beyond\n"
               "the quantile: no interval). Two folders drawn from the same seed whose runs\n"
               "are the same trains are compared as paired runs, others as independent.\n"
               "exit status: 0 report (with --against: every deciding KPI not worse), 1 a\n"
               "deciding KPI worse, 4 none worse but one inconclusive, 2 bad input.")
    q.add_argument("dir", metavar="DIR", help="results folder")
    q.add_argument("--against", metavar="REF_DIR", help="results folder of the reference family")
    q.add_argument("--threshold", action="append", default=[], metavar="KPI=VALUE",
                   help="probability of KPI beyond VALUE in its worse direction (repeatable), "
                        "e.g. peak_draft_kN=400, peak_buff_kN=-400 (buff: below)")
    q.add_argument("--quantile", type=float, default=0.99, metavar="Q",
                   help="quantile the relative approach compares, in the KPI's worse "
                        "direction (default 0.99: the value 1 %% of the runs go beyond)")
    q.add_argument("--confidence", type=float, default=0.95, metavar="C",
                   help="two-sided confidence of the intervals (default 0.95; a "
                        "verdict is a one-sided test at (1 - C) / 2)")
    q.add_argument("--margin", type=float, default=0.05, metavar="M",
                   help="non-inferiority margin: how much worse than the reference's quantile "
                        "the family's may be, as a share of it (default 0.05: 5 %%)")
    q.add_argument("--kpi", action="append", default=[], metavar="KPI",
                   help="KPI whose verdict decides (repeatable; default peak_draft_kN and "
                        "peak_buff_kN; also stopping_distance_m, mean_adhesion, "
                        "max_adhesion_demand); the others are shown but do not decide")
    q.add_argument("--independent", action="store_true",
                   help="compare the two families as independent samples even when they are "
                        "paired")
    q.add_argument("--worst", type=int, default=5, metavar="N",
                   help="worst runs listed (default 5)")
    q.add_argument("--plots", metavar="DIR", help="write CDF and histogram PNGs here")
    q.add_argument("--html", metavar="FILE",
                   help="also write the report as one self-contained HTML file (figures "
                        "embedded, no external resources: it opens offline)")
    q.add_argument("--force", action="store_true", help="replace an existing --html file")
    q.add_argument("--json", action="store_true", help="print JSON instead of text")
    q.set_defaults(func=report)
    w = sub.add_parser(
        "rerun", help="re-run chosen runs with full MCAP recordings",
        description="Rebuild runs of a results folder from its campaign (the same draws), run "
                    "them again offline and record each into a rosbag2/MCAP folder of its own, "
                    "as sim_node records a run: ltd-brake report and Foxglove open them.")
    w.add_argument("dir", metavar="DIR", help="results folder")
    which = w.add_mutually_exclusive_group(required=True)
    which.add_argument("--runs", metavar="IDS", help="run ids, comma-separated, e.g. 17,42")
    which.add_argument("--worst", type=int, metavar="N",
                       help="the N worst successful runs of each manoeuvre by --kpi")
    w.add_argument("--kpi", default="abs_peak_buff_kN", metavar="KPI",
                   help="KPI ranking --worst (default abs_peak_buff_kN; also peak_draft_kN, "
                        "max_adhesion_demand, stopping_distance_m)")
    w.add_argument("--manoeuvre", metavar="NAME", help="only this manoeuvre (default: each)")
    w.add_argument("--out", required=True, metavar="FOLDER",
                   help="recordings go to FOLDER/run_<id>_<manoeuvre>/")
    w.add_argument("--namespace", default="/", metavar="NS",
                   help="namespace of the plant topics (default /, as sim_node without one)")
    w.set_defaults(func=rerun)
    s = sub.add_parser(
        "schema", help="the columns of the results: type, unit, meaning",
        description="List the columns of a campaign's results with their type, unit and "
                    "meaning, as every batch file records them in its Parquet schema (pyarrow: "
                    "read_schema(path).field(name).metadata). FILE is a batch file "
                    "(DIR/batches/batch-*.parquet), a results folder (its first batch) or a "
                    "campaign YAML file (the columns its results will have).")
    s.add_argument("file", metavar="FILE", help="batch Parquet file, results folder or campaign "
                                                "YAML file")
    s.add_argument("--json", action="store_true",
                   help="print JSON: schema_version and columns (name, type, unit, description)")
    s.set_defaults(func=schema)
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

    from ..first_run import compile_here
    from ..inputs.campaign import load_campaign
    from ..studies.campaign_exec import (make_executor, missing_batches, prepare_folder,
                                         run_campaign)
    from ..studies.warm import campaign_runs

    positive_int(args.jobs, "--jobs")
    c = load_campaign(args.file)
    # a folder of another campaign or model is refused before any worker starts
    prepare_folder(c, args.out, create=False)
    todo = missing_batches(c, args.out)
    if todo:  # the workers load the kernels compiled here, announced
        compile_here(campaign_runs(c), lambda line: print(line, file=sys.stderr, flush=True))
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

        def note(line: str) -> None:
            bar.write(f"note: {line}", file=sys.stderr)

        try:
            summary = run_campaign(c, args.out, executor, progress=progress, note_fn=note)
        finally:
            bar.close()
    print(f"{c.name}: {summary['runs']} runs in {summary['batches']} batches "
          f"({summary['failed']} failed), {summary['skipped']} batches already done, "
          f"{executor.workers} workers; results in {args.out}")
    if summary["runs"] and summary["failed"] == summary["runs"]:
        print(f"error: every run failed; the first messages: ltd-brake campaign report "
              f"{args.out}", file=sys.stderr)
        return 1
    if summary["failed"]:
        print(f"warning: {summary['failed']} of {summary['runs']} runs failed; their messages "
              f"are in the results (ltd-brake campaign report {args.out})", file=sys.stderr)
    return 0


def _run_ids(text: str) -> list[int]:
    """``--runs 17,42`` -> [17, 42] (one line naming the option otherwise)."""
    from ..inputs import InputError

    try:
        ids = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError("--runs", "", f"{text!r}: write run ids separated by commas, "
                         "e.g. 17,42") from None
    if not ids or min(ids) < 0:
        raise InputError("--runs", "", f"{text!r}: give one or more run ids >= 0")
    return list(dict.fromkeys(ids))


def rerun(args: argparse.Namespace) -> int:
    """Re-run chosen runs of a campaign with recordings; 1 if one differs from its row."""
    _require_extra()
    import math
    from pathlib import Path

    from ..analysis.campaign_report import worst_runs
    from ..inputs import InputError
    from ..simulator import SimulationError
    from ..studies.campaign_exec import read_results
    from ..studies.campaign_rerun import campaign_of_results, rerun as rerun_one, run_folder_name

    if not args.namespace.startswith("/"):
        raise InputError("--namespace", "", f"{args.namespace!r} must start with /")
    meta, table = read_results(args.dir)
    c = campaign_of_results(args.dir, meta)
    if args.worst is not None:
        positive_int(args.worst, "--worst")
        chosen = [(r["run_id"], r["manoeuvre"])
                  for r in worst_runs(table, args.kpi, args.worst, args.manoeuvre)]
    else:
        names = [m.name for m in c.manoeuvres]
        if args.manoeuvre is not None and args.manoeuvre not in names:
            raise InputError("--manoeuvre", "", f"no manoeuvre {args.manoeuvre!r} in "
                             f"{c.source}; it has {', '.join(names)}")
        ids = _run_ids(args.runs)
        beyond = [i for i in ids if i >= c.runs]
        if beyond:
            raise InputError("--runs", "", f"run {beyond[0]} is not in the campaign "
                             f"(0 to {c.runs - 1})")
        chosen = [(i, n) for i in ids for n in names if args.manoeuvre in (None, n)]
    taken = [f for f in (Path(args.out) / run_folder_name(i, n) for i, n in chosen)
             if f.exists() and (not f.is_dir() or any(f.iterdir()))]
    if taken:  # refused before anything runs
        raise InputError(taken[0], "", "exists and is not empty: give a new --out")
    rows = {(r["run_id"], r["manoeuvre"]): r for r in table.to_pylist()}
    status = 0
    for run_id, name in chosen:
        row = rows.get((run_id, name))
        folder = Path(args.out) / run_folder_name(run_id, name)
        try:
            got = rerun_one(c, run_id, name, folder, namespace=args.namespace)
        except SimulationError as exc:
            same = row is not None and row["status"] == "failed"
            print(f"run {run_id} {name}: failed{' as in the campaign' if same else ''}: {exc}; "
                  f"recorded up to the failure in {folder}")
            status = status if same else 1
            continue
        line = (f"run {run_id} {name}: {folder} ({got['messages']} messages), stopping "
                f"distance {got['stopping_distance_m']:.2f} m, peak draft "
                f"{got['peak_draft_kN']:.1f} kN @{got['peak_draft_coupler']}, peak buff "
                f"{got['peak_buff_kN']:.1f} kN @{got['peak_buff_coupler']}")
        if row is None:
            print(line + " (the results folder has no row for it yet)")
            continue
        keys = ("stopping_distance_m", "peak_draft_kN", "peak_buff_kN")
        differ = [k for k in keys if row[k] is None or not (
            math.isclose(got[k], row[k], rel_tol=1e-9, abs_tol=1e-9)
            or (math.isnan(got[k]) and math.isnan(row[k])))]
        if row["status"] != "ok" or differ:
            status = 1
            print(line + f"; DIFFERS from the campaign row ({row['status']}: "
                  + ", ".join(f"{k} {row[k]}" for k in differ or keys) + ")")
        else:
            print(line + ", as in the campaign")
    return status


def report(args: argparse.Namespace) -> int:
    """Print the campaign report; with ``--against``, 0 every deciding KPI not worse, 1 one
    worse, 4 otherwise (inconclusive). The report is the Python API's
    (:class:`~ltd_brake_ros.analysis.campaign_results.CampaignResults`)."""
    _require_extra()
    from ..analysis.campaign_report import as_json, exit_status, format_report, parse_kpis
    from ..analysis.campaign_report import parse_thresholds
    from ..analysis.campaign_results import CampaignResults, check_options
    from ..inputs import InputError

    check_options(quantile=args.quantile, confidence=args.confidence, margin=args.margin)
    positive_int(args.worst, "--worst")
    kpis = parse_kpis(args.kpi)
    if (args.kpi or args.independent) and args.against is None:
        raise InputError("--kpi" if args.kpi else "--independent", "",
                         "applies to the relative approach: give --against REF_DIR")
    if args.force and args.html is None:
        raise InputError("--force", "", "applies to --html FILE")
    if args.html is not None:  # refused before the report is computed
        check_output_file(args.html, "--html", force=args.force)
    family = CampaignResults(args.dir)
    against = CampaignResults(args.against) if args.against is not None else None
    rep = family.report(against=against, thresholds=parse_thresholds(args.threshold),
                        quantile=args.quantile, confidence=args.confidence, margin=args.margin,
                        kpis=kpis, independent=args.independent, worst=args.worst,
                        plots=args.plots)
    if args.html is not None:
        from ..analysis.campaign_html import write_html

        rep["html"] = write_html(rep, args.html, family=family, against=against)
    print(as_json(rep) if args.json else format_report(rep))
    if args.html is not None and not args.json:
        print(f"html: {args.html}")
    return exit_status(rep)


def _schema_of(path: str):
    """The results schema that ``ltd-brake campaign schema FILE`` lists (see its help)."""
    from pathlib import Path

    import pyarrow as pa
    import pyarrow.parquet as pq

    from ..inputs import InputError
    from ..inputs.campaign import load_campaign
    from ..studies.campaign import schema_of
    from ..studies.campaign_exec import read_manifest

    where = Path(path)
    if where.is_dir():
        read_manifest(where)  # one line when the folder is not a results folder
        files = sorted((where / "batches").glob("batch-*.parquet"))
        if not files:
            raise InputError(where, "", "holds no results yet: run ltd-brake campaign run "
                             "first, or give the campaign YAML file")
        where = files[0]
    elif not where.is_file():
        raise InputError(where, "", "no such file or folder")
    elif where.suffix.lower() in (".yaml", ".yml"):
        return schema_of(load_campaign(where))
    try:
        found = pq.read_schema(where)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(where, "", f"is not a readable Parquet file ({exc}); give a batch "
                         "file, a results folder or a campaign YAML file") from None
    if b"ltd_brake_ros.campaign_digest" not in (found.metadata or {}):
        raise InputError(where, "", "is not a batch file of campaign results (its schema "
                         "names no campaign)")
    return found


def schema(args: argparse.Namespace) -> int:
    """Print the columns of a campaign's results with their types, units and descriptions."""
    _require_extra()
    import json

    from ..studies.campaign import describe_schema

    described = {"file": args.file, **describe_schema(_schema_of(args.file))}
    if args.json:
        print(json.dumps(described, indent=2))
        return 0
    columns = described["columns"]
    version = described["schema_version"]
    print(f"{args.file}: {len(columns)} columns, " + (
        f"schema version {version}" if version is not None else
        "written before units and descriptions were recorded"))
    rows = [("column", "type", "unit", "description")] + [
        (c["name"], c["type"], c["unit"] or "", c["description"] or "") for c in columns]
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    for r in rows:
        print("  ".join(x.ljust(w) for x, w in zip(r, widths)) + "  " + r[3])
    return 0

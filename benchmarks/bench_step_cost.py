"""CPU per integration step of scenario 6's emergency stop: this tree against an earlier commit,
measured interleaved in one run on this tree's Python environment.

The stop: the paper's scenario 6 (E402B + 32 Shimmns at 50 t, brake position P, 100 km/h),
the paper's empirical brake model with Table 3's parameters, the default coupler table, error
control and 10 ms nominal steps; everything the run computes by default is on (coupler peaks,
the verdicts' records, brake heat, the stop's records and settling).

What is counted. An earlier commit may watch less after the stop: this tree keeps integrating
until the train has settled (2 s or more at rest, other steps) and judges it at rest. So that
both count the same thing, each run advances the train in 1 s chunks from the emergency command
(``Simulator.advance(1.0, ...)``) and times only the chunks that end before the first
standstill (``ceil(stop time) - 1`` of them, 28 for scenario 6, which stops at 28.77 s): both
trees integrate the same simulated time with the same chunks, so the same steps (the table
prints both counts, which must be equal), and the CPU time divided by the steps is the cost of
a step of the stop itself, the per-chunk work of ``Simulator.advance`` (commands, the
verdicts' watch, snapshot) included at one call per 100 steps. The chunk holding the stop is
left out: what follows the stop in it is settling in this tree and plain integration at rest
in the other.

Separately, the per-chunk overhead: the CPU time of one ``Simulator.advance(0.01)`` call (one
10 ms step, a few microseconds of it the step itself) while the train brakes, mostly Python
around the kernel; and the same at rest, 5 s after the stop (where this tree also judges the
train's holding each chunk).

How. Each measurement runs in a fresh process whose ``PYTHONPATH`` puts one tree first (the
package imports from there; the same interpreter, numba and numpy for both), warms up (one
whole stop: the compiled kernels loaded from the tree's own numba cache, or compiled into it),
then times ``--repeats`` stops and keeps the best (CPU time of the process, garbage collection
off while timing). Processes alternate between the trees (A B B A A B ...) for ``--rounds``
rounds; the table gives, per tree, the best and the median of the processes' best times, and
the median of the rounds' paired ratios. The earlier commit is extracted with ``git archive``
into a temporary folder, removed at the end (``--keep-old DIR`` keeps it, with its compiled
kernels, for the next run). Its kernels compile into that folder's ``__pycache__``: the first
process of each tree is the cold one (the figures it printed are shown once, compile or cache
load included), and is not among the timed rounds.

Usage::

    python benchmarks/bench_step_cost.py                  # against 414a8b1 (a few minutes)
    python benchmarks/bench_step_cost.py --rounds 4 --repeats 10   # quicker, noisier
    python benchmarks/bench_step_cost.py --old <commit>   # against another commit
    python benchmarks/bench_step_cost.py --new DIR        # another tree against 414a8b1
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

#: The commit measured against by default.
DEFAULT_OLD = "414a8b1"
#: This tree (the folder above benchmarks/).
HERE = Path(__file__).resolve().parent.parent
CHUNK_S = 1.0
STEP_S = 0.01


# --------------------------------------------------------------------------- one process


def _stop_simulator():
    """Scenario 6 as the paper runs it, in whichever tree this process imports."""
    from ltd_brake_ros.inputs import get_scenario, load_brake_params
    from ltd_brake_ros.simulator import Simulator

    sc = get_scenario(6)
    return Simulator(sc.consist(), sc.speed_kmh, load_brake_params("brake_params/paper.yaml"))


def _run_chunks(sim, chunks: int) -> float:
    """Advance ``chunks`` 1 s chunks from the emergency command; CPU time [s]."""
    from ltd_brake_ros.simulator import Commands

    start = time.process_time()
    sim.advance(CHUNK_S, Commands(emergency=True))
    for _ in range(chunks - 1):
        sim.advance(CHUNK_S)
    return time.process_time() - start


def worker(repeats: int, calls: int) -> dict:
    """The figures of one process (see the module)."""
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    from ltd_brake_ros.simulator import Commands

    sim = _stop_simulator()
    sim.advance(CHUNK_S, Commands(emergency=True))
    while sim.stop_time_s is None:
        sim.advance(CHUNK_S)
    first = dict(first_wall_s=time.perf_counter() - t_wall,
                 first_cpu_s=time.process_time() - t_cpu)
    stop_time, stop_steps = float(sim.stop_time_s), int(sim.stats.steps)
    chunks = math.ceil(stop_time / CHUNK_S - 1e-9) - 1  # the chunks that end before the stop
    gc.collect()
    gc.disable()
    best = math.inf
    stats = None
    for _ in range(repeats):
        sim = _stop_simulator()
        cpu = _run_chunks(sim, chunks)
        if stats is None:
            stats = sim.stats
        elif sim.stats != stats:
            raise RuntimeError("two runs of the same stop took different steps")
        best = min(best, cpu)
    # per-chunk overhead: one 10 ms step per call while braking
    best_call = math.inf
    for _ in range(max(repeats // 4, 3)):
        sim = _stop_simulator()
        sim.advance(STEP_S, Commands(emergency=True))
        start = time.process_time()
        for _ in range(calls):
            sim.advance(STEP_S)
        best_call = min(best_call, (time.process_time() - start) / calls)
    # and at rest: 5 s after the stop (this tree has judged the train settled by then)
    best_rest = math.inf
    for _ in range(max(repeats // 4, 3)):
        sim = _stop_simulator()
        _run_chunks(sim, math.ceil(stop_time / CHUNK_S) + 5)
        start = time.process_time()
        for _ in range(calls):
            sim.advance(STEP_S)
        best_rest = min(best_rest, (time.process_time() - start) / calls)
    gc.enable()
    import ltd_brake_ros

    return dict(first, package=str(Path(ltd_brake_ros.__file__).parent), stop_time_s=stop_time,
                stop_steps=stop_steps, chunks=chunks, steps=int(stats.steps),
                rejected=int(stats.rejected_steps), newton=int(stats.newton_iterations),
                best_s=best, call_s=best_call, rest_call_s=best_rest)


# --------------------------------------------------------------------------- the parent


def _extract(commit: str, into: Path) -> None:
    """The files of ``commit`` in ``into`` (git archive: no change to the repository)."""
    into.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(HERE), "archive", "--format=tar", commit],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)


def _cached(tree: Path) -> bool:
    """Whether numba has cached kernels of the tree's physics package (they may be stale, for
    sources changed since: then they compile too)."""
    return any((tree / "ltd_brake_ros" / "physics").rglob("*.nbi"))


def _measure(tree: Path, repeats: int, calls: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), LTD_BRAKE_FIRST_RUN="wait",
               LTD_BRAKE_SERVER="off")
    env.pop("LTD_BRAKE_CONFIG", None)
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker",
                          "--repeats", str(repeats), "--calls", str(calls)],
                         env=env, cwd=str(tree), check=True, capture_output=True, text=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if Path(result["package"]).resolve() != (tree / "ltd_brake_ros").resolve():
        raise RuntimeError(f"the process imported {result['package']}, not {tree}")
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", default=DEFAULT_OLD, help=f"commit (default {DEFAULT_OLD})")
    parser.add_argument("--rounds", type=int, default=8, help="processes per tree (default 8)")
    parser.add_argument("--repeats", type=int, default=20,
                        help="timed stops per process (default 20)")
    parser.add_argument("--calls", type=int, default=300,
                        help="advance(0.01) calls per timed batch (default 300)")
    parser.add_argument("--keep-old", metavar="DIR", type=Path,
                        help="extract the commit here (reused if present) and keep it")
    parser.add_argument("--new", metavar="DIR", type=Path,
                        help="measure this source tree in place of this one (e.g. another "
                        "commit extracted with git archive)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.repeats, args.calls)))
        return
    tmp = None
    if args.keep_old is not None:
        old = args.keep_old.resolve()
        if not (old / "ltd_brake_ros").is_dir():
            _extract(args.old, old)
    else:
        tmp = Path(tempfile.mkdtemp(prefix="ltd_step_cost_"))
        old = tmp / "old"
        _extract(args.old, old)
    trees = {"old": old, "new": args.new.resolve() if args.new else HERE}
    labels = {"old": f"{args.old}", "new": str(args.new) if args.new else "this tree"}
    try:
        if not args.new:
            commit = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"],
                                    capture_output=True, text=True).stdout.strip()
            dirty = subprocess.run(["git", "-C", str(HERE), "status", "--porcelain",
                                    "ltd_brake_ros"], capture_output=True,
                                   text=True).stdout.strip()
            labels["new"] = f"this tree ({commit}{' + changes' if dirty else ''})"
        cold = {}
        for key, tree in trees.items():
            cached = _cached(tree)
            print(f"cold process, {labels[key]}: ", end="", file=sys.stderr, flush=True)
            cold[key] = _measure(tree, 1, 10)
            cold[key]["cached_before"] = cached
            print(f"{cold[key]['first_wall_s']:.1f} s", file=sys.stderr, flush=True)
        runs = {"old": [], "new": []}
        for r in range(args.rounds):
            order = ("old", "new") if r % 2 == 0 else ("new", "old")
            for key in order:
                runs[key].append(_measure(trees[key], args.repeats, args.calls))
            print(f"round {r + 1}/{args.rounds}: " + ", ".join(
                f"{k} {runs[k][-1]['best_s'] / runs[k][-1]['steps'] * 1e6:.3f} µs/step"
                for k in ("old", "new")), file=sys.stderr, flush=True)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    report(args, labels, cold, runs)


def report(args, labels: dict, cold: dict, runs: dict) -> None:
    """Print the figures as Markdown."""
    ref = runs["old"][0]
    print(f"Scenario 6, emergency stop from 100 km/h (paper's empirical model), 1 s chunks "
          f"up to the one holding the stop: {ref['chunks']} chunks, stop at "
          f"{ref['stop_time_s']:.2f} s; {args.rounds} processes per tree, interleaved, "
          f"best of {args.repeats} stops each; CPU time.\n")
    print("| tree | steps (rejected) | Newton it. | steps to the stop | CPU per step, best "
          "[µs] | median of processes [µs] | advance(0.01) per call while braking, best [µs] "
          "| median [µs] | advance(0.01) at rest, best [µs] |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    per_step, per_call = {}, {}
    for key in ("old", "new"):
        rs = runs[key]
        steps = rs[0]["steps"]
        s = [r["best_s"] / r["steps"] * 1e6 for r in rs]
        c = [r["call_s"] * 1e6 for r in rs]
        per_step[key], per_call[key] = s, c
        print(f"| {labels[key]} | {steps} ({rs[0]['rejected']}) | {rs[0]['newton']} | "
              f"{rs[0]['stop_steps']} | {min(s):.3f} | {statistics.median(s):.3f} | "
              f"{min(c):.2f} | {statistics.median(c):.2f} | "
              f"{min(r['rest_call_s'] for r in rs) * 1e6:.2f} |")
    same = all(r["steps"] == ref["steps"] and r["rejected"] == ref["rejected"]
               for key in runs for r in runs[key])
    paired = [n / o for o, n in zip(per_step["old"], per_step["new"])]
    paired_call = [n / o for o, n in zip(per_call["old"], per_call["new"])]
    print(f"\nCPU per step, {labels['new']} / {labels['old']}: best "
          f"{min(per_step['new']) / min(per_step['old']):.3f}, median of the rounds' paired "
          f"ratios {statistics.median(paired):.3f} (range {min(paired):.3f}-"
          f"{max(paired):.3f}); the same steps in both: "
          f"{'yes' if same else 'NO'}.")
    print(f"advance(0.01) per call, {labels['new']} / {labels['old']}: best "
          f"{min(per_call['new']) / min(per_call['old']):.3f}, median of paired ratios "
          f"{statistics.median(paired_call):.3f}.")
    print("\nCold (first process of each tree, the whole stop to standstill, import and "
          "kernel load or compile included):\n")
    print("| tree | numba cache files before | wall [s] | CPU [s] |")
    print("|---|---|---:|---:|")
    for key in ("old", "new"):
        c = cold[key]
        print(f"| {labels[key]} | {'present' if c['cached_before'] else 'none (compiles)'} | "
              f"{c['first_wall_s']:.2f} | {c['first_cpu_s']:.2f} |")


if __name__ == "__main__":
    main()

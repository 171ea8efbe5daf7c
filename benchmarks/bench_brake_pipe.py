"""Speed of the UIC brake-pipe model beside the paper's empirical brake, one Markdown table.

For each train an emergency stop from 100 km/h is run on one core with the ``Simulator`` in 1 s
chunks (best of a few runs, after a warm-up that compiles): the real-time factor (simulated
stop time / CPU time of this single-threaded process, which other load on a shared machine
inflates far less than the wall time) with the empirical model (``brake_params/paper.yaml``)
and with the brake pipe (``brake_params/uic_brake_pipe.yaml``), the stopping distances, and the
CPU time of the pipe and distributors alone over the same simulated time (no mechanics), to
show what the pipe itself costs. Targets: >= 300x real time for scenario 6, >= 50x for 150
wagons, >= 5x for 1000 wagons.

Accuracy (not for 1000 wagons): the pipe model's block forces are a fixed function of time (its
own grid), so a run at fixed 1 ms mechanical steps is a tight reference for the default run:
the table gives the stopping-distance error and the largest error of the per-coupler peak draft
and buff forces, as a percentage of the largest peak.

Usage::

    python benchmarks/bench_brake_pipe.py            # all rows (about 2 minutes)
    python benchmarks/bench_brake_pipe.py --quick    # scenario 6 and 150 wagons
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from ltd_brake_ros.inputs import get_scenario, load_brake_params, load_consist  # noqa: E402
from ltd_brake_ros.physics.brakes import EMERGENCY, uic_pipe  # noqa: E402
from ltd_brake_ros.simulator import Commands, SimulationError, Simulator  # noqa: E402
from ltd_brake_ros.studies.brake_pipe_validation import brake_history, train  # noqa: E402

SPEED_KMH = 100.0
TARGETS = {"scenario 6": 300.0, "150 wagons G": 50.0, "1000 wagons G": 5.0}


def stop(consist, params, **options):
    """CPU time [s], simulated stop time [s], distance [m], Newton failure (bool), simulator."""
    sim = Simulator(consist, SPEED_KMH, params, **options)
    t0 = time.process_time()
    try:
        sim.advance(1.0, Commands(emergency=True))
        while sim.stop_time_s is None and sim.time_s < 600.0:
            sim.advance(1.0)
    except SimulationError:
        return time.process_time() - t0, sim.time_s, float("nan"), True, sim
    return time.process_time() - t0, sim.time_s, sim.stopping_distance_m, False, sim


def accuracy(consist, params, sim):
    """Distance error [%] and largest peak-force error [% of the largest peak] of ``sim``
    against fixed 1 ms steps."""
    ref = stop(consist, params, step_s=0.001, tolerance_m_s=None)[4]
    peaks = np.concatenate((ref.peak_draft_N, -ref.peak_buff_N))
    ours = np.concatenate((sim.peak_draft_N, -sim.peak_buff_N))
    return (100.0 * (sim.stopping_distance_m / ref.stopping_distance_m - 1.0),
            100.0 * np.max(np.abs(ours - peaks)) / np.max(peaks))


def best_stop(consist, params, repeats):
    runs = [stop(consist, params) for _ in range(repeats)]
    walls = sorted(r[0] for r in runs)
    return walls[0], walls[-1], runs[0][:4], runs[0][4]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="scenario 6 and 150 wagons only")
    ap.add_argument("--repeats", type=int, default=3, help="runs per cell (best reported)")
    args = ap.parse_args()
    empirical = load_brake_params("brake_params/paper.yaml")
    pipe = load_brake_params("brake_params/uic_brake_pipe.yaml")
    rows = [("scenario 6", load_consist(get_scenario(6).consist_file)),
            ("150 wagons G", train(150, "G"))]
    if not args.quick:
        rows.append(("1000 wagons G", train(1000, "G")))
    stop(rows[0][1], empirical)  # compile both models
    stop(rows[0][1], pipe)
    print("| train | vehicles | empirical x real time | pipe x real time (spread) | target "
          "| pipe alone x real time | distance empirical m | distance pipe m | Newton failures "
          "| pipe distance error vs 1 ms | pipe peak error vs 1 ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, consist in rows:
        repeats = 1 if consist.n > 500 else args.repeats
        e_best, _, (_, e_t, e_d, e_fail), _ = best_stop(consist, empirical, repeats)
        p_best, p_worst, (_, p_t, p_d, p_fail), p_sim = best_stop(consist, pipe, repeats)
        acc = "| - | - "
        if consist.n <= 500:
            d_err, f_err = accuracy(consist, pipe, p_sim)
            acc = f"| {d_err:+.3f} % | {f_err:.2f} % "
        alone = float("inf")
        for _ in range(repeats):
            t0 = time.process_time()
            brake_history(consist, pipe.pneumatic, [(0.0, 1.0, EMERGENCY)], p_t, sample_s=1.0)
            alone = min(alone, time.process_time() - t0)
        print(f"| {name} | {consist.n} | {e_t / e_best:.0f} | {p_t / p_best:.0f} "
              f"({p_t / p_worst:.0f}-{p_t / p_best:.0f}) | {TARGETS[name]:.0f} "
              f"| {p_t / alone:.0f} | {e_d:.1f} | {p_d:.1f} | {int(e_fail) + int(p_fail)} "
              + acc + "|")
    print(f"\npipe step {uic_pipe.Params().pipe_step_s * 1e3:g} ms; best of {args.repeats} "
          "(1 for 1000 wagons); one core, CPU time")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

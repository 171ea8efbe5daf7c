"""Cost of wheel slide: scenario 6's emergency stop without an adhesion condition and on a few
rails, one Markdown table.

Each stop runs on one core with the ``Simulator`` in 1 s chunks, ``--runs`` times after a
warm-up that compiles (CPU time of this single-threaded process: other load on a shared
machine inflates it far less than the wall time). Per condition: the best and median CPU time
of a stop, the steps it took and the best time per step. Without a condition the kernel runs
the paper's method; with one, a stop on a slippery rail is longer (more steps), each step
costing about the same.

Usage::

    python benchmarks/bench_wheel_slide.py             # 60 runs per row (about 10 s)
    python benchmarks/bench_wheel_slide.py --runs 10
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

from ltd_brake_ros.inputs import get_scenario  # noqa: E402
from ltd_brake_ros.simulator import Commands, Simulator  # noqa: E402

#: The rows: no condition, then the named rails and two constant levels.
CONDITIONS = (None, "wet", "low", 0.07, 0.05)


def time_stop(condition, runs: int) -> tuple[list[float], Simulator]:
    """CPU times of ``runs`` emergency stops of scenario 6 on ``condition`` [s], sorted."""
    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh, adhesion=condition)
    sim.warm_up()
    times = []
    for _ in range(runs):
        sim.reset()
        start = time.process_time()
        sim.advance(1.0, Commands(emergency=True))
        while sim.stop_time_s is None:
            sim.advance(1.0)
        times.append(time.process_time() - start)
    return sorted(times), sim


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=60, help="stops per row (default 60)")
    runs = max(parser.parse_args().runs, 1)
    print("| adhesion | distance m | steps | best ms | median ms | best µs per step |")
    print("|---|---:|---:|---:|---:|---:|")
    for condition in CONDITIONS:
        times, sim = time_stop(condition, runs)
        steps = sim.stats.steps
        print(f"| {sim.adhesion.name} | {sim.stopping_distance_m:.1f} | {steps} | "
              f"{times[0] * 1e3:.2f} | {times[len(times) // 2] * 1e3:.2f} | "
              f"{times[0] / steps * 1e6:.2f} |")


if __name__ == "__main__":
    main()

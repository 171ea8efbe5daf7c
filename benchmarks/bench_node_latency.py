"""Pacing of sim_node: lateness of chunk publication, and the real-time factor it can reach.

The node runs in this process exactly as ``sim_node`` runs it (executor in the main thread, the
plant thread advancing and publishing), with the emergency brake applied at t = 0, for two trains:
the paper's scenario 6 (E402B + 32 wagons, 33 vehicles) and an E402B + 150 loaded wagons.

* real_time_factor 1, chunk 0.02 s: lateness = wall time at which a chunk's last message was
  published minus its deadline (start + k * chunk / real_time_factor); p50, p99, max, overruns;
* real_time_factor 0: simulated time / wall time over ``--sim-seconds`` of simulated time.

Usage::

    ./dev.sh run python benchmarks/bench_node_latency.py [--seconds 15] [--sim-seconds 60]

Prints a Markdown table. Nothing subscribes, so the numbers are the node's own cost; DDS delivery
to subscribers comes on top of them.
"""
from __future__ import annotations

import argparse
import os
import random
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

# a private DDS domain on this machine only, so the benchmark disturbs (and hears) nobody
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402

from ltd_brake_ros.inputs import consist_from_mapping  # noqa: E402
from ltd_brake_ros.plant.runner import PlantRunner  # noqa: E402
from ltd_brake_ros.ros.sim_node import SimNode  # noqa: E402

LONG_TRAIN = {"name": "E402B + 150 Shimmns (80 t)",
              "vehicles": [{"type": "E402B"}, {"type": "Shimmns", "count": 150, "mass_t": 80.0}]}


def run_node(context: Context, overrides: dict, wall_s: float) -> tuple[PlantRunner, float]:
    """Run a node until it finishes (``max_sim_time_s``) or ``wall_s`` elapse.

    Parameters
    ----------
    context : rclpy.context.Context
    overrides : dict
        Parameter name to value.
    wall_s : float
        Longest wall time to run [s].

    Returns
    -------
    runner : PlantRunner
        The stopped node's plant (statistics and ``failure`` still readable).
    elapsed_s : float
        Wall time from start to finish [s].
    """
    node = SimNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in overrides.items()])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    start = time.monotonic()
    node.start()
    runner = node.runner
    while time.monotonic() - start < wall_s and not runner.finished.is_set() \
            and runner.failure is None:
        executor.spin_once(timeout_sec=0.05)
    elapsed = time.monotonic() - start
    executor.remove_node(node)
    executor.shutdown()
    node.close()
    return runner, elapsed


def main() -> None:
    """Run both trains at real_time_factor 1 and 0 and print the Markdown table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=15.0,
                    help="wall time of each real_time_factor 1 run [s]")
    ap.add_argument("--sim-seconds", type=float, default=60.0,
                    help="simulated time of each real_time_factor 0 run [s]")
    args = ap.parse_args()

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    rclpy.logging.set_logger_level("sim_node", rclpy.logging.LoggingSeverity.WARN)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        long_file = Path(tmp) / "e402b_150_shimmns_80t.yaml"
        long_file.write_text(yaml.safe_dump(LONG_TRAIN))
        trains = [("scenario 6", "scenario_6", -1.0, 33),
                  (LONG_TRAIN["name"], str(long_file), 100.0,
                   consist_from_mapping(LONG_TRAIN, "<generated>").n)]
        for label, consist, speed, n in trains:
            base = {"consist": consist, "initial_speed_kmh": speed, "chunk_s": 0.02,
                    "auto_brake_at_s": 0.0}
            paced, _ = run_node(context, base | {"real_time_factor": 1.0}, args.seconds)
            late_ms = np.array(paced.stats.lateness_s) * 1e3
            fast, wall = run_node(context, base | {"real_time_factor": 0.0,
                                                  "max_sim_time_s": args.sim_seconds},
                                  wall_s=600.0)
            for run in (paced, fast):
                if run.failure:
                    raise SystemExit(f"{label}: the simulation failed: {run.failure}")
            rows.append((label, n, paced.stats.chunks, np.percentile(late_ms, 50),
                         np.percentile(late_ms, 99), late_ms.max(), paced.stats.overruns,
                         fast.sim_time_s / wall))
    rclpy.try_shutdown(context=context)

    print(f"sim_node pacing, chunk 0.02 s, emergency brake at t = 0; real_time_factor 1 for "
          f"{args.seconds:g} s wall, real_time_factor 0 for {args.sim_seconds:g} s simulated; "
          f"{os.cpu_count()} CPUs\n")
    print("| train | vehicles | chunks at RTF 1 | lateness p50 [ms] | lateness p99 [ms] "
          "| lateness max [ms] | overruns | achieved RTF at RTF 0 |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for label, n, chunks, p50, p99, worst, overruns, rtf in rows:
        print(f"| {label} | {n} | {chunks} | {p50:.3f} | {p99:.3f} | {worst:.3f} | {overruns} "
              f"| {rtf:.1f} |")


if __name__ == "__main__":
    main()

"""Speed of sim_node as a live plant: free-running as fast as possible, and a lock-step loop.

* ``real_time_factor:=0``, 20 ms chunks, scenario 6 (33 vehicles), emergency brake at t = 0:
  simulated time / wall time with every chunk published (5 arrays, 2 stamped states,
  ``/clock``) and with ``publish_every:=10``. The node runs in this process as ``sim_node``
  runs it (executor in the main thread, the plant thread advancing and publishing); nothing
  subscribes, so the figure is the node's own cost.
* A long train with the brake-pipe model: E402B + 1 000 Shimmns of 80 t,
  ``brake_params/uic_brake_pipe.yaml``, emergency from 100 km/h at t = 0 until 1 s after the
  stop (or ``--long-sim-seconds``), 20 ms chunks, every chunk published (arrays of 1 001 values,
  the pipe and cylinder pressures included): the pace at ``real_time_factor:=0``, the wall time
  of a chunk split into ``Simulator.advance`` (the kernel) and publishing, and at
  ``real_time_factor:=1`` the achieved pace (simulated over wall time from the first to the
  last published chunk), the chunks that overran, the largest lag behind the schedule and
  the chunks caught up: with ``max_catch_up_s:=0`` (a late chunk restarts the schedule) and
  with the default catch-up budget, runs alternated.
* Lock-step loop from a Python client (the way ``examples/speed_controller.py`` drives the
  plant): publish ``brake_demand``, call ``~/step`` (one 20 ms chunk), wait for the reply and
  for the ``vehicles/state`` the step published. The node runs as its own process (the
  installed ``sim_node``); steps per wall second over ``--steps`` steps.

Usage::

    ./dev.sh run python benchmarks/bench_node.py [--sim-seconds 120] [--steps 2000] [--repeat 3]
        [--long-repeat 1] [--long-sim-seconds 200] [--long-chunk-s 0.02] [--only-long]
        [--long-catch-up-s 0.2]

Prints a Markdown table: the best of ``--repeat`` runs and the spread (best to worst).
"""
from __future__ import annotations

import argparse
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# a private DDS domain on this machine only, so the benchmark disturbs (and hears) nobody
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(101, 200)))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from ltd_brake_ros.plant.settings import DEFAULT_MAX_CATCH_UP_S  # noqa: E402
from ltd_brake_ros.ros.sim_node import SimNode  # noqa: E402

CHUNK_S = 0.02
#: The long train of the brake-pipe row.
LONG_TRAIN = """name: E402B + 1000 Shimmns (80 t)
vehicles:
  - type: E402B
  - type: Shimmns
    count: 1000
    mass_t: 80.0
"""


def run_to_the_end(context: Context, node: SimNode) -> float:
    """Spin an in-process node as ``sim_node`` does until its run ends; its wall time [s]."""
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    start = time.monotonic()
    node.start()
    runner = node.runner
    while not runner.finished.is_set() and runner.failure is None:
        executor.spin_once(timeout_sec=0.05)
    elapsed = time.monotonic() - start
    executor.remove_node(node)
    executor.shutdown()
    node.close()
    if runner.failure:
        raise SystemExit(f"the simulation failed: {runner.failure}")
    return elapsed


def free_running(context: Context, sim_seconds: float, publish_every: int) -> float:
    """Achieved real-time factor of an in-process node at ``real_time_factor:=0``."""
    node = SimNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {
            "chunk_s": CHUNK_S, "real_time_factor": 0.0, "auto_brake_at_s": 0.0,
            "max_sim_time_s": sim_seconds, "publish_every": publish_every,
            "clock": "publish"}.items()])
    elapsed = run_to_the_end(context, node)
    return node.runner.sim_time_s / elapsed


def long_train(context: Context, consist: str, sim_seconds: float,
               real_time_factor: float, chunk_s: float = CHUNK_S,
               max_catch_up_s: float = DEFAULT_MAX_CATCH_UP_S) -> dict:
    """Pace and per-chunk wall times of an in-process node on the 1 000-wagon train.

    Returns
    -------
    dict
        ``pace`` (simulated / wall time of the whole run), ``published_pace`` (simulated /
        wall time from the first to the last published chunk), ``advance_ms`` and
        ``publish_ms`` (mean wall time of ``Simulator.advance`` and of publishing a chunk),
        ``advance_p99_ms``, ``overruns`` (chunks finished more than ``max_catch_up_s`` after
        the next was due), ``caught_up`` (chunks finished behind, within it), ``max_lag_ms``
        (largest lag behind the schedule), ``chunks``.
    """
    node = SimNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {
            "consist": consist, "initial_speed_kmh": 100.0,
            "brake_params_file": "brake_params/uic_brake_pipe.yaml", "chunk_s": chunk_s,
            "real_time_factor": real_time_factor, "max_catch_up_s": max_catch_up_s,
            "auto_brake_at_s": 0.0, "max_sim_time_s": sim_seconds,
            "shutdown_after_stop_s": 1.0, "clock": "publish"}.items()])
    runner = node.runner
    advance, publish, published = [], [], []
    timed_advance, timed_publish = runner.sim.advance, runner._publish_state

    def advance_timed(*args, **kwargs):
        t0 = time.perf_counter()
        snap = timed_advance(*args, **kwargs)
        advance.append(time.perf_counter() - t0)
        return snap

    def publish_timed(snap):
        t0 = time.perf_counter()
        timed_publish(snap)
        publish.append(time.perf_counter() - t0)
        published.append((time.monotonic(), snap.time_s))

    runner.sim.advance, runner._publish_state = advance_timed, publish_timed
    elapsed = run_to_the_end(context, node)
    advance.sort()
    (first_wall, first_s), (last_wall, last_s) = published[1], published[-1]
    stats = runner.stats
    return {"pace": runner.sim_time_s / elapsed, "chunks": stats.chunks,
            "published_pace": (last_s - first_s) / (last_wall - first_wall),
            "advance_ms": 1e3 * sum(advance) / len(advance),
            "advance_p99_ms": 1e3 * advance[int(0.99 * (len(advance) - 1))],
            "publish_ms": 1e3 * sum(publish[1:]) / max(len(publish) - 1, 1),
            "overruns": stats.overruns, "caught_up": stats.caught_up,
            "max_lag_ms": 1e3 * stats.max_lag_s}


def sim_node_executable() -> str:
    """The installed ``sim_node`` beside this Python."""
    found = shutil.which("sim_node", path=os.path.dirname(sys.executable))
    if found is None:
        raise SystemExit("sim_node is not installed in this environment (./dev.sh setup)")
    return found


def lockstep_loop(context: Context, steps: int) -> float:
    """Steps per wall second of a client driving a lock-step ``sim_node`` process."""
    ns = f"/bench_lockstep_{os.getpid()}"
    node = rclpy.create_node("bench_client", namespace=ns, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    demand = node.create_publisher(Float64, "brake_demand", reliable)
    stamps: list[int] = []
    node.create_subscription(
        JointState, "vehicles/state",
        lambda m: stamps.append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec),
        reliable)
    client = node.create_client(Trigger, "sim_node/step")
    proc = subprocess.Popen(
        [sim_node_executable(), "--ros-args", "-r", f"__ns:={ns}", "-p", "lockstep:=true",
         "-p", f"chunk_s:={CHUNK_S}", "-p", "clock:=none", "--log-level", "warn"])
    try:
        def spin_until(done, timeout_s=60.0):
            end = time.monotonic() + timeout_s
            while not done():
                if time.monotonic() > end or proc.poll() is not None:
                    raise SystemExit("the lock-step plant did not answer")
                executor.spin_once(timeout_sec=0.01)

        spin_until(lambda: client.service_is_ready() and demand.get_subscription_count() > 0)

        def step(k: int) -> None:
            demand.publish(Float64(data=(k % 100) / 100.0))
            future = client.call_async(Trigger.Request())
            after = round((k - 0.5) * CHUNK_S * 1e9)
            spin_until(lambda: future.done() and stamps and stamps[-1] > after, 10.0)
            if not future.result().success:
                raise SystemExit(f"step refused: {future.result().message}")

        # warm-up: the first reply can be lost before the plant's writer matched our reader
        while True:
            future = client.call_async(Trigger.Request())
            end = time.monotonic() + 2.0
            while not future.done() and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.01)
            if future.done():
                break
            client.remove_pending_request(future)
        spin_until(lambda: bool(stamps) and stamps[-1] > 0)
        done = round(stamps[-1] / (CHUNK_S * 1e9))
        for k in range(done + 1, done + 51):
            step(k)
        start = time.monotonic()
        for k in range(done + 51, done + 51 + steps):
            step(k)
        return steps / (time.monotonic() - start)
    finally:
        proc.terminate()
        proc.wait(timeout=20)
        executor.shutdown()
        node.destroy_node()


def spread(values: list[float], digits: int = 0) -> str:
    return (f"{max(values):.{digits}f} (spread {min(values):.{digits}f}-"
            f"{max(values):.{digits}f})")


def paced_row(runs: list[dict], label: str) -> str:
    """Table row of paced 1 000-wagon runs: pace, overruns, largest lag, chunks caught up
    (the run with the best pace, and the spread of the pace and of the overruns)."""
    best = max(runs, key=lambda r: r["published_pace"])
    overruns = [r["overruns"] for r in runs]
    return (f"| 1 000 wagons, brake pipe, real_time_factor 1, {label}: achieved real-time "
            f"factor; chunks that overran (spread); largest lag; chunks caught up "
            f"| {spread([r['published_pace'] for r in runs], 4)}; "
            f"{best['overruns']} of {best['chunks']} ({min(overruns)}-{max(overruns)}); "
            f"{best['max_lag_ms']:.0f} ms; {best['caught_up']} |")


def long_rows(context: Context, repeat: int, sim_seconds: float, chunk_s: float,
              catch_up_s: float) -> list[str]:
    """Table rows of the 1 000-wagon brake-pipe train (best of ``repeat``; the paced runs
    without and with catch-up alternated, so both see the same load)."""
    with tempfile.TemporaryDirectory() as folder:
        consist = str(Path(folder) / "e402b_1000_shimmns_80t.yaml")
        Path(consist).write_text(LONG_TRAIN)
        fast = [long_train(context, consist, sim_seconds, 0.0, chunk_s) for _ in range(repeat)]
        restart, catch_up = [], []
        for _ in range(repeat):
            restart.append(long_train(context, consist, sim_seconds, 1.0, chunk_s, 0.0))
            catch_up.append(long_train(context, consist, sim_seconds, 1.0, chunk_s, catch_up_s))
    best = max(fast, key=lambda r: r["pace"])
    share = best["publish_ms"] / (best["advance_ms"] + best["publish_ms"])
    return [
        f"| 1 000 wagons, brake pipe, real_time_factor 0: achieved real-time factor "
        f"| {spread([r['pace'] for r in fast], 2)} |",
        f"| 1 000 wagons, brake pipe: wall time per {chunk_s * 1e3:g} ms chunk, advance "
        f"(kernel) mean / p99; "
        f"publishing mean | {best['advance_ms']:.1f} / {best['advance_p99_ms']:.1f} ms; "
        f"{best['publish_ms']:.2f} ms ({100 * share:.0f} %) |",
        paced_row(restart, "max_catch_up_s 0 (a late chunk restarts the schedule)"),
        paced_row(catch_up, f"max_catch_up_s {catch_up_s:g}")]


def main() -> None:
    """Run the measurements and print the Markdown table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-seconds", type=float, default=120.0,
                    help="simulated time of each free-running run [s]")
    ap.add_argument("--steps", type=int, default=2000, help="lock-step loop steps per run")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each measurement")
    ap.add_argument("--long-repeat", type=int, default=1,
                    help="runs of each 1 000-wagon measurement (0: none)")
    ap.add_argument("--long-sim-seconds", type=float, default=200.0,
                    help="longest simulated time of a 1 000-wagon run [s]")
    ap.add_argument("--long-chunk-s", type=float, default=CHUNK_S,
                    help="chunk of the 1 000-wagon runs [s]")
    ap.add_argument("--long-catch-up-s", type=float, default=DEFAULT_MAX_CATCH_UP_S,
                    help="max_catch_up_s of the paced 1 000-wagon runs with catch-up [s]")
    ap.add_argument("--only-long", action="store_true", help="only the 1 000-wagon rows")
    args = ap.parse_args()

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    rclpy.logging.set_logger_level("sim_node", rclpy.logging.LoggingSeverity.WARN)
    every_1, every_10, loops = [], [], []
    for _ in range(0 if args.only_long else args.repeat):
        every_1.append(free_running(context, args.sim_seconds, 1))
        every_10.append(free_running(context, args.sim_seconds, 10))
        loops.append(lockstep_loop(context, args.steps))
    long = long_rows(context, args.long_repeat, args.long_sim_seconds, args.long_chunk_s,
                     args.long_catch_up_s) if args.long_repeat > 0 else []
    rclpy.try_shutdown(context=context)
    print(f"sim_node speed, scenario 6 (33 vehicles) unless said, chunk {CHUNK_S:g} s; best of "
          f"{args.repeat} runs ({args.long_repeat} for 1 000 wagons) (spread); "
          f"{os.cpu_count()} CPUs\n")
    print("| measurement | result |")
    print("|---|---:|")
    if every_1:
        print(f"| real_time_factor 0, every chunk published: achieved real-time factor "
              f"| {spread(every_1)} |")
        print(f"| real_time_factor 0, publish_every 10: achieved real-time factor "
              f"| {spread(every_10)} |")
        print(f"| lock-step loop (command, step one chunk, state) from a Python client: "
              f"steps/s | {spread(loops)} |")
    for row in long:
        print(row)


if __name__ == "__main__":
    main()

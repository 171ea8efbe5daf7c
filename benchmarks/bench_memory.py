"""Memory of a long recorded run: the installed ``sim_node`` for one hour of simulated time.

The node runs as fast as it can (``real_time_factor:=0``), records to a temporary bag folder,
brakes by itself after 30 s and then stands; ``max_sim_time_s`` ends it. Its resident set size
is read from ``/proc`` about four times a second, with the simulated time from its
``/diagnostics``. Reported: RSS after the warm-up, the peak after it and at the end, the growth
(target: under 10 MB), the bag size and bytes per simulated hour.

    ./dev.sh run python benchmarks/bench_memory.py [--sim-seconds 3600] [--warmup-s 300]

Linux only (``/proc``). A private DDS domain on this machine keeps it apart from other runs.
"""
from __future__ import annotations

import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(101, 200)))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402

NODE = "/bench_memory/sim_node"


def rss_kb(pid: int) -> int | None:
    """Resident set size of ``pid`` [kB], None once it has gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError):
        return None
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim-seconds", type=float, default=3600.0,
                    help="simulated time to run [s] (default 3600)")
    ap.add_argument("--warmup-s", type=float, default=300.0,
                    help="simulated time after which the baseline RSS is taken [s]")
    ap.add_argument("--consist", default="scenario_6", help="consist parameter of sim_node")
    ap.add_argument("--keep", action="store_true", help="keep the bag folder")
    args = ap.parse_args()

    exe = shutil.which("sim_node") or str(Path(sys.executable).parent / "sim_node")
    tmp = Path(tempfile.mkdtemp(prefix="bench_memory_"))
    folder = tmp / "run"
    argv = [exe, "--ros-args", "-r", "__ns:=/bench_memory", "-r", "/clock:=/bench_memory/clock",
            "-p", f"consist:={args.consist}", "-p", "real_time_factor:=0.0",
            "-p", "auto_brake_at_s:=30.0", "-p", f"max_sim_time_s:={args.sim_seconds}",
            "-p", "record:=true", "-p", f"record_dir:={folder}"]

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_memory_probe", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    sim_time = [0.0]

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == f"{NODE}: train plant":
                values = {kv.key: kv.value for kv in status.values}
                sim_time[0] = float(values.get("sim_time_s", sim_time[0]))

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    log = open(tmp / "sim_node.log", "wb")  # noqa: SIM115 - closed below
    start = time.monotonic()
    proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    samples: list[tuple[float, float, int]] = []  # wall [s], simulated [s], RSS [kB]
    try:
        while proc.poll() is None:
            executor.spin_once(timeout_sec=0.25)
            rss = rss_kb(proc.pid)
            if rss is not None and proc.poll() is None:
                samples.append((time.monotonic() - start, sim_time[0], rss))
        status = proc.wait()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        log.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    wall = time.monotonic() - start
    if status != 0:
        print((tmp / "sim_node.log").read_text(errors="replace"), file=sys.stderr)
        print(f"sim_node exited with {status}", file=sys.stderr)
        return 1

    after = [(w, t, r) for w, t, r in samples if t >= args.warmup_s]
    if not after:
        print("the run ended before the warm-up; raise --sim-seconds", file=sys.stderr)
        return 1
    warm, end = after[0][2], after[-1][2]
    peak = max(r for _, _, r in after)
    bag = sum(f.stat().st_size for f in folder.iterdir())
    per_hour = bag / max(after[-1][1], 1e-9) * 3600.0
    print(f"sim_node, {args.consist}, real_time_factor 0, recording: "
          f"{args.sim_seconds:g} s simulated in {wall:.0f} s wall")
    print(f"| RSS after {args.warmup_s:g} s simulated | peak after | at the end "
          f"({after[-1][1]:.0f} s) | growth | bag | bag per simulated hour |")
    print("|---|---|---|---|---|---|")
    print(f"| {warm / 1024:.1f} MB | {peak / 1024:.1f} MB | {end / 1024:.1f} MB "
          f"| {(peak - warm) / 1024:+.1f} MB | {bag / 1e6:.1f} MB | {per_hour / 1e6:.0f} MB |")
    verdict = "OK" if peak - warm < 10 * 1024 else "TOO MUCH"
    print(f"growth after warm-up {(peak - warm) / 1024:.1f} MB: {verdict} (limit 10 MB)")
    if args.keep:
        print(f"bag kept in {folder}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0 if verdict == "OK" else 1


if __name__ == "__main__":
    sys.exit(main())

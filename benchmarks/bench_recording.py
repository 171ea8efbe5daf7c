"""What recording costs: wall time per 0.02 s chunk with and without the MCAP writer, and bytes
per simulated second, for the 33-vehicle (paper scenario 6) and a 150-vehicle train.

Each chunk does what the node does: advance the simulator by 0.02 s, build and serialize the
five per-vehicle / per-coupler Float64MultiArray messages and the Clock, and (when recording)
hand the bytes to :class:`~ltd_brake_ros.recording.writer.BagWriter`. Runs are repeated and
interleaved; the fastest of each is reported (the machine is shared and noisy).

    ./dev.sh run python benchmarks/bench_recording.py [--seconds 30] [--repeat 3]
    ./dev.sh run python benchmarks/bench_recording.py --long-report   # 1 h x 50 Hz x 150 report
"""
from __future__ import annotations

import argparse
import array
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from ltd_brake_ros.recording.qos import qos_profiles_yaml
from ltd_brake_ros.recording.writer import BagWriter
from ltd_brake_ros.inputs import (consist_from_mapping, get_scenario, load_brake_params,
                                  load_coupler_lut)
from ltd_brake_ros.simulator import Commands, Simulator

CHUNK_S = 0.02
F64 = "std_msgs/msg/Float64MultiArray"
TOPICS = (("vehicles/speed", "vehicle"), ("vehicles/position", "vehicle"),
          ("vehicles/brake_force", "vehicle"), ("vehicles/traction_force", "vehicle"),
          ("couplers/force", "coupler"))


def consist(n: int):
    if n == 33:
        return get_scenario(6).consist()
    return consist_from_mapping({"name": f"E402B + {n - 1} Shimmns (50 t)", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": n - 1, "mass_t": 50.0}]}, "benchmark")


def array_msg(values: np.ndarray, label: str) -> Float64MultiArray:
    # array.array from the raw bytes: assigning a numpy array to .data is ~10x slower
    m = Float64MultiArray()
    m.layout.dim = [MultiArrayDimension(label=label, size=values.size, stride=values.size)]
    data = array.array("d")
    data.frombytes(values.tobytes())
    m.data = data
    return m


def run(train, seconds: float, mode: str, folder: Path | None) -> dict:
    """One run; per-chunk costs [s] and bytes of payload serialized."""
    sim = Simulator(train, 100.0, load_brake_params(), load_coupler_lut())
    cmd = Commands(emergency=True)
    chunks = round(seconds / CHUNK_S)
    writer = None
    names = [f"/train/{t}" for t, _ in TOPICS]
    if mode == "record":
        writer = BagWriter(folder)
        for name in names:
            writer.add_topic(name, F64)
        writer.add_topic("/clock", "rosgraph_msgs/msg/Clock",
                         qos_profiles_yaml(depth=1, reliability="best_effort"))
    payload = 0
    in_writer = 0.0
    clock = Clock()
    perf = time.perf_counter
    cpu0, start = time.process_time(), perf()
    for _ in range(chunks):
        snap = sim.advance(CHUNK_S, cmd)
        if mode == "advance":
            continue
        t_ns = round(snap.time_s * 1e9)
        clock.clock = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
        traction = getattr(snap, "traction_force_N", None)
        arrays = (snap.speed_m_s, snap.position_m, snap.brake_force_N,
                  traction if traction is not None else np.zeros(sim.n), snap.coupler_force_N)
        datas = [serialize_message(clock)]
        datas += [serialize_message(array_msg(a, label)) for a, (_, label) in zip(arrays, TOPICS)]
        payload += sum(map(len, datas))
        if writer is not None:
            t0 = perf()
            writer.write("/clock", datas[0], t_ns)
            for name, data in zip(names, datas[1:]):
                writer.write(name, data, t_ns)
            writer.flush_if_due()
            in_writer += perf() - t0
    wall, cpu = perf() - start, time.process_time() - cpu0
    thread_cpu = 0.0
    if writer is not None:
        writer.close()
        thread_cpu = writer.writer_thread_cpu_s
    return {"wall": wall / chunks, "cpu": cpu / chunks, "in_writer": in_writer / chunks,
            "thread_cpu": thread_cpu / chunks, "payload": payload}


def bench(n: int, seconds: float, repeat: int) -> dict:
    train = consist(n)
    run(train, 1.0, "serialize", None)  # compile and warm up
    best: dict = {}
    size = payload = 0
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeat):
            for mode in ("advance", "serialize", "record"):
                folder = Path(tmp) / f"bag{r}_{mode}"
                res = run(train, seconds, mode, folder)
                if mode not in best or res["wall"] < best[mode]["wall"]:
                    best[mode] = res
                if mode == "record":
                    size = (folder / f"{folder.name}_0.mcap").stat().st_size
                    payload = res["payload"]
    rec = best["record"]
    base = rec["wall"] - rec["in_writer"]  # the same run without its writer calls
    return {"vehicles": n, "advance": best["advance"]["wall"] * 1e6,
            "serialize": best["serialize"]["wall"] * 1e6, "record": rec["wall"] * 1e6,
            "in_writer": rec["in_writer"] * 1e6, "thread_cpu": rec["thread_cpu"] * 1e6,
            "extra_percent": rec["in_writer"] / base * 100.0,
            "extra_cpu_percent": (rec["in_writer"] + rec["thread_cpu"]) / base * 100.0,
            "file_bytes_per_s": size / seconds, "payload_bytes_per_s": payload / seconds}


def long_report(hours: float = 1.0, n: int = 150, rate_hz: float = 50.0) -> None:
    """Write a synthetic long recording (no simulator) and time the report on it."""
    from ltd_brake_ros.analysis.report import analyse

    rng = np.random.default_rng(0)
    samples = round(hours * 3600 * rate_hz)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "long"
        start = time.perf_counter()
        with BagWriter(folder, metadata={"consist": {"name": "synthetic", "vehicles": n}}) as w:
            names = [f"/train/{t}" for t, _ in TOPICS]
            for name in names:
                w.add_topic(name, F64)
            w.add_topic("/train/brake_command", "std_msgs/msg/Bool")
            w.write("/train/brake_command", b"\x00\x01\x00\x00\x01", 0)
            v = np.linspace(27.8, 27.7, n)
            for i in range(samples):
                t_ns = round(i * 1e9 / rate_hz)
                v = np.maximum(v - 0.3 / rate_hz, 0.0)
                noise = rng.normal(size=n) * 1e4
                for name, (_, label), a in zip(names, TOPICS,
                                               (v, v * i / rate_hz, noise, noise, noise[:-1])):
                    w.write(name, serialize_message(array_msg(a, label)), t_ns)
        wrote = time.perf_counter() - start
        size = (folder / "long_0.mcap").stat().st_size
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        start = time.perf_counter()
        rep = analyse(folder)
        took = time.perf_counter() - start
        rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(f"\nlong recording: {hours:g} h x {rate_hz:g} Hz x {n} vehicles = "
          f"{sum(rep.topics.values())} messages, {size / 1e6:.0f} MB on disk "
          f"(written in {wrote:.0f} s)")
    print(f"report: {took:.0f} s, peak RSS grew by {(rss1 - rss0) / 1024:.0f} MiB "
          f"(heat map {rep.heat_force_N.shape[0]} x {rep.heat_force_N.shape[1]})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated time per run [s]")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--vehicles", type=int, nargs="+", default=[33, 150])
    ap.add_argument("--long-report", action="store_true",
                    help="also time the report on a 1 h x 50 Hz x 150 vehicle recording")
    args = ap.parse_args(argv)
    print(f"per 0.02 s chunk, best of {args.repeat} runs of {args.seconds:g} s simulated; "
          "times in microseconds of wall time per chunk")
    print(f"{'vehicles':>8} {'advance':>8} {'+serial.':>9} {'+record':>8} {'writer':>7} "
          f"{'thread':>7} {'extra':>6} {'extra+thr':>9} {'file kB/s':>10} {'payload kB/s':>12}")
    for n in args.vehicles:
        r = bench(n, args.seconds, args.repeat)
        print(f"{r['vehicles']:>8} {r['advance']:>8.1f} {r['serialize']:>9.1f} "
              f"{r['record']:>8.1f} {r['in_writer']:>7.1f} {r['thread_cpu']:>7.1f} "
              f"{r['extra_percent']:>5.1f}% {r['extra_cpu_percent']:>8.1f}% "
              f"{r['file_bytes_per_s'] / 1e3:>10.1f} {r['payload_bytes_per_s'] / 1e3:>12.1f}")
    print("advance / +serial. / +record: whole chunk (simulate; + build and serialize the six "
          "messages; + record them)\n"
          "writer: time inside BagWriter calls; thread: CPU of its writer thread (compression "
          "and file writes, off the simulation thread)\n"
          "extra = writer / (chunk without writer calls); extra+thr counts the thread's CPU "
          "too\nfile = zstd MCAP bytes per simulated second; payload = serialized CDR bytes")
    if args.long_report:
        long_report()
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""CPU of a model-form band against the sum of its members' single runs.

Run: ``python benchmarks/bench_band.py [--repeats N]``. For scenario 6 and E402B + 150 x 80 t
in G, times (process CPU time) the band of :func:`~ltd_brake_ros.studies.band.run_band` and,
interleaved with it, each member as a single run (:func:`~ltd_brake_ros.studies.runs.
emergency_stop` with the member's models), best of N each, all warm (kernels loaded), and
prints the ratio band / sum of singles (the target: at most 1.1).
"""
from __future__ import annotations

import argparse
import time

from ltd_brake_ros.inputs import consist_from_mapping, get_scenario
from ltd_brake_ros.inputs.band import load_band
from ltd_brake_ros.studies.band import run_band
from ltd_brake_ros.studies.runs import emergency_stop


def _cpu(fn) -> float:
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    band = load_band()
    long = consist_from_mapping({"name": "E402B + 150 x 80 t, G", "vehicles": [
        {"type": "E402B", "brake_position": "G"},
        {"type": "Shimmns", "count": 150, "mass_t": 80.0, "brake_position": "G"}]}, "bench")
    print("| train | members | band CPU | sum of single runs | ratio |")
    print("|---|---|---|---|---|")
    for name, consist, speed in (("scenario 6", get_scenario(6).consist(), 100.0),
                                 ("E402B + 150 x 80 t, G", long, 100.0)):
        run_band(consist, speed, band=band)  # warm: every member's kernels loaded
        best_band, best_sum = float("inf"), float("inf")
        for _ in range(args.repeats):
            best_band = min(best_band, _cpu(lambda: run_band(consist, speed, band=band)))
            total = sum(_cpu(lambda b=b, c=c: emergency_stop(consist, speed, b.params, c.params))
                        for b in band.brake for c in band.coupler)
            best_sum = min(best_sum, total)
        print(f"| {name} | {band.size} | {best_band * 1e3:.0f} ms | {best_sum * 1e3:.0f} ms | "
              f"{best_band / best_sum:.3f} |")


if __name__ == "__main__":
    main()

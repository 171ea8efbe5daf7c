"""Stops, settling and holding as they come out: the numbers of docs/stops.md.

Run: ``python benchmarks/standstill_cases.py``. Prints, for scenario 6 and the holding cases of
the tests, the first standstill, the settled time, how far the vehicles rolled back after the
standstill (10 ms chunks, the largest backward travel of any vehicle in the next 30 s) and the
holding and runaway verdicts.
"""
from __future__ import annotations

import numpy as np

from ltd_brake_ros.inputs import Track, consist_from_mapping, get_scenario
from ltd_brake_ros.simulator import Commands, Simulator

WAGON = {"type": "Shimmns", "mass_t": 80.0}
UNBRAKED = {"type": "Shimmns", "mass_t": 80.0, "brake": {"type": "none"}}


def case(name: str, consist, speed_kmh: float, track: Track | None = None) -> None:
    sim = Simulator(consist, speed_kmh, track=track)
    snap = sim.advance(0.01, Commands(emergency=True))
    while sim.stop_time_s is None:
        snap = sim.advance(0.01)
    at_stop = snap.position_m.copy()
    low = at_stop.copy()
    while sim.time_s < sim.stop_time_s + 30.0 - 1e-9:
        low = np.minimum(low, sim.advance(0.01).position_m)
    back = at_stop - low
    table = sim.verdicts()
    settled = "not settled" if sim.settled_time_s is None else f"{sim.settled_time_s:.2f} s"
    print(f"| {name} | {speed_kmh:g} | {sim.stopping_distance_m:.1f} m | {sim.stop_time_s:.2f} s "
          f"| {settled} | {back.max() * 1e3:.1f} mm (vehicle {int(back.argmax())}) "
          f"| {table['standstill_holding'].status} | {table['runaway'].status} |")


def main() -> None:
    print("| train | V0 km/h | stopping distance | first standstill | settled from | largest "
          "roll-back in 30 s | holding | runaway |")
    print("|---|---|---|---|---|---|---|---|")
    sc = get_scenario(6)
    case("scenario 6: E402B + 32 Shimmns (50 t), level", sc.consist(), sc.speed_kmh)

    def train(wagons):
        return consist_from_mapping({"vehicles": [{"type": "E402B"}, *wagons]}, "case")
    grade = Track(gradient_permille=(-20.0,))
    for v in (2.0, 5.0, 10.0):
        case("E402B + 30 x 80 t, one unbraked, -20 per mille",
             train([WAGON] * 14 + [UNBRAKED] + [WAGON] * 15), v, grade)
    case("E402B + 30 x 80 t, five unbraked at the tail, -20 per mille",
         train([WAGON] * 25 + [UNBRAKED] * 5), 40.0, grade)


if __name__ == "__main__":
    main()

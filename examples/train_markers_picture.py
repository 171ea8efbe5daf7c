"""Draw the plant's markers (what RViz and Foxglove's 3D panel show) for a moment of a stop.

    python examples/train_markers_picture.py                     # docs/images/train_markers.png
    python examples/train_markers_picture.py --scenario 3 --time-s 4 --out markers.png

The same markers the node publishes on ``train/markers`` (:mod:`ltd_brake_ros.plant.markers`),
drawn with matplotlib: the docs' picture of the 3D view is made with this script.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ltd_brake_ros.analysis.plots import render_markers
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.plant.markers import train_markers
from ltd_brake_ros.simulator import Commands, Simulator

DOCS_IMAGE = Path(__file__).resolve().parents[1] / "docs" / "images" / "train_markers.png"


def main(argv: list[str] | None = None) -> Path:
    """Simulate an emergency stop up to ``--time-s`` and draw its markers; the PNG's path."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=int, default=6, help="run of Tables 1-2 (default 6)")
    ap.add_argument("--time-s", type=float, default=2.6,
                    help="time after the emergency command [s] (default 2.6: the brakes "
                         "applying along the train)")
    ap.add_argument("--out", type=Path, default=DOCS_IMAGE, help="PNG file")
    args = ap.parse_args(argv)
    sc = get_scenario(args.scenario)
    sim = Simulator(sc.consist(), sc.speed_kmh)
    snap = sim.advance(args.time_s, Commands(emergency=True))
    lim = sim.limits
    specs = train_markers(snap.position_m, sim.length_m, snap.block_force_N,
                          sim.max_block_force_N, snap.coupler_force_N, lim.draft_strength_N,
                          lim.buff_strength_N, [v.name for v in sim.consist.vehicles])
    return render_markers(specs, args.out, (
        f"{sim.consist.name}: emergency stop from {sc.speed_kmh:g} km/h, t = {snap.time_s:.1f} "
        "s; boxes orange as brakes apply, couplers red in draft, blue in buff"))


if __name__ == "__main__":
    print(main())

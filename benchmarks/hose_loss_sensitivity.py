"""Sensitivity of the brake-pipe model to the hose loss per vehicle junction, one Markdown table.

For a low, the sourced and a high concentrated loss coefficient K (the model's
``hose_loss_coefficient``; every other parameter as in ``brake_params/uic_brake_pipe.yaml``):
the emergency propagation speed on 1 000 m, the equivalent build-up time T_e of a P train of
700 m and 1 500 m (as ETCS times it), the length trend T_e(700 m) - T_e(500 m) and the paper's
Tables 1-2 stopping distances (worst and mean error against LTDPoliTo).

The sourced value is TrainDy's convention (two losses of 3 per junction at 35.6 mm bore,
Colebrook wall friction with 0.046 mm roughness) referred to this model's 32 mm bore:
6 (32 / 35.6)^4 = 3.92.

Usage::

    python benchmarks/hose_loss_sensitivity.py                 # K = 0, 3.92, 10 (about 3 min)
    python benchmarks/hose_loss_sensitivity.py --k 2 3.92 6
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from ltd_brake_ros.inputs import load_brake_params
from ltd_brake_ros.studies import brake_pipe_validation as bpv


def row(k: float, jobs: int) -> str:
    """One table row for hose loss ``k``."""
    preset = load_brake_params(bpv.PRESET)
    pipe = dataclasses.replace(bpv.pipe_params(preset), hose_loss_coefficient=k)
    speed = bpv.propagation_speed_m_s(1000.0, pipe)
    te = {length: bpv.equivalent_build_up_s(length, "P", pipe) for length in (500, 700, 1500)}
    rows = bpv.paper_stops(dataclasses.replace(preset, pneumatic=pipe), workers=jobs)
    err = np.array([r.distance_error_percent for r in rows])
    worst = err[np.argmax(np.abs(err))]
    return (f"| {k:g} | {speed:.0f} | {te[700]:.2f} | {te[1500]:.2f} | "
            f"{te[700] - te[500]:.2f} | {worst:+.2f} % | {np.mean(np.abs(err)):.2f} % |")


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=float, nargs="+", default=[0.0, 3.92, 10.0],
                    help="hose loss coefficients (default: 0, the sourced 3.92, 10)")
    ap.add_argument("--jobs", type=int, default=2, help="processes for Tables 1-2")
    args = ap.parse_args()
    print("| K per junction | propagation, 1 000 m [m/s] | T_e 700 m, P [s] | "
          "T_e 1 500 m, P [s] | T_e(700) - T_e(500) [s] | Tables 1-2 distance, worst | "
          "mean abs. |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for k in args.k:
        print(row(k, args.jobs), flush=True)


if __name__ == "__main__":
    main()

"""Can the brake-pipe model meet run 12's peak draft and the length trend together? A search.

Samples sets of the brake-pipe model's fitted parameters at random (uniform, or uniform in the
logarithm for areas, volumes, rates and time constants, over the ranges below; every other
value as in ``brake_params/uic_brake_pipe.yaml``, the block force threshold included) and
measures for each:

* the emergency propagation speed on 500 m with acceleration chambers (UIC 540: 250-280 m/s);
* the length trend of the build-up time in P, T_e(700 m) - T_e(500 m) (UIC 544-1's length
  correction: 2.2 +/- 1.0 s);
* run 12 of Tables 1-2 (E402B + 32 Shimmns of 50 t from 50 km/h): its peak draft and coupler
  against the paper's 195 kN at coupler 5 (the targets of the paper's own model: within
  +/-10 % and +/-2 couplers).

It prints how many sets meet each of these and the best of them. Usage::

    python benchmarks/pipe_draft_search.py --samples 300 --seed 1 --jobs 2   # about 10 min
"""
from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from ltd_brake_ros.inputs import get_scenario, load_brake_params, load_consist
from ltd_brake_ros.studies import brake_pipe_validation as bpv
from ltd_brake_ros.studies.parallel import map_jobs
from ltd_brake_ros.studies.runs import emergency_stop

BAR = 1e5
#: Fitted parameters searched: field, lower and upper bound (model units), logarithmic.
SPACE = (
    ("valve_delay_s", 0.8, 1.6, False),
    ("inshot_pressure_Pa", 0.8 * BAR, 2.0 * BAR, False),
    ("inshot_rate_Pa_s", 2.0 * BAR, 15.0 * BAR, True),
    ("application_stroke_s", 0.0, 0.6, False),
    ("fill_rate_P_Pa_s", 0.6 * BAR, 1.2 * BAR, False),
    ("lap_time_constant_P_s", 0.2, 1.0, True),
    ("accelerator_threshold_Pa", 0.15 * BAR, 0.4 * BAR, False),
    ("accelerator_time_constant_s", 0.1, 1.0, True),
    ("accelerator_area_m2", 1e-4, 4e-4, True),
    ("accelerator_chamber_volume_m3", 5e-4, 6e-3, True),
    ("branch_volume_m3", 1e-3, 8e-3, True),
    ("quick_service_volume_m3", 2e-4, 2e-3, True),
    ("quick_service_area_m2", 5e-6, 3e-5, True),
    ("emergency_area_m2", 1.7e-4, 8e-4, True),
)
#: Cylinder pressure held during an application stroke of the samples that have one [Pa].
STROKE_PA = 0.25 * BAR
#: Windows: propagation [m/s], length trend [s]; run 12's paper peak draft [kN] and coupler
#: with the tolerances of the paper's own model.
PROPAGATION = (250.0, 280.0)
TREND = (1.2, 3.2)
RUN12 = (195.0, 5, 0.10, 2)


def sample(rng: np.random.Generator) -> dict:
    """One random set of the fitted parameters (model field names and units)."""
    out = {}
    for name, lo, hi, log in SPACE:
        u = rng.random()
        out[name] = (math.exp(math.log(lo) + u * math.log(hi / lo)) if log
                     else lo + u * (hi - lo))
    out["application_stroke_Pa"] = STROKE_PA if out["application_stroke_s"] > 0.05 else 0.0
    if out["application_stroke_Pa"] == 0.0:
        out["application_stroke_s"] = 0.0
    return out


def measure(fields: dict) -> dict:
    """Propagation, length trend and run 12's peak draft of one set."""
    preset = load_brake_params(bpv.PRESET)
    pipe = dataclasses.replace(bpv.pipe_params(preset), **fields)
    scenario = get_scenario(12)
    stop = emergency_stop(load_consist(scenario.consist_file), scenario.speed_kmh,
                          dataclasses.replace(preset, pneumatic=pipe))
    te500, te700 = (bpv.equivalent_build_up_s(length, "P", pipe) for length in (500.0, 700.0))
    return {"propagation_m_s": bpv.propagation_speed_m_s(500.0, pipe),
            "trend_s": te700 - te500, "draft_kN": stop.peak_draft_kN,
            "draft_coupler": stop.peak_draft_coupler}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    sets = [sample(rng) for _ in range(args.samples)]
    results = map_jobs(measure, sets, args.jobs)
    kn, coupler, tol, shift = RUN12

    def prop_ok(r):
        return PROPAGATION[0] <= r["propagation_m_s"] <= PROPAGATION[1]

    def trend_ok(r):
        return TREND[0] <= r["trend_s"] <= TREND[1]

    def draft_ok(r):
        return (abs(r["draft_kN"] / kn - 1.0) <= tol
                and abs(r["draft_coupler"] - coupler) <= shift)

    prop = [r for r in results if prop_ok(r)]
    both = [r for r in prop if trend_ok(r)]
    draft = [r for r in prop if draft_ok(r)]
    print(f"{len(results)} random sets of {len(SPACE)} fitted parameters (seed {args.seed})")
    print(f"propagation {PROPAGATION[0]:g}-{PROPAGATION[1]:g} m/s on 500 m: {len(prop)}")
    print(f"  and length trend {TREND[0]:g}-{TREND[1]:g} s: {len(both)}; their run-12 peak "
          f"draft at couplers {sorted({r['draft_coupler'] for r in both})}, at most "
          f"{max((r['draft_kN'] for r in both), default=float('nan')):.0f} kN; within "
          f"+/-{100 * tol:g} % of {kn:g} kN at coupler {coupler} +/-{shift}: "
          f"{sum(draft_ok(r) for r in both)}")
    print(f"  and run 12's peak draft within +/-{100 * tol:g} % at coupler {coupler} "
          f"+/-{shift}: {len(draft)}; their length trend at most "
          f"{max((r['trend_s'] for r in draft), default=float('nan')):.2f} s")
    for title, rows, key in (("with the length trend, by run 12's peak draft", both,
                              lambda r: -r["draft_kN"]),
                             ("with run 12's peak draft, by length trend", draft,
                              lambda r: -r["trend_s"])):
        print(f"\nbest sets meeting the propagation {title}")
        print("| propagation m/s | trend s | run 12 draft kN@coupler |\n|---|---|---|")
        for r in sorted(rows, key=key)[:5]:
            print(f"| {r['propagation_m_s']:.0f} | {r['trend_s']:.2f} | "
                  f"{r['draft_kN']:.0f}@{r['draft_coupler']} |")

if __name__ == "__main__":
    main()

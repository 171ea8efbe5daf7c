"""Coverage of the campaign report's 95 % intervals, measured on samples of known quantiles.

For each cell (tails, runs n, level q) the benchmark draws ``--reps`` campaigns of n runs
from a distribution whose quantiles are known, computes every interval the report gives
with the report's own functions (:mod:`ltd_brake_ros.analysis.campaign_intervals`, the
Wilson interval of an exceedance) and counts how often it holds the true value:

* ``quantile``: the interval of the level-q quantile (in the KPI's worse direction, here the
  upper tail);
* ``exceedance``: the Wilson interval of the share of runs beyond the true quantile (1 - q);
* ``difference`` and ``worsening``, ``paired`` and ``independent``: the family's quantile
  minus the reference's, and the relative worsening (ratio less 1) of the relative approach.
  The reference draws X, the family 1.03 X' (3 % worse at every level); paired, X and X' are
  the same trains (a Gaussian copula of correlation 0.9, as one parameter changed on the
  same trains), independent, two separate samples.

Light tails: normal, mean 100, sd 15. Heavy tails: Pareto (Lomax) of tail index 3, 100 (1 +
Lomax(3)), whose q0.99 lies 4.6 scale units out. Coverage is printed with its Monte-Carlo
standard error sqrt(c (1 - c) / reps) and judged against 93-97 %: ``ok`` when the coverage
lies in it within two standard errors. Where the report gives no interval (fewer than 20 runs
with a value beyond q, ``MIN_TAIL``), the cell says so.

    ./dev.sh run python benchmarks/bench_interval_coverage.py [--reps 2000] [--seed 0]

One to two minutes with 2000 replications a cell (one core; 63 s and 94 s in two runs on a shared machine).
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.stats import lomax, norm

from ltd_brake_ros.analysis.campaign_intervals import (MIN_TAIL, TOO_FEW, compare_quantiles,
                                                       enough_runs, quantile_interval)
from ltd_brake_ros.analysis.campaign_report import _wilson

#: Runs and levels of the cells.
SIZES = (200, 500, 1000, 2000)
LEVELS = (0.5, 0.9, 0.99)
#: The family is this much worse than the reference at every level.
SCALE = 1.03
#: Correlation of the Gaussian copula of paired runs.
RHO = 0.9
#: Tails: name -> inverse distribution function.
TAILS = {
    "light": lambda u: norm.ppf(u, 100.0, 15.0),
    "heavy": lambda u: 100.0 * (1.0 + lomax.ppf(u, 3.0)),
}
CONFIDENCE = 0.95
#: Acceptable coverage of a 95 % interval.
LOW, HIGH = 0.93, 0.97


def _cell(ppf, n: int, q: float, reps: int, rng) -> dict:
    """Hits and counts of every interval of one cell."""
    truth_ref = ppf(q)
    truth = {"difference": SCALE * truth_ref - truth_ref, "worsening": SCALE - 1.0}
    hits = {k: 0 for k in ("quantile", "exceedance", "difference paired",
                           "worsening paired", "difference independent",
                           "worsening independent")}
    given = dict.fromkeys(hits, 0)
    z = norm.ppf(0.5 + CONFIDENCE / 2.0)
    for _ in range(reps):
        z1 = rng.standard_normal(n)
        z2 = RHO * z1 + math.sqrt(1.0 - RHO * RHO) * rng.standard_normal(n)
        ref = ppf(norm.cdf(z1))
        paired = SCALE * ppf(norm.cdf(z2))
        independent = SCALE * ppf(rng.random(n))
        _, lo, hi = quantile_interval(ref, q, CONFIDENCE)
        if math.isfinite(lo):
            given["quantile"] += 1
            hits["quantile"] += lo <= truth_ref <= hi
        k = int((ref > truth_ref).sum())
        wlo, whi = _wilson(k, n, z)
        given["exceedance"] += 1
        hits["exceedance"] += wlo <= 1.0 - q <= whi
        for mode, fam in (("paired", paired), ("independent", independent)):
            c = compare_quantiles(fam, ref, q, CONFIDENCE, paired=mode == "paired")
            for what, (est, lo, hi) in (("difference", c["difference"]),
                                        ("worsening", (c["ratio"][0] - 1.0,
                                                       c["ratio"][1] - 1.0,
                                                       c["ratio"][2] - 1.0))):
                if math.isfinite(lo):
                    given[f"{what} {mode}"] += 1
                    hits[f"{what} {mode}"] += lo <= truth[what] <= hi
    return {k: (hits[k], given[k]) for k in hits}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=2000, help="replications a cell (>= 1000)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    print(f"coverage of 95 % intervals, {args.reps} replications a cell; ok: within "
          f"{100 * LOW:.0f}-{100 * HIGH:.0f} % by two Monte-Carlo standard errors; no "
          f"interval below {MIN_TAIL} runs beyond q")
    print(f"{'tails':<6} {'n':>5} {'q':>5}  {'interval':<23} {'coverage':>9} {'mc s.e.':>8}  "
          "judged")
    out_of_range = 0
    for tail, ppf in TAILS.items():
        for n in SIZES:
            for q in LEVELS:
                cell = _cell(ppf, n, q, args.reps, rng)
                for name, (hit, of) in cell.items():
                    if not of or (name != "exceedance" and not enough_runs(n, q)):
                        print(f"{tail:<6} {n:>5} {q:>5}  {name:<23} {TOO_FEW}")
                        continue
                    c = hit / of
                    se = math.sqrt(max(c * (1.0 - c), 1e-12) / of)
                    ok = c + 2 * se >= LOW and c - 2 * se <= HIGH
                    out_of_range += not ok
                    print(f"{tail:<6} {n:>5} {q:>5}  {name:<23} {100 * c:8.1f} % "
                          f"{100 * se:6.2f} %  {'ok' if ok else 'OUT OF 93-97 %'}"
                          + (f" ({of} of {args.reps} with an interval)" if of < args.reps
                             else ""))
    print(f"{out_of_range} interval(s) out of {100 * LOW:.0f}-{100 * HIGH:.0f} %; "
          f"{time.perf_counter() - start:.0f} s")
    return 1 if out_of_range else 0


if __name__ == "__main__":
    raise SystemExit(main())

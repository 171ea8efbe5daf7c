"""The intervals of a campaign report: the rule that gives them, the order statistics they lie
between, paired and independent differences and ratios (the measured coverage over many
cells is the benchmark ``benchmarks/bench_interval_coverage.py``)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import betainc
from scipy.stats import binom

from ltd_brake_ros.analysis.campaign_intervals import (MIN_TAIL, compare_quantiles,
                                                       difference_interval, enough_runs,
                                                       fractional_ranks, quantile_interval,
                                                       ratio_interval, standard_error)


@pytest.mark.parametrize("n, q, given", [
    (2000, 0.99, True), (1999, 0.99, False), (500, 0.9, True),
    (200, 0.9, True), (199, 0.9, False), (40, 0.5, True), (39, 0.5, False), (2000, 0.01, True)])
def test_an_interval_needs_twenty_runs_on_each_side_of_the_quantile(n, q, given):
    assert MIN_TAIL == 20
    assert enough_runs(n, q) is given
    x = np.linspace(0.0, 1.0, n)
    _, lo, hi = quantile_interval(x, q)
    assert math.isfinite(lo) is given and math.isfinite(hi) is given


@pytest.mark.parametrize("n, q", [(200, 0.9), (500, 0.9), (2000, 0.99), (40, 0.5)])
def test_the_ends_are_the_fractional_order_statistics_of_the_confidence(n, q):
    lo, hi = fractional_ranks(n, q, 0.95)
    # P(X_(t) <= quantile) = I_q(t, n - t + 1): 97.5 % at the lower end, 2.5 % at the upper
    assert betainc(lo, n - lo + 1, q) == pytest.approx(0.975, abs=1e-7)
    assert betainc(hi, n - hi + 1, q) == pytest.approx(0.025, abs=1e-7)
    # at whole ranks it is the binomial probability of at least t values below the quantile
    t = math.ceil(lo)
    assert betainc(t, n - t + 1, q) == pytest.approx(1 - binom.cdf(t - 1, n, q), abs=1e-12)
    # the ends interpolate between the order statistics around those ranks
    x = np.sort(np.random.default_rng(0).random(n))
    _, a, b = quantile_interval(x, q)
    assert x[math.floor(lo) - 1] <= a <= x[math.floor(lo)]
    assert x[math.floor(hi) - 1] <= b <= x[math.floor(hi)]


def test_a_quantile_interval_covers_as_it_claims_on_a_small_case():
    # 400 samples of 200 uniform values, q0.9 (true value 0.9): 95 % coverage, within three
    # binomial standard errors of 400 trials (3.3 points)
    rng = np.random.default_rng(3)
    hits = sum(lo <= 0.9 <= hi for _, lo, hi in (quantile_interval(rng.random(200), 0.9)
                                                 for _ in range(400)))
    assert abs(hits / 400 - 0.95) <= 3 * math.sqrt(0.95 * 0.05 / 400)


def test_runs_without_a_value_are_left_out():
    x = np.r_[np.arange(1.0, 201.0), np.full(50, np.nan)]
    assert quantile_interval(x, 0.5) == quantile_interval(x[:200], 0.5)
    assert all(math.isnan(v) for v in quantile_interval(np.full(5, np.nan), 0.5))


def test_the_same_runs_compared_with_themselves_differ_by_exactly_nothing():
    x = np.random.default_rng(1).normal(100.0, 15.0, 500)
    c = compare_quantiles(x, x.copy(), 0.9, paired=True)
    assert c["correlation"] == 1.0
    assert c["difference"] == (0.0, 0.0, 0.0) and c["ratio"] == (1.0, 1.0, 1.0)


def test_pairing_narrows_the_interval_of_a_difference_around_its_estimate():
    rng = np.random.default_rng(2)
    ref = rng.normal(100.0, 15.0, 1000)
    fam = 1.03 * (ref + rng.normal(0.0, 3.0, 1000))  # the same trains, 3 % worse
    paired = compare_quantiles(fam, ref, 0.9, paired=True)
    alone = compare_quantiles(fam, ref, 0.9)
    assert 0.7 < paired["correlation"] <= 1.0 and alone["correlation"] == 0.0
    d, lo, hi = paired["difference"]
    assert hi - d == pytest.approx(d - lo)  # centred: the estimate is never at an edge
    assert hi - lo < 0.7 * (alone["difference"][2] - alone["difference"][1])
    r, rlo, rhi = paired["ratio"]
    assert rlo < r < rhi and rlo < 1.03 < rhi


def test_difference_and_ratio_of_known_standard_errors():
    z = 1.959963984540054
    lo, hi = difference_interval(10.0, 1.0, 4.0, 1.0, r=0.5)  # sd of the difference 1
    assert (lo, hi) == pytest.approx((6.0 - z, 6.0 + z))
    assert standard_error(6.0 - z, 6.0 + z) == pytest.approx(1.0)
    # Fieller: the bounds psi solve (105 - 100 psi)^2 = z^2 (4 - 7.2 psi + 4 psi^2)
    for psi in ratio_interval(105.0, 2.0, 100.0, 2.0, r=0.9):
        assert (105 - 100 * psi) ** 2 == pytest.approx(z * z * (4 - 7.2 * psi + 4 * psi ** 2))
    # a reference quantile not told apart from 0: the ratio is unbounded, no interval
    assert all(math.isnan(v) for v in ratio_interval(5.0, 1.0, 1.0, 1.0))
    assert all(math.isnan(v) for v in difference_interval(1.0, math.nan, 0.0, 1.0))

"""Confidence intervals of a campaign's quantiles and of their differences and ratios.

A quantile's interval lies between two fractional order statistics (Hutson 1999): the order
statistic of rank t, for a whole t, lies at or below the level-q quantile with probability
``I_q(t, n - t + 1)`` whatever the (continuous) distribution of the values, the
distribution-free interval of Hahn and Meeker (1991, ch. 5); Hutson extends the rank to real
values, interpolating linearly between order statistics, so that the interval's coverage is
the confidence itself rather than the next value above it that two whole ranks reach (which
swings up to 97.4 % for a 95 % interval).

The difference of two quantiles (family minus reference) and their ratio take each
quantile's standard error from its interval, Woodruff's ``(high - low) / (2 z)`` (Woodruff
1952; Sitter and Wu 2001), and for runs that are the same trains in both families (paired)
the correlation of the two estimates: by Bahadur's representation (Bahadur 1966) a sample
quantile moves with the share of values at or below the true quantile, so the two estimates
correlate as the indicators "at or below the quantile" of the two families do over the
common runs. The difference's interval is then ``d -+ z sqrt(s1^2 + s2^2 - 2 r s1 s2)``,
centred on the estimate; the ratio's is Fieller's (Fieller 1954). The relative worsening of
the relative approach is the ratio less 1, signed in the KPI's worse direction.

Intervals are given only where enough runs lie on both sides of the quantile:
``n min(q, 1 - q) >= MIN_TAIL`` (20) runs with a value. With fewer, the coverage of these
intervals is not measured to hold (a fractional order statistic then interpolates between
the last few runs of the tail); the report says "too few runs beyond q for an interval" and a
verdict resting on it is inconclusive. The coverage of every interval is measured by
``benchmarks/bench_interval_coverage.py`` (light and heavy tails, n = 200 to 2000, q0.5,
q0.9 and q0.99, paired and independent): 93-97 % for 95 % intervals in every cell where one
is given.

References
----------
Hahn, G. J. and Meeker, W. Q. (1991). *Statistical Intervals: A Guide for Practitioners*.
Wiley, ch. 5 (distribution-free intervals for a quantile).
Hutson, A. D. (1999). Calculating nonparametric confidence intervals for quantiles using
fractional order statistics. *Journal of Applied Statistics* 26(3), 343-353.
Woodruff, R. S. (1952). Confidence intervals for medians and other position measures.
*Journal of the American Statistical Association* 47(260), 635-646.
Sitter, R. R. and Wu, C. (2001). A note on Woodruff confidence intervals for quantiles.
*Statistics & Probability Letters* 52(4), 353-358.
Bahadur, R. R. (1966). A note on quantiles in large samples. *Annals of Mathematical
Statistics* 37(3), 577-580.
Fieller, E. C. (1954). Some problems in interval estimation. *Journal of the Royal
Statistical Society B* 16(2), 175-185.
"""
from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["MIN_TAIL", "TOO_FEW", "difference_interval", "enough_runs", "fractional_ranks",
           "compare_quantiles", "quantile_correlation", "quantile_interval", "ratio_interval",
           "standard_error"]

#: Runs with a value needed on each side of a quantile for an interval: n min(q, 1 - q).
MIN_TAIL = 20
#: What a report says instead of an interval with fewer.
TOO_FEW = "too few runs beyond q for an interval"

_NAN2 = (math.nan, math.nan)


def enough_runs(n: int, q: float) -> bool:
    """Whether ``n`` values hold enough runs on both sides of level ``q`` for an interval.

    Parameters
    ----------
    n : int
        Values (runs with a value).
    q : float
        Level of the quantile, in (0, 1).

    Returns
    -------
    bool
        ``n min(q, 1 - q) >= MIN_TAIL`` (a small tolerance for the float product).

    Examples
    --------
    >>> enough_runs(2000, 0.99), enough_runs(1000, 0.99), enough_runs(500, 0.9)
    (True, False, True)
    """
    return n * min(q, 1.0 - q) >= MIN_TAIL - 1e-9


@functools.lru_cache(maxsize=512)
def fractional_ranks(n: int, q: float, confidence: float) -> tuple[float, float] | None:
    """The fractional order statistics (1-based ranks) whose interval holds the level-``q``
    quantile of ``n`` values with probability ``confidence`` (Hutson 1999).

    The order statistic of rank t, for a whole t, lies at or below the quantile with
    probability ``I_q(t, n - t + 1)`` (the regularized incomplete beta function; the binomial
    probability of at least t values below); Hutson extends it to a real t, between order
    statistics interpolated linearly. The lower end is the rank at which that probability is
    ``(1 + confidence) / 2``, the upper end the rank at which it is ``(1 - confidence) / 2``.

    Parameters
    ----------
    n : int
        Values.
    q : float
        Level, in (0, 1).
    confidence : float
        Two-sided confidence, in (0, 1).

    Returns
    -------
    (t_low, t_high) or None
        None when an end would lie outside the sample (rank below 1 or above n).

    Examples
    --------
    >>> lo, hi = fractional_ranks(2000, 0.99, 0.95)
    >>> 1970 < lo < 1975 < 1985 < hi < 1990
    True
    """
    from scipy.optimize import brentq
    from scipy.special import betainc

    def below(t: float) -> float:  # P(X_(t) <= the quantile)
        return float(betainc(t, n - t + 1.0, q))

    a = (1.0 - confidence) / 2.0
    if below(1.0) < 1.0 - a or below(float(n)) > a:
        return None
    t_low = brentq(lambda t: below(t) - (1.0 - a), 1.0, float(n), xtol=1e-9)
    t_high = brentq(lambda t: below(t) - a, 1.0, float(n), xtol=1e-9)
    return t_low, t_high


def _at_rank(x_sorted: np.ndarray, t: float) -> float:
    """The sorted values at real rank t (1-based), interpolated linearly."""
    i = min(int(math.floor(t)), x_sorted.size - 1)
    return float(x_sorted[i - 1] + (t - i) * (x_sorted[i] - x_sorted[i - 1]))


def quantile_interval(x, q: float, confidence: float = 0.95
                      ) -> tuple[float, float, float]:
    """The level-``q`` quantile of the finite values of ``x`` and its distribution-free
    interval.

    Parameters
    ----------
    x : array_like
        Values; NaN (a run without a value) is left out.
    q : float
        Level of the quantile of ``x`` as it is (whatever the KPI's worse direction).
    confidence : float, optional
        Two-sided confidence.

    Returns
    -------
    estimate, low, high : float
        In the unit of ``x``; the estimate interpolates linearly between order statistics
        (numpy's default, type 7 of Hyndman and Fan 1996); ``low`` and ``high`` are NaN when
        :func:`enough_runs` says no (NaN everything without a value).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(1).normal(100.0, 10.0, 2000)
    >>> est, lo, hi = quantile_interval(x, 0.99)
    >>> bool(lo < est < hi)
    True
    >>> quantile_interval(x[:500], 0.99)[1:]
    (nan, nan)
    """
    x = np.asarray(x, float)
    x = np.sort(x[np.isfinite(x)])
    n = x.size
    if not n:
        return (math.nan, *_NAN2)
    est = float(np.quantile(x, q))
    ranks = fractional_ranks(n, float(q), float(confidence)) if enough_runs(n, q) else None
    if ranks is None:
        return (est, *_NAN2)
    return est, _at_rank(x, ranks[0]), _at_rank(x, ranks[1])


def quantile_correlation(x, y, qx: float, qy: float, level: float) -> float:
    """Correlation of the level-``level`` sample quantiles of two paired samples.

    By Bahadur's representation, a sample quantile moves with the share of values at or below
    the true quantile, so two quantiles of paired runs correlate as the indicators
    ``x <= qx`` and ``y <= qy`` do (their phi coefficient), ``qx`` and ``qy`` the estimates.

    Parameters
    ----------
    x, y : array_like
        Values of the same runs (NaN where a run has none; such runs are left out).
    qx, qy : float
        The quantile estimates.
    level : float
        Their level (the indicators' shares are taken from the runs themselves).

    Returns
    -------
    float
        In [-1, 1]; 0 without a run that both have.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(2).normal(size=1000)
    >>> round(quantile_correlation(x, x, np.quantile(x, 0.9), np.quantile(x, 0.9), 0.9), 2)
    1.0
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    both = np.isfinite(x) & np.isfinite(y)
    if not both.any():
        return 0.0
    a, b = x[both] <= qx, y[both] <= qy
    pa, pb = float(a.mean()), float(b.mean())
    spread = math.sqrt((pa - pa * pa) * (pb - pb * pb))  # as the numerator rounds: 1 for x, x
    if spread == 0.0:
        return 0.0
    return float(np.clip((float(np.mean(a & b)) - pa * pb) / spread, -1.0, 1.0))


def _z(confidence: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(0.5 + confidence / 2.0))


def standard_error(low: float, high: float, confidence: float = 0.95) -> float:
    """The standard error of a quantile estimate from its interval, Woodruff's
    ``(high - low) / (2 z)`` (Woodruff 1952; Sitter and Wu 2001).

    Parameters
    ----------
    low, high : float
        The quantile's interval (:func:`quantile_interval`).
    confidence : float, optional
        Its two-sided confidence.

    Returns
    -------
    float
        In the unit of the quantile; NaN without an interval.

    Examples
    --------
    >>> round(standard_error(96.08, 103.92), 3)
    2.0
    """
    return (high - low) / (2.0 * _z(confidence))


def difference_interval(e1: float, s1: float, e2: float, s2: float, r: float = 0.0,
                        confidence: float = 0.95) -> tuple[float, float]:
    """Interval of ``theta1 - theta2`` from the estimates, their standard errors and their
    correlation: ``e1 - e2 -+ z sqrt(s1^2 + s2^2 - 2 r s1 s2)``.

    Parameters
    ----------
    e1, s1 : float
        Estimate of theta1 and its standard error (:func:`standard_error`).
    e2, s2 : float
        The same of theta2.
    r : float, optional
        Correlation of the two estimates (0: independent samples; paired runs:
        :func:`quantile_correlation`).
    confidence : float, optional
        Two-sided confidence.

    Returns
    -------
    low, high : float
        NaN when a standard error is missing.

    Examples
    --------
    >>> difference_interval(10.0, 1.0, 4.0, 1.0, r=0.5)
    (4.04..., 7.95...)
    """
    if not all(math.isfinite(v) for v in (e1, s1, e2, s2)):
        return _NAN2
    h = _z(confidence) * math.sqrt(max(s1 * s1 + s2 * s2 - 2.0 * r * s1 * s2, 0.0))
    return e1 - e2 - h, e1 - e2 + h


def ratio_interval(e1: float, s1: float, e2: float, s2: float, r: float = 0.0,
                   confidence: float = 0.95) -> tuple[float, float]:
    """Fieller's interval of ``theta1 / theta2``: the ratios psi for which
    ``theta1 - psi theta2 = 0`` is not rejected, ``(e1 - psi e2)^2 <= z^2 (s1^2 - 2 psi r s1 s2
    + psi^2 s2^2)`` (Fieller 1954).

    Parameters
    ----------
    e1, s1 : float
        Estimate of theta1 and its standard error.
    e2, s2 : float
        The same of theta2.
    r : float, optional
        Correlation of the two estimates.
    confidence : float, optional
        Two-sided confidence.

    Returns
    -------
    low, high : float
        NaN when a standard error is missing or theta2 is not told apart from 0 at this
        confidence (``|e2| <= z s2``: the set of ratios is then unbounded).

    Examples
    --------
    >>> ratio_interval(105.0, 2.0, 100.0, 2.0, r=0.9)
    (1.03..., 1.06...)
    """
    if not all(math.isfinite(v) for v in (e1, s1, e2, s2)):
        return _NAN2
    z2 = _z(confidence) ** 2
    a = e2 * e2 - z2 * s2 * s2  # a psi^2 - 2 b psi + c <= 0
    b = e1 * e2 - z2 * r * s1 * s2
    c = e1 * e1 - z2 * s1 * s1
    disc = b * b - a * c
    if a <= 0.0 or disc < 0.0:
        return _NAN2
    root = math.sqrt(disc)
    return (b - root) / a, (b + root) / a


def compare_quantiles(x, y, level: float, confidence: float = 0.95, paired: bool = False
                      ) -> dict:
    """The level-``level`` quantiles of two samples, their difference and their ratio, each
    with its interval.

    Parameters
    ----------
    x, y : array_like
        The family's values and the reference's (NaN: a run without a value, left out).
        Paired: the same runs in the same order.
    level : float
        Level of the quantiles of the values as they are, in (0, 1).
    confidence : float, optional
        Two-sided confidence of every interval.
    paired : bool, optional
        Run i of ``x`` and of ``y`` is the same train: the estimates' correlation counts.

    Returns
    -------
    dict
        ``family`` and ``reference``: (estimate, low, high); ``correlation`` (0 unpaired);
        ``difference``: (x's minus y's, low, high); ``ratio``: (x's over y's, low, high).
        An interval is (NaN, NaN) where :func:`enough_runs` says no for either sample.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(3)
    >>> ref = rng.normal(100.0, 15.0, 2000)
    >>> fam = 1.03 * (0.9 * (ref - 100.0) + 100.0 + rng.normal(0.0, 6.5, 2000))
    >>> c = compare_quantiles(fam, ref, 0.99, paired=True)
    >>> bool(c["difference"][1] < c["difference"][0] < c["difference"][2])
    True
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    fx = quantile_interval(x, level, confidence)
    fy = quantile_interval(y, level, confidence)
    sx, sy = (standard_error(f[1], f[2], confidence) for f in (fx, fy))
    r = quantile_correlation(x, y, fx[0], fy[0], level) if paired else 0.0
    ratio = fx[0] / fy[0] if fy[0] != 0.0 else math.nan
    return {"family": fx, "reference": fy, "correlation": r,
            "difference": (fx[0] - fy[0], *difference_interval(fx[0], sx, fy[0], sy, r,
                                                                confidence)),
            "ratio": (ratio, *ratio_interval(fx[0], sx, fy[0], sy, r, confidence))}

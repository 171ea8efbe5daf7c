"""The fit: bounded least squares, its statistics, held parameters and cross-validation."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ...inputs import BrakeParams, Consist, CouplerLUT, load_brake_params, load_coupler_lut
from .parameters import (BOUND_TOL, FitParameter, HOLD_CORRELATION, MAX_ABS_CORRELATION,
                         MAX_RELATIVE_CI, WRITE_DIGITS, _resolve)
from .targets import Target
from .evaluation import DistanceEvaluator


@dataclass(kw_only=True)
class FitOutcome:
    """What every fit reports about its parameters (values in each parameter's unit).

    Attributes
    ----------
    fit : list of FitParameter
        The parameters fitted in the end (without those held for identifiability).
    ci95 : ndarray
        Half-widths of the 95 % confidence intervals, NaN when not estimable.
    correlation : ndarray
        Correlation matrix of the fitted values.
    at_bound : list of str
        Names of the parameters that ended on a bound.
    warnings : list of str
        Identifiability and convergence warnings, in words.
    nfev : int
        Residual evaluations (each one stop per target), finite differences excluded.
    runs : int
        Emergency stops simulated in total.
    dof : int
        Degrees of freedom of the residual: observations minus parameters not held by a
        bound.
    converged : bool
        The optimiser met a tolerance (not the evaluation budget).
    message : str
        The optimiser's termination message.
    held : list of (FitParameter, str)
        Parameters asked for but held at their start values, and why.
    """

    fit: list
    ci95: np.ndarray
    correlation: np.ndarray
    at_bound: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    nfev: int = 0
    runs: int = 0
    dof: int = 0
    converged: bool = True
    message: str = ""
    held: list = field(default_factory=list)

    def value(self, p: FitParameter, which: str = "params") -> float:
        """Value of a fitted parameter in ``params`` or ``start``."""
        return float(getattr(getattr(self, which), p.field))


def _outcome(fit, out: "_Fit", stats: "_Stats", runs: int, held: list) -> dict:
    """The :class:`FitOutcome` fields of a fit, as keywords."""
    return dict(fit=list(fit), ci95=stats.ci95, correlation=stats.correlation,
                at_bound=stats.at_bound, warnings=stats.warnings, nfev=out.nfev, runs=runs,
                dof=stats.dof, converged=out.status > 0, message=out.message, held=held)


@dataclass(kw_only=True)
class Calibration(FitOutcome):
    """Outcome of :func:`calibrate`: a :class:`FitOutcome` and the distances.

    Attributes
    ----------
    targets : list of Target
    start : BrakeParams
        Start values (clipped into the bounds); the parameters not fitted keep them.
    params : BrakeParams
        Fitted values, rounded to :data:`WRITE_DIGITS` significant digits.
    before_m, after_m : ndarray
        Simulated stopping distances at the start and fitted values [m].
    cv_m : ndarray
        Leave-one-train-out distances: each target's train left out of the fit, the others
        refitted, the left-out stop simulated with those values [m] (NaN: not done).
    """

    targets: list
    start: BrakeParams
    params: BrakeParams
    before_m: np.ndarray
    after_m: np.ndarray
    cv_m: np.ndarray | None = None

    @property
    def reference_m(self) -> np.ndarray:
        """Reference distances of the targets [m]."""
        return np.array([t.distance_m for t in self.targets])

    @property
    def before_error_percent(self) -> np.ndarray:
        """Relative distance errors at the start values [%]."""
        return 100.0 * (self.before_m - self.reference_m) / self.reference_m

    @property
    def after_error_percent(self) -> np.ndarray:
        """Relative distance errors at the fitted values [%]."""
        return 100.0 * (self.after_m - self.reference_m) / self.reference_m

    @property
    def cv_error_percent(self) -> np.ndarray:
        """Leave-one-train-out distance errors [%] (NaN where not done)."""
        if self.cv_m is None:
            return np.full(len(self.targets), np.nan)
        return 100.0 * (self.cv_m - self.reference_m) / self.reference_m

def _round(x: float, digits: int = WRITE_DIGITS) -> float:
    return float(f"{x:.{digits}g}")


@dataclass
class _Fit:
    """What the fitting core returns (values in physical units)."""

    x: np.ndarray
    on_lower: np.ndarray
    on_upper: np.ndarray
    r_before: np.ndarray
    r_after: np.ndarray
    jac: np.ndarray
    nfev: int
    status: int
    message: str
    clipped: list


def _least_squares(fit: Sequence[FitParameter], given: np.ndarray, batch, *, max_nfev: int,
                   diff_step: float, stats_step: float, last_failure, progress=None,
                   label: str = "max |error|") -> _Fit:
    """Bounded least squares of a residual vector whose evaluation is a batch of runs.

    Parameters
    ----------
    fit : sequence of FitParameter
    given : ndarray
        Start values, physical units (clipped into the bounds).
    batch : callable
        List of value vectors (physical units) -> ndarray (len, m) of residuals; a row with
        NaN where a run failed.
    max_nfev, diff_step, stats_step
        As :func:`calibrate`.
    last_failure : callable
        () -> message of the last failed run.
    progress : tqdm.tqdm, optional
    label : str
        Postfix of the progress bar, followed by the largest residual.

    Returns
    -------
    _Fit
    """
    from scipy.optimize import least_squares

    from ...simulator import SimulationError

    lower = np.array([p.lower for p in fit])
    upper = np.array([p.upper for p in fit])
    scale = np.array([p.scale for p in fit])
    x0 = np.clip(given, lower, upper)
    clipped = [f"{p.name} = {g:g}{'' if p.unit == '-' else ' ' + p.unit}"
               for p, g, c in zip(fit, given, x0) if g != c]
    n = len(fit)
    cache: dict[bytes, np.ndarray] = {}
    counter = {"nfev": 0}

    def residuals(z) -> np.ndarray:
        key = np.asarray(z, float).tobytes()
        if key not in cache:
            cache[key] = batch([z * scale])[0]
            counter["nfev"] += 1
            if progress is not None and np.all(np.isfinite(cache[key])):
                progress.set_postfix_str(f"{label} {np.abs(cache[key]).max():.3g}")
        return cache[key]

    def jacobian(z) -> np.ndarray:
        r0 = residuals(z)
        # forward steps, backwards where a forward one would cross the upper bound
        h = diff_step * np.maximum(np.abs(z), 1.0)
        h = np.where(z + h > upper / scale, -h, h)
        steps = [(z + h[j] * np.eye(n)[j]) * scale for j in range(n)]
        d = batch(steps)  # all columns in one batch over the pool
        bad = ~np.all(np.isfinite(d), axis=1)
        if bad.any():  # a failed stop: step the other way, inside the bounds
            h = np.where(bad & (z - h >= lower / scale) & (z - h <= upper / scale), -h, h)
            d[bad] = batch([(z + h[j] * np.eye(n)[j]) * scale for j in range(n) if bad[j]])
        if not np.all(np.isfinite(d)):
            raise SimulationError("the finite-difference step failed: " + last_failure())
        return (d - r0).T / h

    r_before = residuals(x0 / scale)
    if not np.all(np.isfinite(r_before)):
        raise SimulationError("at the start values: " + last_failure())
    sol = least_squares(residuals, x0 / scale, jac=jacobian,
                        bounds=(lower / scale, upper / scale), method="trf",
                        x_scale=1.0, xtol=1e-7, ftol=1e-10, gtol=1e-10, max_nfev=max_nfev)
    x = np.clip(sol.x * scale, lower, upper)
    # the reflective steps approach a bound only asymptotically: a value left within
    # BOUND_TOL of the range from a bound is on it
    span = upper - lower
    on_lower = (sol.active_mask < 0) | (x - lower <= BOUND_TOL * span)
    on_upper = (sol.active_mask > 0) | (upper - x <= BOUND_TOL * span)
    x = np.where(on_lower, lower, np.where(on_upper, upper, x))
    x = np.array([_round(v) for v in x])
    r_after = batch([x])[0]
    if not np.all(np.isfinite(r_after)):
        raise SimulationError("at the fitted values: " + last_failure())
    jac = _statistics_jacobian(batch, x / scale, scale, r_after, lower / scale, upper / scale,
                               stats_step)
    jac = np.where(np.isfinite(jac), jac, sol.jac) / scale
    return _Fit(x, on_lower, on_upper, r_before, r_after, jac, counter["nfev"], int(sol.status),
                str(sol.message), clipped)


def _statistics_jacobian(batch, z, scale, r0, lo, hi, step) -> np.ndarray:
    """Second-order finite-difference Jacobian of the residuals in scaled units ``z``.

    Central differences where both neighbours are inside the bounds, one-sided three-point
    formulas on a bound; NaN columns where a stop failed.
    """
    n = len(z)
    h = step * np.maximum(np.abs(z), 1.0)
    plan = []
    for j in range(n):
        if z[j] - h[j] >= lo[j] and z[j] + h[j] <= hi[j]:
            plan.append(("central", (1.0, -1.0)))
        elif z[j] + 2 * h[j] <= hi[j]:
            plan.append(("forward", (1.0, 2.0)))
        else:
            plan.append(("backward", (-1.0, -2.0)))
    r = batch([(z + a * h[j] * np.eye(n)[j]) * scale for j, (_, offsets) in enumerate(plan)
               for a in offsets])
    jac = np.empty((len(r0), n))
    for j, (kind, _) in enumerate(plan):
        r1, r2 = r[2 * j], r[2 * j + 1]
        if kind == "central":
            jac[:, j] = (r1 - r2) / (2 * h[j])
        elif kind == "forward":
            jac[:, j] = (-3 * r0 + 4 * r1 - r2) / (2 * h[j])
        else:
            jac[:, j] = (3 * r0 - 4 * r1 + r2) / (2 * h[j])
    return jac


@dataclass
class _Stats:
    ci95: np.ndarray
    correlation: np.ndarray
    at_bound: list
    warnings: list
    dof: int


def _statistics(fit: Sequence[FitParameter], out: _Fit, failures: int, last_failure: str,
                max_nfev_hit: bool, observations: int | None = None) -> _Stats:
    """Confidence intervals, correlations and warnings of a fit.

    The correlations are those of every fitted parameter (a property of the sensitivities,
    bound or not); the confidence intervals are those of the free parameters, with the ones a
    bound holds fixed. ``observations`` counts the residuals that are measurements (default:
    all), not constraints that cost nothing inside their tolerance: the degrees of freedom
    are the observations minus the free parameters.
    """
    from scipy.stats import t as student_t

    x, jac, r = out.x, out.jac, out.r_after
    n = len(fit)
    m = len(r) if observations is None else observations
    free = ~(out.on_lower | out.on_upper)
    nf = int(free.sum())
    dof = m - nf
    jtj = jac.T @ jac
    singular = np.linalg.matrix_rank(jtj, tol=1e-12 * max(np.abs(jtj).max(), 1e-300)) < n
    inv = np.linalg.pinv(jtj)
    sd = np.sqrt(np.clip(np.diag(inv), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = inv / np.outer(sd, sd)
    corr[~np.isfinite(corr)] = np.nan
    ci95 = np.full(n, np.nan)
    if nf and dof > 0:
        jf = jac[:, free]
        sd_free = np.sqrt(np.clip(np.diag(np.linalg.pinv(jf.T @ jf)), 0.0, None))
        ci95[free] = student_t.ppf(0.975, dof) * math.sqrt(float(r @ r) / dof) * sd_free

    warnings: list[str] = []
    if out.clipped:
        warnings.append(f"start value outside the bounds, started from the bound: "
                        f"{', '.join(out.clipped)}")
    if failures:
        warnings.append(f"{failures} emergency stops failed to integrate at trial values; the "
                        f"optimiser rejected those points (last: {last_failure})")
    if max_nfev_hit:
        warnings.append(f"the fit stopped after {out.nfev} evaluations without converging "
                        f"({out.message}); raise --max-nfev")
    if singular:
        warnings.append("the targets do not determine every fitted parameter (singular "
                        "J^T J): add trains of other lengths or braked-weight percentages, or "
                        "fit fewer parameters")
    if nf and dof <= 0:
        warnings.append(f"{nf} free parameters for {m} targets: no degrees of freedom left, "
                        "confidence intervals cannot be estimated")
    at_bound = []
    for j, p in enumerate(fit):
        if not free[j]:
            side, bound = ("lower", p.lower) if out.on_lower[j] else ("upper", p.upper)
            at_bound.append(p.name)
            warnings.append(f"{p.name} ended on its {side} bound ({bound:g} {p.unit}): the "
                            "targets push it further, so the bound, not the data, sets its "
                            "value (no confidence interval)")
    for j, k in _correlated_pairs(corr):
        warnings.append(
            f"{fit[j].name} and {fit[k].name} are not separately identifiable from "
            f"these targets (correlation {corr[j, k]:+.3f}): the targets fix only a "
            f"combination of them; fix one, or add trains that tell them apart")
    for j, p in enumerate(fit):
        if np.isfinite(ci95[j]) and x[j] != 0 and ci95[j] > MAX_RELATIVE_CI * abs(x[j]):
            unit = "" if p.unit == "-" else f" {p.unit}"
            warnings.append(f"{p.name} is poorly determined: 95 % confidence interval "
                            f"+/-{ci95[j]:.3g}{unit} is {100 * ci95[j] / abs(x[j]):.0f} % of "
                            "its value")
    return _Stats(ci95, corr, at_bound, warnings, dof)


def _correlated_pairs(corr: np.ndarray, limit: float = MAX_ABS_CORRELATION
                      ) -> list[tuple[int, int]]:
    """Index pairs (j < k) whose correlation exceeds ``limit`` in magnitude, worst first."""
    n = corr.shape[0]
    pairs = [(j, k) for j in range(n) for k in range(j + 1, n)
             if np.isfinite(corr[j, k]) and abs(corr[j, k]) > limit]
    return sorted(pairs, key=lambda jk: -abs(corr[jk]))


def _identifiable_fit(fit: list, run, keep_correlated: bool):
    """Fit, and while two fitted parameters are not separately identifiable (correlation beyond
    :data:`HOLD_CORRELATION`) hold the one listed later at its start value and fit again.

    Parameters
    ----------
    fit : list of FitParameter
        In order of priority.
    run : callable
        list of FitParameter -> (_Fit, _Stats).
    keep_correlated : bool
        Fit once, whatever the correlations.

    Returns
    -------
    fit : list of FitParameter
        The parameters fitted in the end.
    out : _Fit
    stats : _Stats
    held : list of (FitParameter, str)
    """
    held: list = []
    while True:
        out, stats = run(fit)
        pairs = _correlated_pairs(stats.correlation, HOLD_CORRELATION)
        if keep_correlated or not pairs or len(fit) < 2:
            return fit, out, stats, held
        j, k = pairs[0]
        held.append((fit[k], f"not separately identifiable from {fit[j].name} (correlation "
                             f"{stats.correlation[j, k]:+.3f})"))
        fit = [p for i, p in enumerate(fit) if i != k]


def _train_groups(consists: Sequence[Consist]) -> list[list[int]]:
    """Indices of the targets grouped by train (the same consist file or name), in order."""
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(consists):
        groups.setdefault(c.source or c.name, []).append(i)
    return list(groups.values())


def _cross_validate(fit, x, groups, batch_of, *, max_nfev, diff_step, last_failure):
    """Leave-one-train-out: refit without each train, predict it.

    Parameters
    ----------
    fit : list of FitParameter
    x : ndarray
        The fitted values (start of every refit).
    groups : list of list of int
        Target indices of each train.
    batch_of : callable
        (target indices) -> batch function of those targets (see :func:`_least_squares`).

    Returns
    -------
    list of (list of int, ndarray)
        Each train's target indices and the values refitted without it.
    """
    out = []
    every = sorted(i for g in groups for i in g)
    for g in groups:
        rest = [i for i in every if i not in g]
        if not rest:
            continue
        try:
            refit = _least_squares(fit, x, batch_of(rest), max_nfev=max_nfev,
                                   diff_step=diff_step, stats_step=diff_step,
                                   last_failure=last_failure)
            out.append((g, refit.x))
        except Exception as exc:  # noqa: BLE001 - a failed refit leaves NaN, said in words
            from ...simulator import SimulationError

            if not isinstance(exc, SimulationError):
                raise
            out.append((g, None))
    return out


def _fit_targets(fit: list, given: dict, batch_of, m: int, consists: Sequence[Consist],
                 evaluator: DistanceEvaluator, *, max_nfev: int, diff_step: float,
                 stats_step: float, progress, keep_correlated: bool, cross_validate: bool,
                 label: str, observations: int | None = None):
    """The fit :func:`calibrate` and :func:`calibrate_couplers` share.

    Fits the targets' residuals (holding unidentifiable parameters unless
    ``keep_correlated``), computes the statistics, and with ``cross_validate`` refits with
    each train left out.

    Parameters
    ----------
    fit : list of FitParameter
    given : dict
        Start value of each parameter by short name (clipped into its bounds by the fit).
    batch_of : callable
        (target indices, fitted parameters) -> batch function (see :func:`_least_squares`).
    m : int
        Number of targets.
    consists : sequence of Consist
        The train of each target (left out together).
    evaluator : DistanceEvaluator
    max_nfev, diff_step, stats_step, progress, keep_correlated, cross_validate
        As :func:`calibrate`.
    label : str
        Progress-bar postfix.
    observations : int, optional
        As :func:`_statistics`.

    Returns
    -------
    fit : list of FitParameter
    out : _Fit
    stats : _Stats
    held : list of (FitParameter, str)
    refits : list of (list of int, ndarray or None)
        Each train's target indices and the values fitted without it.
    """
    failed_before = len(evaluator.failures)

    def last_failure() -> str:
        return evaluator.failures[-1] if evaluator.failures else ""

    def run(chosen: list):
        x0 = np.array([given[p.name] for p in chosen])
        out = _least_squares(chosen, x0, batch_of(list(range(m)), chosen), max_nfev=max_nfev,
                             diff_step=diff_step, stats_step=stats_step,
                             last_failure=last_failure, progress=progress, label=label)
        stats = _statistics(chosen, out, len(evaluator.failures) - failed_before,
                            last_failure(), not out.status > 0, observations=observations)
        return out, stats

    fit, out, stats, held = _identifiable_fit(list(fit), run, keep_correlated)
    refits = []
    if cross_validate:
        refits = _cross_validate(fit, out.x, _train_groups(consists),
                                 lambda rows: batch_of(rows, fit), max_nfev=max_nfev,
                                 diff_step=diff_step, last_failure=last_failure)
    for p, why in held:
        value = float(np.clip(given[p.name], p.lower, p.upper))
        stats.warnings.insert(0, f"{p.name} held at its start value {value:g} {p.unit}: {why}")
    return fit, out, stats, held, refits


def calibrate(targets: Sequence[Target], fit: Sequence[FitParameter | str],
              start: BrakeParams | None = None, lut: CouplerLUT | None = None, *,
              step_s: float = 0.01, workers: int | None = None, progress=None,
              max_nfev: int = 60, diff_step: float = 1e-2, stats_step: float = 5e-2,
              evaluator: DistanceEvaluator | None = None, keep_correlated: bool = True,
              cross_validate: bool = False) -> Calibration:
    """Fit brake parameters to reference stopping distances.

    Minimises ``sum(((S_sim - S_ref) / S_ref)^2)`` over the targets, within the physical
    bounds the brake model's ``FITTABLE`` declares (see :func:`fit_parameters`; narrow them
    with :func:`with_bounds`), by the trust-region reflective method.

    Parameters
    ----------
    targets : sequence of Target
    fit : sequence of FitParameter or str
        Parameters to fit, in order of priority; the others keep their ``start`` values.
    start : BrakeParams, optional
        Start values (default: the shipped ``paper`` preset).
    lut : CouplerLUT, optional
        Coupler table (default: the shipped one).
    step_s : float, optional
        Integration step [s].
    workers : int, optional
        Processes (default: every core).
    progress : tqdm.tqdm, optional
        Advanced by one per emergency stop.
    max_nfev : int, optional
        Most residual evaluations of the optimiser.
    diff_step : float, optional
        Forward-difference step, relative to each parameter's typical magnitude [-]. The
        simulated distance is not smooth at the 1e-4 level: the moment the last vehicle counts
        as stopped can jump by a fraction of a second, and the head rolls back a few
        centimetres meanwhile. A 1 % step keeps such jumps small against the difference.
    stats_step : float, optional
        Step of the second-order differences of the Jacobian behind the confidence intervals
        and correlations, relative to each parameter's typical magnitude [-]: larger than
        ``diff_step`` because the statistics need accurate columns, the fit only a good
        descent direction.
    evaluator : DistanceEvaluator, optional
        Reuse a pool whose cases start with the targets' trains (the caller closes it).
    keep_correlated : bool, optional
        False: while two fitted parameters correlate beyond :data:`HOLD_CORRELATION`, hold
        the one listed later at its start value and fit again (only identifiable parameters
        are fitted).
    cross_validate : bool, optional
        Also refit with each train left out and simulate it with those values
        (``Calibration.cv_m``).

    Returns
    -------
    Calibration
    """
    start = start or load_brake_params()
    fit = _resolve(fit, start.model)
    targets = list(targets)
    lut = lut or load_coupler_lut()
    ref = np.array([t.distance_m for t in targets])
    given = {p.name: float(getattr(start, p.field)) for p in fit}
    start = replace(start, **{p.field: float(np.clip(given[p.name], p.lower, p.upper))
                              for p in fit})
    m = len(targets)

    own = evaluator is None
    if own:
        evaluator = DistanceEvaluator([(t.consist, t.speed_kmh) for t in targets], lut,
                                      step_s=step_s, workers=workers, progress=progress)

    def batch_of(rows: Sequence[int], chosen: list):
        def batch(xs) -> np.ndarray:
            sets = [replace(start, **{p.field: float(v) for p, v in zip(chosen, x)})
                    for x in xs]
            d = evaluator.distances(sets, rows)
            return (d - ref[rows]) / ref[rows]
        return batch

    try:
        fit, out, stats, held, refits = _fit_targets(
            fit, given, batch_of, m, [t.consist for t in targets], evaluator,
            max_nfev=max_nfev, diff_step=diff_step, stats_step=stats_step, progress=progress,
            keep_correlated=keep_correlated, cross_validate=cross_validate,
            label="max |error| [-]")
        params = replace(start, **{p.field: float(v) for p, v in zip(fit, out.x)})
        cv = np.full(m, np.nan) if cross_validate else None
        for g, x in refits:
            if x is not None:
                cv[g] = batch_of(g, fit)([x])[0] * ref[g] + ref[g]
        runs = evaluator.runs
    finally:
        if own:
            evaluator.close()
    return Calibration(targets=targets, start=start, params=params,
                       before_m=out.r_before * ref + ref, after_m=out.r_after * ref + ref,
                       cv_m=cv, **_outcome(fit, out, stats, runs, held))

"""Calibration of the brake-model parameters against reference stopping distances.

The paper tuned ``t_app``, ``v_air`` and ``t_fill`` by trial and error until its simulated
emergency stops matched UIC 544-1. Here the chosen parameters are fitted by bounded nonlinear
least squares (:func:`scipy.optimize.least_squares`, trust-region reflective) on the relative
stopping-distance errors ``(S_sim - S_ref) / S_ref`` of a set of trains.

Targets
-------
``uic``
    UIC 544-1 at 100 km/h: the UIC column of Table 1 for the paper's trains, and the UIC
    reference curve ``S = C / lambda + D`` (C = 50 752 m %, D = 53.45 m, the fit of that
    column) for any other train, with lambda from Eq. 11.
``paper``
    The LTDPoliTo column of Tables 1-2 (the paper's own model), at 100 or 50 km/h.

Every residual evaluation runs the trains' emergency stops on one process pool that lives for
the whole fit; the finite-difference columns of the Jacobian are evaluated as one batch spread
over the workers. The uncertainty reported is the usual linearised one,
``cov = (J^T J)^-1 s^2`` with ``s^2 = |r|^2 / (m - n)`` (m targets, n parameters not held by a
bound), J from second-order differences at the fitted values. The reference distances carry no
measurement noise, so the intervals measure how closely the model structure can follow the
references; the correlation matrix shows which parameters the chosen trains cannot tell apart.
A parameter that ends on a bound is reported as such, without an interval.
"""
from __future__ import annotations

import math
import os
import textwrap
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..inputs import (BrakeParams, Consist, CouplerLUT, InputError, load_brake_params,
                     load_coupler_lut, load_scenarios)
from ..physics import brakes
from ..physics.brakes import friction
from ..physics.parameters import specs
from .parallel import default_workers, process_pool

#: Coefficients of the UIC 544-1 reference curve S = C / lambda + D at 100 km/h [m %], [m].
UIC_C_M_PERCENT = 50752.0
UIC_D_M = 53.45
#: The only initial speed at which UIC 544-1 reference distances are available here [km/h].
UIC_SPEED_KMH = 100.0

#: Thresholds of the identifiability warnings.
MAX_ABS_CORRELATION = 0.95
MAX_RELATIVE_CI = 0.5

#: Fraction of a parameter's range within which a fitted value counts as on its bound.
BOUND_TOL = 1e-4

#: Significant digits of the values written to a parameter file; the "after" residuals are
#: evaluated at the written values, so the file reproduces the report exactly.
WRITE_DIGITS = 5


@dataclass(frozen=True)
class FitParameter:
    """A brake parameter that can be fitted: a short name and its model's ``FITTABLE`` entry.

    Attributes
    ----------
    name : str
        Short name used on the command line (``t_app``).
    field, unit, lower, upper, scale, meaning
        As in :class:`~ltd_brake_ros.physics.parameters.Fittable`; ``field`` is readable on
        :class:`~ltd_brake_ros.inputs.BrakeParams`, the fit works in ``value / scale`` and
        takes finite-difference steps relative to it.
    """

    name: str
    field: str
    unit: str
    lower: float
    upper: float
    scale: float
    meaning: str


def fit_parameters(model: str = brakes.DEFAULT_MODEL) -> dict[str, FitParameter]:
    """The parameters a brake model lets calibration fit: its ``FITTABLE``, then the friction's.

    Parameters
    ----------
    model : str, optional
        Registered brake model (default: the paper's).

    Returns
    -------
    dict of str to FitParameter
        By short name.
    """
    table = {**brakes.MODELS[model].FITTABLE, **friction.FITTABLE}
    return {name: FitParameter(name, *fit) for name, fit in table.items()}


#: The parameters that can be fitted with the paper's brake model.
FIT_PARAMETERS: dict[str, FitParameter] = fit_parameters()


def _field_comment(params: BrakeParams, name: str) -> str:
    """Meaning and unit of a parameter field, as its model declares them."""
    for part in (params.pneumatic, params.friction):
        declared = specs(type(part))
        if name in declared:
            return declared[name].doc
    raise KeyError(name)


def parse_fit(text: str | Sequence[str], model: str = brakes.DEFAULT_MODEL
              ) -> list[FitParameter]:
    """Parse the parameters to fit.

    Parameters
    ----------
    text : str or sequence of str
        Comma-separated names, short (``t_app``) or field names (``t_app_s``).
    model : str, optional
        Brake model whose parameters may be named (default: the paper's).

    Returns
    -------
    list of FitParameter
        In the order given, without duplicates.

    Raises
    ------
    InputError
        An unknown name, or none at all.
    """
    names = text.split(",") if isinstance(text, str) else list(text)
    known = fit_parameters(model)
    by_field = {p.field: p for p in known.values()}
    out: list[FitParameter] = []
    for raw in names:
        name = raw.strip()
        if not name:
            continue
        p = known.get(name) or by_field.get(name)
        if p is None:
            raise InputError("command line", "--fit", f"unknown parameter {name!r}; choose from "
                             f"{', '.join(known)}")
        if p not in out:
            out.append(p)
    if not out:
        raise InputError("command line", "--fit", "give at least one parameter to fit, e.g. "
                         "t_app,v_air,t_fill,k0")
    return out


# --------------------------------------------------------------------------- targets


@dataclass(frozen=True)
class Target:
    """A train, an initial speed and the stopping distance it should reach.

    Attributes
    ----------
    label : str
        Short name in tables: the scenario number, or the consist name.
    consist : Consist
        The train.
    speed_kmh : float
        Initial speed [km/h].
    distance_m : float
        Reference stopping distance [m].
    reference : str
        Where the reference distance comes from.
    lambda_percent : float
        Braked-weight percentage of the train, Eq. 11 [%].
    scenario : int or None
        Row of Tables 1-2, if the train is one of the paper's.
    """

    label: str
    consist: Consist
    speed_kmh: float
    distance_m: float
    reference: str
    lambda_percent: float
    scenario: int | None = None


def braked_weight_percent(consist: Consist) -> float:
    """Braked-weight percentage lambda of a train, Eq. 11 [%].

    Parameters
    ----------
    consist : Consist

    Returns
    -------
    float
    """
    from ..physics import train_braked_weight_percent

    return train_braked_weight_percent([v.braked_weight_t for v in consist.vehicles],
                                       [v.mass_kg / 1e3 for v in consist.vehicles],
                                       consist.length_m)


def uic_curve_distance_m(lambda_percent: float) -> float:
    """UIC 544-1 emergency stopping distance from 100 km/h, ``S = C / lambda + D`` [m].

    Parameters
    ----------
    lambda_percent : float
        Train braked-weight percentage [%].

    Returns
    -------
    float
    """
    return UIC_C_M_PERCENT / lambda_percent + UIC_D_M


def build_targets(target: str, speed_kmh: float = UIC_SPEED_KMH,
                  scenarios: Sequence[int] | None = None,
                  consists: Sequence[Consist] = ()) -> list[Target]:
    """Select the trains to fit and their reference distances.

    Parameters
    ----------
    target : {'uic', 'paper'}
        ``uic``: UIC 544-1 (Table 1's UIC column; the curve ``S = C / lambda + D`` for the
        extra ``consists``), only at 100 km/h. ``paper``: the LTDPoliTo column of Tables 1-2.
    speed_kmh : float, optional
        Initial speed [km/h]; selects the rows of Tables 1-2.
    scenarios : sequence of int, optional
        Rows of Tables 1-2 (default: every row at ``speed_kmh``).
    consists : sequence of Consist, optional
        Further trains (``uic`` only), e.g. other lengths or braked-weight percentages that
        widen what the fit can identify.

    Returns
    -------
    list of Target

    Raises
    ------
    InputError
        Unknown target, a speed without reference values, a scenario that is unknown or at
        another speed.
    """
    if target not in ("uic", "paper"):
        raise InputError("command line", "--target", f"unknown target {target!r}; choose uic "
                         "(UIC 544-1 at 100 km/h) or paper (LTDPoliTo column of Tables 1-2)")
    if not (math.isfinite(speed_kmh) and speed_kmh > 0):
        raise InputError("command line", "--speed-kmh",
                         f"must be a positive speed, got {speed_kmh}")
    if target == "uic" and speed_kmh != UIC_SPEED_KMH:
        raise InputError("command line", "--speed-kmh", f"UIC 544-1 reference distances are "
                         f"available only at {UIC_SPEED_KMH:g} km/h (Table 1 and the curve "
                         f"S = C/lambda + D), got {speed_kmh:g} km/h")
    if target == "paper" and consists:
        raise InputError("command line", "--consist", "extra trains need --target uic: the "
                         "LTDPoliTo column exists only for the paper's trains")
    catalogue = load_scenarios()
    speeds = sorted({s.speed_kmh for s in catalogue.values()})
    if scenarios is None:
        scenarios = [k for k in sorted(catalogue) if catalogue[k].speed_kmh == speed_kmh]
        if not scenarios and not consists:
            raise InputError("command line", "--speed-kmh", f"Tables 1-2 have no run at "
                             f"{speed_kmh:g} km/h; they have {', '.join(f'{v:g}' for v in speeds)}")
    out: list[Target] = []
    for k in scenarios:
        if k not in catalogue:
            raise InputError("command line", "--scenarios", f"unknown scenario {k}; Tables 1-2 "
                             f"have {min(catalogue)}-{max(catalogue)}")
        sc = catalogue[k]
        if sc.speed_kmh != speed_kmh:
            raise InputError("command line", "--scenarios", f"scenario {k} starts at "
                             f"{sc.speed_kmh:g} km/h, not at --speed-kmh {speed_kmh:g}")
        consist = sc.consist()
        lam = braked_weight_percent(consist)
        if target == "uic":
            out.append(Target(str(k), consist, speed_kmh, float(sc.paper["uic_m"]),
                              "UIC 544-1 Table 1", lam, k))
        else:
            out.append(Target(str(k), consist, speed_kmh, float(sc.paper["ltdpolito_m"]),
                              "LTDPoliTo", lam, k))
    for consist in consists:
        lam = braked_weight_percent(consist)
        label = Path(consist.source).stem if consist.source else consist.name
        out.append(Target(label, consist, speed_kmh, uic_curve_distance_m(lam),
                          "UIC 544-1 curve C/lambda + D", lam))
    if not out:
        raise InputError("command line", "--scenarios", "no train to fit")
    return out


def companion_rows(targets: Sequence[Target]) -> list:
    """Rows of Tables 1-2 with the targets' trains at other speeds (reported, not fitted).

    Parameters
    ----------
    targets : sequence of Target

    Returns
    -------
    list of Scenario
    """
    catalogue = load_scenarios()
    used = {t.scenario for t in targets if t.scenario is not None}
    files = {catalogue[k].consist_file for k in used}
    speed = {t.speed_kmh for t in targets}
    return [s for k, s in sorted(catalogue.items())
            if k not in used and s.consist_file in files and s.speed_kmh not in speed]


# --------------------------------------------------------------------------- evaluation

# Per-worker state, set once by the pool initializer, so that tasks carry only parameters.
_CASES: list[tuple[Consist, float]] = []
_LUT: CouplerLUT | None = None
_STEP_S = 0.01


def _init_worker(cases, lut, step_s) -> None:
    global _CASES, _LUT, _STEP_S
    _CASES, _LUT, _STEP_S = list(cases), lut, step_s


def _run_chunk(chunk) -> list[tuple[float, str | None]]:
    from .runs import emergency_stop
    from ..simulator import SimulationError

    out = []
    for params, i in chunk:
        consist, speed = _CASES[i]
        try:
            d = emergency_stop(consist, speed, params, _LUT, step_s=_STEP_S).stopping_distance_m
            out.append((d, None))
        except SimulationError as exc:
            # a trial point the integrator cannot handle: the optimiser rejects it
            values = ", ".join(f"{p.field}={getattr(params, p.field):.6g}"
                               for p in fit_parameters(params.model).values())
            out.append((math.nan, f"{consist.name} from {speed:g} km/h with {values}: {exc}"))
    return out


class DistanceEvaluator:
    """Stopping distances of a fixed set of trains for many parameter sets, on one pool.

    Parameters
    ----------
    cases : sequence of (Consist, float)
        Trains and initial speeds [km/h].
    lut : CouplerLUT
    step_s : float, optional
        Integration step [s].
    workers : int, optional
        Processes (default: every core); 1 runs in this process.
    progress : tqdm.tqdm, optional
        Advanced by one per emergency stop.

    Notes
    -----
    Use as a context manager so that the pool is shut down.
    """

    def __init__(self, cases: Sequence[tuple[Consist, float]], lut: CouplerLUT, *,
                 step_s: float = 0.01, workers: int | None = None, progress=None):
        self.cases = list(cases)
        self.lut, self.step_s = lut, step_s
        self.workers = max(1, int(workers or default_workers()))
        self.progress = progress
        self.runs = 0
        #: Messages of the emergency stops that failed (their distance is NaN).
        self.failures: list[str] = []
        # cost of one stop ~ vehicles x speed (steps to standstill x kernel cost per step)
        self._cost = [c.n * s for c, s in self.cases]
        self._pool = None
        if self.workers > 1:
            self._pool = process_pool(self.workers, initializer=_init_worker,
                                      initargs=(self.cases, lut, step_s))
        else:
            _init_worker(self.cases, lut, step_s)

    def __enter__(self) -> "DistanceEvaluator":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Shut the pool down."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def distances(self, param_sets: Sequence[BrakeParams],
                  cases: Sequence[int] | None = None) -> np.ndarray:
        """Stopping distances of every case for every parameter set.

        Parameters
        ----------
        param_sets : sequence of BrakeParams
        cases : sequence of int, optional
            Indices into the evaluator's cases (default: all).

        Returns
        -------
        ndarray, shape (len(param_sets), len(cases))
            Stopping distances [m]; NaN where the simulation failed (see ``failures``).
        """
        idx = list(range(len(self.cases))) if cases is None else list(cases)
        jobs = [(a, b) for a in range(len(param_sets)) for b in range(len(idx))]
        out = np.empty((len(param_sets), len(idx)))
        for chunk, values in self._run(jobs, param_sets, idx):
            for (a, b), (d, err) in zip(chunk, values):
                out[a, b] = d
                if err:
                    self.failures.append(err)
        return out

    def _run(self, jobs, param_sets, idx):
        def payload(chunk):
            return [(param_sets[a], idx[b]) for a, b in chunk]

        if self._pool is None:
            for job in jobs:
                values = _run_chunk(payload([job]))
                self._advance(1)
                yield [job], values
            return
        # a few chunks per worker, balanced by cost (longest first), so that both the
        # scheduling overhead and the idle tail at the end of a batch stay small
        n_chunks = min(len(jobs), 3 * self.workers)
        chunks: list[list] = [[] for _ in range(n_chunks)]
        load = [0.0] * n_chunks
        for job in sorted(jobs, key=lambda j: -self._cost[idx[j[1]]]):
            k = load.index(min(load))
            chunks[k].append(job)
            load[k] += self._cost[idx[job[1]]]
        from concurrent.futures import as_completed

        futures = {self._pool.submit(_run_chunk, payload(c)): c for c in chunks if c}
        for fut in as_completed(futures):
            chunk = futures[fut]
            values = fut.result()
            self._advance(len(chunk))
            yield chunk, values

    def _advance(self, n: int) -> None:
        self.runs += n
        if self.progress is not None:
            self.progress.update(n)


# --------------------------------------------------------------------------- fit


@dataclass
class Calibration:
    """Outcome of :func:`calibrate` (units: fitted values in each parameter's unit).

    Attributes
    ----------
    targets : list of Target
    fit : list of FitParameter
    start : BrakeParams
        Start values (clipped into the bounds).
    params : BrakeParams
        Fitted values, rounded to :data:`WRITE_DIGITS` significant digits.
    before_m, after_m : ndarray
        Simulated stopping distances at the start and fitted values [m].
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
        Degrees of freedom of the residual: targets minus parameters not held by a bound.
    converged : bool
        The optimiser met a tolerance (not the evaluation budget).
    message : str
        The optimiser's termination message.
    """

    targets: list
    fit: list
    start: BrakeParams
    params: BrakeParams
    before_m: np.ndarray
    after_m: np.ndarray
    ci95: np.ndarray
    correlation: np.ndarray
    at_bound: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    nfev: int = 0
    runs: int = 0
    dof: int = 0
    converged: bool = True
    message: str = ""

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

    def value(self, p: FitParameter, which: str = "params") -> float:
        """Value of a fitted parameter in ``params`` or ``start``."""
        return float(getattr(getattr(self, which), p.field))


def _statistics_jacobian(evaluator, params_at, z, r0, ref, lo, hi, step, cases) -> np.ndarray:
    """Second-order finite-difference Jacobian of the residuals in scaled units.

    ``params_at`` maps scaled values ``z`` to parameters; ``r0`` are the residuals at ``z``.

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
    sets = [params_at(z + a * h[j] * np.eye(n)[j]) for j, (_, offsets) in enumerate(plan)
            for a in offsets]
    d = evaluator.distances(sets, cases)
    r = (d - ref) / ref
    jac = np.empty((len(ref), n))
    for j, (kind, _) in enumerate(plan):
        r1, r2 = r[2 * j], r[2 * j + 1]
        if kind == "central":
            jac[:, j] = (r1 - r2) / (2 * h[j])
        elif kind == "forward":
            jac[:, j] = (-3 * r0 + 4 * r1 - r2) / (2 * h[j])
        else:
            jac[:, j] = (3 * r0 - 4 * r1 + r2) / (2 * h[j])
    return jac


def _round(x: float, digits: int = WRITE_DIGITS) -> float:
    return float(f"{x:.{digits}g}")


def calibrate(targets: Sequence[Target], fit: Sequence[FitParameter | str],
              start: BrakeParams | None = None, lut: CouplerLUT | None = None, *,
              step_s: float = 0.01, workers: int | None = None, progress=None,
              max_nfev: int = 60, diff_step: float = 1e-2, stats_step: float = 5e-2,
              evaluator: DistanceEvaluator | None = None) -> Calibration:
    """Fit brake parameters to reference stopping distances.

    Minimises ``sum(((S_sim - S_ref) / S_ref)^2)`` over the targets, within the physical
    bounds the brake model's ``FITTABLE`` declares (see :func:`fit_parameters`), by the
    trust-region reflective method.

    Parameters
    ----------
    targets : sequence of Target
    fit : sequence of FitParameter or str
        Parameters to fit; the others keep their ``start`` values.
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

    Returns
    -------
    Calibration
    """
    from scipy.optimize import least_squares
    from scipy.stats import t as student_t

    from ..simulator import SimulationError

    start = start or load_brake_params()
    # names resolved against the start's brake model: its FITTABLE gives fields and bounds
    fit = parse_fit([p.name if isinstance(p, FitParameter) else p for p in fit], start.model)
    targets = list(targets)
    lut = lut or load_coupler_lut()
    lower = np.array([p.lower for p in fit])
    upper = np.array([p.upper for p in fit])
    scale = np.array([p.scale for p in fit])
    given = np.array([getattr(start, p.field) for p in fit], float)
    x0 = np.clip(given, lower, upper)
    clipped = [f"{p.name} = {g:g} {p.unit}" for p, g, c in zip(fit, given, x0) if g != c]
    start = replace(start, **{p.field: float(v) for p, v in zip(fit, x0)})
    ref = np.array([t.distance_m for t in targets])
    m, n = len(targets), len(fit)

    def params_at(x) -> BrakeParams:
        return replace(start, **{p.field: float(v) for p, v in zip(fit, x)})

    own = evaluator is None
    if own:
        evaluator = DistanceEvaluator([(t.consist, t.speed_kmh) for t in targets], lut,
                                      step_s=step_s, workers=workers, progress=progress)
    cases = list(range(m))
    failed_before = len(evaluator.failures)
    cache: dict[bytes, np.ndarray] = {}
    counter = {"nfev": 0}

    def residuals(z) -> np.ndarray:
        key = np.asarray(z, float).tobytes()
        if key not in cache:
            d = evaluator.distances([params_at(z * scale)], cases)[0]
            cache[key] = (d - ref) / ref
            counter["nfev"] += 1
            if progress is not None:
                progress.set_postfix_str(f"max |error| {100 * np.abs(cache[key]).max():.2f} %")
        return cache[key]

    def shifted(z, h) -> list[BrakeParams]:
        return [params_at((z + h[j] * np.eye(n)[j]) * scale) for j in range(n)]

    def jacobian(z) -> np.ndarray:
        r0 = residuals(z)
        # forward steps, backwards where a forward one would cross the upper bound
        h = diff_step * np.maximum(np.abs(z), 1.0)
        h = np.where(z + h > upper / scale, -h, h)
        d = evaluator.distances(shifted(z, h), cases)  # all columns in one batch over the pool
        bad = ~np.all(np.isfinite(d), axis=1)
        if bad.any():  # a failed stop: step the other way, inside the bounds
            h = np.where(bad & (z - h >= lower / scale) & (z - h <= upper / scale), -h, h)
            d[bad] = evaluator.distances([c for c, b in zip(shifted(z, h), bad) if b], cases)
        if not np.all(np.isfinite(d)):
            raise SimulationError("the finite-difference step failed: " + evaluator.failures[-1])
        return (((d - ref) / ref) - r0).T / h

    try:
        before = residuals(x0 / scale) * ref + ref
        if not np.all(np.isfinite(before)):
            raise SimulationError("at the start values: " + evaluator.failures[-1])
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
        params = params_at(x)
        after = evaluator.distances([params], cases)[0]
        if not np.all(np.isfinite(after)):
            raise SimulationError("at the fitted values: " + evaluator.failures[-1])
        jac = _statistics_jacobian(evaluator, lambda zz: params_at(zz * scale), x / scale,
                                   (after - ref) / ref, ref,
                                   lower / scale, upper / scale, stats_step, cases)
        jac = np.where(np.isfinite(jac), jac, sol.jac) / scale
        runs, failures = evaluator.runs, len(evaluator.failures) - failed_before
    finally:
        if own:
            evaluator.close()

    # Uncertainty from the Jacobian at the optimum, in physical units. The correlations are
    # those of every fitted parameter (a property of the sensitivities, bound or not); the
    # confidence intervals are those of the free parameters, with the ones a bound holds fixed.
    free = ~(on_lower | on_upper)
    r = (after - ref) / ref
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
    if clipped:
        warnings.append(f"start value outside the bounds, started from the bound: "
                        f"{', '.join(clipped)}")
    if failures:
        warnings.append(f"{failures} emergency stops failed to integrate at trial values; the "
                        f"optimiser rejected those points (last: {evaluator.failures[-1]})")
    if not sol.status > 0:
        warnings.append(f"the fit stopped after {counter['nfev']} evaluations without "
                        f"converging ({sol.message}); raise --max-nfev")
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
            side, bound = ("lower", lower[j]) if on_lower[j] else ("upper", upper[j])
            at_bound.append(p.name)
            warnings.append(f"{p.name} ended on its {side} bound ({bound:g} {p.unit}): the "
                            "targets push it further, so the bound, not the data, sets its "
                            "value (no confidence interval)")
    for j in range(n):
        for k in range(j + 1, n):
            c = corr[j, k]
            if np.isfinite(c) and abs(c) > MAX_ABS_CORRELATION:
                warnings.append(
                    f"{fit[j].name} and {fit[k].name} are not separately identifiable from "
                    f"these targets (correlation {c:+.3f}): the distances fix only a "
                    f"combination of them; fix one, or add trains that tell them apart")
    for j, p in enumerate(fit):
        if np.isfinite(ci95[j]) and x[j] != 0 and ci95[j] > MAX_RELATIVE_CI * abs(x[j]):
            unit = "" if p.unit == "-" else f" {p.unit}"
            warnings.append(f"{p.name} is poorly determined: 95 % confidence interval "
                            f"+/-{ci95[j]:.3g}{unit} is {100 * ci95[j] / abs(x[j]):.0f} % of "
                            "its value")
    return Calibration(targets, list(fit), start, params, before, after, ci95, corr, at_bound,
                       warnings, counter["nfev"], runs, dof, bool(sol.status > 0), str(sol.message))


# --------------------------------------------------------------------------- report


def _pct(v: float | None) -> str:
    return "NA" if v is None or not np.isfinite(v) else f"{v:+.2f} %"


def targets_table(cal: Calibration) -> str:
    """Markdown table of the targets before and after the fit.

    Parameters
    ----------
    cal : Calibration

    Returns
    -------
    str
    """
    lines = ["| target | train | V0 km/h | λ % | reference | ref. m | before m | before err "
             "| after m | after err |", "|---|---|---|---|---|---|---|---|---|---|"]
    eb, ea = cal.before_error_percent, cal.after_error_percent
    for i, t in enumerate(cal.targets):
        lines.append(f"| {t.label} | {t.consist.name} | {t.speed_kmh:g} | {t.lambda_percent:.1f} "
                     f"| {t.reference} | {t.distance_m:.1f} | {cal.before_m[i]:.1f} | "
                     f"{_pct(eb[i])} | {cal.after_m[i]:.1f} | {_pct(ea[i])} |")
    return "\n".join(lines)


def parameters_table(cal: Calibration) -> str:
    """Markdown table of the fitted values with their 95 % confidence intervals.

    Parameters
    ----------
    cal : Calibration

    Returns
    -------
    str
    """
    lines = ["| parameter | unit | start | fitted | 95 % CI (+/-) | relative CI | bounds |",
             "|---|---|---|---|---|---|---|"]
    for j, p in enumerate(cal.fit):
        x, ci = cal.value(p), cal.ci95[j]
        if p.name in cal.at_bound:
            ci_text, rel = "on bound", "-"
        else:
            ci_text = "NA" if not np.isfinite(ci) else f"{ci:.3g}"
            rel = f"{100 * ci / abs(x):.1f} %" if np.isfinite(ci) and x else "NA"
        lines.append(f"| {p.field} | {p.unit} | {cal.value(p, 'start'):.5g} | {x:.5g} | "
                     f"{ci_text} | {rel} | {p.lower:g} to {p.upper:g} |")
    return "\n".join(lines)


def correlation_table(cal: Calibration) -> str:
    """Markdown table of the correlation matrix of the fitted values.

    Parameters
    ----------
    cal : Calibration

    Returns
    -------
    str
    """
    names = [p.name for p in cal.fit]
    lines = ["| | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for j, name in enumerate(names):
        lines.append(f"| {name} | " + " | ".join(
            "NA" if not np.isfinite(c) else f"{c:+.3f}" for c in cal.correlation[j]) + " |")
    return "\n".join(lines)


def companion_table(rows, before_m, after_m) -> str:
    """Markdown table of Tables 1-2 rows that were not fitted, before and after.

    Parameters
    ----------
    rows : list of Scenario
    before_m, after_m : array_like
        Our stopping distances at the start and the fitted values [m].

    Returns
    -------
    str
    """
    lines = ["| No. | V0 km/h | Pugi m | LTDPoliTo m | before m | vs LTDPoliTo | vs Pugi | "
             "after m | vs LTDPoliTo | vs Pugi |", "|---|---|---|---|---|---|---|---|---|---|"]
    for s, b, a in zip(rows, before_m, after_m):
        lt, pu = s.paper["ltdpolito_m"], s.paper["pugi_m"]
        lines.append(f"| {s.number} | {s.speed_kmh:g} | {pu:g} | {lt:.1f} | {b:.1f} | "
                     f"{_pct(100 * (b - lt) / lt)} | {_pct(100 * (b - pu) / pu)} | {a:.1f} | "
                     f"{_pct(100 * (a - lt) / lt)} | {_pct(100 * (a - pu) / pu)} |")
    return "\n".join(lines)


def summary_lines(cal: Calibration) -> list[str]:
    """Largest and RMS errors before and after, one line each."""
    eb, ea = cal.before_error_percent, cal.after_error_percent
    return [f"largest |error|: before {np.abs(eb).max():.2f} %, after {np.abs(ea).max():.2f} %",
            f"RMS error:       before {np.sqrt(np.mean(eb ** 2)):.2f} %, after "
            f"{np.sqrt(np.mean(ea ** 2)):.2f} %"]


# --------------------------------------------------------------------------- parameter file


def display_path(path: str) -> str:
    """``path`` relative to the working directory where it can be, as a user typed it.

    Parameters
    ----------
    path : str

    Returns
    -------
    str
    """
    try:
        return os.path.relpath(path)
    except ValueError:
        return path


def parameter_file_text(cal: Calibration, command: str) -> str:
    """Brake-parameter YAML of the fitted values, headed by how they were produced.

    Parameters
    ----------
    cal : Calibration
    command : str
        The command line that produced it.

    Returns
    -------
    str
        A document that :func:`~ltd_brake_ros.inputs.load_brake_params` accepts.
    """
    ref = {t.reference for t in cal.targets}
    speeds = ", ".join(sorted({f"{t.speed_kmh:g}" for t in cal.targets}))
    head = [f"# Brake-model parameters calibrated against {' and '.join(sorted(ref))} stopping",
            f"# distances at {speeds} km/h, by least squares on the relative distance errors.",
            "# Produced by:",
            f"#   {command}",
            f"# Start values: {display_path(cal.start.source)}; the fields not fitted keep them.",
            "# Residuals (simulated - reference) / reference at the values below:"]
    names = [f"scenario {t.label}" if t.scenario is not None else t.label for t in cal.targets]
    wn = max(len(x) for x in names)
    wc = max(len(t.consist.name) for t in cal.targets)
    for i, (t, name) in enumerate(zip(cal.targets, names)):
        head.append(f"#   {name:<{wn}}  {t.consist.name:<{wc}}  lambda {t.lambda_percent:5.1f} %  "
                    f"ref {t.distance_m:6.1f} m  sim {cal.after_m[i]:6.1f} m  "
                    f"{cal.after_error_percent[i]:+.2f} %"
                    + (f"  ({t.reference})" if len(ref) > 1 else ""))
    head.append(f"# Fitted values, 95 % confidence half-widths (Student t, {max(cal.dof, 0)} dof, "
                "(J^T J)^-1 s^2):")
    for j, p in enumerate(cal.fit):
        ci = cal.ci95[j]
        if p.name in cal.at_bound:
            head.append(f"#   {p.field} = {cal.value(p):.5g} {p.unit} (on its bound)")
        else:
            head.append(f"#   {p.field} = {cal.value(p):.5g} +/- "
                        f"{'NA' if not np.isfinite(ci) else f'{ci:.2g}'}"
                        f"{'' if p.unit == '-' else ' ' + p.unit}")
    for w in cal.warnings:
        head += textwrap.wrap(f"warning: {w}", 98, initial_indent="# ",
                              subsequent_indent="#   ")
    # every field of the model, so that the file alone reproduces the parameters
    params = cal.params
    body = [] if params.model == brakes.DEFAULT_MODEL else [f"model: {params.model}"]
    names = [*specs(type(params.pneumatic)), *specs(type(params.friction))]
    width = max(len(n) for n in names) + 2
    for name in names:
        value = getattr(params, name)
        value = (str(value).lower() if isinstance(value, bool)
                 else f"{float(value):.{WRITE_DIGITS}g}")
        body.append(f"{name + ':':<{width}} {value:<10} # {_field_comment(params, name)}")
    return "\n".join(head + body) + "\n"

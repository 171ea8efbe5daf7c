"""Calibration of model parameters: brake parameters against reference stopping distances,
coupler parameters against the paper's peak in-train forces.

The paper tuned ``t_app``, ``v_air`` and ``t_fill`` by trial and error until its simulated
emergency stops matched UIC 544-1. Here the chosen parameters are fitted by bounded nonlinear
least squares (:func:`scipy.optimize.least_squares`, trust-region reflective) on the relative
stopping-distance errors ``(S_sim - S_ref) / S_ref`` of a set of trains
(:func:`calibrate`), or on the peak draft and buff forces of Tables 1-2 with the coupler
positions and the distances as constraints (:func:`calibrate_couplers`).

A fit that generalises fits only what its targets determine: asked to, it holds the later of
two parameters whose estimates correlate beyond :data:`MAX_ABS_CORRELATION` at its start value
(a physical prior given by the start file) and fits again; it reports leave-one-train-out
errors (each train left out of the fit in turn and predicted by the others' values) next to
the fit's own; and the command line refuses to write a parameter file with a value on a bound.

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

import dataclasses
import math
import os
import textwrap
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..inputs import (BrakeParams, Consist, CouplerLUT, InputError, load_brake_params,
                     load_coupler_lut, load_scenarios)
from ..physics import brakes, couplers
from ..physics.brakes import friction
from ..physics.couplers import lut_hysteresis
from ..physics.parameters import CompileError, specs
from .parallel import default_workers, process_pool

#: Coefficients of the UIC 544-1 reference curve S = C / lambda + D at 100 km/h [m %], [m].
UIC_C_M_PERCENT = 50752.0
UIC_D_M = 53.45
#: The only initial speed at which UIC 544-1 reference distances are available here [km/h].
UIC_SPEED_KMH = 100.0

#: Thresholds of the identifiability warnings.
MAX_ABS_CORRELATION = 0.95
MAX_RELATIVE_CI = 0.5
#: Correlation beyond which two fitted parameters are not separately identifiable and the
#: later one is held (when asked to fit only what the targets determine): at one initial
#: speed t_app and t_fill correlate at -1.000, while K0 and t_app, told apart by trains of
#: different braked-weight percentages, stay near -0.98 with tight intervals.
HOLD_CORRELATION = 0.99

#: Fraction of a parameter's range within which a fitted value counts as on its bound.
BOUND_TOL = 1e-4

#: Significant digits of the values written to a parameter file; the "after" residuals are
#: evaluated at the written values, so the file reproduces the report exactly.
WRITE_DIGITS = 5


@dataclass(frozen=True)
class FitParameter:
    """A parameter that can be fitted: a short name and its model's ``FITTABLE`` entry.

    Attributes
    ----------
    name : str
        Short name used on the command line (``t_app``).
    field, unit, lower, upper, scale, meaning
        As in :class:`~ltd_brake_ros.physics.parameters.Fittable`; ``field`` is readable on
        :class:`~ltd_brake_ros.inputs.BrakeParams` (``part`` brake) or on the coupler model's
        ``Params`` (``part`` coupler), the fit works in ``value / scale`` and takes
        finite-difference steps relative to it.
    part : str
        ``brake`` or ``coupler``.
    """

    name: str
    field: str
    unit: str
    lower: float
    upper: float
    scale: float
    meaning: str
    part: str = "brake"


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


def coupler_fit_parameters(model: str = couplers.DEFAULT_MODEL) -> dict[str, FitParameter]:
    """The parameters a coupler model lets calibration fit: its ``FITTABLE``.

    Parameters
    ----------
    model : str, optional
        Registered coupler model (default: the paper's look-up table).

    Returns
    -------
    dict of str to FitParameter
        By short name.
    """
    return {name: FitParameter(name, *fit, part="coupler")
            for name, fit in couplers.MODELS[model].FITTABLE.items()}


def _known(model: str, part: str) -> dict[str, FitParameter]:
    return fit_parameters(model) if part == "brake" else coupler_fit_parameters(model)


def _resolve(fit: Sequence[FitParameter | str], model: str, part: str = "brake"
             ) -> list[FitParameter]:
    """Names resolved against a model; FitParameters (possibly with narrowed bounds) kept."""
    names = [p.name if isinstance(p, FitParameter) else p for p in fit]
    given = {p.name: p for p in fit if isinstance(p, FitParameter)}
    return [given.get(p.name, p) for p in parse_fit(names, model, part=part)]


def with_bounds(fit: Sequence[FitParameter], text: str) -> list[FitParameter]:
    """Narrow the bounds of fitted parameters, e.g. ``v_air=250:290``.

    Parameters
    ----------
    fit : sequence of FitParameter
    text : str
        Comma-separated ``name=lower:upper`` in each parameter's unit, within its model's
        bounds; a side left empty keeps the model's.

    Returns
    -------
    list of FitParameter

    Raises
    ------
    InputError
        Not of that form, a parameter not fitted, or bounds outside the model's.
    """
    by_name = {p.name: p for p in fit}
    by_name.update({p.field: p for p in fit})
    new = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, sep, rng = item.partition("=")
        lo_text, sep2, hi_text = rng.partition(":")
        p = by_name.get(name.strip())
        if not (sep and sep2):
            raise InputError("command line", "--bounds", f"expected name=lower:upper, e.g. "
                             f"v_air=250:290, got {item!r}")
        if p is None:
            raise InputError("command line", "--bounds", f"{name.strip()!r} is not fitted "
                             f"(--fit {','.join(q.name for q in fit)})")
        try:
            lo = float(lo_text) if lo_text.strip() else p.lower
            hi = float(hi_text) if hi_text.strip() else p.upper
        except ValueError:
            raise InputError("command line", "--bounds", f"{item!r}: bounds must be numbers "
                             f"in {p.unit}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and p.lower <= lo < hi <= p.upper):
            raise InputError("command line", "--bounds", f"{p.name} bounds {lo:g}:{hi:g} must "
                             f"increase within the model's {p.lower:g}:{p.upper:g} {p.unit}")
        new[p.name] = replace(p, lower=lo, upper=hi)
    return [new.get(p.name, p) for p in fit]


def parse_values(text: str, model: str, part: str = "brake") -> dict[str, float]:
    """Start values given on the command line, e.g. ``t_fill=4,t_app=0.5``.

    Parameters
    ----------
    text : str
        Comma-separated ``name=value`` of fittable parameters, in their units.
    model : str
        Model whose parameters may be named.
    part : {'brake', 'coupler'}

    Returns
    -------
    dict of str to float
        Field name -> value.

    Raises
    ------
    InputError
        Not of that form, or an unknown parameter.
    """
    known = _known(model, part)
    by_field = {p.field: p for p in known.values()}
    out = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, sep, value = item.partition("=")
        p = known.get(name.strip()) or by_field.get(name.strip())
        if not sep or p is None:
            raise InputError("command line", "--set", f"expected name=value with a parameter "
                             f"of {', '.join(known)}, got {item!r}")
        try:
            out[p.field] = float(value)
        except ValueError:
            raise InputError("command line", "--set", f"{item!r}: the value must be a number "
                             f"in {p.unit}") from None
        if not math.isfinite(out[p.field]):
            raise InputError("command line", "--set", f"{item!r}: the value must be finite")
    return out


def _field_comment(params: BrakeParams, name: str) -> str:
    """Meaning and unit of a parameter field, as its model declares them."""
    for part in (params.pneumatic, params.friction):
        declared = specs(type(part))
        if name in declared:
            return declared[name].doc
    raise KeyError(name)


def parse_fit(text: str | Sequence[str], model: str = brakes.DEFAULT_MODEL, *,
              part: str = "brake") -> list[FitParameter]:
    """Parse the parameters to fit.

    Parameters
    ----------
    text : str or sequence of str
        Comma-separated names, short (``t_app``) or field names (``t_app_s``).
    model : str, optional
        Brake model (or coupler model, ``part`` coupler) whose parameters may be named
        (default: the paper's brake model).
    part : {'brake', 'coupler'}, optional

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
    known = _known(model, part)
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
                         + ",".join(known))
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

#: What one emergency stop yields for the fits, in this order: stopping distance [m], peak
#: draft force [kN] and its coupler, peak buff force magnitude [kN] and its coupler.
METRICS = ("stopping_distance_m", "peak_draft_kN", "peak_draft_coupler", "peak_buff_kN",
           "peak_buff_coupler")
DISTANCE, DRAFT, DRAFT_AT, BUFF, BUFF_AT = range(len(METRICS))

# Per-worker state, set once by the pool initializer, so that tasks carry only parameters.
_CASES: list[tuple[Consist, float]] = []
_LUT: CouplerLUT | None = None
_STEP_S = 0.01


def _init_worker(cases, lut, step_s) -> None:
    global _CASES, _LUT, _STEP_S
    _CASES, _LUT, _STEP_S = list(cases), lut, step_s


def _describe(params: BrakeParams, lut) -> str:
    """The fittable values of a trial point, for a failure message."""
    values = [f"{p.field}={getattr(params, p.field):.6g}"
              for p in fit_parameters(params.model).values()]
    if lut is not None:
        values += [f"{p.field}={getattr(lut, p.field):.6g}"
                   for p in coupler_fit_parameters(couplers.model_of(lut).NAME).values()]
    return ", ".join(values)


def _run_chunk(chunk) -> list[tuple[tuple, str | None]]:
    from .runs import emergency_stop
    from ..simulator import SimulationError

    out = []
    for params, lut, i in chunk:
        consist, speed = _CASES[i]
        try:
            r = emergency_stop(consist, speed, params, lut or _LUT, step_s=_STEP_S)
            out.append(((r.stopping_distance_m, r.peak_draft_kN, r.peak_draft_coupler,
                         -r.peak_buff_kN, r.peak_buff_coupler), None))
        except (SimulationError, CompileError, InputError) as exc:
            # a trial point the integrator cannot handle, or parameters that make no coupling
            # (a reshaped table beyond its bounds): the optimiser rejects it. Only the message
            # goes back, so that any exception reaches the parent process.
            out.append(((math.nan,) * len(METRICS),
                        f"{consist.name} from {speed:g} km/h with "
                        f"{_describe(params, lut)}: {exc}"))
    return out


class DistanceEvaluator:
    """Emergency stops of a fixed set of trains for many parameter sets, on one pool.

    Parameters
    ----------
    cases : sequence of (Consist, float)
        Trains and initial speeds [km/h].
    lut : CouplerLUT
        Coupler parameters of the runs that name none.
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
        #: Messages of the emergency stops that failed (their metrics are NaN).
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
        """Stopping distances of every case for every brake-parameter set.

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
        return self.metrics([(p, None) for p in param_sets], cases)[:, :, DISTANCE]

    def metrics(self, models: Sequence[tuple[BrakeParams, object]],
                cases: Sequence[int] | None = None) -> np.ndarray:
        """:data:`METRICS` of every case for every pair of brake and coupler parameters.

        Parameters
        ----------
        models : sequence of (BrakeParams, coupler Params or None)
            None: the evaluator's coupler parameters.
        cases : sequence of int, optional
            Indices into the evaluator's cases (default: all).

        Returns
        -------
        ndarray, shape (len(models), len(cases), len(METRICS))
            NaN where the simulation failed (see ``failures``).
        """
        idx = list(range(len(self.cases))) if cases is None else list(cases)
        jobs = [(a, b) for a in range(len(models)) for b in range(len(idx))]
        out = np.empty((len(models), len(idx), len(METRICS)))
        for chunk, values in self._run(jobs, models, idx):
            for (a, b), (v, err) in zip(chunk, values):
                out[a, b] = v
                if err:
                    self.failures.append(err)
        return out

    def _run(self, jobs, models, idx):
        def payload(chunk):
            return [(*models[a], idx[b]) for a, b in chunk]

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

    from ..simulator import SimulationError

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
            from ..simulator import SimulationError

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


# --------------------------------------------------------------------------- coupler forces

#: Targets of the in-train forces against Tables 1-2 (printed by ``ltd-brake validate``):
#: relative tolerance of every peak draft and peak buff force, coupler positions within +-2,
#: stopping distances against LTDPoliTo at each initial speed [km/h] -> relative tolerance.
DRAFT_TOL = 0.10
BUFF_TOL = 0.20
POSITION_TOL = 2
DISTANCE_TOL = {100.0: 0.001, 50.0: 0.007}
#: Weight of a coupler position beyond its tolerance, per coupler, in the units of the force
#: residuals (force tolerances): a peak one coupler beyond its tolerance costs as much as a
#: force three tolerances off.
POSITION_WEIGHT = 3.0
#: A peak force error beyond this fraction of its tolerance costs :data:`MARGIN_WEIGHT` times
#: the excess on top: least squares alone would let one light train's small peak fall outside
#: its tolerance for a closer fit of the others.
TARGET_MARGIN = 0.9
MARGIN_WEIGHT = 10.0
#: Residuals per run of :func:`force_residuals`.
FORCE_RESIDUALS = 7
#: Largest draft the trains of :func:`snatch_trains` may reach with the fitted coupler [N]:
#: 500 kN, well below the 850 kN breaking load of a screw coupling (EN 15566, UIC 520).
DRAFT_LIMIT_N = 500e3
#: Weight of a draft above the limit, per fraction of the limit, in the units of the force
#: residuals.
LIMIT_WEIGHT = 10.0


def snatch_trains() -> list[tuple[Consist, float]]:
    """The trains whose draft snatches a coupler fit must keep below a limit.

    E402B + 34 to 40 Shimmns (50 t and 80 t) from 40 km/h and 38 and 40 light wagons from
    50 km/h: among E402B + 10-40 Shimmns braked from 40-120 km/h, the runs whose draft peaks
    near the tail as the train stops (up to 1.9 MN with the Fig. 4 reconstruction).

    Returns
    -------
    list of (Consist, float)
        Trains and initial speeds [km/h].
    """
    from ..inputs import consist_from_mapping

    def train(n: int, mass_t: float) -> Consist:
        return consist_from_mapping({"name": f"E402B + {n} Shimmns ({mass_t:g} t)", "vehicles": [
            {"type": "E402B"}, {"type": "Shimmns", "count": n, "mass_t": mass_t}]},
            f"<snatch {n} x {mass_t:g} t>")

    return ([(train(n, m), 40.0) for m in (50.0, 80.0) for n in (34, 36, 38, 40)]
            + [(train(n, 50.0), 50.0) for n in (38, 40)])


def limit_residuals(metrics: np.ndarray, limit_N: float = DRAFT_LIMIT_N) -> np.ndarray:
    """Penalty of peak drafts above a limit: :data:`LIMIT_WEIGHT` times the excess fraction.

    Parameters
    ----------
    metrics : ndarray, shape (k, runs, len(METRICS))
    limit_N : float, optional

    Returns
    -------
    ndarray, shape (k, runs)
    """
    excess = metrics[..., DRAFT] * 1e3 / limit_N - 1.0
    return LIMIT_WEIGHT * np.where(np.isfinite(excess), np.maximum(excess, 0.0), np.nan)


def force_residuals(metrics: np.ndarray, scenarios: Sequence) -> np.ndarray:
    """Residuals of the coupler-force fit, :data:`FORCE_RESIDUALS` per run, in fractions of
    the targets.

    Per run: the peak draft error over :data:`DRAFT_TOL`, the peak buff error over
    :data:`BUFF_TOL` (both relative to the paper), each peak's position beyond
    :data:`POSITION_TOL` couplers times :data:`POSITION_WEIGHT`, the stopping-distance
    error beyond its tolerance (:data:`DISTANCE_TOL`) over that tolerance, and the draft and
    buff errors beyond :data:`TARGET_MARGIN` of their tolerances times
    :data:`MARGIN_WEIGHT`: positions, distances and the margins are constraints that cost
    nothing inside them.

    Parameters
    ----------
    metrics : ndarray, shape (k, runs, len(METRICS))
    scenarios : sequence of Scenario

    Returns
    -------
    ndarray, shape (k, FORCE_RESIDUALS * runs)
    """
    p = np.array([[s.paper["ltdpolito_m"], s.paper["draft_kN"], s.paper["draft_coupler"],
                   s.paper["buff_kN"], s.paper["buff_coupler"]] for s in scenarios], float)
    tol_d = np.array([DISTANCE_TOL.get(float(s.speed_kmh), 0.007) for s in scenarios])
    r = np.empty(metrics.shape[:2] + (FORCE_RESIDUALS,))
    r[..., 0] = (metrics[..., DRAFT] - p[:, DRAFT]) / p[:, DRAFT] / DRAFT_TOL
    r[..., 1] = (metrics[..., BUFF] - p[:, BUFF]) / p[:, BUFF] / BUFF_TOL
    for k, (col, at) in enumerate(((DRAFT_AT, DRAFT_AT), (BUFF_AT, BUFF_AT)), start=2):
        beyond = np.abs(metrics[..., col] - p[:, at]) - POSITION_TOL
        r[..., k] = POSITION_WEIGHT * np.where(np.isfinite(beyond), np.maximum(beyond, 0.0),
                                               np.nan)
    e = np.abs(metrics[..., DISTANCE] - p[:, DISTANCE]) / p[:, DISTANCE]
    r[..., 4] = np.where(np.isfinite(e), np.maximum(e - tol_d, 0.0), np.nan) / tol_d
    for k in (0, 1):
        r[..., 5 + k] = MARGIN_WEIGHT * np.maximum(np.abs(r[..., k]) - TARGET_MARGIN, 0.0)
    return r.reshape(metrics.shape[0], -1)


@dataclass(kw_only=True)
class CouplerCalibration(FitOutcome):
    """Outcome of :func:`calibrate_couplers`: a :class:`FitOutcome` (its residuals in fractions
    of the targets, see :func:`force_residuals`) and the forces.

    Attributes
    ----------
    scenarios : list of Scenario
        The runs of Tables 1-2 fitted.
    start, params : coupler Params
        Start values as given (the fit starts from them clipped into the bounds) and fitted
        values (rounded to :data:`WRITE_DIGITS` digits).
    brake : BrakeParams
        Brake parameters of every run.
    before, after : ndarray, shape (runs, len(METRICS))
        :data:`METRICS` at the start and fitted values.
    cv : ndarray, shape (runs, len(METRICS))
        Leave-one-train-out: each run simulated with the values fitted without its train
        (NaN: not done).
    limits : list of (Consist, float)
        Trains whose peak draft was held below ``draft_limit_N``.
    limit_before, limit_after : ndarray, shape (len(limits), len(METRICS))
        Their :data:`METRICS` at the start and fitted values.
    draft_limit_N : float
    """

    scenarios: list
    start: object
    params: object
    brake: BrakeParams
    before: np.ndarray
    after: np.ndarray
    cv: np.ndarray
    limits: list = field(default_factory=list)
    limit_before: np.ndarray | None = None
    limit_after: np.ndarray | None = None
    draft_limit_N: float = DRAFT_LIMIT_N

    def error_percent(self, which: str = "after") -> np.ndarray:
        """Peak draft and buff errors against the paper, shape (runs, 2) [%]."""
        m = getattr(self, which)
        paper = np.array([[s.paper["draft_kN"], s.paper["buff_kN"]] for s in self.scenarios])
        return 100.0 * (m[:, [DRAFT, BUFF]] - paper) / paper


def calibrate_couplers(scenarios: Sequence, fit: Sequence[FitParameter | str],
                       start=None, brake: BrakeParams | None = None, *, step_s: float = 0.01,
                       workers: int | None = None, progress=None, max_nfev: int = 60,
                       diff_step: float = 2e-2, stats_step: float = 5e-2,
                       evaluator: DistanceEvaluator | None = None,
                       keep_correlated: bool = True,
                       cross_validate: bool = False,
                       limits: Sequence[tuple[Consist, float]] = (),
                       draft_limit_N: float = DRAFT_LIMIT_N) -> CouplerCalibration:
    """Fit coupler parameters to the paper's peak in-train forces of Tables 1-2.

    Minimises the squares of :func:`force_residuals`: the relative peak draft and buff errors
    in fractions of their tolerances, with the coupler positions and the stopping distances
    as constraints that cost only beyond their tolerances, within the bounds the coupler
    model's ``FITTABLE`` declares (see :func:`coupler_fit_parameters`).

    Parameters
    ----------
    scenarios : sequence of Scenario
    fit : sequence of FitParameter or str
        Coupler parameters to fit, in order of priority.
    start : coupler Params, optional
        Start values (default: the shipped coupler file).
    brake : BrakeParams, optional
        Brake parameters of the runs (default: the ``paper`` preset).
    step_s, workers, progress, max_nfev, stats_step, evaluator, keep_correlated, cross_validate
        As :func:`calibrate`; an evaluator's cases must start with the scenarios' trains.
    diff_step : float, optional
        Forward-difference step, relative to each parameter's typical magnitude [-]: a peak
        force moves with the scales smoothly only over steps that outgrow the integration
        step's jitter.
    limits : sequence of (Consist, float), optional
        Further trains and initial speeds [km/h] whose peak draft must stay below
        ``draft_limit_N`` (see :func:`snatch_trains`): a penalty (:func:`limit_residuals`)
        in every fit, refits included; an evaluator's cases hold them after the scenarios.
    draft_limit_N : float, optional

    Returns
    -------
    CouplerCalibration
    """
    original = start = start or load_coupler_lut()
    brake = brake or load_brake_params()
    fit = _resolve(fit, couplers.model_of(start).NAME, part="coupler")
    scenarios = list(scenarios)
    given = {p.name: float(getattr(start, p.field)) for p in fit}
    start = replace(start, **{p.field: float(np.clip(given[p.name], p.lower, p.upper))
                              for p in fit})
    m = len(scenarios)
    extra = list(range(m, m + len(limits)))
    own = evaluator is None
    if own:
        evaluator = DistanceEvaluator([(s.consist(), s.speed_kmh) for s in scenarios]
                                      + list(limits), start, step_s=step_s, workers=workers,
                                      progress=progress)

    def coupler_at(chosen, x):
        return replace(start, **{p.field: float(v) for p, v in zip(chosen, x)})

    def metrics_of(rows, chosen, xs) -> np.ndarray:
        return evaluator.metrics([(brake, coupler_at(chosen, x)) for x in xs], rows)

    def batch_of(rows: Sequence[int], chosen: list):
        sel = [scenarios[i] for i in rows]

        def batch(xs) -> np.ndarray:
            r = metrics_of(list(rows) + extra, chosen, xs)
            return np.hstack([force_residuals(r[:, :len(rows)], sel),
                              limit_residuals(r[:, len(rows):], draft_limit_N)])
        return batch

    every = list(range(m))
    try:
        before = evaluator.metrics([(brake, original)], every + extra)[0]
        fit, out, stats, held, refits = _fit_targets(
            fit, given, batch_of, m, [evaluator.cases[i][0] for i in every], evaluator,
            max_nfev=max_nfev, diff_step=diff_step, stats_step=stats_step, progress=progress,
            keep_correlated=keep_correlated, cross_validate=cross_validate,
            label="max |residual| / target", observations=2 * m)
        after = metrics_of(every + extra, fit, [out.x])[0]
        limit_before, limit_after = before[m:], after[m:]
        before, after = before[:m], after[:m]
        cv = np.full_like(after, np.nan)
        for g, x in refits:
            if x is not None:
                cv[g] = metrics_of(g, fit, [x])[0]
        runs = evaluator.runs
    finally:
        if own:
            evaluator.close()
    return CouplerCalibration(scenarios=scenarios, start=original, params=coupler_at(fit, out.x),
                              brake=brake, before=before, after=after, cv=cv,
                              limits=list(limits), limit_before=limit_before,
                              limit_after=limit_after, draft_limit_N=draft_limit_N,
                              **_outcome(fit, out, stats, runs, held))


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
             "| after m | after err | left out err |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    eb, ea, ec = cal.before_error_percent, cal.after_error_percent, cal.cv_error_percent
    for i, t in enumerate(cal.targets):
        lines.append(f"| {t.label} | {t.consist.name} | {t.speed_kmh:g} | {t.lambda_percent:.1f} "
                     f"| {t.reference} | {t.distance_m:.1f} | {cal.before_m[i]:.1f} | "
                     f"{_pct(eb[i])} | {cal.after_m[i]:.1f} | {_pct(ea[i])} | {_pct(ec[i])} |")
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
    """Largest and RMS errors before, after and left out, one line each."""
    eb, ea, ec = cal.before_error_percent, cal.after_error_percent, cal.cv_error_percent
    out = [f"largest |error|: before {np.abs(eb).max():.2f} %, after {np.abs(ea).max():.2f} %",
           f"RMS error:       before {np.sqrt(np.mean(eb ** 2)):.2f} %, after "
           f"{np.sqrt(np.mean(ea ** 2)):.2f} %"]
    if np.any(np.isfinite(ec)):
        out.append(f"leave-one-train-out: largest |error| {np.nanmax(np.abs(ec)):.2f} %, RMS "
                   f"{np.sqrt(np.nanmean(ec ** 2)):.2f} % (each train predicted by the values "
                   "fitted to the others)")
    return out


def force_table(cal: "CouplerCalibration") -> str:
    """Markdown table of the peak forces before and after a coupler fit, and left out.

    Parameters
    ----------
    cal : CouplerCalibration

    Returns
    -------
    str
    """
    lines = ["| No. | train | V0 km/h | draft kN@c paper | before | after | error | left out "
             "| buff kN@c paper | before | after | error | left out | distance vs LTDPoliTo |",
             "|" + "---|" * 14]
    eb, ea, ec = (cal.error_percent(w) for w in ("before", "after", "cv"))
    for i, s in enumerate(cal.scenarios):
        p, b, a = s.paper, cal.before[i], cal.after[i]
        d = 100 * (a[DISTANCE] - p["ltdpolito_m"]) / p["ltdpolito_m"]
        lines.append(
            f"| {s.number} | {Path(s.consist_file).stem} | {s.speed_kmh:g} "
            f"| {p['draft_kN']}@{p['draft_coupler']} | {b[DRAFT]:.0f}@{b[DRAFT_AT]:.0f} "
            f"| {a[DRAFT]:.0f}@{a[DRAFT_AT]:.0f} | {_pct(ea[i, 0])} | {_pct(ec[i, 0])} "
            f"| {p['buff_kN']}@{p['buff_coupler']} | {b[BUFF]:.0f}@{b[BUFF_AT]:.0f} "
            f"| {a[BUFF]:.0f}@{a[BUFF_AT]:.0f} | {_pct(ea[i, 1])} | {_pct(ec[i, 1])} "
            f"| {_pct(d)} |")
    return "\n".join(lines)


def limit_lines(cal: "CouplerCalibration") -> list[str]:
    """One line per train held below the draft limit: its peak draft before and after."""
    out = []
    for (c, v), b, a in zip(cal.limits, cal.limit_before, cal.limit_after):
        out.append(f"{c.name} from {v:g} km/h: peak draft {b[DRAFT]:.0f}@{b[DRAFT_AT]:.0f} -> "
                   f"{a[DRAFT]:.0f}@{a[DRAFT_AT]:.0f} kN (limit {cal.draft_limit_N / 1e3:g} kN)")
    return out


def force_summary_lines(cal: "CouplerCalibration") -> list[str]:
    """Largest draft and buff errors before, after and left out, one line each."""
    out = []
    for k, (name, tol) in enumerate((("draft", DRAFT_TOL), ("buff", BUFF_TOL))):
        parts = []
        for which in ("before", "after", "cv"):
            e = cal.error_percent(which)[:, k]
            if np.any(np.isfinite(e)):
                parts.append(f"{ {'cv': 'left out'}.get(which, which)} "
                             f"{np.nanmin(e):+.1f}..{np.nanmax(e):+.1f} %")
        out.append(f"peak {name} vs the paper (target +/-{100 * tol:g} %): " + ", ".join(parts))
    return out


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


def _held_and_warnings(cal) -> list[str]:
    """Comment lines of the parameters held at their start values and of the warnings."""
    head = []
    for w in cal.warnings:
        head += textwrap.wrap(f"warning: {w}", 98, initial_indent="# ",
                              subsequent_indent="#   ")
    return head


def _fitted_lines(cal) -> list[str]:
    """Comment lines of the fitted values with their 95 % confidence half-widths."""
    head = [f"# Fitted values, 95 % confidence half-widths (Student t, {max(cal.dof, 0)} dof, "
            "(J^T J)^-1 s^2):"]
    for j, p in enumerate(cal.fit):
        ci = cal.ci95[j]
        if p.name in cal.at_bound:
            head.append(f"#   {p.field} = {cal.value(p):.5g} {p.unit} (on its bound)")
        else:
            head.append(f"#   {p.field} = {cal.value(p):.5g} +/- "
                        f"{'NA' if not np.isfinite(ci) else f'{ci:.2g}'}"
                        f"{'' if p.unit == '-' else ' ' + p.unit}"
                        f"  (bounds {p.lower:.4g} to {p.upper:.4g})")
    return head


def _file_value(value, spec) -> str:
    """A field's value in its file unit, as YAML."""
    if isinstance(value, bool):
        return str(value).lower()
    if spec.sequence:
        return "[" + ", ".join(f"{v / spec.scale:.{WRITE_DIGITS}g}" for v in value) + "]"
    return f"{float(value) / spec.scale:.{WRITE_DIGITS}g}"


def coupler_file_text(cal: "CouplerCalibration", command: str) -> str:
    """Coupler YAML of the fitted values, headed by how they were produced.

    Parameters
    ----------
    cal : CouplerCalibration
    command : str
        The command line that produced it.

    Returns
    -------
    str
        A document that :func:`~ltd_brake_ros.inputs.load_coupler_lut` accepts.
    """
    head = ["# Coupler characteristic calibrated against the peak draft and buff forces of the",
            "# paper's Tables 1-2 (positions and LTDPoliTo distances as constraints), by least",
            "# squares on the force errors in fractions of their targets (draft "
            f"+/-{100 * DRAFT_TOL:g} %, buff +/-{100 * BUFF_TOL:g} %).",
            "# Produced by:", f"#   {command}",
            f"# Start values: {display_path(cal.start.source)}; brake parameters: "
            f"{display_path(cal.brake.source)}.",
            "# Peak forces at the values below, kN@coupler (paper, ours, error, left out: "
            "fitted without the train):"]
    ea, ec = cal.error_percent("after"), cal.error_percent("cv")
    for i, s in enumerate(cal.scenarios):
        p, a = s.paper, cal.after[i]
        head.append(f"#   run {s.number:>2} draft {p['draft_kN']:>3}@{p['draft_coupler']:<2} "
                    f"{a[DRAFT]:4.0f}@{a[DRAFT_AT]:<2.0f} {_pct(ea[i, 0]):>9} "
                    f"({_pct(ec[i, 0])})  buff {p['buff_kN']:>3}@{p['buff_coupler']:<2} "
                    f"{a[BUFF]:4.0f}@{a[BUFF_AT]:<2.0f} {_pct(ea[i, 1]):>9} ({_pct(ec[i, 1])})")
    if cal.limits:
        head.append("# Held below the draft limit (start -> fitted):")
        head += [f"#   {line}" for line in limit_lines(cal)]
    head += _fitted_lines(cal)
    model = couplers.model_of(cal.params)
    if model is lut_hysteresis:
        head.append(f"# Energy one buffer stores over its 105 mm stroke: "
                    f"{lut_hysteresis.buffer_energy_J(cal.params) / 1e3:.1f} kJ (UIC 526-1 / "
                    "EN 15551 categories: A 30, B 50, C 70 kJ).")
    head += _held_and_warnings(cal)
    body = [] if model.NAME == couplers.DEFAULT_MODEL else [f"model: {model.NAME}"]
    stem = Path(cal.start.source).stem if cal.start.source else model.NAME
    body.append(f"name: {stem} calibrated to the peak forces of Tables 1-2")
    defaults = {f.name: f.default for f in dataclasses.fields(cal.params)}
    for name, spec in specs(type(cal.params)).items():
        value = getattr(cal.params, name)
        if not spec.sequence and value == defaults[name] and not math.isfinite(value):
            continue  # an unknown strength stays unknown
        body.append(f"{spec.key or name}: {_file_value(value, spec)}  # {spec.doc}")
    return "\n".join(head + body) + "\n"


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
        cv = cal.cv_error_percent[i]
        head.append(f"#   {name:<{wn}}  {t.consist.name:<{wc}}  lambda {t.lambda_percent:5.1f} %  "
                    f"ref {t.distance_m:6.1f} m  sim {cal.after_m[i]:6.1f} m  "
                    f"{cal.after_error_percent[i]:+.2f} %"
                    + (f"  (left out {cv:+.2f} %)" if np.isfinite(cv) else "")
                    + (f"  ({t.reference})" if len(ref) > 1 else ""))
    head += _fitted_lines(cal)
    head += _held_and_warnings(cal)
    return "\n".join(head + parameter_lines(cal.params)) + "\n"


def parameter_lines(params: BrakeParams) -> list[str]:
    """Every field of a brake-parameter set as brake-parameter YAML lines, with their meaning.

    Keys and units are the file's (a field declared with ``key=``/``scale=`` is written as
    the file reads it), so the lines alone reproduce ``params``.

    Parameters
    ----------
    params : BrakeParams

    Returns
    -------
    list of str
    """
    body = [] if params.model == brakes.DEFAULT_MODEL else [f"model: {params.model}"]
    fields = [(name, spec) for part in (params.pneumatic, params.friction)
              for name, spec in specs(type(part)).items()]
    width = max(len(spec.key or name) for name, spec in fields) + 2
    for name, spec in fields:
        value = _file_value(getattr(params, name), spec)
        body.append(f"{(spec.key or name) + ':':<{width}} {value:<10} "
                    f"# {_field_comment(params, name)}")
    return body


# --------------------------------------------------------------------------- targets


def validation_targets(rows) -> list[tuple[str, bool, str]]:
    """The in-train force and distance targets against Tables 1-2, checked on validation rows.

    Parameters
    ----------
    rows : list of ValidationRow

    Returns
    -------
    list of (str, bool, str)
        Criterion, met, and the worst case in words; criteria without a row to check are left
        out.
    """
    out = []

    def worst(values, label, digits=1):
        k = int(np.argmax([abs(v) for v, _ in values]))
        return f"worst {values[k][0]:+.{digits}f}{label} (run {values[k][1]})"

    draft = [(100 * (r.result.peak_draft_kN - r.scenario.paper["draft_kN"])
              / r.scenario.paper["draft_kN"], r.scenario.number) for r in rows]
    buff = [(100 * (-r.result.peak_buff_kN - r.scenario.paper["buff_kN"])
             / r.scenario.paper["buff_kN"], r.scenario.number) for r in rows]
    pos = [(r.result.peak_draft_coupler - r.scenario.paper["draft_coupler"], r.scenario.number)
           for r in rows] + [(r.result.peak_buff_coupler - r.scenario.paper["buff_coupler"],
                              r.scenario.number) for r in rows]
    if rows:
        out.append((f"peak draft within +/-{100 * DRAFT_TOL:g} % of the paper",
                    all(abs(v) <= 100 * DRAFT_TOL for v, _ in draft), worst(draft, " %")))
        out.append((f"peak buff within +/-{100 * BUFF_TOL:g} % of the paper",
                    all(abs(v) <= 100 * BUFF_TOL for v, _ in buff), worst(buff, " %")))
        out.append((f"peak positions within +/-{POSITION_TOL} couplers of the paper",
                    all(abs(v) <= POSITION_TOL for v, _ in pos), worst(pos, " couplers")))
    for speed, tol in sorted(DISTANCE_TOL.items(), reverse=True):
        dist = [(r.distance_error_percent, r.scenario.number) for r in rows
                if r.scenario.speed_kmh == speed]
        if dist:
            out.append((f"stopping distance within +/-{100 * tol:g} % of LTDPoliTo at "
                        f"{speed:g} km/h", all(abs(v) <= 100 * tol for v, _ in dist),
                        worst(dist, " %", 2)))
    return out

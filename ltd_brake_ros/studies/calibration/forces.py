"""Fitting a coupler to the paper's peak in-train forces (Tables 1-2)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ...inputs import BrakeParams, Consist, load_brake_params, load_coupler_lut
from ...physics import couplers
from .parameters import FitParameter, _resolve
from .evaluation import BUFF, BUFF_AT, DISTANCE, DRAFT, DRAFT_AT, DistanceEvaluator
from .fit import FitOutcome, _fit_targets, _outcome


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
    from ...inputs import consist_from_mapping

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

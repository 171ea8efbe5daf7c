"""Sensitivity of a designed campaign's KPIs to its inputs: Sobol' indices of a Saltelli design
and Morris's elementary effects, per manoeuvre and KPI, computed with SALib.

A ``sobol`` campaign runs Saltelli's design (Saltelli 2002; Saltelli et al. 2010): N blocks of
2 D + 2 runs (D + 2 without second-order indices) for D inputs. Its first-order index S1 of an
input is the share of the KPI's variance that the input explains alone, the total index ST the
share it takes part in, interactions included (Sobol' 2001); ST = 0 means the KPI does not
depend on the input over its distribution. A ``morris`` campaign runs r trajectories of D + 1
runs on p levels (Morris 1991): per input, mu* is the mean absolute elementary effect (the
input's importance, Campolongo et al. 2007), mu the mean (its sign says the direction) and
sigma their standard deviation (non-linearity or interaction).

The inputs vary on the probability scale: input j of run i is the probability at which its
distribution's inverse CDF is taken (:func:`~ltd_brake_ros.studies.campaign.design_sample`).
Morris's elementary effects are per whole level range, so mu*, mu and sigma are in the KPI's
unit: about the change of the KPI when the input moves from its lowest level (probability
0.5 / p) to its highest (1 - 0.5 / p).

SALib needs every run of a block: a block (a Saltelli block, a Morris trajectory) with a failed
run, a run without a value of the KPI (a service application after which the train does not
stop) or a run that the results folder does not hold yet is left out of that KPI's analysis,
and the report says how many blocks were left out and why. Intervals are SALib's bootstrap
intervals, the estimate plus or minus z times the standard deviation of the resampled
estimates (over the blocks), at the report's confidence.

References
----------
Morris, M. D. (1991). Factorial sampling plans for preliminary computational experiments.
*Technometrics* 33(2), 161-174.
Sobol', I. M. (2001). Global sensitivity indices for nonlinear mathematical models and their
Monte Carlo estimates. *Mathematics and Computers in Simulation* 55, 271-280.
Saltelli, A. (2002). Making best use of model evaluations to compute sensitivity indices.
*Computer Physics Communications* 145(2), 280-297.
Campolongo, F., Cariboni, J. and Saltelli, A. (2007). An effective screening design for
sensitivity analysis of large models. *Environmental Modelling & Software* 22(10), 1509-1518.
Saltelli, A. et al. (2010). Variance based sensitivity analysis of model output. Design and
estimator for the total sensitivity index. *Computer Physics Communications* 181(2), 259-270.
Herman, J. and Usher, W. (2017). SALib: An open-source Python library for sensitivity
analysis. *Journal of Open Source Software* 2(9), 97.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..inputs import InputError
from ..studies.campaign import COLUMNS
from .campaign_kpis import KPIS, NO_VALUE

__all__ = ["RESAMPLES", "analyze_morris", "analyze_sobol", "complete_blocks", "design_note",
           "format_sensitivity", "sensitivity_report"]

#: Bootstrap resamples of SALib's intervals.
RESAMPLES = 1000
#: Designs whose indices the report computes.
ANALYSED = ("sobol", "morris")


def _salib():
    """SALib's analyses, or one line when SALib is missing."""
    try:
        from SALib.analyze import morris, sobol
    except ImportError:
        raise InputError("SALib", "", "not installed; the sensitivity indices of a sobol or "
                         "morris campaign need it: pip install 'ltd_brake_ros[campaign]'") \
            from None
    return sobol, morris


def _problem(inputs) -> dict:
    d = len(inputs)
    return {"num_vars": d, "names": list(inputs), "bounds": [[0.0, 1.0]] * d}


def _salib_seed(seed: int) -> int:
    """SALib's Sobol' analysis seeds its bootstrap only with a non-zero seed."""
    return int(seed) + 1


def complete_blocks(y: np.ndarray, block: int) -> np.ndarray:
    """Which blocks of ``block`` consecutive runs have a finite value in every run.

    Parameters
    ----------
    y : ndarray
        One value per run of the design, NaN where a run failed, has no value or is missing.
    block : int
        Runs per block.

    Returns
    -------
    ndarray of bool
        One per block.
    """
    return np.isfinite(np.asarray(y, float)).reshape(-1, block).all(axis=1)


def _interval(estimate: float, half: float) -> list:
    return [estimate - half, estimate + half]


def analyze_sobol(y: np.ndarray, inputs, second_order: bool = True, confidence: float = 0.95,
                  seed: int = 0, resamples: int = RESAMPLES) -> dict:
    """Sobol' indices of one KPI from the runs of a Saltelli design.

    Parameters
    ----------
    y : ndarray
        The KPI of every run, in the design's order (N (2 D + 2) values, N (D + 2) without
        second-order indices); NaN where a run has no value. Blocks with a NaN are left out.
    inputs : sequence of str
        Names of the D inputs.
    second_order : bool, optional
        The design holds the second-order blocks.
    confidence : float, optional
        Two-sided confidence of the intervals.
    seed : int, optional
        Seed of the bootstrap (the indices are reproducible).
    resamples : int, optional
        Bootstrap resamples.

    Returns
    -------
    dict
        ``blocks`` (N), ``complete_blocks`` (those analysed), ``note`` (why nothing was
        computed, else empty) and ``indices``: per input ``S1`` and ``ST`` (shares of the
        KPI's variance, dimensionless) with ``S1_interval`` and ``ST_interval``; ``S2``: per
        pair of inputs ``inputs``, ``S2`` and ``S2_interval`` (second order only).
    """
    d = len(inputs)
    block = 2 * d + 2 if second_order else d + 2
    y = np.asarray(y, float)
    keep = complete_blocks(y, block)
    out = {"blocks": len(keep), "complete_blocks": int(keep.sum()), "note": "",
           "indices": {}, "S2": []}
    values = y.reshape(-1, block)[keep].ravel()
    if keep.sum() < 2:
        out["note"] = "fewer than 2 complete blocks: no index"
        return out
    if np.ptp(values) == 0.0:
        out["note"] = "the KPI does not vary over the design: every index is 0 / 0"
        return out
    sobol, _ = _salib()
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        s = sobol.analyze(_problem(inputs), values, calc_second_order=second_order,
                          num_resamples=resamples, conf_level=confidence,
                          print_to_console=False, seed=_salib_seed(seed))
    for j, name in enumerate(inputs):
        out["indices"][name] = {
            "S1": float(s["S1"][j]), "S1_interval": _interval(s["S1"][j], s["S1_conf"][j]),
            "ST": float(s["ST"][j]), "ST_interval": _interval(s["ST"][j], s["ST_conf"][j])}
    if second_order:
        out["S2"] = [{"inputs": [a, inputs[k]], "S2": float(s["S2"][j, k]),
                      "S2_interval": _interval(s["S2"][j, k], s["S2_conf"][j, k])}
                     for j, a in enumerate(inputs) for k in range(j + 1, d)]
    return out


def analyze_morris(x: np.ndarray, y: np.ndarray, inputs, levels: int,
                   confidence: float = 0.95, seed: int = 0,
                   resamples: int = RESAMPLES) -> dict:
    """Morris's elementary-effect statistics of one KPI from the runs of its trajectories.

    Parameters
    ----------
    x : ndarray
        The design's sample, (r (D + 1), D), on the levels k / (p - 1)
        (:func:`~ltd_brake_ros.studies.campaign.design_sample`).
    y : ndarray
        The KPI of every run, in the design's order; NaN where a run has no value.
        Trajectories with a NaN are left out.
    inputs : sequence of str
        Names of the D inputs.
    levels : int
        The levels p of the design.
    confidence : float, optional
        Two-sided confidence of the interval of mu*.
    seed : int, optional
        Seed of the bootstrap.
    resamples : int, optional
        Bootstrap resamples.

    Returns
    -------
    dict
        ``blocks`` (trajectories r), ``complete_blocks``, ``note`` and ``indices``: per input
        ``mu_star`` with ``mu_star_interval``, ``mu`` and ``sigma``, in the KPI's unit per
        whole level range.
    """
    d = len(inputs)
    y = np.asarray(y, float)
    keep = complete_blocks(y, d + 1)
    out = {"blocks": len(keep), "complete_blocks": int(keep.sum()), "note": "", "indices": {}}
    if not keep.any():
        out["note"] = "no complete trajectory: no effect"
        return out
    rows = np.repeat(keep, d + 1)
    _, morris = _salib()
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        s = morris.analyze(_problem(inputs), np.asarray(x, float)[rows], y[rows],
                           num_resamples=resamples, conf_level=confidence,
                           print_to_console=False, num_levels=levels, seed=_salib_seed(seed))
    for j, name in enumerate(inputs):
        mu_star, half = float(s["mu_star"][j]), float(s["mu_star_conf"][j])
        out["indices"][name] = {"mu_star": mu_star, "mu_star_interval": _interval(mu_star, half),
                                "mu": float(s["mu"][j]), "sigma": float(s["sigma"][j])}
    return out


def _values(table, kpi: str) -> np.ndarray:
    """The KPI of each row as floats, NaN where the run failed or has no value."""
    if kpi not in table.column_names:
        return np.full(table.num_rows, np.nan)
    x = np.array(table[kpi].to_numpy(zero_copy_only=False), float)
    x[np.array(table["status"].to_pylist()) != "ok"] = np.nan
    return x


def _missing(table, kpi: str, runs: int, block: int, keep: np.ndarray, ids: np.ndarray) -> dict:
    """Why the blocks left out of a KPI's analysis are incomplete: runs failed, without a
    value, not in the results."""
    dropped = np.repeat(~keep, block)
    ok = np.array(table["status"].to_pylist()) == "ok"
    finite = np.isfinite(_values(table, kpi))
    present = np.zeros(runs, bool)
    present[ids] = True
    in_dropped = dropped[ids]
    return {"failed": int((~ok & in_dropped).sum()),
            "no_value": int((ok & ~finite & in_dropped).sum()),
            "no_value_reason": NO_VALUE.get(kpi, "no value"),
            "not_in_results": int((~present & dropped).sum())}


def design_note(kind: str) -> str:
    """The warning that the quantiles of a designed campaign describe its runs only."""
    return (f"sampling {kind}: the runs are a designed experiment, not a random sample of the "
            "family's trains; the quantiles and exceedances describe the design's runs")


def sensitivity_report(folder, meta: dict, table, *, confidence: float = 0.95, seed: int = 0,
                       resamples: int = RESAMPLES) -> dict | None:
    """The design of a designed campaign and, for ``sobol`` and ``morris``, its indices.

    The design is rebuilt from the campaign file the results were made with (its digest is
    checked): its inputs, size and, for Morris, the sample (from the campaign's seed).

    Parameters
    ----------
    folder : path-like
        Results folder.
    meta : dict
        Its manifest.
    table : pyarrow.Table
        Its rows (:func:`~ltd_brake_ros.studies.campaign_exec.read_results`).
    confidence : float, optional
        Two-sided confidence of the intervals.
    seed : int, optional
        Seed of the bootstrap.
    resamples : int, optional
        Bootstrap resamples.

    Returns
    -------
    dict or None
        None for a random sample (``monte_carlo``, ``latin_hypercube``). Otherwise
        ``design`` (the kind), ``inputs``, ``dimensions`` (input -> the draws it sets),
        ``base_runs``, ``runs``, ``block``, ``second_order`` (sobol), ``levels`` (morris: p;
        grid: input -> levels, or ``{"points": n}``), ``confidence`` and ``manoeuvres``: name
        -> KPI -> :func:`analyze_sobol` or :func:`analyze_morris` with ``unit`` and
        ``missing`` (runs of the blocks left out: ``failed``, ``no_value``,
        ``no_value_reason``, ``not_in_results``). ``error`` (a line) instead when the
        campaign file cannot be found.
    """
    kind = meta.get("sampling")
    if kind not in ("grid", *ANALYSED):
        return None
    from ..studies.campaign import design_sample
    from ..studies.campaign_rerun import campaign_of_results

    try:
        c = campaign_of_results(folder, meta)
    except InputError as exc:
        return {"design": kind, "error": f"the design cannot be rebuilt: {exc}"}
    d = c.design
    out = {"design": kind, "inputs": list(d.inputs),
           "dimensions": {n: list(x) for n, x in zip(d.inputs, d.dimensions)},
           "base_runs": d.base_runs, "runs": c.runs, "block": d.block,
           "confidence": confidence, "manoeuvres": {}}
    if kind == "grid":
        out["levels"] = {n: list(v) if mode == "levels" else {"points": v}
                         for n, (mode, v) in zip(d.inputs, d.grid)}
        return out
    if kind == "sobol":
        out["second_order"] = d.second_order
    else:
        out["levels"] = d.levels
    x = design_sample(c) if kind == "morris" else None
    ids_all = np.array(table["run_id"].to_pylist(), int)
    names = np.array(table["manoeuvre"].to_pylist(), dtype=object)
    for name in meta.get("manoeuvres") or sorted(set(names)):
        rows = np.flatnonzero(names == name)
        part = table.take(rows)
        ids = ids_all[rows]
        section = out["manoeuvres"][name] = {}
        for kpi in KPIS:
            y = np.full(c.runs, np.nan)
            y[ids] = _values(part, kpi)
            if not np.isfinite(y).any():
                continue  # no run has this KPI (no stop from 100 km/h): nothing to analyse
            if kind == "sobol":
                res = analyze_sobol(y, d.inputs, d.second_order, confidence, seed, resamples)
            else:
                res = analyze_morris(x, y, d.inputs, d.levels, confidence, seed, resamples)
            keep = complete_blocks(y, d.block)
            res.update(unit=COLUMNS[kpi][0],
                       missing=_missing(part, kpi, c.runs, d.block, keep, ids))
            section[kpi] = res
    return out


def _g(x) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.3g}"


def _cell(value, interval) -> str:
    return f"{_g(value)} [{_g(interval[0])}, {_g(interval[1])}]"


def _runs(n: int) -> str:
    return f"{n} run" if n == 1 else f"{n} runs"


def _blocks_text(res: dict, what: str) -> str:
    """``30 of 32 blocks; 2 left out: 3 runs failed, 1 without a value (did not stop)``."""
    text = f"{res['complete_blocks']} of {res['blocks']} {what}"
    left = res["blocks"] - res["complete_blocks"]
    if left:
        m = res["missing"]
        why = ([f"{_runs(m['failed'])} failed"] if m["failed"] else []) + (
            [f"{_runs(m['no_value'])} without a value: {m['no_value_reason']}"]
            if m["no_value"] else []) + (
            [f"{_runs(m['not_in_results'])} not in the results yet"] if m["not_in_results"]
            else [])
        text += f"; {left} left out: {', '.join(why)}"
    return text


def format_sensitivity(sens: dict) -> list[str]:
    """The design and its indices as lines of the report.

    Parameters
    ----------
    sens : dict
        From :func:`sensitivity_report`.

    Returns
    -------
    list of str
    """
    kind = sens["design"]
    if "error" in sens:
        return [f"sensitivity ({kind} design): not computed: {sens['error']}"]
    inputs = sens["inputs"]
    held = ("  the inputs vary on the probability scale (the inverse CDF of each distribution); "
            "the other draws are held: at their median, each wagon's those of train 0")
    if kind == "grid":
        levels = "; ".join(f"{n}: " + (", ".join(map(str, v)) if isinstance(v, list) else
                                       f"{v['points']} points at probabilities (k + 0.5) / "
                                       f"{v['points']}")
                           for n, v in sens["levels"].items())
        return [f"grid design: {sens['runs']} runs, {sens['base_runs']} replicate(s) of every "
                f"grid point (replicate j the same train at every point); levels {levels}"]
    c = 100 * sens["confidence"]
    if kind == "sobol":
        per = "2 D + 2" if sens["second_order"] else "D + 2"
        lines = [f"sensitivity: Sobol' indices, Saltelli's design of D = {len(inputs)} inputs "
                 f"({', '.join(inputs)}), N = {sens['base_runs']} blocks of {per} = "
                 f"{sens['block']} runs; S1 first order, ST total, as shares of the KPI's "
                 f"variance, with {c:g} % bootstrap intervals", held]
        what = "blocks"
    else:
        lines = [f"sensitivity: Morris's elementary effects, {sens['base_runs']} trajectories "
                 f"of D + 1 = {sens['block']} runs on {sens['levels']} levels of D = "
                 f"{len(inputs)} inputs ({', '.join(inputs)}); mu* (importance) with its "
                 f"{c:g} % bootstrap interval, mu (direction) and sigma (non-linearity or "
                 "interaction), in the KPI's unit per whole level range", held]
        what = "trajectories"
    width = max(len(n) for n in inputs) + 2
    for name, section in sens["manoeuvres"].items():
        lines.append(f"  manoeuvre {name}:")
        for kpi, res in section.items():
            lines.append(f"    {kpi} [{res['unit']}] ({_blocks_text(res, what)})"
                         + (f": {res['note']}" if res["note"] else ":"))
            if res["note"]:
                continue
            for n in inputs:
                v = res["indices"][n]
                if kind == "sobol":
                    lines.append(f"      {n:<{width}}S1 {_cell(v['S1'], v['S1_interval']):<32} "
                                 f"ST {_cell(v['ST'], v['ST_interval'])}")
                else:
                    lines.append(f"      {n:<{width}}mu* "
                                 f"{_cell(v['mu_star'], v['mu_star_interval']):<32} "
                                 f"mu {_g(v['mu']):<10} sigma {_g(v['sigma'])}")
            if res.get("S2"):  # only the pairs whose interval lies above 0 (all in --json)
                shown = [f"{e['inputs'][0]} x {e['inputs'][1]} "
                         f"{_cell(e['S2'], e['S2_interval'])}"
                         for e in res["S2"] if e["S2_interval"][0] > 0]
                lines.append("      S2 (second order, intervals above 0): " + (
                    "; ".join(shown) if shown else "none"))
    return lines

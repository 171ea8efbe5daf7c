"""Campaign report: quantiles with confidence intervals, exceedance probabilities, the worst
runs, CDF and histogram plots, and the relative approach against a reference family.

The relative approach (UIC 421 admits a new freight-train family by comparing it with one
already admitted) is a non-inferiority comparison of a tail quantile of each KPI: the
interval of the family's worsening against the reference, relative to the reference's
quantile (:mod:`.campaign_intervals`: distribution-free intervals of each quantile, Fieller's
interval of their ratio), is set against a margin (Wellek 2010; the three outcomes as Piaggio
et al. 2012, Fig. 2):

* ``not worse``: the whole interval lies below the margin;
* ``worse``: the whole interval lies above it (worse than the reference by more than the
  margin);
* ``inconclusive``: the interval holds the margin, or there is no interval (too few runs
  beyond the quantile).

Two families drawn with the same seed whose runs are the same trains (the reference with one
parameter changed) are *paired*: the correlation of their quantiles over the common runs
narrows the interval of the difference, removing the train-to-train scatter that both
share. Otherwise the two are independent samples.

Quantile levels count in each KPI's worse direction: ``q0.99`` is the value that a share
0.01 of the runs goes beyond, i.e. the 0.99 quantile of ``peak_draft_kN`` but the 0.01
quantile of ``peak_buff_kN`` (buff forces are negative, a more negative one is worse).

References
----------
Wellek, S. (2010). *Testing Statistical Hypotheses of Equivalence and Noninferiority*, 2nd ed.
CRC Press.
Piaggio, G. et al. (2012). Reporting of noninferiority and equivalence randomized trials:
extension of the CONSORT 2010 statement. *JAMA* 308(24), 2594-2604.
UIC 421 (2012). Rules for the consist and braking of international freight trains.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..inputs import InputError
from ..outputs import file_part, replaced_file
from ..studies.campaign import COLUMNS
from ..studies.campaign_exec import read_results
from .campaign_intervals import TOO_FEW, compare_quantiles, enough_runs, quantile_interval
from .campaign_kpis import KPIS, NO_VALUE

__all__ = ["DECIDING", "KPIS", "OUTCOMES", "as_json", "campaign_report",
           "exit_status", "format_report", "pairing", "parse_kpis", "parse_thresholds",
           "worst_runs"]

#: KPIs that decide the relative approach unless ``kpis`` (``--kpi``) names others.
DECIDING = ("peak_draft_kN", "peak_buff_kN")
#: Alias that ``worst_runs`` (``campaign rerun --kpi``) accepts: the magnitude of
#: ``peak_buff_kN``, which ranks runs as ``peak_buff_kN`` does.
ABS_BUFF = "abs_peak_buff_kN"
#: Outcomes of the relative approach and the exit status of ``campaign report`` for each.
OUTCOMES = {"not worse": 0, "worse": 1, "inconclusive": 4}
#: Quantile levels reported (in each KPI's worse direction).
QUANTILES = (0.5, 0.9, 0.99)
#: Bootstrap resamples of the sensitivity indices (SALib's intervals).
RESAMPLES = 1000
#: Draw columns that must agree, run by run, for two families to be paired.
PAIRING_COLUMNS = ("family", "wagons", "speed_kmh", "wagon_mass_t")
#: Stand-in for an infinite relative change (a reference quantile of 0), so that percentiles
#: interpolate.
_HUGE = 1e300


def _unit(kpi: str) -> str:
    return COLUMNS[kpi][0]


def _direction_words(kpi: str) -> str:
    return "larger is worse" if KPIS[kpi][1] > 0 else "more negative is worse"


def parse_kpis(names: list[str] | None) -> tuple[str, ...]:
    """The deciding KPIs of ``--kpi`` (repeatable; none: :data:`DECIDING`).

    Raises
    ------
    InputError
        Naming ``--kpi`` and the unknown KPI.
    """
    if not names:
        return DECIDING
    for name in names:
        if name not in KPIS:
            hint = "; the buff force is peak_buff_kN (negative)" if name == ABS_BUFF else ""
            raise InputError("--kpi", "", f"unknown KPI {name!r}{hint}; known: "
                             f"{', '.join(KPIS)}")
    return tuple(dict.fromkeys(names))


def parse_thresholds(items: list[str]) -> dict[str, float]:
    """``["KPI=VALUE", ...]`` -> {KPI: VALUE}, VALUE in the KPI column's unit.

    A run exceeds the threshold beyond it in the KPI's worse direction: above it, or below it
    for ``peak_buff_kN`` (whose threshold is therefore negative, e.g. ``peak_buff_kN=-400``).

    Raises
    ------
    InputError
        Naming ``--threshold`` and the bad item.
    """
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        if name == ABS_BUFF:
            raise InputError("--threshold", "", f"{item!r}: write the buff force as it is "
                             "recorded, negative: peak_buff_kN=-VALUE")
        if name not in KPIS:
            raise InputError("--threshold", "", f"unknown KPI {name!r} in {item!r}; known: "
                             f"{', '.join(KPIS)}")
        try:
            out[name] = float(value)
        except ValueError:
            raise InputError("--threshold", "", f"{item!r}: write KPI=NUMBER") from None
        if not math.isfinite(out[name]):
            raise InputError("--threshold", "", f"{item!r}: the value must be finite")
        if KPIS[name][1] < 0 and out[name] > 0:
            raise InputError("--threshold", "", f"{item!r}: buff forces are negative (draft "
                             f"positive, buff negative): write {name}=-{value}")
    return out


def _column(table, kpi: str) -> np.ndarray:
    """KPI column as floats, NaN where a run failed or has no value."""
    if kpi not in table.column_names:  # results written before the KPI existed
        return np.full(table.num_rows, np.nan)
    x = np.array(table[kpi].to_numpy(zero_copy_only=False), float)
    x[np.array(table["status"].to_pylist()) != "ok"] = np.nan
    return x


def _counts(table, kpi: str) -> dict:
    """How many runs of ``table`` have a value of ``kpi``, and why the others have none.

    Returns
    -------
    dict
        ``runs``; ``values`` (successful runs with a finite value); ``failed`` (status
        failed); ``no_value`` (successful runs whose value is null or NaN) and
        ``no_value_reason``.
    """
    ok = np.array(table["status"].to_pylist()) == "ok"
    finite = np.isfinite(_column(table, kpi))
    reason = NO_VALUE.get(kpi, "no value") if kpi in table.column_names else \
        "no such column (results written before it existed)"
    return {"runs": table.num_rows, "values": int(finite.sum()), "failed": int((~ok).sum()),
            "no_value": int((ok & ~finite).sum()), "no_value_reason": reason}


def _describe_counts(c: dict) -> str:
    """``87 of 100 runs; 13 without a value: 13 did not stop`` (failed runs named first)."""
    text = f"{c['values']} of {c['runs']} runs"
    missing = c["runs"] - c["values"]
    if missing:
        why = ([f"{c['failed']} failed"] if c["failed"] else []) + (
            [f"{c['no_value']} {c['no_value_reason']}"] if c["no_value"] else [])
        text += f"; {missing} without a value: {', '.join(why)}"
    return text


def _column_level(kpi: str, q: float) -> float:
    """Level of the column's quantile that is the level-``q`` quantile in the worse direction."""
    return q if KPIS[kpi][1] > 0 else 1.0 - q


def _beyond(kpi: str, x: np.ndarray, value: float) -> int:
    """Runs of ``x`` beyond ``value`` in the KPI's worse direction (NaN never is)."""
    return int((x > value).sum() if KPIS[kpi][1] > 0 else (x < value).sum())


def worst_runs(table, kpi: str, n: int, manoeuvre: str | None = None) -> list[dict]:
    """The ``n`` worst successful runs by a KPI, per manoeuvre, worst first.

    Parameters
    ----------
    table : pyarrow.Table
        Rows of a results folder (:func:`~..studies.campaign_exec.read_results`).
    kpi : str
        A key of :data:`KPIS`, or ``abs_peak_buff_kN``: the magnitude of ``peak_buff_kN`` [kN]
        (the same ranking, the most negative buff force first).
    n : int
        Runs per manoeuvre.
    manoeuvre : str, optional
        Only this manoeuvre's rows.

    Returns
    -------
    list of dict
        ``run_id``, ``manoeuvre`` and ``value`` (the KPI in its unit), by manoeuvre then worst
        first; a run without a value (no stop) is never among them.

    Raises
    ------
    InputError
        Unknown KPI or manoeuvre (naming ``--kpi`` or ``--manoeuvre``).
    """
    if kpi not in KPIS and kpi != ABS_BUFF:
        raise InputError("--kpi", "", f"unknown KPI {kpi!r}; known: "
                         f"{', '.join([*KPIS, ABS_BUFF])}")
    names = list(dict.fromkeys(table["manoeuvre"].to_pylist()))
    if manoeuvre is not None and manoeuvre not in names:
        raise InputError("--manoeuvre", "", f"no manoeuvre {manoeuvre!r} in the results; they "
                         f"hold {', '.join(names)}")
    ids = np.array(table["run_id"].to_pylist())
    man = np.array(table["manoeuvre"].to_pylist(), dtype=object)
    x = _column(table, "peak_buff_kN" if kpi == ABS_BUFF else kpi)
    if kpi == ABS_BUFF:
        x = np.abs(x)
    worse = x if kpi == ABS_BUFF else KPIS[kpi][1] * x  # larger is worse
    out = []
    for name in ([manoeuvre] if manoeuvre is not None else names):
        rows = np.flatnonzero(np.isfinite(x) & (man == name))
        rows = rows[np.argsort(-worse[rows], kind="stable")][:n]
        out += [{"run_id": int(ids[i]), "manoeuvre": name, "value": float(x[i])} for i in rows]
    return out


def _same(a, b) -> bool:
    """Two draws of a run agree (floats to 1e-9 relative, lists element by element)."""
    if isinstance(a, list) or isinstance(b, list):
        return isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(
            _same(u, v) for u, v in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and (
            math.isclose(a, b, rel_tol=1e-9) or (math.isnan(a) and math.isnan(b)))
    return a == b


def pairing(meta: dict, table, ref_meta: dict, ref_table, manoeuvres: list[str],
            independent: bool = False) -> dict:
    """Whether a family and its reference are paired: run i of both is the same train.

    They are when their manifests hold the same ``seed`` and, for every run id and
    manoeuvre that both hold, the draws :data:`PAIRING_COLUMNS` agree (the data are checked,
    not only the seed: a Latin hypercube also depends on the number of runs, and another
    family file draws other trains from the same seed).

    Parameters
    ----------
    meta, ref_meta : dict
        Manifests of the family and the reference.
    table, ref_table : pyarrow.Table
        Their rows.
    manoeuvres : list of str
        The manoeuvres compared.
    independent : bool, optional
        Resample independently whatever the data (``--independent``).

    Returns
    -------
    dict
        ``mode`` (``paired`` or ``independent``), ``reason`` (a sentence) and ``common_runs``
        (run ids that both hold, over the manoeuvres compared).
    """
    def keyed(t):
        part = t.filter(pc.is_in(t["manoeuvre"], value_set=pa.array(manoeuvres)))
        cols = [c for c in ("run_id", "manoeuvre", *PAIRING_COLUMNS) if c in part.column_names]
        return {(r["run_id"], r["manoeuvre"]): r for r in part.select(cols).to_pylist()}

    rows, ref_rows = keyed(table), keyed(ref_table)
    common = sorted(set(rows) & set(ref_rows))
    out = {"mode": "independent", "common_runs": len({k[0] for k in common})}
    seed, ref_seed = meta.get("seed"), ref_meta.get("seed")
    if independent:
        return {**out, "reason": "independent comparison requested"}
    if seed is None or ref_seed is None:
        return {**out, "reason": "a manifest records no seed"}
    if seed != ref_seed:
        return {**out, "reason": f"the seeds differ ({seed} and {ref_seed}): other trains"}
    if not common:
        return {**out, "reason": "no run id in common"}
    for key in common:
        for col in PAIRING_COLUMNS:
            if not _same(rows[key].get(col), ref_rows[key].get(col)):
                return {**out, "reason": f"same seed {seed}, but run {key[0]} ({key[1]}) "
                        f"differs in {col}: other trains"}
    return {**out, "mode": "paired",
            "reason": f"same seed {seed} and the same trains ({', '.join(PAIRING_COLUMNS)} "
                      f"agree) in all {out['common_runs']} common runs"}


def campaign_report(folder, *, against=None, thresholds: dict | None = None,
                    quantile: float = 0.99, confidence: float = 0.95, margin: float = 0.05,
                    kpis=None, independent: bool = False, worst: int = 5, plots=None,
                    seed: int = 0, resamples: int = RESAMPLES) -> dict:
    """Summarise a campaign results folder, manoeuvre by manoeuvre.

    Parameters
    ----------
    folder : path-like or CampaignResults
        Results folder of ``ltd-brake campaign run``, or its results already read
        (:class:`~ltd_brake_ros.analysis.campaign_results.CampaignResults`).
    against : path-like or CampaignResults, optional
        Results of the reference family (relative approach, for the manoeuvres of the same
        name).
    thresholds : dict, optional
        KPI -> value in the KPI's unit: the probability of going beyond it in the KPI's worse
        direction (Wilson interval).
    quantile : float, optional
        Quantile level the relative approach compares, in each KPI's worse direction.
    confidence : float, optional
        Two-sided confidence of the intervals; the verdicts are one-sided tests at level
        (1 - confidence) / 2.
    margin : float, optional
        Non-inferiority margin of the relative approach, as a share of the reference's
        quantile (0.05: 5 %).
    kpis : sequence of str, optional
        KPIs whose verdicts decide the outcome (default :data:`DECIDING`); the others are
        compared and shown but do not vote.
    independent : bool, optional
        Resample the two families independently even when they are paired.
    worst : int, optional
        Worst runs listed per force KPI.
    plots : path-like, optional
        Folder for ``cdf_<manoeuvre>_<KPI>.png`` and ``hist_<manoeuvre>_<KPI>.png``.
    seed : int, optional
        Seed of the sensitivity indices' bootstrap (the report is reproducible).
    resamples : int, optional
        Bootstrap resamples of the sensitivity indices.

    Returns
    -------
    dict
        ``name``, ``folder``, ``runs``, ``expected_runs``, ``failed``, ``failures`` (first
        messages), ``warnings``, ``confidence``, ``plots`` and ``manoeuvres``: name ->
        ``runs``, ``counts`` (per KPI: :func:`_counts`), ``quantiles`` (per KPI and level:
        ``estimate``, ``low``, ``high``, ``column_level``, ``tail_points``,
        ``expected_tail_points``), ``verdict_counts``, ``exceedance``, ``worst`` and
        ``relative`` (a list, see :func:`_compare`). With ``against``, also ``reference``,
        ``pairing`` (:func:`pairing`), ``quantile``, ``margin``, ``deciding`` and
        ``outcome`` (a key of :data:`OUTCOMES`). A designed experiment (``grid``, ``sobol``,
        ``morris``) adds ``sensitivity``
        (:func:`~ltd_brake_ros.analysis.sensitivity.sensitivity_report`).

    Raises
    ------
    InputError
        A folder that is not a results folder; a reference without a manoeuvre in common, or
        on which no deciding KPI can be compared.
    """
    deciding = parse_kpis(list(kpis) if kpis else None)
    folder, meta, table = results_of(folder)
    status = np.array(table["status"].to_pylist())
    rep: dict = {"name": meta.get("name", str(folder)), "folder": str(folder),
                 "runs": table.num_rows,
                 "expected_runs": meta.get("runs", 0) * len(meta.get("manoeuvres", [None])),
                 "failed": int((status != "ok").sum()),
                 "failures": [f"run {r['run_id']} {r['manoeuvre']}: {r['message']}"
                              for r in table.filter(status != "ok").slice(0, 5)
                              .select(["run_id", "manoeuvre", "message"]).to_pylist()],
                 "confidence": confidence, "manoeuvres": {}, "plots": []}
    rep["warnings"] = []
    if rep["runs"] < rep["expected_runs"]:
        share = 100 * rep["runs"] / rep["expected_runs"]
        rep["warnings"].append(f"{folder} is incomplete: {rep['runs']} of "
                               f"{rep['expected_runs']} runs ({share:.0f} %)")
    names = meta.get("manoeuvres") or sorted(set(table["manoeuvre"].to_pylist()))
    ref_table = None
    if against is not None:
        against, ref_meta, ref_table = results_of(against)
        rep["reference"] = ref_meta.get("name", str(against))
        ref_names = set(ref_table["manoeuvre"].to_pylist())
        common = [n for n in names if n in ref_names]
        if not common:
            raise InputError(against, "", f"has no manoeuvre in common with {folder} "
                             f"({', '.join(sorted(ref_names)) or 'none'} against "
                             f"{', '.join(names)}): nothing to compare")
        ref_expected = ref_meta["runs"] * len(ref_meta["manoeuvres"])
        if ref_table.num_rows < ref_expected:
            rep["warnings"].append(f"reference {against} is incomplete: {ref_table.num_rows} "
                                   f"of {ref_expected} runs "
                                   f"({100 * ref_table.num_rows / ref_expected:.0f} %)")
        missing = [n for n in names if n not in ref_names]
        if missing:
            rep["warnings"].append(f"reference {against} has no runs of "
                                   f"{', '.join(missing)}: not compared")
        rep.update(pairing=pairing(meta, table, ref_meta, ref_table, common, independent),
                   quantile=quantile, margin=margin, deciding=list(deciding))
    for name in names:
        part = table.filter(pc.equal(table["manoeuvre"], name))
        section = _section(part, thresholds or {}, confidence, worst,
                           sorted(set(QUANTILES) | {quantile}))
        ref_part = None
        if ref_table is not None:
            ref_part = ref_table.filter(pc.equal(ref_table["manoeuvre"], name))
            if ref_part.num_rows:
                mode = rep["pairing"]["mode"]
                if mode == "paired" and not set(part["run_id"].to_pylist()) & set(
                        ref_part["run_id"].to_pylist()):
                    mode = "independent"  # incomplete folders without a train in common here
                    rep["warnings"].append(f"{name}: no run in common with the reference, "
                                           "compared as independent samples")
                section["relative"] = _relative(part, ref_part, mode, quantile, confidence,
                                                margin, deciding)
            else:
                ref_part = None
        rep["manoeuvres"][name] = section
        if plots is not None:
            rep["plots"] += _plots(Path(plots), name, part, ref_part, rep["name"],
                                   rep.get("reference"))
    # a designed experiment (grid, sobol, morris): its design and sensitivity indices
    if meta.get("sampling") in ("grid", "sobol", "morris"):
        from .sensitivity import design_note, sensitivity_report

        rep["warnings"].append(design_note(meta["sampling"]))
        rep["sensitivity"] = sensitivity_report(folder, meta, table, confidence=confidence,
                                                seed=seed, resamples=resamples)
    if against is not None:
        votes = [v for sec in rep["manoeuvres"].values() for v in sec["relative"]
                 if v["deciding"] and v["verdict"] != "not assessed"]
        if not any(v["compared"] for v in votes):
            raise InputError(against, "", f"none of the deciding KPIs ({', '.join(deciding)}) "
                             f"of {folder} could be compared with it (no successful run with a "
                             "value on one side): nothing to compare")
        verdicts = {v["verdict"] for v in votes}
        rep["outcome"] = ("worse" if "worse" in verdicts else
                          "not worse" if verdicts == {"not worse"} else "inconclusive")
    return rep


def results_of(source) -> tuple[str, dict, pa.Table]:
    """The folder, manifest and rows of a results folder, or of results already read (an
    object with ``folder``, ``manifest`` and ``table``)."""
    if all(hasattr(source, k) for k in ("folder", "manifest", "table")):
        return str(source.folder), source.manifest, source.table
    meta, table = read_results(source)
    return str(source), meta, table


def exit_status(rep: dict) -> int:
    """Exit status of ``campaign report`` for a report: 0, or with a reference 0 (every
    deciding KPI ``not worse``), 1 (one ``worse``) or 4 (otherwise: ``inconclusive``)."""
    return OUTCOMES[rep["outcome"]] if "outcome" in rep else 0


def _too_few(q: float, n: int) -> str:
    """The note of a quantile without an interval: how many runs would give one."""
    from .campaign_intervals import MIN_TAIL

    need = math.ceil(MIN_TAIL / min(q, 1.0 - q) - 1e-9)
    return f"{TOO_FEW} ({n} runs with a value; {need} give one)"


def _section(table, thresholds: dict, confidence: float, worst: int,
             levels: list[float]) -> dict:
    """The report of one manoeuvre's rows (without the relative approach)."""
    ok = np.array(table["status"].to_pylist()) == "ok"
    out: dict = {"runs": table.num_rows, "counts": {}, "quantiles": {}, "exceedance": {},
                 "worst": {}, "relative": []}
    for kpi in KPIS:
        x = _column(table, kpi)
        out["counts"][kpi] = counts = _counts(table, kpi)
        if not counts["values"]:
            continue
        out["quantiles"][kpi] = qs = {}
        for q in levels:
            level = _column_level(kpi, q)
            est, lo, hi = quantile_interval(x, level, confidence)
            qs[f"{q:g}"] = {"estimate": est, "low": lo, "high": hi, "column_level": level,
                            "tail_points": _beyond(kpi, x, est),
                            "expected_tail_points": counts["values"] * (1.0 - q),
                            "note": "" if math.isfinite(lo) else _too_few(q, counts["values"])}
    # flags of results written before a criterion existed count as passed
    out["verdict_counts"] = {flag: int((~np.array(table[flag].to_pylist(), bool)[ok]).sum())
                             if flag in table.column_names else 0
                             for flag in ("draft_ok", "buff_ok", "travel_ok", "adhesion_ok")}
    z = _z(confidence)
    for kpi, limit in thresholds.items():
        x = _column(table, kpi)
        x = x[np.isfinite(x)]
        k, n = _beyond(kpi, x, limit), len(x)
        out["exceedance"][kpi] = {"threshold": limit, "beyond": "above" if KPIS[kpi][1] > 0
                                  else "below", "count": k, "of": n,
                                  "probability": k / n if n else None,
                                  "interval": _wilson(k, n, z)}
    cols = ["run_id", "family", "wagons", "speed_kmh", "peak_draft_kN", "peak_draft_coupler",
            "peak_buff_kN", "peak_buff_coupler", "max_adhesion_demand", "stopping_distance_m"]
    rows = table.filter(ok).select(cols).to_pylist()
    out["worst"]["buff"] = sorted(rows, key=lambda r: r["peak_buff_kN"])[:worst]
    out["worst"]["draft"] = sorted(rows, key=lambda r: -r["peak_draft_kN"])[:worst]
    return out


def _relative(table, ref_table, mode: str, quantile: float, confidence: float, margin: float,
              deciding: tuple) -> list[dict]:
    """The relative approach for one manoeuvre: a :func:`_compare` entry per KPI that either
    family has a value of, and per deciding KPI."""
    if mode == "paired":  # the run ids both hold, aligned
        _, at, ref_at = np.intersect1d(np.array(table["run_id"].to_pylist()),
                                       np.array(ref_table["run_id"].to_pylist()),
                                       return_indices=True)
        table, ref_table = table.take(at), ref_table.take(ref_at)
    out = []
    for kpi in KPIS:
        entry = _compare(kpi, table, ref_table, mode == "paired", quantile, confidence, margin)
        entry["deciding"] = kpi in deciding
        if entry["deciding"] or entry["counts"]["values"] or entry["reference_counts"]["values"]:
            out.append(entry)
    return out


def _compare(kpi: str, table, ref_table, paired: bool, quantile: float, confidence: float,
             margin: float) -> dict:
    """Non-inferiority of one KPI's quantile against the reference.

    The worsening is ``w = d * (Q - Q_ref) / |Q_ref|`` (``d`` the KPI's worse direction,
    ``Q`` the level-``quantile`` quantile in that direction); its interval [lo, hi] (from
    Fieller's interval of ``Q / Q_ref``, :func:`~.campaign_intervals.compare_quantiles`)
    gives ``not worse`` (hi < margin), ``worse`` (lo > margin) or ``inconclusive`` (the
    interval holds the margin, or there is none: too few runs beyond the quantile).

    Returns
    -------
    dict
        ``kpi``, ``unit``, ``direction`` (+1 larger is worse, -1 smaller is), ``quantile``,
        ``column_level``, ``family`` and ``reference`` (estimates) with ``family_interval``
        and ``reference_interval``, ``difference`` (family minus reference, in the unit) with
        ``difference_interval``, ``worsening`` (relative, 0.05 = 5 % worse) with
        ``worsening_interval``, ``correlation`` (of the two quantiles; 0 independent),
        ``margin`` (relative) and ``margin_value`` (in the unit), ``compared`` (both
        families have values), ``verdict``, ``counts`` and ``reference_counts``
        (:func:`_counts`, over the runs compared), ``tail_points`` (runs beyond the
        estimates: family, reference), ``expected_tail_points`` (n (1 - q) of each),
        ``runs_needed`` (inconclusive: the runs that would decide at the observed spread,
        family and reference; None otherwise) and ``note``. Intervals without enough runs
        are (NaN, NaN).
    """
    d = KPIS[kpi][1]
    level = _column_level(kpi, quantile)
    x, y = _column(table, kpi), _column(ref_table, kpi)
    entry = {"kpi": kpi, "unit": _unit(kpi), "direction": d, "quantile": quantile,
             "column_level": level, "margin": margin, "counts": _counts(table, kpi),
             "reference_counts": _counts(ref_table, kpi), "compared": False,
             "runs_needed": None, "note": ""}
    nx, ny = entry["counts"]["values"], entry["reference_counts"]["values"]
    if not (nx and ny):
        entry["verdict"] = "not assessed" if not (nx or ny) else "inconclusive"
        entry["note"] = ("no run of either family has a value" if not (nx or ny) else
                         f"no run of the {'family' if not nx else 'reference'} has a value")
        return entry
    c = compare_quantiles(x, y, level, confidence, paired)
    fx, fy = c["family"][0], c["reference"][0]
    worse_by = float(_worsening(d * (fx - fy), fy))
    _, r_lo, r_hi = c["ratio"]
    turn = d * (1.0 if fy > 0 else -1.0)  # w = turn (ratio - 1)
    lo, hi = sorted((turn * (r_lo - 1.0), turn * (r_hi - 1.0))) if math.isfinite(r_lo) \
        else (math.nan, math.nan)
    entry.update(compared=True, family=fx, reference=fy,
                 family_interval=c["family"][1:], reference_interval=c["reference"][1:],
                 difference=c["difference"][0], difference_interval=c["difference"][1:],
                 worsening=worse_by, worsening_interval=(lo, hi), correlation=c["correlation"],
                 margin_value=margin * abs(fy),
                 tail_points=(_beyond(kpi, x, fx), _beyond(kpi, y, fy)),
                 expected_tail_points=(nx * (1.0 - quantile), ny * (1.0 - quantile)))
    notes = []
    if hi < margin:
        entry["verdict"] = "not worse"
    elif lo > margin:
        entry["verdict"] = "worse"
    else:
        entry["verdict"] = "inconclusive"
        if not (enough_runs(nx, level) and enough_runs(ny, level)):
            notes.append(_too_few(quantile, min(nx, ny)))
        elif not math.isfinite(lo):
            notes.append("the reference's quantile is not told apart from 0: no relative "
                         "interval")
        else:
            entry["runs_needed"] = _runs_needed(worse_by, lo, hi, margin, table.num_rows,
                                                ref_table.num_rows)
            if entry["runs_needed"] is None:
                notes.append("the estimate lies on the margin: more runs alone do not decide")
    entry["note"] = "; ".join(notes)
    return entry


def _worsening(change, ref):
    """Relative change in the worse direction, ``change / |ref|``; for a reference of 0, a
    huge value of the sign of ``change`` (0 if none)."""
    change, ref = np.asarray(change, float), np.abs(np.asarray(ref, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(ref > 0, change / np.where(ref > 0, ref, 1.0), np.sign(change) * _HUGE)
    return out


def _runs_needed(est: float, lo: float, hi: float, margin: float, n: int,
                 n_ref: int) -> tuple[int, int] | None:
    """Runs of the family and the reference that would make an inconclusive verdict
    conclusive at the observed spread.

    The half-width of the interval on the margin's side of the estimate, ``h``, shrinks as
    ``h sqrt(n / N)`` with ``N`` runs instead of ``n``; it clears the margin once it is below
    ``|est - margin|``: ``N = n (h / |est - margin|)^2`` (both families scaled alike).
    """
    gap = abs(est - margin)
    h = hi - est if est < margin else est - lo
    if not (gap > 0 and math.isfinite(h) and abs(est) < _HUGE):
        return None
    factor = (h / gap) ** 2
    if not math.isfinite(factor) or factor > 1e9:
        return None
    return math.ceil(factor * n), math.ceil(factor * n_ref)


def _z(confidence: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(0.5 + confidence / 2.0))


def _wilson(k: int, n: int, z: float) -> tuple[float | None, float | None]:
    """Wilson score interval of a proportion k / n (None, None without any run)."""
    if n == 0:
        return (None, None)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (0.0 if k == 0 else max(0.0, c - h), 1.0 if k == n else min(1.0, c + h))


def _plots(folder: Path, manoeuvre: str, table, ref_table, name: str,
           ref_name: str | None) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import legend_as_written

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for kpi, (label, _) in KPIS.items():
        data = [(x[np.isfinite(x)], lab) for x, lab in (
            (_column(table, kpi), name),
            (_column(ref_table, kpi) if ref_table is not None else np.array([]), ref_name))]
        data = [(x, lab) for x, lab in data if len(x)]
        if not data:
            continue  # no run has this KPI (e.g. no stop from 100 km/h): nothing to draw
        for kind in ("cdf", "hist"):
            fig, ax = plt.subplots(figsize=(6, 4))
            drawn = []
            for x, lab in data:
                if kind == "cdf":
                    s = np.sort(x)
                    drawn += ax.step(s, np.arange(1, len(s) + 1) / len(s), where="post")
                    ax.set_ylabel("cumulative probability")
                else:
                    drawn.append(ax.hist(x, bins=40, alpha=0.6)[2])
                    ax.set_ylabel("runs")
            # names as written: never mathtext, never a file path
            ax.set_xlabel(f"{kpi} [{_unit(kpi)}] ({label}), {manoeuvre}", parse_math=False)
            legend_as_written(ax, drawn, [lab for _, lab in data])
            ax.grid(alpha=0.3)
            path = folder / f"{kind}_{file_part(manoeuvre)}_{kpi}.png"
            fig.tight_layout()
            with replaced_file(path, "wb") as fh:
                fig.savefig(fh, format="png", dpi=90)
            plt.close(fig)
            written.append(str(path))
    return written


def as_json(rep: dict) -> str:
    """The report as JSON text (a value that is not a finite number becomes null).

    Parameters
    ----------
    rep : dict
        From :func:`campaign_report`.

    Returns
    -------
    str
    """
    import json

    def clean(v):
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        if isinstance(v, (float, np.floating)):
            return float(v) if math.isfinite(v) else None
        if isinstance(v, np.integer):
            return int(v)
        return v

    return json.dumps(clean(rep), indent=2)


def _g(x) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.4g}"


def _pct(x, sign: bool = True) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    if abs(x) >= _HUGE:
        return "+inf %" if x > 0 else "-inf %"
    return f"{100 * x:+.1f} %" if sign else f"{100 * x:.1f} %"


def _iv(lo, hi, fmt, missing: str = f"({TOO_FEW})") -> str:
    """``[lo, hi]``, or ``missing`` where there is no interval."""
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return missing
    return f"[{fmt(lo)}, {fmt(hi)}]"


def format_report(rep: dict) -> str:
    """The report as text.

    Parameters
    ----------
    rep : dict
        From :func:`campaign_report`.

    Returns
    -------
    str
    """
    c = rep["confidence"]
    lines = [f"campaign {rep['name']}: {rep['runs']} of {rep['expected_runs']} runs, "
             f"{rep['failed']} failed"]
    lines += [f"  {m}" for m in rep["failures"]]
    lines += [f"warning: {w}" for w in rep.get("warnings", ())]
    for name, sec in rep["manoeuvres"].items():
        lines.append(f"manoeuvre {name} ({sec['runs']} runs), quantiles qP in the worse "
                     f"direction (estimate [{100 * c:g} % interval], tail: runs beyond it), "
                     "over the runs with a value:")
        for kpi, counts in sec["counts"].items():
            head = f"  {kpi} [{_unit(kpi)}], {_direction_words(kpi)} ({_describe_counts(counts)})"
            qs = sec["quantiles"].get(kpi)
            if not qs:
                lines.append(f"{head}: no quantile")
                continue
            cells = "  ".join(f"q{q}: {_g(v['estimate'])} {_iv(v['low'], v['high'], _g)} "
                              f"tail {v['tail_points']}" for q, v in qs.items())
            lines.append(f"{head}: {cells}")
        vc = sec["verdict_counts"]
        lines.append(f"  verdicts: {vc['draft_ok']} runs beyond the draft strength, "
                     f"{vc['buff_ok']} beyond the buff strength, {vc['travel_ok']} beyond the "
                     f"couplers' travel (forces not physical), {vc['adhesion_ok']} beyond the "
                     "mean-adhesion limit")
        for kpi, e in sec["exceedance"].items():
            lo, hi = e["interval"]
            sign = ">" if e["beyond"] == "above" else "<"
            lines.append(f"  P({kpi} {sign} {e['threshold']:g}) = {_g(e['probability'])} "
                         f"({e['count']}/{e['of']} runs with a value; [{_g(lo)}, {_g(hi)}])")
        for which, rows in sec["worst"].items():
            lines.append(f"  worst runs by {which}:")
            for r in rows:
                lines.append(f"    run {r['run_id']}: {r['family']}, {r['wagons']} wagons, "
                             f"{r['speed_kmh']:.1f} km/h, draft {r['peak_draft_kN']:.0f} kN "
                             f"@{r['peak_draft_coupler']}, buff {r['peak_buff_kN']:.0f} kN "
                             f"@{r['peak_buff_coupler']}, adhesion above 30 km/h "
                             f"{r['max_adhesion_demand']:.3f}")
        if any(sec["worst"].values()):
            lines.append(f"  recordings of the worst runs: ltd-brake campaign rerun "
                         f"{rep['folder']} --worst N --manoeuvre {name} --out FOLDER")
        if sec["relative"]:
            lines += _format_relative(rep, sec["relative"])
    if "outcome" in rep:
        lines.append(f"relative approach: {rep['outcome']} (deciding KPIs: "
                     f"{', '.join(rep['deciding'])}; exit status {exit_status(rep)})")
    if rep.get("sensitivity"):  # a designed experiment
        from .sensitivity import format_sensitivity

        lines += format_sensitivity(rep["sensitivity"])
    for p in rep["plots"]:
        lines.append(f"plot: {p}")
    return "\n".join(lines)


def _format_relative(rep: dict, entries: list[dict]) -> list[str]:
    """Lines of the relative approach of one manoeuvre."""
    p = rep["pairing"]
    lines = [f"  relative approach against {rep['reference']}: q{rep['quantile']:g} in the "
             f"worse direction, margin {_pct(rep['margin'], False)} of the reference's "
             f"quantile, {100 * rep['confidence']:g} % intervals",
             f"    runs: {p['mode']} ({p['reason']})"]
    for v in entries:
        vote = "" if v["deciding"] else " (shown, does not decide)"
        head = f"    {v['verdict']:<12}  {v['kpi']} [{v['unit']}], {_direction_words(v['kpi'])}"
        runs = (f"family {_describe_counts(v['counts'])}; reference "
                f"{_describe_counts(v['reference_counts'])}")
        if not v["compared"]:
            lines += [f"{head}{vote}: {v['note']}", f"{'':18}{runs}"]
            continue
        dlo, dhi = v["difference_interval"]
        wlo, whi = v["worsening_interval"]
        lines.append(f"{head}{vote}: {_g(v['family'])} vs {_g(v['reference'])}, family - "
                     f"reference {v['difference']:+.4g} "
                     f"{_iv(dlo, dhi, '{:+.4g}'.format, '(no interval)')}")
        more = (f"worsening {_pct(v['worsening'])} {_iv(wlo, whi, _pct, '(no interval)')} "
                "against the "
                f"margin {_pct(v['margin'], False)} ({v['margin_value']:.4g} {v['unit']}); "
                f"{runs}; tail {v['tail_points'][0]} and {v['tail_points'][1]} runs")
        if v["runs_needed"] is not None:
            n, n_ref = v["runs_needed"]
            more += (f"; about {n} runs" if p["mode"] == "paired" else
                     f"; about {n} runs of the family and {n_ref} of the reference") + \
                " would decide at the observed spread"
        if v["note"]:
            more += f"; {v['note']}"
        lines.append(f"{'':18}{more}")
    return lines

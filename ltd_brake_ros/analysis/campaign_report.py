"""Campaign report: quantiles with bootstrap confidence intervals, exceedance probabilities,
the worst runs, CDF and histogram plots, and the relative approach against a reference family.

The relative approach (as UIC 421 admits new freight-train families): a family fails a
criterion when its quantile of the KPI exceeds the reference family's with the stated
confidence (the share of bootstrap resamples in which the family's quantile is the larger),
and passes otherwise.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow.compute as pc

from ..inputs import InputError
from ..studies.campaign_exec import read_results

__all__ = ["KPIS", "bootstrap_quantile", "campaign_report", "format_report", "parse_thresholds",
           "worst_runs"]

#: KPIs summarised: column -> (label, unit); larger is worse for each.
KPIS = {
    "abs_peak_buff_kN": ("peak buff force (magnitude)", "kN"),
    "peak_draft_kN": ("peak draft force", "kN"),
    "mean_adhesion": ("largest mean utilised adhesion (stops from 100 km/h)", "-"),
    "max_adhesion_demand": ("largest adhesion demand above 30 km/h", "-"),
    "stopping_distance_m": ("stopping distance", "m"),
}
#: Quantiles reported.
QUANTILES = (0.5, 0.9, 0.99)
#: Bootstrap resamples.
RESAMPLES = 1000


def parse_thresholds(items: list[str]) -> dict[str, float]:
    """``["KPI=VALUE", ...]`` -> {KPI: VALUE}.

    Raises
    ------
    InputError
        Naming ``--threshold`` and the bad item.
    """
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in KPIS:
            raise InputError("--threshold", "", f"unknown KPI {name!r} in {item!r}; known: "
                             f"{', '.join(KPIS)}")
        try:
            out[name] = float(value)
        except ValueError:
            raise InputError("--threshold", "", f"{item!r}: write KPI=NUMBER") from None
        if not math.isfinite(out[name]):
            raise InputError("--threshold", "", f"{item!r}: the value must be finite")
    return out


def _kpi_values(table, name: str) -> np.ndarray:
    """Column of KPI ``name`` (larger is worse: the buff force as a magnitude) as floats."""
    col = "peak_buff_kN" if name == "abs_peak_buff_kN" else name
    if col not in table.column_names:  # results written before the KPI existed
        return np.full(table.num_rows, np.nan)
    x = np.array(table[col].to_numpy(zero_copy_only=False), float)
    return np.abs(x) if name == "abs_peak_buff_kN" else x


def worst_runs(table, kpi: str, n: int, manoeuvre: str | None = None) -> list[dict]:
    """The ``n`` worst successful runs by a KPI, per manoeuvre, worst first.

    Parameters
    ----------
    table : pyarrow.Table
        Rows of a results folder (:func:`~..studies.campaign_exec.read_results`).
    kpi : str
        A key of :data:`KPIS`.
    n : int
        Runs per manoeuvre.
    manoeuvre : str, optional
        Only this manoeuvre's rows.

    Returns
    -------
    list of dict
        ``run_id``, ``manoeuvre`` and ``value`` (the KPI), by manoeuvre then worst first; a
        run without a value (no stop) is never among them.

    Raises
    ------
    InputError
        Unknown KPI or manoeuvre (naming ``--kpi`` or ``--manoeuvre``).
    """
    if kpi not in KPIS:
        raise InputError("--kpi", "", f"unknown KPI {kpi!r}; known: {', '.join(KPIS)}")
    names = list(dict.fromkeys(table["manoeuvre"].to_pylist()))
    if manoeuvre is not None and manoeuvre not in names:
        raise InputError("--manoeuvre", "", f"no manoeuvre {manoeuvre!r} in the results; they "
                         f"hold {', '.join(names)}")
    ids = np.array(table["run_id"].to_pylist())
    man = np.array(table["manoeuvre"].to_pylist(), dtype=object)
    x = _kpi_values(table, kpi)
    usable = (np.array(table["status"].to_pylist()) == "ok") & np.isfinite(x)
    out = []
    for name in ([manoeuvre] if manoeuvre is not None else names):
        rows = np.flatnonzero(usable & (man == name))
        rows = rows[np.argsort(-x[rows], kind="stable")][:n]
        out += [{"run_id": int(ids[i]), "manoeuvre": name, "value": float(x[i])} for i in rows]
    return out


def bootstrap_quantile(x: np.ndarray, q: float, confidence: float, rng: np.random.Generator,
                       resamples: int = RESAMPLES) -> tuple[float, float, float, np.ndarray]:
    """Quantile ``q`` of ``x`` with a percentile-bootstrap confidence interval.

    Parameters
    ----------
    x : ndarray
    q : float
        Quantile in (0, 1).
    confidence : float
        Two-sided confidence of the interval.
    rng : numpy.random.Generator
    resamples : int, optional

    Returns
    -------
    estimate, low, high : float
    replicates : ndarray
        The resampled quantiles (for paired comparisons).
    """
    idx = rng.integers(0, len(x), (resamples, len(x)))
    reps = np.quantile(x[idx], q, axis=1)
    a = (1.0 - confidence) / 2.0
    return float(np.quantile(x, q)), float(np.quantile(reps, a)), float(np.quantile(reps, 1 - a)), reps


def _kpis(table) -> dict[str, np.ndarray]:
    ok = np.array(table["status"].to_pylist()) == "ok"
    out = {name: _kpi_values(table, name)[ok] for name in KPIS}
    return {k: v[np.isfinite(v)] for k, v in out.items()}


def campaign_report(folder, *, against=None, thresholds: dict | None = None,
                    quantile: float = 0.99, confidence: float = 0.95, worst: int = 5,
                    plots=None, seed: int = 0) -> dict:
    """Summarise a campaign results folder, manoeuvre by manoeuvre.

    Parameters
    ----------
    folder : path-like
        Results folder of ``ltd-brake campaign run``.
    against : path-like, optional
        Results folder of the reference family (relative approach, for the manoeuvres of the
        same name).
    thresholds : dict, optional
        KPI -> value: the probability of exceeding it (Wilson interval).
    quantile : float, optional
        Quantile compared by the relative approach.
    confidence : float, optional
        Confidence of intervals and verdicts.
    worst : int, optional
        Worst runs listed per force KPI.
    plots : path-like, optional
        Folder for ``cdf_<manoeuvre>_<KPI>.png`` and ``hist_<manoeuvre>_<KPI>.png``.
    seed : int, optional
        Bootstrap seed (the report is reproducible).

    Returns
    -------
    dict
        ``name``, ``runs``, ``failed``, ``failures`` (first messages), ``confidence``,
        ``reference``, ``plots`` and ``manoeuvres``: name -> ``runs``, ``quantiles``,
        ``verdict_counts``, ``exceedance``, ``worst`` and ``relative``.
    """
    meta, table = read_results(folder)
    rng = np.random.default_rng(seed)
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
        ref_meta, ref_table = read_results(against)
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
    for name in names:
        part = table.filter(pc.equal(table["manoeuvre"], name))
        ref = None
        if ref_table is not None:
            ref_part = ref_table.filter(pc.equal(ref_table["manoeuvre"], name))
            ref = _kpis(ref_part) if ref_part.num_rows else None
        section = _section(part, ref, thresholds or {}, quantile, confidence, worst, rng)
        rep["manoeuvres"][name] = section
        if plots is not None:
            rep["plots"] += _plots(Path(plots), name, _kpis(part), ref, rep["name"],
                                   rep.get("reference"))
    if against is not None and not any(sec["relative"] for sec in rep["manoeuvres"].values()):
        raise InputError(against, "", f"no KPI of {folder} could be compared with it (no "
                         "successful run with a value on one side): nothing to compare")
    return rep


def _section(table, ref: dict | None, thresholds: dict, quantile: float, confidence: float,
             worst: int, rng) -> dict:
    """The report of one manoeuvre's rows (``ref``: the reference family's KPIs)."""
    kpis = _kpis(table)
    ok = np.array(table["status"].to_pylist()) == "ok"
    out: dict = {"runs": table.num_rows, "quantiles": {}, "exceedance": {}, "worst": {},
                 "relative": []}
    for name, x in kpis.items():
        if len(x):
            out["quantiles"][name] = {f"{q:g}": bootstrap_quantile(x, q, confidence, rng)[:3]
                                      for q in sorted(set(QUANTILES) | {quantile})}
    # flags of results written before a criterion existed count as passed
    out["verdict_counts"] = {flag: int((~np.array(table[flag].to_pylist(), bool)[ok]).sum())
                             if flag in table.column_names else 0
                             for flag in ("draft_ok", "buff_ok", "travel_ok", "adhesion_ok")}
    z = _z(confidence)
    for name, limit in thresholds.items():
        x = kpis[name]
        k, n = int((x > limit).sum()), len(x)
        out["exceedance"][name] = {"threshold": limit, "count": k, "of": n,
                                   "probability": k / n if n else math.nan,
                                   "interval": _wilson(k, n, z)}
    cols = ["run_id", "family", "wagons", "speed_kmh", "peak_draft_kN", "peak_draft_coupler",
            "peak_buff_kN", "peak_buff_coupler", "max_adhesion_demand", "stopping_distance_m"]
    rows = table.filter(ok).select(cols).to_pylist()
    out["worst"]["buff"] = sorted(rows, key=lambda r: r["peak_buff_kN"])[:worst]
    out["worst"]["draft"] = sorted(rows, key=lambda r: -r["peak_draft_kN"])[:worst]
    for name, x in kpis.items():
        y = ref.get(name) if ref else None
        if y is None or not (len(x) and len(y)):
            continue
        fx, lo_x, hi_x, rx = bootstrap_quantile(x, quantile, confidence, rng)
        fy, lo_y, hi_y, ry = bootstrap_quantile(y, quantile, confidence, rng)
        p_worse = float(np.mean(rx > ry))
        out["relative"].append({
            "kpi": name, "quantile": quantile, "family": fx, "reference": fy,
            "family_interval": (lo_x, hi_x), "reference_interval": (lo_y, hi_y),
            "probability_worse": p_worse, "verdict": "FAIL" if p_worse >= confidence else "PASS"})
    return out


def _z(confidence: float) -> float:
    from scipy.special import ndtri

    return float(ndtri(0.5 + confidence / 2.0))


def _wilson(k: int, n: int, z: float) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (0.0 if k == 0 else max(0.0, c - h), 1.0 if k == n else min(1.0, c + h))


def _plots(folder: Path, manoeuvre: str, kpis: dict, ref: dict | None, name: str,
           ref_name: str | None) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for kpi, x in kpis.items():
        label, unit = KPIS[kpi]
        if not len(x) and not (ref and len(ref.get(kpi, ()))):
            continue  # no run has this KPI (e.g. no stop from 100 km/h): nothing to draw
        for kind in ("cdf", "hist"):
            fig, ax = plt.subplots(figsize=(6, 4))
            for data, lab in ((x, name), (ref.get(kpi) if ref else None, ref_name)):
                if data is None or not len(data):
                    continue
                if kind == "cdf":
                    s = np.sort(data)
                    ax.step(s, np.arange(1, len(s) + 1) / len(s), where="post", label=lab)
                    ax.set_ylabel("cumulative probability")
                else:
                    ax.hist(data, bins=40, alpha=0.6, label=lab)
                    ax.set_ylabel("runs")
            ax.set_xlabel(f"{label} [{unit}], {manoeuvre}")
            ax.legend()
            ax.grid(alpha=0.3)
            path = folder / f"{kind}_{manoeuvre}_{kpi}.png"
            fig.tight_layout()
            fig.savefig(path, dpi=90)
            plt.close(fig)
            written.append(str(path))
    return written


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
        lines.append(f"manoeuvre {name} ({sec['runs']} runs), quantiles "
                     f"(estimate [{100 * c:g} % bootstrap interval]):")
        for kpi, qs in sec["quantiles"].items():
            label, unit = KPIS[kpi]
            cells = "  ".join(f"q{q}: {e:.4g} [{lo:.4g}, {hi:.4g}]"
                              for q, (e, lo, hi) in qs.items())
            lines.append(f"  {label} [{unit}]  {cells}")
        vc = sec["verdict_counts"]
        lines.append(f"  verdicts: {vc['draft_ok']} runs beyond the draft strength, "
                     f"{vc['buff_ok']} beyond the buff strength, {vc['travel_ok']} beyond the "
                     f"couplers' travel (forces not physical), {vc['adhesion_ok']} beyond the "
                     "mean-adhesion limit")
        for kpi, e in sec["exceedance"].items():
            lo, hi = e["interval"]
            lines.append(f"  P({kpi} > {e['threshold']:g}) = {e['probability']:.4g} "
                         f"({e['count']}/{e['of']}; [{lo:.4g}, {hi:.4g}])")
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
            lines.append(f"  relative approach against {rep['reference']}:")
        for v in sec["relative"]:
            label, unit = KPIS[v["kpi"]]
            lines.append(f"    {v['verdict']}  {label} q{v['quantile']:g}: {v['family']:.4g} vs "
                         f"{v['reference']:.4g} {unit}, P(family worse) = "
                         f"{v['probability_worse']:.3f}")
    for p in rep["plots"]:
        lines.append(f"plot: {p}")
    return "\n".join(lines)

"""A calibration as tables: targets, parameters, correlations, forces."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .evaluation import BUFF, BUFF_AT, DISTANCE, DRAFT, DRAFT_AT
from .fit import Calibration
from .forces import BUFF_TOL, CouplerCalibration, DRAFT_TOL


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

"""The campaign report as one self-contained HTML file.

Everything a reader needs is inside the file: the style sheet inline, the figures as PNG
images embedded in base64 ``data:`` URIs, no script and no reference to anything outside it,
so the file opens offline and can be mailed or archived as it is. It shows what
:func:`~ltd_brake_ros.analysis.campaign_report.campaign_report` returns: the runs and failures,
per manoeuvre the quantiles with their intervals, the verdict counts, the exceedance
curves (the share of runs at or beyond a value, on a log scale), the relative approach against
a reference family, the sensitivity indices of a Sobol' or Morris campaign, and the worst runs
with the commands that rerun them with a full recording.
"""
from __future__ import annotations

import base64
import html
import io
import math
import shlex
from pathlib import Path

import numpy as np

from .campaign_intervals import TOO_FEW
from .campaign_report import KPIS, exit_status

__all__ = ["html_report", "write_html"]

#: The style sheet, inline.
_CSS = """
body { font-family: sans-serif; margin: 2em auto; max-width: 72em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.05em; margin-top: 1.5em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; vertical-align: top; }
th { background: #f0f0f0; } td.l, th.l { text-align: left; }
code { font-size: 0.9em; background: #f5f5f5; padding: 0 0.2em; }
.warn { color: #8a4b00; } .worse { color: #b00020; font-weight: bold; }
.notworse { color: #006400; font-weight: bold; }
.inconclusive { color: #8a4b00; font-weight: bold; }
img { max-width: 100%; height: auto; border: 1px solid #eee; }
.note { color: #555; font-size: 0.9em; }
"""


#: Attribute of a left-aligned table cell.
_LEFT = ' class="l"'


def _e(text) -> str:
    """Text as HTML shows it: every user-given name passes here, never as markup."""
    return html.escape(str(text), quote=True)


def _plain(text) -> str:
    """Text as a matplotlib label shows it: ``$`` would start mathtext (and an unbalanced
    formula fail the page)."""
    return str(text).replace("$", r"\$")


def _g(x) -> str:
    return "n/a" if x is None or not isinstance(x, (int, float)) or not math.isfinite(x) \
        else f"{x:.4g}"


def _pct(x, sign: bool = True) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{100 * x:+.1f} %" if sign else f"{100 * x:.1f} %"


def _iv(lo, hi, fmt) -> str:
    """``[lo, hi]``, or why there is no interval (escaped)."""
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return f"<span class=\"note\">({_e(TOO_FEW)})</span>"
    return f"[{_e(fmt(lo))}, {_e(fmt(hi))}]"


def _table(head: list, rows: list, left: int = 1) -> str:
    """An HTML table; ``left`` columns are aligned left (text), the others right."""
    def cells(tag, values):
        return "".join(f"<{tag}{_LEFT if i < left else ''}>{v}</{tag}>"
                       for i, v in enumerate(values))

    body = "".join(f"<tr>{cells('td', r)}</tr>" for r in rows)
    return f"<table><tr>{cells('th', [_e(h) for h in head])}</tr>{body}</table>"


def _png(fig) -> str:
    """A matplotlib figure as an embedded PNG image."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img alt="figure" src="data:image/png;base64,{data}">'


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _values(table, manoeuvre: str, kpi: str) -> np.ndarray:
    """Finite values of a KPI over a manoeuvre's successful runs."""
    if table is None or kpi not in table.column_names:
        return np.array([])
    import pyarrow.compute as pc

    part = table.filter(pc.and_(pc.equal(table["manoeuvre"], manoeuvre),
                                pc.equal(table["status"], "ok")))
    x = np.array(part[kpi].to_numpy(zero_copy_only=False), float)
    return x[np.isfinite(x)]


def _exceedance_figure(table, ref_table, manoeuvre: str, name: str, ref_name) -> str:
    """1 - F against each KPI of a manoeuvre, in its worse direction, on a log scale."""
    kpis = [k for k in KPIS if len(_values(table, manoeuvre, k))
            or len(_values(ref_table, manoeuvre, k))]
    if not kpis:
        return ""
    plt = _pyplot()
    cols = 2 if len(kpis) > 1 else 1
    rows = -(-len(kpis) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.4 * rows), squeeze=False)
    from ..studies.campaign import COLUMNS

    for ax, kpi in zip(axes.flat, kpis):
        direction = KPIS[kpi][1]
        for t, label in ((table, f"family {name}"), (ref_table, f"reference {ref_name}")):
            label = _plain(label)
            x = _values(t, manoeuvre, kpi)
            if not len(x):
                continue
            s = np.sort(x)[::direction]  # worst last
            share = (len(s) - np.arange(len(s))) / len(s)  # at or beyond each value
            ax.step(s, share, where="post" if direction > 0 else "pre", label=label)
        ax.set_yscale("log")
        if direction < 0:
            ax.invert_xaxis()  # worse to the right
        for q in (0.1, 0.01):
            ax.axhline(q, color="0.7", lw=0.8, ls=":")
        ax.set_xlabel(f"{kpi} [{COLUMNS[kpi][0]}]" + (" (more negative is worse)"
                                                      if direction < 0 else ""))
        ax.set_ylabel("share of runs at or beyond")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    for ax in list(axes.flat)[len(kpis):]:
        ax.set_visible(False)
    fig.suptitle(_plain(f"exceedance (1 - F), manoeuvre {manoeuvre}"))
    return _png(fig)


def _counts_text(c: dict) -> str:
    text = f"{c['values']} of {c['runs']}"
    if c["failed"]:
        text += f"; {c['failed']} failed"
    if c["no_value"]:
        text += f"; {c['no_value']} {c['no_value_reason']}"
    return text


def _summary(rep: dict) -> str:
    rows = [[_e(name), str(sec["runs"])] + [str(sec["verdict_counts"][flag]) for flag in
                                            ("draft_ok", "buff_ok", "travel_ok", "adhesion_ok")]
            for name, sec in rep["manoeuvres"].items()]
    out = [f"<p>{_e(rep['runs'])} of {_e(rep['expected_runs'])} runs, {_e(rep['failed'])} "
           f"failed; results folder <code>{_e(rep['folder'])}</code>.</p>"]
    out += [f'<p class="warn">warning: {_e(w)}</p>' for w in rep.get("warnings", ())]
    if rep["failures"]:
        out.append("<p>first failures:</p><ul>" + "".join(
            f"<li><code>{_e(m)}</code></li>" for m in rep["failures"]) + "</ul>")
    out.append(_table(["manoeuvre", "runs", "beyond the draft strength",
                       "beyond the buff strength", "beyond the couplers' travel",
                       "beyond the mean-adhesion limit"], rows, 1))
    return "\n".join(out)


def _quantiles(rep: dict, name: str, sec: dict) -> str:
    levels = sorted({q for qs in sec["quantiles"].values() for q in qs}, key=float)
    head = ["KPI", "unit", "worse", "runs with a value"] + [f"q{q}" for q in levels]
    from ..studies.campaign import COLUMNS

    rows = []
    for kpi, counts in sec["counts"].items():
        qs = sec["quantiles"].get(kpi, {})
        cells = [f"{_g(v['estimate'])} {_iv(v['low'], v['high'], _g)}<br>"
                 f"<span class=\"note\">tail {v['tail_points']}</span>" if v else "-"
                 for v in (qs.get(q) for q in levels)]
        rows.append([_e(kpi), _e(COLUMNS[kpi][0]), "larger" if KPIS[kpi][1] > 0 else
                     "more negative", _e(_counts_text(counts))] + cells)
    conf = 100 * rep["confidence"]
    out = [f"<p class=\"note\">qP: the value that a share 1 - P of the runs goes beyond in the "
           f"KPI's worse direction; estimate [{conf:g} % distribution-free interval], tail: "
           "the runs beyond the estimate.</p>", _table(head, rows, 4)]
    if sec["exceedance"]:
        erows = [[_e(kpi), _e(f"{'>' if e['beyond'] == 'above' else '<'} {e['threshold']:g}"),
                  f"{e['count']} / {e['of']}", _g(e["probability"]),
                  f"[{_g(e['interval'][0])}, {_g(e['interval'][1])}]"]
                 for kpi, e in sec["exceedance"].items()]
        out.append(_table(["KPI", "threshold", "runs", "probability",
                           f"{conf:g} % Wilson interval"], erows, 2))
    return "\n".join(out)


def _relative(rep: dict, sec: dict) -> str:
    if not sec["relative"]:
        return ""
    p = rep["pairing"]
    out = [f"<h3>Relative approach against {_e(rep['reference'])}</h3>",
           f"<p>q{_e(rep['quantile'])} in the worse direction, margin "
           f"{_e(_pct(rep['margin'], False))} of the reference's quantile, "
           f"{100 * rep['confidence']:g} % intervals; runs {_e(p['mode'])} "
           f"({_e(p['reason'])}).</p>"]
    rows = []
    for v in sec["relative"]:
        css = v["verdict"].replace(" ", "")
        cells = [f'<span class="{_e(css)}">{_e(v["verdict"])}</span>', _e(v["kpi"]),
                 "yes" if v["deciding"] else "no"]
        if v["compared"]:
            d, w = v["difference_interval"], v["worsening_interval"]
            cells += [_g(v["family"]), _g(v["reference"]),
                      f"{_g(v['difference'])} {_iv(d[0], d[1], _g)} {_e(v['unit'])}",
                      f"{_pct(v['worsening'])} {_iv(w[0], w[1], _pct)}",
                      _e(f"{_pct(v['margin'], False)} ({v['margin_value']:.4g} {v['unit']})"),
                      _e(v["note"])]
        else:
            cells += ["-", "-", "-", "-", "-", _e(v["note"])]
        rows.append(cells)
    out.append(_table(["verdict", "KPI", "decides", "family", "reference",
                       "family - reference", "worsening", "margin", "note"], rows, 3))
    return "\n".join(out)


def _sensitivity(sens: dict) -> str:
    """The design, the index tables and bars of a designed campaign."""
    from .sensitivity import format_sensitivity

    lines = format_sensitivity(sens)
    out = ["<h2>Design and sensitivity</h2>", f"<p>{'<br>'.join(_e(x) for x in lines[:2])}</p>"]
    if "error" in sens or sens["design"] == "grid":
        return "\n".join(out)
    sobol = sens["design"] == "sobol"
    inputs = sens["inputs"]
    plt = _pyplot()
    for name, section in sens["manoeuvres"].items():
        out.append(f"<h3>Manoeuvre {_e(name)}</h3>")
        shown = [(k, r) for k, r in section.items() if not r["note"]]
        for kpi, res in section.items():
            head = (["input", "S1", "S1 interval", "ST", "ST interval"] if sobol else
                    ["input", "mu*", "mu* interval", "mu", "sigma"])
            rows = []
            for n in inputs:
                v = res["indices"].get(n)
                if v is None:
                    continue
                a, b = ("S1", "ST") if sobol else ("mu_star", None)
                rows.append([_e(n), _g(v[a]), f"[{_g(v[a + '_interval'][0])}, "
                             f"{_g(v[a + '_interval'][1])}]"] + (
                    [_g(v[b]), f"[{_g(v[b + '_interval'][0])}, {_g(v[b + '_interval'][1])}]"]
                    if sobol else [_g(v["mu"]), _g(v["sigma"])]))
            kept = f"{res['complete_blocks']} of {res['blocks']} blocks"
            out.append(f"<p><b>{_e(kpi)}</b> [{_e(res['unit'])}] ({_e(kept)})"
                       + (f": {_e(res['note'])}" if res["note"] else "") + "</p>")
            if rows:
                out.append(_table(head, rows, 1))
        if not shown:
            continue
        cols = min(3, len(shown))
        rows_n = -(-len(shown) // cols)
        fig, axes = plt.subplots(rows_n, cols, figsize=(3.8 * cols, 3.2 * rows_n),
                                 squeeze=False)
        for ax in list(axes.flat)[len(shown):]:
            ax.set_visible(False)
        pos = np.arange(len(inputs))
        for ax, (kpi, res) in zip(axes.flat, shown):
            idx = [res["indices"][n] for n in inputs]
            bars = (("S1", "first order S1"), ("ST", "total ST")) if sobol else \
                (("mu_star", "mu*"), ("sigma", "sigma"))
            for k, (key, label) in enumerate(bars):
                val = np.array([v[key] for v in idx], float)
                err = None
                if key + "_interval" in idx[0]:
                    err = np.array([[v[key] - v[key + "_interval"][0] for v in idx],
                                    [v[key + "_interval"][1] - v[key] for v in idx]])
                    err = np.where(np.isfinite(err), np.abs(err), 0.0)
                ax.bar(pos + (k - 0.5) * 0.38, np.nan_to_num(val), 0.38, yerr=err,
                       capsize=3, label=label)
            ax.set_xticks(pos, [_plain(n) for n in inputs], rotation=30, ha="right", fontsize=8)
            ax.set_title(f"{kpi} [{res['unit']}]" if not sobol else kpi, fontsize=9)
            ax.grid(alpha=0.3, axis="y")
            ax.legend(fontsize=7)
        fig.suptitle(_plain(f"{'Sobol indices' if sobol else 'Morris mu* and sigma'}, "
                            f"manoeuvre {name}"), fontsize=10)
        out.append(_png(fig))
    return "\n".join(out)


def _worst(rep: dict, name: str, sec: dict) -> str:
    folder = rep["folder"]
    out_folder = f"{folder.rstrip('/')}_reruns"
    out = []
    for which, rows in sec["worst"].items():
        if not rows:
            continue
        body = []
        for r in rows:
            cmd = (f"ltd-brake campaign rerun {shlex.quote(folder)} --runs {r['run_id']} "
                   f"--manoeuvre {shlex.quote(name)} --out {shlex.quote(out_folder)}")
            body.append([str(r["run_id"]), _e(r["family"]), str(r["wagons"]),
                         _g(r["speed_kmh"]), _g(r["peak_draft_kN"]),
                         _e(r["peak_draft_coupler"]), _g(r["peak_buff_kN"]),
                         _e(r["peak_buff_coupler"]), _g(r["max_adhesion_demand"]),
                         _g(r["stopping_distance_m"]), f"<code>{_e(cmd)}</code>"])
        out.append(f"<p>worst runs by {_e(which)} force:</p>")
        out.append(_table(["run", "family", "wagons", "speed [km/h]", "draft [kN]", "@",
                           "buff [kN]", "@", "adhesion demand", "stopping [m]",
                           "rerun with a recording"], body, 2))
    return "\n".join(out)


def html_report(rep: dict, table=None, ref_table=None) -> str:
    """The report as the text of a self-contained HTML page.

    Parameters
    ----------
    rep : dict
        From :func:`~ltd_brake_ros.analysis.campaign_report.campaign_report`.
    table, ref_table : pyarrow.Table, optional
        The rows of the family and of the reference, for the exceedance curves (without
        them, the page has no curves).

    Returns
    -------
    str
        The page: inline style sheet, PNG figures in ``data:`` URIs, no external reference.
    """
    title = f"Campaign {rep['name']}"
    parts = [f"<h1>{_e(title)}</h1>", "<h2>Summary</h2>", _summary(rep)]
    if "outcome" in rep:
        css = rep["outcome"].replace(" ", "")
        parts.append(f'<p>Relative approach against {_e(rep["reference"])}: '
                     f'<span class="{_e(css)}">{_e(rep["outcome"])}</span> (deciding KPIs: '
                     f'{_e(", ".join(rep["deciding"]))}; exit status {exit_status(rep)}).</p>')
    for name, sec in rep["manoeuvres"].items():
        parts.append(f"<h2>Manoeuvre {_e(name)} ({sec['runs']} runs)</h2>")
        parts.append("<h3>Quantiles</h3>")
        parts.append(_quantiles(rep, name, sec))
        if table is not None:
            parts.append("<h3>Exceedance curves</h3>")
            parts.append("<p class=\"note\">The share of runs at or beyond each value in the "
                         "KPI's worse direction (1 - F; for the buff force, at or below), on a "
                         "log scale; the dotted lines mark 10 % and 1 % (q0.9 and q0.99).</p>")
            parts.append(_exceedance_figure(table, ref_table, name, rep["name"],
                                            rep.get("reference")))
        parts.append(_relative(rep, sec))
        parts.append("<h3>Worst runs</h3>")
        parts.append(_worst(rep, name, sec) or "<p>no successful run</p>")
    if rep.get("sensitivity"):
        parts.append(_sensitivity(rep["sensitivity"]))
    body = "\n".join(p for p in parts if p)
    return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n{body}\n"
            "</body>\n</html>\n")


def write_html(rep: dict, path, *, family=None, against=None) -> str:
    """Write the report to one self-contained HTML file.

    Parameters
    ----------
    rep : dict
        From :func:`~ltd_brake_ros.analysis.campaign_report.campaign_report`.
    path : path-like
        The file (replaced if it exists: the caller decides whether it may be).
    family : path-like or CampaignResults, optional
        The family's results (default: read from ``rep["folder"]``).
    against : path-like or CampaignResults, optional
        The reference's results (its exceedance curves beside the family's).

    Returns
    -------
    str
        The path written.
    """
    from .campaign_report import results_of

    table = results_of(family if family is not None else rep["folder"])[2]
    ref_table = results_of(against)[2] if against is not None else None
    text = html_report(rep, table, ref_table)
    Path(path).write_text(text, encoding="utf-8")
    return str(path)

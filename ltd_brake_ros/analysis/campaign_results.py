"""A campaign's results as a Python object: its rows, quantiles with intervals, exceedances,
the relative approach, sensitivity indices and the HTML page.

:class:`CampaignResults` is what :func:`ltd_brake_ros.read_campaign` and
:func:`ltd_brake_ros.run_campaign` return; ``ltd-brake campaign report`` computes its text,
JSON and HTML through the same object (:meth:`CampaignResults.report`,
:meth:`CampaignResults.to_html`), so a notebook gets the command line's numbers and verdicts.
:meth:`CampaignResults.compare` returns a :class:`Comparison`, the relative approach's
three-outcome verdict with every KPI's line.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..inputs import InputError
from ..studies.campaign_exec import read_results
from .campaign_kpis import KPIS

__all__ = ["CampaignResults", "Comparison"]


def _frame(rows: list[dict], columns: list[str]):
    import pandas as pd

    return pd.DataFrame(rows, columns=columns)


def _fmt(x) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.4g}"


class CampaignResults:
    """The results of a campaign folder, read and checked.

    Attributes
    ----------
    folder : str
        The results folder.
    manifest : dict
        Its ``manifest.json``: ``name``, ``seed``, ``runs``, ``sampling``, ``manoeuvres``,
        ``digest``, ``package_version``, ...
    table : pyarrow.Table
        Every row, one per train and manoeuvre, sorted by run id and manoeuvre; units and
        descriptions in its schema's field metadata.

    Examples
    --------
    >>> from ltd_brake_ros import read_campaign
    >>> res = read_campaign("runs/example")                       # doctest: +SKIP
    >>> res.quantiles(kpi="peak_draft_kN")                        # doctest: +SKIP
    >>> res.compare(read_campaign("runs/reference"), margin=0.05)  # doctest: +SKIP
    Comparison(example against reference, q0.99, margin 5 %): inconclusive
    """

    def __init__(self, folder: str | os.PathLike):
        meta, table = read_results(folder)
        self.folder = str(folder)
        self.manifest = meta
        self.table = table

    # ------------------------------------------------------------------ what it holds

    @property
    def name(self) -> str:
        """The campaign's name."""
        return str(self.manifest.get("name", self.folder))

    @property
    def manoeuvres(self) -> list[str]:
        """The manoeuvres every train ran, in the campaign's order."""
        return list(self.manifest.get("manoeuvres") or
                    dict.fromkeys(self.table["manoeuvre"].to_pylist()))

    def __len__(self) -> int:
        return self.table.num_rows

    def __eq__(self, other) -> bool:
        return isinstance(other, CampaignResults) and self.folder == other.folder and \
            self.manifest == other.manifest and self.table.equals(other.table)

    __hash__ = None  # mutable attributes: equal objects need not hash alike

    def to_dataframe(self):
        """The rows as a pandas DataFrame (one row per train and manoeuvre).

        Returns
        -------
        pandas.DataFrame
            Units of the columns in ``df.attrs["units"]`` (where the files state them), the
            schema's metadata in ``df.attrs["schema"]``.

        Examples
        --------
        >>> df = read_campaign("runs/example").to_dataframe()     # doctest: +SKIP
        >>> df.peak_buff_kN.min()                                  # doctest: +SKIP
        """
        table = self.table
        df = table.to_pandas()
        df.attrs["units"] = {f.name: f.metadata[b"unit"].decode() for f in table.schema
                             if f.metadata and b"unit" in f.metadata}
        meta = table.schema.metadata or {}
        if meta:
            df.attrs["schema"] = {k.decode(): v.decode(errors="replace")
                                  for k, v in meta.items()
                                  if not k.startswith(b"pandas") and not k.startswith(b"ARROW")}
        return df

    # ------------------------------------------------------------------ statistics

    def report(self, against: CampaignResults | str | os.PathLike | None = None, **options
               ) -> dict:
        """The report of ``ltd-brake campaign report`` as a dict (its ``--json``).

        Parameters
        ----------
        against : CampaignResults or path-like, optional
            The reference family (relative approach).
        **options
            ``thresholds``, ``quantile``, ``confidence``, ``margin``, ``kpis``,
            ``independent``, ``worst``, ``plots``, ``seed``, ``resamples``: see
            :func:`~ltd_brake_ros.analysis.campaign_report.campaign_report`.

        Returns
        -------
        dict

        Examples
        --------
        >>> rep = read_campaign("runs/example").report(thresholds={"peak_draft_kN": 400})  # doctest: +SKIP
        """
        from .campaign_report import campaign_report

        return campaign_report(self, against=against, **options)

    def quantiles(self, levels=(0.5, 0.9, 0.99), *, confidence: float = 0.95,
                  kpi: str | None = None, manoeuvre: str | None = None):
        """Quantiles of the KPIs in their worse direction, with their intervals.

        Parameters
        ----------
        levels : sequence of float, optional
            Levels q in the worse direction (q0.99: the value 1 % of the runs go beyond).
        confidence : float, optional
            Two-sided confidence of the intervals.
        kpi, manoeuvre : str, optional
            Only this KPI, this manoeuvre.

        Returns
        -------
        pandas.DataFrame
            ``manoeuvre``, ``kpi``, ``unit``, ``q``, ``estimate``, ``low``, ``high`` (NaN
            with too few runs beyond q: see ``note``), ``tail_points`` (runs beyond the
            estimate), ``values`` (runs with a value), ``note``.

        Examples
        --------
        >>> read_campaign("runs/example").quantiles([0.99], kpi="peak_buff_kN")  # doctest: +SKIP
        """
        import pyarrow.compute as pc

        from ..studies.campaign import COLUMNS
        from .campaign_intervals import quantile_interval
        from .campaign_report import _beyond, _column, _column_level, _too_few

        kpis = self._kpis(kpi)
        rows = []
        for name in self._manoeuvres(manoeuvre):
            part = self.table.filter(pc.equal(self.table["manoeuvre"], name))
            for k in kpis:
                x = _column(part, k)
                n = int(np.isfinite(x).sum())
                for q in levels:
                    level = _column_level(k, q)
                    est, lo, hi = quantile_interval(x, level, confidence)
                    rows.append({"manoeuvre": name, "kpi": k, "unit": COLUMNS[k][0], "q": q,
                                 "estimate": est, "low": lo, "high": hi,
                                 "tail_points": _beyond(k, x, est) if n else 0, "values": n,
                                 "note": "" if math.isfinite(lo) or not n else
                                 _too_few(q, n)})
        return _frame(rows, ["manoeuvre", "kpi", "unit", "q", "estimate", "low", "high",
                             "tail_points", "values", "note"])

    def exceedance_curve(self, kpi: str, manoeuvre: str | None = None):
        """The exceedance curve 1 - F of a KPI: the share of runs at or beyond each value in
        its worse direction (the HTML page's curve).

        Parameters
        ----------
        kpi : str
            E.g. ``peak_buff_kN`` (more negative is worse) or ``peak_draft_kN``.
        manoeuvre : str, optional
            Default: the first manoeuvre.

        Returns
        -------
        pandas.DataFrame
            ``value`` (in the KPI's unit, worst last) and ``share`` (at or beyond it, 0 to
            1), one row per run with a value.

        Examples
        --------
        >>> c = read_campaign("runs/example").exceedance_curve("peak_draft_kN")  # doctest: +SKIP
        >>> c.plot(x="value", y="share", logy=True)                              # doctest: +SKIP
        """
        from .campaign_html import _values

        (name,) = self._manoeuvres(manoeuvre or self.manoeuvres[0])
        x = _values(self.table, name, self._kpis(kpi)[0])
        s = np.sort(x)[::KPIS[kpi][1]]
        share = (len(s) - np.arange(len(s))) / max(len(s), 1)
        return _frame([{"value": v, "share": p} for v, p in zip(s, share)], ["value", "share"])

    def exceedance(self, thresholds: dict, *, confidence: float = 0.95):
        """The probability of each KPI going beyond a threshold in its worse direction, with
        its Wilson interval (``--threshold``).

        Parameters
        ----------
        thresholds : dict
            KPI -> value in its unit, e.g. ``{"peak_draft_kN": 400, "peak_buff_kN": -400}``
            (buff forces are negative: beyond is below).
        confidence : float, optional

        Returns
        -------
        pandas.DataFrame
            ``manoeuvre``, ``kpi``, ``threshold``, ``beyond`` (above/below), ``count``,
            ``of`` (runs with a value), ``probability``, ``low``, ``high``.

        Examples
        --------
        >>> read_campaign("runs/example").exceedance({"peak_draft_kN": 400})  # doctest: +SKIP
        """
        from .campaign_report import parse_thresholds

        parse_thresholds([f"{k}={v}" for k, v in thresholds.items()])  # one line if bad
        rep = self.report(thresholds=dict(thresholds), confidence=confidence)
        rows = [{"manoeuvre": name, "kpi": k, "threshold": e["threshold"], "beyond": e["beyond"],
                 "count": e["count"], "of": e["of"], "probability": e["probability"],
                 "low": e["interval"][0], "high": e["interval"][1]}
                for name, sec in rep["manoeuvres"].items() for k, e in sec["exceedance"].items()]
        return _frame(rows, ["manoeuvre", "kpi", "threshold", "beyond", "count", "of",
                             "probability", "low", "high"])

    def compare(self, other: CampaignResults | str | os.PathLike, *, margin: float = 0.05,
                kpi=None, quantile: float = 0.99, confidence: float = 0.95,
                independent: bool = False) -> Comparison:
        """The relative approach against a reference family: the same three-outcome verdict
        as ``ltd-brake campaign report DIR --against REF_DIR``.

        Parameters
        ----------
        other : CampaignResults or path-like
            The reference family.
        margin : float, optional
            How much worse than the reference's quantile the family's may be, as a share of
            it (0.05: 5 %).
        kpi : str or sequence of str, optional
            The deciding KPIs (default ``peak_draft_kN`` and ``peak_buff_kN``).
        quantile : float, optional
            Level compared, in each KPI's worse direction.
        confidence : float, optional
            Two-sided confidence of the intervals (a verdict is a one-sided test at
            (1 - confidence) / 2).
        independent : bool, optional
            Compare as independent samples even when the runs are the same trains.

        Returns
        -------
        Comparison

        Raises
        ------
        InputError
            A bad option, or nothing to compare.

        Examples
        --------
        >>> new, ref = read_campaign("runs/new"), read_campaign("runs/reference")  # doctest: +SKIP
        >>> c = new.compare(ref, margin=0.05, kpi="peak_draft_kN", quantile=0.9)   # doctest: +SKIP
        >>> c.outcome, c.exit_status                                               # doctest: +SKIP
        ('worse', 1)
        >>> c.verdicts[["kpi", "verdict", "worsening", "worsening_low", "worsening_high"]]  # doctest: +SKIP
        """
        from .campaign_report import parse_kpis

        check_options(quantile=quantile, confidence=confidence, margin=margin)
        kpis = parse_kpis([kpi] if isinstance(kpi, str) else list(kpi) if kpi else None)
        return Comparison(self.report(against=other, quantile=quantile, confidence=confidence,
                                      margin=margin, kpis=kpis, independent=independent))

    def sensitivity(self, *, confidence: float = 0.95, seed: int = 0):
        """Sobol' indices (a ``sobol`` campaign) or Morris's elementary effects (``morris``)
        of every KPI, with their bootstrap intervals (SALib).

        Parameters
        ----------
        confidence : float, optional
        seed : int, optional
            Seed of the bootstrap.

        Returns
        -------
        pandas.DataFrame
            ``manoeuvre``, ``kpi``, ``unit``, ``input`` and, for ``sobol``, ``S1``,
            ``S1_low``, ``S1_high``, ``ST``, ``ST_low``, ``ST_high``; for ``morris``,
            ``mu_star``, ``mu_star_low``, ``mu_star_high``, ``mu``, ``sigma``; ``note`` (why a
            KPI has no indices). Shares of the KPI's variance (Sobol'); the KPI's unit per
            whole level range (Morris).

        Raises
        ------
        InputError
            The campaign is not a ``sobol`` or ``morris`` design.

        Examples
        --------
        >>> read_campaign("runs/sobol_example").sensitivity().query("kpi == 'peak_draft_kN'")  # doctest: +SKIP
        """
        from .sensitivity import sensitivity_report

        kind = self.manifest.get("sampling")
        if kind not in ("sobol", "morris"):
            raise InputError(self.folder, "sampling", f"{kind}: sensitivity indices come from "
                             "a sobol or morris design")
        sens = sensitivity_report(self.folder, self.manifest, self.table,
                                  confidence=confidence, seed=seed)
        if "error" in sens:
            raise InputError(self.folder, "", sens["error"])
        keys = ("S1", "ST") if kind == "sobol" else ("mu_star",)
        rows = []
        for name, section in sens["manoeuvres"].items():
            for k, res in section.items():
                for inp in sens["inputs"]:
                    v = res["indices"].get(inp, {})
                    row = {"manoeuvre": name, "kpi": k, "unit": res["unit"], "input": inp,
                           "note": res["note"]}
                    for key in keys:
                        lo, hi = v.get(f"{key}_interval", (math.nan, math.nan))
                        row.update({key: v.get(key, math.nan), f"{key}_low": lo,
                                    f"{key}_high": hi})
                    if kind == "morris":
                        row.update(mu=v.get("mu", math.nan), sigma=v.get("sigma", math.nan))
                    rows.append(row)
        cols = ["manoeuvre", "kpi", "unit", "input"] + [f"{k}{s}" for k in keys
                                                        for s in ("", "_low", "_high")]
        return _frame(rows, cols + (["mu", "sigma"] if kind == "morris" else []) + ["note"])

    def to_html(self, path: str | os.PathLike,
                against: CampaignResults | str | os.PathLike | None = None, *,
                force: bool = False, **options) -> Path:
        """Write the report as one self-contained HTML page (``--html``): style inline,
        figures embedded, nothing loaded from elsewhere.

        Parameters
        ----------
        path : path-like
            The file; an existing one is refused unless ``force``.
        against : CampaignResults or path-like, optional
            The reference family (the relative approach and its exceedance curves).
        force : bool, optional
            Replace an existing file.
        **options
            As for :meth:`report`.

        Returns
        -------
        pathlib.Path

        Examples
        --------
        >>> read_campaign("runs/new").to_html("new.html", against="runs/reference")  # doctest: +SKIP
        """
        from .campaign_html import write_html

        path = Path(path)
        if path.exists() and not force:
            raise InputError(path, "", "exists; give a new file, or force=True to replace it")
        if not path.parent.is_dir():
            raise InputError(path, "", f"{path.parent} does not exist")
        ref = against if against is None or isinstance(against, CampaignResults) else \
            CampaignResults(against)
        rep = self.report(against=ref, **options)
        return Path(write_html(rep, path, family=self, against=ref))

    # ------------------------------------------------------------------ helpers, display

    def _kpis(self, kpi: str | None) -> list[str]:
        if kpi is None:
            return list(KPIS)
        if kpi not in KPIS:
            raise InputError("kpi", "", f"unknown KPI {kpi!r}; known: {', '.join(KPIS)}")
        return [kpi]

    def _manoeuvres(self, manoeuvre: str | None) -> list[str]:
        if manoeuvre is None:
            return self.manoeuvres
        if manoeuvre not in self.manoeuvres:
            raise InputError("manoeuvre", "", f"no manoeuvre {manoeuvre!r} in the results; "
                             f"they hold {', '.join(self.manoeuvres)}")
        return [manoeuvre]

    def _summary(self) -> tuple[str, int, int]:
        status = np.array(self.table["status"].to_pylist())
        runs = self.manifest.get("runs", 0) * len(self.manoeuvres)
        return self.manifest.get("sampling", "?"), runs, int((status != "ok").sum())

    def __repr__(self) -> str:
        sampling, expected, failed = self._summary()
        return (f"CampaignResults({self.name!r}: {len(self)} of {expected} runs, {failed} "
                f"failed, {sampling}, manoeuvres {', '.join(self.manoeuvres)}; "
                f"folder {self.folder!r})")

    def _repr_html_(self) -> str:
        from html import escape

        sampling, expected, failed = self._summary()
        q = self.quantiles([0.5, 0.99])
        rows = "".join(
            f"<tr><td>{escape(r.manoeuvre)}</td><td>{escape(r.kpi)} [{escape(r.unit)}]</td>"
            f"<td>q{r.q:g}</td><td>{_fmt(r.estimate)}</td><td>"
            + (f"[{_fmt(r.low)}, {_fmt(r.high)}]" if math.isfinite(r.low) else
               "too few runs") + "</td></tr>"
            for r in q.itertuples() if r.values)
        return (f"<b>CampaignResults</b> {escape(self.name)}: {len(self)} of {expected} runs, "
                f"{failed} failed, {escape(str(sampling))}; folder "
                f"<code>{escape(self.folder)}</code>"
                "<table><tr><th>manoeuvre</th><th>KPI</th><th>q</th><th>estimate</th>"
                f"<th>95 % interval</th></tr>{rows}</table>")


def check_options(*, quantile: float = 0.5, confidence: float = 0.95, margin: float = 0.0
                  ) -> None:
    """One line naming the option for a level, confidence or margin out of range.

    Raises
    ------
    InputError
    """
    if not 0.0 < quantile < 1.0:
        raise InputError("--quantile", "", f"must be between 0 and 1, got {quantile}")
    if not 0.5 <= confidence < 1.0:
        raise InputError("--confidence", "", f"must be in [0.5, 1), got {confidence}")
    if not (math.isfinite(margin) and 0.0 <= margin < 1.0):
        raise InputError("--margin", "", f"must be in [0, 1) (a share of the reference's "
                         f"quantile, 0.05 = 5 %), got {margin}")


class Comparison:
    """The relative approach of a family against a reference (:meth:`CampaignResults.compare`).

    Attributes
    ----------
    outcome : str
        ``not worse`` (every deciding KPI), ``worse`` (one of them) or ``inconclusive``.
    exit_status : int
        The command line's: 0, 1, 4.
    report : dict
        The whole report (:func:`~ltd_brake_ros.analysis.campaign_report.campaign_report`);
        its ``pairing`` says whether the runs were compared as paired.

    Examples
    --------
    >>> c = read_campaign("runs/new").compare("runs/reference", quantile=0.9)  # doctest: +SKIP
    >>> c.outcome                                                             # doctest: +SKIP
    'worse'
    """

    def __init__(self, report: dict):
        from .campaign_report import exit_status

        self.report = report
        self.outcome = report["outcome"]
        self.exit_status = exit_status(report)

    def __eq__(self, other) -> bool:
        from .campaign_report import as_json

        return isinstance(other, Comparison) and as_json(self.report) == as_json(other.report)

    __hash__ = None

    @property
    def verdicts(self):
        """Every KPI's line as a DataFrame.

        Returns
        -------
        pandas.DataFrame
            ``manoeuvre``, ``kpi``, ``unit``, ``verdict``, ``deciding``, ``family``,
            ``reference`` (quantiles), ``difference`` with ``difference_low`` and
            ``difference_high`` (in the unit), ``worsening`` with ``worsening_low`` and
            ``worsening_high`` (0.05 = 5 % worse), ``margin``, ``correlation``, ``note``.
        """
        rows = []
        for name, sec in self.report["manoeuvres"].items():
            for v in sec["relative"]:
                d = v.get("difference_interval", (math.nan, math.nan))
                w = v.get("worsening_interval", (math.nan, math.nan))
                rows.append({"manoeuvre": name, "kpi": v["kpi"], "unit": v["unit"],
                             "verdict": v["verdict"], "deciding": v["deciding"],
                             "family": v.get("family", math.nan),
                             "reference": v.get("reference", math.nan),
                             "difference": v.get("difference", math.nan),
                             "difference_low": d[0], "difference_high": d[1],
                             "worsening": v.get("worsening", math.nan),
                             "worsening_low": w[0], "worsening_high": w[1],
                             "margin": v["margin"],
                             "correlation": v.get("correlation", math.nan), "note": v["note"]})
        return _frame(rows, ["manoeuvre", "kpi", "unit", "verdict", "deciding", "family",
                             "reference", "difference", "difference_low", "difference_high",
                             "worsening", "worsening_low", "worsening_high", "margin",
                             "correlation", "note"])

    def __repr__(self) -> str:
        r = self.report
        return (f"Comparison({r['name']} against {r['reference']}, q{r['quantile']:g}, margin "
                f"{100 * r['margin']:g} %, {r['pairing']['mode']}): {self.outcome}")

    def _repr_html_(self) -> str:
        from html import escape

        def pct(x):
            return "n/a" if not math.isfinite(x) else f"{100 * x:+.1f} %"

        rows = "".join(
            f"<tr><td>{escape(v.verdict)}</td><td>{escape(v.kpi)}"
            f"{'' if v.deciding else ' (does not decide)'}</td><td>{pct(v.worsening)}</td><td>"
            + (f"[{pct(v.worsening_low)}, {pct(v.worsening_high)}]"
               if math.isfinite(v.worsening_low) else escape(v.note or "no interval"))
            + "</td></tr>" for v in self.verdicts.itertuples())
        return (f"<b>{escape(self.outcome)}</b>: {escape(repr(self))}<table><tr>"
                "<th>verdict</th><th>KPI</th><th>worsening</th><th>interval</th></tr>"
                f"{rows}</table>")

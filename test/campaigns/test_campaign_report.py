"""Campaign report: quantiles and intervals, missing values, exceedances, plots, the relative
approach (paired and independent runs, non-inferiority verdicts, exit statuses)."""
from __future__ import annotations

import json
import math

import numpy as np
import pyarrow as pa
import pytest
from campaign_helpers import write_campaign

from ltd_brake_ros.analysis import campaign_report as report_module
from ltd_brake_ros.analysis import campaign_results as results_module
from ltd_brake_ros.analysis.campaign_intervals import TOO_FEW
from ltd_brake_ros.analysis.campaign_report import campaign_report
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.studies.campaign_exec import PoolExecutor, read_results, run_campaign

#: Quantile level of the relative-approach tests: 20 runs of 200 beyond it, the fewest that
#: give an interval.
Q = 0.9
#: Runs of the relative-approach families.
RUNS = 200


def _run(folder, name, runs, edit=None, **kw):
    """Run the small campaign ``name`` (its text changed by ``edit``) into folder/name."""
    path = write_campaign(folder, name=name, runs=runs, batch=10, **kw)
    if edit:
        path.write_text(edit(path.read_text()))
    with PoolExecutor(2) as pool:
        run_campaign(load_campaign(path), folder / name, pool)
    return folder / name


def _column(folder, name) -> np.ndarray:
    return np.array(read_results(folder)[1][name].to_pylist(), float)


def _entry(rep, kpi, manoeuvre="emergency") -> dict:
    return next(v for v in rep["manoeuvres"][manoeuvre]["relative"] if v["kpi"] == kpi)


@pytest.fixture(scope="module")
def families(tmp_path_factory):
    """A slow family and a fast one (same trains, 30-50 against 60-70 km/h)."""
    folder = tmp_path_factory.mktemp("families")
    return {name: _run(folder, name, 40, v_lo=lo, v_hi=hi)
            for name, lo, hi in (("slow", 30.0, 50.0), ("fast", 60.0, 70.0))}


@pytest.fixture(scope="module")
def changes(tmp_path_factory):
    """A reference and, from the same seed (the same trains), a harmful change (the mean of
    the k0 scale of the block friction lowered by 1.5 standard deviations: more brake force,
    larger in-train forces) and a null change (the identical campaign under another name);
    the reference from another seed; and from the same seed other trains (heavier wagons)."""
    folder = tmp_path_factory.mktemp("changes")
    return {
        "reference": _run(folder, "reference", RUNS),
        "harmful": _run(folder, "harmful", RUNS, lambda t: t.replace("mean: 2.7", "mean: 2.55")),
        "null": _run(folder, "null", RUNS),
        "other_seed": _run(folder, "other_seed", 8, lambda t: t.replace("seed: 11", "seed: 12")),
        "other_trains": _run(folder, "other_trains", 8,
                             lambda t: t.replace("tare_t: 22.0", "tare_t: 23.0")),
    }


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """100 service applications (half demand, released after 25 s): some trains stop within
    the 40 s, the others have no stopping distance."""
    folder = tmp_path_factory.mktemp("service")
    return _run(folder, "service", 100, lambda t: t.replace(
        "  - {kind: emergency, speed_kmh: {uniform: [30.0, 50.0]}}",
        "  - {name: service, kind: service, speed_kmh: {uniform: [30.0, 50.0]}, demand: 0.5, "
        "release_s: 25.0, duration_s: 40.0}"))


def test_quantiles_and_exceedance_match_the_table(families, tmp_path):
    rep = campaign_report(families["slow"], thresholds={"stopping_distance_m": 150.0,
                                                        "peak_buff_kN": -20.0}, plots=tmp_path)
    x = _column(families["slow"], "stopping_distance_m")
    sec = rep["manoeuvres"]["emergency"]
    med = sec["quantiles"]["stopping_distance_m"]["0.5"]
    assert med["estimate"] == pytest.approx(np.median(x)) and med["low"] <= med["estimate"] \
        <= med["high"]
    e = sec["exceedance"]["stopping_distance_m"]
    assert e["count"] == int((x > 150.0).sum()) and e["of"] == 40
    assert e["interval"][0] <= e["probability"] <= e["interval"][1]
    # buff forces are negative: beyond -20 kN is below it, and q0.9 is the 0.1 quantile
    buff = _column(families["slow"], "peak_buff_kN")
    assert sec["exceedance"]["peak_buff_kN"]["count"] == int((buff < -20.0).sum())
    q9 = sec["quantiles"]["peak_buff_kN"]["0.9"]
    assert q9["estimate"] == pytest.approx(np.quantile(buff, 0.1)) and q9["column_level"] \
        == pytest.approx(0.1)
    # a CDF and a histogram per KPI (the adhesion design check whatever the run's speed)
    assert len(rep["plots"]) == 10 and all((tmp_path / p).stat().st_size > 1000
                                          for p in rep["plots"])
    assert sec["worst"]["buff"][0]["peak_buff_kN"] == buff.min()


def test_a_positive_buff_threshold_is_refused(families, capsys):
    assert main(["campaign", "report", str(families["slow"]), "--threshold",
                 "peak_buff_kN=400"]) == 2
    assert "write peak_buff_kN=-400" in capsys.readouterr().err


def test_faster_trains_are_worse_on_stopping_distance(families, capsys):
    assert main(["campaign", "report", str(families["fast"]), "--against",
                 str(families["slow"]), "--kpi", "stopping_distance_m", "--quantile",
                 "0.5"]) == 1
    out = capsys.readouterr().out
    # the same seed, but other speeds: not the same runs, independent samples
    assert "runs: independent (same seed 11, but run 0 (emergency) differs in speed_kmh" \
        in out
    assert "worse         stopping_distance_m [m]" in out
    assert main(["campaign", "report", str(families["slow"]), "--against",
                 str(families["slow"]), "--quantile", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "runs: paired" in out and out.count("not worse     ") == 5  # every KPI
    assert "relative approach: not worse" in out


def test_paired_runs_decide_where_independent_samples_cannot(changes, capsys):
    ref, harmful, null = changes["reference"], changes["harmful"], changes["null"]
    # the harmful change raises the peak draft force of the trains: far more of them than the
    # half (and three binomial standard deviations) that chance would give
    raised = int((_column(harmful, "peak_draft_kN") > _column(ref, "peak_draft_kN")).sum())
    assert raised > RUNS / 2 + 3 * math.sqrt(RUNS * 0.25)
    argv = ["campaign", "report", "--against", str(ref), "--quantile", str(Q)]
    assert main([*argv, str(harmful)]) == 1
    out = capsys.readouterr().out
    assert "runs: paired (same seed 11 and the same trains" in out
    assert f"in all {RUNS} common runs" in out and "relative approach: worse" in out
    assert main([*argv, str(null)]) == 0
    assert "relative approach: not worse" in capsys.readouterr().out
    for folder in (harmful, null):
        assert main([*argv, str(folder), "--independent"]) == 4
        out = capsys.readouterr().out
        assert "runs: independent (independent comparison requested)" in out
        assert "relative approach: inconclusive" in out
        rep = campaign_report(folder, against=ref, quantile=Q, independent=True)
        assert {_entry(rep, k)["verdict"] for k in rep["deciding"]} == {"inconclusive"}

    paired = campaign_report(harmful, against=ref, quantile=Q)
    alone = campaign_report(harmful, against=ref, quantile=Q, independent=True)
    assert paired["pairing"]["mode"] == "paired" and alone["pairing"]["mode"] == "independent"
    p, i = _entry(paired, "peak_draft_kN"), _entry(alone, "peak_draft_kN")
    assert p["verdict"] == "worse" and i["verdict"] == "inconclusive"
    # the same estimate from the table; pairing removes the train-to-train scatter
    x, y = _column(harmful, "peak_draft_kN"), _column(ref, "peak_draft_kN")
    assert p["worsening"] == i["worsening"] == pytest.approx(
        (np.quantile(x, Q) - np.quantile(y, Q)) / np.quantile(y, Q))
    assert np.ptp(p["worsening_interval"]) < np.ptp(i["worsening_interval"])
    assert p["worsening_interval"][0] > p["margin"]
    assert i["worsening_interval"][0] <= i["margin"] <= i["worsening_interval"][1]
    # the null change: the same values run by run, a difference of exactly 0
    same = campaign_report(null, against=ref, quantile=Q)
    for kpi in ("peak_draft_kN", "peak_buff_kN"):
        v = _entry(same, kpi)
        assert v["verdict"] == "not worse" and tuple(v["worsening_interval"]) == (0.0, 0.0)


def test_buff_worsens_towards_more_negative_forces(changes):
    rep = campaign_report(changes["harmful"], against=changes["reference"], quantile=Q)
    v = _entry(rep, "peak_buff_kN")
    x, y = _column(changes["harmful"], "peak_buff_kN"), _column(changes["reference"],
                                                                  "peak_buff_kN")
    fx, fy = np.quantile(x, 1 - Q), np.quantile(y, 1 - Q)  # the 10 % most negative
    assert v["direction"] == -1 and v["column_level"] == pytest.approx(1 - Q)
    assert (v["family"], v["reference"]) == pytest.approx((fx, fy))
    assert v["difference"] == pytest.approx(fx - fy)
    assert v["worsening"] == pytest.approx(-(fx - fy) / abs(fy))
    assert tuple(v["tail_points"]) == (int((x < fx).sum()), int((y < fy).sum()))


def test_pairing_needs_the_same_seed_and_the_same_trains(changes):
    ref = changes["reference"]
    rep = campaign_report(changes["other_seed"], against=ref, quantile=Q)
    assert rep["pairing"]["mode"] == "independent"
    assert rep["pairing"]["reason"] == "the seeds differ (12 and 11): other trains"
    rep = campaign_report(changes["other_trains"], against=ref, quantile=Q)
    assert rep["pairing"] == {"mode": "independent", "common_runs": 8, "reason": "same seed "
                              "11, but run 0 (emergency) differs in wagon_mass_t: other trains"}


def test_inconclusive_verdicts_state_the_runs_that_would_decide(changes, capsys):
    rep = campaign_report(changes["harmful"], against=changes["reference"], quantile=Q,
                          independent=True)
    v = _entry(rep, "peak_draft_kN")
    assert v["verdict"] == "inconclusive"
    est, (lo, hi), m = v["worsening"], v["worsening_interval"], v["margin"]
    n, n_ref = v["runs_needed"]
    assert n == n_ref  # both families of RUNS runs, scaled alike
    # the half-width on the margin's side shrinks as sqrt(RUNS / N): at N runs it just clears
    # the margin, one run fewer it does not
    h = hi - est if est < m else est - lo
    assert h * math.sqrt(RUNS / n) <= abs(est - m) < h * math.sqrt(RUNS / (n - 1))
    main(["campaign", "report", str(changes["harmful"]), "--against",
          str(changes["reference"]), "--quantile", str(Q), "--independent"])
    assert (f"about {n} runs of the family and {n_ref} of the reference would decide at the "
            "observed spread") in capsys.readouterr().out


def test_kpi_chooses_the_deciding_kpis(changes, capsys):
    argv = ["campaign", "report", str(changes["harmful"]), "--against",
            str(changes["reference"]), "--quantile", str(Q)]
    # more brake force: shorter stops (not worse), larger draft forces (worse, not deciding)
    assert main([*argv, "--kpi", "stopping_distance_m"]) == 0
    out = capsys.readouterr().out
    assert "not worse     stopping_distance_m [m], larger is worse:" in out
    assert "worse         peak_draft_kN [kN], larger is worse (shown, does not decide):" in out
    assert "deciding KPIs: stopping_distance_m;" in out
    assert main([*argv, "--kpi", "stopping_distance_m", "--kpi", "peak_draft_kN"]) == 1
    assert "deciding KPIs: stopping_distance_m, peak_draft_kN;" in capsys.readouterr().out
    assert main([*argv, "--kpi", "stopping_distance_m", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["deciding"] == ["stopping_distance_m"] and rep["outcome"] == "not worse"
    deciding = {v["kpi"] for v in rep["manoeuvres"]["emergency"]["relative"] if v["deciding"]}
    assert deciding == {"stopping_distance_m"}


def test_bad_relative_options_are_one_line(changes, capsys):
    argv = ["campaign", "report", str(changes["harmful"]), "--against",
            str(changes["reference"])]
    for extra, message in ((["--kpi", "speed"], "--kpi: unknown KPI 'speed'"),
                           (["--kpi", "abs_peak_buff_kN"], "the buff force is peak_buff_kN"),
                           (["--margin", "1.5"], "--margin: must be in [0, 1)"),
                           (["--margin", "nan"], "--margin: must be in [0, 1)")):
        assert main([*argv, *extra]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and message in err
    assert main(["campaign", "report", str(changes["harmful"]), "--kpi", "peak_draft_kN"]) == 2
    assert "give --against REF_DIR" in capsys.readouterr().err


def test_every_quantile_says_over_how_many_runs_and_why_others_have_none(service, capsys):
    stop = _column(service, "stopping_distance_m")
    stopped = int(np.isfinite(stop).sum())
    assert 0 < stopped < 100  # the setup: some trains stop, some do not
    assert main(["campaign", "report", str(service)]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if " q0.5: " in line]
    assert len(lines) == 5  # every KPI: the adhesion design check whatever the run
    assert all("of 100 runs" in line for line in lines)
    assert (f"stopping_distance_m [m], larger is worse ({stopped} of 100 runs; "
            f"{100 - stopped} without a value: {100 - stopped} did not stop): q0.5:") in out
    rep = campaign_report(service)
    sec = rep["manoeuvres"]["service"]
    assert sec["counts"]["stopping_distance_m"] == {
        "runs": 100, "values": stopped, "failed": 0, "no_value": 100 - stopped,
        "no_value_reason": "did not stop"}
    # the runs beyond each quantile: about n (1 - q) of the runs with a value
    for q, v in sec["quantiles"]["stopping_distance_m"].items():
        assert v["tail_points"] == int((stop > v["estimate"]).sum())
        assert abs(v["tail_points"] - stopped * (1 - float(q))) <= 1


def test_failed_runs_are_counted_apart(service, monkeypatch, capsys):
    meta, table = read_results(service)
    rows = table.to_pylist()
    for r in rows[:3]:  # three runs failed: no KPI at all
        r.update(status="failed", message="SimulationError: diverged", stopping_distance_m=None,
                 peak_draft_kN=None, peak_buff_kN=None, max_adhesion_demand=None)
    damaged = pa.Table.from_pylist(rows, schema=table.schema)
    monkeypatch.setattr(report_module, "read_results", lambda folder: (meta, damaged))
    monkeypatch.setattr(results_module, "read_results", lambda folder: (meta, damaged))
    stop = _column(service, "stopping_distance_m")
    stopped = int(np.isfinite(stop[3:]).sum())
    no_stop = 97 - stopped
    assert main(["campaign", "report", str(service), "--json"]) == 0
    text = capsys.readouterr().out
    json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} is not JSON"))
    rep = campaign_report(service)
    counts = rep["manoeuvres"]["service"]["counts"]
    assert counts["stopping_distance_m"] == {"runs": 100, "values": stopped, "failed": 3,
                                             "no_value": no_stop,
                                             "no_value_reason": "did not stop"}
    assert counts["peak_draft_kN"]["values"] == 97 and counts["peak_draft_kN"]["failed"] == 3
    assert main(["campaign", "report", str(service)]) == 0
    out = capsys.readouterr().out
    assert (f"({stopped} of 100 runs; {100 - stopped} without a value: 3 failed, {no_stop} did "
            "not stop)") in out
    assert "peak_draft_kN [kN], larger is worse (97 of 100 runs; 3 without a value: 3 failed)" \
        in out


def test_too_few_runs_beyond_the_quantile_give_no_interval_and_no_verdict(changes, capsys):
    # 200 runs put 2 beyond q0.99: no interval of the quantiles, nor of their difference
    ref, harmful = changes["reference"], changes["harmful"]
    rep = campaign_report(harmful, against=ref, quantile=0.99)
    q99 = rep["manoeuvres"]["emergency"]["quantiles"]["peak_draft_kN"]["0.99"]
    assert math.isnan(q99["low"]) and q99["note"].startswith(TOO_FEW)
    assert "2000 give one" in q99["note"]
    for kpi in rep["deciding"]:
        v = _entry(rep, kpi)
        assert v["verdict"] == "inconclusive" and v["note"].startswith(TOO_FEW)
        assert all(math.isnan(b) for b in (*v["worsening_interval"], *v["difference_interval"]))
    assert main(["campaign", "report", str(harmful), "--against", str(ref)]) == 4
    out = capsys.readouterr().out
    assert f"q0.99: {q99['estimate']:.4g} ({TOO_FEW}) tail" in out
    assert "(no interval) against the margin 5.0 %" in out and f"; {TOO_FEW} (" in out


def test_report_of_a_folder_without_results_is_one_line(tmp_path, capsys):
    assert main(["campaign", "report", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"ltd-brake campaign: error: {tmp_path}: is not a campaign results folder "
        "(no manifest.json)")

"""Campaign report: quantiles and intervals, exceedances, plots, the relative approach."""
from __future__ import annotations

import numpy as np
import pytest
from campaign_helpers import write_campaign

from ltd_brake_ros.analysis.campaign_report import bootstrap_quantile, campaign_report
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.studies.campaign_exec import PoolExecutor, read_results, run_campaign


@pytest.fixture(scope="module")
def families(tmp_path_factory):
    """A slow family and a fast one (same trains, 30-50 against 60-70 km/h)."""
    folder = tmp_path_factory.mktemp("families")
    out = {}
    with PoolExecutor(2) as pool:
        for name, lo, hi in (("slow", 30.0, 50.0), ("fast", 60.0, 70.0)):
            c = load_campaign(write_campaign(folder, name=name, runs=30, batch=5, v_lo=lo,
                                             v_hi=hi))
            run_campaign(c, folder / name, pool)
            out[name] = folder / name
    return out


def test_quantiles_and_exceedance_match_the_table(families, tmp_path):
    rep = campaign_report(families["slow"], thresholds={"stopping_distance_m": 150.0},
                          plots=tmp_path)
    x = np.array(read_results(families["slow"])[1]["stopping_distance_m"].to_pylist())
    sec = rep["manoeuvres"]["emergency"]
    est, lo, hi = sec["quantiles"]["stopping_distance_m"]["0.5"]
    assert est == pytest.approx(np.median(x)) and lo <= est <= hi
    e = sec["exceedance"]["stopping_distance_m"]
    assert e["count"] == int((x > 150.0).sum()) and e["of"] == 30
    assert e["interval"][0] <= e["probability"] <= e["interval"][1]
    # a CDF and a histogram per KPI; the slow family has no stop from 100 km/h, so no mean
    # utilised adhesion to draw
    assert len(rep["plots"]) == 8 and all((tmp_path / p).stat().st_size > 1000
                                          for p in rep["plots"])
    worst = sec["worst"]["buff"]
    assert worst[0]["peak_buff_kN"] == min(read_results(families["slow"])[1]["peak_buff_kN"]
                                           .to_pylist())


def test_relative_approach_fails_the_faster_family_on_stopping_distance(families, capsys):
    assert main(["campaign", "report", str(families["fast"]), "--against",
                 str(families["slow"])]) == 1
    out = capsys.readouterr().out
    assert "FAIL  stopping distance q0.99" in out
    assert main(["campaign", "report", str(families["slow"]), "--against",
                 str(families["slow"])]) == 0
    out = capsys.readouterr().out
    assert out.count("PASS") == 4 and "FAIL" not in out


def test_bootstrap_interval_covers_the_true_quantile():
    # the 0.9 quantile of U(0, 1) is 0.9; a 95 % interval from 400 draws covers it
    rng = np.random.default_rng(3)
    covered = 0
    for _ in range(40):
        x = rng.random(400)
        _, lo, hi, _ = bootstrap_quantile(x, 0.9, 0.95, rng, resamples=300)
        covered += lo <= 0.9 <= hi
    assert covered >= 34  # 95 % of 40, less three binomial standard deviations (~4)


def test_report_of_a_folder_without_results_is_one_line(tmp_path, capsys):
    assert main(["campaign", "report", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"ltd-brake campaign: error: {tmp_path}: is not a campaign results folder "
        "(no manifest.json)")

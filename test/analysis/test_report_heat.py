"""The report of a recording reads the brake heat back: the hottest blocks and wheels, a plot."""
from __future__ import annotations

import json

import pytest

from ltd_brake_ros.cli.main import main


def test_the_report_finds_the_peaks_the_run_printed(tmp_path, capsys):
    assert main(["simulate", "--scenario", "1", "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    assert main(["simulate", "--scenario", "1", "--record", str(tmp_path / "rec")]) == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path / "rec"), "--json", "--out",
                 str(tmp_path / "plots")]) == 0
    report = json.loads(capsys.readouterr().out)
    heat = report["brake_heat"]
    # the recording samples every 0.1 s and the model moves at most a few kelvin per second
    # at the peak: the recorded peak is the printed one within 1 K, on the same vehicle
    for part in ("block", "wheel"):
        assert heat[f"peak_{part}_temperature_K"] == pytest.approx(
            run[f"peak_{part}_temperature_K"], abs=1.0)
        assert heat[f"peak_{part}_temperature_vehicle"] == \
            run[f"peak_{part}_temperature_vehicle"]
    assert heat["ambient_temperature_K"] == run["ambient_temperature_K"]
    assert heat["heat_model"] == run["heat_model"] == "not validated"
    # and judges them as the run did: the same status, the peak within 1 K on the same vehicle
    ours, theirs = ({c["criterion"]: c for c in r["verdicts"]["criteria"]}["wheel_temperature"]
                    for r in (report, run))
    assert ours["status"] == theirs["status"] == "PASS"
    assert ours["worst_K"] == pytest.approx(theirs["worst_K"], abs=1.0)
    assert ours["worst_vehicle"] == theirs["worst_vehicle"]
    assert (tmp_path / "plots" / "brake_temperature.png").stat().st_size > 10_000

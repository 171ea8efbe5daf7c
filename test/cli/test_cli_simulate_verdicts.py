"""``ltd-brake simulate``: speed at the brake command, venting vehicle and verdicts."""
from __future__ import annotations

import json

import pytest
import yaml

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.studies.runs import emergency_stop


def test_json_carries_the_verdicts_and_equals_the_emergency_stop(capsys):
    assert main(["simulate", "--scenario", "8", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    sc = get_scenario(8)
    ref = emergency_stop(sc.consist(), sc.speed_kmh)
    # the same run as emergency_stop, number for number
    for key in ("stopping_distance_m", "stop_time_s", "peak_draft_kN", "peak_buff_kN",
                "peak_draft_coupler", "peak_buff_coupler", "steps"):
        assert out[key] == getattr(ref, key), key
    assert out["brake_command_time_s"] == 0.0
    assert out["brake_command_speed_kmh"] == pytest.approx(sc.speed_kmh, rel=1e-12)
    assert out["venting_vehicle"] == 0
    v = out["verdicts"]
    assert [c["criterion"] for c in v["criteria"]] == ["draft_strength", "buff_strength",
                                                       "endurable_lcf", "adhesion"]
    draft = v["criteria"][0]
    assert draft["status"] == "PASS" and draft["worst_kN"] == pytest.approx(ref.peak_draft_kN)
    assert draft["worst_coupler"] == ref.peak_draft_coupler
    # 50 t wagons: the adhesion demand near standstill is beyond 0.15, every wagon named
    adhesion = v["criteria"][3]
    assert adhesion["status"] == "FAIL" and not v["passed"]
    assert {e["vehicle"] for e in adhesion["exceedances"]} == set(range(1, sc.consist().n))
    assert {e["vehicle"] for e in out["limits_exceeded"]} == set(range(1, sc.consist().n))


def test_text_names_the_speed_at_the_command_and_the_verdicts(capsys):
    assert main(["simulate", "--scenario", "7"]) == 0
    text = capsys.readouterr().out
    assert "brake command    emergency at t = 0.00 s, 50.00 km/h; brake pipe vented at " \
           "vehicle 0" in text
    assert "from the brake command" in text
    assert "verdicts         FAIL" in text  # 80 t wagons: 0.16 adhesion as they come to rest
    assert "PASS  Coupler draft strength: limit" in text
    assert "FAIL  Adhesion demand of the air brake" in text
    assert "... and 5 more vehicles beyond their limit" in text  # 10 wagons, 5 shown


def test_a_script_reports_the_speed_at_its_brake_command(tmp_path, capsys):
    script = tmp_path / "coast.yaml"
    script.write_text(yaml.safe_dump({"commands": [{"t_s": 0.0, "traction": 0.0},
                                                   {"t_s": 2.0, "emergency": True}]}))
    assert main(["simulate", "--scenario", "7", "--commands", str(script), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["brake_command_time_s"] == pytest.approx(2.0)
    # two seconds of coasting on level track: running resistance (Eq. 2, well below 5 N/kN at
    # 50 km/h) slows the train by less than 2 s x 0.05 m/s^2 = 0.36 km/h
    assert 50.0 - 0.36 < out["brake_command_speed_kmh"] < 50.0
    assert out["verdicts"]["criteria"][3]["status"] == "FAIL"

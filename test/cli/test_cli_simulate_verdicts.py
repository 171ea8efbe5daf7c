"""``ltd-brake simulate``: speed at the brake command, venting vehicle and verdicts."""
from __future__ import annotations

import json

import pytest
import yaml

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.studies.runs import emergency_stop


def test_json_carries_the_verdicts_and_equals_the_emergency_stop(capsys):
    assert main(["simulate", "--scenario", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    sc = get_scenario(2)
    ref = emergency_stop(sc.consist(), sc.speed_kmh)
    # the same run as emergency_stop, number for number
    for key in ("stopping_distance_m", "stop_time_s", "peak_draft_kN", "peak_buff_kN",
                "peak_draft_coupler", "peak_buff_coupler", "steps"):
        assert out[key] == getattr(ref, key), key
    assert out["brake_command_time_s"] == 0.0
    assert out["brake_command_speed_kmh"] == pytest.approx(sc.speed_kmh, rel=1e-12)
    assert out["venting_vehicle"] == 0
    v = out["verdicts"]
    assert [c["criterion"] for c in v["criteria"]] == [
        "draft_strength", "buff_strength", "endurable_lcf", "buffer_limit_state",
        "coupler_travel", "adhesion", "adhesion_demand", "standstill_holding", "runaway",
        "wheel_temperature"]
    crit = {c["criterion"]: c for c in v["criteria"]}
    draft = crit["draft_strength"]
    assert draft["status"] == "PASS" and draft["worst_kN"] == pytest.approx(ref.peak_draft_kN)
    assert draft["worst_coupler"] == ref.peak_draft_coupler
    # 50 t wagons braked alone from their 100 km/h: a mean utilised adhesion near 0.10,
    # within 0.12; their demand near standstill within a dry rail's adhesion
    adhesion = crit["adhesion"]
    assert adhesion["status"] == "PASS" and 0.09 < adhesion["worst"] < 0.12
    demand = crit["adhesion_demand"]
    assert demand["status"] == "PASS" and demand["worst"] > 0.15
    # the train settled after its stop, held, and nothing moved
    assert crit["standstill_holding"]["status"] == "PASS" and crit["runaway"]["status"] == "PASS"
    stop, = out["stops"]
    assert stop["stopping_distance_m"] == out["stopping_distance_m"]
    assert stop["settled_time_s"] == out["settled_time_s"] > stop["stop_time_s"]
    assert v["passed"] and v["status"] == "PASS" and out["non_physical"] is False
    assert all(c["scope"] and c["origin"] for c in v["criteria"])
    # one stop barely warms the wheels: far below the warning
    hot = crit["wheel_temperature"]
    assert hot["status"] == "PASS" and hot["worst_K"] < 320.0
    assert hot["worst_K"] == pytest.approx(out["peak_wheel_temperature_K"])


def test_text_names_the_speed_at_the_command_and_the_verdicts(capsys):
    assert main(["simulate", "--scenario", "7"]) == 0
    text = capsys.readouterr().out
    assert "brake command    emergency at t = 0.00 s, 50.00 km/h; brake pipe vented at " \
           "vehicle 0" in text
    assert "(the head's travel), every vehicle at rest" in text and "after the brake command" in text
    assert "verdicts         PASS" in text
    assert "PASS  Coupler draft strength (every coupler, all speeds): limit 850 kN" in text
    # the design check is the wagons' own stop from their maximum speed, whatever the run's
    assert "PASS  Mean utilised adhesion by design" in text
    assert "this run's stop from 50 km/h" in text
    assert "PASS  Adhesion demand against the rail" in text and "source: dry rail" in text


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
    assert out["verdicts"]["status"] == "PASS"

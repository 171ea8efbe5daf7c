"""The one run-spec resolver: the same rules for the command line and the node."""
import math

import pytest

from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.run_spec import RunSpecError, resolve_run_spec

CONSIST_FILE = "consists/e402b_10_shimmns_80t.yaml"


def test_scenario_brings_train_and_speed():
    spec = resolve_run_spec("scenario_7")
    sc = get_scenario(7)
    assert spec.speed_kmh == sc.speed_kmh == 50.0
    assert spec.consist.n == sc.consist().n
    assert spec.origin == "scenario 7" and spec.scenario.number == 7
    assert resolve_run_spec(None, scenario=7).speed_kmh == 50.0


def test_explicit_speed_wins_none_means_the_scenarios_and_negative_is_refused():
    assert resolve_run_spec("6", speed_kmh=80.0).speed_kmh == 80.0
    assert resolve_run_spec("6", speed_kmh=None).speed_kmh == 100.0
    assert resolve_run_spec("6", speed_kmh=0.0).speed_kmh == 0.0  # at rest: command runs
    for speed in (-1.0, -50.0):  # never the scenario's speed in its place
        with pytest.raises(RunSpecError, match="speed_kmh.*between 0 and 400 km/h"):
            resolve_run_spec("6", speed_kmh=speed)


def test_file_train_runs_at_the_scenario_speed_when_both_are_given():
    spec = resolve_run_spec(CONSIST_FILE, scenario=9)
    assert spec.speed_kmh == 50.0 and spec.origin == f"file {CONSIST_FILE}"


@pytest.mark.parametrize("kwargs,name,words", [
    (dict(consist=CONSIST_FILE), "speed_kmh", "must be given"),
    (dict(consist="6", speed_kmh=math.nan), "speed_kmh", "finite"),
    (dict(consist="6", speed_kmh=math.inf), "speed_kmh", "finite"),
    (dict(consist="6", speed_kmh=401.0), "speed_kmh", "between 0 and 400"),
    (dict(consist=""), "consist", "is empty"),
    (dict(consist="no_such_scenario"), "consist", "unknown scenario"),
    (dict(consist="6", params_file="/nonexistent/p.yaml"), "brake_params", "does not exist"),
    (dict(consist="6", lut_file="/nonexistent/c.yaml"), "coupler_lut", "does not exist"),
    (dict(consist="6", track_file="/nonexistent/t.yaml"), "track", "does not exist"),
])
def test_errors_name_the_input_and_the_reason(kwargs, name, words):
    with pytest.raises(RunSpecError) as info:
        resolve_run_spec(**kwargs)
    assert info.value.input_name == name
    assert words in str(info.value)


def test_a_file_error_keeps_file_and_field(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("t_app_s: -3\n")
    with pytest.raises(RunSpecError) as info:
        resolve_run_spec("6", params_file=str(bad))
    err = info.value
    assert err.input_name == "brake_params" and err.source == str(bad)
    assert "t_app_s" in err.detail and str(bad) in err.detail

"""Calibration reads what it may fit from the brake model (its FITTABLE), for every model."""
import pytest

from ltd_brake_ros.inputs import (BrakeParams, InputError, load_brake_params, load_coupler_lut,
                                  load_scenarios)
from ltd_brake_ros.physics import brakes
from ltd_brake_ros.physics.brakes import friction
from ltd_brake_ros.studies import calibration as cal_mod


@pytest.mark.parametrize("name", sorted(brakes.MODELS))
def test_fit_list_is_the_models_and_the_frictions(name):
    fit = cal_mod.fit_parameters(name)
    declared = {**brakes.MODELS[name].FITTABLE, **friction.FITTABLE}
    assert list(fit) == list(declared)
    for short, p in fit.items():
        assert (p.field, p.unit, p.lower, p.upper, p.scale) == declared[short][:5]
        # every fittable field is readable on the run's brake parameters
        assert getattr(BrakeParams(model=name), p.field) is not None


def test_the_paper_models_list_is_unchanged():
    assert list(cal_mod.FIT_PARAMETERS) == ["t_app", "v_air", "t_fill", "k0", "k_loco",
                                            "mu_eff"]
    # UIC 540: 90-180 m/s without acceleration chambers, 250-280 m/s with them
    v_air = cal_mod.FIT_PARAMETERS["v_air"]
    assert v_air.lower <= 90.0 and 280.0 <= v_air.upper < 340.0


def test_names_resolve_against_the_model():
    assert cal_mod.parse_fit("t_fill", "linear_ramp")[0] == \
        cal_mod.fit_parameters("linear_ramp")["t_fill"]
    with pytest.raises(InputError, match="unknown parameter 'tau'"):
        cal_mod.parse_fit("tau,k0", "linear_ramp")


def test_a_fit_of_another_model_writes_a_file_of_that_model(tmp_path):
    # synthetic distances of the toy model with t_fill = 4 s, fitted from 6 s
    truth = BrakeParams(model="linear_ramp", t_fill_s=4.0)
    sc = load_scenarios()[1]
    consist, lut, step_s = sc.consist(), load_coupler_lut(), 0.02
    with cal_mod.DistanceEvaluator([(consist, sc.speed_kmh)], lut, step_s=step_s,
                                   workers=1) as ev:
        distance = float(ev.distances([truth])[0][0])
        target = cal_mod.Target("1", consist, sc.speed_kmh, distance, "synthetic",
                                cal_mod.braked_weight_percent(consist), 1)
        start = BrakeParams(model="linear_ramp", t_fill_s=6.0, source="start")
        cal = cal_mod.calibrate([target], ["t_fill"], start, lut, step_s=step_s, evaluator=ev)
    assert cal.fit == [cal_mod.fit_parameters("linear_ramp")["t_fill"]]
    # one target, one parameter: the distance pins t_fill (to the written digits)
    assert cal.params.t_fill_s == pytest.approx(4.0, rel=1e-3)
    out = tmp_path / "fitted.yaml"
    out.write_text(cal_mod.parameter_file_text(cal, "test"))
    loaded = load_brake_params(out)
    assert loaded.model == "linear_ramp"
    assert loaded.pneumatic == cal.params.pneumatic and loaded.friction == cal.params.friction


@pytest.mark.parametrize("model", sorted(brakes.MODELS))
def test_a_written_parameter_file_reads_back_the_same_parameters(model, tmp_path):
    # every field in its file key and unit (bar, kN, ...): the file alone reproduces them
    params = BrakeParams(model=model)
    path = tmp_path / "p.yaml"
    path.write_text("\n".join(cal_mod.parameter_lines(params)) + "\n")
    back = load_brake_params(str(path))
    assert back.pneumatic == params.pneumatic and back.friction == params.friction

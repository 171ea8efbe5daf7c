"""Parameter files whose fields are each in range but together describe no brake are refused,
naming both fields."""
from __future__ import annotations

import pytest

from ltd_brake_ros.inputs import (InputError, brake_params_from_mapping, config_dir,
                                  load_brake_params)

PIPE = {"model": "uic_brake_pipe"}


@pytest.mark.parametrize("fields, first, other", [
    ({"t_fill_s": 5.0, "t_fill_G_s": 4.0}, "t_fill_G_s", "t_fill_s"),
    ({"t_release_s": 20.0, "t_release_G_s": 18.0}, "t_release_G_s", "t_release_s"),
    ({"simultaneous": True, "v_air_m_s": 250.0}, "v_air_m_s", "simultaneous"),
    (PIPE | {"running_pressure_bar": 5.0, "overcharge_bar": 0.4,
             "main_reservoir_pressure_bar": 5.2}, "main_reservoir_pressure_bar",
     "running_pressure_bar"),
    (PIPE | {"first_step_bar": 0.8, "full_service_bar": 0.6}, "first_step_bar",
     "full_service_bar"),
    (PIPE | {"release_threshold_bar": 0.3, "application_threshold_bar": 0.2},
     "release_threshold_bar", "application_threshold_bar"),
    (PIPE | {"application_threshold_bar": 0.9, "full_application_drop_bar": 0.8},
     "application_threshold_bar", "full_application_drop_bar"),
    (PIPE | {"inshot_pressure_bar": 1.9, "max_cylinder_pressure_bar": 1.5},
     "inshot_pressure_bar", "max_cylinder_pressure_bar"),
    (PIPE | {"block_force_threshold_bar": 1.0, "max_cylinder_pressure_bar": 1.0},
     "block_force_threshold_bar", "max_cylinder_pressure_bar"),
    (PIPE | {"application_stroke_bar": 0.5, "inshot_pressure_bar": 0.4},
     "application_stroke_bar", "inshot_pressure_bar"),
    # 100 L at 5 bar shared with 50 L reaches about 3.3 bar, not 3.8
    (PIPE | {"cylinder_volume_m3": 0.05}, "cylinder_volume_m3", "max_cylinder_pressure_bar"),
])
def test_a_combination_no_brake_has_is_refused_naming_both_fields(fields, first, other):
    with pytest.raises(InputError) as err:
        brake_params_from_mapping(fields, "mine.yaml")
    assert err.value.field == first and other in err.value.reason, str(err.value)


def test_the_reservoir_check_is_the_isothermal_equalisation_pressure():
    # 100 L at 5 bar gauge with 20 L at atmosphere: (0.1 * 6.013 + 0.02 * 1.013) / 0.12 bar
    # absolute = 5.18 bar, 4.17 bar gauge; 4.1 bar is reached, 4.2 bar is not
    brake_params_from_mapping(PIPE | {"max_cylinder_pressure_bar": 4.1}, "mine.yaml")
    with pytest.raises(InputError, match="reaches at most 4.17 bar"):
        brake_params_from_mapping(PIPE | {"max_cylinder_pressure_bar": 4.2}, "mine.yaml")


@pytest.mark.parametrize("name", sorted(f"brake_params/{p.name}" for p in
                                         (config_dir() / "brake_params").glob("*.yaml")))
def test_every_shipped_file_is_a_possible_brake(name):
    load_brake_params(name)


def test_the_shipped_files_include_the_first_stage_band_ends():
    shipped = {p.name for p in (config_dir() / "brake_params").glob("*.yaml")}
    assert {"paper.yaml", "uic.yaml", "uic_brake_pipe.yaml", "uic_brake_pipe_first_stage_fast.yaml",
            "uic_brake_pipe_first_stage_slow.yaml"} <= shipped


@pytest.mark.parametrize("data, field, words", [
    ({"vehicles": [{"type": "E402B"}, {"type": "Shimmns", "brake": {"type": "none"},
                                       "brake_position": "G"}]},
     "vehicles[1].brake_position", "no effect on a vehicle without a brake"),
    ({"vehicles": [{"type": "E402B"}, {"type": "Shimmns", "limits": {
        "draft_strength_kN": 500, "endurable_lcf_kN": 900}}]},
     "vehicles[1].limits.endurable_lcf_kN", "exceeds the draft strength (500 kN)"),
    ({"limits": {"endurable_lcf_kN": 900}, "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "limits": {"draft_strength_kN": 500}}]},
     "vehicles[1].limits.draft_strength_kN", "endurable fatigue load (900 kN)"),
])
def test_a_consist_combination_that_cannot_be_is_refused(data, field, words):
    from ltd_brake_ros.inputs import consist_from_mapping

    with pytest.raises(InputError) as err:
        consist_from_mapping(data, "train.yaml")
    assert err.value.field == field and words in err.value.reason, str(err.value)

"""Input files: the shipped ones load, bad ones fail with file, field and reason."""
import subprocess
import sys

import pytest
import yaml

from ltd_brake_ros.inputs import (BlockBrake, DiscBrake, InputError, load_brake_params,
                                  load_consist, load_coupler_lut, load_scenarios)


def write(tmp_path, name, doc):
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else yaml.safe_dump(doc))
    return p


def train(**wagon_overrides):
    wagon = {"type": "Shimmns", "count": 3}
    wagon.update(wagon_overrides)
    return {"name": "t", "vehicles": [{"type": "E402B"}, wagon]}


def test_shipped_files_load():
    scenarios = load_scenarios()
    assert sorted(scenarios) == list(range(1, 13))
    c = scenarios[6].consist()
    assert c.n == 33 and c.length_m == pytest.approx(19.42 + 32 * 12.64)
    assert isinstance(c.vehicles[0].brake, DiscBrake)
    wagon = c.vehicles[1]
    assert isinstance(wagon.brake, BlockBrake)
    assert wagon.mass_kg == 50e3 and wagon.braked_weight_t == 58.55  # loaded above 48 t
    p = load_brake_params()
    assert (p.t_app_s, p.v_air_m_s, p.t_fill_s, p.k_loco, p.mu_eff) == (1.0, 200.0, 5.0, 3.54, 0.264)
    lut = load_coupler_lut()
    assert lut.v_th_m_s == pytest.approx(1e-4)


def test_empty_loaded_device_switches_at_changeover(tmp_path):
    light = load_consist(write(tmp_path, "a.yaml", train(mass_t=30.0)))
    assert light.vehicles[1].braked_weight_t == 23.0
    heavy = load_consist(write(tmp_path, "b.yaml", train(mass_t=48.0)))
    assert heavy.vehicles[1].braked_weight_t == 58.55


@pytest.mark.parametrize("override,field,words", [
    ({"mass_t": -5.0}, "vehicles[1].mass_t", "must be >"),
    ({"mass_t": float("nan")}, "vehicles[1].mass_t", "finite"),
    ({"mass_t": "heavy"}, "vehicles[1].mass_t", "must be a number"),
    ({"length_m": 0}, "vehicles[1].length_m", "must be >"),
    ({"axles": 2.5}, "vehicles[1].axles", "whole number"),
    ({"brake": {"type": "magnetic"}}, "vehicles[1].brake.type", "unknown value 'magnetic'"),
    ({"brake": {"type": "blocks", "blocks": 8}}, "vehicles[1].brake.braked_weight_t", "missing"),
    ({"brake": {"type": "disc", "braked_weight_t": 500.0}}, "vehicles[1].brake.braked_weight_t",
     "more than twice"),
    ({"type": "Habbins"}, "vehicles[1].type", "unknown vehicle type"),
    ({"colour": "red"}, "vehicles[1].colour", "unknown field"),
])
def test_bad_consist_names_file_vehicle_and_field(tmp_path, override, field, words):
    p = write(tmp_path, "bad.yaml", train(**override))
    with pytest.raises(InputError) as err:
        load_consist(p)
    msg = str(err.value)
    assert str(p) in msg and field in msg and words in msg


def test_missing_field_in_inline_vehicle(tmp_path):
    doc = {"vehicles": [{"length_m": 12.0, "axles": 4, "brake": {"type": "none"}}]}
    with pytest.raises(InputError, match=r"vehicles\[0\]\.mass_t: missing"):
        load_consist(write(tmp_path, "c.yaml", doc))


@pytest.mark.parametrize("doc,words", [
    ("vehicles: [", "not valid YAML"),
    ("- 1\n- 2\n", "must be a mapping"),
    ({"vehicles": []}, "vehicles: is empty"),
    ({"vehicles": "E402B"}, "not a list"),
    ({"name": "x"}, "vehicles: missing"),
])
def test_malformed_consist_files(tmp_path, doc, words):
    with pytest.raises(InputError, match=words):
        load_consist(write(tmp_path, "m.yaml", doc))


def test_missing_file_is_named(tmp_path):
    with pytest.raises(InputError, match="does not exist") as err:
        load_consist(tmp_path / "absent.yaml")
    assert "absent.yaml" in str(err.value)


@pytest.mark.parametrize("change,field,words", [
    ({"loading_kN": [-6500, -2000, -960, -640, -400, -240, -140, -50, 0, 30, 80, 150, 250, 200, 2850]},
     "loading_kN[13]", "must not decrease"),
    ({"deflection_mm": [-300, -210, -190, -170, -140, -100, -60, -20, 0, 20, 50, 50, 100, 110, 150]},
     "deflection_mm[11]", "strictly increasing"),
    ({"unloading_kN": [0, 1]}, "unloading_kN", "has 2 values"),
    ({"v_th_mm_s": -1}, "v_th_mm_s", "must be >"),
    ({"deflection_mm": [0], "loading_kN": [0], "unloading_kN": [0]}, "deflection_mm", "at least 2"),
])
def test_bad_lut(tmp_path, change, field, words):
    doc = yaml.safe_load(open(load_coupler_lut().source))
    doc.update(change)
    p = write(tmp_path, "lut.yaml", doc)
    with pytest.raises(InputError) as err:
        load_coupler_lut(p)
    assert str(p) in str(err.value) and field in str(err.value) and words in str(err.value)


@pytest.mark.parametrize("doc,field", [({"t_fill_s": 0}, "t_fill_s"), ({"v_air_m_s": "fast"}, "v_air_m_s"),
                                       ({"k0": float("inf")}, "k0"), ({"tapp": 1}, "tapp")])
def test_bad_brake_params(tmp_path, doc, field):
    with pytest.raises(InputError, match=field):
        load_brake_params(write(tmp_path, "p.yaml", doc))


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "ltd_brake_ros.cli", *args],
                          capture_output=True, text=True, timeout=120)


def test_cli_reports_bad_input_without_traceback(tmp_path):
    p = write(tmp_path, "bad.yaml", train(mass_t=-1.0))
    r = run_cli("simulate", "--consist", str(p))
    assert r.returncode == 2
    assert "vehicles[1].mass_t" in r.stderr and str(p) in r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    r = run_cli("simulate", "--scenario", "13")
    assert r.returncode == 2 and "unknown scenario" in r.stderr and "Traceback" not in r.stderr


def test_cli_simulate_json_has_units_in_keys():
    import json

    r = run_cli("simulate", "--scenario", "7", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("stopping_distance_m", "stop_time_s", "peak_draft_kN", "peak_buff_kN",
                "braked_weight_percent", "real_time_factor"):
        assert key in out
    assert out["peak_draft_coupler"] >= 1 and out["peak_buff_kN"] < 0

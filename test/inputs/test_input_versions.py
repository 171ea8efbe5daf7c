"""Input files are read once per version: an edited file is read anew at once, even when the
edit keeps its size and modification time (two writes within one tick of the file system's
clock)."""
import os
import shutil

import pytest

from ltd_brake_ros.inputs import (config_dir, get_scenario, load_brake_params, load_consist,
                                  load_coupler_lut, load_scenarios)


def rewrite(path, old: str, new: str) -> None:
    """Replace ``old`` by ``new`` (same length) keeping the file's size and times."""
    assert len(old) == len(new)
    st = os.stat(path)
    text = path.read_text()
    assert text.count(old) == 1
    path.write_text(text.replace(old, new))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert os.stat(path).st_mtime_ns == st.st_mtime_ns and os.stat(path).st_size == st.st_size


@pytest.fixture
def config(tmp_path, monkeypatch):
    """A copy of the shipped config directory, the one the loaders use."""
    copy = tmp_path / "config"
    shutil.copytree(config_dir(), copy)
    monkeypatch.setenv("LTD_BRAKE_CONFIG", str(copy))
    assert config_dir() == copy
    return copy


def test_an_edited_consist_file_is_read_anew(config):
    path = config / "consists" / "e402b_32_shimmns_50t.yaml"
    first = load_consist(path)
    assert load_consist(path) is first  # unchanged: the consist built before
    rewrite(path, "mass_t: 50.0", "mass_t: 60.0")
    again = load_consist(path)
    assert first.vehicles[1].mass_kg == 50e3 and again.vehicles[1].mass_kg == 60e3
    rewrite(path, "count: 32", "count: 31")
    assert load_consist(path).n == 32


def test_an_edited_vehicle_library_changes_the_consists_built_from_it(config):
    path = config / "consists" / "e402b_32_shimmns_50t.yaml"
    first = load_consist(path)
    rewrite(config / "vehicles.yaml", "mass_t: 89.0", "mass_t: 88.0")  # the E402B
    assert first.vehicles[0].mass_kg == 89e3
    assert load_consist(path).vehicles[0].mass_kg == 88e3


def test_edited_model_files_and_catalogue_are_read_anew(config):
    params = config / "brake_params" / "paper.yaml"
    assert load_brake_params(params).friction.k0 == 2.72
    rewrite(params, "k0: 2.72", "k0: 2.62")
    assert load_brake_params(params).friction.k0 == 2.62
    # the defaults are the copied files
    assert load_brake_params().friction.k0 == 2.62

    lut = config / "couplers" / "buffer_hook_pugi.yaml"
    assert load_coupler_lut(lut).v_th_m_s == pytest.approx(0.1e-3)
    rewrite(lut, "v_th_mm_s: 0.1 ", "v_th_mm_s: 0.2 ")
    assert load_coupler_lut(lut).v_th_m_s == pytest.approx(0.2e-3)

    catalogue = config / "scenarios.yaml"
    assert get_scenario(6).speed_kmh == 100.0
    rewrite(catalogue, "e402b_32_shimmns_50t.yaml, speed_kmh: 100,",
            "e402b_32_shimmns_50t.yaml, speed_kmh: 090,")
    assert get_scenario(6).speed_kmh == load_scenarios()[6].speed_kmh == 90.0


def test_a_scenario_is_a_copy(config):
    sc = get_scenario(6)
    sc.paper["uic_m"] = -1.0
    assert get_scenario(6).paper["uic_m"] == load_scenarios()[6].paper["uic_m"] == 492.5


def test_a_simulator_of_an_edited_file_runs_the_edited_train(config):
    from ltd_brake_ros.simulator import Commands, Simulator

    path = config / "consists" / "e402b_32_shimmns_50t.yaml"
    params = load_brake_params()

    def stop(consist):
        sim = Simulator(consist, 100.0, params)
        sim.advance(5.0, Commands(emergency=True))
        return sim

    first, same = stop(load_consist(path)), stop(load_consist(path))
    assert same.model is first.model  # the same files: the train compiled before
    assert same.snapshot().speed_m_s.tolist() == first.snapshot().speed_m_s.tolist()
    rewrite(path, "mass_t: 50.0", "mass_t: 80.0")
    heavier = stop(load_consist(path))
    assert heavier.model is not first.model
    assert heavier.mass_kg[1] == 80e3
    # loaded wagons brake a lower share of their weight (lambda_train about 74 % against
    # 116 %, Tables 1-2): less speed lost after 5 s
    assert heavier.snapshot().speed_m_s[1] > first.snapshot().speed_m_s[1]


def test_a_kept_file_is_read_again_once_replaced(tmp_path, monkeypatch):
    from ltd_brake_ros.inputs import schema

    # every file counts as settled (a file changed more than a few seconds before it is read
    # is kept; one changed since keeps its signature only within a time-stamp tick)
    monkeypatch.setattr(schema, "_SETTLED_NS", -1)
    path = tmp_path / "train.yaml"
    path.write_text("name: a\n")
    first = schema.read_input(path)
    assert schema.read_input(path) is first  # kept: not read again
    # an editor's save: a new file renamed over the old one, same size and times
    st = os.stat(path)
    new = tmp_path / "train.yaml.new"
    new.write_text("name: b\n")
    os.utime(new, ns=(st.st_atime_ns, st.st_mtime_ns))
    os.replace(new, path)
    assert schema.read_input(path) == b"name: b\n"

"""Input files mean what a person reads in them, and the loader is bounded.

YAML 1.1 (PyYAML's default) reads ``050`` as 40 (octal), ``1:20`` as 80 (base 60) and ``yes`` as
true, and lets a second ``vehicles:`` silently replace the first. The loader reads numbers as
decimal, only ``true``/``false`` as booleans, refuses duplicate keys, and refuses documents that
nest too deep or expand (through aliases) beyond a fixed number of values, in well under a
second and with one line naming the file.
"""
import time

import pytest

from ltd_brake_ros.inputs import (InputError, load_command_script, load_consist,
                                  load_coupler_lut, load_scenarios, load_track, load_yaml)
from ltd_brake_ros.inputs import schema


def write(tmp_path, text, name="input.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def error_of(loader, path):
    with pytest.raises(InputError) as err:
        loader(path)
    msg = str(err.value)
    assert str(path) in msg and "\n" not in msg
    return msg


# ----------------------------------------------------------------------------- numbers


def test_leading_zeros_are_decimal(tmp_path):
    p = write(tmp_path, "name: zeros\nvehicles:\n  - {type: E402B}\n"
                        "  - {type: Shimmns, count: 010, mass_t: 050}\n")
    consist = load_consist(p)
    assert consist.n == 11                        # 1 + 10, not 1 + 8
    assert consist.vehicles[1].mass_kg == 50e3    # not 40 t


@pytest.mark.parametrize("text", ["1:20", "1_000", "0x10", "0o10", "0b10", "12 t"])
def test_other_number_spellings_are_refused_with_the_field(tmp_path, text):
    # YAML 1.1 read the first five as 80, 1000, 16, 8, 2; here they are text, and text is
    # not a number
    p = write(tmp_path, f"sections:\n  - {{from_m: 0, gradient_permille: {text}}}\n")
    msg = error_of(load_track, p)
    assert "sections[0].gradient_permille: must be a number, got text" in msg
    assert "plain decimal number" in msg


@pytest.mark.parametrize("text", ["1:20", "1_000", "0x10", "nan"])
def test_csv_track_reads_numbers_as_the_yaml_files_do(tmp_path, text):
    # Python's float() reads 1_000 and nan; the cells follow the YAML files' reading
    p = write(tmp_path, f"chainage_m,gradient_permille\n0,1.5e1\n500,{text}\n", "track.csv")
    assert f"row 3.gradient_permille: must be a number, got text '{text}'" in \
        error_of(load_track, p)
    p.write_text("chainage_m,gradient_permille\n0,1.5e1\n500, -2 \n")
    assert load_track(p).gradient_permille == (15.0, -2.0)


def test_exponents_without_a_point_or_sign_are_numbers(tmp_path):
    # YAML 1.1 reads 2.85e3 and 1e3 as text
    p = write(tmp_path, "deflection_mm: [-300, 0, 1.5e2]\nloading_kN: [-6.5e3, 0, 2850]\n"
                        "unloading_kN: [-6500, 0, 2.85E+3]\n")
    lut = load_coupler_lut(p)
    assert lut.deflection_m == (-0.3, 0.0, 0.15)
    assert lut.loading_N == (-6.5e6, 0.0, 2.85e6) == lut.unloading_N


def test_special_floats_still_reach_the_field_check(tmp_path):
    p = write(tmp_path, "name: x\nvehicles:\n  - {type: Shimmns, mass_t: .nan}\n")
    assert "vehicles[0].mass_t: must be finite" in error_of(load_consist, p)


# ----------------------------------------------------------------------------- booleans


def test_only_true_and_false_are_booleans(tmp_path):
    p = write(tmp_path, "commands:\n  - {t_s: 0, emergency: yes}\n")
    msg = error_of(load_command_script, p)
    assert "commands[0].emergency: must be true or false, got text 'yes'" in msg
    p = write(tmp_path, "commands:\n  - {t_s: 0, emergency: true}\n  - {t_s: 1, emergency: False}\n")
    assert [s[1]["emergency"] for s in load_command_script(p).steps] == [True, False]


@pytest.mark.parametrize("word", ["on", "off", "yes", "no", "Y"])
def test_yes_no_on_off_where_a_number_is_expected(tmp_path, word):
    p = write(tmp_path, f"name: x\nvehicles:\n  - {{type: Shimmns, mass_t: {word}}}\n")
    assert f"vehicles[0].mass_t: must be a number, got text '{word}'" in error_of(load_consist, p)


@pytest.mark.parametrize("word", ["NO", "off", "2024-01-01"])
def test_text_stays_the_text_written(tmp_path, word):
    # a consist named after Norway, not False; a date is a name, not a timestamp
    p = write(tmp_path, f"name: {word}\nvehicles:\n  - {{type: E402B}}\n")
    assert load_consist(p).name == word


def test_a_name_must_be_text(tmp_path):
    p = write(tmp_path, "name: [a, b]\nvehicles:\n  - {type: E402B}\n")
    assert "name: must be text, got a list" in error_of(load_consist, p)


# ----------------------------------------------------------------------------- duplicate keys


def test_a_second_vehicles_list_is_refused(tmp_path):
    p = write(tmp_path, "name: dup\nvehicles:\n  - {type: E402B}\n  - {type: Shimmns, count: 3}\n"
                        "vehicles:\n  - {type: E402B}\n")
    msg = error_of(load_consist, p)
    assert msg.endswith("vehicles: given twice (line 2 and line 5); a key may appear once")


def test_duplicate_key_deep_inside_names_its_path(tmp_path):
    p = write(tmp_path, "name: dup\nvehicles:\n  - type: Shimmns\n    brake:\n"
                        "      type: blocks\n      blocks: 8\n      braked_weight_t: 58\n"
                        "      blocks: 16\n")
    assert "vehicles[0].brake.blocks: given twice (line 6 and line 8)" in error_of(load_consist, p)


def test_duplicate_in_one_flow_mapping(tmp_path):
    p = write(tmp_path, "name: dup\nvehicles:\n  - {type: Shimmns, count: 3, count: 4}\n")
    assert "vehicles[0].count: given twice on line 3" in error_of(load_consist, p)


def test_keys_equal_as_numbers_are_duplicates(tmp_path):
    p = write(tmp_path, "scenarios:\n  6: {consist: a.yaml, speed_kmh: 100}\n"
                        "  06: {consist: b.yaml, speed_kmh: 50}\n")
    assert "scenarios.06: given twice (line 2 and line 3)" in error_of(load_yaml, p)


# ----------------------------------------------------------------------------- bounds


def billion_laughs(levels=10, width=10):
    lines = ["description:", f"  - &l0 [{', '.join(['lol'] * width)}]"]
    for i in range(1, levels):
        lines.append(f"  - &l{i} [{', '.join([f'*l{i - 1}'] * width)}]")
    return "\n".join(lines) + f"\nname: *l{levels - 1}\nvehicles:\n  - {{type: E402B}}\n"


def test_alias_bomb_is_refused_fast(tmp_path):
    p = write(tmp_path, billion_laughs())          # 10^10 values from 1 kB
    start = time.perf_counter()
    msg = error_of(load_consist, p)
    assert time.perf_counter() - start < 1.0
    assert f"more than {schema.MAX_NODES} values" in msg and "alias" in msg


def test_modest_aliases_are_fine(tmp_path):
    p = write(tmp_path, "vehicle_types:\n  Heavy: &brake {type: blocks, blocks: 8, "
                        "braked_weight_t: 58.55}\nname: shared\nvehicles:\n"
                        "  - {type: Shimmns, mass_t: 80, brake: *brake}\n"
                        "  - {type: Shimmns, mass_t: 70, brake: *brake}\n")
    assert [v.brake.blocks for v in load_consist(p).vehicles] == [8, 8]


def test_self_referencing_alias_is_refused(tmp_path):
    p = write(tmp_path, "name: &a [*a]\nvehicles:\n  - {type: E402B}\n")
    assert "refers to a list or mapping that contains it" in error_of(load_consist, p)


def test_deep_nesting_is_refused(tmp_path):
    depth = 5000                                   # a RecursionError traceback before
    p = write(tmp_path, "name: " + "[" * depth + "]" * depth + "\n")
    msg = error_of(load_consist, p)
    assert f"name: nested deeper than {schema.MAX_DEPTH} levels (line 1)" in msg


def test_oversized_file_is_refused_before_parsing(tmp_path):
    p = tmp_path / "huge.yaml"
    with open(p, "wb") as fh:
        fh.truncate(schema.MAX_FILE_BYTES + 1)     # sparse: costs no disk
    start = time.perf_counter()
    msg = error_of(load_consist, p)
    assert time.perf_counter() - start < 1.0
    assert "input files are limited to" in msg


def test_node_count_without_aliases_is_bounded(tmp_path, monkeypatch):
    monkeypatch.setattr(schema, "MAX_NODES", 1000)  # the real bound takes 5 s to reach
    # the root mapping, two keys, "x", the list and its n numbers: 5 + n values
    p = write(tmp_path, "name: x\ndescription: [" + "0, " * 995 + "]\n")
    assert len(load_yaml(p)["description"]) == 995
    p = write(tmp_path, "name: x\ndescription: [" + "0, " * 996 + "]\n")
    assert "holds more than 1000 values" in error_of(load_consist, p)
    p = write(tmp_path, "name: x\ndescription: [" + "0, " * 1000 + "]\n")
    assert "description: holds more than 1000 values" in error_of(load_consist, p)


@pytest.mark.parametrize("text,words", [
    ("mass_t: !!int 0x10", "decimal whole number"),
    ("mass_t: !!float 1:20", "decimal number"),
    ("when: !!timestamp 2024-13-99", "could not determine a constructor"),
    ("blob: !!binary AAAA", "could not determine a constructor"),
    ("mass_t: !!python/object:os.system ls", "could not determine a constructor"),
])
def test_explicit_tags_outside_the_core_schema(tmp_path, text, words):
    assert words in error_of(load_yaml, write(tmp_path, text + "\n"))


@pytest.mark.parametrize("key,words", [
    ("06", None),
    ("six", "scenarios.six: must be a scenario number"),
    ("true", "scenarios.True: must be a scenario number"),
])
def test_scenario_numbers_are_decimal_whole_numbers(tmp_path, monkeypatch, key, words):
    write(tmp_path, f"scenarios:\n  {key}: {{consist: a.yaml, speed_kmh: 100}}\n", "scenarios.yaml")
    monkeypatch.setenv("LTD_BRAKE_CONFIG", str(tmp_path))
    if words is None:
        assert list(load_scenarios()) == [6]
    else:
        assert words in error_of(lambda _p: load_scenarios(), tmp_path / "scenarios.yaml")

"""Names, descriptions and keys of every input are bounded printable text, refused in one line
naming the field otherwise; the characters markup uses are ordinary text."""
from __future__ import annotations

import copy
import subprocess
from pathlib import Path

import pytest
import yaml

from conftest import executable
from ltd_brake_ros.inputs import (InputError, brake_params_from_mapping, config_dir,
                                  consist_from_mapping, load_brake_params,
                                  load_command_script, load_consist, load_coupler_lut,
                                  load_track)
from ltd_brake_ros.inputs.campaign import campaign_from_mapping, load_campaign
from ltd_brake_ros.inputs.schema import TEXT_MAX_CHARS, check_texts

CONSIST = {"name": "train", "vehicles": [{"type": "E402B"},
                                         {"type": "Shimmns", "count": 3, "mass_t": 80.0}]}
CAMPAIGN = yaml.safe_load((config_dir() / "campaigns" / "example.yaml").read_text())

#: Characters no name may hold: line breaks, escapes, NUL, a bidirectional override, a
#: zero-width space, a line separator, a byte-order mark inside text.
HOSTILE = ["\n", "\r", "\t", "\x00", "\x1b[31m", "\u202e", "\u200b", "\u2028", "\ufeff"]


def _refused(build, field: str) -> str:
    with pytest.raises(InputError) as info:
        build()
    text = str(info.value)
    assert "\n" not in text and "\r" not in text and "\x1b" not in text, repr(text)
    assert field in text, (field, text)
    return text


@pytest.mark.parametrize("bad", HOSTILE)
def test_a_consist_name_with_a_control_character_is_refused(bad):
    doc = dict(CONSIST, name=f"train{bad}1")
    text = _refused(lambda: consist_from_mapping(doc, "c.yaml"), "c.yaml: name")
    assert "U+" in text and "character 6" in text


@pytest.mark.parametrize("where, field", [
    (("vehicles", 1, "description"), "vehicles[1].description"),
    (("vehicles", 0, "type"), "vehicles[0].type"),
    (("description",), "description"),
])
def test_every_free_text_field_of_a_consist_is_checked(where, field):
    doc = copy.deepcopy(CONSIST)
    target = doc
    for key in where[:-1]:
        target = target[key]
    target[where[-1]] = "x\u202egnp.exe"
    _refused(lambda: consist_from_mapping(doc, "c.yaml"), field)


def test_a_vehicle_type_name_is_a_key_and_checked_as_one():
    doc = copy.deepcopy(CONSIST)
    doc["vehicle_types"] = {"Shimmns\n": {"mass_t": 80.0}}
    text = _refused(lambda: consist_from_mapping(doc, "c.yaml"), "vehicle_types")
    assert "'Shimmns\\n'" in text  # shown escaped


def test_names_are_at_most_200_characters_and_exactly_200_are_fine():
    long = "W" * (TEXT_MAX_CHARS + 1)
    text = _refused(lambda: consist_from_mapping(dict(CONSIST, name=long), "c.yaml"), "name")
    assert f"{TEXT_MAX_CHARS + 1} characters long; at most {TEXT_MAX_CHARS}" in text
    assert consist_from_mapping(dict(CONSIST, name="W" * TEXT_MAX_CHARS), "c.yaml").name == \
        "W" * TEXT_MAX_CHARS


def test_a_huge_name_is_refused_before_it_is_read_character_by_character():
    with pytest.raises(InputError, match="5000000 characters long"):
        consist_from_mapping(dict(CONSIST, name="x" * 5_000_000), "c.yaml")


@pytest.mark.parametrize("name", ["<b>bold</b> & 'quoted' \"train\"", "$\\alpha$ {braces}",
                                  "Güterzug Nürnberg–München", "货运列车 № 7", "train 🚂",
                                  "a\u00a0b (no-break space)"])
def test_the_characters_markup_uses_and_any_script_are_names(name):
    assert consist_from_mapping(dict(CONSIST, name=name), "c.yaml").name == name


def test_campaign_manoeuvre_family_and_campaign_names_are_checked():
    for where, field in [(("name",), "name"),
                         (("manoeuvres", 0, "name"), "manoeuvres[0].name"),
                         (("families", 0, "name"), "families[0].name")]:
        doc = copy.deepcopy(CAMPAIGN)
        target = doc
        for key in where[:-1]:
            target = target[key]
        target[where[-1]] = "run\x07"
        _refused(lambda doc=doc: campaign_from_mapping(doc, "camp.yaml"), field)


def test_brake_parameters_check_their_name_and_description():
    _refused(lambda: brake_params_from_mapping({"description": "a\nb"}, "p.yaml"),
             "p.yaml: description")


@pytest.mark.parametrize("loader, name", [
    (load_coupler_lut, "couplers/buffer_hook_pugi.yaml"),
    (load_brake_params, "brake_params/paper.yaml"),
    (load_track, "tracks/hump_10permille.yaml"),
    (load_command_script, "commands/service_then_emergency.yaml"),
])
def test_a_file_with_a_control_character_in_a_text_is_refused(tmp_path, loader, name):
    doc = yaml.safe_load((config_dir() / name).read_text())
    doc["description"] = "made by\x1b]0;pwned\x07 a tool"
    path = tmp_path / Path(name).name
    path.write_text(yaml.safe_dump(doc))
    assert "U+001B" in _refused(lambda: loader(path), "description")


def test_every_shipped_file_is_bounded_printable_text():
    files = sorted(config_dir().rglob("*.yaml"))
    assert len(files) > 20
    for path in files:
        check_texts(yaml.safe_load(path.read_text()), str(path))
    load_campaign(config_dir() / "campaigns" / "example.yaml")
    load_consist("consists/mixed_heavy_front_light_rear.yaml")


def test_the_command_line_says_it_in_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(dict(CONSIST, name="ok\u202eko")))
    out = subprocess.run([executable("ltd-brake"), "simulate", "--consist", str(bad), "--json"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.count("\n") == 1 and "name" in out.stderr and "U+202E" in out.stderr

"""Property-based fuzzing of the YAML loaders: every bad file ends in one clear InputError.

Each generated document is a valid file with one field broken (removed, wrong type, NaN/inf,
negative, out of range); the error must name the file and the broken field. A few cases go
through the command line to check the exit status, the silence on stdout and the absence of a
traceback.
"""
import copy
import math
import subprocess
import sys

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ltd_brake_ros.inputs import (InputError, load_brake_params, load_consist, load_coupler_lut,
                                  resolve_config_path)

VALID_CONSIST = {
    "name": "fuzz",
    "vehicles": [
        {"mass_t": 89.0, "length_m": 19.42, "axles": 4, "inertia_factor": 1.15,
         "brake": {"type": "disc", "braked_weight_t": 79.0}},
        {"mass_t": 80.0, "length_m": 12.64, "axles": 4, "inertia_factor": 1.04, "count": 3,
         "brake": {"type": "blocks", "blocks": 8, "arrangement": "Bg",
                   "braked_weight_t": 58.55}},
    ],
}
VALID_LUT = yaml.safe_load(open(resolve_config_path("couplers/buffer_hook_pugi.yaml")))
VALID_PARAMS = yaml.safe_load(open(resolve_config_path("brake_params/paper.yaml")))

# (path into the document, label the error must contain)
CONSIST_FIELDS = [
    (("vehicles", 0, "mass_t"), "vehicles[0].mass_t"),
    (("vehicles", 1, "mass_t"), "vehicles[1].mass_t"),
    (("vehicles", 1, "length_m"), "vehicles[1].length_m"),
    (("vehicles", 1, "axles"), "vehicles[1].axles"),
    (("vehicles", 0, "brake", "braked_weight_t"), "vehicles[0].brake.braked_weight_t"),
    (("vehicles", 1, "brake", "blocks"), "vehicles[1].brake.blocks"),
    (("vehicles", 1, "brake", "braked_weight_t"), "vehicles[1].brake.braked_weight_t"),
]
BAD_NUMBERS = [float("nan"), float("inf"), -float("inf"), -1.0, 0.0, "12 t", [1, 2], {"a": 1},
               True, None]


def _set(doc, path, value):
    node = doc
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


_DELETE = object()


def _bad_for(path, value):
    """Whether ``value`` at ``path`` must be rejected (a few values are legal for some fields)."""
    if value is _DELETE or value is None:
        return path[-1] != "inertia_factor"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return True
    if not math.isfinite(value) or value <= 0:
        return True
    return False


def _write(tmp_path_factory, doc):
    p = tmp_path_factory.mktemp("fuzz") / "input.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(CONSIST_FIELDS), value=st.sampled_from(BAD_NUMBERS + [_DELETE]))
def test_consist_field_broken(tmp_path_factory, field, value):
    path, label = field
    doc = copy.deepcopy(VALID_CONSIST)
    _set(doc, path, value)
    p = _write(tmp_path_factory, doc)
    if not _bad_for(path, value):
        load_consist(p)
        return
    with pytest.raises(InputError) as err:
        load_consist(p)
    assert str(p) in str(err.value)
    assert label in str(err.value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(ratio=st.floats(min_value=2.0001, max_value=50.0))
def test_braked_weight_above_twice_the_mass(tmp_path_factory, ratio):
    doc = copy.deepcopy(VALID_CONSIST)
    doc["vehicles"][1]["brake"]["braked_weight_t"] = 80.0 * ratio
    p = _write(tmp_path_factory, doc)
    with pytest.raises(InputError, match=r"vehicles\[1\]\.brake\.braked_weight_t: .*twice"):
        load_consist(p)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.text(min_size=1, max_size=12).filter(lambda s: s not in ("blocks", "disc", "none")))
def test_unknown_brake_type(tmp_path_factory, kind):
    doc = copy.deepcopy(VALID_CONSIST)
    doc["vehicles"][0]["brake"]["type"] = kind
    p = _write(tmp_path_factory, doc)
    with pytest.raises(InputError, match=r"vehicles\[0\]\.brake\.type"):
        load_consist(p)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_lut_broken(tmp_path_factory, data):
    doc = copy.deepcopy(VALID_LUT)
    column = data.draw(st.sampled_from(["deflection_mm", "loading_kN", "unloading_kN"]))
    n = len(doc[column])
    how = data.draw(st.sampled_from(["swap", "nan", "short", "text", "drop"]))
    if how == "swap":
        i = data.draw(st.integers(0, n - 2))
        if doc[column][i] == doc[column][i + 1]:
            return
        doc[column][i], doc[column][i + 1] = doc[column][i + 1], doc[column][i]
    elif how == "nan":
        doc[column][data.draw(st.integers(0, n - 1))] = float("nan")
    elif how == "short":
        doc[column] = doc[column][: data.draw(st.integers(0, n - 1))]
    elif how == "text":
        doc[column][data.draw(st.integers(0, n - 1))] = "x"
    else:
        del doc[column]
    p = _write(tmp_path_factory, doc)
    with pytest.raises(InputError) as err:
        load_coupler_lut(p)
    msg = str(err.value)
    assert str(p) in msg
    assert column in msg or ("deflection_mm" in msg and how == "short")


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(sorted(set(VALID_PARAMS) - {"name", "description"})),
       value=st.sampled_from(BAD_NUMBERS))
def test_brake_params_broken(tmp_path_factory, field, value):
    doc = copy.deepcopy(VALID_PARAMS)
    doc[field] = value
    p = _write(tmp_path_factory, doc)
    if value is None or (field == "t_app_s" and value == 0.0):
        load_brake_params(p)  # None = default; t_app may be zero
        return
    with pytest.raises(InputError, match=field):
        load_brake_params(p)


@pytest.mark.parametrize("text,words", [
    ("{{{{", "not valid YAML"),
    ("", "is empty"),
    ("42", "must be a mapping"),
    ("vehicles: []", "empty"),
    ("vehicles:\n  - {type: Shimmns, count: 10000, mass_t: 80}", r"count: must be between 1 and 5000"),
    ("vehicles:\n" + "  - {type: Shimmns, count: 4000, mass_t: 80}\n" * 3, "exceed 5000 vehicles"),
])
def test_structurally_bad_consists(tmp_path, text, words):
    p = tmp_path / "c.yaml"
    p.write_text(text)
    with pytest.raises(InputError, match=words):
        load_consist(p)


def test_binary_file_is_not_yaml(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_bytes(bytes(range(256)))
    with pytest.raises(InputError, match="is a binary file, not text"):
        load_consist(p)


@pytest.mark.parametrize("args,label", [
    (["--consist", "{bad}"], "vehicles[1].mass_t"),
    (["--scenario", "6", "--lut", "{bad}"], "loading_kN[13]"),
    (["--scenario", "6", "--params", "{bad}"], "t_fill_s"),
    (["--consist", "{missing}"], "does not exist"),
])
def test_cli_bad_files_exit_cleanly(tmp_path, args, label):
    consist = copy.deepcopy(VALID_CONSIST)
    consist["vehicles"][1]["mass_t"] = float("nan")
    lut = copy.deepcopy(VALID_LUT)
    lut["loading_kN"][13] = 0.0
    files = {"consist": consist, "lut": lut, "params": dict(VALID_PARAMS, t_fill_s=-5)}
    kind = "consist" if "--consist" in args and "{bad}" in args else (
        "lut" if "--lut" in args else "params")
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(files[kind]))
    argv = [a.replace("{bad}", str(bad)).replace("{missing}", str(tmp_path / "no.yaml"))
            for a in args]
    r = subprocess.run([sys.executable, "-m", "ltd_brake_ros.cli", "simulate", *argv],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert label in r.stderr
    assert "Traceback" not in r.stderr
    assert r.stdout == ""  # no partial output
    assert len(r.stderr.strip().splitlines()) == 1  # one clear message


YAML_ALPHABET = "[]{}:,&*!|>-?'\"#%@`~.\n\t 0123456789abexyz_+"


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(alphabet=YAML_ALPHABET, max_size=200) | st.binary(max_size=200))
def test_any_text_is_a_document_or_one_input_error(tmp_path_factory, text):
    from ltd_brake_ros.inputs import load_yaml

    p = tmp_path_factory.mktemp("fuzz") / "any.yaml"
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    try:
        load_yaml(p)
    except InputError as exc:
        assert str(exc).startswith(str(p)) and "\n" not in str(exc)

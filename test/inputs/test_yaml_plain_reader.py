"""libyaml's composer reads plain documents; anything else is read (or refused) as always.

:func:`~ltd_brake_ros.inputs.schema.load_yaml` lets libyaml compose a document that is a plain
tree within the bounds, and gives everything else (aliases to lists or mappings, duplicate keys,
deep nesting, tags outside the core schema, bad YAML) to the exact Python reader. The data and
every error message are those of the exact reader.
"""
import math
import subprocess
import sys

import pytest

from ltd_brake_ros.inputs import InputError, config_dir, load_yaml
from ltd_brake_ros.inputs import schema

PLAIN = [
    "name: x\nmass_t: 050\nspeed: -1.5e3\nflag: true\nnothing: ~\nempty:\n",
    "a: [1, 2.5, .inf, -.inf, .nan, '7', \"8\", 1:20, 1_000, 0x10, yes, Off, null, NULL]",
    "{1: a, 1.0: b, true: c, '1': d, .nan: e, ~: f}",      # equal as Python keys: last wins
    "- &x 5\n- *x\n- {k: *x}\n",                            # an alias to a scalar
    "a: !!str 12\nb: !!float 1\nc: !!int '7'\nd: !!null x\ne: !!bool 'true'\nf: !!seq [1]\n",
    "text: |\n  two\n  lines\nfolded: >\n  one\n  line\n",
    "", "# only a comment\n", "42", "[]", "{}", "- - - - deep\n",
    "k: " + "[" * (schema.MAX_DEPTH - 1) + "1" + "]" * (schema.MAX_DEPTH - 1),
    "big: " + "1" * 4000,
]
NOT_PLAIN = [
    "a: &x [1, 2]\nb: *x\n",                                # an alias to a list
    "name: &a [*a]\n",                                      # ... that contains it
    "a: 1\nb: 2\na: 3\n",
    "scenarios:\n  06: x\n  6: y\n",
    "k: " + "[" * schema.MAX_DEPTH + "1" + "]" * schema.MAX_DEPTH,
    "? [1, 2]\n: x\n",
    "mass_t: !!int 0x10", "mass_t: !!float 1:20", "b: !!bool yes", "when: !!timestamp 2024-01-01",
    "blob: !!binary AAAA", "s: !!set {a, b}", "m: {!!merge <<: {a: 1}}", "v: {!!value x: 1}",
    "big: !!int " + "1" * 5000,
    "a: [1, 2\n", "a: b: c\n", "--- 1\n--- 2\n", "a: *nowhere\n", "a: &x 1\nb: &x 2\n",
    "\t- tab\n", "'unclosed\n", "- [" * 600 + "]" * 600,    # more indicators than libyaml takes
]


def _exact(tmp_path, monkeypatch, text):
    """What the exact reader gives for ``text``: its data, or its error message."""
    monkeypatch.setattr(schema, "_C_COMPOSER_INDICATORS", -1)   # every text to the exact one
    try:
        return _read(tmp_path, text)
    finally:
        monkeypatch.undo()


def _read(tmp_path, text):
    p = tmp_path / "input.yaml"
    p.write_text(text)
    try:
        return repr(load_yaml(p))      # repr: nan equals nan, 1 differs from 1.0 and True
    except InputError as exc:
        return f"InputError: {exc}"


@pytest.mark.parametrize("text", PLAIN + NOT_PLAIN)
def test_data_and_errors_are_those_of_the_exact_reader(tmp_path, monkeypatch, text):
    assert _read(tmp_path, text) == _exact(tmp_path, monkeypatch, text)


@pytest.mark.parametrize("text", PLAIN)
def test_plain_documents_are_composed_by_libyaml(text):
    assert schema._load_plain(text) is not schema._NOT_PLAIN


@pytest.mark.parametrize("text", NOT_PLAIN)
def test_other_documents_go_to_the_exact_reader(text):
    assert schema._load_plain(text) is schema._NOT_PLAIN


def test_every_shipped_file_is_plain_and_reads_the_same(tmp_path, monkeypatch):
    files = sorted(config_dir().rglob("*.yaml"))
    assert len(files) >= 10
    for f in files:
        text = f.read_text()
        assert schema._load_plain(text) is not schema._NOT_PLAIN, f
        assert _read(tmp_path, text) == _exact(tmp_path, monkeypatch, text), f


def test_special_floats_keep_their_values(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text("a: [.inf, -.inf, .nan, 1e3, 050]\n")
    a = load_yaml(p)["a"]
    assert a[:2] == [math.inf, -math.inf] and math.isnan(a[2]) and a[3:] == [1000.0, 50]
    assert [type(x) for x in a] == [float, float, float, float, int]


def test_nesting_libyaml_cannot_take_is_refused_in_one_line(tmp_path):
    # libyaml's composer recurses in C without a bound: a million levels (2 MB) would crash
    # the process, so the document must reach the exact reader, which refuses it
    depth = 1_000_000
    p = tmp_path / "deep.yaml"
    p.write_text("name: " + "[" * depth + "]" * depth + "\n")
    code = ("from ltd_brake_ros.inputs import InputError, load_yaml\nimport sys\n"
            "try:\n    load_yaml(sys.argv[1])\nexcept InputError as exc:\n    print(exc)\n")
    run = subprocess.run([sys.executable, "-c", code, str(p)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert f"name: nested deeper than {schema.MAX_DEPTH} levels (line 1)" in run.stdout


def test_without_libyaml_files_read_the_same(tmp_path):
    # PyYAML built without libyaml: the Python parser reads every file, to the same data
    p = tmp_path / "dup.yaml"
    p.write_text("a: 1\nb: [2, 3]\na: 4\n")
    code = ("import sys\nsys.modules['yaml._yaml'] = None\n"
            "from ltd_brake_ros.inputs import InputError, load_scenarios, load_yaml, schema\n"
            "assert schema._CParser is None\n"
            "print(sorted(load_scenarios()))\n"
            "try:\n    load_yaml(sys.argv[1])\nexcept InputError as exc:\n    print(exc)\n")
    run = subprocess.run([sys.executable, "-c", code, str(p)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0] == repr(list(range(1, 13)))
    with pytest.raises(InputError) as exc:
        load_yaml(p)
    assert lines[1] == str(exc.value) and "given twice (line 1 and line 3)" in lines[1]

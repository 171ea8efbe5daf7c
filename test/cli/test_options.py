"""Options the verbs share: the scenario list, counts, the run specification."""
from __future__ import annotations

import pytest

from ltd_brake_ros.cli.options import parse_scenarios, positive_int
from ltd_brake_ros.inputs import InputError


@pytest.mark.parametrize("text, numbers", [
    ("6", [6]), ("1-6", [1, 2, 3, 4, 5, 6]), ("1-3,9", [1, 2, 3, 9]), ("2, 6 ,12", [2, 6, 12]),
    ("3-3", [3]), ("2,1-3", [2, 1, 3]), ("1,,2,", [1, 2]),
])
def test_scenario_lists_keep_order_and_each_number_once(text, numbers):
    assert parse_scenarios(text) == numbers


@pytest.mark.parametrize("text, words", [
    ("1-x", "expected numbers and ranges like 1-6,9"), ("6-1", "expected numbers and ranges"),
    ("a", "expected numbers"), ("-2", "expected numbers"), (",", "is empty"), ("", "is empty"),
])
def test_bad_scenario_lists_name_the_option(text, words):
    with pytest.raises(InputError) as err:
        parse_scenarios(text, "--rows")
    assert err.value.field == "--rows" and words in err.value.reason


def test_counts_must_be_positive():
    assert positive_int(None, "--jobs") is None and positive_int(3, "--jobs") == 3
    with pytest.raises(InputError, match="--jobs: must be at least 1, got 0"):
        positive_int(0, "--jobs")


def test_json_by_key_writes_each_value_as_the_json_module_does():
    import json
    import math

    from ltd_brake_ros.cli.options import json_by_key

    values = [0.1, -0.0, 1e-7, 1e16, 1e300, 2.0 / 3.0, math.nan, math.inf, -math.inf, 0, -3,
              2**70, True, False, None, 'a "quoted" \u00e9', [1.5, None, math.nan],
              {"x": {"y": [True, 2]}}, (), 7.0]
    doc = {f"k{i}": v for i, v in enumerate(values)}
    text = json_by_key(doc)
    lines = text.splitlines()
    assert lines[0] == "{" and lines[-1] == "}" and len(lines) == len(values) + 2
    for line, (k, v) in zip(lines[1:-1], doc.items()):
        assert line.rstrip(",") == f"  {json.dumps(k)}: {json.dumps(v)}"
    assert json.loads(text).keys() == doc.keys()
    assert json_by_key({}) == "{}"

"""Consist fields of the verdicts and the brake pipe: ``venting_vehicle`` and ``limits``."""
from __future__ import annotations

import pytest

from ltd_brake_ros.inputs import InputError, consist_from_mapping

TRAIN = [{"type": "Shimmns", "count": 3}, {"type": "E402B"}]


def consist(**top):
    return consist_from_mapping(dict({"vehicles": TRAIN}, **top), "train.yaml")


def test_the_venting_vehicle_is_the_leading_locomotive_unless_named():
    assert consist().venting_vehicle == 3
    assert consist(venting_vehicle=1).venting_vehicle == 1


@pytest.mark.parametrize("value, words", [
    (4, "between 0 and 3, got 4"), (-1, "between 0 and 3, got -1"),
    ("2", "whole number"), (1.5, "whole number")])
def test_a_bad_venting_vehicle_is_one_line_naming_the_field(value, words):
    with pytest.raises(InputError) as exc:
        consist(venting_vehicle=value)
    text = str(exc.value)
    assert "train.yaml" in text and "venting_vehicle" in text and words in text
    assert "\n" not in text


@pytest.mark.parametrize("limits, field, words", [
    ({"draft_strength_kN": 0}, "limits.draft_strength_kN", "0"),
    ({"buff_strength_kN": -5}, "limits.buff_strength_kN", "-5"),
    ({"endurable_lcf_kN": 1e6}, "limits.endurable_lcf_kN", "20000"),
    ({"adhesion_limit": 1.5}, "limits.adhesion_limit", "1.5"),
    ({"adhesion": 0.1}, "limits", "adhesion"),
    ("strong", "limits", "mapping")])
def test_bad_limits_are_one_line_naming_the_field(limits, field, words):
    for doc in ({"vehicles": TRAIN, "limits": limits},
                {"vehicles": [{"type": "Shimmns", "limits": limits}]}):
        with pytest.raises(InputError) as exc:
            consist_from_mapping(doc, "train.yaml")
        text = str(exc.value)
        assert field in text and words in text and "\n" not in text, text

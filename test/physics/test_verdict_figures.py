"""A verdict line never contradicts itself once its figures are rounded for printing."""
from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ltd_brake_ros.verdicts.table import Criterion, Exceedance

NUMBER = r"[-+]?\d+(?:\.\d+)?"


def _line(criterion: str, value: float, limit: float) -> str:
    return Exceedance(criterion, "coupler", 3, value, limit, 1.0, 50.0, 0.5).describe()


def _figures(line: str, unit: str) -> tuple[float, float, float, float | None]:
    u = re.escape(unit)
    m = re.search(rf"({NUMBER}){u} > ({NUMBER}){u} \(\+({NUMBER}){u}(?:, \+({NUMBER}) %)?\)",
                  line)
    assert m, line
    value, limit, excess = (float(m.group(k)) for k in (1, 2, 3))
    return value, limit, excess, None if m.group(4) is None else float(m.group(4))


def test_the_reported_defect_reads_right():
    # 44 N beyond a limit of 0.3 N used to read "0 kN > 0 kN (+0 kN, +14567 %)"
    line = _line("draft_strength", 44.0, 0.3)
    value, limit, excess, percent = _figures(line, " kN")
    assert value > limit > 0.0 and excess > 0.0 and percent == pytest.approx(14567, rel=1e-3)


def test_no_relative_margin_over_a_zero_limit():
    line = _line("draft_strength", 1500.0, 0.0)
    assert "%" not in line
    value, limit, excess, _ = _figures(line, " kN")
    assert value > limit == 0.0 and excess > 0.0


@settings(max_examples=300, derandomize=True, deadline=None)
@given(limit=st.floats(0.0, 5e6), excess=st.floats(1e-3, 5e6),
       criterion=st.sampled_from([("draft_strength", " kN"), ("wheel_temperature", " K")]))
def test_a_value_beyond_its_limit_reads_beyond_it(limit, excess, criterion):
    """Whatever the magnitudes (from a thousandth of a newton or kelvin up): the printed value
    is above the printed limit, the printed excess and margin are positive, and a non-zero
    limit is not printed as zero."""
    name, unit = criterion
    value = limit + excess
    if value <= limit:  # the excess vanished in the addition: nothing is beyond
        return
    shown_value, shown_limit, shown_excess, percent = _figures(_line(name, value, limit), unit)
    assert shown_value > shown_limit and shown_excess > 0.0
    assert (shown_limit > 0.0) == (limit > 0.0 and limit * (1e-3 if unit == " kN" else 1.0)
                                   >= 1e-12)
    if percent is not None:
        assert percent > 0.0 and limit > 0.0


def test_a_criterion_row_shows_its_worst_beyond_its_limit():
    exceed = Exceedance("draft_strength", "coupler", 3, 300_400.0, 300_000.0, 1.0, 50.0, 0.5)
    row = Criterion("draft_strength", True, 300_000.0, 300_000.0, "EN 12663-2", 300_400.0, 3,
                    1.0, (exceed,))
    head = row.describe()[0]
    m = re.search(rf"limit ({NUMBER}) kN; worst .* ({NUMBER}) kN at", head)
    assert m and float(m.group(2)) > float(m.group(1)), head
    calm = Criterion("draft_strength", True, 300_000.0, 300_000.0, "EN 12663-2", 120_400.0, 3,
                     1.0)
    assert "limit 300 kN; worst" in calm.describe()[0] and "120 kN" in calm.describe()[0]

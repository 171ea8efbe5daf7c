"""The judgment targets ``ltd-brake validate`` prints: each one met by the shipped models."""
from __future__ import annotations

import pytest

from ltd_brake_ros.studies.judgments import judgment_targets


@pytest.fixture(scope="module")
def targets():
    return judgment_targets()


def test_every_judgment_target_is_met(targets):
    assert len(targets) >= 3
    for what, ok, detail in targets:
        assert ok, f"{what}: {detail}"


def test_the_long_train_is_marked_non_physical_where_its_couplers_go_beyond_their_travel(
        targets):
    what, ok, detail = next(t for t in targets if "300" in t[0])
    # braked from the head, 300 loaded wagons run into each other beyond any coupler's travel
    assert "marked NON-PHYSICAL" in detail

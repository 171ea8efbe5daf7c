"""Who publishes the simulated time: the clock setting resolved, the second publisher warned of."""
from __future__ import annotations

import pytest

from plant_helpers import FakeClock
from ltd_brake_ros.plant.clock_policy import (ANOTHER_NODE, CLOCK_DISCOVERY_MIN_S,
                                              CLOCK_DISCOVERY_POLL_S, CLOCK_DISCOVERY_S,
                                              ClockWatch, other_publishers, resolve_clock)


def test_other_publishers_are_named_once_without_this_node():
    me = ("/train1", "sim_node")
    found = other_publishers(me, [("/train1", "sim_node"), ("/train2", "sim_node"),
                                  ("/", "gazebo"), ("/train2", "sim_node"),
                                  ("/", "_CREATED_BY_BARE_DDS_APP_"), ("/", "_NODE_NAME_UNKNOWN_")])
    assert found == ["/_CREATED_BY_BARE_DDS_APP_", "/gazebo", "/train2/sim_node", ANOTHER_NODE]


@pytest.mark.parametrize("mode", ["publish", "follow", "none"])
def test_a_mode_other_than_auto_is_kept_without_looking(mode):
    def others():
        raise AssertionError("looked for other publishers")

    assert resolve_clock(mode, False, others, 0.0, "/clock") == (mode, None)


def test_auto_publishes_when_nobody_else_does_after_waiting_for_discovery():
    fake = FakeClock(100.0)
    looks = []
    mode, line = resolve_clock("auto", False, lambda: looks.append(fake.t) or [], 99.5,
                               "/clock", fake.clock())
    assert (mode, line) == ("publish", None)
    # until CLOCK_DISCOVERY_S after creation, and at least CLOCK_DISCOVERY_MIN_S from now
    assert fake.t == pytest.approx(99.5 + CLOCK_DISCOVERY_S, abs=CLOCK_DISCOVERY_POLL_S)
    assert len(looks) > 10
    fake = FakeClock(100.0)
    resolve_clock("auto", False, lambda: [], 90.0, "/clock", fake.clock())
    assert fake.t == pytest.approx(100.0 + CLOCK_DISCOVERY_MIN_S, abs=CLOCK_DISCOVERY_POLL_S)


def test_auto_follows_another_publisher_and_waits_for_its_name():
    fake = FakeClock(100.0)

    def others():  # the endpoint shows first, its node's name half a second later
        return [] if fake.t < 100.5 else [ANOTHER_NODE] if fake.t < 101.0 else \
            ["/leader/sim_node"]

    mode, line = resolve_clock("auto", True, others, 100.0, "/clock", fake.clock())
    assert mode == "follow" and fake.t < 100.0 + CLOCK_DISCOVERY_S
    assert line == ("/clock is published by /leader/sim_node: following it, one simulated time "
                    "for both (lockstep ignored: that clock steps this train); clock:=publish "
                    "would publish a second clock")


def test_a_second_clock_publisher_is_warned_about_once_by_name():
    watch = ClockWatch("/clock")
    assert watch.check([]) is None and watch.check([ANOTHER_NODE]) is None
    assert watch.check(["/b/sim_node"]) == (
        "/b/sim_node also publish(es) /clock: time jumps back and forth for every node using "
        "it; start one plant with clock:=publish and the others with clock:=follow")
    assert watch.check(["/b/sim_node"]) is None
    assert watch.check(["/b/sim_node", "/c/sim_node"]).startswith("/c/sim_node also")

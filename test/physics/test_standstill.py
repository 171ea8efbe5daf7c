"""Standstill: a stopped, braked vehicle holds up to its brake's grip on the rail."""
from __future__ import annotations

import numpy as np
import pytest

from ltd_brake_ros.inputs import consist_from_mapping, get_scenario
from ltd_brake_ros.physics.brakes import friction
from ltd_brake_ros.physics.constants import G
from ltd_brake_ros.simulator import Commands, Simulator

#: Largest roll-back allowed after a stop [m].
ROLL_BACK_M = 5e-3


def roll_back_after_stop(sim, seconds=30.0):
    """Largest backward travel of any vehicle in the ``seconds`` after the stop [m]."""
    sim.advance(1.0, Commands(emergency=True))
    while sim.stop_time_s is None:
        sim.advance(1.0)
    at_stop = sim.snapshot().position_m.copy()
    lowest = at_stop.copy()
    for _ in range(int(seconds / 0.5)):
        lowest = np.minimum(lowest, sim.advance(0.5).position_m)
    return float((at_stop - lowest).max())


@pytest.mark.parametrize("consist,speed_kmh", [
    (get_scenario(6).consist(), 100.0),
    (consist_from_mapping({"vehicles": [{"type": "E402B"},
                                        {"type": "Shimmns", "count": 100, "mass_t": 80.0}]},
                          "100 wagons"), 100.0)])
def test_no_vehicle_rolls_back_after_the_stop(consist, speed_kmh):
    # the coupler forces left at the stop (~177 kN on the locomotive of scenario 6) are far
    # below what a braked wheelset holds at rest (0.3 m g: 262 kN for the 89 t E402B)
    assert roll_back_after_stop(Simulator(consist, speed_kmh)) < ROLL_BACK_M


def test_the_holding_capacity_is_the_standstill_adhesion_at_full_application():
    m, full = 89e3, 200e3
    cap = friction.standstill_capacity(full, full, m)
    assert cap == pytest.approx(friction.STANDSTILL_ADHESION * G * m)
    assert friction.standstill_capacity(0.5 * full, full, m) == pytest.approx(0.5 * cap)
    assert friction.standstill_capacity(0.0, full, m) == 0.0  # released: nothing beyond
    assert friction.standstill_capacity(2.0 * full, full, m) == pytest.approx(cap)


@pytest.mark.parametrize("share,moves", [(0.8, False), (1.2, True)])
def test_a_braked_vehicle_at_rest_holds_up_to_its_capacity_and_no_further(share, moves):
    c = consist_from_mapping({"vehicles": [{"type": "Shimmns", "mass_t": 80.0}]}, "one wagon")
    sim = Simulator(c, 0.0)
    sim.advance(10.0, Commands(emergency=True))  # the brake applies fully at rest
    cap = friction.STANDSTILL_ADHESION * G * 80e3
    x0 = float(sim.snapshot().position_m[0])
    sim.fext_N[:] = -share * cap  # pulled backwards (a coupler, a grade)
    sim.advance(10.0)
    moved = x0 - float(sim.snapshot().position_m[0])
    if moves:
        # beyond its capacity it breaks away and slides back against the kinetic brake force
        # (about 0.16 m g for an 80 t Shimmns near rest): some 0.2 g, tens of metres in 10 s
        assert moved > 1.0
    else:
        assert abs(moved) < 1e-3

"""Standstill: a stopped train settles, holds by its brakes' friction, and never runs away
without a judgment.

A vehicle at rest holds the static friction of its brake (the kinetic law at rest: Karwatzki's
0.6 (16 F/g + 100) / (80 F/g + 100) F for P10 blocks), at most the rail's adhesion at rest,
0.12 m g, plus its running resistance at rest (Eq. 2: m_t (2.943 + 89.2 / q_axle) [N]).
"""
from __future__ import annotations

import numpy as np
import pytest

from ltd_brake_ros.inputs import Track, consist_from_mapping, get_scenario
from ltd_brake_ros.physics.constants import G
from ltd_brake_ros.physics.kernel import SETTLE_S
from ltd_brake_ros.simulator import Commands, Simulator
from ltd_brake_ros.studies.runs import emergency_run

#: The 80 t Shimmns of the shipped vehicle library: 8 Bg blocks, 4 axles.
WAGON = {"type": "Shimmns", "mass_t": 80.0}
UNBRAKED = {"type": "Shimmns", "mass_t": 80.0, "brake": {"type": "none"}}


def train(wagons: list) -> object:
    return consist_from_mapping({"name": "test", "vehicles": [{"type": "E402B"}, *wagons]},
                                "<test>")


def down_grade(permille: float) -> Track:
    return Track(gradient_permille=(-abs(permille),))


def karwatzki_static_N(block_force_N: float, blocks: int) -> float:
    """The kinetic law at rest of P10 Bg blocks (Eq. 9 at v = 0), written out here."""
    f_t = block_force_N / blocks / 1000.0 / G  # one block's force in tonnes-force
    return 0.6 * (16.0 * f_t + 100.0) / (80.0 * f_t + 100.0) * block_force_N


def rest_resistance_N(mass_t: float, axles: int) -> float:
    """Eq. 2 at rest: m_t (2.943 + 89.2 / q_axle) [N]."""
    return mass_t * (2.943 + 89.2 / (mass_t / axles))


@pytest.mark.parametrize("speed_kmh", [2.0, 5.0, 10.0, 40.0])
def test_a_train_with_one_unbraked_wagon_holds_on_a_20_permille_down_grade(speed_kmh):
    # each braked wagon holds far more than the 15.7 kN its grade asks (and the unbraked
    # wagon's share through its couplers): whatever the speed it stopped from, it holds
    wagons = [WAGON] * 14 + [UNBRAKED] + [WAGON] * 15
    sim = emergency_run(train(wagons), speed_kmh, track=down_grade(20.0))
    table = sim.verdicts()
    assert sim.settled_time_s is not None
    assert table["standstill_holding"].status == "PASS"
    assert table["runaway"].status == "PASS"
    assert table.status == "PASS"
    # it stays so: another minute at rest, nothing moves
    for _ in range(6):
        sim.advance(10.0)
    assert sim.phase == "at rest" and sim.verdicts().status == "PASS"


def test_five_unbraked_tail_wagons_settle_after_their_recoil():
    wagons = [WAGON] * 25 + [UNBRAKED] * 5
    sim = Simulator(train(wagons), 40.0, track=down_grade(20.0))
    sim.advance(0.5, Commands(emergency=True))
    last_move = None
    while sim.settled_time_s is None:
        snap = sim.advance(0.5)
        if np.abs(snap.speed_m_s).max() > sim.standstill_m_s:
            last_move = snap.time_s
    # the tail recoils after the first standstill; the train settles only after it
    assert sim.stop_time_s < last_move
    assert sim.settled_time_s >= last_move - 0.5  # within the chunk of its last movement
    assert sim.time_s == pytest.approx(sim.settled_time_s + SETTLE_S, abs=0.5)
    stop, = sim.stops
    assert stop.settled_time_s == sim.settled_time_s > stop.stop_time_s


def _parked(share: float, permille: float = 40.0):
    """Ten 80 t wagons at rest on a down grade, chocked, a service application of ``share``
    of the full block force made; then the chocks removed."""
    consist = consist_from_mapping({"name": "cut", "vehicles": [{**WAGON, "count": 10}]},
                                   "<test>")
    sim = Simulator(consist, 0.0, track=down_grade(permille))
    grade = sim.mass_kg * G * permille / 1000.0
    sim.fext_N[:] = -grade  # the chocks
    sim.advance(60.0, Commands(brake_demand=share))  # fully applied
    sim.fext_N[:] = 0.0
    sim.advance(10.0)
    return sim


def test_a_parked_cut_holds_above_the_share_its_grade_needs_and_runs_away_below():
    permille, n_blocks = 40.0, 8
    probe = Simulator(consist_from_mapping({"vehicles": [WAGON]}, "<test>"), 0.0)
    full = float(probe.max_block_force_N[0])
    m_t = 80.0
    grade_N = m_t * 1e3 * G * permille / 1000.0

    def capacity(share):
        brake = min(karwatzki_static_N(share * full, n_blocks), 0.12 * m_t * 1e3 * G)
        return brake + rest_resistance_N(m_t, 4)
    lo, hi = 0.0, 1.0  # the share at which each wagon holds exactly its grade force
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if capacity(mid) < grade_N else (lo, mid)
    share = 0.5 * (lo + hi)
    assert 0.05 < share < 0.9  # a share a service application can make
    held = _parked(1.2 * share, permille)
    assert held.phase == "at rest"
    assert held.verdicts()["runaway"].status == "PASS"
    assert held.verdicts()["standstill_holding"].status == "PASS"
    gone = _parked(0.8 * share, permille)
    assert gone.phase == "runaway"
    runaway = gone.verdicts()["runaway"]
    assert runaway.status == "FAIL" and len(runaway.exceedances) == 10
    assert all(e.first_time_s >= 60.0 for e in runaway.exceedances)  # once the chocks went


def test_a_force_beyond_the_rails_adhesion_at_rest_fails_the_holding():
    # an 80 t wagon's blocks hold about 127 kN at rest, the rail only 0.12 m g = 94 kN: a pull
    # between the two is held by the brake but not by the rail
    c = consist_from_mapping({"vehicles": [WAGON]}, "one wagon")
    sim = Simulator(c, 0.0)
    sim.advance(30.0, Commands(emergency=True))  # fully applied at rest
    rail = 0.12 * 80e3 * G
    sim.fext_N[:] = -0.8 * rail
    sim.advance(5.0)
    assert sim.verdicts()["standstill_holding"].status == "PASS"
    sim.fext_N[:] = -1.2 * rail
    events = sim.advance(5.0).events
    hold = sim.verdicts()["standstill_holding"]
    assert hold.status == "FAIL" and hold.exceedances[0].element == "train"
    assert hold.exceedances[0].limit == pytest.approx(rail + rest_resistance_N(80.0, 4),
                                                      rel=1e-6)
    assert hold.exceedances[0].describe().startswith("train: force to hold")
    assert any(e.detail.get("criterion") == "standstill_holding" for e in events)
    assert sim.phase == "at rest"  # the brake holds it: the rail is what fails


def test_scenario_6_settles_and_holds_and_no_moving_vehicle_is_judged_at_rest():
    sc = get_scenario(6)
    sim = emergency_run(sc.consist(), sc.speed_kmh)
    table = sim.verdicts()
    assert table["standstill_holding"].status == "PASS" and table["runaway"].status == "PASS"
    # judged only at rest: every speed the holding row reports is below the standstill speed
    for e in table["standstill_holding"].exceedances:
        assert e.speed_kmh < 0.0036
    assert sim.settled_time_s > sim.stop_time_s

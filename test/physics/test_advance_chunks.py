"""What Simulator.advance hands back chunk by chunk: snapshots that are the simulator's state as
independent copies, external forces changed between chunks taking effect, and a coupler's first
excursion beyond its table reported once."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ltd_brake_ros.inputs import Track, get_scenario
from ltd_brake_ros.simulator import Commands, Simulator, Snapshot


@pytest.fixture(scope="module")
def consist():
    return get_scenario(6).consist()


def test_snapshot_is_an_independent_copy_of_the_state(consist):
    track = Track(start_chainage_m=1234.5)
    sim = Simulator(consist, 100.0, track=track)
    snap = sim.advance(1.0, Commands(emergency=True))
    k = sim._state.kinematics  # the kernel's arrays the snapshot is taken from
    built = Snapshot(*(getattr(snap, f.name) for f in dataclasses.fields(Snapshot)))
    assert type(snap) is Snapshot and list(vars(snap)) == list(vars(built))
    with pytest.raises(dataclasses.FrozenInstanceError):
        snap.time_s = 0.0
    np.testing.assert_array_equal(
        snap.position_m, track.start_chainage_m + k.x_m - sim.model.train.centre_offset_m)
    kept = {name: np.array(getattr(snap, name)) for name in (
        "position_m", "speed_m_s", "brake_force_N", "traction_force_N", "block_force_N",
        "coupler_force_N")}
    for name in kept:  # changing a snapshot changes neither the simulator nor the next one
        getattr(snap, name)[:] = np.nan
    again = sim.snapshot()
    for name, values in kept.items():
        np.testing.assert_array_equal(getattr(again, name), values)
    sim.advance(1.0)  # nor does the simulator going on change a snapshot kept
    for name, values in kept.items():
        np.testing.assert_array_equal(getattr(again, name), values)
    assert not np.array_equal(sim.snapshot().position_m, kept["position_m"])


def test_external_forces_changed_between_chunks_take_effect(consist):
    pull = np.zeros(len(consist.vehicles))
    pull[0] = 200e3  # [N]
    in_place, new_array, as_list = (Simulator(consist, 60.0) for _ in range(3))
    for sim in (in_place, new_array, as_list):
        sim.advance(0.5)
    in_place.fext_N[:] = pull
    new_array.fext_N = pull.copy()
    as_list.fext_N = pull.tolist()
    snaps = [sim.advance(0.5) for sim in (in_place, new_array, as_list)]
    for snap in snaps[1:]:
        np.testing.assert_array_equal(snap.speed_m_s, snaps[0].speed_m_s)
    # 200 kN on about 1 900 t for 0.5 s: the head gains speed against the coasting train
    coasting = Simulator(consist, 60.0)
    coasting.advance(1.0)
    assert snaps[0].speed_m_s[0] > coasting.snapshot().speed_m_s[0] + 0.01
    in_place.fext_N = np.zeros(3)
    with pytest.raises(ValueError, match="one force per vehicle"):
        in_place.advance(0.5)


def test_each_coupler_leaving_its_table_is_reported_once(consist):
    sim = Simulator(consist, 0.0)
    # head and tail pulled apart far beyond what the buffers and draw gear take
    sim.fext_N[0], sim.fext_N[-1] = 3e6, -3e6
    events = []
    for _ in range(20):
        events += [e for e in sim.advance(0.1).events if e.kind == "coupler_out_of_lut"]
    couplers = [e.detail["coupler"] for e in events]
    excursions = sim.coupler_excursions()
    assert excursions.count > 0
    assert sorted(couplers) == sorted(set(couplers))  # once each
    assert len(couplers) == excursions.count
    assert all(e.detail["beyond_table_mm"] > 0.0 for e in events)

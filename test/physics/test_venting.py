"""Brake pipe vented at the driver's brake valve: Eq. 6 timed from the venting vehicle."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ltd_brake_ros.inputs import get_scenario, load_brake_params
from ltd_brake_ros.physics.brakes import linear_ramp
from ltd_brake_ros.physics.equations import centre_offsets_m
from ltd_brake_ros.simulator import Commands, Simulator

SCENARIO = 6  # E402B + 32 Shimmns 50 t from 100 km/h (the loco-at-rear case)


@pytest.fixture(scope="module")
def forward():
    return get_scenario(SCENARIO).consist()


def reversed_train(consist, venting=None):
    return dataclasses.replace(consist, vehicles=consist.vehicles[::-1], venting=venting)


def centres(consist):
    return centre_offsets_m(np.array([v.length_m for v in consist.vehicles]))


def test_the_leading_locomotive_vents_by_default(forward):
    assert forward.venting_vehicle == 0  # the paper's trains: E402B at the head
    assert reversed_train(forward).venting_vehicle == forward.n - 1
    wagons = dataclasses.replace(forward, vehicles=forward.vehicles[1:])
    assert wagons.venting_vehicle == 0  # no locomotive: the head
    assert dataclasses.replace(forward, venting=5).venting_vehicle == 5


def test_paper_trains_keep_eq6_from_the_head_bit_for_bit(forward):
    p = load_brake_params()
    c = centres(forward)
    expected = p.t_app_s + (c - c[0]) / p.v_air_m_s
    assert np.array_equal(Simulator(forward, 100.0, p).brake_delay_s, expected)


@pytest.mark.parametrize("model", ["uic_empirical", "linear_ramp"])
def test_a_reversed_train_vented_at_its_locomotive_mirrors_the_delays(forward, model):
    params = load_brake_params() if model == "uic_empirical" else \
        dataclasses.replace(load_brake_params(), pneumatic=linear_ramp.Params())
    fwd = Simulator(forward, 100.0, params).brake_delay_s
    rev = Simulator(reversed_train(forward), 100.0, params).brake_delay_s
    # the same distances from the venting vehicle, summed from the other end
    np.testing.assert_allclose(rev[::-1], fwd, rtol=0.0, atol=1e-12)
    assert rev[-1] == params.t_app_s == rev.min()


def test_venting_in_the_middle_travels_both_ways(forward):
    k = 16
    p = load_brake_params()
    d = Simulator(dataclasses.replace(forward, venting=k), 100.0, p).brake_delay_s
    c = centres(forward)
    assert d[k] == p.t_app_s == d.min()
    assert np.all(np.diff(d[: k + 1]) < 0) and np.all(np.diff(d[k:]) > 0)
    np.testing.assert_allclose(d, p.t_app_s + np.abs(c - c[k]) / p.v_air_m_s, rtol=1e-15)
    # the far end hears the command after the longer half of the train
    assert d.max() == pytest.approx(p.t_app_s + max(c[k] - c[0], c[-1] - c[k]) / p.v_air_m_s)


def stop_peaks(consist, speed_kmh):
    sim = Simulator(consist, speed_kmh)
    sim.advance(1.0, Commands(emergency=True))
    while sim.stop_time_s is None:
        sim.advance(1.0)
    return sim.coupler_peaks()


@pytest.mark.parametrize("speed_kmh", [100.0, 50.0])
def test_venting_at_a_rear_locomotive_stretches_the_train(forward, speed_kmh):
    # Vented at the rear, the brakes apply from the tail forwards: the braked rear holds back
    # the still rolling front, so the train runs in draft; vented at the head wagon, the
    # front brakes first and the rear runs in. The draft peak must grow.
    at_loco = stop_peaks(reversed_train(forward), speed_kmh)
    at_head = stop_peaks(reversed_train(forward, venting=0), speed_kmh)
    assert at_loco.draft_N > 1.5 * at_head.draft_N

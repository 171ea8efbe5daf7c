"""Traction, dynamic brake, service brake, brake position and track: hand-checked physics."""
import math

import numpy as np
import pytest

from ltd_brake_ros.inputs import BrakeParams, Track, consist_from_mapping, get_scenario, load_track
from ltd_brake_ros.physics import G, curve_resistance_N_per_kN, resistance_N
from ltd_brake_ros.simulator import Commands, Simulator


def wagons(n, mass_t=80.0, **extra):
    return consist_from_mapping({"name": "t", "vehicles": [
        dict({"type": "Shimmns", "count": n, "mass_t": mass_t}, **extra)]}, "<test>")


def test_free_train_on_down_grade_accelerates_at_g_gradient_over_rho():
    track = Track((0.0,), (-10.0,), (0.0,))
    sim = Simulator(wagons(5), 36.0, track=track)
    v0 = sim.snapshot().speed_m_s[0]
    sim.advance(1.0)
    v1 = sim.snapshot().speed_m_s[0]
    res, _ = resistance_N(80e3, 4.0, 0.5 * (v0 + v1))
    expected = (80e3 * G * 0.010 - res) / (1.04 * 80e3)  # [m/s^2]
    assert (v1 - v0) / 1.0 == pytest.approx(expected, rel=1e-3)
    assert np.allclose(sim.snapshot().coupler_force_N, 0.0, atol=1.0)  # uniform train: no load


def test_grade_change_under_train_loads_couplers_quasi_statically():
    # front half of 20 identical wagons on a 10 per mille climb, rear half level, no resistance:
    # a = -g*0.01/(2 rho) and the coupler at the grade change carries -(N/2)*m*g*0.005 (buff),
    # falling linearly to zero at both ends
    n, m = 20, 80e3
    track = Track((-1e4, 0.0), (0.0, 10.0), (0.0, 0.0), start_chainage_m=n * 12.64 / 2)
    sim = Simulator(wagons(n), 1.8, track=track, resistance=False)
    for _ in range(9):
        snap = sim.advance(1.0)
    fc = snap.coupler_force_N
    expected = -(n / 2) * m * G * 0.005
    assert fc[9] == pytest.approx(expected, rel=0.02)
    assert np.argmin(fc) == 9
    ramp = expected * np.concatenate((np.arange(1, 11), np.arange(9, 0, -1))) / 10
    assert np.allclose(fc, ramp, atol=0.1 * abs(expected))


def test_curve_resistance_roeckl():
    assert curve_resistance_N_per_kN(0.0) == 0.0
    assert curve_resistance_N_per_kN(600.0) == pytest.approx(650 / 545)
    assert curve_resistance_N_per_kN(250.0) == pytest.approx(500 / 220)


def loco_consist():
    return consist_from_mapping({"name": "loco", "vehicles": [{"type": "E402B"}]}, "<test>")


def test_traction_respects_max_force_and_power():
    sim = Simulator(loco_consist(), 0.0, resistance=False)
    tr = sim.consist.vehicles[0].traction
    sim.advance(0.1, Commands(traction=1.0))
    # rate limit: 50 kN/s
    assert sim.snapshot().traction_force_N[0] <= tr.rate_limit_N_s * 0.1 + 1e-6
    sim.advance(4.0)
    assert sim.snapshot().traction_force_N[0] <= tr.max_force_N * (1 + 1e-12)
    # at speed the power limit governs: F -> P / v; a heavy train accelerates slowly, so the
    # 1 s lag trails the falling P / v by well under 1 %
    fast = Simulator(get_scenario(6).consist(), 120.0)
    for _ in range(20):
        snap = fast.advance(0.5, Commands(traction=1.0))
        f, v = snap.traction_force_N[0], snap.speed_m_s[0]
        assert f <= tr.max_power_W / v * 1.01
    assert f == pytest.approx(tr.max_power_W / v, rel=0.02)
    assert f < tr.max_force_N


def test_dynamic_brake_opposes_motion_and_fades_at_standstill():
    sim = Simulator(loco_consist(), 80.0)
    for _ in range(10):
        snap = sim.advance(0.5, Commands(traction=-1.0))
    assert snap.traction_force_N[0] < 0.0
    assert abs(snap.traction_force_N[0]) <= sim.consist.vehicles[0].traction.brake_max_force_N
    for _ in range(200):
        snap = sim.advance(0.5, Commands(traction=-1.0))
    assert snap.speed_m_s[0] < 0.5
    assert snap.speed_m_s[0] >= 0.0  # never drives the train backwards


def stop_distance(sim, cmd):
    sim.advance(0.02, cmd)
    while sim.stop_time_s is None:
        assert sim.time_s < 600
        sim.advance(0.5)
    return sim.stopping_distance_m


def test_service_brake_distance_between_emergency_and_infinity_monotone():
    sc = get_scenario(6)
    consist = sc.consist()
    emergency = stop_distance(Simulator(consist, 100.0), Commands(emergency=True))
    service = [stop_distance(Simulator(consist, 100.0), Commands(brake_demand=d))
               for d in (0.3, 0.5, 0.8)]
    assert service[0] > service[1] > service[2] > emergency
    assert math.isfinite(service[0])


def test_emergency_overrides_service_demand():
    sc = get_scenario(6)
    a = stop_distance(Simulator(sc.consist(), 100.0), Commands(emergency=True))
    b = stop_distance(Simulator(sc.consist(), 100.0), Commands(emergency=True, brake_demand=0.3))
    assert a == b


def test_release_returns_block_force_to_zero_with_its_time_constant():
    params = BrakeParams(t_release_s=15.0)
    sim = Simulator(wagons(3), 60.0, params)
    sim.advance(60.0, Commands(brake_demand=1.0))
    f0 = sim.snapshot().block_force_N[0]
    assert f0 == pytest.approx(sim.max_block_force_N[0], rel=1e-9)
    # the head vehicle hears the release after t_app (no distance delay), then decays with
    # tau = t_release / ln 20: 5 % left after t_release
    sim.advance(params.t_app_s + params.t_release_s, Commands(brake_demand=0.0))
    assert sim.snapshot().block_force_N[0] == pytest.approx(0.05 * f0, rel=1e-6)
    sim.advance(60.0)
    assert sim.snapshot().block_force_N.max() < 1e-3 * f0


def test_g_position_fills_slower_and_uses_its_braked_weight():
    p = BrakeParams()
    c = consist_from_mapping({"vehicles": [
        {"type": "E402B", "brake_position": "G",
         "brake": {"type": "disc", "braked_weight_t": 79.0, "braked_weight_G_t": 60.0}},
        {"type": "Shimmns", "count": 2, "mass_t": 80.0, "brake_position": "G"}]}, "<test>")
    sim = Simulator(c, 50.0, p)
    assert sim.max_block_force_N[0] == pytest.approx(60.0 * 9.81 / p.k_loco * 1e3)
    sim.advance(p.t_app_s + p.t_fill_G_s, Commands(emergency=True))
    assert sim.snapshot().block_force_N[0] / sim.max_block_force_N[0] == pytest.approx(0.95, rel=1e-6)


def test_locomotive_in_the_middle_vents_the_brake_pipe_both_ways():
    c = consist_from_mapping({"vehicles": [
        {"type": "Shimmns", "count": 5, "mass_t": 80.0}, {"type": "E402B"},
        {"type": "Shimmns", "count": 5, "mass_t": 80.0}]}, "<test>")
    sim = Simulator(c, 80.0)
    d = sim.brake_delay_s  # the driver's brake valve in the locomotive (vehicle 5) vents
    assert np.all(np.diff(d[:6]) < 0) and np.all(np.diff(d[5:]) > 0)
    assert stop_distance(sim, Commands(emergency=True)) > 0


def test_track_file_yaml_and_csv(tmp_path):
    t = load_track("tracks/hump_10permille.yaml")
    assert t.gradient_permille[1] == 10.0 and t.radius_m[2] == 600.0
    p = tmp_path / "t.csv"
    p.write_text("chainage_m,gradient_permille,radius_m\n0,0,\n500,-5,800\n")
    t = load_track(p, start_chainage_m=100.0)
    assert t.chainage_m == (0.0, 500.0) and t.radius_m == (0.0, 800.0)
    assert t.start_chainage_m == 100.0


@pytest.mark.parametrize("field,value", [("brake_demand", 1.5), ("brake_demand", float("nan")),
                                         ("traction", -2.0), ("traction", float("inf"))])
def test_commands_reject_bad_values(field, value):
    with pytest.raises(ValueError, match=field):
        Commands(**{field: value})

"""Strength and adhesion verdicts: limits, events when first exceeded, the table."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ltd_brake_ros import verdicts
from ltd_brake_ros.inputs import consist_from_mapping, get_scenario, load_coupler_lut
from ltd_brake_ros.inputs.consist import VehicleLimits
from ltd_brake_ros.physics.constants import G, KMH_PER_MS
from ltd_brake_ros.simulator import Commands, Simulator


def stop(sim, chunk_s=1.0):
    events = list(sim.advance(chunk_s, Commands(emergency=True)).events)
    while sim.stop_time_s is None:
        events += sim.advance(chunk_s).events
    return [e for e in events if e.kind == "limit_exceeded"]


def with_limits(consist, **limits):
    lim = VehicleLimits(**limits)
    return dataclasses.replace(consist, vehicles=tuple(
        dataclasses.replace(v, limits=lim) for v in consist.vehicles))


def test_limits_come_from_the_consist_then_the_coupler_then_the_standards():
    c = get_scenario(7).consist()  # 11 vehicles, 10 couplers
    lut = load_coupler_lut()
    lim = verdicts.train_limits(c, dataclasses.replace(lut, draft_strength_N=math.inf,
                                                       buff_strength_N=math.inf))
    assert np.all(lim.draft_strength_N == 850e3) and np.all(lim.buff_strength_N == 2000e3)
    assert np.all(np.isinf(lim.endurable_lcf_N)) and np.all(lim.adhesion_limit == 0.12)
    assert "EN 15566" in lim.origin["draft_strength"]
    lim = verdicts.train_limits(c, dataclasses.replace(lut, draft_strength_N=1000e3))
    assert np.all(lim.draft_strength_N == 1000e3) and lim.origin["draft_strength"] == \
        "coupler file"
    # vehicle 4 has a weaker draw gear: the couplers on either side of it (4 and 5) take it
    vs = list(c.vehicles)
    vs[4] = dataclasses.replace(vs[4], limits=VehicleLimits(draft_strength_N=600e3,
                                                            adhesion_limit=0.10))
    vs[5] = dataclasses.replace(vs[5], limits=VehicleLimits(wheel_slide_protection=True))
    lim = verdicts.train_limits(dataclasses.replace(c, vehicles=tuple(vs)),
                                dataclasses.replace(lut, draft_strength_N=1000e3))
    assert lim.draft_strength_N.tolist() == [1000e3] * 3 + [600e3] * 2 + [1000e3] * 5
    # an explicit limit, wheel-slide protection's default, the default without it
    assert lim.adhesion_limit[4] == 0.10 and lim.adhesion_limit[5] == 0.15
    assert lim.adhesion_limit[3] == 0.12
    np.testing.assert_allclose(lim.weight_N, [v.mass_kg * G for v in c.vehicles])


def test_a_consist_file_gives_limits_for_the_train_and_per_vehicle():
    c = consist_from_mapping({"limits": {"draft_strength_kN": 1000, "adhesion_limit": 0.13},
                              "vehicles": [{"type": "E402B"},
                                           {"type": "Shimmns", "count": 2},
                                           {"type": "Shimmns",
                                            "limits": {"endurable_lcf_kN": 240}}]}, "t.yaml")
    assert c.vehicles[0].limits == VehicleLimits(1000e3, None, None, 0.13)
    assert c.vehicles[3].limits == VehicleLimits(1000e3, None, 240e3, 0.13)
    lim = verdicts.train_limits(c)
    assert lim.endurable_lcf_N[:2].tolist() == [math.inf, math.inf]
    assert lim.endurable_lcf_N[2] == 240e3


def test_every_coupler_beyond_its_strength_is_named_once_with_its_worst():
    sc = get_scenario(6)
    # a draft strength below this train's peak draft: the couplers above it must be named
    ref = Simulator(sc.consist(), sc.speed_kmh)
    stop(ref)
    limit = 0.6 * ref.peak_draft_N.max()
    sim = Simulator(with_limits(sc.consist(), draft_strength_N=limit), sc.speed_kmh)
    events = stop(sim)
    beyond = set(np.flatnonzero(sim.peak_draft_N > limit) + 1)
    assert beyond and {e.detail["coupler"] for e in events
                       if e.detail["criterion"] == "draft_strength"} == beyond
    keys = [(e.detail["criterion"], e.detail.get("coupler"), e.detail.get("vehicle"))
            for e in events]
    assert len(keys) == len(set(keys))  # each coupler or vehicle once per criterion
    v = sim.verdicts()["draft_strength"]
    assert v.status == "FAIL" and {e.number for e in v.exceedances} == beyond
    for e in v.exceedances:
        assert e.value == sim.peak_draft_N[e.number - 1] > e.limit == limit
        assert e.time_s == sim.peak_draft_time_s[e.number - 1] >= e.first_time_s >= 0.0
        assert 0.0 <= e.speed_kmh <= sc.speed_kmh
    worst = v.exceedances[0]
    assert worst.value == sim.peak_draft_N.max()
    assert "coupler" in worst.describe() and "km/h" in worst.describe()
    diag = verdicts.diagnostic_values(sim.verdicts())
    assert diag["verdicts"] == "FAIL" and diag["verdict_endurable_lcf"] == "not assessed"
    assert diag["verdict_draft_strength"].startswith(f"FAIL: {len(beyond)} coupler(s)")
    assert f"coupler {worst.number}:" in diag["verdict_draft_strength"]
    assert all(isinstance(x, str) for x in diag.values())


def test_the_speed_of_an_exceedance_is_the_trains_then():
    sc = get_scenario(6)
    sim = Simulator(with_limits(sc.consist(), buff_strength_N=1e3), sc.speed_kmh)
    stop(sim, chunk_s=0.05)  # small chunks: speeds known at the chunk ends
    for e in sim.verdicts()["buff_strength"].exceedances:
        # decelerating at most ~1.5 m/s^2 (Table 1 stops): within a chunk the speed moves
        # by less than 0.3 km/h from the linear interpolation used
        ref = Simulator(sc.consist(), sc.speed_kmh)
        ref.advance(e.time_s, Commands(emergency=True))
        assert e.speed_kmh == pytest.approx(float(ref.snapshot().speed_m_s[0]) * KMH_PER_MS,
                                            abs=0.3)
        break


def braked_at(consist, percent, wagons=None):
    """The consist with its wagons' braked weight set to ``percent`` of their mass."""
    vs = list(consist.vehicles)
    for i in wagons or range(1, len(vs)):
        v = vs[i]
        vs[i] = dataclasses.replace(v, brake=dataclasses.replace(
            v.brake, braked_weight_t=percent / 100.0 * v.mass_kg / 1e3))
    return dataclasses.replace(consist, vehicles=tuple(vs))


@pytest.fixture(scope="module")
def scenario_6():
    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh)
    events = stop(sim)
    return sim, events


def test_mean_adhesion_of_the_paper_train_passes_and_lies_within_its_friction_bounds(scenario_6):
    sim, _ = scenario_6
    table = sim.verdicts()
    v = table["adhesion"]
    assert v.assessed and v.status == "PASS" and table.status == "PASS"
    d = sim.adhesion_records()
    fr, rho = sim.model.friction, np.array([x.inertia_factor for x in sim.consist.vehicles])
    w = sim.mass_kg * G
    wagons = slice(1, None)
    # a fully applied block brake's force lies between Karwatzki's speed factor at 100 km/h
    # (0.6 * 200 / 600) and at 5 km/h (0.6 * 105 / 125) times its full scale; the rails take
    # less by what decelerates the rotating masses, (rho - 1) M a with a below 1.5 m/s^2
    lo = fr.full_scale_N * 0.2 / w - (rho - 1.0) * 1.5 / G
    hi = fr.full_scale_N * (0.6 * 105.0 / 125.0) / w
    assert np.all((lo[wagons] < d.mean[wagons]) & (d.mean[wagons] < hi[wagons]))
    # scenario 6's wagons use about 0.09-0.11 (its whole stop: (100/3.6)^2 / (2 * 489 m) / g
    # = 0.080, from the command, delay and rise included)
    assert np.all((0.09 < d.mean[wagons]) & (d.mean[wagons] < 0.11))
    # the disc-braked locomotive: mu_eff F_B at every speed, less its rotating masses' share
    loco = fr.mu_disc[0] * fr.force_max_N[0] / w[0]
    assert loco - (rho[0] - 1.0) * 1.5 / G < d.mean[0] < loco
    # braked part: from full application (a few seconds after the command) to 5 km/h
    assert np.all(d.mean_distance_m[wagons] < sim.stopping_distance_m)
    assert np.all(d.mean_distance_m[wagons] > 0.5 * sim.stopping_distance_m)


def _design_tau(sim, i):
    """A vehicle's design mean utilised adhesion written out here: braked alone at full
    application from its maximum speed to 5 km/h, its retarding force F(v) = full scale x
    Karwatzki's speed factor 0.6 (V + 100) / (5 V + 100); the equivalent deceleration over g,
    (v1^2 - v2^2) / (2 g s) with s = int rho M v / F(v) dv (quadrature)."""
    from scipy.integrate import quad

    v = sim.consist.vehicles[i]
    scale = float(sim.model.friction.full_scale_N[i])
    vmax = (v.max_speed_kmh or 100.0) / 3.6

    def dist(u):
        kmh = 3.6 * u
        return v.inertia_factor * v.mass_kg * u / (scale * 0.6 * (kmh + 100) / (5 * kmh + 100))
    s, _ = quad(dist, 5.0 / 3.6, vmax, epsabs=1e-10)
    return (vmax ** 2 - (5.0 / 3.6) ** 2) / (2.0 * G * s)


@pytest.mark.parametrize("number", [3, 9])  # the same train from 100 and from 50 km/h
def test_a_wagon_braked_at_150_percent_of_its_weight_fails_by_design_whatever_the_run(number):
    sc = get_scenario(number)  # E402B + 15 Shimmns of 80 t
    c = braked_at(sc.consist(), 150.0, wagons=[5])
    sim = Simulator(c, sc.speed_kmh)
    stop(sim)
    v = sim.verdicts()["adhesion"]
    assert v.status == "FAIL" and [e.number for e in v.exceedances] == [5]
    e = v.exceedances[0]
    assert e.limit == verdicts.ADHESION_LIMIT and e.speed_kmh == 100.0  # its maximum speed
    assert e.value == pytest.approx(_design_tau(sim, 5), abs=1e-5)
    assert verdicts.flags(sim.verdicts())["adhesion_ok"] is False
    # the same value whatever the run: the design check does not depend on the run's speed
    assert sim.limits.design_adhesion[5] == pytest.approx(_design_tau(sim, 5), abs=1e-5)
    # with wheel-slide protection its default limit is 0.15 (an analogy, labelled so)
    wsp = dataclasses.replace(sim.limits, adhesion_limit=np.full(sim.n, 0.15))
    assert sim.verdicts(wsp)["adhesion"].passed is (e.value <= 0.15)
    assert "not verified" in sim.limits.origin["adhesion"]


def test_the_paper_wagons_pass_the_design_check_at_their_maximum_speed(scenario_6):
    sim, _ = scenario_6
    row = sim.verdicts()["adhesion"]
    assert row.status == "PASS"
    for i in (1, 16, 32):
        assert sim.limits.design_adhesion[i] == pytest.approx(_design_tau(sim, i), abs=1e-5)
    # a declared maximum speed changes the check: from 120 km/h the block friction is lower
    vs = list(sim.consist.vehicles)
    vs[1] = dataclasses.replace(vs[1], max_speed_kmh=120.0)
    faster = Simulator(dataclasses.replace(sim.consist, vehicles=tuple(vs)), 100.0)
    assert faster.limits.design_adhesion[1] < sim.limits.design_adhesion[1]
    assert faster.limits.max_speed_kmh[1] == 120.0


def test_the_demand_is_judged_against_the_declared_rail_and_never_changes_the_run():
    sc = get_scenario(6)
    dry = Simulator(sc.consist(), sc.speed_kmh)
    stop(dry)
    assert dry.verdicts()["adhesion_demand"].status == "PASS"
    wet = Simulator(sc.consist(), sc.speed_kmh, rail="wet")
    events = stop(wet)
    row = wet.verdicts()["adhesion_demand"]
    # near the stop the blocks ask more than 0.6 x Curtius-Kniffler: slide expected, a WARN
    assert row.status == "WARN" and "wheel slide expected on a wet rail" in row.note
    assert wet.verdicts().passed  # never a failure
    for e in row.exceedances:
        mu = 0.6 * (7.5 / (e.speed_kmh + 44.0) + 0.161)
        assert e.limit == pytest.approx(mu, abs=1e-3) and e.value > e.limit
    assert any(e.detail["criterion"] == "adhesion_demand" for e in events)
    # the run itself is the dry one, to the bit
    assert wet.stopping_distance_m == dry.stopping_distance_m
    assert np.array_equal(wet.peak_draft_N, dry.peak_draft_N)


def test_every_criterion_states_its_scope_and_source(scenario_6):
    sim, _ = scenario_6
    lines = sim.verdicts().describe()
    for c in sim.verdicts().criteria:
        if c.assessed:
            assert c.rule.scope in "\n".join(lines)
            assert c.origin and f"        source: {c.origin}" in lines
        d = c.as_dict()
        assert d["scope"] == c.rule.scope and d["severity"] in ("FAIL", "WARN", "INFO")


def test_nothing_beyond_a_limit_passes_and_unset_criteria_are_not_assessed():
    sc = get_scenario(1)
    sim = Simulator(with_limits(sc.consist(), adhesion_limit=1.0), sc.speed_kmh)
    assert stop(sim) == []
    table = sim.verdicts()
    assert table.passed and table.status == "PASS" and not table.non_physical
    # stopped, not yet settled: holding and runaway are not assessed yet
    assert [(c.name, c.status) for c in table.criteria] == [
        ("draft_strength", "PASS"), ("buff_strength", "PASS"),
        ("endurable_lcf", "not assessed"), ("buffer_limit_state", "PASS"),
        ("coupler_travel", "PASS"), ("adhesion", "PASS"), ("adhesion_demand", "PASS"),
        ("standstill_holding", "not assessed"), ("runaway", "not assessed"),
        ("wheel_temperature", "PASS")]
    assert table["draft_strength"].worst_value == sim.peak_draft_N.max()
    assert verdicts.flags(table) == {"draft_ok": True, "buff_ok": True, "lcf_ok": True,
                                     "travel_ok": True, "buffers_ok": True,
                                     "adhesion_ok": True, "holding_ok": True,
                                     "runaway_ok": True}
    d = table.as_dict()
    assert d["passed"] and d["criteria"][0]["worst_kN"] == pytest.approx(
        sim.peak_draft_N.max() / 1e3)


def test_a_reset_forgets_the_exceedances():
    sc = get_scenario(7)
    sim = Simulator(with_limits(sc.consist(), buff_strength_N=1e3), sc.speed_kmh)
    first = stop(sim)
    sim.reset()
    assert not sim.verdicts()["buff_strength"].exceedances
    again = stop(sim)
    assert [(e.time_s, e.detail) for e in again] == [(e.time_s, e.detail) for e in first]


@pytest.mark.parametrize("wagons", [10, 32, 40])
@pytest.mark.parametrize("mass_t", [50.0, 80.0])
def test_a_draft_above_the_default_strength_is_always_named(wagons, mass_t):
    # E402B + Shimmns from 40 km/h, the slow end of the range, where light trains
    # snatch: any draft beyond the screw coupling's 850 kN must be a FAIL naming it
    c = consist_from_mapping({"vehicles": [{"type": "E402B"},
                                           {"type": "Shimmns", "count": wagons,
                                            "mass_t": mass_t}]}, "snatch.yaml")
    sim = Simulator(c, 40.0)
    events = stop(sim)
    beyond = set(np.flatnonzero(sim.peak_draft_N > verdicts.DRAFT_STRENGTH_N) + 1)
    named = {e.detail["coupler"] for e in events if e.detail["criterion"] == "draft_strength"}
    assert named == beyond
    assert (sim.verdicts()["draft_strength"].status == "FAIL") == bool(beyond)
    # judged by a 500 kN draft limit (e.g. limits: {draft_strength_kN: 500} in the consist),
    # every coupler above it is named, with its worst force
    strict = dataclasses.replace(sim.limits, draft_strength_N=np.full(wagons, 500e3))
    table = sim.verdicts(strict)["draft_strength"]
    assert {e.number: e.value for e in table.exceedances} == {
        int(j) + 1: sim.peak_draft_N[j] for j in np.flatnonzero(sim.peak_draft_N > 500e3)}


def test_at_rest_the_force_to_hold_is_judged_for_the_train(scenario_6):
    sc = get_scenario(1)
    sim = Simulator(sc.consist(), sc.speed_kmh)
    stop(sim)
    while sim.settled_time_s is None:
        sim.advance(0.5)
    assert sim.verdicts()["standstill_holding"].status == "PASS"
    # a force beyond what the whole train holds (20 MN on wagon 3, e.g. a collision): FAIL,
    # and the train moves
    sim.fext_N[3] = -20e6
    events = sim.advance(0.5).events
    table = sim.verdicts()
    assert table["runaway"].status == "FAIL"
    assert any(e.detail["criterion"] == "runaway" for e in events)


def test_the_watch_judges_every_brake_force_peak_it_skips_as_it_would_again():
    # the watch checks each vehicle's demand against the rail at the kernel's peaks of the
    # brake force, but only at those that changed since its last check: checking every peak
    # of every chunk gives the same records, bit for bit. On a low rail (the demand exceeds
    # its adhesion: the first times count), in 2 s chunks, with a release and a second
    # application, so that peaks fall inside chunks and stay there while the force falls
    from ltd_brake_ros.verdicts import watch as watch_module

    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh, rail="low")
    n = sim.n
    script = {0.0: Commands(emergency=True), 6.0: Commands(), 12.0: Commands(emergency=True)}
    watch, skipped, every, windows = None, 0, None, 0
    while sim.settled_time_s is None:
        sim.advance(2.0, script.get(round(sim.time_s)))
        w, k = sim._state.window.watch, sim._state.kinematics
        if w is not watch:  # a window of its own (the second stop): its records anew
            watch, windows = w, windows + 1
            every = [np.zeros(n), np.zeros(n), np.full(n, np.nan), np.full(n, -1.0),
                     np.zeros(n), np.full(n, -1.0), np.zeros(n), np.zeros(n)]
        for when in (k.peak_brake_fast_time_s, k.peak_brake_slow_time_s):
            skipped += int(np.count_nonzero((when > 0.0) & (when <= sim.time_s - 2.0)))
        watch_module._chunk_vehicles(
            sim.time_s, k.v_m_s, k.brake_force_N, k.peak_brake_fast_time_s,
            k.peak_brake_fast_speed_m_s, k.peak_brake_fast_N, k.peak_brake_slow_time_s,
            k.peak_brake_slow_speed_m_s, k.peak_brake_slow_N, sim.limits.weight_N,
            np.ascontiguousarray(sim.limits.rail_table, float), watch.standstill_m_s, *every,
            -math.inf)
        kept = (watch._rail_ratio, watch._rail_tau, watch._rail_mu, watch._rail_t,
                watch._rail_kmh, watch.first_time_s["adhesion_demand"], watch._mean_end_t,
                watch._mean_end_kmh)
        for a, b in zip(kept, every):
            assert a.tobytes() == b.tobytes()
    assert windows == 2 and skipped > n  # both applications judged; peaks skipped
    assert np.count_nonzero(every[5] >= 0.0) > 0  # beyond the rail's adhesion

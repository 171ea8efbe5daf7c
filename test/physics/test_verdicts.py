"""Strength and adhesion verdicts: limits, events when first exceeded, the table."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ltd_brake_ros import verdicts
from ltd_brake_ros.inputs import consist_from_mapping, get_scenario, load_coupler_lut
from ltd_brake_ros.inputs.consist import VehicleLimits
from ltd_brake_ros.physics.brakes import friction
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
    assert np.all(np.isinf(lim.endurable_lcf_N)) and np.all(lim.adhesion_limit == 0.15)
    assert "EN 15566" in lim.origin["draft_strength"]
    lim = verdicts.train_limits(c, dataclasses.replace(lut, draft_strength_N=1000e3))
    assert np.all(lim.draft_strength_N == 1000e3) and lim.origin["draft_strength"] == \
        "coupler file"
    # vehicle 4 has a weaker draw gear: the couplers on either side of it (4 and 5) take it
    vs = list(c.vehicles)
    vs[4] = dataclasses.replace(vs[4], limits=VehicleLimits(draft_strength_N=600e3,
                                                            adhesion_limit=0.12))
    lim = verdicts.train_limits(dataclasses.replace(c, vehicles=tuple(vs)),
                                dataclasses.replace(lut, draft_strength_N=1000e3))
    assert lim.draft_strength_N.tolist() == [1000e3] * 3 + [600e3] * 2 + [1000e3] * 5
    assert lim.adhesion_limit[4] == 0.12 and lim.adhesion_limit[3] == 0.15
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


def test_adhesion_demand_peaks_as_the_wheels_come_to_rest():
    sc = get_scenario(2)  # 50 t wagons, whose block brakes demand most adhesion at rest
    sim = Simulator(sc.consist(), sc.speed_kmh)
    events = stop(sim)
    v = sim.verdicts()["adhesion"]
    fr = sim.model.friction
    i = 1  # a wagon: full block force long before the stop (t_fill = 5 s, stop ~ 40 s)
    fmax = fr.force_max_N[i]
    at_rest = fmax * friction.block_force_factor(fmax / (1000.0 * fr.blocks[i]),
                                                 int(fr.arrangement[i])) * 0.6
    expected = at_rest / (sim.mass_kg[i] * G)
    assert v.status == "FAIL" and expected > 0.15
    e = next(x for x in v.exceedances if x.number == i)
    assert e.value == pytest.approx(expected, rel=1e-6)
    assert e.speed_kmh == 0.0 and e.time_s == pytest.approx(sim.stop_time_s)
    assert e.first_time_s < e.time_s  # seen already at a chunk end while rolling
    assert any(x.detail["criterion"] == "adhesion" and x.detail["vehicle"] == i
               for x in events)
    # the disc-braked locomotive: mu_eff F_B / (m g), the same at any speed
    loco = fr.mu_disc[0] * fr.force_max_N[0] / (sim.mass_kg[0] * G)
    assert sim._state.watch.adhesion[0] == pytest.approx(loco, rel=1e-3)


def test_nothing_beyond_a_limit_passes_and_unset_criteria_are_not_assessed():
    sc = get_scenario(7)
    sim = Simulator(with_limits(sc.consist(), adhesion_limit=1.0), sc.speed_kmh)
    assert stop(sim) == []
    table = sim.verdicts()
    assert table.passed
    assert [c.status for c in table.criteria] == ["PASS", "PASS", "not assessed", "PASS"]
    assert table["draft_strength"].worst_value == sim.peak_draft_N.max()
    assert verdicts.flags(table) == {"draft_ok": True, "buff_ok": True, "lcf_ok": True,
                                     "adhesion_ok": True}
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

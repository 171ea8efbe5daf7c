"""Wheel slide (an option): the brake force capped by the rail's adhesion, and reported."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ltd_brake_ros.inputs import InputError, get_scenario
from ltd_brake_ros.physics.brakes import adhesion, friction, uic_empirical, wheel_slide
from ltd_brake_ros.physics.constants import G
from ltd_brake_ros.simulator import Commands, Simulator


def stop(sim, chunk_s=0.5, on_chunk=None):
    snap = sim.advance(chunk_s, Commands(emergency=True))
    while sim.stop_time_s is None:
        if on_chunk:
            on_chunk(snap)
        snap = sim.advance(chunk_s)
    return sim


def test_the_named_conditions_follow_their_sources():
    dry, wet, low = (adhesion.condition(c) for c in ("dry", "wet", "low"))
    for v_kmh in (0.0, 30.0, 100.0, 171.0):
        ck = 7.5 / (v_kmh + 44.0) + 0.161  # Curtius-Kniffler
        assert adhesion.mu_of(dry.table, v_kmh / 3.6)[0] == pytest.approx(ck, abs=1e-4)
        assert adhesion.mu_of(wet.table, v_kmh / 3.6)[0] == pytest.approx(0.6 * ck, abs=1e-4)
        assert adhesion.mu_of(low.table, v_kmh / 3.6)[0] == pytest.approx(0.47 * ck, abs=1e-4)
    # the low-adhesion level: about 0.10 at 100 km/h (the 0.1 below which leaves take
    # traction), an assumption and labelled so
    assert adhesion.mu_of(low.table, 100 / 3.6)[0] == pytest.approx(0.10, abs=0.001)
    assert "not verified" in low.source
    # locked wheelsets slide at 0.4 of the adhesion (Polach's ratio, not verified)
    assert low.sliding_ratio == adhesion.SLIDING_RATIO == 0.4
    assert "not verified" in low.sliding_source == adhesion.SLIDING_RATIO_SOURCE
    assert adhesion.condition(None) is adhesion.OFF and not adhesion.OFF.on
    assert adhesion.condition("0.1").table[1, 0] == 0.1
    for bad in ("icy", "0", "1.5"):
        with pytest.raises(ValueError):
            adhesion.condition(bad)
    with pytest.raises(ValueError, match="sliding_ratio"):
        dataclasses.replace(low, sliding_ratio=0.0)
    assert dataclasses.replace(low, sliding_ratio=1.0) != low


def _one_wagon(mu, kind=friction.BRAKE_BLOCKS, ratio=0.4):
    """Friction arrays of one 50 t vehicle on a rail of constant adhesion ``mu``."""
    weight = 50e3 * G
    return friction.FrictionArrays(
        np.array([kind]), np.array([16.0]), np.array([friction.ARR_BG]), np.array([0.25]),
        np.array([300e3]), np.array([100e3]), np.array([weight]), np.array([[0.0], [mu]]),
        ratio), weight


@pytest.mark.parametrize("kind, static_per_scale", [(friction.BRAKE_BLOCKS, 0.6),
                                                     (friction.BRAKE_DISC, 1.0)])
def test_a_locked_wheelset_rolls_again_only_below_the_sliding_force(kind, static_per_scale):
    fr, weight = _one_wagon(0.1, kind)
    # it stays locked while the brake's static friction (the kinetic law at rest: 0.6 x the
    # scale for cast-iron blocks, the disc force itself) holds the rail's 0.4 x 0.1 m g
    edge = 0.4 * 0.1 * weight / static_per_scale
    slide = np.empty(1)
    for scale, factor in ((edge * (1 + 1e-9), 0.4), (edge * (1 - 1e-9), 0.0)):
        released = wheel_slide.step_factors(np.array([True]), np.array([20.0]),
                                            np.array([scale]), fr, slide)
        assert slide[0] == factor and released == (factor == 0.0)
    # a rolling wheelset does not start a step locked, however hard it is braked
    assert not wheel_slide.step_factors(np.array([False]), np.array([20.0]),
                                        np.array([10 * weight]), fr, slide)
    assert slide[0] == 0.0


def test_a_wheelset_locks_after_a_step_at_the_adhesion_limit_and_not_at_rest():
    fr, weight = _one_wagon(0.1)
    cases = [  # (step's factor, speed m/s, force, locked before) -> (slid, locked after)
        ((0.0, 20.0, 0.1 * weight, False), (True, True)),     # capped: locks
        ((0.0, 20.0, 0.099 * weight, False), (False, False)),  # below the cap: rolls
        ((0.4, 20.0, 0.04 * weight, True), (True, True)),     # slides on
        ((0.4, 1e-6, 0.04 * weight, True), (True, False)),    # came to rest: no longer slides
    ]
    for (factor, speed, force, before), (slid, after) in cases:
        locked = np.array([before])
        got = wheel_slide.after_step(0, speed, force, np.array([factor]), fr, 1e-5, locked)
        assert got == (slid, after != before) and locked[0] == after


def test_a_condition_that_never_binds_changes_nothing():
    sc = get_scenario(6)  # demand at most ~0.22 near rest, below the dry rail's 0.33
    off = stop(Simulator(sc.consist(), sc.speed_kmh))
    dry = stop(Simulator(sc.consist(), sc.speed_kmh, adhesion="dry"))
    assert dry.wheel_slides() == [] and off.wheel_slides() == []
    assert dry.stopping_distance_m == off.stopping_distance_m
    np.testing.assert_array_equal(dry.peak_draft_N, off.peak_draft_N)


def test_a_low_adhesion_caps_every_brake_force_and_lengthens_the_stop():
    sc = get_scenario(6)
    mu = 0.08
    weight = np.array([v.mass_kg for v in sc.consist().vehicles]) * G
    over = []

    def check(snap):
        moving = snap.speed_m_s > 1e-3
        over.append(float(np.max((snap.brake_force_N - mu * weight)[moving], initial=0.0)))
    sim = stop(Simulator(sc.consist(), sc.speed_kmh, adhesion=mu), on_chunk=check)
    # capped within the Newton tolerance (1e-6 of the weight)
    assert max(over) <= 1e-6 * weight.max()
    # the train cannot decelerate faster than the adhesion and the running resistance allow
    # (under 0.01 g for these wagons): v^2 / (2 g (0.08 + 0.01))
    v = sc.speed_kmh / 3.6
    assert sim.stopping_distance_m > v * v / (2 * G * (mu + 0.01))
    slides = sim.wheel_slides()
    # every wagon slid; the disc-braked locomotive (about 0.05 m g) never asks that much
    assert {s["vehicle"] for s in slides} == set(range(1, sim.n))
    for s in slides:
        assert 0.0 <= s["first_s"] and 0.0 < s["duration_s"] <= sim.stop_time_s


def test_wet_rail_from_the_command_line(capsys, tmp_path):
    from ltd_brake_ros.cli.main import main

    assert main(["simulate", "--scenario", "6", "--adhesion", "wet", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # on a wet rail every wagon locks in the last seconds of the stop (demand up to ~0.22)
    assert out["adhesion"] == "wet" and len(out["wheel_slides"]) == 32
    assert out["sliding_ratio"] == 0.4 and "not verified" in out["sliding_ratio_source"]
    assert main(["simulate", "--scenario", "6", "--adhesion", "wet"]) == 0
    assert "wheel slide      adhesion wet" in capsys.readouterr().out
    # the low-adhesion curve and the sliding friction are assumptions, and say so
    assert main(["simulate", "--scenario", "6", "--adhesion", "low"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("wheel slide"))
    assert line.count("not verified") == 2 and "0.4 x mu" in line
    assert main(["simulate", "--scenario", "6", "--adhesion", "icy"]) == 2
    err = capsys.readouterr().err
    assert "--adhesion" in err and "icy" in err and "Traceback" not in err
    curve = tmp_path / "curve.yaml"
    curve.write_text("speed_kmh: [0, 50, 100]\nmu: [0.2, 0.15]\nsource: test\n")
    assert main(["simulate", "--scenario", "6", "--adhesion", str(curve)]) == 2
    assert "mu" in capsys.readouterr().err
    curve.write_text("speed_kmh: [0, 50, 100]\nmu: [0.2, 0.15, 0.1]\nsource: a test curve\n"
                     "sliding_ratio: 0.5\n")
    assert main(["simulate", "--scenario", "6", "--adhesion", str(curve), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["adhesion"], out["sliding_ratio"], out["sliding_ratio_source"]) == (
        "curve", 0.5, "given")
    curve.write_text("speed_kmh: [0, 100]\nmu: [0.2, 0.1]\nsource: a test\nsliding_ratio: 0\n")
    assert main(["simulate", "--scenario", "6", "--adhesion", str(curve)]) == 2
    assert "sliding_ratio" in capsys.readouterr().err


def test_a_curve_file_must_name_its_source(tmp_path):
    from ltd_brake_ros.inputs.adhesion import load_adhesion

    p = tmp_path / "c.yaml"
    p.write_text("speed_kmh: [0, 100]\nmu: [0.2, 0.1]\n")
    with pytest.raises(InputError, match="source"):
        load_adhesion(p)


def _released_while_sliding(chunk_s, mu=0.07, release_s=8.0, end_s=32.0, on_chunk=None):
    """Scenario 6 on a rail of constant ``mu``: emergency at 0, released at ``release_s``."""
    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh, adhesion=mu)
    snaps = []
    while sim.time_s < end_s - 1e-9:
        cmd = Commands(emergency=sim.time_s < release_s - 1e-9)
        snaps.append(sim.advance(chunk_s, cmd))
        if on_chunk:
            on_chunk(sim, snaps[-1])
    return sim, snaps


def test_wheelsets_released_while_sliding_roll_again_when_the_brake_no_longer_holds_them():
    # mu 0.07, k 0.4: a wagon's wheelsets lock within ~3 s of the emergency command; the
    # release then lowers the block force: they slide on, the rail taking 0.028 m g, until
    # the static block friction 0.6 x scale falls below that, then roll with the kinetic
    # force (Karwatzki, Eq. 8-10), and never lock again while the brake releases
    mu, k = 0.07, adhesion.SLIDING_RATIO
    sc = get_scenario(6)
    weight = np.array([v.mass_kg for v in sc.consist().vehicles]) * G
    seen = {"locked before release": 0, "hysteresis": 0, "rolled again": 0}
    was_rolling = np.zeros(weight.size, bool)

    def check(sim, snap):
        fr = sim.model.friction
        for i in range(1, sim.n):  # the wagons (the locomotive never asks 0.07)
            scale = friction.force_scale(fr.kind[i], fr.blocks[i], fr.arrangement[i],
                                         fr.mu_disc[i], snap.block_force_N[i])
            static = 0.6 * scale
            kinetic = friction.retarding_force(fr.kind[i], snap.speed_m_s[i], scale)[0]
            sliding = k * mu * weight[i]
            force = snap.brake_force_N[i]
            if snap.time_s <= 8.0:
                if snap.time_s >= 7.0:  # the tail applied by then: every wagon locked
                    assert force == pytest.approx(sliding, rel=1e-6)
                    seen["locked before release"] += 1
            elif static >= sliding * (1 + 1e-9) and not was_rolling[i]:
                assert force == pytest.approx(sliding, rel=1e-6), (i, snap.time_s)
                # its kinetic force is below the adhesion: a rolling wheelset would hold
                seen["hysteresis"] += kinetic < mu * weight[i]
            elif static < sliding * (1 - 1e-9):
                assert force == pytest.approx(kinetic, rel=1e-6), (i, snap.time_s)
                was_rolling[i] = True
                seen["rolled again"] += 1
    _released_while_sliding(0.1, mu, on_chunk=check)
    assert all(seen.values()), seen


def test_wheel_slide_does_not_depend_on_the_chunks():
    one, a = _released_while_sliding(1.0)
    many, b = _released_while_sliding(0.05)
    b = b[19::20]  # the same times
    assert [s.time_s for s in a] == pytest.approx([s.time_s for s in b], abs=1e-9)
    for x, y in zip(a, b):
        for name in ("position_m", "speed_m_s", "brake_force_N", "coupler_force_N"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name), err_msg=name)
    assert one.wheel_slides() == many.wheel_slides() and len(one.wheel_slides()) == 32
    np.testing.assert_array_equal(one.brake_energy_J, many.brake_energy_J)


def test_locked_wheelsets_do_not_heat_their_blocks():
    # at mu 0.05 every wagon locks within ~2.5 s and slides to the stop: its blocks took only
    # the work before, at most mu m g times the initial speed over that time
    sc = get_scenario(6)
    off = stop(Simulator(sc.consist(), sc.speed_kmh))
    low = stop(Simulator(sc.consist(), sc.speed_kmh, adhesion=0.05))
    weight = np.array([v.mass_kg for v in sc.consist().vehicles]) * G
    v0 = sc.speed_kmh / 3.6
    first = {s["vehicle"]: s["first_s"] for s in low.wheel_slides()}
    for i in range(1, low.n):
        assert low.brake_energy_J[i] <= 0.05 * weight[i] * v0 * (first[i] + 0.01)
        # braked to rest by its blocks, a wagon's share of the kinetic energy is ~10x more
        assert off.brake_energy_J[i] > 10 * low.brake_energy_J[i]
    assert np.nanmax(low.temperatures()[0][1:]) < np.nanmax(off.temperatures()[0][1:])

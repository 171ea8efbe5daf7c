"""Wheel slide (an option): the brake force capped by the rail's adhesion, and reported."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ltd_brake_ros.inputs import InputError, get_scenario
from ltd_brake_ros.physics.brakes import adhesion
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
    dry, wet = adhesion.condition("dry"), adhesion.condition("wet")
    for v_kmh in (0.0, 30.0, 100.0, 171.0):
        ck = 7.5 / (v_kmh + 44.0) + 0.161  # Curtius-Kniffler
        assert adhesion.mu_of(dry.table, v_kmh / 3.6)[0] == pytest.approx(ck, abs=1e-4)
        assert adhesion.mu_of(wet.table, v_kmh / 3.6)[0] == pytest.approx(0.6 * ck, abs=1e-4)
    assert adhesion.condition(None) is adhesion.OFF and not adhesion.OFF.on
    assert adhesion.condition("0.1").table[1, 0] == 0.1
    for bad in ("icy", "0", "1.5"):
        with pytest.raises(ValueError):
            adhesion.condition(bad)


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
    # on a wet rail every wagon slides in the last ~2 s of the stop (demand up to ~0.22)
    assert out["adhesion"] == "wet" and len(out["wheel_slides"]) == 32
    assert main(["simulate", "--scenario", "6", "--adhesion", "wet"]) == 0
    assert "wheel slide      adhesion wet" in capsys.readouterr().out
    assert main(["simulate", "--scenario", "6", "--adhesion", "icy"]) == 2
    err = capsys.readouterr().err
    assert "--adhesion" in err and "icy" in err and "Traceback" not in err
    curve = tmp_path / "curve.yaml"
    curve.write_text("speed_kmh: [0, 50, 100]\nmu: [0.2, 0.15]\nsource: test\n")
    assert main(["simulate", "--scenario", "6", "--adhesion", str(curve)]) == 2
    assert "mu" in capsys.readouterr().err
    curve.write_text("speed_kmh: [0, 50, 100]\nmu: [0.2, 0.15, 0.1]\nsource: a test curve\n")
    assert main(["simulate", "--scenario", "6", "--adhesion", str(curve), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["adhesion"] == "curve"


def test_a_curve_file_must_name_its_source(tmp_path):
    from ltd_brake_ros.inputs.adhesion import load_adhesion

    p = tmp_path / "c.yaml"
    p.write_text("speed_kmh: [0, 100]\nmu: [0.2, 0.1]\n")
    with pytest.raises(InputError, match="source"):
        load_adhesion(p)

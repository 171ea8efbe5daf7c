"""The brake-pipe model's validated range, stated in its contract and repeated by every output,
and its hose loss taken from its source."""
from __future__ import annotations

import dataclasses
import json

import pytest

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import consist_from_mapping, load_brake_params
from ltd_brake_ros.physics import brakes
from ltd_brake_ros.physics.brakes import uic_pipe

PIPE = "brake_params/uic_brake_pipe.yaml"


def _train(wagons: int, tail_loco: bool = False):
    vehicles = [{"type": "E402B"}, {"type": "Shimmns", "count": wagons, "mass_t": 80.0}]
    if tail_loco:
        vehicles.append({"type": "E402B"})
    return consist_from_mapping({"name": f"{wagons} wagons", "vehicles": vehicles}, "<test>")


def test_the_range_is_the_longest_run_of_pipe_from_a_drivers_brake_valve():
    pipe = load_brake_params(PIPE)
    inside, outside = _train(117), _train(133)  # 1 498 m and 1 701 m over buffers
    assert inside.length_m < uic_pipe.MAX_VENTED_LENGTH_M < outside.length_m
    assert brakes.validity(inside, pipe) == []
    warning, = brakes.validity(outside, pipe)
    assert "outside its validated range" in warning and "vented from one end" in warning
    # a second locomotive at the tail repeating the valve by radio halves the longest run
    both_ends = _train(132, tail_loco=True)
    assert brakes.validity(both_ends, pipe) != []
    assert brakes.validity(both_ends, dataclasses.replace(pipe, distributed_power=True)) == []
    # the paper's empirical brake has a range of its own: trains up to 500 m
    warning, = brakes.validity(outside, load_brake_params())
    assert "empirical brake model outside its validated range" in warning and "500 m" in warning


def test_every_output_of_a_run_outside_the_range_says_so(tmp_path, capsys):
    path = tmp_path / "long.yaml"
    path.write_text("name: long\nvehicles:\n  - {type: E402B}\n"
                    "  - {type: Shimmns, count: 133, mass_t: 80}\n")
    base = ["simulate", "--consist", str(path), "--speed-kmh", "30", "--params", PIPE]
    assert main(base) == 0
    text = capsys.readouterr().out
    assert sum("outside its validated range" in line and line.startswith("warning")
               for line in text.splitlines()) == 1
    # beyond both brake models' ranges: the output says that none covers the train
    assert sum("no brake model covers this train" in line and line.startswith("warning")
               for line in text.splitlines()) == 1
    assert main(base + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["warnings"]) == 2 and "1500 m" in out["warnings"][0]
    assert "no brake model covers" in out["warnings"][1]
    assert main(base + ["--record", str(tmp_path / "rec")]) == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path / "rec"), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["warnings"] == out["warnings"]
    assert main(["report", str(tmp_path / "rec")]) == 0
    assert "Warning: brake-pipe model outside its validated range" in capsys.readouterr().out
    # inside the range: no warning at all
    assert main(["simulate", "--scenario", "6", "--params", PIPE, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == []


def test_diagnostics_warn_for_a_run_outside_the_range():
    from ltd_brake_ros.plant.diagnostics import WARN, plant_status
    from ltd_brake_ros.simulator import Simulator

    sim = Simulator(_train(133), 30.0, load_brake_params(PIPE))
    status = plant_status(sim, state="running")
    assert status.level == WARN and "validated range" in status.message
    assert "1500 m" in status.values["model_validity"]
    fine = plant_status(Simulator(_train(20), 30.0, load_brake_params(PIPE)), state="running")
    assert fine.values["model_validity"] == "inside the validated ranges"


def test_the_hose_loss_is_traindys_referred_to_this_bore():
    p = uic_pipe.Params()
    # two losses of 3 per junction at 35.6 mm bore carry the same pressure drop at the same
    # mass flow as K (35.6 / D)^4 ... referred to the 32 mm pipe: K = 6 (32 / 35.6)^4
    assert p.hose_loss_coefficient == pytest.approx(6 * (p.pipe_diameter_m / 0.0356) ** 4,
                                                    abs=0.005)
    assert p.pipe_roughness_m == 4.6e-5  # commercial steel, as TrainDy
    shipped = load_brake_params(PIPE)
    assert shipped.hose_loss_coefficient == p.hose_loss_coefficient
    assert shipped.pipe_roughness_m == p.pipe_roughness_m

"""A plant run built from parameter values, and a reset that rebuilds it, without ROS."""
from __future__ import annotations

import pytest

from plant_helpers import Log
from ltd_brake_ros.plant.pacing import Clock
from ltd_brake_ros.plant.run import PlantRun, reset_run
from ltd_brake_ros.plant.runner import PlantRunner
from ltd_brake_ros.plant.settings import PlantSettings, StartupError

#: Parameter values as sim_node declares them by default (config/sim_node.yaml).
VALUES = {"consist": "scenario_7", "initial_speed_kmh": -1.0, "brake_params_file": "",
          "coupler_lut_file": "", "track_file": "", "start_chainage_m": 0.0, "chunk_s": 0.02,
          "tolerance_m_s": 0.0, "real_time_factor": 0.0, "max_catch_up_s": 0.2,
          "lockstep": True, "steps_per_call": 1, "publish_every": 1, "auto_brake_at_s": -1.0,
          "max_sim_time_s": -1.0, "shutdown_after_stop_s": -1.0}


@pytest.fixture(scope="module")
def run():
    return PlantRun.build(VALUES)


def test_a_run_is_the_train_its_values_name_with_its_settings(run):
    assert run.sim.n == run.spec.consist.n and run.sim.time_s == 0.0
    assert run.settings(follow_clock=True) == PlantSettings(
        chunk_s=0.02, real_time_factor=0.0, lockstep=True, follow_clock=True)
    assert run.describe().startswith(f"{run.spec.consist.name}: {run.sim.n} vehicles, ")
    assert run.describe().endswith(f"at {run.spec.speed_kmh:g} km/h")
    assert run.start_line(run.settings(), "publish") == \
        f"{run.describe()}; chunk 0.02 s, lock-step, publishes /clock"
    # the empirical brake model has no further state: the blocks' and wheels' temperature only
    assert run.extra_topics() == ["vehicles/block_temperature", "vehicles/wheel_temperature"]
    meta = run.metadata()
    assert meta["parameters"]["consist"] == "scenario_7"


def test_the_brake_pipe_model_adds_its_pressures_as_topics():
    pipe = PlantRun.build(VALUES | {"brake_params_file": "brake_params/uic_brake_pipe.yaml"})
    assert pipe.extra_topics() == ["vehicles/brake_pipe_pressure",
                                   "vehicles/brake_cylinder_pressure",
                                   "vehicles/block_temperature", "vehicles/wheel_temperature"]


def test_rebuilt_only_when_a_value_changed_and_refused_naming_the_parameter(run):
    assert run.rebuilt({"consist": "scenario_7", "initial_speed_kmh": -1.0}) is None
    other = run.rebuilt({"consist": "scenario_6", "initial_speed_kmh": 50.0})
    assert other.spec.speed_kmh == 50.0 and other.sim.n != run.sim.n
    assert other.values == VALUES | {"consist": "scenario_6", "initial_speed_kmh": 50.0}
    with pytest.raises(StartupError) as err:
        run.rebuilt({"brake_params_file": "no/such/file.yaml"})
    assert err.value.parameter == "brake_params_file"


def test_reset_restarts_rebuilds_or_refuses_and_the_old_run_goes_on(run):
    log, prepared = Log(), []
    runner = PlantRunner(run.sim, run.settings(), publish_state=lambda snap: None,
                         publish_status=lambda status: None, log=log, clock=Clock())
    runner.start()
    try:
        assert runner.result(runner.step())[0]
        ok, text, same = reset_run(runner, run, {"consist": "scenario_7"}, prepared.append, log)
        assert (ok, same, prepared, runner.sim) == (True, run, [], run.sim)
        assert text.startswith("reset to the initial state") and run.sim.time_s == 0.0

        ok, text, same = reset_run(runner, run, {"track_file": "missing.csv"},
                                   prepared.append, log)
        assert (ok, same, runner.sim) == (False, run, run.sim)
        assert text.startswith("not reset: parameter track_file: ") and \
            text.endswith("; the run goes on as it was")
        assert log.at("error") == [text]

        ok, text, new = reset_run(runner, run, {"consist": "scenario_6"}, prepared.append, log)
        assert ok and new is not run and prepared == [new] and runner.sim is new.sim
        assert text.endswith(f"; new run: {new.describe()}")
        assert log.at("info")[-1] == f"new run: {new.describe()}"
    finally:
        runner.close()


def test_run_inputs_are_checked_together_as_a_reset_would_use_them():
    from ltd_brake_ros.plant.run import check_run_inputs

    good = {"consist": "scenario_6", "initial_speed_kmh": -1.0, "brake_params_file": "",
            "coupler_lut_file": "", "track_file": "", "start_chainage_m": 0.0}
    assert check_run_inputs(good) is None
    assert check_run_inputs(dict(good, consist="scenario_99")).startswith("consist:")
    problem = check_run_inputs(dict(good, consist="consists/e402b_10_shimmns_80t.yaml"))
    assert problem.startswith("initial_speed_kmh:")  # a file brings no speed of its own
    assert check_run_inputs(dict(good, coupler_lut_file="nope.yaml")).startswith(
        "coupler_lut_file:")

"""Overcharge and the driver's brake valve positions: commands, brake command events, scripts."""
import numpy as np
import pytest

from ltd_brake_ros.inputs import InputError, consist_from_mapping, load_command_script
from ltd_brake_ros.inputs.commands import FIRST_STEP_DEMAND, VALVE_POSITIONS, valve_position
from ltd_brake_ros.physics.brakes.base import EMERGENCY, OVERCHARGE, SERVICE
from ltd_brake_ros.simulator import Commands, Simulator


def wagons(n=5):
    return consist_from_mapping({"name": "t", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": n, "mass_t": 80.0}]}, "<test>")


def issued(sim):
    """(level, kind) of every brake command event the simulator issued so far."""
    ev = sim.state.events
    return [(float(ev.level[k]), int(ev.kind[k])) for k in range(ev.count)]


@pytest.mark.parametrize("value", ["yes", 1, None])
def test_overcharge_must_be_a_bool(value):
    with pytest.raises(ValueError, match="overcharge"):
        Commands(overcharge=value)


def test_overcharge_is_a_release_kind_only_when_released_and_a_change_of_it_is_a_command():
    sim = Simulator(wagons(), 60.0)
    sim.advance(0.5, Commands(brake_demand=0.5))
    assert sim.state.brake_command == (0.5, SERVICE)
    sim.advance(0.5, Commands(brake_demand=0.5, overcharge=True))  # braking: no overcharge
    assert sim.state.brake_command == (0.5, SERVICE)
    sim.advance(0.5, Commands(overcharge=True))
    assert sim.state.brake_command == (0.0, OVERCHARGE)
    sim.advance(0.5, Commands())  # only the flag changes: back to running pressure
    assert sim.state.brake_command == (0.0, SERVICE)
    sim.advance(0.5, Commands(emergency=True, overcharge=True))
    assert sim.state.brake_command == (1.0, EMERGENCY)
    # (events every vehicle has received are dropped)
    assert issued(sim)[-3:] == [(0.0, OVERCHARGE), (0.0, SERVICE), (1.0, EMERGENCY)]


def test_the_empirical_model_releases_with_overcharge_exactly_as_without():
    runs = []
    for overcharge in (False, True):
        sim = Simulator(wagons(), 60.0)
        sim.advance(6.0, Commands(brake_demand=0.6))
        forces = [sim.advance(0.5, Commands(overcharge=overcharge)).brake_force_N
                  for _ in range(20)]
        runs.append(np.array(forces))
    assert runs[0][0].sum() > 0.0 and runs[0][-1].sum() < 0.5 * runs[0][0].sum()  # releasing
    np.testing.assert_array_equal(runs[0], runs[1])


def test_valve_positions_map_onto_the_commands():
    c = Commands(brake_demand=0.7, traction=0.2)
    applied = {name: Commands(**{**vars(c), **valve_position(name)}) for name in VALVE_POSITIONS}
    assert applied["release_overcharge"] == Commands(traction=0.2, overcharge=True)
    assert applied["running"] == Commands(traction=0.2)
    assert applied["lap"] == c  # holds the present demand
    assert applied["service"] == Commands(brake_demand=FIRST_STEP_DEMAND, traction=0.2)
    assert applied["full_service"] == Commands(brake_demand=1.0, traction=0.2)
    assert applied["emergency"] == Commands(emergency=True, brake_demand=0.7, traction=0.2)
    # UIC 541-03 first step 0.4-0.5 bar of the 1.5 bar full service reduction (UIC 540)
    assert 0.4 / 1.5 <= FIRST_STEP_DEMAND <= 0.5 / 1.5
    assert valve_position(" Full_Service ") == VALVE_POSITIONS["full_service"]
    assert valve_position("release") is None and valve_position(3) is None


def write(tmp_path, text):
    p = tmp_path / "script.yaml"
    p.write_text(text)
    return p


def test_scripts_take_valve_positions(tmp_path):
    p = write(tmp_path, "commands:\n"
                        "  - {t_s: 0, driver_brake_valve: service, traction: 0.0}\n"
                        "  - {t_s: 5, driver_brake_valve: lap}\n"
                        "  - {t_s: 9, driver_brake_valve: release_overcharge}\n"
                        "  - {t_s: 20, emergency: true}\n")
    steps = load_command_script(p).steps
    assert steps == ((0.0, {"emergency": False, "brake_demand": FIRST_STEP_DEMAND,
                            "overcharge": False, "traction": 0.0}),
                     (5.0, {}),
                     (9.0, {"emergency": False, "brake_demand": 0.0, "overcharge": True}),
                     (20.0, {"emergency": True}))


@pytest.mark.parametrize("entry,reason", [
    ("{t_s: 0, driver_brake_valve: release}",
     "commands[0].driver_brake_valve: unknown position 'release'; expected one of "
     "release_overcharge, running, lap, service, full_service, emergency"),
    ("{t_s: 0, driver_brake_valve: service, brake_demand: 0.5}",
     "commands[0].driver_brake_valve: give either a valve position or brake_demand, not both"),
    ("{t_s: 0, overcharge: true}", "commands[0].overcharge: unknown field; expected one of "
     "brake_demand, driver_brake_valve, emergency, t_s, traction"),
])
def test_a_bad_valve_entry_is_one_line_naming_the_field(tmp_path, entry, reason):
    p = write(tmp_path, f"commands:\n  - {entry}\n")
    with pytest.raises(InputError) as err:
        load_command_script(p)
    msg = str(err.value)
    assert reason in msg and str(p) in msg and "\n" not in msg


def test_with_the_brake_pipe_model_each_position_gives_its_pipe_reduction():
    # README, sim_node's driver's brake valve: running pressure 5.0 bar, first service step
    # 0.45 bar (UIC 541-03: 0.4-0.5), full service 1.5 bar (UIC 540), emergency vents the pipe
    from ltd_brake_ros.inputs import load_brake_params

    # and the release with overcharge fills it towards 5.4 bar (the file's overcharge_bar)
    pipe = load_brake_params("brake_params/uic_brake_pipe.yaml")
    expected = {"running": (5.0, 5.0, 0.0, 0.0), "release_overcharge": (5.3, 5.4, 0.0, 0.0),
                "service": (4.55, 4.55, 1.1, 1.35), "full_service": (3.5, 3.5, 3.75, 3.8),
                "emergency": (0.0, 0.0, 3.75, 3.8)}
    for position, (pipe_lo, pipe_hi, cyl_lo, cyl_hi) in expected.items():
        sim = Simulator(wagons(10), 60.0, pipe)
        commands = Commands(**valve_position(position))
        for _ in range(25):
            snap = sim.advance(1.0, commands)
        p = snap.extras["brake_pipe_pressure_Pa"][1:] / 1e5  # the wagons [bar]
        c = snap.extras["brake_cylinder_pressure_Pa"][1:] / 1e5
        assert pipe_lo - 0.02 <= p.min() and p.max() <= pipe_hi + 0.02, (position, p)
        assert cyl_lo <= c.min() and c.max() <= cyl_hi + 1e-9, (position, c)


def test_a_script_entry_is_recorded_as_the_messages_that_make_it():
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Bool, Float64, String

    from ltd_brake_ros.recording.plant_topics import command_messages

    def decoded(change):
        types = {"brake_command": Bool, "brake_demand": Float64, "traction_command": Float64,
                 "driver_brake_valve": String}
        return [(topic, deserialize_message(data, types[topic]).data)
                for topic, data in command_messages(change)]

    for position in VALVE_POSITIONS:
        if position != "lap":  # lap changes nothing: no message
            assert decoded(valve_position(position) | {"traction": 0.5}) == [
                ("traction_command", 0.5), ("driver_brake_valve", position)]
    assert decoded({"emergency": True, "brake_demand": 0.4}) == [
        ("brake_command", True), ("brake_demand", 0.4)]
    assert decoded({}) == []
    with pytest.raises(KeyError, match="overcharge"):
        command_messages({"overcharge": True})

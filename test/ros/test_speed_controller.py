"""The closed-loop example: ``examples/speed_controller.py`` drives sim_node in lock-step.

Scenario 6's train (E402B + 32 loaded Shimmns, 1689 t) starts at 80 km/h; the controller brings
it to 40 km/h and holds it. Both run as separate processes, the plant records the run, and the
checks read the recording: the speed trajectory, the commands, and that every command reached the
plant between the state it was computed from and the next chunk (deterministic lock-step).
"""
from __future__ import annotations

import functools
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import pytest
# a broken ROS installation fails these tests; it never skips them
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64, Float64MultiArray

from conftest import executable
from ltd_brake_ros.recording.bag import read_bag

pytestmark = pytest.mark.ros

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "speed_controller.py"
NS = "/speed_control"
CHUNK_S = 0.1            # the control period: one ~/step advances one chunk
DURATION_S = 150.0       # simulated
START_KMH, TARGET_KMH = 80.0, 40.0

# Reaching the band: the dynamic brake alone (E402B: 150 kN, config/vehicles.yaml; P/v is
# larger below 96 km/h) takes m * dv / F = 1689 t * (80 - 42) km/h / 150 kN = 119 s, running
# resistance neglected. The controller adds the service brake while the dynamic brake is
# saturated; it must at least halve that time.
TRAIN_MASS_KG = (89.0 + 32 * 50.0) * 1e3
DYNAMIC_BRAKE_N = 150e3
DB_ONLY_S = TRAIN_MASS_KG * (START_KMH - TARGET_KMH - 2.0) / 3.6 / DYNAMIC_BRAKE_N
REACH_BOUND_S = 0.5 * DB_ONLY_S


@functools.cache
def load_example():
    """The example as a module (it is a script, not part of the package)."""
    spec = importlib.util.spec_from_file_location("speed_controller_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def default_law(**overrides):
    """The example's control law with its default parameters, except ``overrides``."""
    example = load_example()
    values = {name: default for name, (default, _, _) in example.PARAMETERS.items()}
    return example.speed_law(values | overrides)


def recorded_run(bag: Path) -> dict[str, np.ndarray]:
    """Head speed [m/s] and the received commands from the recording, each with its time [s]."""
    series = {"speed": [], "traction": [], "brake": []}
    topics = {f"{NS}/vehicles/speed": ("speed", Float64MultiArray),
              f"{NS}/traction_command": ("traction", Float64),
              f"{NS}/brake_demand": ("brake", Float64)}
    for topic, _, log_time_ns, data in read_bag(bag):
        if topic in topics:
            name, msg_type = topics[topic]
            msg = deserialize_message(data, msg_type)
            value = msg.data[0] if name == "speed" else msg.data
            series[name].append((log_time_ns, value))
    out = {}
    for name, rows in series.items():
        assert rows, f"no {name} messages recorded"
        stamps, values = zip(*rows)
        out[f"{name}_ns"] = np.array(stamps, dtype=np.int64)
        out[name] = np.array(values)
    return out


def effort_sign_changes(traction: np.ndarray, brake: np.ndarray) -> int:
    """Switches between traction and braking (dynamic or service), coasting not counted."""
    effort = np.where(brake > 0.0, -1.0, np.sign(traction))
    signs = effort[effort != 0.0]
    return int(np.count_nonzero(signs[1:] != signs[:-1]))


def test_speed_law_splits_effort_without_windup():
    law = default_law()
    target = law.target_m_s
    # far too fast: full dynamic brake plus service brake, no integral wind-up
    for _ in range(100):
        traction, brake = law.update(target + 10.0, CHUNK_S)
        assert traction == -1.0 and brake == law.max_brake_demand
    assert law.integral == 0.0
    # a little too fast: dynamic brake only
    traction, brake = law.update(target + 0.2, CHUNK_S)
    assert -1.0 < traction < 0.0 and brake == 0.0
    # on target with no integral: inside the deadband, coasting
    law.integral = 0.0
    assert law.update(target, CHUNK_S) == (0.0, 0.0)


def test_speed_controller_brings_the_train_to_40_kmh_and_holds_it(processes, tmp_path):
    bag = tmp_path / "run"
    wall = time.monotonic()
    plant = processes.start(
        executable("sim_node"), "--ros-args", "-r", f"__ns:={NS}", "-r", f"/clock:={NS}/clock",
        "-p", "consist:=scenario_6", "-p", f"initial_speed_kmh:={START_KMH}",
        "-p", "lockstep:=true", "-p", f"chunk_s:={CHUNK_S}",
        "-p", "record:=true", "-p", f"record_dir:={bag}", name="sim_node")
    controller = processes.start(
        sys.executable, str(EXAMPLE), "--ros-args", "-r", f"__ns:={NS}",
        "-p", f"target_speed_kmh:={TARGET_KMH}", "-p", f"duration_s:={DURATION_S}",
        name="speed_controller")
    status = controller.wait(timeout_s=120)
    out = controller.output()
    assert status == 0, out
    assert "Traceback" not in out, out
    assert plant.stop() == 0, plant.output()  # SIGINT: the recording is closed
    wall = time.monotonic() - wall

    run = recorded_run(bag)
    steps = round(DURATION_S / CHUNK_S)
    step_ns = np.arange(1, steps + 1, dtype=np.int64) * round(CHUNK_S * 1e9)

    # Lock-step: the plant recorded the initial state and one state per step, and each command
    # once, received after the state it was computed from and before the next chunk ran
    assert np.array_equal(run["speed_ns"], np.concatenate(([0], step_ns)))
    assert np.array_equal(run["traction_ns"], step_ns)
    assert np.array_equal(run["brake_ns"], step_ns)
    # ... and the commands are exactly the control law applied to the recorded states
    law = default_law(target_speed_kmh=TARGET_KMH)
    expected = np.array([law.update(v, CHUNK_S) for v in run["speed"][1:]])
    np.testing.assert_array_equal(run["traction"], expected[:, 0])
    np.testing.assert_array_equal(run["brake"], expected[:, 1])

    t = run["speed_ns"] / 1e9
    deviation = run["speed"] * 3.6 - TARGET_KMH
    within_2 = np.flatnonzero(np.abs(deviation) <= 2.0)
    within_1_5 = np.flatnonzero(np.abs(deviation) <= 1.5)
    assert within_2.size and within_1_5.size, f"never near {TARGET_KMH} km/h: {deviation[-1]}"
    t_reach = t[within_2[0]]
    summary = (f"reached {TARGET_KMH:g} +- 2 km/h at t = {t_reach:.1f} s (bound "
               f"{REACH_BOUND_S:.0f} s), +- 1.5 km/h at t = {t[within_1_5[0]]:.1f} s; then "
               f"{deviation[within_1_5[0]:].min():+.2f} to {deviation[within_1_5[0]:].max():+.2f}"
               f" km/h; final {deviation[-1]:+.3f} km/h; wall {wall:.1f} s")
    print(summary)
    assert t_reach <= REACH_BOUND_S, summary
    assert np.all(np.abs(deviation[within_2[0]:]) <= 2.0), summary
    assert np.all(np.abs(deviation[within_1_5[0]:]) <= 1.5), summary
    # held: the last 30 s settled on the target
    assert np.all(np.abs(deviation[t >= DURATION_S - 30.0]) <= 0.25), summary

    # the service brake helped only on the way down: applied once, released before the band,
    # and the commands switched from braking to traction once, without hunting
    brake_on = run["brake"] > 0.0
    assert brake_on.any(), "the service brake was never used"
    assert np.count_nonzero(brake_on[1:] != brake_on[:-1]) <= 2
    assert not brake_on[run["traction_ns"] / 1e9 >= t_reach].any()
    switches = effort_sign_changes(run["traction"], run["brake"])
    assert switches <= 2, f"{switches} switches between traction and braking"


@pytest.mark.parametrize("value, reason", [
    ("500.0", "parameter kp: 500.0 is out of range, expected 0 to 100"),
    ("abc", "parameter kp: 'abc' is not a number with a decimal point (e.g. 2.0)")])
def test_a_parameter_the_controller_cannot_use_is_one_line_and_exit_1(value, reason):
    import subprocess

    run = subprocess.run([sys.executable, str(EXAMPLE), "--ros-args", "-p", f"kp:={value}"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1
    lines = [line for line in (run.stdout + run.stderr).splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].endswith(f"[speed_controller]: {reason}"), lines

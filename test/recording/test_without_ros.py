"""Recording needs no ROS install: the recorded types' definitions ship with the package."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ltd_brake_ros.recording import ros_types

#: ROS packages an install of ``pip install .`` alone does not have.
ROS_MODULES = ("rclpy", "std_msgs", "sensor_msgs", "rosgraph_msgs", "builtin_interfaces",
               "rosidl_parser", "rosidl_runtime_py", "ament_index_python", "rcl_interfaces",
               "diagnostic_msgs", "std_srvs")

BLOCKER = """
import sys
from importlib.abc import MetaPathFinder

class NoRos(MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}} (no ROS here)")
        return None

sys.meta_path.insert(0, NoRos())
from ltd_brake_ros.cli.main import main
code = main(sys.argv[1:])
assert not any(m.split('.')[0] in {blocked!r} for m in sys.modules), "a ROS module was imported"
sys.exit(code)
"""


def test_the_shipped_definitions_are_those_of_the_installed_packages():
    pytest.importorskip("std_msgs")
    shipped = json.loads(ros_types._SHIPPED_FILE.read_text())
    assert len(shipped) >= 6
    for msg_type, entry in shipped.items():
        assert entry["definition"] == ros_types.installed_definition(msg_type), msg_type
        assert entry["type_description_hash"] == ros_types.installed_type_hash(msg_type)


def test_a_run_records_and_reports_without_any_ros_module(tmp_path):
    folder = tmp_path / "run"
    script = BLOCKER.format(blocked=set(ROS_MODULES))

    def cli(*args):
        return subprocess.run([sys.executable, "-c", script, *args], capture_output=True,
                              text=True, timeout=300)
    rec = cli("simulate", "--scenario", "1", "--record", str(folder), "--json")
    assert rec.returncode == 0, rec.stderr
    summary = json.loads(rec.stdout)
    rep = cli("report", str(folder), "--json", "--out", str(tmp_path / "report"))
    assert rep.returncode == 0, rep.stderr
    report = json.loads(rep.stdout)
    assert report["stopping_distance_m"] == pytest.approx(summary["stopping_distance_m"],
                                                          rel=5e-3)

"""The launch files: installed where ``ros2 launch`` looks, and what they start.

The ROS 2 launch library is not among the PyPI ROS wheels, so each launch file runs here against
a stand-in of the few ``launch``/``launch_ros`` classes it uses, which records the actions and
evaluates arguments as ``ros2 launch`` does (defaults, choices, scoped includes, opaque
functions). The nodes they describe are then checked against the package: executables it
installs, parameters the node declares with their types, the installed parameter file; and one
plant is started with the command line that ``launch_ros`` makes of its ``Node``.
"""
from __future__ import annotations

import importlib.util
import os
import shutil
import sys
import time
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

from conftest import BIN_DIR
from node_helpers import chunks_from_log

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
PACKAGE = "ltd_brake_ros"
LAUNCH_FILES = sorted(p.name for p in (REPO / "launch").glob("*.launch.*"))


# --------------------------------------------------------------------------- installation


def _distribution(monkeypatch):
    """setup.py's distribution as setuptools sees it (nothing built or installed)."""
    from setuptools._distutils.core import run_setup

    monkeypatch.chdir(REPO)  # setup.py globs relative to the checkout
    return run_setup(str(REPO / "setup.py"), stop_after="init")


@pytest.fixture(scope="module")
def prefix(tmp_path_factory):
    """An install prefix holding the package's data files as setup.py installs them.

    ``AMENT_PREFIX_PATH`` points at it, so ``ros2 launch ltd_brake_ros`` and the launch files'
    own look-ups find the package there.
    """
    mp = pytest.MonkeyPatch()
    dist = _distribution(mp)
    root = tmp_path_factory.mktemp("prefix")
    for folder, files in dist.data_files:
        (root / folder).mkdir(parents=True, exist_ok=True)
        for file in files:
            shutil.copy2(REPO / file, root / folder)
    mp.setenv("AMENT_PREFIX_PATH", str(root))
    yield root
    mp.undo()


def test_launch_files_layouts_and_the_example_are_installed(monkeypatch):
    dist = _distribution(monkeypatch)
    installed = {folder: sorted(Path(f).name for f in files) for folder, files in dist.data_files}
    assert LAUNCH_FILES and installed[f"share/{PACKAGE}/launch"] == LAUNCH_FILES
    layouts = sorted(p.name for p in (REPO / "layouts").iterdir())
    assert installed[f"share/{PACKAGE}/layouts"] == layouts
    assert "sim_node.yaml" in installed[f"share/{PACKAGE}/config"]
    # the controller trains.launch.py starts (colcon: lib/ltd_brake_ros, pip: bin)
    assert dist.scripts == ["examples/speed_controller.py"]
    assert os.access(REPO / "examples" / "speed_controller.py", os.X_OK)
    assert (REPO / "examples" / "speed_controller.py").read_text().startswith("#!")


def test_the_shipped_parameter_file_applies_in_any_namespace_with_every_default():
    from ltd_brake_ros.ros.params import PARAMETERS

    listed = yaml.safe_load((REPO / "config" / "sim_node.yaml").read_text())
    # a plain `sim_node:` key would apply only to /sim_node: under -r __ns:=/train3 the node
    # would silently keep its defaults
    assert list(listed) == ["/**/sim_node"]
    assert listed["/**/sim_node"]["ros__parameters"] == {p.name: p.default for p in PARAMETERS}


# --------------------------------------------------------------------------- launch stand-in


class _Action:
    """A launch action: its constructor arguments, recorded."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context.launch_configurations[self.name]


def _stand_in_modules() -> dict[str, types.ModuleType]:
    classes = {"launch": ["LaunchDescription"],
               "launch.actions": ["DeclareLaunchArgument", "OpaqueFunction", "Shutdown",
                                  "GroupAction", "IncludeLaunchDescription"],
               "launch.launch_description_sources": ["PythonLaunchDescriptionSource"],
               "launch_ros.actions": ["Node"]}
    modules = {}
    for name, members in classes.items():
        module = types.ModuleType(name)
        for member in members:
            setattr(module, member, type(member, (_Action,), {}))
        modules[name] = module
    modules["launch.substitutions"] = types.ModuleType("launch.substitutions")
    modules["launch.substitutions"].LaunchConfiguration = _LaunchConfiguration
    modules["launch_ros"] = types.ModuleType("launch_ros")
    return modules


@pytest.fixture
def launch(monkeypatch, prefix):
    """``launch(file, **arguments)``: the Node actions of a launch file, as ``ros2 launch
    ltd_brake_ros file name:=value ...`` would start them."""
    for name, module in _stand_in_modules().items():
        monkeypatch.setitem(sys.modules, name, module)
    share = prefix / "share" / PACKAGE / "launch"

    def run(file: str, **arguments: str) -> list:
        return _expand(share / file, dict(arguments), set())
    return run


def _load(path: Path):
    """The Python file at ``path`` as a module (as ``ros2 launch`` loads a launch file)."""
    name = f"loaded_{path.stem.replace('.', '_')}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while it executes
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[name]
    return module


def _expand(path: Path, configurations: dict, declared: set) -> list:
    """Nodes of the launch file at ``path``; ``declared`` collects its argument names."""
    description = _load(path).generate_launch_description()
    context = types.SimpleNamespace(launch_configurations=configurations)
    nodes = []

    def process(entity) -> None:
        kind = type(entity).__name__
        if kind == "DeclareLaunchArgument":
            name = entity.args[0]
            declared.add(name)
            configurations.setdefault(name, entity.kwargs["default_value"])
            choices = entity.kwargs.get("choices")
            if choices is not None and configurations[name] not in choices:
                raise ValueError(f'Argument "{name}" provided value "{configurations[name]}" '
                                 f'is not valid. Valid options are: {choices}')
        elif kind == "OpaqueFunction":
            for action in entity.kwargs["function"](context):
                process(action)
        elif kind == "GroupAction":
            saved = dict(configurations)
            for action in entity.args[0]:
                process(action)
            if entity.kwargs.get("scoped", True):
                configurations.clear()
                configurations.update(saved)
        elif kind == "IncludeLaunchDescription":
            given = dict(entity.kwargs.get("launch_arguments", ()))
            inner_declared: set = set()
            inner = _expand(Path(entity.args[0].args[0]), {**configurations, **given},
                            inner_declared)
            undeclared = set(given) - inner_declared
            assert not undeclared, f"{path.name} passes undeclared {sorted(undeclared)}"
            nodes.extend(inner)
        elif kind == "Node":
            nodes.append(entity)
        else:
            raise AssertionError(f"{path.name}: unexpected entity {kind}")

    for entity in description.args[0]:
        process(entity)
    return nodes


def _overrides(node) -> dict:
    """The parameters a Node action sets beyond its parameter files."""
    out = {}
    for params in node.kwargs["parameters"]:
        if isinstance(params, dict):
            out |= params
    return out


def _files(node) -> list[str]:
    return [p for p in node.kwargs["parameters"] if isinstance(p, str)]


# --------------------------------------------------------------------------- what they start


def test_every_launch_file_loads_and_xml_ones_include_installed_files(launch):
    assert {"sim.launch.py", "sim.launch.xml", "trains.launch.py"} <= set(LAUNCH_FILES)
    for name in LAUNCH_FILES:
        if name.endswith(".py"):
            assert launch(name), f"{name} starts nothing"
            continue
        root = ET.parse(REPO / "launch" / name).getroot()
        assert root.tag == "launch", name
        includes = [e.get("file") for e in root.iter("include")]
        assert includes, name
        for file in includes:
            head = f"$(find-pkg-share {PACKAGE})/launch/"
            assert file.startswith(head) and file[len(head):] in LAUNCH_FILES, (name, file)


def test_sim_launch_starts_the_plant_with_the_installed_file_and_typed_overrides(launch, prefix):
    from ltd_brake_ros.ros.params import CLOCK_MODES, PARAMETERS

    installed = str(prefix / "share" / PACKAGE / "config" / "sim_node.yaml")
    node, = launch("sim.launch.py")
    assert node.kwargs["executable"] == "sim_node" and node.kwargs["name"] == "sim_node"
    assert node.kwargs["namespace"] is None
    # nothing given: the installed file alone decides (no default of the launch file overrides)
    assert _files(node) == [installed] and _overrides(node) == {}

    sim = _load(REPO / "launch" / "sim.launch.py")
    types_of = {p.name: type(p.default).__name__ for p in PARAMETERS}
    for argument, (parameter, kind, _) in sim.PARAMETER_ARGUMENTS.items():
        assert types_of.get(parameter) == kind, f"argument {argument} sets {parameter}"
    # a choice the node refuses would pass the launch and stop the node
    assert sim.CHOICES["clock"] == ["", *CLOCK_MODES]

    # every run-defining parameter has an argument of its own name
    assert {"consist", "initial_speed_kmh", "brake_params_file", "coupler_lut_file",
            "track_file", "start_chainage_m", "tolerance_m_s", "steps_per_call",
            "lockstep"} <= set(sim.PARAMETER_ARGUMENTS)
    assert all(argument == parameter
               for argument, (parameter, _, _) in sim.PARAMETER_ARGUMENTS.items())
    node, = launch("sim.launch.py", namespace="/t7", real_time_factor="0", lockstep="true",
                   consist="6", record_dir="runs/x", initial_speed_kmh="80", publish_every="5",
                   max_catch_up_s="0.5", tolerance_m_s="0.002", steps_per_call="3",
                   track_file="tracks/hump_10permille.yaml", log_level="debug")
    assert node.kwargs["namespace"] == "/t7"
    assert _overrides(node) == {"real_time_factor": 0.0, "lockstep": True, "consist": "6",
                                "record_dir": "runs/x", "initial_speed_kmh": 80.0,
                                "publish_every": 5, "max_catch_up_s": 0.5,
                                "tolerance_m_s": 0.002, "steps_per_call": 3,
                                "track_file": "tracks/hump_10permille.yaml"}
    # the level is the node's logger's only (rclpy names it namespace.node)
    assert node.kwargs["ros_arguments"] == ["--log-level", "t7.sim_node:=debug"]
    assert all(type(v).__name__ == types_of[k] for k, v in _overrides(node).items())

    with pytest.raises(ValueError, match="launch argument real_time_factor: 'fast' is not a "
                                         "number"):
        launch("sim.launch.py", real_time_factor="fast")
    with pytest.raises(ValueError, match="launch argument publish_every: '2.5' is not a whole "
                                         "number"):
        launch("sim.launch.py", publish_every="2.5")
    with pytest.raises(ValueError, match='Argument "lockstep" provided value "yes"'):
        launch("sim.launch.py", lockstep="yes")
    with pytest.raises(ValueError, match="launch argument params_file: /nonexistent.yaml is "
                                         "not a file"):
        launch("sim.launch.py", params_file="/nonexistent.yaml")


def test_trains_launch_runs_one_leader_its_controller_and_followers_on_its_clock(launch):
    nodes = launch("trains.launch.py", trains="3", record="true", record_dir="runs/yard")
    plants = [n for n in nodes if n.kwargs["name"] == "sim_node"]
    controller, = [n for n in nodes if n.kwargs["name"] == "speed_controller"]
    assert [p.kwargs["namespace"] for p in plants] == ["/train1", "/train2", "/train3"]
    leader, *followers = (_overrides(p) for p in plants)
    assert leader["clock"] == "publish" and leader["lockstep"] is True
    assert leader["chunk_s"] == 0.1 and leader["consist"] == "scenario_6"
    assert [f["clock"] for f in followers] == ["follow", "follow"]
    assert [f["record_dir"] for f in (leader, *followers)] == [
        f"runs/yard/train{k}" for k in (1, 2, 3)]
    assert all(f.get("lockstep") is None for f in followers)

    # the closed-loop example, by the name setup.py installs it under, in the leader's namespace
    assert controller.kwargs["executable"] == "speed_controller.py"
    assert controller.kwargs["namespace"] == "/train1"
    example = _load(REPO / "examples" / "speed_controller.py")
    params = _overrides(controller)
    assert set(params) - {"use_sim_time"} <= set(example.PARAMETERS)
    assert params["use_sim_time"] is True and params["duration_s"] == 180.0
    assert all(p.get("max_sim_time_s") == 180.0 for p in followers)
    assert shutil.which("speed_controller.py", path=str(BIN_DIR)), \
        "speed_controller.py is not installed (run ./dev.sh setup)"

    assert len(launch("trains.launch.py", trains="1")) == 2
    assert len(launch("trains.launch.py", trains="1", controller="false")) == 1
    with pytest.raises(ValueError, match="launch argument trains: '0' is not a whole number"):
        launch("trains.launch.py", trains="0")


def _exit(node, code: int, shutting_down: bool = False):
    """What the launch does when ``node`` exits with ``code`` (its ``on_exit`` handler)."""
    event = types.SimpleNamespace(returncode=code)
    return node.kwargs["on_exit"](event, types.SimpleNamespace(is_shutdown=shutting_down))


def test_a_plant_that_fails_fails_the_launch_and_one_that_ends_ends_it(launch):
    node, = launch("sim.launch.py", namespace="/t2")
    # ros2 launch exits non-zero only when an exception reaches its loop: a failed node raises
    with pytest.raises(RuntimeError, match=r"^/t2/sim_node exited with status 1: it failed"):
        _exit(node, 1)
    ends = _exit(node, 0)
    assert [type(a).__name__ for a in ends] == ["Shutdown"]
    # stopped by the launch's own Ctrl-C while shutting down: not a failure
    assert [type(a).__name__ for a in _exit(node, -2, shutting_down=True)] == ["Shutdown"]
    with pytest.raises(RuntimeError, match="exited with status -11"):
        _exit(node, -11, shutting_down=True)  # a crash is a failure, even then
    alone, = launch("sim.launch.py", end_launch_on_exit="false")
    assert _exit(alone, 0) is None
    with pytest.raises(RuntimeError):
        _exit(alone, 3)
    with pytest.raises(ValueError, match='Argument "end_launch_on_exit" provided value "no"'):
        launch("sim.launch.py", end_launch_on_exit="no")
    timed, = launch("sim.launch.py", use_sim_time="true")
    assert _overrides(timed) == {"use_sim_time": True}


def test_trains_end_independently_and_run_at_any_pace_with_or_without_the_controller(launch):
    nodes = launch("trains.launch.py", trains="3", duration_s="60")
    plants = [n for n in nodes if n.kwargs["name"] == "sim_node"]
    controller, = [n for n in nodes if n.kwargs["name"] == "speed_controller"]
    leader, *followers = plants
    # the followers stop at the end of the run by themselves, and end only themselves
    assert [_overrides(f)["max_sim_time_s"] for f in followers] == [60.0, 60.0]
    assert all(_exit(p, 0) is None for p in plants)
    # the driven leader ends with its controller, whose end ends the experiment
    assert "max_sim_time_s" not in _overrides(leader)
    assert [type(a).__name__ for a in _exit(controller, 0)] == ["Shutdown"]
    with pytest.raises(RuntimeError, match="/train1/speed_controller exited with status 1"):
        _exit(controller, 1)
    assert _overrides(controller)["real_time_factor"] == 0.0
    paced = launch("trains.launch.py", trains="2", real_time_factor="2")
    assert [_overrides(n)["real_time_factor"] for n in paced
            if n.kwargs["name"] == "speed_controller"] == [2.0]

    alone = launch("trains.launch.py", trains="2", controller="false", real_time_factor="5",
                   duration_s="30")
    assert [n.kwargs["name"] for n in alone] == ["sim_node", "sim_node"]
    leader = _overrides(alone[0])
    assert leader["lockstep"] is False and leader["real_time_factor"] == 5.0
    assert leader["max_sim_time_s"] == 30.0 and leader["clock"] == "publish"
    first = launch("trains.launch.py", trains="2", controller="false",
                   end_all_on_first_exit="true")
    assert all([type(a).__name__ for a in _exit(p, 0)] == ["Shutdown"] for p in first)
    for argument, text in (("controller", "yes"), ("real_time_factor", "-1"),
                           ("duration_s", "0")):
        with pytest.raises(ValueError, match=f"launch argument {argument}"):
            launch("trains.launch.py", **{argument: text})


# --------------------------------------------------------------------------- one real plant


def _command_line(node, folder: Path) -> list[str]:
    """The command line launch_ros makes of a Node action (its parameter dicts become files
    under the wildcard node name, after the given files)."""
    kw = node.kwargs
    exe = shutil.which(kw["executable"], path=str(BIN_DIR))
    assert exe and "package" not in kw, kw  # pip layout: the executable comes from PATH
    argv = [exe, "--ros-args", *kw.get("ros_arguments", ()), "-r", f"__node:={kw['name']}"]
    if kw.get("namespace"):
        argv += ["-r", f"__ns:={kw['namespace']}"]
    for k, params in enumerate(kw["parameters"]):
        if isinstance(params, dict):
            path = folder / f"launch_params_{k}.yaml"
            path.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}))
            params = str(path)
        argv += ["--params-file", params]
    return argv


def test_a_namespaced_plant_takes_the_parameter_file_and_the_arguments(
        launch, processes, probe, tmp_path):
    """The installed file's /**/sim_node key reaches a node in /launched: with the file's
    max_sim_time_s and the argument's chunk_s it stops after exactly 2.0 / 0.05 chunks, and
    its topics are under the namespace."""
    from std_msgs.msg import Float64MultiArray

    own = yaml.safe_load((REPO / "config" / "sim_node.yaml").read_text())
    own["/**/sim_node"]["ros__parameters"]["max_sim_time_s"] = 2.0
    params_file = tmp_path / "plant.yaml"
    params_file.write_text(yaml.safe_dump(own))
    node, = launch("sim.launch.py", namespace="/launched", params_file=str(params_file),
                   chunk_s="0.05")
    probe.subscribe("/launched/vehicles/speed", Float64MultiArray)
    proc = processes.start(*_command_line(node, tmp_path), name="launched")
    probe.spin_until(lambda: probe.received["/launched/vehicles/speed"], 60,
                     "a state message on /launched/vehicles/speed")
    assert proc.wait(60) == 0, proc.output()
    assert "max_sim_time_s = 2 s reached" in proc.output(), proc.output()
    assert chunks_from_log(proc.output()) == 40


def test_a_plant_that_cannot_start_fails_its_launch_within_seconds(launch, processes, tmp_path):
    """The real node of a launch with a consist that does not exist exits non-zero with its
    one-line reason, and the launch's handler turns that status into a failed launch."""
    node, = launch("sim.launch.py", consist="nonexistent.yaml")
    proc = processes.start(*_command_line(node, tmp_path), name="doomed")
    start = time.monotonic()
    code = proc.wait(60)
    assert code != 0 and "nonexistent.yaml" in proc.output(), proc.output()
    assert time.monotonic() - start < 30.0  # well within the 10 s of an idle machine
    with pytest.raises(RuntimeError, match=f"/sim_node exited with status {code}"):
        _exit(node, code)

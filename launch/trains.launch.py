"""Several trains on one simulation time, the first driven by the closed-loop example.

    ros2 launch ltd_brake_ros trains.launch.py
    ros2 launch ltd_brake_ros trains.launch.py trains:=4 record:=true record_dir:=runs/yard
    ros2 launch ltd_brake_ros trains.launch.py real_time_factor:=1
    ros2 launch ltd_brake_ros trains.launch.py controller:=false real_time_factor:=5

``/train1`` is the paper's scenario 6 train (E402B + 32 Shimmns) from 80 km/h; it publishes
``/clock`` (``clock:=publish``). With ``controller:=true`` (the default) it runs in lock-step,
driven by ``speed_controller.py`` (examples/speed_controller.py) to ``target_speed_kmh``, one
step every ``0.1 / real_time_factor`` s of wall time (0: as fast as possible); with
``controller:=false`` it runs by itself at ``real_time_factor``. ``/train2`` ...
``/train<trains>`` follow that clock (``clock:=follow``): every plant advances to the leader's
simulated time, so all trains share one time line. Train k runs scenario
``FOLLOWER_SCENARIOS[k - 2]`` (cycled) and applies its emergency brake by itself at
``20 (k - 1)`` s. Each train is one ``sim.launch.py`` in its own namespace. The controller
ends the launch after ``duration_s`` of simulated time; without it every train stops by itself
at ``duration_s`` and the launch ends with the last one (``end_all_on_first_exit:=true``: with
the first one). A train or controller that fails ends the launch with a non-zero status.
"""
from __future__ import annotations

import datetime
import importlib.util
import os

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, GroupAction, IncludeLaunchDescription,
                            OpaqueFunction)
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = os.path.dirname(os.path.abspath(__file__))
#: The closed-loop example, installed as a script of the package.
CONTROLLER = "speed_controller.py"
#: Control period = the leader's chunk [s]; followers advance in chunks of the same length.
CHUNK_S = 0.1
#: Wall time the controller waits for its plant at start-up [s].
CONNECT_TIMEOUT_S = 600.0
#: Scenarios of config/scenarios.yaml run by train 2, 3, ... (cycled).
FOLLOWER_SCENARIOS = (2, 4, 1, 3, 5)
#: Arguments: name -> (default, description).
ARGUMENTS = {
    "trains": ("3", "Number of trains (1 to 20): /train1 driven by the controller, the others "
                    "following its clock"),
    "target_speed_kmh": ("40.0", "Speed the controller brings /train1 to [km/h]"),
    "duration_s": ("180.0", "Simulated time the controller runs before the launch ends [s]"),
    "record": ("false", "Record every train to <record_dir>/train<k>"),
    "record_dir": ("", "Folder of the recordings; empty = runs/trains_<date>-<time>"),
    "controller": ("true", "true: speed_controller drives /train1 in lock-step; false: /train1 "
                           "runs by itself"),
    "real_time_factor": ("0", "Simulated seconds per wall second of the leader (and so of all "
                              "trains); 0 = as fast as possible"),
    "end_all_on_first_exit": ("false", "true: the first train to end ends the launch; false: "
                                       "each train ends by itself"),
}
#: Arguments that take true or false.
FLAGS = ("record", "controller", "end_all_on_first_exit")


def _sim_launch():
    """The sibling sim.launch.py as a module (its executable lookup is shared)."""
    spec = importlib.util.spec_from_file_location("ltd_brake_sim_launch",
                                                  os.path.join(HERE, "sim.launch.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _number(argument: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"launch argument {argument}: {text!r} is not a number") from None


def _count(text: str) -> int:
    if not text.isdigit() or not 1 <= int(text) <= 20:
        raise ValueError(f"launch argument trains: {text!r} is not a whole number from 1 to 20")
    return int(text)


def _flag(name: str, text: str) -> bool:
    if text not in ("true", "false"):
        raise ValueError(f"launch argument {name}: {text!r} is not true or false")
    return text == "true"


def _trains(context):
    """One sim.launch.py per train and the controller of /train1."""
    def value(name: str) -> str:
        return LaunchConfiguration(name).perform(context).strip()

    count = _count(value("trains"))
    flags = {name: _flag(name, value(name)) for name in FLAGS}
    rtf = _number("real_time_factor", value("real_time_factor"))
    if not 0.0 <= rtf <= 1e6:
        raise ValueError(f"launch argument real_time_factor: {rtf:g} is not from 0 to 1e6")
    duration = _number("duration_s", value("duration_s"))
    if not duration > 0.0:
        raise ValueError(f"launch argument duration_s: {duration:g} is not above 0")
    folder = value("record_dir") or os.path.join(
        "runs", datetime.datetime.now().strftime("trains_%Y%m%d-%H%M%S"))
    record = "true" if flags["record"] else "false"
    end_all = "true" if flags["end_all_on_first_exit"] else "false"
    sim = _sim_launch()
    actions = []
    for k in range(1, count + 1):
        args = {"namespace": f"/train{k}", "chunk_s": str(CHUNK_S), "record": record,
                "record_dir": os.path.join(folder, f"train{k}") if record == "true" else "",
                "end_launch_on_exit": end_all}
        if k == 1:
            args |= {"consist": "scenario_6", "initial_speed_kmh": "80.0", "clock": "publish"}
            if flags["controller"]:
                args |= {"lockstep": "true"}
            else:
                args |= {"lockstep": "false", "real_time_factor": f"{rtf:g}"}
        else:
            scenario = FOLLOWER_SCENARIOS[(k - 2) % len(FOLLOWER_SCENARIOS)]
            args |= {"consist": f"scenario_{scenario}", "clock": "follow",
                     "auto_brake_at_s": str(20.0 * (k - 1))}
        if k > 1 or not flags["controller"]:  # a driven leader ends with its controller
            args["max_sim_time_s"] = f"{duration:g}"
        include = IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(HERE, "sim.launch.py")),
            launch_arguments=args.items())
        actions.append(GroupAction([include], scoped=True))
    if flags["controller"]:
        actions.append(Node(
            **sim.installed_executable(CONTROLLER), name="speed_controller",
            namespace="/train1",
            parameters=[{"target_speed_kmh": _number("target_speed_kmh",
                                                     value("target_speed_kmh")),
                         "duration_s": duration, "real_time_factor": rtf,
                         # the first start after an install compiles the plants' kernel,
                         # several at once here: minutes on a busy machine
                         "connect_timeout_s": CONNECT_TIMEOUT_S, "use_sim_time": True}],
            output="screen", emulate_tty=True,
            # the controller's end is the end of the experiment: it ends the launch
            on_exit=sim.exit_handler("/train1/speed_controller", True)))
    return actions


def generate_launch_description() -> LaunchDescription:
    """Arguments, the trains and the controller (see the module docstring)."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=text)
         for name, (default, text) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_trains)])

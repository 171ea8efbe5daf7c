"""One train plant: ``sim_node`` in a namespace of its own.

    ros2 launch ltd_brake_ros sim.launch.py --show-args
    ros2 launch ltd_brake_ros sim.launch.py namespace:=/train1 record:=true
    ros2 launch ltd_brake_ros sim.launch.py params_file:=my_plant.yaml real_time_factor:=0

The node takes ``params_file`` (default: the installed ``config/sim_node.yaml``, whose
``/**/sim_node:`` key applies in any namespace), then every argument given on the command
line. An argument left empty keeps the file's value, so a value in your own file is never
overridden by a default of this launch file. Values are checked as the node checks
``-p name:=value``: a bad one stops the launch with one line naming the argument.
``sim.launch.xml`` is the same launch for XML launch files.
"""
from __future__ import annotations

import os

from ament_index_python.packages import get_package_prefix, get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = "ltd_brake_ros"
#: The plant's executable and node name (controllers find its services under this name).
PLANT = "sim_node"

#: Launch arguments that set a node parameter: argument -> (parameter, type, description).
#: Empty (the default of every one) keeps the value of params_file.
PARAMETER_ARGUMENTS = {
    "consist": ("consist", "str",
                "Consist YAML file or scenario (scenario_6 or 6)"),
    "initial_speed_kmh": ("initial_speed_kmh", "float",
                          "Initial speed [km/h]; -1 = the scenario's"),
    "chunk_s": ("chunk_s", "float",
                "Simulated time advanced and published per chunk [s]"),
    "real_time_factor": ("real_time_factor", "float",
                         "Simulated seconds per wall second; 0 = as fast as possible"),
    "max_catch_up_s": ("max_catch_up_s", "float",
                       "Wall time the plant may fall behind its schedule and catch up by "
                       "advancing the chunks already due [s]; 0 = never (long trains at "
                       "real_time_factor 1)"),
    "publish_every": ("publish_every", "int",
                      "Publish (and record) the state after every N-th chunk, for faster runs"),
    "lockstep": ("lockstep", "bool",
                 "true: advance only when <namespace>/sim_node/step is called"),
    "steps_per_call": ("steps_per_call", "int", "Chunks advanced by one ~/step call"),
    "brake_params_file": ("brake_params_file", "str",
                          "Brake-parameter YAML (empty: the paper's Table 3)"),
    "coupler_lut_file": ("coupler_lut_file", "str",
                         "Coupler YAML (empty: the shipped buffer-hook table)"),
    "track_file": ("track_file", "str", "Track YAML (empty: level straight track)"),
    "start_chainage_m": ("start_chainage_m", "float",
                         "Chainage of the head's front at t = 0 on the track [m]"),
    "tolerance_m_s": ("tolerance_m_s", "float",
                      "Local error allowed per step in each vehicle's speed [m/s]; 0 = fixed "
                      "steps"),
    "clock": ("clock", "str",
              "/clock policy: auto (publish unless another plant does, then follow it), "
              "publish, follow (run on another plant's /clock) or none"),
    "auto_brake_at_s": ("auto_brake_at_s", "float",
                        "Emergency brake by itself at this simulated time [s]; -1 = never"),
    "max_sim_time_s": ("max_sim_time_s", "float",
                       "Stop (and end the launch) at this simulated time [s]; -1 = never"),
    "shutdown_after_stop_s": ("shutdown_after_stop_s", "float",
                              "Stop (and end the launch) this long after the train has stopped "
                              "[s simulated]; -1 = never"),
    "tf_vehicle_rate_hz": ("tf_vehicle_rate_hz", "float",
                           "Rate of each vehicle's frame on /tf in simulated time [Hz]; 0 = the "
                           "head's frame (base_link) only"),
    "record": ("record", "bool",
               "Record everything published and received to an MCAP bag folder"),
    "record_frames": ("record_frames", "bool",
                      "With record: also record /tf, odom and train/markers"),
    "record_dir": ("record_dir", "str",
                   "Bag folder, which must not exist or be empty (the node's default: "
                   "runs/run_<date>-<time> in the working directory)"),
}
#: Accepted values of the arguments that have a fixed set (empty = the file's value).
CHOICES = {"bool": ["", "true", "false"],
           "clock": ["", "auto", "publish", "follow", "none"],
           "use_sim_time": ["", "true", "false"],
           "log_level": ["debug", "info", "warn", "error", "fatal"],
           "end_launch_on_exit": ["true", "false"]}
#: Arguments that do not set a parameter: argument -> (default, description).
OTHER_ARGUMENTS = {
    "namespace": ("", "Namespace of the node and its topics, e.g. /train1 (empty = /)"),
    "params_file": ("", "Parameter file (/**/sim_node: ros__parameters:); empty = the "
                        "installed share/ltd_brake_ros/config/sim_node.yaml"),
    "log_level": ("info", "Log level of the node's own logger (debug, info, warn, error, "
                          "fatal); the middleware's loggers keep theirs"),
    "use_sim_time": ("", "true: the node's ROS clock (log stamps, timers) runs on /clock; "
                         "empty = the value in params_file"),
    "end_launch_on_exit": ("true", "true: the launch ends when this plant ends; false: it "
                                   "ends by itself (several trains). A plant that fails "
                                   "ends the launch with a non-zero status either way"),
}
#: Exit statuses of a node stopped by the launch's own SIGINT/SIGTERM while shutting down.
SIGNAL_EXITS = (-2, -15, 130, 143)


def installed_executable(name: str) -> dict:
    """``Node`` keywords that find executable ``name`` of this package.

    colcon installs executables to ``<prefix>/lib/ltd_brake_ros`` (where ``ros2 run`` looks);
    ``pip install`` puts them on ``PATH``.

    Parameters
    ----------
    name : str
        Executable name.

    Returns
    -------
    dict
        ``package`` and ``executable``, or ``executable`` alone (found on ``PATH``).
    """
    if os.access(os.path.join(get_package_prefix(PACKAGE), "lib", PACKAGE, name), os.X_OK):
        return {"package": PACKAGE, "executable": name}
    return {"executable": name}


def _typed(argument: str, text: str, kind: str):
    """The parameter value of a launch argument's text, or ValueError naming the argument."""
    if kind == "str":
        return text
    if kind == "bool":
        return text == "true"  # the argument's choices admit only true and false
    try:
        return int(text) if kind == "int" else float(text)
    except ValueError:
        what = "a whole number" if kind == "int" else "a number"
        raise ValueError(f"launch argument {argument}: {text!r} is not {what}") from None


def exit_handler(node: str, end_launch: bool):
    """The ``on_exit`` of a node: a failure fails the launch, an end may end it.

    ``ros2 launch`` exits 0 unless an exception reaches its event loop, so a node that exits
    with a non-zero status (a start-up error, a failed run) raises one here: the launch shuts
    down and exits 1 with the node's name and status as its last line.

    Parameters
    ----------
    node : str
        The node's full name, for the message.
    end_launch : bool
        A node that ends normally ends the launch.

    Returns
    -------
    callable
        ``handler(event, context)`` for ``on_exit``.
    """
    def handler(event, context):
        code = event.returncode
        if code and not (context.is_shutdown and code in SIGNAL_EXITS):
            raise RuntimeError(f"{node} exited with status {code}: it failed (its reason is "
                               "in the lines above)")
        return [Shutdown(reason=f"{node} exited")] if end_launch else None
    return handler


def _plant(context):
    """The sim_node action for the arguments' values."""
    def value(name: str) -> str:
        return LaunchConfiguration(name).perform(context).strip()

    params_file = value("params_file") or os.path.join(
        get_package_share_directory(PACKAGE), "config", "sim_node.yaml")
    if not os.path.isfile(params_file):
        raise ValueError(f"launch argument params_file: {params_file} is not a file")
    overrides = {parameter: _typed(argument, value(argument), kind)
                 for argument, (parameter, kind, _) in PARAMETER_ARGUMENTS.items()
                 if value(argument)}
    if value("use_sim_time"):
        overrides["use_sim_time"] = value("use_sim_time") == "true"
    namespace = value("namespace") or None
    # the node's logger alone (rclpy names it after the namespace and the node): a global
    # level would also turn on the middleware's debug lines
    logger = ".".join([*(namespace or "").strip("/").split("/"), PLANT]).lstrip(".")
    return [Node(**installed_executable(PLANT), name=PLANT, namespace=namespace,
                 parameters=[params_file, overrides],
                 ros_arguments=["--log-level", f"{logger}:={value('log_level')}"],
                 output="screen", emulate_tty=True,
                 # a plant that stops by itself (max_sim_time_s, shutdown_after_stop_s) ends
                 # the launch unless told otherwise; one that fails fails the launch
                 on_exit=exit_handler(f"{(namespace or '').rstrip('/')}/{PLANT}",
                                      value("end_launch_on_exit") != "false"))]


def generate_launch_description() -> LaunchDescription:
    """Arguments and the plant (see the module docstring)."""
    arguments = [DeclareLaunchArgument(name, default_value=default, description=text,
                                       choices=CHOICES.get(name))
                 for name, (default, text) in OTHER_ARGUMENTS.items()]
    for name, (_, kind, text) in PARAMETER_ARGUMENTS.items():
        choices = CHOICES.get(name, CHOICES.get(kind))
        arguments.append(DeclareLaunchArgument(
            name, default_value="", choices=choices,
            description=f"{text} (empty = the value in params_file)"))
    return LaunchDescription([*arguments, OpaqueFunction(function=_plant)])

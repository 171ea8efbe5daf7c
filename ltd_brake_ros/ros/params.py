"""The nodes' parameters: one table with defaults, types, ranges and descriptions, their
declaration and the checks of values set at run time (what sim_node's parameters resolve to is
:class:`~ltd_brake_ros.plant.run.PlantRun`)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, ParameterException

from ..physics.kernel import DEFAULT_TOLERANCE_M_S
from ..plant.settings import DEFAULT_MAX_CATCH_UP_S, MAX_REAL_TIME_FACTOR, StartupError

__all__ = ["ParamSpec", "PARAMETERS", "CLOCK_MODES", "RESET_PARAMETERS", "StartupError",
           "declare_parameters", "check_value", "check_run_time_change"]

#: Values of the ``clock`` parameter.
#: (``off`` would be read as the boolean false on a ROS command line, hence ``none``.)
CLOCK_MODES = ("auto", "publish", "follow", "none")
#: Said of a parameter that a running node takes at its next reset.
AT_RESET = "; set at run time, takes effect at the next ~/reset"


@dataclass(frozen=True)
class ParamSpec:
    """Declaration of one node parameter.

    Attributes
    ----------
    name : str
        Parameter name.
    default : bool, int, float or str
        Default value; its Python type is the parameter type.
    description : str
        Shown by ``ros2 param describe`` (units in brackets).
    read_only : bool
        Structural: fixed once the node runs.
    lo, hi : float or None
        Accepted range (inclusive), for numbers.
    at_reset : bool
        Settable at run time, taken at the next ``~/reset`` (it defines the run).
    """

    name: str
    default: Any
    description: str
    read_only: bool = True
    lo: float | None = None
    hi: float | None = None
    at_reset: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """The ROS parameter descriptor (type, description, range, read-only flag)."""
        types = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
                 float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
        d = ParameterDescriptor(name=self.name, type=types[type(self.default)],
                                description=self.description + (AT_RESET if self.at_reset
                                                                else ""),
                                read_only=self.read_only and not self.at_reset)
        if isinstance(self.default, float) and self.lo is not None:
            d.floating_point_range = [FloatingPointRange(from_value=float(self.lo),
                                                         to_value=float(self.hi), step=0.0)]
        elif isinstance(self.default, int) and not isinstance(self.default, bool) \
                and self.lo is not None:
            d.integer_range = [IntegerRange(from_value=int(self.lo), to_value=int(self.hi),
                                            step=1)]
        return d


#: Every parameter of sim_node, with its default (mirrored in ``config/sim_node.yaml``).
PARAMETERS = (
    ParamSpec("consist", "scenario_6",
              "Consist YAML file, or a scenario of config/scenarios.yaml given as text "
              "(scenario_6 or '6'; default: the paper's scenario 6)", at_reset=True),
    ParamSpec("initial_speed_kmh", -1.0,
              "Initial speed of every vehicle [km/h]; -1 = the scenario's speed "
              "(a value is required when consist is a file)", lo=-1.0, hi=400.0,
              at_reset=True),
    ParamSpec("brake_params_file", "",
              "Brake-parameter YAML file; empty = the shipped brake_params/paper.yaml",
              at_reset=True),
    ParamSpec("coupler_lut_file", "",
              "Coupler look-up-table YAML file; empty = the shipped couplers/buffer_hook_pugi.yaml",
              at_reset=True),
    ParamSpec("chunk_s", 0.02,
              "Simulated time advanced and published per chunk [s]: a whole number of the "
              "10 ms integration steps", lo=0.01, hi=10.0),
    ParamSpec("tolerance_m_s", DEFAULT_TOLERANCE_M_S,
              "Local error allowed per integration step in each vehicle's speed [m/s]; a step "
              "beyond it is taken in shorter sub-steps; 0 = fixed steps", lo=0.0, hi=1.0,
              at_reset=True),
    ParamSpec("real_time_factor", 1.0,
              "Simulated seconds per wall second: 1 = wall-clock pace, 2 = twice as fast, "
              "0 = as fast as possible; not used in lock-step mode; changeable at run time",
              read_only=False, lo=0.0, hi=MAX_REAL_TIME_FACTOR),
    ParamSpec("max_catch_up_s", DEFAULT_MAX_CATCH_UP_S,
              "Wall time the free-running plant may fall behind its schedule and still catch "
              "up, advancing the chunks already due at once (none before it is due) [s]; "
              "further behind, the schedule restarts from now and an overrun is counted; "
              "0 = never catch up", lo=0.0, hi=10.0),
    ParamSpec("lockstep", False,
              "Advance only when ~/step is called (steps_per_call chunks per call)"),
    ParamSpec("steps_per_call", 1,
              "Chunks advanced and published per ~/step call", read_only=False, lo=1, hi=100_000),
    ParamSpec("publish_every", 1,
              "Publish (and record) the state after every N-th chunk when free-running or "
              "following a clock, for faster runs; a ~/step's last chunk is always published",
              lo=1, hi=100_000),
    ParamSpec("clock", "auto",
              "Simulated time source: auto = publish /clock unless another node already "
              "publishes it, then follow that one; publish = publish /clock; follow = advance "
              "to the /clock another plant publishes (one simulated time for several trains: "
              "stepping or pausing that plant steps or pauses this one); none = neither"),
    ParamSpec("auto_brake_at_s", -1.0,
              "Apply the emergency brake by itself at the first chunk boundary at or after "
              "this simulated time [s]; -1 = never", lo=-1.0, hi=1e6, at_reset=True),
    ParamSpec("max_sim_time_s", -1.0,
              "Shut down cleanly once the simulated time reaches this [s]; -1 = run until "
              "signalled", lo=-1.0, hi=1e7, at_reset=True),
    ParamSpec("shutdown_after_stop_s", -1.0,
              "Shut down cleanly this long after the train has stopped [s simulated]; "
              "-1 = keep running", lo=-1.0, hi=1e6, at_reset=True),
    ParamSpec("track_file", "",
              "Track profile (YAML or CSV: chainage -> gradient [per mille], curve radius [m]); "
              "empty = level straight track", at_reset=True),
    ParamSpec("start_chainage_m", 0.0,
              "Chainage of the head's front at t = 0 [m] (overrides the track file's)",
              lo=-1e7, hi=1e7, at_reset=True),
    ParamSpec("tf_vehicle_rate_hz", 10.0,
              "Rate of each vehicle's frame (<prefix>vehicle_<i>, child of <prefix>base_link) "
              "on /tf in simulated time [Hz]; 0 = the head's frame only (base_link goes out "
              "with every published chunk)", lo=0.0, hi=1000.0),
    ParamSpec("record", False,
              "Record every published and received message to an MCAP bag folder"),
    ParamSpec("record_frames", False,
              "With record: also record /tf, odom and train/markers (the markers then drawn "
              "at tf_vehicle_rate_hz of simulated time, whether or not anyone subscribes)"),
    ParamSpec("record_dir", "",
              "Bag folder for record:=true, which must not exist or be empty; empty = "
              "runs/run_<date>-<time> in the working directory; after ~/reset the next run "
              "goes to the next free <record_dir>_2, _3, ..."),
)

_TYPE_WORDS = {bool: "true or false", int: "a whole number", float: "a number with a decimal "
               "point (e.g. 80.0)", str: "text (quote numbers, e.g. consist:=scenario_6)"}


#: Parameters a running node takes at its next reset.
RESET_PARAMETERS = tuple(p.name for p in PARAMETERS if p.at_reset)


def check_value(name: str, value: Any) -> str | None:
    """Why ``value`` is not usable for parameter ``name`` beyond its type and range, or None.

    Parameters
    ----------
    name : str
    value : bool, int, float or str

    Returns
    -------
    str or None
    """
    if name == "initial_speed_kmh" and value < 0.0 and value != -1.0:
        return (f"must be -1 (the scenario's speed) or a speed from 0 to 400 km/h, "
                f"got {value:g}")
    if name == "clock" and value not in CLOCK_MODES:
        return f"must be one of {', '.join(CLOCK_MODES)}, got {value!r}"
    return None


def declare_parameters(node, specs: Iterable[ParamSpec] = PARAMETERS) -> dict[str, Any]:
    """Declare ``specs`` on ``node`` and return their values.

    Raises
    ------
    StartupError
        A given value has the wrong type, is out of range or unusable (naming the parameter).
    """
    values = {}
    for spec in specs:
        try:
            values[spec.name] = node.declare_parameter(spec.name, spec.default,
                                                       spec.descriptor()).value
        except InvalidParameterTypeException:
            raise StartupError(spec.name, f"wrong type, expected "
                               f"{_TYPE_WORDS[type(spec.default)]}") from None
        except ParameterException as exc:
            reason = str(exc).split("Reason: ", 1)[-1].removesuffix(f": {spec.name}")
            raise StartupError(spec.name, reason) from None
        problem = check_value(spec.name, values[spec.name])
        if problem:
            raise StartupError(spec.name, problem)
    return values


def check_run_time_change(params, real_time_factor: float) -> SetParametersResult:
    """Accept or refuse new values of the run-time parameters, with a reason.

    Parameters
    ----------
    params : list of rclpy.parameter.Parameter
    real_time_factor : float
        The value in force (named in the refusal).

    Returns
    -------
    SetParametersResult
    """
    for p in params:
        problem = check_value(p.name, p.value) if p.name in RESET_PARAMETERS else None
        if problem:
            return SetParametersResult(successful=False, reason=f"{p.name} {problem}")
        if p.name == "real_time_factor":
            v = p.value
            if not (isinstance(v, float) and math.isfinite(v)
                    and 0.0 <= v <= MAX_REAL_TIME_FACTOR):
                return SetParametersResult(
                    successful=False,
                    reason=f"real_time_factor must be a number from 0 (as fast as possible) "
                           f"to {MAX_REAL_TIME_FACTOR:g}, got {v!r}; keeping {real_time_factor:g}")
        elif p.name == "steps_per_call" and not (isinstance(p.value, int) and p.value >= 1):
            return SetParametersResult(
                successful=False,
                reason=f"steps_per_call must be a whole number >= 1, got {p.value!r}")
    return SetParametersResult(successful=True)

"""ltd_brake_ros: freight-train emergency braking (UIC braked-weight method) as a ROS 2 plant.

The public Python API is what ``__all__`` lists; everything else is internal and may move::

    from ltd_brake_ros import load_consist, emergency_stop
    run = emergency_stop(load_consist("scenario_6"), 100.0)
    run.summary.stopping_distance_m        # 489.2 m
    df = run.to_dataframe("coupler")       # time_s, coupler, coupler_force_N (pandas)
    ds = run.to_xarray()                   # dims time x vehicle, time x coupler (xarray)

Names load on first use, so that ``import ltd_brake_ros`` (and the command line, which
imports the package) stays cheap.
"""
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from ._version import __version__

#: Public name -> the module that defines it.
_EXPORTS = {
    # inputs
    "load_consist": "api", "load_brake_params": "api", "load_coupler": "api",
    "load_track": "api", "load_commands": "api", "InputError": "inputs",
    "Consist": "inputs", "BrakeParams": "inputs", "CouplerLUT": "inputs", "Track": "inputs",
    "CommandScript": "inputs",
    # runs
    "emergency_stop": "api", "run_commands": "api", "RunResult": "api", "TimeSeries": "api",
    "Simulator": "simulator", "Commands": "simulator", "Snapshot": "simulator",
    "SimulationError": "simulator", "StopResult": "studies.runs", "Verdicts": "verdicts",
    "StopRecord": "stops",
    # recordings
    "read_recording": "api", "Recording": "api",
    # campaigns
    "load_campaign": "api", "run_campaign": "api", "read_campaign": "api",
    "CampaignResults": "analysis.campaign_results", "Comparison": "analysis.campaign_results",
}
__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'ltd_brake_ros' has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value  # the next access is a plain lookup
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # for type checkers and IDEs: the same names, imported eagerly
    from .api import (Recording, RunResult, TimeSeries, emergency_stop, load_brake_params,
                      load_campaign, load_commands, load_consist, load_coupler, load_track,
                      read_campaign, read_recording, run_campaign, run_commands)
    from .inputs import BrakeParams, CommandScript, Consist, CouplerLUT, InputError, Track
    from .simulator import Commands, SimulationError, Simulator, Snapshot
    from .stops import StopRecord
    from .studies.runs import StopResult
    from .verdicts import Verdicts
    from .analysis.campaign_results import CampaignResults, Comparison

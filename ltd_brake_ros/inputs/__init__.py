"""Input files: consist, brake parameters, coupler, track, command scripts, scenarios.

Every file is validated once, at load, into immutable dataclasses whose field names carry their
units. Bad input raises :class:`InputError` naming the file, the field path and the reason.

Modules: ``schema`` (errors, file lookup, YAML, field checks), ``consist``, ``brake_params``,
``couplers``, ``track``, ``commands``, ``scenarios``; their public names are importable from here.
"""
from .brake_params import (BrakeParams, brake_params_from_mapping, default_brake_params,
                           load_brake_params, model_warnings)
from .commands import COMMAND_RANGES, CommandScript, load_command_script
from .consist import (MAX_VEHICLES, BlockBrake, Consist, DiscBrake, Traction, Vehicle,
                      consist_from_mapping, load_consist, with_wagon_mass)
from .couplers import CouplerLUT, load_coupler_lut
from .scenarios import Scenario, get_scenario, load_scenarios
from .schema import InputError, config_dir, load_yaml, resolve_config_path
from .track import MIN_RADIUS_M, Track, load_track

__all__ = ["BlockBrake", "BrakeParams", "COMMAND_RANGES", "CommandScript", "Consist",
           "CouplerLUT", "DiscBrake", "InputError", "MAX_VEHICLES", "MIN_RADIUS_M", "Scenario",
           "Track", "Traction", "Vehicle", "brake_params_from_mapping", "config_dir",
           "consist_from_mapping", "default_brake_params", "get_scenario", "load_brake_params", "load_command_script",
           "load_consist", "load_coupler_lut", "load_scenarios", "load_track", "load_yaml",
           "model_warnings", "resolve_config_path", "with_wagon_mass"]

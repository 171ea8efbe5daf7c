"""The driver's and train control's inputs: the one table of their accepted ranges, the positions
of the driver's brake valve, and timed command scripts for offline runs."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from .schema import Fields, load_yaml, resolve_config_path

#: Accepted range of each numeric command, inclusive: service brake demand as a fraction of the
#: emergency block force [-], traction (positive) or dynamic-brake (negative) demand as a
#: fraction of the powered vehicles' available effort [-].
COMMAND_RANGES = {"brake_demand": (0.0, 1.0), "traction": (-1.0, 1.0)}

#: Brake demand of the driver's brake valve's first service step [-]: its pipe reduction over
#: that of a full service application, 0.45 bar (UIC 541-03: 0.4-0.5 bar) / 1.5 bar (UIC 540).
#: A distributor's cylinder pressure follows the pipe drop (3.8 bar at 1.5 bar), so the first
#: step gives this fraction of the full block force.
FIRST_STEP_DEMAND = 0.45 / 1.5

#: Positions of the driver's brake valve (UIC 540 / UIC 541-03 practice), each as the inputs it
#: sets (those it leaves out keep their value): ``release_overcharge`` releases and overcharges
#: the pipe, ``running`` releases at running pressure, ``lap`` holds the present command,
#: ``service`` is the first service step, ``full_service`` the full service application,
#: ``emergency`` the emergency application. Between the first step and full service the
#: ``brake_demand`` input graduates the application.
VALVE_POSITIONS: dict[str, dict[str, Any]] = {
    "release_overcharge": {"emergency": False, "brake_demand": 0.0, "overcharge": True},
    "running": {"emergency": False, "brake_demand": 0.0, "overcharge": False},
    "lap": {},
    "service": {"emergency": False, "brake_demand": FIRST_STEP_DEMAND, "overcharge": False},
    "full_service": {"emergency": False, "brake_demand": 1.0, "overcharge": False},
    "emergency": {"emergency": True, "overcharge": False},
}
#: The fields a valve position sets (a script entry gives either a position or these).
VALVE_FIELDS = ("emergency", "brake_demand", "overcharge")


def valve_position(name: Any) -> dict[str, Any] | None:
    """The inputs a driver's brake valve position sets, or None for an unknown position.

    Parameters
    ----------
    name : str
        A key of :data:`VALVE_POSITIONS`; surrounding blanks and letter case are ignored.

    Returns
    -------
    dict or None
        Input name to value (a copy), None if ``name`` is not a position.
    """
    if not isinstance(name, str):
        return None
    change = VALVE_POSITIONS.get(name.strip().lower())
    return None if change is None else dict(change)


@dataclass(frozen=True)
class CommandScript:
    """Timed driver inputs for an offline run.

    Attributes
    ----------
    steps : tuple of (float, dict)
        (time [s], fields that change then: ``emergency`` bool, ``brake_demand`` 0-1,
        ``traction`` -1-1, and ``overcharge`` bool from a valve position), sorted by time.
    duration_s : float or None
        Length of the run [s]; ``None``: until the train stops after a brake command.
    source : str
        File the script came from.

    Examples
    --------
    >>> from ltd_brake_ros import load_commands
    >>> script = load_commands([{"t_s": 0, "brake_demand": 0.5}, {"t_s": 20, "emergency": True}])
    >>> len(script.steps)
    2
    """

    steps: tuple
    duration_s: float | None = None
    source: str = ""


def load_command_script(path: str | os.PathLike) -> CommandScript:
    """Load a command script YAML file.

    The file holds ``duration_s`` (optional) and ``commands``, a list of mappings with ``t_s``
    and any of ``emergency``, ``brake_demand``, ``traction`` and ``driver_brake_valve`` (a
    position of :data:`VALVE_POSITIONS`, in place of ``emergency`` and ``brake_demand``: the
    one way to overcharge, as on the node's topics); each holds from its time on.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    CommandScript
    """
    p = resolve_config_path(path)
    return command_script_from_mapping(load_yaml(p), str(p))


def command_script_from_mapping(data: Any, source: str) -> CommandScript:
    """A command script from the mapping a script file holds (see :func:`load_command_script`).

    Parameters
    ----------
    data : mapping
        ``{"duration_s": ..., "commands": [{"t_s": 0, ...}, ...]}``.
    source : str
        Name for error messages.

    Returns
    -------
    CommandScript
    """
    top = Fields(data, source)
    top.reject_unknown({"name", "description", "duration_s", "commands"})
    duration = top.number("duration_s", lo=0.0, lo_open=True, hi=1e6) if top.has("duration_s") else None
    entries = top.data.get("commands")
    if not isinstance(entries, list) or not entries:
        raise top.error("commands", "missing or empty: give a list of {t_s, ...} entries")
    steps = []
    for i, entry in enumerate(entries):
        f = Fields(entry, source, f"commands[{i}]")
        f.reject_unknown({"t_s", "emergency", "brake_demand", "traction", "driver_brake_valve"})
        t = f.number("t_s", lo=0.0)
        if steps and t < steps[-1][0]:
            raise f.error("t_s", f"{t:g} s comes before the previous entry ({steps[-1][0]:g} s)")
        change: dict[str, Any] = {}
        if f.has("driver_brake_valve"):
            given = [name for name in VALVE_FIELDS if f.has(name)]
            if given:
                raise f.error("driver_brake_valve", f"give either a valve position or "
                              f"{', '.join(given)}, not both")
            change = valve_position(f.data["driver_brake_valve"])
            if change is None:
                raise f.error("driver_brake_valve", f"unknown position "
                              f"{f.data['driver_brake_valve']!r}; expected one of "
                              f"{', '.join(VALVE_POSITIONS)}")
        if f.has("emergency"):
            change["emergency"] = f.boolean("emergency", False)
        for name, (lo, hi) in COMMAND_RANGES.items():
            if f.has(name):
                change[name] = f.number(name, lo=lo, hi=hi)
        steps.append((t, change))
    return CommandScript(tuple(steps), duration, source)

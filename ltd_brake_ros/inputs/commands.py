"""The driver's and train control's inputs: the one table of their accepted ranges, and timed
command scripts for offline runs."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from .schema import Fields, load_yaml, resolve_config_path

#: Accepted range of each numeric command, inclusive: service brake demand as a fraction of the
#: emergency block force [-], traction (positive) or dynamic-brake (negative) demand as a
#: fraction of the powered vehicles' available effort [-].
COMMAND_RANGES = {"brake_demand": (0.0, 1.0), "traction": (-1.0, 1.0)}


@dataclass(frozen=True)
class CommandScript:
    """Timed driver inputs for an offline run.

    Attributes
    ----------
    steps : tuple of (float, dict)
        (time [s], fields that change then: ``emergency`` bool, ``brake_demand`` 0-1,
        ``traction`` -1-1), sorted by time.
    duration_s : float or None
        Length of the run [s]; ``None``: until the train stops after a brake command.
    source : str
        File the script came from.
    """

    steps: tuple
    duration_s: float | None = None
    source: str = ""


def load_command_script(path: str | os.PathLike) -> CommandScript:
    """Load a command script YAML file.

    The file holds ``duration_s`` (optional) and ``commands``, a list of mappings with ``t_s``
    and any of ``emergency``, ``brake_demand``, ``traction``; each holds from its time on.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    CommandScript
    """
    p = resolve_config_path(path)
    top = Fields(load_yaml(p), str(p))
    top.reject_unknown({"name", "description", "duration_s", "commands"})
    duration = top.number("duration_s", lo=0.0, lo_open=True, hi=1e6) if top.has("duration_s") else None
    entries = top.data.get("commands")
    if not isinstance(entries, list) or not entries:
        raise top.error("commands", "missing or empty: give a list of {t_s, ...} entries")
    steps = []
    for i, entry in enumerate(entries):
        f = Fields(entry, str(p), f"commands[{i}]")
        f.reject_unknown({"t_s", "emergency", "brake_demand", "traction"})
        t = f.number("t_s", lo=0.0)
        if steps and t < steps[-1][0]:
            raise f.error("t_s", f"{t:g} s comes before the previous entry ({steps[-1][0]:g} s)")
        change: dict[str, Any] = {}
        if f.has("emergency"):
            change["emergency"] = f.boolean("emergency", False)
        if f.has("brake_demand"):
            lo, hi = COMMAND_RANGES["brake_demand"]
            change["brake_demand"] = f.number("brake_demand", lo=lo, hi=hi)
        if f.has("traction"):
            lo, hi = COMMAND_RANGES["traction"]
            change["traction"] = f.number("traction", lo=lo, hi=hi)
        steps.append((t, change))
    return CommandScript(tuple(steps), duration, str(p))

"""The scenario catalogue: the runs of the paper's Tables 1-2."""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace

from .consist import Consist, load_consist
from .schema import Fields, InputError, config_dir, load_once


@dataclass(frozen=True)
class Scenario:
    """One run of the paper's Tables 1-2.

    Attributes
    ----------
    number : int
        Simulation number in the paper.
    consist_file : str
        Consist file (relative to the shipped config directory).
    speed_kmh : float
        Initial speed [km/h].
    paper : dict
        Reference values: ``lambda_percent``, ``uic_m`` (None at 50 km/h), ``pugi_m``,
        ``ltdpolito_m``, ``draft_kN``, ``draft_coupler``, ``buff_kN``, ``buff_coupler``.
    """

    number: int
    consist_file: str
    speed_kmh: float
    paper: dict = field(default_factory=dict)

    def consist(self) -> Consist:
        """Load the scenario's consist."""
        return load_consist(self.consist_file)


def load_scenarios() -> dict[int, Scenario]:
    """Load the shipped scenario catalogue (``config/scenarios.yaml``).

    Returns
    -------
    dict of int to Scenario
    """
    return {k: replace(s, paper=dict(s.paper)) for k, s in _catalogue().items()}


def _catalogue() -> dict[int, Scenario]:
    """The shipped catalogue, parsed once per version of the file; callers copy the mutable
    parts."""
    return load_once(os.path.join(config_dir(), "scenarios.yaml"), _catalogue_of)


def _catalogue_of(data, p: str) -> dict[int, Scenario]:
    """The catalogue of file ``p`` holding ``data``."""
    data = Fields(data, p).data.get("scenarios") or {}
    out = {}
    if not isinstance(data, dict):
        raise InputError(p, "scenarios", "must be a mapping of scenario number to run")
    for key, row in data.items():
        if isinstance(key, bool) or not isinstance(key, int):
            raise InputError(p, f"scenarios.{key}", "must be a scenario number")
        f = Fields(row, p, f"scenarios.{key}")
        paper = {k: v for k, v in row.items() if k not in ("consist", "speed_kmh")}
        out[int(key)] = Scenario(int(key), f.string("consist"), f.number("speed_kmh", lo=0.0), paper)
    return out


def get_scenario(name: str | int) -> Scenario:
    """Look up a scenario by number (``6``, ``"6"`` or ``"scenario_6"``).

    Parameters
    ----------
    name : str or int

    Returns
    -------
    Scenario
    """
    catalogue = _catalogue()
    text = str(name).strip().lower().removeprefix("scenario").strip("_ -")
    if text.isdigit() and int(text) in catalogue:
        found = catalogue[int(text)]
        return Scenario(found.number, found.consist_file, found.speed_kmh, dict(found.paper))
    raise InputError("scenario", "", f"unknown scenario {name!r}; known: "
                     f"{', '.join(str(k) for k in sorted(catalogue))}")

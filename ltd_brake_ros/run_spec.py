"""What to simulate: one resolver, shared by the command line and the node.

A run is named by a consist (a YAML file or a paper scenario), an initial speed, and the
brake-parameter, coupler-table and track files. :func:`resolve_run_spec` turns those names into
validated inputs with one set of rules:

* a scenario (``6``, ``scenario_6``) brings its train and its speed; a consist file brings a
  train and needs a speed;
* an explicit speed wins over the scenario's;
* empty file names take the shipped defaults (Table 3 brake parameters, the reconstructed
  buffer-hook table, level straight track).

Every error is an :class:`RunSpecError` naming the input (``consist``, ``speed_kmh``,
``brake_params``, ``coupler_lut``, ``track``) so that each front end reports it under its own
option or parameter name.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .inputs import (BrakeParams, Consist, CouplerLUT, InputError, Scenario, Track,
                     default_brake_params, get_scenario, load_brake_params, load_consist,
                     load_coupler_lut, load_track, resolve_config_path)

#: Accepted initial speeds [km/h].
SPEED_RANGE_KMH = (0.0, 400.0)


class RunSpecError(InputError):
    """An input of the run spec is missing or invalid.

    Parameters
    ----------
    input_name : str
        Which input: ``consist``, ``speed_kmh``, ``brake_params``, ``coupler_lut``, ``track``.
    reason : str
        What is wrong (for a file: the file, field and reason of the underlying error).
    """

    def __init__(self, input_name: str, reason: str, *, cause: InputError | None = None):
        self.input_name = input_name
        if cause is not None and cause.source != "scenario":
            # a file error keeps its file and field
            super().__init__(cause.source, cause.field, cause.reason)
        else:
            super().__init__(input_name, "", cause.reason if cause is not None else reason)

    @property
    def detail(self) -> str:
        """The reason, with the file and field when a file was at fault."""
        return self.reason if self.source == self.input_name else str(self)


@dataclass(frozen=True)
class RunSpec:
    """Validated inputs a simulator is built from.

    Attributes
    ----------
    consist : Consist
        The train, head first.
    speed_kmh : float
        Initial speed [km/h].
    params : BrakeParams
    lut : CouplerLUT
    track : Track
    origin : str
        Where the train came from, for people: ``scenario 6`` or ``file consists/x.yaml``.
    scenario : Scenario or None
        The paper scenario, when the train is one.
    """

    consist: Consist
    speed_kmh: float
    params: BrakeParams
    lut: CouplerLUT
    track: Track = field(default_factory=Track)
    origin: str = ""
    scenario: Scenario | None = None


def looks_like_file(text: str) -> bool:
    """True when ``text`` names a consist file rather than a scenario.

    Parameters
    ----------
    text : str

    Returns
    -------
    bool
    """
    return text.lower().endswith((".yaml", ".yml")) or "/" in text \
        or resolve_config_path(text).is_file()


def _file(input_name: str, loader, *args):
    try:
        return loader(*args)
    except RunSpecError:
        raise
    except InputError as exc:
        raise RunSpecError(input_name, exc.reason, cause=exc) from None


def resolve_run_spec(consist: str | None = None, *, scenario: str | int | None = None,
                     speed_kmh: float | None = None, params_file: str | None = None,
                     lut_file: str | None = None, v_th_mm_s: float | None = None,
                     track_file: str | None = None,
                     start_chainage_m: float | None = None) -> RunSpec:
    """Resolve and validate what to simulate.

    Parameters
    ----------
    consist : str, optional
        Consist YAML file, or a scenario name or number (``scenario_6``, ``6``).
    scenario : str or int, optional
        Paper scenario; with ``consist`` a file, the file's train runs at the scenario's speed.
    speed_kmh : float, optional
        Initial speed [km/h], 0 to 400; ``None`` takes the scenario's (a negative or
        non-finite speed is refused).
    params_file, lut_file, track_file : str, optional
        Files; ``None`` or empty takes the shipped default (brake parameters:
        :func:`~ltd_brake_ros.inputs.default_brake_params` of the train).
    v_th_mm_s : float, optional
        Eq. 3 threshold speed overriding the coupler table's [mm/s].
    start_chainage_m : float, optional
        Chainage of the head's front at t = 0 [m] (default: the track file's, else 0).

    Returns
    -------
    RunSpec

    Raises
    ------
    RunSpecError
        Naming the input and the reason.
    """
    sc = None
    if scenario is not None and str(scenario).strip():
        sc = _file("consist", get_scenario, scenario)
    consist = (consist or "").strip()
    if consist and not looks_like_file(consist) and sc is None:
        sc = _file("consist", get_scenario, consist)
        consist = ""
    if consist:
        train, origin = _file("consist", load_consist, consist), f"file {consist}"
    elif sc is not None:
        train, origin = sc.consist(), f"scenario {sc.number}"
    else:
        raise RunSpecError("consist", "is empty: give a consist file or a scenario (e.g. "
                           "scenario_6)")
    if speed_kmh is not None and not math.isfinite(speed_kmh):
        raise RunSpecError("speed_kmh", f"must be a finite number of km/h, got {speed_kmh}")
    lo, hi = SPEED_RANGE_KMH
    if speed_kmh is not None and speed_kmh < lo:
        raise RunSpecError("speed_kmh", f"must be between {lo:g} and {hi:g} km/h, got "
                           f"{speed_kmh:g} (a speed, not a direction: the train runs forward)")
    if speed_kmh is not None:
        speed = float(speed_kmh)
    elif sc is not None:
        speed = float(sc.speed_kmh)
    else:
        raise RunSpecError("speed_kmh", "must be given (0 to 400 km/h) when the train comes "
                           "from a consist file; only a scenario brings its own speed")
    if not (math.isfinite(speed) and lo <= speed <= hi):
        raise RunSpecError("speed_kmh", f"must be between {lo:g} and {hi:g} km/h, got {speed}")
    params = (_file("brake_params", load_brake_params, params_file) if params_file
              else default_brake_params(train))
    lut = _file("coupler_lut", load_coupler_lut, lut_file or None, v_th_mm_s)
    if track_file:
        track = _file("track", load_track, track_file, start_chainage_m)
    else:
        track = Track(start_chainage_m=start_chainage_m or 0.0)
    return RunSpec(train, speed, params, lut, track, origin, sc)

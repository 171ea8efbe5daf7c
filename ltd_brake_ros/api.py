"""The public Python API: load inputs, run a stop or a command script, read a recording.

Every function here is re-exported by the package (``from ltd_brake_ros import ...``) and listed
in its ``__all__``; everything else is internal and may move. SI units everywhere unless a name
says otherwise; vehicle 0 is the head; coupler j joins vehicles j - 1 and j; coupler forces are
positive in draft (tension), negative in buff; brake forces are retarding forces, positive.

Time series come as :class:`TimeSeries`: NumPy arrays, a tidy pandas DataFrame
(:meth:`TimeSeries.to_dataframe`) and an xarray Dataset (:meth:`TimeSeries.to_xarray`); Parquet
files need pyarrow (``pip install 'ltd_brake_ros[analysis]'``).

Example
-------
>>> from ltd_brake_ros import load_consist, emergency_stop
>>> run = emergency_stop(load_consist("scenario_6"), 100.0)  # doctest: +SKIP
>>> run.summary.stopping_distance_m  # doctest: +SKIP
489.2
>>> run.to_dataframe("coupler").groupby("coupler").coupler_force_N.max()  # doctest: +SKIP
"""
from __future__ import annotations

import csv
import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .inputs import (BrakeParams, CommandScript, Consist, CouplerLUT, InputError, Track,
                     consist_from_mapping, get_scenario)
from .inputs import load_brake_params as _load_brake_params
from .inputs import load_command_script
from .inputs import load_consist as _load_consist
from .inputs import load_coupler_lut, load_track as _load_track
from .inputs.commands import command_script_from_mapping
from .run_spec import looks_like_file
from .physics.kernel import DEFAULT_TOLERANCE_M_S
from .simulator import Simulator, Snapshot
from .studies.runs import StopResult, emergency_run, scripted_run, summarize
from .verdicts import Verdicts

__all__ = ["RunResult", "TimeSeries", "Recording", "load_consist", "load_brake_params",
           "load_coupler", "load_track", "load_commands", "emergency_stop", "run_commands",
           "read_recording", "load_campaign", "run_campaign", "read_campaign"]

#: Per-vehicle quantities of a time series: name -> (unit, description).
VEHICLE_QUANTITIES = {
    "position_m": ("m", "chainage of the vehicle's centre (the head's front starts at 0)"),
    "speed_m_s": ("m/s", "speed, forward positive"),
    "brake_force_N": ("N", "air-brake retarding force, positive"),
    "traction_force_N": ("N", "traction (positive) or dynamic-brake (negative) force"),
    "block_force_N": ("N", "total force on the brake blocks or pads, F_B,tot"),
    "block_temperature_K": ("K", "brake-block temperature, lumped (NaN: no block brakes)"),
    "wheel_temperature_K": ("K", "wheel (tread and rim) temperature, lumped (NaN: no block "
                                 "brakes)"),
    "brake_pipe_pressure_Pa": ("Pa", "brake-pipe pressure at the vehicle, gauge (the brake-pipe "
                                     "model only)"),
    "brake_cylinder_pressure_Pa": ("Pa", "brake-cylinder pressure, gauge (the brake-pipe model "
                                         "only)"),
}
#: Quantities a snapshot carries among its extras rather than as fields (the pressures only
#: where the brake model has them: a time series holds those its run had).
_EXTRAS = ("block_temperature_K", "wheel_temperature_K", "brake_pipe_pressure_Pa",
           "brake_cylinder_pressure_Pa")
#: Per-coupler quantities of a time series: name -> (unit, description).
COUPLER_QUANTITIES = {
    "coupler_force_N": ("N", "coupler force, draft (tension) positive, buff negative"),
}
_SIGN = ("vehicle 0 is the head; coupler j joins vehicles j-1 and j; coupler forces positive in "
         "draft (tension), negative in buff; brake forces are retarding forces, positive")


# --------------------------------------------------------------------------- inputs


def _warn_axle_loads(consist: Consist) -> None:
    """A :class:`UserWarning` per group of vehicles too heavy for a line category."""
    import warnings

    from .inputs.consist import axle_load_warnings

    for line in axle_load_warnings(consist):
        warnings.warn(f"{consist.name}: {line}", UserWarning, stacklevel=3)


def load_consist(source: str | int | os.PathLike | Mapping) -> Consist:
    """A train: a consist file, a paper scenario's train, or a mapping.

    Parameters
    ----------
    source : str, int, path-like or mapping
        A consist YAML file (relative names are also looked up in the shipped ``config/``), a
        scenario of the paper's Tables 1-2 (``"scenario_6"``, ``"6"`` or ``6``), or the
        mapping a consist file holds (``{"vehicles": [{"type": "E402B"}, ...]}``).

    Returns
    -------
    Consist

    Raises
    ------
    InputError
        Naming the file or scenario, the field and the reason.

    Warns
    -----
    UserWarning
        A vehicle whose axle load needs a category E line (above 22.5 t) or exceeds every
        EN 15528 line category (above 25 t), naming it.

    Examples
    --------
    >>> from ltd_brake_ros import load_consist
    >>> load_consist("scenario_6")  # doctest: +SKIP
    Consist('E402B + 32 Shimmns (50 t)': 33 vehicles, 423.9 m, 1689 t: E402B + 32 x Shimmns)
    >>> load_consist({"vehicles": [{"type": "E402B"}, {"type": "Shimmns", "count": 3}]}).n  # doctest: +SKIP
    4
    """
    if isinstance(source, Mapping):
        out = consist_from_mapping(source, "consist mapping")
    elif isinstance(source, int) or (isinstance(source, str) and not looks_like_file(source)):
        out = get_scenario(source).consist()
    else:
        out = _load_consist(source)
    _warn_axle_loads(out)
    return out


def load_brake_params(source: str | os.PathLike | None = None) -> BrakeParams:
    """Brake parameters from a file (default: the paper's Table 3 with K0 = 2.72).

    Parameters
    ----------
    source : str or path-like, optional
        A brake-parameter YAML file, e.g. ``brake_params/uic_brake_pipe.yaml`` (relative
        names are also looked up in the shipped ``config/``).

    Returns
    -------
    BrakeParams
        The brake model's parameters (``pneumatic``: delays [s], fill time [s], ...;
        ``friction``: the block friction's k factor and laws; the thermal fields).

    Raises
    ------
    InputError
        Naming the file, the field and the reason.

    Examples
    --------
    >>> from ltd_brake_ros import load_brake_params
    >>> paper = load_brake_params()
    >>> pipe = load_brake_params("brake_params/uic_brake_pipe.yaml")  # doctest: +SKIP
    """
    return _load_brake_params(source)


def load_coupler(source: str | os.PathLike | None = None) -> CouplerLUT:
    """A coupler characteristic from a file (default: the shipped buffer-hook table).

    Parameters
    ----------
    source : str or path-like, optional
        A coupler YAML file, e.g. ``couplers/buffer_hook_fig4.yaml``.

    Returns
    -------
    CouplerLUT
        Its model's parameters (for the default table: deflections [m], loading and unloading
        forces [N], strengths [N]).

    Raises
    ------
    InputError
        Naming the file, the field and the reason.

    Examples
    --------
    >>> from ltd_brake_ros import load_coupler
    >>> lut = load_coupler("couplers/buffer_hook_pugi.yaml")
    >>> lut.draft_strength_N > 0
    True
    """
    return load_coupler_lut(source)


def load_track(source: str | os.PathLike | None = None) -> Track:
    """A track profile from a file (default: level straight track).

    Parameters
    ----------
    source : str or path-like, optional
        A track YAML file, e.g. ``tracks/hump_10permille.yaml``; None: level straight track.

    Returns
    -------
    Track
        Gradients [permille] and curves [m radius] by chainage [m].

    Raises
    ------
    InputError
        Naming the file, the field and the reason.

    Examples
    --------
    >>> from ltd_brake_ros import load_track
    >>> hump = load_track("tracks/hump_10permille.yaml")  # doctest: +SKIP
    """
    return Track() if source is None else _load_track(source)


def load_commands(source: str | os.PathLike | Mapping | Sequence) -> CommandScript:
    """A timed command script: a file, a mapping ``{"commands": [...]}`` or the list itself.

    Parameters
    ----------
    source : str, path-like, mapping or sequence
        E.g. ``[{"t_s": 0, "brake_demand": 0.5}, {"t_s": 20, "emergency": True}]``: times
        [s], brake and traction demands [-, 0 to 1], the emergency brake (true/false).

    Returns
    -------
    CommandScript
        The timed steps, in time order.

    Raises
    ------
    InputError
        Naming the file or entry (``commands[0]``), the field and the reason.

    Examples
    --------
    >>> from ltd_brake_ros import load_commands
    >>> load_commands([{"t_s": 0, "brake_demand": 0.5}, {"t_s": 20, "emergency": True}]).steps[1]
    (20.0, {'emergency': True})
    """
    if isinstance(source, Mapping):
        return command_script_from_mapping(source, "commands mapping")
    if isinstance(source, Sequence) and not isinstance(source, str):
        return command_script_from_mapping({"commands": list(source)}, "commands list")
    return load_command_script(source)


# --------------------------------------------------------------------------- time series


@dataclass
class TimeSeries:
    """Per-vehicle and per-coupler histories of a run, sampled at chunk ends.

    Attributes
    ----------
    time_s : ndarray, shape (k,)
        Simulated time of each sample [s].
    vehicles : dict of str to ndarray, shape (k, n)
        :data:`VEHICLE_QUANTITIES` (those recorded), SI units in the names.
    couplers : dict of str to ndarray, shape (k, n - 1)
        :data:`COUPLER_QUANTITIES`.
    vehicle_names : list of str
        Type name of each vehicle, head first.
    attrs : dict
        Run information (consist, initial speed, ...).

    Examples
    --------
    >>> ts = emergency_stop("scenario_6", 100.0).timeseries  # doctest: +SKIP
    >>> ts.time_s[:3]                                         # doctest: +SKIP
    array([0. , 0.1, 0.2])
    >>> ts.vehicles["speed_m_s"].shape                        # doctest: +SKIP
    (289, 33)
    """

    time_s: np.ndarray
    vehicles: dict
    couplers: dict
    vehicle_names: list = field(default_factory=list)
    attrs: dict = field(default_factory=dict)

    @property
    def n_vehicles(self) -> int:
        """Vehicles in the train."""
        return next(iter(self.vehicles.values())).shape[1] if self.vehicles else 0

    @property
    def time_ns(self) -> np.ndarray:
        """The sample times as whole nanoseconds (int64), the stamps of a recording [ns]."""
        return np.round(self.time_s * 1e9).astype(np.int64)

    def __eq__(self, other) -> bool:
        """Equal names, attributes and arrays, bit for bit (NaN equal to NaN)."""
        def same(a, b) -> bool:
            a, b = np.asarray(a), np.asarray(b)
            return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()

        return (isinstance(other, TimeSeries) and same(self.time_s, other.time_s)
                and self.vehicles.keys() == other.vehicles.keys()
                and self.couplers.keys() == other.couplers.keys()
                and all(same(a, other.vehicles[k]) for k, a in self.vehicles.items())
                and all(same(a, other.couplers[k]) for k, a in self.couplers.items())
                and list(self.vehicle_names) == list(other.vehicle_names)
                and self.attrs == other.attrs)

    __hash__ = None

    def __repr__(self) -> str:
        k, t = self.time_s.size, self.time_s
        span = f"{t[0]:g}-{t[-1]:g} s" if k else "no samples"
        every = f" every {t[1] - t[0]:.6g} s" if k > 1 else ""
        return (f"TimeSeries({k} samples, {span}{every}; {self.n_vehicles} vehicles: "
                f"{', '.join(self.vehicles)}; couplers: {', '.join(self.couplers)}; "
                ".to_dataframe(), .to_xarray())")

    def _repr_html_(self) -> str:
        from ._display import html_table

        units = {**VEHICLE_QUANTITIES, **COUPLER_QUANTITIES}
        rows = [(name, units[name][0], "x".join(map(str, a.shape)), units[name][1])
                for name, a in (*self.vehicles.items(), *self.couplers.items())]
        return html_table(repr(self).split(";")[0], rows,
                          ["quantity", "unit", "shape (time x element)", "meaning"])

    def _long(self) -> dict:
        """The long (tidy) columns: one row per time, element and quantity."""
        cols: dict[str, list] = {"time_s": [], "element": [], "number": [], "quantity": [],
                                 "unit": [], "value": []}
        for element, table, units in (("vehicle", self.vehicles, VEHICLE_QUANTITIES),
                                      ("coupler", self.couplers, COUPLER_QUANTITIES)):
            base = 0 if element == "vehicle" else 1
            for name, a in table.items():
                k, m = a.shape
                cols["time_s"].append(np.repeat(self.time_s, m))
                cols["element"].append(np.full(k * m, element, dtype=object))
                cols["number"].append(np.tile(np.arange(base, base + m), k))
                cols["quantity"].append(np.full(k * m, name, dtype=object))
                cols["unit"].append(np.full(k * m, units[name][0], dtype=object))
                cols["value"].append(a.reshape(-1))
        return {c: (np.concatenate(v) if v else np.zeros(0)) for c, v in cols.items()}

    def to_dataframe(self, element: str | None = "vehicle"):
        """The histories as a tidy pandas DataFrame.

        Parameters
        ----------
        element : {"vehicle", "coupler", None}, optional
            ``vehicle``: one row per time and vehicle, a column per quantity (``time_s``,
            ``vehicle``, ``position_m``, ``speed_m_s``, ...); ``coupler``: one row per time and
            coupler (``time_s``, ``coupler``, ``coupler_force_N``); None: the long form, one
            row per time, element and quantity (``time_s``, ``element``, ``number``,
            ``quantity``, ``unit``, ``value``).

        Returns
        -------
        pandas.DataFrame
            Units and descriptions in ``df.attrs["units"]``, ``df.attrs["descriptions"]``; the
            sign convention in ``df.attrs["conventions"]``.

        Raises
        ------
        ImportError
            pandas is not installed (a dependency of the package: reinstall it).
        """
        pd = _optional("pandas")
        if element is None:
            df = pd.DataFrame(self._long())
            units = {"time_s": "s"}
        elif element in ("vehicle", "coupler"):
            table = self.vehicles if element == "vehicle" else self.couplers
            quantities = VEHICLE_QUANTITIES if element == "vehicle" else COUPLER_QUANTITIES
            k = self.time_s.size
            m = next(iter(table.values())).shape[1] if table else 0
            base = 0 if element == "vehicle" else 1
            data = {"time_s": np.repeat(self.time_s, m),
                    element: np.tile(np.arange(base, base + m), k)}
            data.update({name: a.reshape(-1) for name, a in table.items()})
            df = pd.DataFrame(data)
            units = {"time_s": "s", **{n: quantities[n][0] for n in table}}
            df.attrs["descriptions"] = {n: quantities[n][1] for n in table}
        else:
            raise ValueError(f"element must be 'vehicle', 'coupler' or None, got {element!r}")
        df.attrs["units"] = units
        df.attrs["conventions"] = _SIGN
        df.attrs.update({k: v for k, v in self.attrs.items() if isinstance(v, (str, float, int))})
        return df

    def to_xarray(self):
        """The histories as an xarray Dataset: dims ``time`` x ``vehicle`` and ``time`` x
        ``coupler``, units and descriptions in each variable's attrs.

        Returns
        -------
        xarray.Dataset

        Raises
        ------
        ImportError
            xarray is not installed (a dependency of the package: reinstall it).
        """
        xr = _optional("xarray")
        n = self.n_vehicles
        data = {}
        for name, a in self.vehicles.items():
            unit, desc = VEHICLE_QUANTITIES[name]
            data[name] = (("time", "vehicle"), a, {"units": unit, "description": desc})
        for name, a in self.couplers.items():
            unit, desc = COUPLER_QUANTITIES[name]
            data[name] = (("time", "coupler"), a, {"units": unit, "description": desc})
        coords = {"time": ("time", self.time_s, {"units": "s", "description": "simulated time"}),
                  "vehicle": ("vehicle", np.arange(n), {"description": "0 is the head"}),
                  "coupler": ("coupler", np.arange(1, max(n, 1)),
                              {"description": "coupler j joins vehicles j-1 and j"})}
        if self.vehicle_names and len(self.vehicle_names) == n:
            coords["vehicle_name"] = ("vehicle", np.array(self.vehicle_names, dtype=object))
        attrs = {"conventions": _SIGN, **{k: v for k, v in self.attrs.items()
                                          if isinstance(v, (str, float, int))}}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def write(self, path: str | os.PathLike) -> Path:
        """Write the long (tidy) form to a file: Parquet (``.parquet``) or CSV (``.csv``).

        Parameters
        ----------
        path : str or path-like

        Returns
        -------
        Path

        Raises
        ------
        InputError
            The suffix is neither, or pyarrow is missing for Parquet.
        FileExistsError
            ``path`` exists: a time series never replaces a file
            (:func:`~ltd_brake_ros.outputs.new_file`; a failed write leaves nothing).
        """
        from .outputs import new_file

        p = Path(path)
        cols = self._long()
        if p.suffix.lower() == ".csv":
            with new_file(p, "w", newline="", encoding="utf-8") as f:
                w = csv.writer(f)
                w.writerow(list(cols))
                for row in zip(*(c.tolist() for c in cols.values())):
                    w.writerow(row)
            return p
        if p.suffix.lower() == ".parquet":
            try:
                import pyarrow as pa
                import pyarrow.parquet as pq
            except ImportError:
                raise InputError(str(p), "", "writing Parquet needs pyarrow: pip install "
                                 "'ltd_brake_ros[analysis]', or write a .csv") from None
            table = pa.table({k: (v.astype(str) if v.dtype == object else v)
                              for k, v in cols.items()})
            meta = {b"conventions": _SIGN.encode(), b"attrs": json.dumps(
                {k: v for k, v in self.attrs.items() if isinstance(v, (str, float, int))}
            ).encode()}
            with new_file(p, "wb") as f:
                pq.write_table(table.replace_schema_metadata(meta), f)
            return p
        raise InputError(str(p), "", "time series are written as .parquet or .csv")


def _equal(a, b) -> bool:
    """Equal results: dataclasses field by field, arrays bit for bit, NaN equal to NaN."""
    import dataclasses

    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if dataclasses.is_dataclass(a) and not isinstance(a, (TimeSeries, RunResult)):
        return all(_equal(getattr(a, f.name), getattr(b, f.name))
                   for f in dataclasses.fields(a))
    if hasattr(a, "__dict__") and not dataclasses.is_dataclass(a) and \
            type(a).__eq__ is object.__eq__:
        return _equal(vars(a), vars(b))
    return bool(a == b)


def _optional(name: str):
    try:
        return __import__(name)
    except ImportError:
        raise ImportError(f"{name} is not installed: pip install pandas xarray (both are "
                          "dependencies of ltd_brake_ros: reinstall it)") from None


def _stamp_ns(time_s: float) -> int:
    """A simulated time on the nanosecond grid [ns]: the stamp a recording gives the same
    state (the simulator sums its steps in floating point, 0.1 s ten times being
    0.9999999999999999 s)."""
    return round(time_s * 1e9)


def _seconds(stamps_ns) -> np.ndarray:
    """Nanosecond stamps as seconds, each the float nearest to its exact value (a division,
    correctly rounded: 300_000_000 ns is 0.3 as written)."""
    return np.asarray(stamps_ns, np.int64) / 1e9


class _Sampler:
    """Collects snapshots into a :class:`TimeSeries`, the state at t = 0 first
    (:meth:`start`)."""

    def __init__(self):
        self.t: list[int] = []
        self.v: dict[str, list] | None = None  # the quantities of the first snapshot
        self.c: list = []

    def start(self, sim: Simulator) -> None:
        """Sample the state before the first chunk (t = 0)."""
        self(sim.snapshot())

    def __call__(self, snap: Snapshot) -> None:
        if self.v is None:
            self.v = {k: [] for k in VEHICLE_QUANTITIES if k not in _EXTRAS or k in snap.extras}
        self.t.append(_stamp_ns(snap.time_s))
        for k, a in self.v.items():
            a.append(np.array(snap.extras[k] if k in _EXTRAS else getattr(snap, k), float))
        self.c.append(np.array(snap.coupler_force_N, float))

    def series(self, sim: Simulator, attrs: dict) -> TimeSeries:
        n = sim.n
        return TimeSeries(_seconds(self.t),
                          {k: np.array(a, float).reshape(len(self.t), n)
                           for k, a in (self.v or {}).items()},
                          {"coupler_force_N": np.array(self.c, float).reshape(
                              len(self.t), max(n - 1, 0))},
                          [v.name for v in sim.consist.vehicles], attrs)


# --------------------------------------------------------------------------- runs


@dataclass
class RunResult:
    """A simulated run: its summary, its verdicts, its brake heat and its time series.

    A run pickles (a process pool, joblib or Dask can return it) and comes back equal in
    every result field, arrays bit for bit; the live simulator is not carried
    (``simulator`` is None after unpickling: run again to go on).

    Attributes
    ----------
    summary : StopResult or None
        Stopping distance, peak forces with their couplers, cost (None: the train did not stop).
    verdicts : Verdicts
        The judgments on the run (:mod:`ltd_brake_ros.verdicts`).
    timeseries : TimeSeries
        The histories, sampled every ``sample_s`` from t = 0.
    simulator : Simulator or None
        The simulator at the end of the run (for further queries or to go on); None in a
        copy that was pickled.
    brake_heat : Peaks or None
        The hottest brake blocks and wheels: ``block_K``, ``wheel_K`` [K], which vehicle and
        when [s], the air's ``ambient_K``
        (:class:`~ltd_brake_ros.physics.brakes.thermal.Peaks`; NaN without block brakes).
    stops : tuple of StopRecord
        Every stop of the run, each its own record: brake command time and speed, stopping
        distance and time, settled time, peak forces with their couplers, and its verdicts
        (:class:`~ltd_brake_ros.stops.StopRecord`).
    band : BandResult or None
        The stop under every member of a model-form band, when asked for
        (:class:`~ltd_brake_ros.studies.band.BandResult`; the summary, verdicts and time
        series are then the nominal member's).

    Examples
    --------
    >>> run = emergency_stop(load_consist("scenario_6"), 100.0)  # doctest: +SKIP
    >>> run.brake_heat.block_K - 273.15                          # doctest: +SKIP
    """

    summary: StopResult | None
    verdicts: Verdicts
    timeseries: TimeSeries
    simulator: Simulator | None = field(default=None, compare=False)
    brake_heat: Any = None
    stops: tuple = ()
    band: Any = None

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["simulator"] = None  # compiled kernels and live state do not travel
        return state

    def __eq__(self, other) -> bool:
        """Equal in every result field (arrays bit for bit; the simulator aside)."""
        return isinstance(other, RunResult) and all(
            _equal(getattr(self, k), getattr(other, k))
            for k in ("summary", "verdicts", "timeseries", "brake_heat", "stops", "band"))

    __hash__ = None

    def __repr__(self) -> str:
        s = self.summary
        head = repr(s) if s is not None else "the train did not stop"
        heat = "" if self.brake_heat is None or not np.isfinite(self.brake_heat.block_K) else \
            f"; hottest blocks {self.brake_heat.block_K - 273.15:.0f} C"
        return (f"RunResult({head}; verdicts {self.verdicts.status}{heat}; "
                f"{self.timeseries.time_s.size} samples)")

    def _repr_html_(self) -> str:
        parts = [f"<b>RunResult</b>: verdicts {self.verdicts.status}"]
        if self.summary is not None:
            parts.append(self.summary._repr_html_())
        parts.append(self.verdicts._repr_html_())
        return "".join(parts)

    def to_dataframe(self, element: str | None = "vehicle"):
        """:meth:`TimeSeries.to_dataframe` of the run."""
        return self.timeseries.to_dataframe(element)

    def to_xarray(self):
        """:meth:`TimeSeries.to_xarray` of the run."""
        return self.timeseries.to_xarray()


def _announce_compile(**simulator_kwargs) -> None:
    """On the first run after installing, compile the simulation kernels (in the background
    while the run starts as plain Python, :func:`~ltd_brake_ros.first_run.prepare`), saying so
    with the compile's estimated duration on stderr."""
    import sys

    from .first_run import prepare

    def say(line: str) -> None:
        print(f"ltd_brake_ros: {line}", file=sys.stderr, flush=True)

    prepare(simulator_kwargs, say)


def _train(consist) -> Consist:
    """A :class:`Consist`, or what :func:`load_consist` loads one from (a scenario name or
    number, a consist file, a mapping); anything else is one line."""
    if isinstance(consist, (str, int, os.PathLike, Mapping)) and not isinstance(consist, bool):
        consist = load_consist(consist)
    if isinstance(consist, Consist):
        _warn_axle_loads(consist)
        return consist
    raise InputError("consist", "", f"expected a Consist (load_consist(...)), a scenario, a "
                     f"consist file or a mapping, got {type(consist).__name__}")


def _speed(speed_kmh, *, at_rest: bool) -> float:
    """The initial speed [km/h], checked: finite, 0 to 400, above 0 for a stop from speed."""
    from .run_spec import SPEED_RANGE_KMH

    lo, hi = SPEED_RANGE_KMH
    try:
        v = float(speed_kmh)
    except (TypeError, ValueError):
        raise InputError("speed_kmh", "", f"must be a number of km/h, got {speed_kmh!r}") \
            from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise InputError("speed_kmh", "", f"must be between {lo:g} and {hi:g} km/h, got {v:g}")
    if v == 0.0 and not at_rest:
        raise InputError("speed_kmh", "", "an emergency stop needs a speed above 0 km/h "
                         "(run_commands may start at rest)")
    return v


def _rail_condition(spec, name: str):
    """An adhesion condition of the API (None: not given)."""
    from .inputs.adhesion import adhesion_condition

    return adhesion_condition(spec, name)


def _attrs(sim: Simulator, speed_kmh: float) -> dict:
    return {"consist": sim.consist.name, "initial_speed_kmh": float(speed_kmh),
            "step_s": sim.step_s, "tolerance_m_s": float(sim.tolerance_m_s)}


def emergency_stop(consist: Consist, speed_kmh: float, *, params: BrakeParams | None = None,
                   coupler: CouplerLUT | None = None, track: Track | None = None,
                   sample_s: float = 0.1, step_s: float = 0.01,
                   tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                   max_time_s: float = 600.0, band=False, adhesion=None,
                   rail=None) -> RunResult:
    """Apply the emergency brake at t = 0 and run to the stop, the train settled.

    Parameters
    ----------
    consist : Consist, str, int, path-like or mapping
        The train: a :class:`Consist`, or what :func:`load_consist` loads one from
        (``"scenario_6"``, ``6``, a consist file, a mapping).
    speed_kmh : float
        Initial speed [km/h], above 0 and at most 400.
    params, coupler, track : optional
        Model inputs (defaults: :func:`load_brake_params`, :func:`load_coupler`, level track).
    sample_s : float, optional
        Interval of the time series' samples [s] (the integration runs at ``step_s`` with its
        error control whatever the sampling).
    step_s : float, optional
        Largest integration step [s].
    tolerance_m_s : float or None, optional
        Local error allowed per step in each vehicle's speed [m/s] (0 or None: fixed steps).
    max_time_s : float, optional
        Give up if the train has not stopped by then [s].
    band : bool, str, path-like or ModelFormBand, optional
        Also run the stop under every member of a model-form band (True: the shipped
        ``bands/model_form.yaml``; a file; or a loaded band): :attr:`RunResult.band`.
    adhesion : str, float, path-like or AdhesionCondition, optional
        Model wheel slide against this rail: ``dry``, ``wet``, ``low``, a constant mu, or an
        adhesion YAML file (default: off, as in the paper's method; see the wheel-slide page).
    rail : str, float, path-like or AdhesionCondition, optional
        The rail the adhesion-demand check judges against (default: ``adhesion``'s, else
        ``dry``); the run is not changed.

    Returns
    -------
    RunResult

    Raises
    ------
    InputError
        A consist that cannot be loaded, a speed that is not a finite number above 0, an
        unknown rail condition, a band asked for with ``adhesion`` or ``rail``.
    SimulationError
        A step failed, or the train did not stop within ``max_time_s``.

    Examples
    --------
    >>> from ltd_brake_ros import emergency_stop
    >>> run = emergency_stop("scenario_6", 100.0)  # doctest: +SKIP
    >>> run.summary.stopping_distance_m            # doctest: +SKIP
    489.2
    """
    consist, speed_kmh = _train(consist), _speed(speed_kmh, at_rest=False)
    _announce_compile(consist=consist, speed_kmh=speed_kmh, params=params, lut=coupler,
                      track=track, step_s=step_s, tolerance_m_s=tolerance_m_s)
    adhesion, rail = _rail_condition(adhesion, "adhesion"), _rail_condition(rail, "rail")
    sampler = _Sampler()
    start = time.perf_counter()
    result = None
    if band is not False and band is not None:
        if adhesion is not None or rail is not None:
            raise InputError("band", "", "a model-form band runs the paper's method on a "
                             "nominal rail: leave out adhesion and rail")
        from .inputs.band import ModelFormBand, load_band
        from .studies.band import run_band

        members = band if isinstance(band, ModelFormBand) else load_band(
            None if band is True else band)
        result, sim = run_band(consist, speed_kmh, params, coupler, track, band=members,
                               step_s=step_s, tolerance_m_s=tolerance_m_s, chunk_s=sample_s,
                               max_time_s=max_time_s, on_nominal=sampler,
                               on_nominal_start=sampler.start)
    else:
        sim = emergency_run(consist, speed_kmh, params, coupler, track, adhesion=adhesion,
                            rail=rail, step_s=step_s, tolerance_m_s=tolerance_m_s,
                            chunk_s=sample_s,
                            max_time_s=max_time_s, on_chunk=sampler, on_start=sampler.start)
    summary = summarize(sim, time.perf_counter() - start)
    return RunResult(summary, sim.verdicts(), sampler.series(sim, _attrs(sim, speed_kmh)), sim,
                     sim.brake_temperatures(), sim.stops, result)


def run_commands(consist: Consist, speed_kmh: float, commands, *,
                 params: BrakeParams | None = None, coupler: CouplerLUT | None = None,
                 track: Track | None = None, sample_s: float = 0.1, step_s: float = 0.01,
                 tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                 max_time_s: float = 3600.0, adhesion=None, rail=None) -> RunResult:
    """Run a train under a timed command script (service brake, traction, emergency).

    Parameters
    ----------
    consist : Consist, str, int, path-like or mapping
        As for :func:`emergency_stop`.
    speed_kmh : float
        Initial speed [km/h], 0 (at rest) to 400.
    commands : CommandScript, path-like, mapping or list
        See :func:`load_commands`; the commands change at sample boundaries.
    params, coupler, track, sample_s, step_s, tolerance_m_s : optional
        As for :func:`emergency_stop`.
    max_time_s : float, optional
        Upper bound when the script has no duration and the train does not stop [s].
    adhesion, rail : optional
        As for :func:`emergency_stop`.

    Returns
    -------
    RunResult
        ``summary`` is None when the train did not stop.

    Raises
    ------
    InputError
        A consist or script that cannot be loaded, a speed that is not finite or is negative.
    SimulationError
        A step failed.

    Examples
    --------
    >>> from ltd_brake_ros import run_commands
    >>> run = run_commands("scenario_1", 0.0, [{"t_s": 0, "traction": 0.5}], max_time_s=60)  # doctest: +SKIP
    """
    consist, speed_kmh = _train(consist), _speed(speed_kmh, at_rest=True)
    script = commands if isinstance(commands, CommandScript) else load_commands(commands)
    _announce_compile(consist=consist, speed_kmh=speed_kmh, params=params, lut=coupler,
                      track=track, step_s=step_s, tolerance_m_s=tolerance_m_s)
    sampler = _Sampler()
    start = time.perf_counter()
    adhesion, rail = _rail_condition(adhesion, "adhesion"), _rail_condition(rail, "rail")
    sim = scripted_run(consist, speed_kmh, script, params, coupler, track, adhesion=adhesion,
                       rail=rail, step_s=step_s,
                       tolerance_m_s=tolerance_m_s, chunk_s=sample_s, max_time_s=max_time_s,
                       on_chunk=sampler, on_start=sampler.start)
    wall = time.perf_counter() - start
    summary = summarize(sim, wall) if sim.stopping_distance_m is not None else None
    return RunResult(summary, sim.verdicts(), sampler.series(sim, _attrs(sim, speed_kmh)), sim,
                     sim.brake_temperatures(), sim.stops)


# --------------------------------------------------------------------------- recordings


@dataclass
class Recording:
    """A recorded run read back: its report and its time series.

    Attributes
    ----------
    report : RunReport
        Stopping distance, peaks, verdicts, brake pipe (:mod:`ltd_brake_ros.analysis.report`).
    timeseries : TimeSeries
        The recorded arrays (the quantities the recording holds).

    Examples
    --------
    >>> rec = read_recording("runs/demo_20261203-101500")  # doctest: +SKIP
    >>> rec.report.stopping_distance_m, rec.report.verdicts.status  # doctest: +SKIP
    """

    report: Any
    timeseries: TimeSeries

    def __repr__(self) -> str:
        r = self.report
        stop = "no stop" if r.stopping_distance_m is None else \
            f"stopping distance {r.stopping_distance_m:.1f} m"
        return (f"Recording({r.source!r}: {stop}, peak draft {r.peak_draft_kN:.1f} kN, buff "
                f"{r.peak_buff_kN:.1f} kN, verdicts {r.verdicts.status}; "
                f"{self.timeseries.time_s.size} samples)")

    def _repr_html_(self) -> str:
        from ._display import html_table, number

        r = self.report
        rows = [(k, number(getattr(r, k))) for k in (
            "stopping_distance_m", "stopping_time_s", "command_speed_kmh", "peak_draft_kN",
            "peak_draft_coupler", "peak_buff_kN", "peak_buff_coupler", "n_vehicles")]
        return html_table(f"Recording {r.source}", rows, ["field", "value"]) + \
            r.verdicts._repr_html_()

    def __eq__(self, other) -> bool:
        """Equal report and time series (arrays bit for bit, NaN equal to NaN)."""
        return isinstance(other, Recording) and self.timeseries == other.timeseries and \
            _equal(self.report, other.report)

    __hash__ = None

    def to_dataframe(self, element: str | None = "vehicle"):
        """:meth:`TimeSeries.to_dataframe` of the recording."""
        return self.timeseries.to_dataframe(element)

    def to_xarray(self):
        """:meth:`TimeSeries.to_xarray` of the recording."""
        return self.timeseries.to_xarray()


def read_recording(path: str | os.PathLike, namespace: str | None = None) -> Recording:
    """Read a recording (a ``sim_node`` or ``simulate --record`` folder, or an ``.mcap``).

    Parameters
    ----------
    path : str or path-like
        The recording's folder or ``.mcap`` file (an unfinished one is read to its last
        complete chunk).
    namespace : str, optional
        Namespace of the plant's topics (default: the first that holds them).

    Returns
    -------
    Recording
        Its report and time series (sample times on the nanosecond stamps of the recording).

    Raises
    ------
    BagError
        The recording cannot be read or holds no plant state.

    Examples
    --------
    >>> from ltd_brake_ros import read_recording
    >>> rec = read_recording("runs/demo_20261203-101500")  # doctest: +SKIP
    >>> rec.to_dataframe("coupler").coupler_force_N.max()   # doctest: +SKIP
    """
    from .analysis.report import analyse
    from .analysis.samples import ARRAYS, plant_samples

    report = analyse(path, namespace)
    names = {"vehicles/speed": "speed_m_s", "vehicles/position": "position_m",
             "vehicles/brake_force": "brake_force_N",
             "vehicles/traction_force": "traction_force_N",
             "vehicles/block_temperature": "block_temperature_K",
             "vehicles/wheel_temperature": "wheel_temperature_K",
             "couplers/force": "coupler_force_N"}
    rows: dict[int, dict] = {}  # by the stamp [ns]
    for name, t, _log, value in plant_samples(path, report.namespace, report.stamped):
        if name in names and name in ARRAYS:
            rows.setdefault(_stamp_ns(t), {})[names[name]] = np.asarray(value, float)
    times = sorted(rows)
    complete = [t for t in times if len(rows[t]) == len(
        {k for r in rows.values() for k in r})]  # samples holding every recorded quantity
    keys = sorted({k for r in rows.values() for k in r})
    vehicles = {k: np.array([rows[t][k] for t in complete], float) for k in keys
                if k in VEHICLE_QUANTITIES}
    couplers = {k: np.array([rows[t][k] for t in complete], float) for k in keys
                if k in COUPLER_QUANTITIES}
    meta = report.metadata if isinstance(report.metadata, dict) else {}
    composition = meta.get("consist", {}).get("composition") \
        if isinstance(meta.get("consist"), dict) else None
    names_list: list[str] = []
    if isinstance(composition, list):
        for item in composition:
            if isinstance(item, list) and len(item) == 2 and isinstance(item[1], int):
                names_list += [str(item[0])] * item[1]
    attrs = {"source": str(path)}
    if isinstance(meta.get("initial_speed_kmh"), (int, float)):
        attrs["initial_speed_kmh"] = float(meta["initial_speed_kmh"])
    if isinstance(meta.get("consist"), dict) and isinstance(meta["consist"].get("name"), str):
        attrs["consist"] = meta["consist"]["name"]
    return Recording(report, TimeSeries(_seconds(complete), vehicles, couplers,
                                        names_list, attrs))


# --------------------------------------------------------------------------- campaigns


def load_campaign(source: str | os.PathLike | Mapping):
    """A campaign of randomised trains: a campaign file, or the mapping such a file holds.

    Parameters
    ----------
    source : str, path-like or mapping
        E.g. ``campaigns/example.yaml``, or ``{"name": ..., "runs": 100, "families": [...],
        ...}`` (relative file names inside resolve against the shipped ``config/``).

    Returns
    -------
    Campaign
        The validated campaign (its families, variants, uncertainties, manoeuvres, seed and
        size).

    Raises
    ------
    InputError
        Naming the file or mapping, the field and the reason.

    Examples
    --------
    >>> from ltd_brake_ros import load_campaign
    >>> c = load_campaign("campaigns/example.yaml")
    >>> c.runs > 0 and c.seed >= 0
    True
    """
    from .inputs.campaign import campaign_from_mapping, load_campaign as _load

    if isinstance(source, Mapping):
        return campaign_from_mapping(dict(source), "campaign mapping")
    return _load(source)


def run_campaign(campaign, out: str | os.PathLike, *, jobs: int | None = None,
                 dask: str | None = None, progress: bool = True):
    """Run a campaign into a results folder (resumes what is missing) and read its results.

    Parameters
    ----------
    campaign : Campaign, path-like or mapping
        See :func:`load_campaign`.
    out : str or path-like
        Results folder (Parquet batches and a manifest); an existing one must hold the same
        campaign (it is completed, never mixed).
    jobs : int, optional
        Worker processes (default: all cores; 1: in this process).
    dask : str, optional
        ``local:N`` or a scheduler address ``tcp://host:8786``.
    progress : bool, optional
        Show a progress bar (``tqdm.auto``: a widget in a notebook, text on stderr
        elsewhere).

    Returns
    -------
    CampaignResults
        Every row of the folder and the report's statistics
        (:class:`~ltd_brake_ros.analysis.campaign_results.CampaignResults`).

    Raises
    ------
    InputError
        A bad campaign, or a folder of another campaign.

    Examples
    --------
    >>> from ltd_brake_ros import load_campaign, run_campaign
    >>> res = run_campaign(load_campaign("campaigns/example.yaml"), "runs/example", jobs=2)  # doctest: +SKIP
    >>> res.quantiles(kpi="peak_buff_kN")                                                  # doctest: +SKIP
    """
    import sys

    from .first_run import compile_here
    from .studies.campaign_exec import make_executor, missing_batches, prepare_folder
    from .studies.campaign_exec import run_campaign as _run
    from .studies.warm import campaign_runs

    c = campaign if hasattr(campaign, "families") else load_campaign(campaign)
    prepare_folder(c, out, create=False)  # another campaign's folder: one line, no worker
    compile_here(campaign_runs(c), lambda line: print(f"ltd_brake_ros: {line}",
                                                      file=sys.stderr, flush=True))
    bar = None
    if progress:
        from tqdm.auto import tqdm

        todo = missing_batches(c, out)
        left = sum(min(c.batch_size, c.runs - b * c.batch_size) for b in todo)
        per_train = len(c.manoeuvres)
        bar = tqdm(total=c.runs * per_train, initial=(c.runs - left) * per_train, unit="run",
                   desc=c.name)
    try:
        with make_executor(jobs, dask) as executor:
            _run(c, out, executor, progress=(lambda runs, failed: bar.update(runs)) if bar
                 else None)
    finally:
        if bar is not None:
            bar.close()
    return read_campaign(out)


def read_campaign(out: str | os.PathLike):
    """The results of a campaign folder, as an object with the report's statistics.

    Parameters
    ----------
    out : str or path-like
        A results folder of :func:`run_campaign` or ``ltd-brake campaign run``.

    Returns
    -------
    CampaignResults
        ``to_dataframe()`` (one row per train and manoeuvre, units in ``df.attrs["units"]``),
        ``quantiles()``, ``exceedance_curve()``, ``exceedance()``, ``compare()`` (the
        relative approach), ``sensitivity()``, ``report()``, ``to_html()``
        (:class:`~ltd_brake_ros.analysis.campaign_results.CampaignResults`).

    Raises
    ------
    InputError
        Not a results folder, or a damaged batch file.

    Examples
    --------
    >>> from ltd_brake_ros import read_campaign
    >>> res = read_campaign("runs/example")                        # doctest: +SKIP
    >>> df = res.to_dataframe()                                    # doctest: +SKIP
    >>> res.compare(read_campaign("runs/reference"), quantile=0.9).outcome  # doctest: +SKIP
    'not worse'
    """
    from .analysis.campaign_results import CampaignResults

    return CampaignResults(out)

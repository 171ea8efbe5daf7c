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
}
#: Per-coupler quantities of a time series: name -> (unit, description).
COUPLER_QUANTITIES = {
    "coupler_force_N": ("N", "coupler force, draft (tension) positive, buff negative"),
}
_SIGN = ("vehicle 0 is the head; coupler j joins vehicles j-1 and j; coupler forces positive in "
         "draft (tension), negative in buff; brake forces are retarding forces, positive")


# --------------------------------------------------------------------------- inputs


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
    """
    if isinstance(source, Mapping):
        return consist_from_mapping(source, "consist mapping")
    if isinstance(source, int) or (isinstance(source, str) and not looks_like_file(source)):
        return get_scenario(source).consist()
    return _load_consist(source)


def load_brake_params(source: str | os.PathLike | None = None) -> BrakeParams:
    """Brake parameters from a file (default: the paper's Table 3 with K0 = 2.72).

    Parameters
    ----------
    source : str or path-like, optional
        A brake-parameter YAML file, e.g. ``brake_params/uic_brake_pipe.yaml``.

    Returns
    -------
    BrakeParams
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
    """
    return load_coupler_lut(source)


def load_track(source: str | os.PathLike | None = None) -> Track:
    """A track profile from a file (default: level straight track).

    Parameters
    ----------
    source : str or path-like, optional
        A track YAML file, e.g. ``tracks/hump_10permille.yaml``.

    Returns
    -------
    Track
    """
    return Track() if source is None else _load_track(source)


def load_commands(source: str | os.PathLike | Mapping | Sequence) -> CommandScript:
    """A timed command script: a file, a mapping ``{"commands": [...]}`` or the list itself.

    Parameters
    ----------
    source : str, path-like, mapping or sequence
        E.g. ``[{"t_s": 0, "brake_demand": 0.5}, {"t_s": 20, "emergency": True}]``.

    Returns
    -------
    CommandScript
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


def _optional(name: str):
    try:
        return __import__(name)
    except ImportError:
        raise ImportError(f"{name} is not installed: pip install pandas xarray (both are "
                          "dependencies of ltd_brake_ros: reinstall it)") from None


class _Sampler:
    """Collects snapshots into a :class:`TimeSeries`."""

    def __init__(self):
        self.t: list[float] = []
        self.v: dict[str, list] = {k: [] for k in VEHICLE_QUANTITIES}
        self.c: list = []

    def __call__(self, snap: Snapshot) -> None:
        self.t.append(snap.time_s)
        for k, a in self.v.items():
            a.append(np.array(getattr(snap, k), float))
        self.c.append(np.array(snap.coupler_force_N, float))

    def series(self, sim: Simulator, attrs: dict) -> TimeSeries:
        n = sim.n
        return TimeSeries(np.array(self.t, float),
                          {k: np.array(a, float).reshape(len(self.t), n)
                           for k, a in self.v.items()},
                          {"coupler_force_N": np.array(self.c, float).reshape(
                              len(self.t), max(n - 1, 0))},
                          [v.name for v in sim.consist.vehicles], attrs)


# --------------------------------------------------------------------------- runs


@dataclass
class RunResult:
    """A simulated run: its summary, its verdicts and its time series.

    Attributes
    ----------
    summary : StopResult or None
        Stopping distance, peak forces with their couplers, cost (None: the train did not stop).
    verdicts : Verdicts
        The judgments on the run (:mod:`ltd_brake_ros.verdicts`).
    timeseries : TimeSeries
    simulator : Simulator
        The simulator at the end of the run (for further queries or to go on).
    """

    summary: StopResult | None
    verdicts: Verdicts
    timeseries: TimeSeries
    simulator: Simulator

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


def _attrs(sim: Simulator, speed_kmh: float) -> dict:
    return {"consist": sim.consist.name, "initial_speed_kmh": float(speed_kmh),
            "step_s": sim.step_s, "tolerance_m_s": float(sim.tolerance_m_s)}


def emergency_stop(consist: Consist, speed_kmh: float, *, params: BrakeParams | None = None,
                   coupler: CouplerLUT | None = None, track: Track | None = None,
                   sample_s: float = 0.1, step_s: float = 0.01,
                   tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                   max_time_s: float = 600.0) -> RunResult:
    """Apply the emergency brake at t = 0 and run to the stop.

    Parameters
    ----------
    consist : Consist
        E.g. :func:`load_consist` ``("scenario_6")``.
    speed_kmh : float
        Initial speed [km/h].
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

    Returns
    -------
    RunResult

    Raises
    ------
    SimulationError
        A step failed, or the train did not stop within ``max_time_s``.
    """
    _announce_compile(consist=consist, speed_kmh=speed_kmh, params=params, lut=coupler,
                      track=track, step_s=step_s, tolerance_m_s=tolerance_m_s)
    sampler = _Sampler()
    start = time.perf_counter()
    sim = emergency_run(consist, speed_kmh, params, coupler, track, step_s=step_s,
                        tolerance_m_s=tolerance_m_s, chunk_s=sample_s, max_time_s=max_time_s,
                        on_chunk=sampler)
    summary = summarize(sim, time.perf_counter() - start)
    return RunResult(summary, sim.verdicts(), sampler.series(sim, _attrs(sim, speed_kmh)), sim)


def run_commands(consist: Consist, speed_kmh: float, commands, *,
                 params: BrakeParams | None = None, coupler: CouplerLUT | None = None,
                 track: Track | None = None, sample_s: float = 0.1, step_s: float = 0.01,
                 tolerance_m_s: float | None = DEFAULT_TOLERANCE_M_S,
                 max_time_s: float = 3600.0) -> RunResult:
    """Run a train under a timed command script (service brake, traction, emergency).

    Parameters
    ----------
    consist : Consist
    speed_kmh : float
        Initial speed [km/h].
    commands : CommandScript, path-like, mapping or list
        See :func:`load_commands`; the commands change at sample boundaries.
    params, coupler, track, sample_s, step_s, tolerance_m_s : optional
        As for :func:`emergency_stop`.
    max_time_s : float, optional
        Upper bound when the script has no duration and the train does not stop [s].

    Returns
    -------
    RunResult
        ``summary`` is None when the train did not stop.
    """
    script = commands if isinstance(commands, CommandScript) else load_commands(commands)
    _announce_compile(consist=consist, speed_kmh=speed_kmh, params=params, lut=coupler,
                      track=track, step_s=step_s, tolerance_m_s=tolerance_m_s)
    sampler = _Sampler()
    start = time.perf_counter()
    sim = scripted_run(consist, speed_kmh, script, params, coupler, track, step_s=step_s,
                       tolerance_m_s=tolerance_m_s, chunk_s=sample_s, max_time_s=max_time_s,
                       on_chunk=sampler)
    wall = time.perf_counter() - start
    summary = summarize(sim, wall) if sim.stopping_distance_m is not None else None
    return RunResult(summary, sim.verdicts(), sampler.series(sim, _attrs(sim, speed_kmh)), sim)


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
    """

    report: Any
    timeseries: TimeSeries

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
    namespace : str, optional
        Namespace of the plant's topics (default: the first that holds them).

    Returns
    -------
    Recording

    Raises
    ------
    BagError
        The recording cannot be read or holds no plant state.
    """
    from .analysis.report import analyse
    from .analysis.samples import ARRAYS, plant_samples

    report = analyse(path, namespace)
    names = {"vehicles/speed": "speed_m_s", "vehicles/position": "position_m",
             "vehicles/brake_force": "brake_force_N",
             "vehicles/traction_force": "traction_force_N",
             "couplers/force": "coupler_force_N"}
    rows: dict[float, dict] = {}
    for name, t, _log, value in plant_samples(path, report.namespace, report.stamped):
        if name in names and name in ARRAYS:
            rows.setdefault(round(t, 9), {})[names[name]] = np.asarray(value, float)
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
    return Recording(report, TimeSeries(np.array(complete, float), vehicles, couplers,
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
    """
    from .inputs.campaign import campaign_from_mapping, load_campaign as _load

    if isinstance(source, Mapping):
        import hashlib

        text = json.dumps(source, sort_keys=True, default=str)
        return campaign_from_mapping(dict(source), "campaign mapping",
                                     hashlib.sha256(text.encode()).hexdigest())
    return _load(source)


def run_campaign(campaign, out: str | os.PathLike, *, jobs: int | None = None,
                 dask: str | None = None, progress: bool = False):
    """Run a campaign into a results folder (resumes what is missing).

    Parameters
    ----------
    campaign : Campaign, path-like or mapping
        See :func:`load_campaign`.
    out : str or path-like
        Results folder (Parquet batches and a manifest).
    jobs : int, optional
        Worker processes (default: all cores).
    dask : str, optional
        ``local:N`` or a scheduler address ``tcp://host:8786``.
    progress : bool, optional
        Show a progress bar on stderr.

    Returns
    -------
    pyarrow.Table
        Every row of the results folder.
    """
    import sys

    from .first_run import compile_here
    from .studies.campaign_exec import make_executor, read_results
    from .studies.campaign_exec import run_campaign as _run
    from .studies.warm import campaign_runs

    c = campaign if hasattr(campaign, "families") else load_campaign(campaign)
    compile_here(campaign_runs(c), lambda line: print(f"ltd_brake_ros: {line}",
                                                      file=sys.stderr, flush=True))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=c.runs * len(c.manoeuvres), unit="run", desc=c.name)
    with make_executor(jobs, dask) as executor:
        _run(c, out, executor, progress=(lambda runs, failed: bar.update(runs)) if bar
             else None)
    if bar is not None:
        bar.close()
    return read_results(out)[1]


def read_campaign(out: str | os.PathLike):
    """The results of a campaign folder as a pandas DataFrame (one row per train and
    manoeuvre; units of each column in ``df.attrs["units"]`` where the files state them).

    Parameters
    ----------
    out : str or path-like

    Returns
    -------
    pandas.DataFrame
    """
    from .studies.campaign_exec import read_results

    _optional("pandas")
    table = read_results(out)[1]
    df = table.to_pandas()
    meta = table.schema.metadata or {}
    units = {}
    for f in table.schema:
        m = f.metadata or {}
        if b"unit" in m:
            units[f.name] = m[b"unit"].decode()
    df.attrs["units"] = units
    if meta:
        df.attrs["schema"] = {k.decode(): v.decode(errors="replace") for k, v in meta.items()
                              if not k.startswith(b"pandas") and not k.startswith(b"ARROW")}
    return df

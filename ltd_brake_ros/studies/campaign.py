"""Campaign runs: draw run i of a campaign, run it, and summarise it as one table row.

Every random number of run i comes from the campaign seed and i alone (numpy's
``default_rng([seed, i, stream])``; Latin hypercube columns from ``[seed, dimension]``), so a
run is the same wherever and in whatever batch it executes. A designed experiment
(:class:`~ltd_brake_ros.inputs.campaign.Design`) sets some of the draws instead: a grid from
its levels (the others those of replicate j: ``default_rng([seed, j, stream])``), a Sobol' or
Morris design from row i of its sample in the unit hypercube (SALib, seeded from
``[seed, 2**31, 2]``), through the same inverse CDFs.
"""
from __future__ import annotations

import bisect
import dataclasses
import functools
import json
import math
import time

import numpy as np
import pyarrow as pa
from scipy.special import ndtr, ndtri

from .. import verdicts as verdicts_module
from ..inputs import consist_from_mapping
from ..inputs.campaign import Campaign, Distribution, fittable_parameters
from ..inputs.commands import CommandScript
from ..simulator import Commands, Simulator
from .runs import emergency_run, scripted_run, summarize

__all__ = ["COLUMNS", "KPI_FIELDS", "SCHEMA_VERSION", "describe_schema", "design_sample",
           "dimensions", "draw", "inverse_cdf", "models", "run_batch", "run_one", "schema_of",
           "warm_up"]

#: Simulated time per chunk of an emergency stop [s], and when to give up if the train has not
#: stopped [s] (as :func:`.runs.emergency_stop`). While the stop is far, several chunks are
#: advanced in one call (:func:`.runs.emergency_run`).
CHUNK_S, MAX_TIME_S = 1.0, 600.0
#: Command-update interval of service and traction runs [s]; their adhesion demand is
#: sampled at these instants (and as the train comes to rest).
SCRIPT_CHUNK_S = 0.5
#: Stream numbers of ``default_rng([seed, run, stream])``.
_RUN_STREAM, _WAGON_STREAM = 0, 1
#: The sample of a Sobol' or Morris design comes from ``default_rng([seed, _DESIGN_RUN,
#: _DESIGN_STREAM])``: a run id beyond any campaign's, so no run shares its stream.
_DESIGN_RUN, _DESIGN_STREAM = 2**31, 2


def inverse_cdf(dist: Distribution, u: float) -> float:
    """The value of ``dist`` at cumulative probability ``u``.

    Parameters
    ----------
    dist : Distribution
    u : float
        Probability in [0, 1).

    Returns
    -------
    float
    """
    kind, v = dist.kind, dist.values
    if kind == "fixed":
        return float(v[0])
    if kind == "uniform":
        return float(v[0] + u * (v[1] - v[0]))
    if kind == "normal":
        mean, sd, lo, hi = v
        p_lo, p_hi = ndtr((lo - mean) / sd), ndtr((hi - mean) / sd)
        return float(min(max(mean + sd * ndtri(p_lo + u * (p_hi - p_lo)), lo), hi))
    cdf, edges = _histogram_cdf(tuple(v))
    return float(np.interp(u, cdf, edges))


@functools.lru_cache(maxsize=64)
def _histogram_cdf(values: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative probability at each edge of a histogram (edges then weights), and the
    edges (a campaign draws from the same few histograms thousands of times)."""
    n = (len(values) + 1) // 2
    edges, weights = np.array(values[:n]), np.array(values[n:])
    return np.concatenate(([0.0], np.cumsum(weights) / weights.sum())), edges


@functools.lru_cache(maxsize=64)
def _cumulative(weights: tuple) -> list:
    """Cumulative share of each of ``weights``, as floats."""
    return (np.cumsum(weights) / np.sum(weights)).tolist()


def _choose(weights, u: float) -> int:
    """Index drawn with relative ``weights`` at probability ``u``."""
    cdf = _cumulative(tuple(weights))
    return min(bisect.bisect_right(cdf, u), len(cdf) - 1)


def _whole(lo: int, hi: int, u: float) -> int:
    """Whole number in [lo, hi] drawn uniformly at probability ``u``."""
    return min(lo + int(u * (hi - lo + 1)), hi)


def dimensions(c: Campaign) -> tuple[str, ...]:
    """Names of the run-level draws (the Latin hypercube's dimensions), in draw order.

    A design that varies ``payload_t`` adds it: the payload quantile that every loaded wagon
    of the train shares (otherwise each wagon draws its own).
    """
    dims = ("family", "size", "locomotives", "coupler", "brake_params",
            *sorted(c.uncertainties), *(f"speed_kmh:{m.name}" for m in c.manoeuvres))
    if c.design is not None and any("payload_t" in d for d in c.design.dimensions):
        dims += ("payload_t",)
    return dims


def design_sample(c: Campaign) -> np.ndarray:
    """The sample of a Sobol' or Morris design in the unit hypercube, one row per run.

    Column j is input j of the design (``c.design.inputs``). Sobol': Saltelli's scheme of a
    scrambled Sobol' sequence (``SALib.sample.sobol``), blocks of 2 D + 2 (D + 2 without
    second-order indices) rows. Morris: ``c.design.base_runs`` trajectories of D + 1 rows
    (``SALib.sample.morris``) on the levels k / (p - 1); level k is drawn at probability
    (k + 0.5) / p. These are the rows SALib's analysis takes with the runs' results.

    Parameters
    ----------
    c : Campaign
        With a ``sobol`` or ``morris`` design.

    Returns
    -------
    ndarray
        (c.runs, D), read-only.

    Raises
    ------
    InputError
        SALib is not installed.
    """
    d = c.design
    return _salib_sample(d.kind, c.seed, d.base_runs, len(d.inputs), d.second_order, d.levels)


@functools.lru_cache(maxsize=4)
def _salib_sample(kind: str, seed: int, base_runs: int, inputs: int, second_order: bool,
                  levels: int) -> np.ndarray:
    """:func:`design_sample` (once per process: every run of a batch takes its row)."""
    try:
        from SALib.sample import morris, sobol
    except ImportError:
        from ..inputs import InputError

        raise InputError("SALib", "", f"not installed; a {kind} design needs it: pip install "
                         "'ltd_brake_ros[campaign]'") from None
    problem = {"num_vars": inputs, "names": [f"x{j}" for j in range(inputs)],
               "bounds": [[0.0, 1.0]] * inputs}
    rng = np.random.default_rng([seed, _DESIGN_RUN, _DESIGN_STREAM])
    if kind == "sobol":
        x = sobol.sample(problem, base_runs, calc_second_order=second_order, scramble=True,
                         seed=rng)
    else:
        x = morris.sample(problem, base_runs, num_levels=levels, seed=rng)
    x = np.ascontiguousarray(x, dtype=float)
    x.setflags(write=False)
    return x


@functools.lru_cache(maxsize=4)
def _hypercube(seed: int, runs: int, dims: int) -> np.ndarray:
    """Latin hypercube design, (runs, dims) probabilities: one run per stratum per dimension."""
    out = np.empty((runs, dims))
    for d in range(dims):
        rng = np.random.default_rng([seed, d])
        out[:, d] = (rng.permutation(runs) + rng.random(runs)) / runs
    return out


def _unit_draws(c: Campaign, run_id: int) -> np.ndarray:
    dims = len(dimensions(c))
    if c.sampling == "latin_hypercube":
        return _hypercube(c.seed, c.runs, dims)[run_id]
    return np.random.default_rng([c.seed, run_id, _RUN_STREAM]).random(dims)


def _design_point(c: Campaign, run_id: int) -> tuple[dict, dict, int]:
    """The draws of run ``run_id``: a probability per run-level draw, the values a grid sets
    directly (draw -> value), and the train whose wagon draws it takes."""
    design = c.design
    dims = dimensions(c)
    if design is None:
        return dict(zip(dims, _unit_draws(c, run_id))), {}, run_id
    if design.kind == "grid":  # run = point * replicates + replicate; last input fastest
        point, replicate = divmod(run_id, design.base_runs)
        own = [d for d in dims if d != "payload_t"]
        u = dict(zip(own, np.random.default_rng([c.seed, replicate, _RUN_STREAM])
                     .random(len(own))))
        values = {}
        for (mode, spec), dims_j, k in zip(design.grid, design.dimensions,
                                          np.unravel_index(point, design.shape)):
            for dim in dims_j:
                if mode == "levels":
                    values[dim] = spec[k]
                else:
                    u[dim] = (k + 0.5) / spec
        return u, values, replicate
    x = design_sample(c)[run_id]
    u = dict.fromkeys(dims, 0.5)  # what the design does not vary: the median draw
    for j, dims_j in enumerate(design.dimensions):
        p = float(x[j]) if design.kind == "sobol" else \
            (float(x[j]) * (design.levels - 1) + 0.5) / design.levels
        for dim in dims_j:
            u[dim] = p
    return u, {}, 0


def _variant(items: tuple, dim: str, u: dict, values: dict):
    """The family or model variant of draw ``dim``: named by a grid, else by weight at u."""
    if dim in values:
        return next(x for x in items if x.name == values[dim])
    return items[_choose([x.weight for x in items], u[dim])]


def draw(c: Campaign, run_id: int) -> tuple[dict, dict]:
    """Compose run ``run_id`` of a campaign.

    Parameters
    ----------
    c : Campaign
    run_id : int
        0 <= run_id < c.runs; with a design, its run (a grid's point ``run_id // runs`` and
        replicate ``run_id % runs``, a row of :func:`design_sample`).

    Returns
    -------
    sample : dict
        Every drawn quantity (the row's input columns); ``speed_kmh`` maps each manoeuvre's
        name to its initial speed.
    consist_data : dict
        The consist document of the train (see
        :func:`~ltd_brake_ros.inputs.consist_from_mapping`).
    """
    u, values, train = _design_point(c, run_id)
    fam = _variant(c.families, "family", u, values)
    rng = np.random.default_rng([c.seed, train, _WAGON_STREAM])
    loco = fam.locomotives
    n_loco = values["locomotives"] if "locomotives" in values else \
        _whole(*loco.count, u["locomotives"])
    lengths = c.vehicle_lengths_m
    if "size" in values:  # a grid's wagon count or train length
        target_m = float(values["size"]) if fam.length_m else None
        n_target = int(values["size"]) if fam.wagons else None
    else:
        target_m = inverse_cdf(Distribution("uniform", fam.length_m), u["size"]) \
            if fam.length_m else None
        n_target = _whole(*fam.wagons, u["size"]) if fam.wagons else None
    length_m = n_loco * lengths[loco.type]
    wagons, codes, masses, types = [], [], [], []
    shares = [w.share for w in fam.wagon_types]
    while True:
        # five numbers per wagon, always drawn, so that each wagon's draws stay in step
        r_type, r_loaded, r_payload, r_g, r_iso = rng.random(5)
        wt = fam.wagon_types[_choose(shares, r_type)]
        if n_target is not None and len(wagons) >= n_target:
            break
        if target_m is not None and wagons and length_m + lengths[wt.type] > target_m:
            break
        loaded = r_loaded < wt.loaded_fraction
        if "payload_t" in values:  # a grid's payload of every loaded wagon
            payload = float(values["payload_t"])
        else:  # a design's quantile, shared by the train's loaded wagons, or the wagon's own
            payload = inverse_cdf(wt.payload_t, u.get("payload_t", r_payload))
        mass = wt.tare_t + (payload if loaded else 0.0)
        entry = {"type": wt.type, "mass_t": mass,
                 "brake_position": "G" if r_g < fam.g_fraction else "P"}
        isolated = r_iso < fam.isolated_fraction
        if isolated:  # an isolated brake has no position
            entry["brake"] = {"type": "none"}
            del entry["brake_position"]
        wagons.append(entry)
        masses.append(mass)
        types.append(wt.type)
        codes.append(("x" if isolated else entry["brake_position"]) + ("L" if loaded else "E"))
        length_m += lengths[wt.type]
    head = [{"type": loco.type} for p in loco.positions[:n_loco] if p == "head"]
    middle = [{"type": loco.type} for p in loco.positions[:n_loco] if p == "middle"]
    tail = [{"type": loco.type} for p in loco.positions[:n_loco] if p == "tail"]
    half = len(wagons) // 2
    vehicles = head + wagons[:half] + middle + wagons[half:] + tail
    sample = {
        "family": fam.name, "wagons": len(wagons), "locomotives": n_loco,
        "locomotive_positions": ",".join(loco.positions[:n_loco]),
        "speed_kmh": {m.name: _value(m.speed_kmh, f"speed_kmh:{m.name}", u, values)
                      for m in c.manoeuvres},
        "coupler": _variant(c.couplers, "coupler", u, values).name,
        "brake_params": _variant(c.brake_params, "brake_params", u, values).name,
        "wagon_types": types, "wagon_mass_t": masses, "wagon_brakes": " ".join(codes),
        "loaded_wagons": sum(k.endswith("L") for k in codes),
        "g_wagons": sum(k.startswith("G") for k in codes),
        "isolated_wagons": sum(k.startswith("x") for k in codes),
    }
    for name in sorted(c.uncertainties):
        sample[name] = _value(c.uncertainties[name], name, u, values)
    return sample, {"name": f"{c.name} run {run_id}", "vehicle_types": c.vehicle_types,
                    "vehicles": vehicles}


def _value(dist: Distribution, dim: str, u: dict, values: dict) -> float:
    """Draw ``dim``: a grid's level, else ``dist`` at probability u."""
    return float(values[dim]) if dim in values else inverse_cdf(dist, u[dim])


def models(c: Campaign, sample: dict):
    """Brake and coupler parameters of a run, with its uncertain parameters set.

    Parameters
    ----------
    c : Campaign
    sample : dict
        The run's draws (from :func:`draw`).

    Returns
    -------
    params : BrakeParams
    lut : CouplerLUT
    """
    params = next(v.params for v in c.brake_params if v.name == sample["brake_params"])
    lut = next(v.params for v in c.couplers if v.name == sample["coupler"])
    known = fittable_parameters()
    brake_values, coupler_values = {}, {}
    for name in sorted(c.uncertainties):
        part, fit = known[name]
        target = brake_values if part == "brake" else coupler_values
        if part == "brake" and (hasattr(params.pneumatic, fit.field)
                                or hasattr(params.friction, fit.field)):
            target[fit.field] = sample[name]
        elif part == "coupler" and hasattr(lut, fit.field):
            target[fit.field] = sample[name]
    if brake_values:
        params = dataclasses.replace(params, **brake_values)
    if coupler_values:
        lut = dataclasses.replace(lut, **coupler_values)
    return params, lut


#: Version of the results' columns and their metadata, recorded in every batch file
#: (``ltd_brake_ros.schema_version``): 2 adds each column's unit and description.
SCHEMA_VERSION = 3
#: Keys of the schema-level metadata of a batch file.
SCHEMA_VERSION_KEY, UNITS_KEY = "ltd_brake_ros.schema_version", "ltd_brake_ros.units"

#: The input columns of a row, before the uncertain parameters.
_INPUT_FIELDS = (
    ("run_id", pa.int64()), ("manoeuvre", pa.string()), ("seed", pa.int64()),
    ("status", pa.string()), ("message", pa.string()), ("family", pa.string()),
    ("wagons", pa.int32()), ("locomotives", pa.int32()), ("locomotive_positions", pa.string()),
    ("speed_kmh", pa.float64()), ("coupler", pa.string()), ("brake_params", pa.string()),
    ("wagon_types", pa.list_(pa.string())), ("wagon_mass_t", pa.list_(pa.float64())),
    ("wagon_brakes", pa.string()),
    ("loaded_wagons", pa.int32()), ("g_wagons", pa.int32()), ("isolated_wagons", pa.int32()),
)

#: The KPI columns of a row (units in the names).
KPI_FIELDS = (
    ("train_mass_t", pa.float64()), ("train_length_m", pa.float64()),
    ("braked_weight_percent", pa.float64()),
    ("stopping_distance_m", pa.float64()), ("stop_time_s", pa.float64()),
    ("peak_draft_kN", pa.float64()), ("peak_draft_coupler", pa.int32()),
    ("peak_draft_time_s", pa.float64()),
    ("peak_buff_kN", pa.float64()), ("peak_buff_coupler", pa.int32()),
    ("peak_buff_time_s", pa.float64()),
    ("mean_adhesion", pa.float64()), ("mean_adhesion_vehicle", pa.int32()),
    ("max_adhesion_demand", pa.float64()), ("max_adhesion_vehicle", pa.int32()),
    ("draft_ok", pa.bool_()), ("buff_ok", pa.bool_()), ("travel_ok", pa.bool_()),
    ("adhesion_ok", pa.bool_()), ("buffers_ok", pa.bool_()),
    ("non_physical", pa.string()), ("in_model_range", pa.bool_()),
    ("model_warnings", pa.string()),
    ("steps", pa.int64()), ("newton_iterations", pa.int64()),
    ("newton_iterations_per_step", pa.float64()), ("max_newton_iterations", pa.int32()),
    ("couplers_beyond_lut", pa.int32()),
    ("band_status", pa.string()),
    ("stopping_distance_m_min", pa.float64()), ("stopping_distance_m_max", pa.float64()),
    ("peak_draft_kN_min", pa.float64()), ("peak_draft_kN_max", pa.float64()),
    ("peak_buff_kN_min", pa.float64()), ("peak_buff_kN_max", pa.float64()),
)

#: Column -> (unit, description) of every column but the uncertain parameters (theirs come
#: from :func:`~ltd_brake_ros.inputs.campaign.fittable_parameters`). Units: SI or the one in
#: the name, ``-`` for a dimensionless number, empty for text, ids and flags.
COLUMNS = {
    "run_id": ("", "Run (train) number, 0 to runs - 1; its draws depend only on the seed and "
                   "this number."),
    "manoeuvre": ("", "Manoeuvre of the row (each train runs every manoeuvre, a row each)."),
    "seed": ("", "Campaign seed the train was drawn from."),
    "status": ("", "ok, or failed when drawing or simulating the run raised an error (its "
                   "KPIs are then null)."),
    "message": ("", "Why the run failed (error type and text); empty when status is ok."),
    "family": ("", "Train family the train was drawn from."),
    "wagons": ("-", "Number of wagons in the train."),
    "locomotives": ("-", "Number of locomotives in the train."),
    "locomotive_positions": ("", "Position of each locomotive (head, middle or tail), comma "
                                 "separated."),
    "speed_kmh": ("km/h", "Initial speed of the manoeuvre, drawn per train and manoeuvre."),
    "coupler": ("", "Coupler variant drawn for the train."),
    "brake_params": ("", "Brake-parameter variant drawn for the train."),
    "wagon_types": ("", "Vehicle type of each wagon, from the head."),
    "wagon_mass_t": ("t", "Mass of each wagon (tare plus payload if loaded), from the head."),
    "wagon_brakes": ("", "Brake code of each wagon, space separated from the head: position P "
                         "or G, or x for an isolated brake, then L loaded or E empty."),
    "loaded_wagons": ("-", "Number of loaded wagons."),
    "g_wagons": ("-", "Number of wagons with the brake in position G."),
    "isolated_wagons": ("-", "Number of wagons with the brake isolated."),
    "train_mass_t": ("t", "Mass of the train, locomotives included."),
    "train_length_m": ("m", "Length of the train over buffers."),
    "braked_weight_percent": ("%", "Braked-weight percentage of the train (lambda, UIC "
                                   "544-1)."),
    "stopping_distance_m": ("m", "Travel of the head vehicle from the brake command to "
                                 "standstill; NaN when the train did not stop."),
    "stop_time_s": ("s", "Time from the brake command to standstill; NaN when the train did "
                         "not stop."),
    "peak_draft_kN": ("kN", "Largest draft force of any coupler (draft positive, buff "
                            "negative); 0 when no coupler was in draft."),
    "peak_draft_coupler": ("", "Coupler of the largest draft force, counted from 1 behind "
                               "the head vehicle."),
    "peak_draft_time_s": ("s", "When the largest draft force occurred, from the start of the "
                               "manoeuvre."),
    "peak_buff_kN": ("kN", "Largest buff force of any coupler, as a negative value (draft "
                           "positive, buff negative)."),
    "peak_buff_coupler": ("", "Coupler of the largest buff force, counted from 1 behind the "
                              "head vehicle."),
    "peak_buff_time_s": ("s", "When the largest buff force occurred, from the start of the "
                              "manoeuvre."),
    "mean_adhesion": ("-", "Largest mean utilised adhesion of a braked vehicle by design (brake "
                           "force at the rails over weight, its own stop from its maximum "
                           "speed, the mean-value method); null when no vehicle is braked."),
    "mean_adhesion_vehicle": ("", "Vehicle of the largest mean utilised adhesion, counted from "
                                  "1 at the head; 0 when it was not assessed."),
    "max_adhesion_demand": ("-", "Largest adhesion demand (brake force over weight) of a braked "
                                 "vehicle at its worst against the rail's available adhesion."),
    "max_adhesion_vehicle": ("", "Vehicle of the largest adhesion demand, counted from 1 at "
                                 "the head."),
    "draft_ok": ("", "True when no coupler's draft force exceeded the coupler variant's draft "
                     "strength."),
    "buff_ok": ("", "True when no coupler's buff force exceeded the coupler variant's buff "
                    "strength."),
    "travel_ok": ("", "True when every coupler stayed within the travel of its coupler "
                      "model."),
    "adhesion_ok": ("", "True when no vehicle's mean utilised adhesion exceeded its limit "
                        "(true when not assessed)."),
    "steps": ("-", "Integration steps taken."),
    "newton_iterations": ("-", "Newton iterations of the implicit integrator over all steps."),
    "newton_iterations_per_step": ("-", "Mean Newton iterations per step."),
    "max_newton_iterations": ("-", "Most Newton iterations of a single step."),
    "couplers_beyond_lut": ("-", "Number of couplers that went beyond the range of their "
                                 "coupler characteristic (forces there are not physical)."),
    "buffers_ok": ("", "True when no coupling went beyond twice its buffers' declared end "
                       "force (their limit state)."),
    "non_physical": ("", "The run's NON-PHYSICAL line (the first coupling beyond its buffers' "
                         "limit state or travel, when, how many did); empty when physical."),
    "in_model_range": ("", "True when the train is inside every model's validated range."),
    "model_warnings": ("", "Where the train leaves its models' ranges, one sentence each, "
                           "separated by ' | '; empty inside them."),
    "band_status": ("", "The model-form band's verdict (campaign key band): PASS, WARN, FAIL, "
                        "model-dependent, NON-PHYSICAL or no member in range; null without a "
                        "band or for other manoeuvres."),
    "stopping_distance_m_min": ("m", "The band's shortest stopping distance (null without)."),
    "stopping_distance_m_max": ("m", "The band's longest stopping distance (null without)."),
    "peak_draft_kN_min": ("kN", "The band's smallest peak draft force (null without)."),
    "peak_draft_kN_max": ("kN", "The band's largest peak draft force (null without)."),
    "peak_buff_kN_min": ("kN", "The band's smallest peak buff force in magnitude, negative "
                               "(null without)."),
    "peak_buff_kN_max": ("kN", "The band's largest peak buff force in magnitude, negative "
                               "(null without)."),
}


def _uncertain_column(name: str) -> tuple[str, str]:
    """Unit and description of the column of uncertain parameter ``name``."""
    part, fit = fittable_parameters()[name]
    meaning = fit.meaning[:1].upper() + fit.meaning[1:]
    return fit.unit, f"{meaning} ({part} parameter {fit.field}, drawn per run)."


def schema_of(c: Campaign) -> pa.Schema:
    """The Parquet schema of a campaign's rows, with each column's unit and description.

    Inputs: the run's draws (``wagon_types``, ``wagon_mass_t`` and ``wagon_brakes`` list the
    wagons from the head; a brake code is the position ``P``/``G`` or ``x`` for an isolated
    brake, then ``L`` loaded or ``E`` empty), one column per uncertain parameter; then
    :data:`KPI_FIELDS`; ``status`` ``ok`` or ``failed`` with its ``message``.

    Every field's metadata holds ``unit`` (``-`` dimensionless, empty for text, ids and
    flags) and ``description`` (:data:`COLUMNS`; an uncertain parameter's from its
    :class:`~ltd_brake_ros.physics.parameters.Fittable`); the schema's metadata holds
    ``ltd_brake_ros.schema_version`` (:data:`SCHEMA_VERSION`) and ``ltd_brake_ros.units``,
    a JSON object column -> unit.

    Parameters
    ----------
    c : Campaign

    Returns
    -------
    pyarrow.Schema
    """
    return _schema(tuple(sorted(c.uncertainties)))


@functools.lru_cache(maxsize=16)
def _schema(uncertain: tuple) -> pa.Schema:
    """:func:`schema_of` for the uncertain parameters ``uncertain`` (once per process: every
    batch builds its table with it)."""
    columns = [(name, kind, *COLUMNS[name]) for name, kind in _INPUT_FIELDS]
    columns += [(name, pa.float64(), *_uncertain_column(name)) for name in uncertain]
    columns += [(name, kind, *COLUMNS[name]) for name, kind in KPI_FIELDS]
    fields = [pa.field(name, kind, metadata={"unit": unit, "description": text})
              for name, kind, unit, text in columns]
    units = {name: unit for name, _, unit, _ in columns}
    return pa.schema(fields, metadata={SCHEMA_VERSION_KEY: str(SCHEMA_VERSION),
                                       UNITS_KEY: json.dumps(units)})


def describe_schema(schema: pa.Schema) -> dict:
    """The columns of a campaign schema (e.g. a batch file's) with their units and meanings.

    Parameters
    ----------
    schema : pyarrow.Schema
        As :func:`schema_of` builds it or ``pyarrow.parquet.read_schema`` reads it back.

    Returns
    -------
    dict
        ``schema_version`` (int, None for a file written before units were recorded) and
        ``columns``: per column a dict of ``name``, ``type``, ``unit`` and ``description``
        (None where the schema does not record them).
    """
    version = (schema.metadata or {}).get(SCHEMA_VERSION_KEY.encode())
    columns = []
    for field in schema:
        meta = field.metadata or {}
        kind = field.type
        columns.append({
            "name": field.name,
            "type": f"list<{kind.value_type}>" if pa.types.is_list(kind) else str(kind),
            "unit": meta[b"unit"].decode() if b"unit" in meta else None,
            "description": meta[b"description"].decode() if b"description" in meta else None})
    return {"schema_version": int(version) if version and version.isdigit() else None,
            "columns": columns}


def run_one(c: Campaign, run_id: int) -> list[dict]:
    """Draw train ``run_id`` of a campaign and run each manoeuvre with it.

    A failure (of the draw or of a manoeuvre) becomes a row with its message.

    Parameters
    ----------
    c : Campaign
    run_id : int

    Returns
    -------
    list of dict
        One row per manoeuvre, in the file's order (see :func:`schema_of`); ``status`` is
        ``ok`` or ``failed``.
    """
    rows = [{"run_id": run_id, "manoeuvre": m.name, "seed": c.seed, "status": "ok",
             "message": ""} for m in c.manoeuvres]
    try:
        sample, data = draw(c, run_id)
        for m, row in zip(c.manoeuvres, rows):
            row.update(sample, speed_kmh=sample["speed_kmh"][m.name])
        consist = consist_from_mapping(data, f"{c.source} run {run_id}")
        params, lut = models(c, sample)
    except Exception as exc:  # noqa: BLE001 - a failed run is a result, recorded with its reason
        for row in rows:
            row["status"], row["message"] = "failed", f"{type(exc).__name__}: {exc}"
        return rows
    for m, row in zip(c.manoeuvres, rows):
        try:
            row.update(_simulate(c, m, consist, row["speed_kmh"], params, lut))
        except Exception as exc:  # noqa: BLE001 - as above
            row["status"], row["message"] = "failed", f"{type(exc).__name__}: {exc}"
    return rows


def _simulate(c: Campaign, m, consist, speed_kmh: float, params, lut) -> dict:
    """KPIs of one run of manoeuvre ``m``, and its verdicts by the campaign's limits."""
    band = None
    if m.kind == "emergency":
        # as emergency_stop runs it (the same steps, results and final chunk), with the
        # simulator's verdicts at hand; with a band, the run is its nominal member
        start = time.perf_counter()
        if c.band is not None:
            from .band import run_band

            band, sim = run_band(consist, speed_kmh, params, lut, band=c.band, step_s=c.step_s,
                                 chunk_s=CHUNK_S, max_time_s=MAX_TIME_S)
        else:
            sim = emergency_run(consist, speed_kmh, params, lut, step_s=c.step_s,
                                chunk_s=CHUNK_S, max_time_s=MAX_TIME_S, group=True)
        r = summarize(sim, time.perf_counter() - start)
        out = {k: getattr(r, k) for k in (
            "train_mass_t", "train_length_m", "braked_weight_percent", "stopping_distance_m",
            "stop_time_s", "peak_draft_kN", "peak_draft_coupler", "peak_draft_time_s",
            "peak_buff_kN", "peak_buff_coupler", "peak_buff_time_s", "steps",
            "newton_iterations", "newton_iterations_per_step", "max_newton_iterations",
            "couplers_beyond_lut")}
    else:
        if m.kind == "service":
            steps = [(0.0, {"brake_demand": m.demand})]
            if m.release_s < m.duration_s:
                steps.append((m.release_s, {"brake_demand": 0.0}))
        else:
            steps = [(0.0, {"traction": m.demand})]
        sim = scripted_run(consist, speed_kmh, CommandScript(tuple(steps), m.duration_s),
                           params, lut, step_s=c.step_s, chunk_s=SCRIPT_CHUNK_S)
        peaks = sim.coupler_peaks()
        stopped = sim.stopping_distance_m is not None
        out = {"train_mass_t": consist.mass_kg / 1e3, "train_length_m": consist.length_m,
               "braked_weight_percent": sim.braked_weight_percent(),
               "stopping_distance_m": sim.stopping_distance_m if stopped else math.nan,
               "stop_time_s": (sim.stop_time_s - (sim.command_time_s or 0.0)) if stopped
               else math.nan,
               "peak_draft_kN": peaks.draft_N / 1e3, "peak_draft_coupler": peaks.draft_coupler,
               "peak_draft_time_s": peaks.draft_time_s, "peak_buff_kN": peaks.buff_N / 1e3,
               "peak_buff_coupler": peaks.buff_coupler, "peak_buff_time_s": peaks.buff_time_s,
               "steps": sim.steps, "newton_iterations": sim.newton_iterations,
               "newton_iterations_per_step": sim.newton_iterations / max(sim.steps, 1),
               "max_newton_iterations": sim.max_newton_iterations,
               "couplers_beyond_lut": sim.coupler_excursions().count}
    # the verdicts by the coupler variant's strengths and the campaign's adhesion limit
    verdicts = sim.verdicts(verdicts_module.train_limits(
        consist, lut, adhesion_limit=c.adhesion_limit, friction_arrays=sim.model.friction,
        coupler_arrays=sim.model.couplers))
    # the largest mean utilised adhesion of a vehicle by design (its own stop from its
    # maximum speed) and the run's largest demand against the rail; vehicles counted from 1
    mean = verdicts["adhesion"]
    out["mean_adhesion"] = mean.worst_value if mean.assessed else None
    out["mean_adhesion_vehicle"] = mean.worst_number + 1 if mean.assessed else 0
    demand = verdicts["adhesion_demand"]
    out["max_adhesion_demand"] = demand.worst_value
    out["max_adhesion_vehicle"] = demand.worst_number + 1
    flags = verdicts_module.flags(verdicts)
    for name in ("draft_ok", "buff_ok", "travel_ok", "adhesion_ok", "buffers_ok"):
        out[name] = flags[name]
    out["non_physical"] = verdicts.non_physical_line or ""
    out["in_model_range"] = not sim.model_warnings
    out["model_warnings"] = " | ".join(sim.model_warnings)
    if band is not None:
        out["band_status"] = band.status
        for name, k in band.kpis.items():
            out[f"{name}_min"], out[f"{name}_max"] = k.low, k.high
    return out


def warm_up() -> None:
    """Load the compiled kernel into this process before its first batch.

    A short emergency stop of a locomotive and a wagon of the shipped vehicle library with
    the default models: numba loads the kernel from its on-disk cache (or compiles it) once
    per process, which a worker otherwise does in its first batch.
    """
    import sys

    from ..first_run import measured

    try:
        consist = consist_from_mapping({"name": "warm-up", "vehicles": [
            {"type": "E402B"}, {"type": "Shimmns", "mass_t": 80.0}]}, "warm-up")
        with measured({"consist": consist}, lambda line: print(line, file=sys.stderr)):
            sim = Simulator(consist, 50.0)
            sim.advance(0.1, Commands(emergency=True))
            sim.verdicts()
    except Exception:  # noqa: BLE001 - a vehicle library without these types: the first
        pass  # batch loads the kernel instead, and reports any real problem with its runs


def run_batch(c: Campaign, batch: int) -> pa.Table:
    """Run batch ``batch`` (trains ``batch * batch_size`` onwards) into a table.

    Parameters
    ----------
    c : Campaign
    batch : int

    Returns
    -------
    pyarrow.Table
        One row per train and manoeuvre, by run id and then manoeuvre, with
        :func:`schema_of` (its field and schema metadata included).
    """
    first = batch * c.batch_size
    rows = [row for i in range(first, min(first + c.batch_size, c.runs))
            for row in run_one(c, i)]
    schema = schema_of(c)
    return pa.Table.from_pylist([{k: r.get(k) for k in schema.names} for r in rows],
                                schema=schema)

"""Run information stored in a recording: what train, at what speed, with which settings."""
from __future__ import annotations

from .._version import __version__
from ..verdicts import limits_metadata


def model_warnings(sim) -> list[str]:
    """Where the run of ``sim`` leaves its models' validated ranges, and vehicles too heavy
    for a line category (empty: neither).

    Parameters
    ----------
    sim : Simulator

    Returns
    -------
    list of str
    """
    return list(sim.model_warnings)


def run_metadata(sim, *, scenario=None, parameters: dict | None = None, **extra) -> dict:
    """Run information to store in a recording (``BagWriter(metadata=...)``).

    Parameters
    ----------
    sim : Simulator
        The simulator of the run (its consist and initial speed are summarised).
    scenario : str or int, optional
        Scenario name or number.
    parameters : dict, optional
        Node parameters (JSON-serialisable values).
    **extra
        Any further JSON-serialisable entries.

    Returns
    -------
    dict
    """
    c = sim.consist
    groups: list[list] = []
    for v in c.vehicles:
        if groups and groups[-1][0] == v.name:
            groups[-1][1] += 1
        else:
            groups.append([v.name, 1])
    meta = {
        "consist": {"name": c.name, "source": str(c.source), "vehicles": int(sim.n),
                    "length_m": float(c.length_m), "mass_t": float(c.mass_kg) / 1e3,
                    "braked_weight_percent": float(sim.braked_weight_percent()),
                    "composition": groups},
        "initial_speed_kmh": float(sim.speed_kmh),
        "package_version": __version__,
        "step_s": float(sim.step_s),
        "tolerance_m_s": float(sim.tolerance_m_s or 0.0),  # 0: fixed steps
        # strength and adhesion limits the run was judged by (kN, t): the report reads them back
        "limits": limits_metadata(sim.limits),
        # the air the brake-heat model starts and cools to [K]
        "ambient_temperature_K": float(sim.model.thermal.ambient_K),
    }
    warnings = model_warnings(sim)
    if warnings:  # the run is outside a model's validated range
        meta["warnings"] = warnings
    if scenario is not None:
        meta["scenario"] = scenario
    if parameters:
        meta["parameters"] = dict(parameters)
    meta.update(extra)
    return meta


#: Version of the train description's layout.
DESCRIPTION_VERSION = 1


def train_description(sim, metadata: dict, frame_id: str = "map") -> str:
    """The train description a plant latches on ``train/description`` (JSON text).

    What a tool joining late needs to read the plant's topics: the run information (as a
    recording stores it), every vehicle with its joint name, type, mass, length and brake,
    every coupler with its joint name, the vehicles it joins and its strengths, the models,
    the marker frame and the units and sign conventions.

    Parameters
    ----------
    sim : Simulator
        The run's simulator.
    metadata : dict
        Its run information (:func:`run_metadata`).
    frame_id : str, optional
        Frame of the plant's markers.

    Returns
    -------
    str
        One JSON object.
    """
    import json

    from ..physics import couplers

    c, lim = sim.consist, sim.limits
    vehicles = []
    for i, v in enumerate(c.vehicles):
        vehicles.append({
            "index": i, "joint": f"vehicle_{i}", "type": v.name,
            "mass_t": round(v.mass_kg / 1e3, 6), "length_m": float(v.length_m),
            "axles": int(v.axles),
            "brake": "none" if v.brake is None else v.brake.type,
            "brake_position": v.brake_position if v.brake is not None else None,
            "braked_weight_t": float(v.braked_weight_t),
            "traction": v.traction is not None})
    joins = []
    for j in range(1, c.n):
        joins.append({
            "index": j, "joint": f"coupler_{j}", "between": [j - 1, j],
            "draft_strength_kN": _kn(lim.draft_strength_N[j - 1]),
            "buff_strength_kN": _kn(lim.buff_strength_N[j - 1])})
    out = {
        "format": "ltd_brake_ros train description", "version": DESCRIPTION_VERSION,
        "run": metadata, "frame_id": frame_id,
        "brake_model": sim.params.model,
        "coupler_model": couplers.model_of(sim.lut).NAME,
        "vehicles": vehicles, "couplers": joins,
        "conventions": {
            "vehicles": "vehicle 0 is the head; arrays and joints vehicle_<i> run head to tail",
            "couplers": "coupler j joins vehicle j-1 and vehicle j (coupler 1 behind the head)",
            "units": "SI: m, s, m/s, N, Pa (gauge); time is simulated time from 0",
            "signs": "speed forward positive; brake force retarding positive; coupler force "
                     "draft (tension) positive, buff (compression) negative",
            "vehicles/state": "position = centre [m], velocity [m/s], effort = brake force [N]",
            "couplers/state": "position = elongation from rest [m], velocity [m/s], "
                              "effort = coupler force [N]"},
    }
    return json.dumps(out, allow_nan=False, default=str)


def _kn(force_N: float) -> float | None:
    """A strength in kN for JSON (None where unknown)."""
    import math

    return round(float(force_N) / 1e3, 3) if math.isfinite(force_N) else None

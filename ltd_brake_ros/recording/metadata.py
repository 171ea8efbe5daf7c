"""Run information stored in a recording: what train, at what speed, with which settings."""
from __future__ import annotations

from .. import __version__
from ..verdicts import limits_metadata


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
    }
    if scenario is not None:
        meta["scenario"] = scenario
    if parameters:
        meta["parameters"] = dict(parameters)
    meta.update(extra)
    return meta

"""Targets of the judgments on a run, as ``ltd-brake validate`` prints them.

Each target is one (what, passed, detail) line, computed from runs made here:

* scenario 6, the paper's validated train: every assessed FAIL or WARN criterion PASSes and its
  wagons' mean utilised adhesion lies in 0.09-0.11 (the whole stop decelerates at
  (100/3.6)^2 / (2 x 489 m) / g = 0.080 from the command, delay and rise included);
* a Shimmns braked at 150 % of its weight (scenario 3's wagon 5) FAILs the adhesion design check
  (the mean utilised adhesion of its own stop from its maximum speed);
* E402B + 300 x 80 t in G braked from the head (3.8 km), with the empirical model and with the
  brake pipe: every coupling beyond its buffers' limit state or its coupler model's travel
  comes with the run marked non-physical.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..inputs import consist_from_mapping, get_scenario, load_brake_params
from ..inputs.brake_params import DEFAULT_FILES
from ..verdicts.table import NON_PHYSICAL_CRITERIA
from .runs import emergency_run

__all__ = ["judgment_targets"]

#: Band of scenario 6's wagons' mean utilised adhesion [-] (see the module).
SCENARIO_6_MEAN = (0.09, 0.11)


def _scenario_6(params, lut) -> tuple[str, bool, str]:
    sc = get_scenario(6)
    sim = emergency_run(sc.consist(), sc.speed_kmh, params, lut)
    table = sim.verdicts()
    mean = sim.adhesion_records().mean[1:]
    lo, hi = SCENARIO_6_MEAN
    bad = [c.name for c in table.criteria if c.status in ("FAIL", "WARN")]
    ok = not bad and bool(np.all((lo <= mean) & (mean <= hi)))
    return ("scenario 6: every assessed verdict PASS, wagons' mean utilised adhesion in "
            f"{lo}-{hi}", ok, f"verdicts {table.status}"
            + (f" ({', '.join(bad)})" if bad else "")
            + f", mean {mean.min():.3f}-{mean.max():.3f}")


def _over_braked(params, lut) -> tuple[str, bool, str]:
    sc = get_scenario(3)
    c = sc.consist()
    vs = list(c.vehicles)
    v = vs[5]
    vs[5] = dataclasses.replace(v, brake=dataclasses.replace(
        v.brake, braked_weight_t=1.5 * v.mass_kg / 1e3))
    sim = emergency_run(dataclasses.replace(c, vehicles=tuple(vs)), sc.speed_kmh, params, lut)
    crit = sim.verdicts()["adhesion"]
    named = [e.number for e in crit.exceedances]
    ok = crit.status == "FAIL" and named == [5]
    worst = crit.exceedances[0].value if crit.exceedances else crit.worst_value
    return ("a Shimmns braked at 150 % of its weight (scenario 3, wagon 5) FAILs the adhesion "
            "design check (its stop from 100 km/h)", ok,
            f"{crit.status}, vehicles beyond: {named or 'none'}, mean {worst:.3f}")


def long_train():
    """The long train of the judgments: E402B + 300 Shimmns of 80 t, braked in G."""
    return consist_from_mapping({"name": "E402B + 300 Shimmns (80 t, G)", "vehicles": [
        {"type": "E402B"},
        {"type": "Shimmns", "count": 300, "mass_t": 80.0, "brake_position": "G"}]},
        "long train")


def _long_train(params, lut) -> list[tuple[str, bool, str]]:
    c = long_train()
    out = []
    shipped = [load_brake_params(f) for f in DEFAULT_FILES]  # empirical, brake pipe
    for brake in (params if params is not None and params.model == b.model else b
                  for b in shipped):
        sim = emergency_run(c, 100.0, brake, lut)
        table = sim.verdicts()
        beyond = {e.number for name in NON_PHYSICAL_CRITERIA
                  for e in table[name].exceedances}
        ok = not beyond or (table.non_physical and table.non_physical_detail["couplings"]
                            == len(beyond))
        out.append((f"E402B + 300 x 80 t in G from the head, {brake.model}: couplings beyond "
                    "their buffers' limit state or travel are marked non-physical", ok,
                    f"{len(beyond)} couplings beyond, run "
                    + ("marked NON-PHYSICAL" if table.non_physical else "not marked")
                    + f"; peak draft {sim.peak_draft_N.max() / 1e3:.0f} kN, buff "
                      f"{-sim.peak_buff_N.min() / 1e3:.0f} kN"))
    return out


def judgment_targets(params=None, lut=None) -> list[tuple[str, bool, str]]:
    """The judgment targets, one (what, passed, detail) each.

    Parameters
    ----------
    params : BrakeParams, optional
    lut : coupler parameters, optional
        The models to judge with (default: the shipped ones).

    Returns
    -------
    list of tuple
    """
    return [_scenario_6(params, lut), _over_braked(params, lut), *_long_train(params, lut)]

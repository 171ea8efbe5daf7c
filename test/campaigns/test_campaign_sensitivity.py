"""Designed campaigns: grid, Sobol' and Morris designs, their files, their runs and the
sensitivity indices of the report.

The Sobol' campaign varies three inputs of short trains stopping from 40 km/h: the wagon count
(2 to 8), the payload of the loaded wagons (30 to 58 t) and ``k_loco``, the brake parameters'
k factor of a disc-braked locomotive, which has no effect here: the campaign's locomotive
type gives its own k (and mu_eff), which the brake parameters' do not override. Physics gives
the ordering of the other two:

* stopping distance: every wagon is loaded above its changeover mass (48 t), so its brake
  force is that of its loaded braked weight (58.55 t) whatever its payload, and its
  deceleration falls as 1 / mass; the wagon count changes only the share of the locomotive
  (whose braked-weight percentage, 79 / 89 t, about equals that of a mid-loaded wagon) and the
  brake command's short travel along the train: payload matters far more;
* peak buff force: the brake command reaches the rear last, which runs in on the braked front;
  the more wagons, the more mass runs in and the later the rear brakes, while the payload,
  with brake forces in proportion to the loaded braked weight, scales forces and masses alike:
  the wagon count matters far more.
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pyarrow as pa
import pytest

from ltd_brake_ros.analysis.campaign_report import campaign_report
from ltd_brake_ros.analysis.sensitivity import (analyze_sobol, complete_blocks,
                                                 sensitivity_report)
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import campaign_from_mapping, load_campaign
from ltd_brake_ros.studies.campaign import design_sample, dimensions, draw, run_one
from ltd_brake_ros.studies.campaign_exec import read_results, run_campaign

pytest.importorskip("SALib")

#: Short trains at 40 km/h; ``{sampling}``, ``{runs}`` and the locomotive type are filled in.
DESIGNED = """\
name: {name}
seed: 5
runs: {runs}
batch_size: 16
sampling: {sampling}
manoeuvres:
  - {{kind: emergency, speed_kmh: {{uniform: [30.0, 50.0]}}}}
vehicle_types:
  E402B_own_k:      # E402B with its own k and mu_eff: the brake parameters' do not apply
    mass_t: 89.0
    length_m: 19.42
    axles: 4
    brake: {{type: disc, braked_weight_t: 79.0, k: 3.54, mu_eff: 0.264}}
families:
  - name: short
    wagons: [2, 8]
    wagon_types:
      Shimmns:
        tare_t: 22.0
        loaded_fraction: {loaded}
        payload_t: {{uniform: [30.0, 58.0]}}
    locomotives: {{type: {loco}}}
couplers:
  - file: couplers/buffer_hook_pugi.yaml
uncertainties:
  k0: {{normal: {{mean: 2.7, sd: 0.1}}}}
  k_loco: {{uniform: [3.0, 4.0]}}
"""
SOBOL = "{design: sobol, inputs: [wagons, payload_t, k_loco]}"


def _write(folder, name="designed", runs=32, sampling=SOBOL, loco="E402B_own_k", loaded=1.0):
    path = folder / f"{name}.yaml"
    path.write_text(DESIGNED.format(name=name, runs=runs, sampling=sampling, loco=loco,
                                    loaded=loaded))
    return path


def _run(folder, **kw):
    path = _write(folder, **kw)
    out = folder / f"{kw.get('name', 'designed')}_out"
    run_campaign(load_campaign(path), out)
    return out


@pytest.fixture(scope="module")
def sobol_folder(tmp_path_factory):
    """The Sobol' campaign: N = 32 blocks of 2 D + 2 = 8 runs."""
    return _run(tmp_path_factory.mktemp("sobol"), name="sobol")


def test_k_loco_acts_only_without_the_locomotive_s_own_k(tmp_path):
    """The no-effect input is a live parameter: with the shipped E402B (k from the brake
    parameters) the stop changes with it, with the locomotive's own k it does not."""
    grid = "{design: grid, inputs: {k_loco: [3.0, 4.0]}}"
    for loco, differ in (("E402B", True), ("E402B_own_k", False)):
        c = load_campaign(_write(tmp_path, name=loco, runs=1, sampling=grid, loco=loco))
        a, b = (run_one(c, i)[0]["stopping_distance_m"] for i in range(2))
        assert (a != b) == differ, (loco, a, b)


def test_sobol_indices_follow_the_physics(sobol_folder, capsys):
    rep = campaign_report(sobol_folder)
    sens = rep["sensitivity"]
    assert sens["design"] == "sobol" and sens["inputs"] == ["wagons", "payload_t", "k_loco"]
    assert sens["runs"] == 32 * 8 and sens["block"] == 8 and sens["second_order"]
    assert sens["dimensions"]["wagons"] == ["size"]
    idx = {kpi: r["indices"] for kpi, r in sens["manoeuvres"]["emergency"].items()}
    for kpi in ("stopping_distance_m", "peak_draft_kN", "peak_buff_kN"):
        res = sens["manoeuvres"]["emergency"][kpi]
        assert res["complete_blocks"] == res["blocks"] == 32 and not res["note"]
        # the no-effect input: its total (and first-order) index is 0 within its interval
        for key in ("ST", "S1"):
            v = idx[kpi]["k_loco"]
            lo, hi = v[f"{key}_interval"]
            assert lo <= v[key] <= hi and lo <= 0.0 <= hi and abs(v[key]) < 0.05, (kpi, v)
    # stopping distance: payload far above the wagon count, the intervals apart
    st = {n: idx["stopping_distance_m"][n]["ST_interval"] for n in ("wagons", "payload_t")}
    assert st["payload_t"][0] > st["wagons"][1], st
    # peak buff force: the wagon count far above the payload
    st = {n: idx["peak_buff_kN"][n]["ST_interval"] for n in ("wagons", "payload_t")}
    assert st["wagons"][0] > st["payload_t"][1], st
    # the same in the text and in JSON
    assert "Sobol' indices, Saltelli's design of D = 3 inputs (wagons, payload_t, k_loco)" \
        in _report(capsys, sobol_folder)
    data = json.loads(_report(capsys, sobol_folder, "--json"))
    entry = data["sensitivity"]["manoeuvres"]["emergency"]["peak_buff_kN"]["indices"]["wagons"]
    assert set(entry) == {"S1", "S1_interval", "ST", "ST_interval"}


def _report(capsys, folder, *extra) -> str:
    """The standard output of ``ltd-brake campaign report FOLDER ...`` (exit status 0)."""
    assert main(["campaign", "report", str(folder), *extra]) == 0
    return capsys.readouterr().out


def test_sobol_draws_follow_the_design(sobol_folder):
    c = load_campaign(sobol_folder / "campaign.yaml")
    x = design_sample(c)
    assert x.shape == (256, 3) and dimensions(c)[-1] == "payload_t"
    meta, table = read_results(sobol_folder)
    assert meta["sampling"] == "sobol" and meta["runs"] == 256
    rows = table.to_pylist()
    for i in (0, 9, 100):
        sample, _ = draw(c, i)
        # the held draws: the median speed; every loaded wagon the payload at the input's
        # probability; the wagon count from its column
        assert sample["speed_kmh"]["emergency"] == pytest.approx(40.0)
        assert sample["wagon_mass_t"] == pytest.approx(
            [22.0 + 30.0 + 28.0 * x[i, 1]] * sample["wagons"])
        assert sample["wagons"] == min(2 + int(x[i, 0] * 7), 8) == rows[i]["wagons"]
        assert sample["k_loco"] == pytest.approx(3.0 + x[i, 2]) == rows[i]["k_loco"]
    # Saltelli's block: A, then A with column j from B (j = 0, 1, 2), ... B
    assert x[1, 1:] == pytest.approx(x[0, 1:]) and x[1, 0] != x[0, 0]


def test_a_block_with_a_missing_run_is_left_out_and_said(sobol_folder, tmp_path, capsys):
    folder = tmp_path / "incomplete"
    shutil.copytree(sobol_folder, folder)
    for f in (folder / "batches").glob("batch-0000001.parquet*"):
        f.unlink()  # runs 16-31: blocks 2 and 3
    res = campaign_report(folder)["sensitivity"]["manoeuvres"]["emergency"]["peak_draft_kN"]
    assert res["complete_blocks"] == 30 and res["missing"]["not_in_results"] == 16
    text = _report(capsys, folder)
    assert "peak_draft_kN [kN] (30 of 32 blocks; 2 left out: 16 runs not in the results yet)" \
        in text
    # a failed run takes its block out of every KPI, and is counted
    meta, table = read_results(sobol_folder)
    status = table["status"].to_pylist()
    status[5] = "failed"
    table = table.set_column(table.schema.get_field_index("status"), "status",
                             pa.array(status))
    sens = sensitivity_report(sobol_folder, meta, table)
    res = sens["manoeuvres"]["emergency"]["stopping_distance_m"]
    assert res["complete_blocks"] == 31 and res["missing"]["failed"] == 1
    # the analysis alone: a run without a value (NaN) takes its block out
    y = np.arange(80.0)
    y[13] = np.nan
    assert complete_blocks(y, 8).tolist() == [True, False] + [True] * 8
    out = analyze_sobol(y, ["a", "b", "c"])
    assert out["complete_blocks"] == 9 and out["indices"]
    assert analyze_sobol(np.ones(80), ["a", "b", "c"])["note"].startswith(
        "the KPI does not vary")


def test_grid_runs_every_level_combination(tmp_path, capsys):
    grid = ("{design: grid, inputs: {k0: {levels: [2.5, 2.9]}, wagons: [2, 4], "
            "speed_kmh: {points: 2}, payload_t: [40.0]}}")
    folder = _run(tmp_path, name="grid", runs=3, sampling=grid, loaded=0.5)
    meta, table = read_results(folder)
    assert meta["sampling"] == "grid" and meta["runs"] == 2 * 2 * 2 * 1 * 3
    rows = table.to_pylist()
    # the last input fastest, replicates innermost
    combos = [(r["k0"], r["wagons"], r["speed_kmh"]) for r in rows]
    expected = [(k, w, v) for k in (2.5, 2.9) for w in (2, 4) for v in (35.0, 45.0)
                for _ in range(3)]
    assert combos == expected  # the exact levels; speeds at probabilities 1/4 and 3/4
    # a loaded wagon carries the payload level; replicate j is the same train at every point
    for r in rows:
        assert all(m in (22.0, 62.0) for m in r["wagon_mass_t"])
    assert all(a["wagon_brakes"] == b["wagon_brakes"] and a["k_loco"] == b["k_loco"]
               for a, b in zip(rows[0:3], rows[3:6]))
    assert len({r["k_loco"] for r in rows[:3]}) == 3  # replicates differ
    text = _report(capsys, folder)
    assert "grid design: 24 runs, 3 replicate(s) of every grid point" in text
    assert "levels k0: 2.5, 2.9; wagons: 2, 4; speed_kmh: 2 points" in text


def test_morris_report(tmp_path, capsys):
    morris = "{design: morris, inputs: [wagons, payload_t, k_loco], levels: 4}"
    folder = _run(tmp_path, name="morris", runs=6, sampling=morris)
    assert read_results(folder)[0]["runs"] == 6 * 4
    sens = json.loads(_report(capsys, folder, "--json"))["sensitivity"]
    assert sens["design"] == "morris" and sens["levels"] == 4 and sens["block"] == 4
    for kpi in ("stopping_distance_m", "peak_draft_kN", "peak_buff_kN"):
        res = sens["manoeuvres"]["emergency"][kpi]
        assert res["complete_blocks"] == 6
        nothing = res["indices"]["k_loco"]
        assert nothing["mu_star"] == nothing["mu"] == nothing["sigma"] == 0.0
        for name in ("wagons", "payload_t"):
            v = res["indices"][name]
            lo, hi = v["mu_star_interval"]
            assert v["mu_star"] > 0 and lo <= v["mu_star"] <= hi and v["sigma"] >= 0
    buff = sens["manoeuvres"]["emergency"]["peak_buff_kN"]["indices"]
    assert buff["wagons"]["mu"] < 0  # more wagons, a more negative (larger) buff force
    text = _report(capsys, folder)
    assert "Morris's elementary effects, 6 trajectories of D + 1 = 4 runs on 4 levels" in text
    assert "k_loco     mu* 0 [0, 0]" in text


#: Bad sampling fields: (the sampling, extra text replaced, the field, words of the reason).
BAD = [
    ("grid", None, "sampling", "a grid needs its levels"),
    ("{design: mystery}", None, "sampling.design", "unknown value 'mystery'"),
    ("{design: sobol, inputs: [wagons, nope]}", None, "sampling.inputs[1]",
     "unknown input 'nope'"),
    ("{design: sobol, inputs: [t_fill]}", None, "sampling.inputs[0]",
     "t_fill is not among the campaign's uncertainties"),
    ("{design: sobol, inputs: [speed_kmh, 'speed_kmh:emergency']}", None,
     "sampling.inputs[1]", "speed_kmh:emergency and speed_kmh both vary"),
    ("{design: sobol, inputs: ['speed_kmh:stop']}", None, "sampling.inputs[0]",
     "no manoeuvre 'stop'"),
    ("{design: sobol, inputs: [k0]}", ("runs: 32", "runs: 24"), "runs",
     "must be a power of 2"),
    ("{design: sobol, levels: 4}", None, "sampling.levels", "applies to morris designs only"),
    ("{design: morris, levels: 3}", None, "sampling.levels", "must be even"),
    ("{design: morris, second_order: true}", None, "sampling.second_order",
     "applies to sobol designs only"),
    ("{design: grid, inputs: {k0: [2.7, 2.7]}}", None, "sampling.inputs.k0.levels[1]",
     "repeats the level 2.7"),
    ("{design: grid, inputs: {k0: {levels: [2.7], points: 3}}}", None, "sampling.inputs.k0",
     "give either levels: [values] or points: N"),
    ("{design: grid, inputs: {k0: [200.0]}}", None, "sampling.inputs.k0.levels[0]",
     "100"),
    ("{design: grid, inputs: {wagons: {points: 9}}}", None, "sampling.inputs.wagons.points",
     "family short takes 7 counts of wagons (2 to 8), fewer than 9 points"),
    ("{design: grid, inputs: {wagons: [2.5]}}", None, "sampling.inputs.wagons.levels[0]",
     "whole number"),
    ("{design: grid, inputs: {length_m: [100.0]}}", None, "sampling.inputs.length_m",
     "family short gives wagons, not length_m"),
    ("{design: grid, inputs: {coupler: {points: 2}}}", None, "sampling.inputs.coupler.points",
     "applies to numeric inputs"),
    ("{design: grid, inputs: {coupler: [other]}}", None, "sampling.inputs.coupler.levels[0]",
     "unknown coupler 'other'"),
    ("{design: grid, inputs: {payload_t: [480.0]}}", None,
     "sampling.inputs.payload_t.levels[0]", "payload of a Shimmns"),
    ("{design: grid, inputs: {k0: [2.7]}, levels: 3}", None, "sampling.levels",
     "unknown field"),
    ("{design: grid, inputs: {speed_kmh: {points: 2}}}",
     ("speed_kmh: {uniform: [30.0, 50.0]}", "speed_kmh: 40.0"),
     "sampling.inputs.speed_kmh.points",
     "the speed of manoeuvre emergency is fixed at 40"),
    ("[sobol]", None, "sampling", "must be a name"),
]


@pytest.mark.parametrize("sampling, edit, field, words", BAD)
def test_bad_design_fields_are_one_line(tmp_path, sampling, edit, field, words):
    path = _write(tmp_path, sampling=sampling)
    if edit:
        path.write_text(path.read_text().replace(*edit))
    with pytest.raises(InputError) as err:
        load_campaign(path)
    assert err.value.field == field and words in err.value.reason, str(err.value)
    assert "\n" not in str(err.value)
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "out"), "--jobs",
                 "1", "--quiet"]) == 2


def test_sobol_and_morris_vary_the_uncertainties_by_default(tmp_path):
    import yaml

    data = yaml.safe_load(DESIGNED.format(name="d", runs=4, sampling="sobol",
                                          loco="E402B_own_k", loaded=1.0))
    c = campaign_from_mapping(data, "mapping")
    assert c.design.inputs == ("k0", "k_loco") and c.runs == 4 * 6
    data["sampling"] = {"design": "sobol", "second_order": False}
    assert campaign_from_mapping(data, "mapping").runs == 4 * 4
    data["sampling"] = "morris"
    assert campaign_from_mapping(data, "mapping").runs == 4 * 3

"""The public Python API: inputs, runs with their time series, recordings, campaigns."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ltd_brake_ros as api
from ltd_brake_ros.physics.kernel import SETTLE_S
from ltd_brake_ros.inputs import InputError, get_scenario
from ltd_brake_ros.studies.runs import emergency_stop as summary_only

SMALL_CAMPAIGN = {
    "name": "from_a_dict", "seed": 3, "runs": 4, "batch_size": 2,
    "manoeuvres": [{"kind": "emergency", "speed_kmh": {"uniform": [30.0, 40.0]}}],
    "families": [{"name": "short", "wagons": [2, 3],
                  "wagon_types": {"Shimmns": {"tare_t": 22.0, "loaded_fraction": 0.5,
                                              "payload_t": {"uniform": [20.0, 50.0]}}}}],
    "couplers": [{"file": "couplers/buffer_hook_pugi.yaml"}],
}


@pytest.fixture(scope="module")
def run6():
    return api.emergency_stop(api.load_consist("scenario_6"), 100.0)


def test_every_public_name_resolves_and_import_stays_cheap():
    for name in api.__all__:
        assert getattr(api, name) is not None, name
    assert (Path(api.__file__).parent / "py.typed").is_file()
    # importing the package loads no simulation machinery: the command line imports it too
    code = ("import sys, ltd_brake_ros; heavy = {'numba', 'scipy', 'matplotlib', 'pandas'}; "
            "print(sorted(heavy & set(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
    with pytest.raises(AttributeError):
        api.no_such_name  # noqa: B018


def test_a_consist_loads_from_a_scenario_a_file_or_a_mapping():
    six = get_scenario(6).consist()
    for source in ("scenario_6", "6", 6):
        assert api.load_consist(source) == six
    assert api.load_consist("consists/e402b_32_shimmns_50t.yaml").n == six.n
    c = api.load_consist({"vehicles": [{"type": "E402B"}, {"type": "Shimmns", "count": 3}]})
    assert c.n == 4
    with pytest.raises(InputError, match="scenario"):
        api.load_consist("scenario_99")
    with pytest.raises(InputError):
        api.load_consist({"vehicles": [{"type": "NoSuchWagon"}]})


def test_emergency_stop_is_the_stop_of_the_library_with_its_time_series(run6):
    ref = summary_only(get_scenario(6).consist(), 100.0)
    # the same nominal steps whatever the sampling: the same stop, number for number
    assert run6.summary.stopping_distance_m == ref.stopping_distance_m
    assert run6.summary.peak_draft_kN == ref.peak_draft_kN
    assert run6.verdicts.status == "PASS"
    ts = run6.timeseries
    k, n = ts.time_s.size, 33
    assert ts.vehicles["speed_m_s"].shape == (k, n) and ts.couplers["coupler_force_N"].shape \
        == (k, n - 1)
    # a sample every 0.1 s, from t = 0 (the state before the brake command), each time the
    # float nearest to k * 0.1 s as written (0.3, not the simulator's summed 0.30000000000000004)
    assert ts.time_s[0] == 0.0 and ts.vehicles["speed_m_s"][0, 0] == 100 / 3.6
    assert ts.time_s.tolist() == [float(f"{k / 10:.1f}") for k in range(ts.time_s.size)]
    # the samples run on until the train has settled (2 s at rest after its recoil)
    assert ts.time_s[-1] == pytest.approx(run6.summary.settled_time_s + SETTLE_S,
                                          abs=0.1 + 1e-9)
    stop, = run6.stops
    assert stop.stopping_distance_m == run6.summary.stopping_distance_m
    assert stop.peaks.draft_N == run6.summary.peak_draft_kN * 1e3
    # the samples lie within the run's peaks, and the head's travel is the stopping distance
    f = ts.couplers["coupler_force_N"]
    assert f.max() <= run6.summary.peak_draft_kN * 1e3 + 1e-6
    assert f.min() >= run6.summary.peak_buff_kN * 1e3 - 1e-6
    x0 = -ts.vehicles["position_m"][0, 0] + 0.0
    travel = ts.vehicles["position_m"][-1, 0] - ts.vehicles["position_m"][0, 0]
    assert travel < run6.summary.stopping_distance_m < travel + 0.1 * 100 / 3.6 + x0 + 3.0


def test_time_series_as_a_tidy_dataframe_and_an_xarray_dataset(run6):
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    ts = run6.timeseries
    k = ts.time_s.size
    df = run6.to_dataframe()
    assert len(df) == k * 33 and {"time_s", "vehicle", "speed_m_s", "brake_force_N"} <= \
        set(df.columns)
    assert df.attrs["units"]["speed_m_s"] == "m/s" and "draft" in df.attrs["conventions"]
    dc = run6.to_dataframe("coupler")
    assert len(dc) == k * 32 and dc.coupler.min() == 1 and dc.coupler.max() == 32
    peak = dc.loc[dc.coupler_force_N.idxmax()]
    assert peak.coupler_force_N == ts.couplers["coupler_force_N"].max()
    long = run6.to_dataframe(None)
    assert len(long) == k * (7 * 33 + 32) and set(long.element) == {"vehicle", "coupler"}
    ds = run6.to_xarray()
    assert dict(ds.sizes) == {"time": k, "vehicle": 33, "coupler": 32}
    # every sample time indexes the Dataset, as a user types it
    for t in (0.0, 0.3, 10.0, *ts.time_s):
        assert ds.sel(time=t).time.item() == t
    assert ds.coupler_force_N.attrs["units"] == "N" and "draft" in ds.attrs["conventions"]
    assert ds.vehicle_name.values[0] == "E402B"
    np.testing.assert_array_equal(ds.speed_m_s.values, ts.vehicles["speed_m_s"])
    with pytest.raises(ValueError, match="element"):
        run6.to_dataframe("wagon")


def test_time_series_files_in_long_form(run6, tmp_path):
    ts = run6.timeseries
    rows = ts.time_s.size * (7 * 33 + 32)
    csv = ts.write(tmp_path / "s6.csv")
    lines = csv.read_text().splitlines()
    assert lines[0] == "time_s,element,number,quantity,unit,value" and len(lines) == rows + 1
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(ts.write(tmp_path / "s6.parquet"))
    assert table.num_rows == rows and "conventions" in {k.decode() for k in
                                                        table.schema.metadata}
    with pytest.raises(InputError, match="parquet or .csv"):
        ts.write(tmp_path / "s6.txt")


def test_simulate_writes_the_time_series_and_refuses_to_overwrite(tmp_path, capsys):
    from ltd_brake_ros.cli.main import main

    out = tmp_path / "s1.csv"
    assert main(["simulate", "--scenario", "1", "--json", "--timeseries", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    lines = out.read_text().splitlines()
    k = (len(lines) - 1) // (7 * 11 + 10)
    assert (len(lines) - 1) == k * (7 * 11 + 10)
    # t = 0 on, to the train settled
    assert (k - 1) * 0.1 == pytest.approx(summary["settled_time_s"] + SETTLE_S, abs=0.1 + 1e-9)
    assert lines[1].startswith("0.0,vehicle,0,position_m,")
    assert main(["simulate", "--scenario", "1", "--timeseries", str(out)]) == 2
    assert "exists" in capsys.readouterr().err


def test_a_command_script_from_a_list(tmp_path):
    run = api.run_commands(api.load_consist(1), 60.0,
                           [{"t_s": 0.0, "brake_demand": 0.5}, {"t_s": 5.0, "emergency": True}])
    assert run.summary is not None and run.simulator.command_time_s == 0.0
    assert run.timeseries.vehicles["brake_force_N"][-1, 1] > 0.0
    with pytest.raises(InputError, match="commands\\[0\\]"):
        api.load_commands([{"t_s": 0.0, "brake_demand": 2.0}])


def test_a_recording_reads_back_as_the_run(tmp_path, capsys):
    from ltd_brake_ros.cli.main import main

    folder = tmp_path / "rec"
    assert main(["simulate", "--scenario", "1", "--record", str(folder), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    rec = api.read_recording(folder)
    assert rec.report.stopping_distance_m == pytest.approx(summary["stopping_distance_m"],
                                                           rel=5e-3)
    ts = rec.timeseries
    assert ts.vehicles["speed_m_s"].shape[1] == 11 and ts.couplers["coupler_force_N"].shape[1] \
        == 10
    assert ts.vehicle_names[:2] == ["E402B", "Shimmns"] and ts.attrs["initial_speed_kmh"] == 100
    assert ts.vehicles["speed_m_s"][0, 0] == pytest.approx(100 / 3.6, rel=1e-3)
    # the same run in Python joins its recording on time: every row of either matched, and the
    # states agree (the recording holds float64 arrays of the same chunks)
    run = api.emergency_stop(api.load_consist(1), 100.0)
    pytest.importorskip("pandas")
    mine, theirs = run.to_dataframe("vehicle"), rec.to_dataframe("vehicle")
    joined = mine.merge(theirs, on=["time_s", "vehicle"], suffixes=("", "_rec"))
    assert len(joined) == len(mine) == len(theirs)
    np.testing.assert_array_equal(joined.speed_m_s, joined.speed_m_s_rec)


def test_a_campaign_from_a_mapping_runs(tmp_path):
    pytest.importorskip("pyarrow")
    c = api.load_campaign(SMALL_CAMPAIGN)
    res = api.run_campaign(c, tmp_path / "out", jobs=1, progress=False)
    assert len(res) == 4 and set(res.table["status"].to_pylist()) == {"ok"}
    # the same mapping is the same campaign: the folder resumes, nothing is run again
    again = api.run_campaign(dict(SMALL_CAMPAIGN), tmp_path / "out", jobs=1, progress=False)
    assert again == res and again.table.equals(api.read_campaign(tmp_path / "out").table)
    with pytest.raises(InputError, match="runs"):
        api.load_campaign(dict(SMALL_CAMPAIGN, runs=-1))


def _family(name: str, k0_mean: float) -> dict:
    """40 trains of the small campaign (20 on each side of the median: intervals of q0.5), the
    k0 scale of the block friction's mean ``k0_mean``; the same seed, the same trains."""
    return dict(SMALL_CAMPAIGN, name=name, runs=40, batch_size=20,
                uncertainties={"k0": {"normal": {"mean": k0_mean, "sd": 0.1}}})


@pytest.fixture(scope="module")
def families(tmp_path_factory):
    pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    folder = tmp_path_factory.mktemp("families")
    return {name: api.run_campaign(_family(name, k0), folder / name, jobs=1, progress=False)
            for name, k0 in (("reference", 2.7), ("stronger", 2.55))}


def test_campaign_objects_give_the_command_lines_numbers_and_verdicts(families, tmp_path,
                                                                      capsys):
    from ltd_brake_ros.cli.main import main

    fam, ref = families["stronger"], families["reference"]
    argv = ["campaign", "report", fam.folder, "--against", ref.folder, "--quantile", "0.5",
            "--json"]
    status = main(argv)
    cli = json.loads(capsys.readouterr().out)
    c = fam.compare(ref, quantile=0.5, margin=0.05)
    assert (c.outcome, c.exit_status) == (cli["outcome"], status)
    assert c.report["pairing"]["mode"] == "paired"
    rows = c.verdicts.set_index("kpi")
    for v in cli["manoeuvres"]["emergency"]["relative"]:
        assert rows.loc[v["kpi"], "verdict"] == v["verdict"]
        if v["compared"]:
            assert [rows.loc[v["kpi"], "worsening_low"], rows.loc[v["kpi"], "worsening_high"]] \
                == pytest.approx(v["worsening_interval"])
    # the deciding KPI chosen by name, one line for an unknown one
    only = fam.compare(ref, quantile=0.5, kpi="stopping_distance_m")
    assert only.report["deciding"] == ["stopping_distance_m"]
    with pytest.raises(InputError, match="unknown KPI 'speed'"):
        fam.compare(ref, kpi="speed")
    with pytest.raises(InputError, match="--margin"):
        fam.compare(ref, margin=2.0)
    # quantiles with intervals: the report's
    q = fam.quantiles([0.5, 0.99], kpi="peak_draft_kN").set_index("q")
    cell = cli["manoeuvres"]["emergency"]["quantiles"]["peak_draft_kN"]
    assert q.loc[0.5, ["estimate", "low", "high"]].tolist() == pytest.approx(
        [cell["0.5"]["estimate"], cell["0.5"]["low"], cell["0.5"]["high"]])
    assert np.isnan(q.loc[0.99, "low"]) and "too few runs beyond q" in q.loc[0.99, "note"]
    # exceedances and the curve: buff forces are negative, beyond is below
    e = fam.exceedance({"peak_buff_kN": -20.0}).iloc[0]
    buff = fam.to_dataframe().peak_buff_kN
    assert (e["count"], e["of"], e["beyond"]) == (int((buff < -20).sum()), 40, "below")
    curve = fam.exceedance_curve("peak_buff_kN")
    assert curve.value.iloc[-1] == buff.min() and curve.share.iloc[-1] == 1 / 40
    assert fam.to_dataframe().attrs["units"]["peak_buff_kN"] == "kN"
    # the HTML page, refused over an existing file unless forced
    page = fam.to_html(tmp_path / "fam.html", against=ref, quantile=0.5)
    assert "Relative approach against reference" in page.read_text()
    with pytest.raises(InputError, match="exists"):
        fam.to_html(page)
    fam.to_html(page, force=True)
    with pytest.raises(InputError, match="sobol or morris"):
        fam.sensitivity()


def test_results_travel_through_a_process_pool_and_dask(families, tmp_path):
    """Every result type pickles and comes back equal, arrays bit for bit; a run's live
    simulator does not travel."""
    import pickle
    from concurrent.futures import ProcessPoolExecutor

    from ltd_brake_ros.analysis.campaign_results import CampaignResults
    from ltd_brake_ros.cli.main import main

    consist = api.load_consist(1)
    run = api.emergency_stop(consist, 60.0)
    assert main(["simulate", "--scenario", "1", "--speed-kmh", "60", "--record",
                 str(tmp_path / "rec")]) == 0
    rec = api.read_recording(tmp_path / "rec")
    fam, ref = families["stronger"], families["reference"]
    comparison = fam.compare(ref, quantile=0.5)
    copy = pickle.loads(pickle.dumps(run))
    assert copy == run and copy.simulator is None and run.simulator is not None
    assert copy.timeseries.vehicles["speed_m_s"].tobytes() == \
        run.timeseries.vehicles["speed_m_s"].tobytes()
    def same_run(got) -> bool:  # computed elsewhere: equal but for its wall time
        cost = ("wall_time_s", "real_time_factor")
        return (got.timeseries == run.timeseries and got.verdicts == run.verdicts
                and got.brake_heat == run.brake_heat and got.simulator is None
                and {k: v for k, v in got.summary.as_dict().items() if k not in cost}
                == {k: v for k, v in run.summary.as_dict().items() if k not in cost})

    with ProcessPoolExecutor(1) as pool:
        # there and back again: each object as it was
        assert pool.submit(list, [run, rec, fam, comparison, run.verdicts]).result() == \
            [copy, rec, fam, comparison, run.verdicts]
        assert same_run(pool.submit(api.emergency_stop, consist, 60.0).result())
        assert pool.submit(api.read_recording, tmp_path / "rec").result() == rec
        assert pool.submit(api.read_campaign, fam.folder).result() == fam
        assert pool.submit(CampaignResults.compare, fam, ref, quantile=0.5).result() \
            == comparison
    from ltd_brake_ros.studies.campaign_exec import DaskExecutor

    pytest.importorskip("distributed")
    with DaskExecutor("local:1") as dask:
        client = dask.client
        assert client.submit(list, [run, rec, fam, comparison, run.verdicts]).result() == \
            [copy, rec, fam, comparison, run.verdicts]
        assert same_run(client.submit(api.emergency_stop, consist, 60.0, pure=False).result())
        assert client.submit(api.read_recording, tmp_path / "rec").result() == rec
        assert client.submit(api.read_campaign, fam.folder).result() == fam
        assert client.submit(CampaignResults.compare, fam, ref, quantile=0.5).result() \
            == comparison


def test_displays_fit_a_screen(families):
    run = api.emergency_stop(api.load_consist(6), 100.0)
    consist = api.load_consist(6)
    for obj in (run, run.summary, run.verdicts, run.timeseries, consist, families["stronger"],
                families["stronger"].compare(families["reference"], quantile=0.5)):
        text = repr(obj)
        assert len(text) <= 400 and "\n" not in text, (type(obj).__name__, len(text))
        html = obj._repr_html_()
        # a table of at most a screen: 40 rows, escaped text
        assert html.count("<tr>") <= 40 and "<script" not in html, type(obj).__name__
    assert "33 vehicles" in repr(consist) and "32 x Shimmns" in repr(consist)
    assert "489.2 m" in repr(run.summary) and "PASS" in repr(run.verdicts)
    # brake heat: in the summary of the run and in its time series
    assert run.brake_heat.block_K > run.brake_heat.ambient_K
    hot = run.timeseries.vehicles["block_temperature_K"]
    # the peaks sit on the thermal model's 1 s grid: within a second's heating at the mean rate
    heat = run.brake_heat
    rate = (heat.block_K - heat.ambient_K) / heat.block_time_s  # [K/s]
    assert abs(np.nanmax(hot) - heat.block_K) <= rate * 1.0
    assert "block_temperature_K" in run.to_xarray()


def test_typical_mistakes_are_one_line_or_taken_as_meant(capsys):
    import warnings

    from ltd_brake_ros.cli.main import main
    from ltd_brake_ros.plant.run import load_plant_inputs

    # a scenario's name where a Consist is expected is loaded; anything else is one line
    by_name = api.emergency_stop("scenario_1", 30.0)
    assert by_name.timeseries == api.emergency_stop(api.load_consist(1), 30.0).timeseries
    with pytest.raises(InputError, match="^consist: expected a Consist"):
        api.emergency_stop(3.5, 30.0)
    # a speed is a finite number from 0 to 400 km/h, above 0 for a stop from speed
    for speed in (-50.0, float("nan"), float("inf"), 401.0, 0.0, "fast"):
        with pytest.raises(InputError, match="^speed_kmh: "):
            api.emergency_stop("scenario_1", speed)
    with pytest.raises(InputError, match="^speed_kmh: must be between 0 and 400"):
        api.run_commands("scenario_1", -1.0, [{"t_s": 0.0, "traction": 0.2}], max_time_s=1.0)
    at_rest = api.run_commands("scenario_1", 0.0, [{"t_s": 0.0, "traction": 0.3}],
                               max_time_s=2.0)
    assert at_rest.timeseries.vehicles["speed_m_s"][-1, 0] > 0.0  # starts at rest, moves off
    for speed, words in (("-50", "must be between 0 and 400 km/h, got -50"),
                         ("nan", "must be a finite number"),
                         ("0", "an emergency stop needs a speed above 0 km/h")):
        assert main(["simulate", "--scenario", "6", "--speed-kmh", speed]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "--speed-kmh" in err and words in err
    # the plant's -1 still means the scenario's speed; other negatives are refused
    assert load_plant_inputs("scenario_6", -1.0).speed_kmh == 100.0
    with pytest.raises(Exception, match="initial_speed_kmh"):
        load_plant_inputs("scenario_6", -5.0)
    # a 102 t wagon on 4 axles: 25.5 t an axle, beyond every line category, named
    heavy = {"vehicles": [{"type": "E402B"}, {"type": "Shimmns", "mass_t": 95.0},
                          {"type": "Shimmns", "mass_t": 102.0}]}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        api.load_consist(heavy)
    lines = [str(w.message) for w in caught]
    assert len(lines) == 2
    assert "vehicle 1 (Shimmns): axle load 23.8 t" in lines[0] and \
        "needs a category E line" in lines[0]
    assert "vehicle 2 (Shimmns): axle load 25.5 t" in lines[1] and \
        "beyond every EN 15528 line category" in lines[1]


def test_a_brake_pipe_run_carries_its_pressures_in_its_time_series(tmp_path):
    from ltd_brake_ros import emergency_stop, load_brake_params, load_consist
    from ltd_brake_ros.cli.main import main

    pipe = load_brake_params("brake_params/uic_brake_pipe.yaml")
    run = emergency_stop(load_consist("scenario_1"), 100.0, params=pipe)
    ts = run.timeseries
    p, c = ts.vehicles["brake_pipe_pressure_Pa"], ts.vehicles["brake_cylinder_pressure_Pa"]
    # charged at 5 bar, vented by the emergency: the head's pipe empties, every cylinder fills
    assert p[0] == pytest.approx(5e5, rel=1e-3) and p[-1, 0] < 0.5e5
    assert np.all(c[0] == 0.0) and np.all(c[-1, 1:] > 3e5)
    assert run.to_xarray().brake_cylinder_pressure_Pa.attrs["units"] == "Pa"
    # the paper's model has no pipe: no such quantity, rather than zeros
    assert "brake_pipe_pressure_Pa" not in emergency_stop(
        load_consist("scenario_1"), 100.0).timeseries.vehicles
    out = tmp_path / "pipe.csv"
    assert main(["simulate", "--scenario", "1", "--params", "brake_params/uic_brake_pipe.yaml",
                 "--timeseries", str(out)]) == 0
    assert ",brake_cylinder_pressure_Pa,Pa," in out.read_text()


def test_the_rail_and_wheel_slide_are_arguments_as_on_the_command_line():
    dry = api.emergency_stop("scenario_7", 100.0)
    wet = api.emergency_stop("scenario_7", 100.0, rail="wet")
    # the same run (the rail is judged against, not modelled) ...
    assert wet.summary.stopping_distance_m == dry.summary.stopping_distance_m
    # ... judged against a rail with 0.6 x the dry rail's adhesion (Koffman's wet/dry ratio)
    a, b = dry.verdicts["adhesion_demand"], wet.verdicts["adhesion_demand"]
    assert b.limit_max == pytest.approx(0.6 * a.limit_max, rel=1e-3)
    # wheel slide on a low rail lengthens the stop
    low = api.emergency_stop("scenario_7", 100.0, adhesion="low")
    assert low.summary.stopping_distance_m > dry.summary.stopping_distance_m
    with pytest.raises(InputError, match="^rail: unknown adhesion condition 'icy'"):
        api.emergency_stop("scenario_7", 100.0, rail="icy")
    with pytest.raises(InputError, match="^band: .*leave out adhesion and rail"):
        api.emergency_stop("scenario_7", 100.0, rail="dry", band=True)

"""Campaign runs: one row per run whatever the executor, failures recorded, resume after a kill."""
from __future__ import annotations

import signal
import time

import numpy as np
import pyarrow.parquet as pq
import pytest
from campaign_helpers import write_campaign
from conftest import executable

from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.physics.constants import G
from ltd_brake_ros.studies.campaign_exec import (PoolExecutor, SerialExecutor, missing_batches,
                                                 read_results, run_campaign)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The small campaign run serially: the table every other way must reproduce."""
    folder = tmp_path_factory.mktemp("reference")
    c = load_campaign(write_campaign(folder))
    run_campaign(c, folder / "out", SerialExecutor())
    return c, read_results(folder / "out")[1]


def test_serial_table_holds_every_run_once_with_physical_kpis(reference):
    c, table = reference
    assert table["run_id"].to_pylist() == list(range(c.runs))
    assert set(table["status"].to_pylist()) == {"ok"}
    rows = table.to_pylist()
    for r in rows:
        assert r["wagons"] == len(r["wagon_brakes"].split()) == len(r["wagon_mass_t"]) \
            == len(r["wagon_types"])
        assert r["loaded_wagons"] == sum(m > 22.0 for m in r["wagon_mass_t"])
        # stopping distance between v^2 / (2 * 1 g) (wheel/rail adhesion bound) and the
        # distance at constant speed for the stop time
        v = r["speed_kmh"] / 3.6
        assert v ** 2 / (2 * G) < r["stopping_distance_m"] < v * r["stop_time_s"]
        assert 0.0 < r["max_adhesion_demand"] < 1.0
        # the mean utilised adhesion by design (each wagon's own stop from its 100 km/h,
        # whatever the run's speed), against the verdicts' default of 0.12 for wagons without
        # wheel-slide protection
        assert 0.0 < r["mean_adhesion"] < 0.2
        assert r["adhesion_ok"] == (r["mean_adhesion"] <= 0.12)
        assert r["travel_ok"] == (r["couplers_beyond_lut"] == 0)
        assert r["buff_ok"] == (-r["peak_buff_kN"] <= 2000.0)
        # about one Newton iteration a step while braking; a step whose predictor already
        # meets the residual tolerance (steady motion, vehicles at rest) takes none
        assert r["steps"] > 0
        assert 0.5 * r["steps"] <= r["newton_iterations"] <= 5 * r["steps"]


def test_process_pool_gives_the_identical_table(reference, tmp_path):
    c, table = reference
    with PoolExecutor(2) as pool:
        summary = run_campaign(c, tmp_path / "pool", pool)
    assert summary == {"batches": c.batches, "runs": c.runs, "failed": 0, "skipped": 0,
                       "redone": 0}
    assert read_results(tmp_path / "pool")[1].equals(table)


def test_resume_runs_only_missing_batches(reference, tmp_path):
    c, table = reference
    run_campaign(c, tmp_path / "out")
    (tmp_path / "out" / "batches" / "batch-0000003.parquet").unlink()
    assert missing_batches(c, tmp_path / "out") == [3]
    summary = run_campaign(c, tmp_path / "out")
    assert summary["batches"] == 1 and summary["runs"] == c.batch_size
    assert read_results(tmp_path / "out")[1].equals(table)


def test_another_campaign_cannot_write_into_a_results_folder(reference, tmp_path):
    c, _ = reference
    run_campaign(c, tmp_path / "out")
    other = load_campaign(write_campaign(tmp_path, name="other", runs=10))
    with pytest.raises(Exception, match="holds results made with another campaign file"):
        run_campaign(other, tmp_path / "out")


def test_a_failing_run_is_recorded_with_its_message(tmp_path, monkeypatch):
    # the stop of every train with an empty braked wagon fails in the simulator
    from ltd_brake_ros.simulator import SimulationError
    from ltd_brake_ros.studies import campaign as studies

    real = studies._simulate

    def simulate(c, m, consist, speed_kmh, params, lut):
        if any(v.mass_kg < 30e3 and v.brake is not None for v in consist.vehicles):
            raise SimulationError("an empty braked wagon")
        return real(c, m, consist, speed_kmh, params, lut)

    monkeypatch.setattr(studies, "_simulate", simulate)
    path = write_campaign(tmp_path, runs=6, batch=3)
    path.write_text(path.read_text().replace("loaded_fraction: 0.7", "loaded_fraction: 0.9"))
    c = load_campaign(path)
    summary = run_campaign(c, tmp_path / "out")
    table = read_results(tmp_path / "out")[1]
    assert table.num_rows == 6 and 1 <= summary["failed"] < 6
    for r in table.to_pylist():
        # a braked empty wagon (P or G, not isolated) is what fails
        empty = any(k in ("PE", "GE") for k in r["wagon_brakes"].split())
        assert r["status"] == ("failed" if empty else "ok")
        if r["status"] == "failed":
            assert r["message"] == "SimulationError: an empty braked wagon"
            assert r["stopping_distance_m"] is None
        else:
            assert not empty and r["message"] == ""


def test_an_impossible_load_is_refused_at_load_naming_both_fields(tmp_path):
    # a 0.5 t wagon cannot carry the 23 t braked weight of the empty Shimmns
    path = write_campaign(tmp_path, runs=6, batch=3)
    path.write_text(path.read_text().replace("tare_t: 22.0", "tare_t: 0.5"))
    with pytest.raises(InputError, match=r"wagon_types.Shimmns.tare_t: an empty Shimmns \(0.5 t\)"
                       r".*braked_weight_empty_t: 23 t is more than twice the vehicle mass"):
        load_campaign(path)


def test_sigkill_of_the_driver_then_resume(reference, tmp_path, processes):
    c, table = reference
    path = write_campaign(tmp_path, runs=c.runs * 4, batch=2)
    out = tmp_path / "out"
    proc = processes.start(executable("ltd-brake"), "campaign", "run", str(path), "--out",
                           str(out), "--jobs", "1", "--quiet")
    deadline = time.monotonic() + 120
    while len(list((out / "batches").glob("batch-*.parquet"))) < 3:
        assert proc.popen.poll() is None, proc.output()
        assert time.monotonic() < deadline, "no batch written within 120 s"
        time.sleep(0.01)
    proc.stop(signal.SIGKILL)
    big = load_campaign(path)
    left = missing_batches(big, out)
    assert 0 < len(left) < big.batches, "the kill came too late to test a resume"
    rerun = processes.start(executable("ltd-brake"), "campaign", "run", str(path), "--out",
                            str(out), "--jobs", "2", "--quiet")
    assert rerun.wait(120) == 0, rerun.output()
    assert f"{len(left)} batches" in rerun.output()
    done = read_results(out)[1]
    assert done["run_id"].to_pylist() == list(range(big.runs))
    # Monte Carlo run i depends on (seed, i) only: the first runs are the reference's
    assert done.slice(0, c.runs).drop(["run_id"]).equals(table.drop(["run_id"]))
    for f in (out / "batches").iterdir():  # no temporary file left; each batch checksummed
        assert f.suffix in (".parquet", ".sha256"), f
        if f.suffix == ".parquet":
            assert pq.read_metadata(f).num_rows == 2
            assert f.with_name(f.name + ".sha256").read_text().split()[1] == "2"


def test_adhesion_demand_is_the_simulators_own_judgment_of_the_run(reference):
    from ltd_brake_ros.inputs import consist_from_mapping
    from ltd_brake_ros.studies.campaign import CHUNK_S, MAX_TIME_S, draw, models
    from ltd_brake_ros.studies.runs import emergency_run

    c, table = reference
    for run in (0, 5):
        sample, data = draw(c, run)
        consist = consist_from_mapping(data, "test")
        params, lut = models(c, sample)
        sim = emergency_run(consist, sample["speed_kmh"]["emergency"], params, lut,
                            step_s=c.step_s, chunk_s=CHUNK_S, max_time_s=MAX_TIME_S)
        row = sim.verdicts()["adhesion_demand"]
        reported = table["max_adhesion_demand"][run].as_py()
        # the demand at each wagon's worst against a dry rail's adhesion: within it, and a
        # wagon's brake force over its weight (P10 blocks: 0.1-0.4)
        assert reported == row.worst_value and 0.05 < reported < 0.4
        assert table["max_adhesion_vehicle"][run].as_py() == row.worst_number + 1
        assert row.status == "PASS"


@pytest.mark.parametrize("step_s", [None, 0.025])
def test_grouped_chunks_give_the_run_of_one_chunk_per_call(reference, tmp_path, monkeypatch,
                                                           step_s):
    from ltd_brake_ros.inputs import consist_from_mapping
    from ltd_brake_ros.inputs.commands import CommandScript
    from ltd_brake_ros.simulator import Simulator
    from ltd_brake_ros.studies.campaign import (CHUNK_S, MAX_TIME_S, draw, models, run_one)
    from ltd_brake_ros.studies.runs import scripted_run

    c = reference[0]
    if step_s is not None:  # another step: 40 a chunk
        path = write_campaign(tmp_path)
        path.write_text(path.read_text() + f"step_s: {step_s}\n")
        c = load_campaign(path)
    calls = []
    advance = Simulator.advance

    def counted(sim, duration_s, commands=None):
        calls.append(duration_s)
        return advance(sim, duration_s, commands)

    for run in range(6):
        monkeypatch.setattr(Simulator, "advance", counted)
        calls.clear()
        [row] = run_one(c, run)
        monkeypatch.setattr(Simulator, "advance", advance)
        sample, data = draw(c, run)
        params, lut = models(c, sample)
        sim = scripted_run(consist_from_mapping(data, "test"), row["speed_kmh"],
                           CommandScript(((0.0, {"emergency": True}),)), params, lut,
                           step_s=c.step_s, chunk_s=CHUNK_S, max_time_s=MAX_TIME_S)
        # the same steps give the same numbers bit for bit; the same final chunk the same
        # steps after the stop
        assert (row["stopping_distance_m"], row["stop_time_s"], row["steps"],
                row["newton_iterations"], row["peak_buff_kN"], row["peak_draft_kN"]) == (
            sim.stopping_distance_m, sim.stop_time_s, sim.steps, sim.newton_iterations,
            sim.stop_peaks.buff_N / 1e3, sim.stop_peaks.draft_N / 1e3)
        assert calls[-1] == CHUNK_S  # the train stopped in a single chunk, as before
        # chunks grouped while the stop was far
        assert max(calls) > CHUNK_S and len(calls) < sim.time_s / CHUNK_S - 1


def test_every_train_runs_every_manoeuvre(tmp_path):
    # a service application released at 20 s, a full one to standstill, a traction start
    manoeuvres = """manoeuvres:
  - {name: emergency, kind: emergency, speed_kmh: 40.0}
  - {name: partial, kind: service, speed_kmh: 40.0, demand: 0.5, release_s: 20.0,
     duration_s: 30.0}
  - {name: full, kind: service, speed_kmh: 30.0, demand: 1.0, duration_s: 60.0}
  - {name: start, kind: traction_start, demand: 1.0, duration_s: 20.0}
"""
    path = write_campaign(tmp_path, runs=2, batch=2)
    text = path.read_text()
    start = text.index("manoeuvres:")
    end = text.index("families:")
    path.write_text(text[:start] + manoeuvres + text[end:])
    c = load_campaign(path)
    summary = run_campaign(c, tmp_path / "out")
    rows = read_results(tmp_path / "out")[1].to_pylist()
    assert summary["runs"] == 8 and [(r["run_id"], r["manoeuvre"]) for r in rows] == [
        (i, m) for i in range(2) for m in ("emergency", "partial", "full", "start")]
    for r in rows:
        assert r["status"] == "ok", r["message"]
        same_train = rows[4 * r["run_id"]]
        assert r["wagon_mass_t"] == same_train["wagon_mass_t"] and r["k0"] == same_train["k0"]
        stops = r["manoeuvre"] in ("emergency", "full")
        assert np.isfinite(r["stopping_distance_m"]) == stops
        if r["manoeuvre"] in ("partial", "start"):
            # runs for the whole duration: 30 s and 20 s of 0.01 s steps
            assert r["steps"] == {"partial": 3000, "start": 2000}[r["manoeuvre"]]
        if r["manoeuvre"] == "start":
            # pulling away from rest: the couplers behind the locomotive are in draft
            assert r["peak_draft_kN"] > 10.0 and r["max_adhesion_demand"] == 0.0
    by = {(r["run_id"], r["manoeuvre"]): r for r in rows}
    for i in range(2):
        # the emergency stop from 40 km/h is shorter than the half service application's run
        assert by[i, "emergency"]["stopping_distance_m"] < 40 / 3.6 * 30.0


def test_a_killed_pool_worker_has_its_batches_redone(reference, tmp_path):
    import psutil

    c, table = reference
    killed = []

    def kill_a_worker(runs: int, failed: int) -> None:
        if not killed:
            worker = psutil.Process().children()[0]
            worker.kill()
            worker.wait(10)
            killed.append(worker.pid)

    with PoolExecutor(2) as pool:
        summary = run_campaign(c, tmp_path / "out", pool, progress=kill_a_worker)
    assert killed and summary["runs"] == c.runs
    assert read_results(tmp_path / "out")[1].equals(table)


def test_a_campaign_band_judges_every_emergency_stop_under_every_member(reference, tmp_path):
    from ltd_brake_ros.inputs.band import load_band
    from ltd_brake_ros.studies.band import run_band
    from ltd_brake_ros.inputs import consist_from_mapping
    from ltd_brake_ros.studies.campaign import draw, models, run_one

    c, table = reference
    # without a band: no band columns, but the limit-state and range columns
    rows = table.to_pylist()
    assert all(r["band_status"] is None and r["peak_draft_kN_max"] is None for r in rows)
    assert all(r["buffers_ok"] and r["non_physical"] == "" for r in rows)
    assert all(r["in_model_range"] == (r["model_warnings"] == "") for r in rows)
    path = write_campaign(tmp_path, runs=2, batch=2)
    path.write_text(path.read_text() + "band: true\n")
    banded = load_campaign(path)
    assert banded.band == load_band()
    for run in range(2):
        [row] = run_one(banded, run)
        sample, data = draw(banded, run)
        params, lut = models(banded, sample)
        band, _ = run_band(consist_from_mapping(data, "test"), row["speed_kmh"], params, lut,
                           step_s=banded.step_s)
        assert row["band_status"] == band.status
        for name, k in band.kpis.items():
            assert (row[f"{name}_min"], row[f"{name}_max"]) == (k.low, k.high)
        # the row's own numbers are the nominal member's: within the band
        lo, hi = sorted((row["peak_buff_kN_min"], row["peak_buff_kN_max"]))
        assert lo <= row["peak_buff_kN"] <= hi
    path.write_text(path.read_text().replace("band: true", "band: 3"))
    with pytest.raises(InputError, match="band: must be true, false or a band file"):
        load_campaign(path)

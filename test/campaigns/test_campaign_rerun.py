"""Re-running a campaign's runs with recordings: the same runs, recorded as sim_node records."""
from __future__ import annotations

import numpy as np
import pytest

from campaign_helpers import SMALL

from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.physics.constants import STANDSTILL_M_S
from ltd_brake_ros.recording.bag import bag_info, read_bag
from ltd_brake_ros.recording.cdr import decode_float64_array
from ltd_brake_ros.recording.cdr_encode import encode_float64
from ltd_brake_ros.recording.plant_topics import plant_topics
from ltd_brake_ros.recording.qos import parse_qos_profiles
from ltd_brake_ros.studies.campaign import run_one
from ltd_brake_ros.studies.campaign_exec import read_results, run_campaign
from ltd_brake_ros.studies.campaign_rerun import RECORD_CHUNK_S, rerun, run_folder_name

#: The small campaign with a service application (released before the end) and a traction
#: start besides the emergency stop.
MANOEUVRES = """\
  - {kind: emergency, speed_kmh: {uniform: [30, 50]}}
  - {kind: service, speed_kmh: {uniform: [30, 50]}, demand: 0.6, release_s: 7.3,
     duration_s: 12.0}
  - {kind: traction_start, demand: 0.8, duration_s: 6.0}
"""
#: The snapshot extras every brake model's run records (physics/brakes/thermal.py).
TEMPERATURES = ("block_temperature_K", "wheel_temperature_K")
KPIS = ("stopping_distance_m", "peak_draft_kN", "peak_draft_coupler", "peak_buff_kN",
        "peak_buff_coupler")


def write_mixed(folder, name: str, runs: int, extra: str = ""):
    """The small campaign with :data:`MANOEUVRES`, ``extra`` top-level YAML appended."""
    text = SMALL.format(name=name, runs=runs, batch=3, sampling="monte_carlo", v_lo=30, v_hi=50)
    head, _, tail = text.partition("manoeuvres:\n")
    path = folder / f"{name}.yaml"
    path.write_text(head + "manoeuvres:\n" + MANOEUVRES + tail.split("\n", 1)[1] + extra)
    return path


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rerun")
    run_campaign(load_campaign(write_mixed(folder, "mixed", 6)), folder / "results")
    return folder / "results"


def test_every_rerun_is_the_campaign_run(results, tmp_path):
    c = load_campaign(results / "campaign.yaml")
    rows = read_results(results)[1].to_pylist()
    assert {r["status"] for r in rows} == {"ok"} and len(rows) == 18
    for row in rows:
        got = rerun(c, row["run_id"], row["manoeuvre"], tmp_path / f"{row['run_id']}"
                    f"{row['manoeuvre']}")
        # the same train, parameters and commands on the same steps: the same numbers
        np.testing.assert_equal([got[k] for k in KPIS], [row[k] for k in KPIS],
                                err_msg=f"run {row['run_id']} {row['manoeuvre']}")


def _coupler_forces(folder) -> np.ndarray:
    return np.array([decode_float64_array(data) for topic, _, _, data in read_bag(folder)
                     if topic == "/couplers/force"])


def test_worst_runs_recorded_as_the_node_records_and_reported_alike(results, tmp_path, capsys):
    out = tmp_path / "worst"
    assert main(["campaign", "rerun", str(results), "--worst", "2", "--manoeuvre", "emergency",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.count("as in the campaign") == 2
    main(["campaign", "report", str(results)])
    assert f"ltd-brake campaign rerun {results} --worst N --manoeuvre emergency" \
        in capsys.readouterr().out
    rows = [r for r in read_results(results)[1].to_pylist() if r["manoeuvre"] == "emergency"]
    worst = sorted(rows, key=lambda r: r["peak_buff_kN"])[:2]  # largest buff magnitude
    assert sorted(p.name for p in out.iterdir()) == sorted(
        run_folder_name(r["run_id"], "emergency") for r in worst)
    # the plant's topics and, with every brake model, the blocks' and wheels' temperature
    declared = {t: (ty, parse_qos_profiles(q)) for t, ty, q in plant_topics(extras=TEMPERATURES)}
    for row in worst:
        folder = out / run_folder_name(row["run_id"], "emergency")
        info = bag_info(folder)
        assert info.complete and (folder / "metadata.yaml").is_file()
        assert {t: (i.msg_type, i.qos_profiles) for t, i in info.topics.items()} == declared
        assert info.topics["/brake_command"].message_count == 1
        # every state goes out as arrays and stamped, as the node publishes it
        states = info.topics["/vehicles/speed"].message_count
        assert states > 1 and info.topics["/vehicles/state"].message_count == states
        assert info.topics["/couplers/state"].message_count == states
        assert info.metadata["run_id"] == row["run_id"]
        assert info.metadata["initial_speed_kmh"] == pytest.approx(row["speed_kmh"])
        rep = analyse(folder)
        # the stop as the simulator judged it, closed with its verdicts as the rerun ends
        (stop,) = rep.stops
        assert stop["stopping_distance_m"] == pytest.approx(row["stopping_distance_m"],
                                                            rel=1e-12)
        assert stop["end"] == "end of run" and stop["verdict"] in ("PASS", "WARN", "FAIL")
        # the report finds the stop at the first recorded state at standstill, at most one
        # recording interval after the step that stopped the train, moving below standstill
        assert rep.stopping_distance_m == pytest.approx(
            row["stopping_distance_m"], abs=STANDSTILL_M_S * RECORD_CHUNK_S)
        # recorded states are a subset of the steps: a recorded peak never exceeds the
        # campaign's, and falls short by at most what a force changes in one interval
        forces = _coupler_forces(folder) / 1e3
        step_kN = np.abs(np.diff(forces, axis=0)).max(axis=0)
        for kind, sign in (("draft", 1.0), ("buff", -1.0)):
            peak, true = getattr(rep, f"peak_{kind}_kN"), row[f"peak_{kind}_kN"]
            j = row[f"peak_{kind}_coupler"] - 1
            assert sign * peak <= sign * true + 1e-9
            assert sign * (true - peak) <= step_kN[j], (kind, peak, true, step_kN[j])


def test_scripted_manoeuvres_record_their_commands(results, tmp_path):
    c = load_campaign(results / "campaign.yaml")
    service = tmp_path / "service"
    rerun(c, 4, "service", service, namespace="/train1")
    commands = [(ns, data) for t, _, ns, data in read_bag(service) if t == "/train1/brake_demand"]
    # applied at t = 0 and released at the first command update (0.5 s) after 7.3 s
    assert commands == [(0, encode_float64(0.6)), (7_500_000_000, encode_float64(0.0))]
    assert set(bag_info(service).topics) == {t for t, _, _ in plant_topics("/train1",
                                                                             TEMPERATURES)}
    traction = tmp_path / "traction"
    rerun(c, 4, "traction_start", traction)
    rep = analyse(traction)
    assert rep.stopping_distance_m is None and rep.end_time_s == pytest.approx(6.0)
    assert rep.head_speed_m_s[-1] > rep.head_speed_m_s[0]


def test_bad_requests_name_the_option(results, tmp_path, capsys):
    out = str(tmp_path / "o")
    for args, expected in (
            (["--runs", "3,x"], "--runs: '3,x': write run ids"),
            (["--runs", "6"], "--runs: run 6 is not in the campaign (0 to 5)"),
            (["--worst", "1", "--kpi", "speed"], "--kpi: unknown KPI 'speed'"),
            (["--worst", "1", "--manoeuvre", "shunt"], "--manoeuvre: no manoeuvre 'shunt'")):
        assert main(["campaign", "rerun", str(results), *args, "--out", out]) == 2, args
        err = capsys.readouterr().err
        assert expected in err and "Traceback" not in err
    assert main(["campaign", "rerun", str(results), "--runs", "1", "--manoeuvre", "emergency",
                 "--out", out]) == 0
    assert main(["campaign", "rerun", str(results), "--runs", "0,1", "--out", out]) == 2
    assert "exists and is not empty" in capsys.readouterr().err
    assert not (tmp_path / "o" / run_folder_name(0, "emergency")).exists()


def test_topics_are_the_nodes():
    from ltd_brake_ros.recording.qos import qos_profiles_yaml
    from ltd_brake_ros.recording.ros_types import type_name
    from ltd_brake_ros.ros import sim_node
    from ltd_brake_ros.ros.messages import (CLOCK_QOS, COMMAND_QOS, DESCRIPTION_QOS, STATE_QOS,
                                            STOPS_QOS)

    node = ([(f"/{sim_node.DESCRIPTION_TOPIC}", "std_msgs/msg/String",
              qos_profiles_yaml(DESCRIPTION_QOS)),
             (f"/{sim_node.STOPS_TOPIC}", "std_msgs/msg/String", qos_profiles_yaml(STOPS_QOS))]
            + [(f"/{t}", "std_msgs/msg/Float64MultiArray", qos_profiles_yaml(STATE_QOS))
               for t, _, _ in sim_node.ARRAY_TOPICS]
            + [(f"/{t}", type_name(sim_node.JointState), qos_profiles_yaml(STATE_QOS))
               for t, _ in sim_node.STATE_TOPICS]
            + [(sim_node.CLOCK_TOPIC, "rosgraph_msgs/msg/Clock", qos_profiles_yaml(CLOCK_QOS))]
            + [(f"/{t}", type_name(cls), qos_profiles_yaml(COMMAND_QOS))
               for t, (cls, _) in sim_node.INPUT_TOPICS.items()])
    assert plant_topics("/") == node


def test_a_failing_run_leaves_a_complete_recording_up_to_the_failure(results, tmp_path,
                                                                      monkeypatch, capsys):
    from ltd_brake_ros.simulator import SimulationError, Simulator
    from ltd_brake_ros.studies import campaign_rerun

    class FailsAt2s(Simulator):
        def advance(self, duration_s, commands=None):
            if self.time_s >= 2.0 - 1e-9:
                raise SimulationError("Newton iteration did not converge (test)")
            return super().advance(duration_s, commands)

    monkeypatch.setattr(campaign_rerun, "Simulator", FailsAt2s)
    out = tmp_path / "o"
    # the campaign ran it without a failure: a difference, exit status 1
    assert main(["campaign", "rerun", str(results), "--runs", "2", "--manoeuvre", "emergency",
                 "--out", str(out)]) == 1
    assert "run 2 emergency: failed: Newton iteration" in capsys.readouterr().out
    folder = out / run_folder_name(2, "emergency")
    info = bag_info(folder)
    assert info.complete and info.end_ns == 2_000_000_000
    assert info.topics["/vehicles/speed"].message_count == round(2.0 / RECORD_CHUNK_S) + 1


@pytest.mark.parametrize("step_s", [0.03, 0.007])
def test_steps_that_do_not_divide_the_recording_interval(tmp_path, step_s):
    # 0.5 s is no whole number of such steps: the runs' chunks would be taken in shorter
    # steps and change the results, so the campaign is refused at load, naming the field
    path = write_mixed(tmp_path, "steps", 2, f"step_s: {step_s}\n")
    with pytest.raises(InputError, match=f"step_s: {step_s:g} s does not divide the 0.5 s "
                                         "chunks"):
        load_campaign(path)


def test_the_campaign_is_the_one_that_ran(results, tmp_path, capsys):
    import json
    import shutil

    copy = tmp_path / "results"
    shutil.copytree(results, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    # the file named in the manifest is gone: the copy in the folder serves
    manifest["campaign_file"] = str(tmp_path / "gone.yaml")
    (copy / "manifest.json").write_text(json.dumps(manifest))
    assert main(["campaign", "rerun", str(copy), "--runs", "0", "--manoeuvre", "emergency",
                 "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    # an edited copy is not the campaign that ran: refused, naming the manifest's digest
    text = (copy / "campaign.yaml").read_text()
    (copy / "campaign.yaml").write_text(text.replace("seed: 11", "seed: 12"))
    assert main(["campaign", "rerun", str(copy), "--runs", "0", "--out",
                 str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "manifest.json: digest: no campaign file with this digest" in err, err
    assert not (tmp_path / "b").exists()

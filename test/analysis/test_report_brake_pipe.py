"""The report of a recorded brake-pipe run: profiles, cylinders, filling times, the plot."""
from __future__ import annotations

import numpy as np
import pytest

from ltd_brake_ros.physics.kernel import SETTLE_S
from ltd_brake_ros.analysis.export import write_csv
from ltd_brake_ros.analysis.plots import write_plots
from ltd_brake_ros.analysis.report import (FILLED, PIPE_ONSET_PA, PIPE_PROFILE_OFFSETS_S,
                                          analyse)
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.cli.simulate import RECORD_CHUNK_S
from ltd_brake_ros.inputs import load_brake_params, load_consist
from ltd_brake_ros.simulator import Commands, Simulator

CONSIST = "config/consists/e402b_10_shimmns_80t.yaml"
PIPE_PARAMS = "config/brake_params/uic_brake_pipe.yaml"
SPEED_KMH = 30.0
PNG = b"\x89PNG\r\n\x1a\n"


def _record(folder, *params) -> None:
    assert main(["simulate", "--consist", CONSIST, "--speed-kmh", str(SPEED_KMH), *params,
                 "--record", str(folder), "--json"]) == 0


@pytest.fixture(scope="module")
def pipe_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pipe") / "run"
    _record(folder, "--params", PIPE_PARAMS)
    return folder, analyse(folder)


@pytest.fixture(scope="module")
def fine():
    """The same stop advanced in 10 ms chunks, to the train settled and a recording chunk
    beyond (the recording ends at a chunk's end): pressures of every vehicle in time."""
    sim = Simulator(load_consist(CONSIST), SPEED_KMH, load_brake_params(PIPE_PARAMS))
    snaps = [sim.snapshot()]
    commands = Commands(emergency=True)
    while (sim.settled_time_s is None or sim.time_s < sim.settled_time_s + SETTLE_S
           + RECORD_CHUNK_S) and sim.time_s < 90.0:
        snaps.append(sim.advance(0.01, commands))
        commands = None
    t = np.array([s.time_s for s in snaps])
    pipe = np.array([s.extras["brake_pipe_pressure_Pa"] for s in snaps])
    cyl = np.array([s.extras["brake_cylinder_pressure_Pa"] for s in snaps])
    return t, pipe, cyl


def _within_a_chunk(t, q, at_s, value) -> bool:
    """``value`` lies within what ``q`` takes in one recording chunk around ``at_s``."""
    near = (t >= at_s - RECORD_CHUNK_S - 1e-9) & (t <= at_s + RECORD_CHUNK_S + 1e-9)
    return q[near].min() - 1.0 <= value <= q[near].max() + 1.0  # 1 Pa: float noise


def _fill_time(t, p) -> float:
    target = FILLED * p[-1]
    k = int(np.flatnonzero(p >= target)[0])
    return float(np.interp(target, p[k - 1:k + 1], t[k - 1:k + 1]))


def test_pipe_run_gives_the_brake_pipe_plot(pipe_run, tmp_path):
    _, rep = pipe_run
    assert rep.has_brake_pipe
    paths = write_plots(rep, tmp_path)
    plot = tmp_path / "brake_pipe.png"
    assert plot in paths
    assert plot.read_bytes()[:8] == PNG
    text = rep.describe()
    assert "Brake pipe at the end" in text and "95 % of it" in text


def test_only_a_few_profiles_are_kept(pipe_run):
    _, rep = pipe_run
    k, n = rep.pipe_profile_Pa.shape
    assert n == rep.n_vehicles == 11
    assert k <= len(PIPE_PROFILE_OFFSETS_S) + 2  # and the one before the pipe moves, the end
    assert np.all(np.diff(rep.pipe_profile_time_s) > 0)
    # distance behind the head grows along the train, up to about its length (145.8 m)
    assert rep.pipe_distance_m[0] == 0.0 and np.all(np.diff(rep.pipe_distance_m) > 0)
    assert 100.0 < rep.pipe_distance_m[-1] < 145.8


def test_summary_agrees_with_the_simulator(pipe_run, fine):
    _, rep = pipe_run
    t, pipe, cyl = fine
    assert rep.pipe_reference_time_s == rep.command_time_s == 0.0
    # the first profile is the charged pipe, the second one has moved: the wave starts there
    assert np.abs(rep.pipe_profile_Pa[0] - pipe[0]).max() <= PIPE_ONSET_PA
    assert np.abs(rep.pipe_profile_Pa[1] - pipe[0]).max() > PIPE_ONSET_PA
    assert rep.pipe_profile_time_s[1] - rep.pipe_profile_time_s[0] == pytest.approx(
        RECORD_CHUNK_S)
    for k, tk in enumerate(rep.pipe_profile_time_s):
        for j in (0, rep.n_vehicles - 1):
            assert _within_a_chunk(t, pipe[:, j], tk, rep.pipe_profile_Pa[k, j])
    end = rep.end_time_s
    assert _within_a_chunk(t, pipe[:, -1], end, rep.tail_pipe_end_Pa)
    assert _within_a_chunk(t, cyl[:, -1], end, rep.tail_cylinder_end_Pa)
    assert _within_a_chunk(t, cyl[:, 1], end, rep.head_wagon_cylinder_end_Pa)
    for j, got in ((1, rep.head_wagon_fill_time_s), (rep.n_vehicles - 1, rep.tail_fill_time_s)):
        assert got is not None
        assert abs(got - _fill_time(t, cyl[:, j])) <= RECORD_CHUNK_S
    # the pipe is vented from the head: the tail cylinder fills after the head wagon's
    assert rep.tail_fill_time_s > rep.head_wagon_fill_time_s
    d = rep.as_dict()["brake_pipe"]
    assert d["tail_fill_time_s"] == rep.tail_fill_time_s


def test_csv_holds_the_pressures(pipe_run, tmp_path):
    _, rep = pipe_run
    names = {p.name for p in write_csv(rep, tmp_path)}
    assert {"brake_pipe_pressure_Pa.csv", "brake_cylinder_pressure_Pa.csv"} <= names
    rows = np.loadtxt(tmp_path / "brake_pipe_pressure_Pa.csv", delimiter=",", skiprows=1)
    assert rows.shape[1] == rep.n_vehicles + 1
    assert rows[-1, -1] == pytest.approx(rep.tail_pipe_end_Pa, rel=1e-9)  # CSV digits


def test_empirical_run_has_no_pipe_section(tmp_path):
    folder = tmp_path / "run"
    _record(folder)
    assert main(["report", str(folder)]) == 0
    rep = analyse(folder)
    assert not rep.has_brake_pipe
    assert rep.as_dict()["brake_pipe"] is None
    assert "Brake pipe" not in rep.describe()
    assert not (folder / "report" / "brake_pipe.png").exists()
    assert (folder / "report" / "speed.png").read_bytes()[:8] == PNG


def test_record_into_a_used_folder_is_one_line(tmp_path, capsys):
    folder = tmp_path / "used"
    folder.mkdir()
    (folder / "notes.txt").write_text("an earlier run\n")
    assert main(["simulate", "--consist", CONSIST, "--speed-kmh", "30", "--record",
                 str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ltd-brake simulate: error:") and err.count("\n") == 1, err
    assert "--record" in err and "not empty" in err
    assert [p.name for p in folder.iterdir()] == ["notes.txt"]


def test_profiles_follow_the_emergency_after_a_service_application(tmp_path):
    folder = tmp_path / "run"
    assert main(["simulate", "--consist", CONSIST, "--speed-kmh", "60", "--params", PIPE_PARAMS,
                 "--commands", "config/commands/service_then_emergency.yaml", "--record",
                 str(folder), "--json"]) == 0
    rep = analyse(folder)
    assert rep.command_time_s is not None and rep.command_time_s > 0.0
    assert rep.pipe_reference_time_s == rep.command_time_s
    # the profiles show the emergency wave, not the service application before it
    times, profiles = rep.pipe_profile_time_s, rep.pipe_profile_Pa
    assert times[0] >= rep.command_time_s
    assert np.abs(profiles[1] - profiles[0]).max() > PIPE_ONSET_PA
    assert profiles[-1].max() < profiles[0].min()  # vented everywhere at the end
    assert rep.tail_fill_time_s is not None and rep.tail_fill_time_s > 0.0


def test_driver_brake_valve_script_is_recorded_and_its_emergency_counts(tmp_path):
    from ltd_brake_ros.analysis.samples import BRAKE_COMMAND, plant_samples
    from ltd_brake_ros.recording.cdr import decode_string
    from ltd_brake_ros.recording.reader import read_bag

    script = tmp_path / "valve.yaml"
    script.write_text("duration_s: 30.0\ncommands:\n"
                      "  - {t_s: 0.0, driver_brake_valve: service}\n"
                      "  - {t_s: 4.0, driver_brake_valve: lap}\n"
                      "  - {t_s: 8.0, driver_brake_valve: release_overcharge}\n"
                      "  - {t_s: 16.0, driver_brake_valve: emergency}\n")
    folder = tmp_path / "run"
    assert main(["simulate", "--consist", CONSIST, "--speed-kmh", "60", "--params", PIPE_PARAMS,
                 "--commands", str(script), "--record", str(folder), "--json"]) == 0
    # lap changes no input, so it sends nothing; the other positions go out by name, in order
    sent = [(round(log_ns * 1e-9, 3), decode_string(data))
            for topic, _, log_ns, data in read_bag(folder) if topic == "/driver_brake_valve"]
    assert sent == [(0.0, "service"), (8.0, "release_overcharge"), (16.0, "emergency")]
    commands = [t for name, t, _, value in plant_samples(folder, "") if name == BRAKE_COMMAND
                and value]
    assert commands and commands[0] == pytest.approx(16.0)
    assert analyse(folder).command_time_s == pytest.approx(16.0)

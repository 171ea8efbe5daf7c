"""``ltd-brake simulate`` and ``validate``: what they print and how they refuse bad input."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
import yaml

from cli_fixtures import one_line_error  # noqa: F401 - fixtures
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.physics.constants import KMH_PER_MS, STANDSTILL_M_S
from ltd_brake_ros.studies.runs import emergency_stop



@pytest.mark.parametrize("argv, words", [
    (["validate", "--scenarios", "13"], ["--scenarios", "unknown scenario 13", "1-12"]),
    (["validate", "--scenarios", "6-1"], ["--scenarios", "1-6,9"]),
    (["validate", "--jobs", "0"], ["--jobs", "at least 1"]),
    (["simulate"], ["--scenario/--consist"]),
    (["simulate", "--scenario", "6", "--speed-kmh", "500"], ["--speed-kmh", "400 km/h"]),
    (["simulate", "--scenario", "13"], ["--scenario/--consist", "unknown scenario"]),
])
def test_bad_options_are_one_line_naming_the_option(argv, words, one_line_error):
    assert main(argv) == 2
    err = one_line_error(argv[0])
    for w in words:
        assert w in err


def test_validate_json_holds_the_run_and_the_paper(capsys):
    assert main(["validate", "--scenarios", "7", "--jobs", "1", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    sc = get_scenario(7)
    ref = emergency_stop(sc.consist(), sc.speed_kmh)
    assert row["scenario"] == 7 and row["paper"] == sc.paper
    assert row["ours"]["stopping_distance_m"] == ref.stopping_distance_m
    assert row["ours"]["peak_buff_kN"] == ref.peak_buff_kN < 0


def test_scripted_emergency_at_time_zero_travels_the_stopping_distance(tmp_path, capsys):
    # emergency at t = 0: the head's travel to the stop is the stopping distance itself
    script = tmp_path / "stop.yaml"
    script.write_text(yaml.safe_dump({"commands": [{"t_s": 0.0, "emergency": True}]}))
    assert main(["simulate", "--scenario", "7", "--start-chainage-m", "1234.5",
                 "--commands", str(script), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # the run ends with the 0.1 s chunk in which the train stopped: meanwhile every vehicle is
    # slower than STANDSTILL_M_S, so the head moves less than that times 0.1 s after the stop
    assert out["distance_travelled_m"] == pytest.approx(out["stopping_distance_m"],
                                                        abs=STANDSTILL_M_S * 0.1)
    assert out["stopping_distance_m"] > 100.0
    assert out["final_speed_kmh"] == pytest.approx(0.0, abs=STANDSTILL_M_S * KMH_PER_MS)
    assert out["peak_buff_kN"] < 0 < out["peak_draft_kN"] and out["peak_draft_coupler"] >= 1


def test_output_closed_early_is_not_an_error_trace():
    # `ltd-brake validate | head -1`: the reader is gone before the table is printed
    proc = subprocess.Popen([sys.executable, "-m", "ltd_brake_ros.cli", "validate",
                             "--scenarios", "7", "--jobs", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141 and err == b""


@pytest.mark.parametrize("verb", [[], ["simulate"], ["validate"], ["report"]])
def test_help_teaches_units_and_signs(capsys, verb):
    with pytest.raises(SystemExit) as exc:
        main([*verb, "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for words in ("km/h", "SI (m, s, N)", "coupler 1 is the coupler behind the head",
                  "draft\n  (tension) forces are positive, buff (compression) forces negative"):
        assert words in text


def test_a_verbs_help_needs_no_physics():
    # a verb's --help and usage errors come from its own options alone: they must not wait
    # for the compiled physics (numba) to import
    code = ("import sys\nfrom ltd_brake_ros.cli.main import main\n"
            "try:\n    main(['simulate', '--help'])\nexcept SystemExit as exc:\n"
            "    assert exc.code == 0\n"
            "print(sorted(m for m in ('numba', 'ltd_brake_ros.physics', 'ltd_brake_ros.inputs')"
            " if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120).stdout
    assert "--scenario" in out and out.splitlines()[-1] == "[]"


@pytest.mark.parametrize("argv", [["simulate", "--scenario", "6", "--json", "--step-s", "0.02"],
                                  ["calibrate", "--target", "paper", "--fit", "k0"],
                                  ["campaign", "run", "x.yaml", "--out", "d"]])
def test_a_verb_parses_alone_as_among_all(argv):
    from ltd_brake_ros.cli.main import build_parser

    alone = vars(build_parser(argv[0]).parse_args(argv))
    among_all = vars(build_parser().parse_args(argv))
    assert alone == among_all and alone["func"].__module__.endswith(argv[0])

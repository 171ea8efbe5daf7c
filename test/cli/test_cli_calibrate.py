"""``ltd-brake calibrate``: the parameter file it writes, one-line errors, the help text."""
from dataclasses import replace

import pytest

from bag_helpers import DiskFull
from cli_fixtures import one_line_error  # noqa: F401 - fixtures
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import load_brake_params, load_coupler_lut, load_scenarios
from ltd_brake_ros.recording import output as output_module
from ltd_brake_ros.studies.runs import emergency_stop


# --------------------------------------------------------------------------- parameter file


def test_out_file_round_trips(tmp_path, capsys):
    out = tmp_path / "fitted.yaml"
    code = main(["calibrate", "--target", "paper", "--fit", "k0", "--scenarios", "1,2",
                 "--step-s", "0.02", "--jobs", "2", "--quiet", "--out", str(out)])
    assert code == 0
    report = capsys.readouterr().out
    assert "| k0 |" in report and f"wrote {out}" in report
    params = load_brake_params(out)
    start = load_brake_params()
    assert params.source == str(out)
    # only k0 moved; the written values are the ones the residuals were computed with
    assert params.k0 != start.k0
    assert replace(params, k0=start.k0, source="") == replace(start, source="")
    text = out.read_text()
    assert "--fit k0 --scenarios 1,2 --step-s 0.02" in text
    lut = load_coupler_lut()
    sc = load_scenarios()[1]
    d = emergency_stop(sc.consist(), sc.speed_kmh, params, lut, step_s=0.02).stopping_distance_m
    assert f"sim {d:6.1f} m" in text


def test_out_file_on_a_full_disk_is_one_line_and_keeps_the_old_file(tmp_path, monkeypatch,
                                                                     one_line_error):
    out = tmp_path / "fitted.yaml"
    out.write_text("previous: file\n")
    monkeypatch.setattr(output_module, "open", DiskFull(500).open, raising=False)
    assert main(["calibrate", "--target", "paper", "--fit", "k0", "--scenarios", "1",
                 "--step-s", "0.05", "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    assert "No space left on device" in one_line_error("calibrate")
    assert out.read_text() == "previous: file\n"  # not a truncated parameter file
    assert [p.name for p in tmp_path.iterdir()] == ["fitted.yaml"]


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("argv, words", [
    (["--fit", "t_app,brake_force"], ["--fit", "unknown parameter 'brake_force'", "t_app",
                                       "v_air", "k0"]),
    (["--fit", ","], ["--fit", "at least one parameter"]),
    (["--target", "uic", "--speed-kmh", "50"], ["--speed-kmh", "100 km/h"]),
    (["--target", "paper", "--scenarios", "1,7"], ["scenario 7", "50 km/h"]),
    (["--scenarios", "1-x"], ["--scenarios", "1-6"]),
    (["--target", "paper", "--consist", "consists/e402b_10_shimmns_80t.yaml"],
     ["--consist", "--target uic"]),
])
def test_bad_input_exits_2_with_clear_message(argv, words, one_line_error):
    assert main(["calibrate", *argv, "--quiet"]) == 2
    err = one_line_error("calibrate")
    for w in words:
        assert w in err


def test_help_teaches_units_and_targets(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["calibrate", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for w in ("UIC 544-1", "LTDPoliTo", "S = C/lambda + D", "km/h", "[m/s]", "t_fill",
              "confidence"):
        assert w in text

"""``ltd-brake report`` and ``ltd-brake recover``: output, exit status, one-line errors."""
from __future__ import annotations

import json

import pytest

from cli_fixtures import folder, one_line_error  # noqa: F401 - fixtures
from ltd_brake_ros.cli.main import main


def test_report_prints_json_and_writes_plots_and_csv(folder, tmp_path, capsys):
    assert main(["report", str(folder), "--out", str(tmp_path / "out"), "--csv", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["peak_draft_coupler"] == 1 and len(out["plots"]) == 4 and out["csv"]
    assert out["metadata"]["consist"]["vehicles"] == 11
    assert out["peak_buff_kN"] < 0 < out["peak_draft_kN"]
    assert main(["report", str(folder / "run_0.mcap"), "--out", str(tmp_path / "o2")]) == 0
    text = capsys.readouterr().out
    assert "Peak buff" in text and "draft (tension) positive" in text


@pytest.mark.parametrize("make, words", [
    (lambda d: d / "missing", ["RUN", "no recording at"]),
    (lambda d: (d / "notes.mcap").write_text("not a recording") and d / "notes.mcap",
     ["RUN", "not an MCAP file"]),
])
def test_report_of_what_is_not_a_recording_is_one_line(tmp_path, make, words, one_line_error):
    assert main(["report", str(make(tmp_path))]) == 2
    err = one_line_error("report")
    for w in words:
        assert w in err


def test_report_into_an_unwritable_place_is_one_line(folder, tmp_path, one_line_error):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["report", str(folder), "--out", str(blocker / "sub")]) == 2
    assert "--out" in one_line_error("report")


def test_recover_rewrites_a_cut_recording(folder, tmp_path, capsys, one_line_error):
    data = (folder / "run_0.mcap").read_bytes()
    cut = tmp_path / "killed.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    assert main(["recover", str(cut)]) == 0
    out = capsys.readouterr().out
    assert "source ended early" in out and "recovered" in out
    assert (tmp_path / "killed_recovered" / "metadata.yaml").is_file()
    # the destination now holds a bag: a second recovery there is refused
    assert main(["recover", str(cut), str(tmp_path / "killed_recovered")]) == 2
    assert "DST" in one_line_error("recover")
    assert main(["recover", str(tmp_path / "missing")]) == 2
    assert "SRC" in one_line_error("recover")

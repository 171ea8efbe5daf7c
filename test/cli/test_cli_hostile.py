"""``ltd-brake report`` and ``recover`` on hostile recordings and failing outputs.

Every case ends with exit status 2 and one line naming the file (or option) and the reason —
never a traceback, never exit 0 with a wrong or half-written result. A full disk is simulated
in-process (writes that fail with ENOSPC once a byte budget is spent) and, once per output
path, for real in a child process whose file-size limit makes the kernel refuse the write.
"""
from __future__ import annotations

import os
import resource
import shutil
import signal
import subprocess
import sys

import pytest

from bag_helpers import PNG_END, DiskFull, record_emergency_stop
from cli_fixtures import folder, one_line_error  # noqa: F401 - fixtures
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros import outputs as output_module


@pytest.fixture(scope="module")
def mixed(folder, tmp_path_factory):
    """The run of ``folder`` and another run (scenario 10) in one folder, no metadata.yaml."""
    root = tmp_path_factory.mktemp("mixed")
    sc = get_scenario(10)
    record_emergency_stop(root / "other", sc.consist(), sc.speed_kmh, ns="/train1",
                          chunk_size=1 << 16)
    both = root / "both"
    both.mkdir()
    shutil.copy(folder / "run_0.mcap", both / "run_0.mcap")
    shutil.copy(root / "other" / "other_0.mcap", both / "other_0.mcap")
    return both


def _no_partial_files(out) -> None:
    """After a failed report: every plot complete, no CSV (all or none), no temporary file."""
    for p in out.iterdir() if out.exists() else ():
        assert not p.name.startswith(".") and p.suffix != ".csv", p
        if p.suffix == ".png":
            assert p.read_bytes().endswith(PNG_END), p


@pytest.mark.parametrize("verb", ["report", "recover"])
def test_two_runs_in_one_folder_are_refused(mixed, tmp_path, verb, one_line_error):
    argv = [verb, str(mixed), str(tmp_path / "out")] if verb == "recover" else \
        [verb, str(mixed), "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    err = one_line_error(verb)
    for w in ("run_0.mcap", "other_0.mcap", "not parts of one run", "give one .mcap"):
        assert w in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("verb", ["report", "recover"])
@pytest.mark.parametrize("text", ["{not: yaml", "- a list\n", "rosbag2_bagfile_information:\n"
                                  "  relative_file_paths: [gone_0.mcap]\n"])
def test_odd_metadata_yaml_is_one_line(folder, tmp_path, verb, text, one_line_error):
    bag = tmp_path / "bag"
    shutil.copytree(folder, bag)
    (bag / "metadata.yaml").write_text(text)
    assert main([verb, str(bag), str(tmp_path / "out")] if verb == "recover" else
                [verb, str(bag), "--out", str(tmp_path / "out")]) == 2
    err = one_line_error(verb)
    assert "metadata.yaml" in err and ("SRC" if verb == "recover" else "RUN") in err


def test_a_file_cut_inside_its_header_is_one_line(folder, tmp_path, one_line_error):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes((folder / "run_0.mcap").read_bytes()[:20])
    assert main(["report", str(cut), "--out", str(tmp_path / "out")]) == 2
    assert "no <ns>/vehicles/speed topic" in one_line_error("report")


@pytest.mark.parametrize("where", ["out", "default"])
def test_report_out_on_a_file_is_one_line(folder, tmp_path, where, one_line_error):
    if where == "out":
        target = tmp_path / "a_file"
        target.write_text("keep me")
        argv = ["report", str(folder), "--out", str(target)]
    else:  # the default RUN_report beside an .mcap file is a file
        mcap = tmp_path / "run.mcap"
        shutil.copy(folder / "run_0.mcap", mcap)
        target = tmp_path / "run_report"
        target.write_text("keep me")
        argv = ["report", str(mcap)]
    assert main(argv) == 2
    err = one_line_error("report")
    assert "--out" in err and "is a file" in err
    assert target.read_text() == "keep me"


# --------------------------------------------------------------------------- a full disk


def test_report_csv_on_a_full_disk_is_one_line_and_leaves_no_partial_file(
        folder, tmp_path, monkeypatch, one_line_error):
    out = tmp_path / "out"
    disk = DiskFull(400_000)  # the plots fit, the CSV do not
    monkeypatch.setattr(output_module, "open", disk.open, raising=False)
    assert main(["report", str(folder), "--out", str(out), "--csv"]) == 2
    err = one_line_error("report")
    assert "--out" in err and "No space left on device" in err and ".csv" in err
    _no_partial_files(out)
    assert len(list(out.glob("*.png"))) == 4


def test_recover_on_a_full_disk_is_one_line_and_leaves_nothing(folder, tmp_path, monkeypatch,
                                                               one_line_error):
    monkeypatch.setattr(os, "writev", DiskFull(100_000).writev)
    assert main(["recover", str(folder), str(tmp_path / "rec")]) == 2
    err = one_line_error("recover")
    assert "DST" in err and "No space left on device" in err
    assert not (tmp_path / "rec").exists()


def test_standard_output_on_a_full_disk_is_one_line(folder, tmp_path, monkeypatch, capsys,
                                                    one_line_error):
    capsys.readouterr()
    monkeypatch.setattr(sys, "stdout", DiskFull(1000).stream())  # the JSON takes 2.6 kB
    assert main(["report", str(folder), "--out", str(tmp_path / "out"), "--json"]) == 2
    assert "cannot write the output: No space left on device" in one_line_error("report")


def _limited(limit_bytes: int):
    """Child set-up: files may not grow past ``limit_bytes`` (the kernel refuses with EFBIG)."""
    def apply():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return apply


@pytest.mark.parametrize("argv, reason", [
    (["report", "--csv"], "File too large"),
    (["recover"], "File too large"),
    (["report", "--json"], "No space left on device"),
])
def test_a_real_write_refused_by_the_kernel_is_one_line(folder, tmp_path, argv, reason):
    # files may grow to 100 kB: the plots fit, the CSV and the bag do not; standard output
    # goes to /dev/full, which refuses every write with ENOSPC
    out = tmp_path / "out"
    verb, *options = argv
    where = [str(out)] if verb == "recover" else ["--out", str(out)]
    with open("/dev/full" if "--json" in argv else os.devnull, "w") as stdout:
        proc = subprocess.run([sys.executable, "-m", "ltd_brake_ros.cli", verb, str(folder),
                               *where, *options], stdout=stdout, stderr=subprocess.PIPE,
                              text=True, preexec_fn=_limited(100_000), timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith(f"ltd-brake {verb}: error:")
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert reason in proc.stderr
    if verb == "recover":
        assert not out.exists()
    else:
        _no_partial_files(out)

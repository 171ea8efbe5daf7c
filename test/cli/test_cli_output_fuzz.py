"""Property-based fuzzing of the command line's output paths.

``ltd-brake report`` and ``recover`` write into generated places (new, nested, an existing
folder, a file, below a file) on a disk that fills up after a generated number of bytes, and
print to a standard output that may fill up too. Every run either succeeds with every output
complete, or exits 2 with one line on stderr and leaves no half-written file.
"""
from __future__ import annotations

import errno
import json
import os
from datetime import timedelta

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bag_helpers import PNG_END, DiskFull, plant_messages, write_messages
from ltd_brake_ros.cli.main import main
from ltd_brake_ros import outputs as output_module
from ltd_brake_ros.recording.reader import read_bag

SETTINGS = dict(deadline=timedelta(seconds=30), derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
PLANT = plant_messages(n_vehicles=4, samples=30, ns="/train1")


def _place(root, kind):
    """An --out / DST of the given kind under ``root``."""
    if kind == "file":
        (root / "a_file").write_text("")
        return root / "a_file"
    if kind == "below_a_file":
        (root / "a_file").write_text("")
        return root / "a_file" / "out"
    if kind == "existing":
        (root / "out").mkdir()
        return root / "out"
    return root / "new" / "nested" / "out" if kind == "nested" else root / "out"


def _one_line(err: str, verb: str) -> None:
    assert err.startswith(f"ltd-brake {verb}: error:") and err.count("\n") == 1, err
    assert "Traceback" not in err


KINDS = ["new", "nested", "existing", "file", "below_a_file"]


@settings(max_examples=15, **SETTINGS)
@given(kind=st.sampled_from(KINDS), budget=st.integers(0, 600_000),
       stdout_budget=st.integers(0, 6000), csv=st.booleans())
def test_report_outputs(tmp_path_factory, monkeypatch, capsys, kind, budget, stdout_budget,
                        csv):
    root = tmp_path_factory.mktemp("report")
    write_messages(root / "run", PLANT)
    out = _place(root, kind)
    stdout = DiskFull(stdout_budget).stream()
    with monkeypatch.context() as m:
        m.setattr(output_module, "open", DiskFull(budget).open, raising=False)
        m.setattr("sys.stdout", stdout)
        status = main(["report", str(root / "run"), "--out", str(out), "--json"]
                      + ["--csv"] * csv)
    err = capsys.readouterr().err
    if out.is_dir():
        assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file
    if status == 2:
        _one_line(err, "report")
        if out.is_dir():  # what is there is complete, and the CSV are all there or none
            _complete(out.glob("*.png"), out.glob("*.csv"))
            assert len(list(out.glob("*.csv"))) in (0, 7)
        return
    assert status == 0 and err == "" and kind not in ("file", "below_a_file")
    printed = json.loads("".join(stdout.written))
    assert len(printed["plots"]) == 4 and len(printed["csv"]) == (7 if csv else 0)
    _complete(printed["plots"], printed["csv"])


def _complete(plots, csvs) -> None:
    for p in plots:
        assert open(p, "rb").read().endswith(PNG_END), p
    for p in csvs:
        rows = np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2)
        if str(p).endswith("speed_m_s.csv"):
            assert rows.shape == (30, 5)



@settings(max_examples=25, **SETTINGS)
@given(kind=st.sampled_from(KINDS), budget=st.integers(0, 40_000))
def test_recover_outputs(tmp_path_factory, monkeypatch, capsys, kind, budget):
    root = tmp_path_factory.mktemp("recover")
    src = root / "run"
    write_messages(src, PLANT, chunk_size=4096)
    dst = _place(root, kind)
    existed = dst.exists()
    with monkeypatch.context() as m:
        m.setattr(os, "writev", DiskFull(budget).writev)
        status = main(["recover", str(src), str(dst)])
    err = capsys.readouterr().err
    if status == 2:
        _one_line(err, "recover")
        assert dst.exists() == existed and (not dst.is_dir() or not list(dst.iterdir()))
        return
    assert status == 0 and kind not in ("file", "below_a_file")
    assert list(read_bag(dst)) == list(read_bag(src))


def test_the_fuzzed_disk_fails_as_a_full_disk_does():
    # guards the tests above against a budget that never bites
    disk = DiskFull(10)
    disk.take(10)
    with pytest.raises(OSError) as err:
        disk.take(1)
    assert err.value.errno == errno.ENOSPC

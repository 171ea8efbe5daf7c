"""A recording says it is unfinished while it is written and after a crash, and is read."""
from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from bag_helpers import plant_messages
from ltd_brake_ros.cli.main import main
from ltd_brake_ros.recording.layout import UNFINISHED_NAME
from ltd_brake_ros.recording.reader import bag_info
from ltd_brake_ros.recording.writer import BagWriter

PLANT = plant_messages(n_vehicles=3, samples=30, ns="/train")


def _record(folder, close: bool) -> BagWriter:
    w = BagWriter(folder, chunk_size=1 << 10)  # small chunks: most reach the disk at once
    for topic, msg_type, *_ in PLANT:
        w.add_topic(topic, msg_type)
    for topic, _type, t_ns, data in PLANT:
        w.write(topic, data, t_ns)
    if close:
        w.close()
    return w


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_recording_under_way_is_marked_and_the_finished_one_is_a_plain_rosbag2_folder(
        tmp_path):
    folder = tmp_path / "run"
    w = _record(folder, close=False)
    try:
        assert sorted(p.name for p in folder.iterdir()) == [UNFINISHED_NAME, "run_0.mcap"]
        info = bag_info(folder)
        assert not info.complete and "still recording" in info.unfinished
    finally:
        w.close()
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml", "run_0.mcap"]
    info = bag_info(folder)
    assert info.complete and info.unfinished == ""
    rosbags = pytest.importorskip("rosbags.rosbag2")
    with rosbags.Reader(folder) as reader:
        assert reader.message_count == len(PLANT)


def test_a_marked_folder_is_not_recorded_into_again(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / UNFINISHED_NAME).write_text("pid: 1\nhost: elsewhere\n")
    with pytest.raises(FileExistsError, match="another recorder is writing"):
        BagWriter(folder)
    assert sorted(p.name for p in folder.iterdir()) == [UNFINISHED_NAME]


@pytest.fixture
def crashed(tmp_path):
    """A recording whose recorder died: its file cut after the last flushed chunk, the marker
    naming a process that has ended."""
    live = tmp_path / "live"
    w = _record(live, close=False)
    try:
        crashed = tmp_path / "crashed"
        crashed.mkdir()
        shutil.copy(live / "live_0.mcap", crashed / "crashed_0.mcap")
        marker = (live / UNFINISHED_NAME).read_text()
        pid = marker.split("pid: ")[1].split()[0]
        (crashed / UNFINISHED_NAME).write_text(marker.replace(f"pid: {pid}",
                                                              f"pid: {_dead_pid()}"))
    finally:
        w.close()
    return crashed


def test_an_unfinished_recording_is_reported_with_a_warning(crashed, tmp_path, capsys):
    info = bag_info(crashed)
    assert not info.complete and "ended without closing it" in info.unfinished
    assert main(["report", str(crashed), "--out", str(tmp_path / "report"), "--json"]) == 0
    out = capsys.readouterr()
    warning = [line for line in out.err.splitlines() if "warning" in line]
    assert len(warning) == 1 and "unfinished" in warning[0] and str(crashed) in warning[0]
    assert '"complete": false' in out.out


def test_an_unfinished_recording_is_recovered_with_a_warning(crashed, tmp_path, capsys):
    dst = tmp_path / "recovered"
    assert main(["recover", str(crashed), str(dst)]) == 0
    out = capsys.readouterr()
    assert "warning" in out.err and "not finished by its recorder" in out.err
    assert sorted(p.name for p in dst.iterdir()) == ["metadata.yaml", "recovered_0.mcap"]
    info = bag_info(dst)
    assert info.complete and info.message_count == bag_info(crashed).message_count

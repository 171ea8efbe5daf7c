"""The recorder's lifecycle in the plant: open, write, flush while idle, reset, failures.

A fake writer shows what the plant asks of it and fails on demand (a full disk); one test
records through the real writer and reads the bag back.
"""
from __future__ import annotations

import errno
import functools

import pytest

from plant_helpers import Log, make_plant
from ltd_brake_ros.plant.diagnostics import OK, WARN
from ltd_brake_ros.plant.recorder import Recorder
from ltd_brake_ros.plant.settings import StartupError
from ltd_brake_ros.recording.bag import bag_info, read_bag
from ltd_brake_ros.simulator import SimulationError

TOPICS = [("/t/clock", "rosgraph_msgs/msg/Clock", "- depth: 1"),
          ("/t/brake_command", "std_msgs/msg/Bool", "- depth: 1000")]


class FakeWriter:
    """Keeps what it is given; ``fail_at`` makes that call raise (a full disk)."""

    def __init__(self, folder, metadata=None, *, opened, fail_at=(), flush_in_s=0.3):
        self.folder, self.metadata = folder, metadata
        self.topics, self.messages, self.flushes, self.closed = [], [], 0, False
        self._fail_at, self.flush_in_s = set(fail_at), flush_in_s
        if "open" in self._fail_at:
            raise OSError(errno.EACCES, "Permission denied")
        opened.append(self)

    def _maybe_fail(self, call):
        if call in self._fail_at:
            raise OSError(errno.EFBIG, "File too large")

    def add_topic(self, topic, msg_type, qos=None):
        self._maybe_fail("add_topic")
        self.topics.append((topic, msg_type, qos))

    def write(self, topic, data, log_time_ns):
        self._maybe_fail("write")
        self.messages.append((topic, data, log_time_ns))

    def flush_if_due(self):
        self.flushes += 1

    def seconds_until_flush(self):
        return self.flush_in_s

    def close(self):
        self.closed = True
        self._maybe_fail("close")

    @property
    def message_count(self):
        return len(self.messages)

    messages_on_disk = message_count


def recorder(opened, log=None, **writer_options):
    return Recorder("runs/r", TOPICS, log or Log(), metadata={"run": 1},
                    writer=functools.partial(FakeWriter, opened=opened, **writer_options))


def recording_plant(opened, **settings):
    """A plant recording its states through a fake writer (options in ``settings``)."""
    options = {k: settings.pop(k) for k in ("fail_at",) if k in settings}
    log = Log()
    rec = recorder(opened, log, **options)
    rec.open()
    return make_plant(recorder=rec, log=log, **settings), rec


def test_opening_declares_every_topic_with_its_type_qos_and_the_run_metadata():
    opened = []
    log = Log()
    rec = recorder(opened, log)
    assert rec.seconds_until_flush() == float("inf") and not rec.active
    rec.open()
    assert rec.active and rec.state == "runs/r" and log.at("info") == ["recording to runs/r"]
    assert opened[0].topics == TOPICS and opened[0].metadata == {"run": 1}
    rec.write("/t/clock", b"x", 5)
    rec.close()
    assert opened[0].closed and opened[0].messages == [("/t/clock", b"x", 5)]
    assert log.at("info")[-1] == "recording finished: 1 messages in runs/r"
    assert rec.state == "finished" and not rec.active
    rec.write("/t/clock", b"y", 6)  # nothing open: ignored
    assert opened[0].messages == [("/t/clock", b"x", 5)]


@pytest.mark.parametrize("fail_at", ["open", "add_topic"])
def test_a_bag_that_cannot_be_opened_names_record_dir_and_leaves_nothing_open(fail_at):
    opened = []
    rec = recorder(opened, fail_at={fail_at})
    with pytest.raises(StartupError) as err:
        rec.open()
    assert err.value.parameter == "record_dir"
    assert str(err.value).startswith("parameter record_dir: cannot record to runs/r: [Errno")
    assert not rec.active and all(w.closed for w in opened)  # a half-opened bag is closed


def test_an_idle_plant_still_flushes_within_the_interval():
    opened = []
    plant, rec = recording_plant(opened, lockstep=True)
    assert plant.runner.poll() == pytest.approx(0.3)  # the writer's flush is due before 1 s
    plant.run_until(plant.clock.t + 3.0)
    assert opened[0].flushes >= 10  # one poll at least every 0.3 s


def test_reset_finishes_the_bag_and_starts_the_next_run_in_a_new_folder():
    opened = []
    plant, rec = recording_plant(opened, lockstep=True)
    plant.request(plant.runner.step())
    plant.request(plant.runner.reset())
    assert [w.folder for w in opened] == ["runs/r", "runs/r_2"]
    assert opened[0].closed and not opened[1].closed
    assert [m[2] for m in opened[0].messages] == [0, 20_000_000]
    assert [m[2] for m in opened[1].messages] == [0]  # the new run starts at t = 0
    assert "recording finished: 2 messages in runs/r" in plant.log.at("info")
    plant.runner.close()
    assert opened[1].closed


def test_a_simulator_failure_finishes_the_bag_and_reset_starts_the_next(monkeypatch):
    opened = []
    plant, rec = recording_plant(opened, lockstep=True)

    def diverge(*args, **kwargs):
        raise SimulationError("forced")

    monkeypatch.setattr(plant.runner.sim, "advance", diverge)
    assert not plant.request(plant.runner.step())[0]
    assert opened[0].closed and rec.state == "finished"
    # the ERROR report is published before the bag is finished (it ends the bag); the next
    # one says the bag is finished
    assert plant.statuses[-1][1].values["recording"] == "runs/r"
    plant.run_until(plant.clock.t + 1.5)
    assert plant.statuses[-1][1].values["recording"] == "finished"
    monkeypatch.undo()
    plant.request(plant.runner.reset())
    assert rec.state == "runs/r_2" and not opened[1].closed


def test_a_write_error_stops_the_recording_not_the_plant():
    opened = []
    plant, rec = recording_plant(opened, real_time_factor=1.0, fail_at={"write"})
    start = plant.clock.t
    plant.run_until(start + 1.51)
    assert rec.error == "OSError: [Errno 27] File too large" and rec.state == "failed"
    assert opened[0].closed
    line, = plant.log.at("error")
    assert line == ("recording to runs/r stopped: OSError: [Errno 27] File too large; the plant "
                    "keeps running; 0 messages are on disk (ltd-brake recover runs/r makes it "
                    "a complete bag)")
    assert plant.runner.stats.chunks == 75  # 1.5 s at real_time_factor 1, on time
    status = plant.statuses[-1][1]
    assert status.level == WARN and status.message == "recording stopped"
    assert (status.values["recording"], status.values["recording_error"]) == \
        ("failed", rec.error)
    # a reset that cannot record either is refused: the run goes on, unrecorded, as it was
    rec._make_writer = functools.partial(FakeWriter, opened=[], fail_at={"open"})
    chunks = plant.runner.stats.chunks
    assert plant.request(plant.runner.reset()) == (
        False, "not reset: cannot record to runs/r_2: [Errno 13] Permission denied; the run "
        "goes on without recording")
    assert plant.runner.resets == 0 and plant.runner.stats.chunks >= chunks
    # the next run records again, to a new folder
    opened_ok = []
    rec._make_writer = functools.partial(FakeWriter, opened=opened_ok)
    plant.request(plant.runner.reset())
    assert rec.error is None and rec.state == "runs/r_2"
    plant.run_until(plant.clock.t + 1.01)
    assert plant.statuses[-1][1].level == OK
    assert len(opened_ok[0].messages) == 51  # the reset state and a second of chunks


def test_a_failing_close_counts_as_a_write_error():
    opened = []
    log = Log()
    rec = recorder(opened, log, fail_at={"close"})
    rec.open()
    rec.close()
    assert rec.error == "OSError: [Errno 27] File too large" and rec.state == "failed"
    assert "stopped: OSError" in log.at("error")[0]


def test_the_real_writer_yields_a_complete_readable_bag(tmp_path):
    folder = tmp_path / "run"
    log = Log()
    rec = Recorder(str(folder), [("/t/brake_command", "std_msgs/msg/Bool", None)], log,
                   metadata={"consist": {"name": "short"}})
    rec.open()
    for k in range(3):
        # std_msgs/Bool in CDR: the 4-byte header, then the value
        rec.write("/t/brake_command", bytes([0, 1, 0, 0, k % 2]), k * 20_000_000)
    rec.close()
    info = bag_info(folder)
    assert info.complete and info.message_count == 3
    assert [(t, n) for t, _, n, _ in read_bag(folder)] == \
        [("/t/brake_command", k * 20_000_000) for k in range(3)]
    assert log.at("info")[-1] == f"recording finished: 3 messages in {folder}"


# --------------------------------------------------------------------------- folders in use


def _bag_in(folder, log=None):
    """A finished one-message bag in ``folder`` (what an earlier run leaves behind)."""
    rec = Recorder(str(folder), [("/t/clock", "rosgraph_msgs/msg/Clock", None)], log or Log())
    rec.open()
    rec.write("/t/clock", bytes([0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]), 0)
    rec.close()


def test_reset_records_to_the_next_free_folder_when_the_next_name_is_taken(tmp_path):
    """An earlier run that was reset once left ``<record_dir>_2``: the next run goes to
    ``_3``, the reply says so, and everything after the reset is recorded."""
    base = tmp_path / "run"
    _bag_in(tmp_path / "run_2")
    earlier = sorted(p.name for p in (tmp_path / "run_2").iterdir())
    log = Log()
    rec = Recorder(str(base), [("/t/clock", "rosgraph_msgs/msg/Clock", None)], log)
    rec.open()
    plant = make_plant(recorder=rec, log=log, lockstep=True)
    plant.request(plant.runner.step())
    ok, text = plant.request(plant.runner.reset())
    assert ok and text.endswith(f"; recording to {tmp_path / 'run_3'}"), text
    assert rec.active and rec.state == str(tmp_path / "run_3")
    plant.request(plant.runner.step())
    plant.request(plant.runner.step())
    plant.runner.close()
    assert not log.at("error")
    # the earlier run's bag is untouched; the new run holds its reset state and both chunks
    assert sorted(p.name for p in (tmp_path / "run_2").iterdir()) == earlier
    assert bag_info(tmp_path / "run_2").message_count == 1
    assert [t for _, _, t, _ in read_bag(tmp_path / "run_3")] == [0, 20_000_000, 40_000_000]
    assert [t for _, _, t, _ in read_bag(base)] == [0, 20_000_000]


def test_a_second_reset_skips_every_taken_name(tmp_path):
    opened = []
    rec = recorder(opened)
    rec.base = str(tmp_path / "r")
    for taken in ("r_2", "r_3", "r_5"):
        (tmp_path / taken).mkdir()
        (tmp_path / taken / "notes.txt").write_text("not ours")
    (tmp_path / "r_4").mkdir()  # an empty folder is free
    rec.open()
    rec.reopen()
    rec.reopen()
    assert [w.folder for w in opened] == [str(tmp_path / n) for n in ("r", "r_4", "r_6")]


@pytest.mark.parametrize("content", ["bag", "file"])
def test_a_record_dir_that_holds_anything_is_refused_at_start_up(tmp_path, content):
    folder = tmp_path / "run"
    if content == "bag":
        _bag_in(folder)
    else:
        folder.mkdir()
        (folder / "notes.txt").write_text("mine")
    before = sorted(p.name for p in folder.iterdir())
    rec = Recorder(str(folder), TOPICS, Log())
    with pytest.raises(StartupError) as err:
        rec.open()
    assert err.value.parameter == "record_dir"
    assert str(err.value) == (f"parameter record_dir: {folder} exists and is not empty: give a "
                              "new folder (a run is never recorded into another one's folder)")
    assert sorted(p.name for p in folder.iterdir()) == before and not rec.active


def test_a_reset_that_cannot_record_is_refused_and_the_run_goes_on_recording():
    """Never a success while the recording has stopped: the reset either gets its new bag or
    does not happen (the run and its bag go on)."""
    opened = []
    plant, rec = recording_plant(opened, lockstep=True)
    plant.request(plant.runner.step())
    rec._make_writer = functools.partial(FakeWriter, opened=opened, fail_at={"open"})
    ok, text = plant.request(plant.runner.reset())
    assert not ok
    assert text == ("not reset: cannot record to runs/r_2: [Errno 13] Permission denied; the "
                    "run goes on recording to runs/r")
    assert plant.runner.sim_time_s == pytest.approx(0.02) and plant.runner.resets == 0
    assert rec.state == "runs/r" and not opened[0].closed
    assert plant.log.at("error") == [text]
    plant.request(plant.runner.step())
    assert [m[2] for m in opened[0].messages] == [0, 20_000_000, 40_000_000]

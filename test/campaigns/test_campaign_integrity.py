"""Results folders pinned to what made them; batches verified; comparisons that compare; workers
that never outlive the driver."""
from __future__ import annotations

import json
import shutil
import signal
import time
from pathlib import Path

import pytest
from campaign_helpers import write_campaign
from conftest import executable

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.inputs.schema import config_dir
from ltd_brake_ros.studies.campaign_exec import (check_batches, read_results, run_campaign)


def _campaign_with_own_coupler(folder: Path, **kw) -> Path:
    """The small campaign reading a coupler file of its own folder (one the test can edit)."""
    shutil.copyfile(config_dir() / "couplers" / "buffer_hook_pugi.yaml", folder / "pugi.yaml")
    path = write_campaign(folder, **kw)
    path.write_text(path.read_text().replace("file: couplers/buffer_hook_pugi.yaml",
                                             "file: pugi.yaml"))
    return path


def test_manifest_pins_every_input_file_and_the_version(tmp_path):
    c = load_campaign(_campaign_with_own_coupler(tmp_path, runs=4))
    run_campaign(c, tmp_path / "out")
    meta = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert str((tmp_path / "pugi.yaml").resolve()) in meta["inputs"]
    assert str((tmp_path / "small.yaml").resolve()) in meta["inputs"]
    assert any(p.endswith("vehicles.yaml") for p in meta["inputs"])
    assert meta["package_version"]


def test_resume_after_a_cosmetic_edit_goes_on_and_after_a_changed_value_is_refused(
        tmp_path, capsys):
    path = _campaign_with_own_coupler(tmp_path, runs=8, batch=2)
    c = load_campaign(path)
    out = tmp_path / "out"
    run_campaign(c, out)
    batch = out / "batches" / "batch-0000003.parquet"
    batch.unlink()
    coupler = tmp_path / "pugi.yaml"
    text, model = path.read_text(), coupler.read_text()
    # comments, blank lines and a key's quoting change nothing the files say: the run resumes
    path.write_text("# the small campaign, commented\n" + text.replace("seed: 11", "seed: 11   # "
                    "the trains").replace("name: small", "name: 'small'") + "\n\n")
    coupler.write_text("# a copy of the shipped table\n" + model + "\n# edited\n")
    assert main(["campaign", "run", str(path), "--out", str(out), "--quiet"]) == 0
    assert "in 1 batches (0 failed), 3 batches already done" in capsys.readouterr().out
    assert batch.exists()
    # a value of the model file changed: refused, naming it, nothing mixed in
    batch.unlink()
    changed = model.replace("2850]  # loading", "2851]  # loading")
    assert changed != model
    coupler.write_text(changed)
    assert load_campaign(path).inputs != c.inputs
    assert main(["campaign", "run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "pugi.yaml changed" in err and "new --out" in err and len(err.splitlines()) == 1
    assert not batch.exists()
    # a value of the campaign file changed: refused as another campaign
    coupler.write_text(model)
    path.write_text(text.replace("sd: 0.1", "sd: 0.11"))
    assert main(["campaign", "run", str(path), "--out", str(out), "--quiet"]) == 2
    assert "another campaign file" in capsys.readouterr().err and not batch.exists()


def test_a_folder_without_manifest_is_never_adopted(tmp_path):
    c = load_campaign(write_campaign(tmp_path, runs=4))
    run_campaign(c, tmp_path / "out")
    (tmp_path / "out" / "manifest.json").unlink()
    with pytest.raises(InputError, match="never adopted"):
        run_campaign(c, tmp_path / "out")


def test_a_damaged_or_foreign_batch_is_run_again_with_a_note(tmp_path):
    c = load_campaign(write_campaign(tmp_path, runs=8, batch=2))
    out = tmp_path / "out"
    run_campaign(c, out)
    good = read_results(out)[1]
    other = load_campaign(write_campaign(tmp_path, name="other", runs=8, batch=2, v_lo=60.0,
                                         v_hi=70.0))
    run_campaign(other, tmp_path / "other")
    damaged = out / "batches" / "batch-0000001.parquet"
    data = bytearray(damaged.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged.write_bytes(bytes(data))
    for name in ("batch-0000002.parquet", "batch-0000002.parquet.sha256"):  # well-formed, foreign
        shutil.copyfile(tmp_path / "other" / "batches" / name, out / "batches" / name)
    (out / "batches" / "batch-0000003.parquet.sha256").unlink()  # killed before the checksum
    todo, notes = check_batches(c, out)
    assert todo == [1, 2, 3]
    assert "damaged" in notes[0] and "another campaign" in notes[1] and "checksum" in notes[2]
    with pytest.raises(InputError, match="batch-0000001.parquet: does not match its checksum"):
        read_results(out)
    seen = []
    summary = run_campaign(c, out, note_fn=seen.append)
    assert summary["batches"] == 3 and summary["redone"] == 3 and len(seen) == 3
    assert read_results(out)[1].equals(good)


def test_report_never_counts_a_batch_beyond_the_campaign(tmp_path, capsys):
    c = load_campaign(write_campaign(tmp_path, runs=4, batch=2))
    out = tmp_path / "out"
    run_campaign(c, out)
    for suffix in ("", ".sha256"):
        shutil.copyfile(out / "batches" / f"batch-0000001.parquet{suffix}",
                        out / "batches" / f"batch-0000002.parquet{suffix}")
    assert main(["campaign", "report", str(out)]) == 2
    err = capsys.readouterr().err
    assert "batch-0000002.parquet: is not a batch of this campaign" in err


def test_a_damaged_manifest_is_one_line(tmp_path, capsys):
    c = load_campaign(write_campaign(tmp_path, runs=4, batch=2))
    out = tmp_path / "out"
    run_campaign(c, out)
    for text in ("[1, 2]", '{"digest": "x", "runs": "many"}', "{not json"):
        (out / "manifest.json").write_text(text)
        assert main(["campaign", "report", str(out)]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "manifest.json" in err


def test_against_a_reference_with_nothing_in_common_is_an_error(tmp_path, capsys):
    c = load_campaign(write_campaign(tmp_path, runs=4, batch=2))
    run_campaign(c, tmp_path / "a")
    ref = write_campaign(tmp_path, name="ref", runs=4, batch=2)
    ref.write_text(ref.read_text().replace("{kind: emergency,", "{kind: emergency, name: stop,"))
    run_campaign(load_campaign(ref), tmp_path / "b")
    assert main(["campaign", "report", str(tmp_path / "a"), "--against",
                 str(tmp_path / "b")]) == 2
    assert "no manoeuvre in common" in capsys.readouterr().err


def test_a_partial_reference_is_compared_with_a_warning(tmp_path, capsys):
    c = load_campaign(write_campaign(tmp_path, runs=8, batch=2))
    run_campaign(c, tmp_path / "a")
    run_campaign(c, tmp_path / "b")
    for suffix in ("", ".sha256"):
        (tmp_path / "b" / "batches" / f"batch-0000003.parquet{suffix}").unlink()
    main(["campaign", "report", str(tmp_path / "a"), "--against", str(tmp_path / "b")])
    out = capsys.readouterr().out
    assert "warning: reference" in out and "6 of 8 runs (75 %)" in out
    assert "relative approach against" in out


def test_a_campaign_whose_every_run_fails_exits_non_zero(tmp_path, capsys, monkeypatch):
    from ltd_brake_ros.simulator import SimulationError
    from ltd_brake_ros.studies import campaign as studies

    def fail(*args):
        raise SimulationError("diverged")

    monkeypatch.setattr(studies, "_simulate", fail)
    path = write_campaign(tmp_path, runs=4, batch=2)
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "out"), "--quiet",
                 "--jobs", "1"]) == 1
    assert "every run failed" in capsys.readouterr().err


def _children(pid: int) -> list[int]:
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_pool_workers_never_outlive_the_driver(tmp_path, processes, sig):
    # the campaign must still run when the signal comes: 4 000 of these runs end within
    # 15 s on two cores, 40 000 take minutes (it is stopped long before)
    path = write_campaign(tmp_path, runs=40000, batch=2)
    out = tmp_path / "out"
    proc = processes.start(executable("ltd-brake"), "campaign", "run", str(path), "--out",
                           str(out), "--jobs", "2", "--quiet")
    deadline = time.monotonic() + 120
    while not list((out / "batches").glob("batch-*.parquet")) or len(_children(proc.pid)) < 2:
        assert proc.popen.poll() is None, proc.output()
        assert time.monotonic() < deadline, "no worker at work within 120 s"
        time.sleep(0.01)
    workers = _children(proc.pid)
    status = proc.stop(sig)
    assert status == (143 if sig == signal.SIGTERM else -signal.SIGKILL), proc.output()
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers):
        assert time.monotonic() < deadline, f"workers {workers} alive 10 s after the driver"
        time.sleep(0.05)
    if sig == signal.SIGTERM:
        assert "terminated" in proc.output()

"""The user's private folder is private, and compiles are announced with an estimate."""
from __future__ import annotations

import json
import os
import stat
import tempfile

import pytest

from ltd_brake_ros import user_files


@pytest.fixture
def cache_home(tmp_path, monkeypatch):
    home = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(home))
    return home


def test_the_folder_is_created_for_the_user_alone(cache_home):
    folder = user_files.private_folder()
    assert folder == cache_home / "ltd_brake_ros"
    st = os.lstat(folder)
    assert stat.S_ISDIR(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o700
    assert st.st_uid == os.geteuid()


def test_a_relative_cache_home_is_not_used(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/cache")
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    assert user_files.private_folder() == tmp_path / ".cache" / "ltd_brake_ros"
    assert not (tmp_path / "relative").exists()


def test_no_home_folder_is_one_line_not_a_crash(monkeypatch):
    from pathlib import Path

    def no_home():
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(Path, "home", staticmethod(no_home))
    with pytest.raises(user_files.UnsafeFolder, match="home folder is unknown"):
        user_files.private_folder()
    assert user_files.compile_estimate("uic_empirical", False)[1].startswith("estimated")


def _refused(match: str) -> str:
    with pytest.raises(user_files.UnsafeFolder, match=match) as info:
        user_files.private_folder()
    line = str(info.value)
    assert "\n" not in line and "ltd_brake_ros" in line
    return line


def test_a_symbolic_link_put_there_by_someone_else_is_refused(cache_home, tmp_path):
    theirs = tmp_path / "theirs"
    theirs.mkdir(mode=0o700)
    cache_home.mkdir()
    (cache_home / "ltd_brake_ros").symlink_to(theirs)
    _refused("symbolic link")
    assert list(theirs.iterdir()) == []


def test_a_folder_others_may_write_is_refused(cache_home):
    folder = cache_home / "ltd_brake_ros"
    folder.mkdir(parents=True)
    for mode in (0o777, 0o770, 0o722):
        os.chmod(folder, mode)
        _refused("others may write")


@pytest.mark.skipif(os.geteuid() != 0, reason="giving a folder to another user needs root")
def test_a_folder_of_another_user_is_refused(cache_home):
    folder = cache_home / "ltd_brake_ros"
    folder.mkdir(parents=True, mode=0o700)
    os.chown(folder, 4242, 4242)
    _refused("belongs to user id 4242")


def test_a_folder_in_a_folder_anyone_may_write_without_the_sticky_bit_is_refused(cache_home):
    cache_home.mkdir()
    os.chmod(cache_home, 0o777)  # anyone could rename ltd_brake_ros away and put theirs
    _refused("no sticky bit")
    os.chmod(cache_home, 0o1777)  # as /tmp: only the owner may rename it
    assert user_files.private_folder().is_dir()


def test_the_first_run_compile_keeps_nothing_in_the_shared_temporary_folder(cache_home):
    from ltd_brake_ros import first_run

    lock = first_run.lock_path()
    assert lock.parent == cache_home / "ltd_brake_ros"
    assert not str(lock).startswith(tempfile.gettempdir() + os.sep) or \
        str(cache_home).startswith(tempfile.gettempdir())  # the tests' own folder


def test_an_unsafe_folder_is_said_in_one_line_and_the_run_compiles_in_the_foreground(
        cache_home, monkeypatch):
    from ltd_brake_ros import first_run
    from ltd_brake_ros.inputs import get_scenario

    monkeypatch.setenv("LTD_BRAKE_FIRST_RUN", "background")
    cache_home.mkdir()
    os.symlink(cache_home / "elsewhere", cache_home / "ltd_brake_ros")
    said = []
    assert first_run.start({"consist": get_scenario(1).consist(), "speed_kmh": 40.0},
                           said.append) is None
    assert len(said) == 1 and "symbolic link" in said[0] and "foreground" in said[0]
    assert first_run.wait_for_compile(timeout_s=0.0)  # nothing to wait for
    assert not (cache_home / "elsewhere").exists()


def test_the_first_compile_is_estimated_for_the_cores_and_load(cache_home, monkeypatch):
    base = user_files.FIRST_COMPILE_S[("uic_brake_pipe", True)]
    monkeypatch.setattr(user_files, "usable_cores", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    seconds, basis = user_files.compile_estimate("uic_brake_pipe", True)
    assert seconds == pytest.approx(base) and "2 cores" in basis
    # beside a plain-Python run on one core: the two share it
    monkeypatch.setattr(user_files, "usable_cores", lambda: 1)
    assert user_files.compile_estimate("uic_brake_pipe", True, beside_a_run=True)[0] == \
        pytest.approx(2 * base)
    # a loaded machine: 2 cores, 4 processes running and the compile
    monkeypatch.setattr(user_files, "usable_cores", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (4.0, 4.0, 4.0))
    assert user_files.compile_estimate("uic_brake_pipe", True)[0] == pytest.approx(2.5 * base)


def test_later_compiles_are_estimated_by_the_last_one_of_their_kind(cache_home):
    user_files.record_compile("linear_ramp", True, 37.4)
    user_files.record_compile("linear_ramp", True, 41.2)  # the last one counts
    user_files.record_compile("uic_brake_pipe", False, 12.0)
    assert user_files.compile_estimate("linear_ramp", True) == (41.2, "as the last compile took")
    assert user_files.compile_estimate("uic_brake_pipe", False)[0] == 12.0
    assert user_files.compile_estimate("linear_ramp", False)[1].startswith("estimated for")
    times = cache_home / "ltd_brake_ros" / user_files.TIMES_FILE
    assert stat.S_IMODE(times.stat().st_mode) & 0o077 in (0, 0o044, 0o004, 0o040)


@pytest.mark.parametrize("content", [b"not json", b"[1, 2]", b'{"uic_brake_pipe": "fast"}',
                                     b'{"uic_brake_pipe": -3}', b'{"uic_brake_pipe": NaN}',
                                     b"{" + b" " * 70000 + b"}"])
def test_a_damaged_compile_times_file_is_ignored(cache_home, content):
    folder = user_files.private_folder()
    (folder / user_files.TIMES_FILE).write_bytes(content)
    seconds, basis = user_files.compile_estimate("uic_brake_pipe", False)
    assert basis.startswith("estimated for") and seconds > 0
    user_files.record_compile("uic_brake_pipe", False, 9.0)
    assert json.loads((folder / user_files.TIMES_FILE).read_text()) == {"uic_brake_pipe": 9.0}


def test_the_notice_names_the_kernels_and_the_estimate(cache_home, monkeypatch):
    from ltd_brake_ros import compiled
    from ltd_brake_ros.inputs import consist_from_mapping, load_brake_params

    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    long = consist_from_mapping({"name": "long", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": 100, "mass_t": 80.0}]}, "long")
    user_files.record_compile("uic_brake_pipe", True, 47.0)
    notice = compiled.compile_notice(long, load_brake_params("brake_params/uic_brake_pipe.yaml"))
    assert notice.startswith("compiling the simulation kernels (first run only")
    assert "uic_brake_pipe brake model with local time steps" in notice
    assert "about 47 s as the last compile took" in notice
    short = compiled.compile_notice(None, None, background=True)
    assert "uic_empirical brake model, about" in short and "in the background" in short


def test_a_plant_says_its_compile_and_keeps_its_duration(cache_home, monkeypatch):
    """sim_node's start-up (its run built from the parameters) announces the compile of the
    train it runs, not of a default one, and keeps how long it took."""
    from ltd_brake_ros import compiled
    from ltd_brake_ros.plant.run import build_simulator
    from ltd_brake_ros.run_spec import resolve_run_spec

    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    spec = resolve_run_spec(scenario=1, params_file="brake_params/uic.yaml")
    said = []
    build_simulator(spec, 0.1, say=said.append)
    assert len(said) == 2
    assert "uic_empirical brake model" in said[0]
    assert "compiled the simulation kernels in" in said[1]
    assert "uic_empirical" in json.loads(
        (cache_home / "ltd_brake_ros" / user_files.TIMES_FILE).read_text())

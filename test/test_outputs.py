"""Outputs are complete or absent, and a new result never replaces a file (``outputs``)."""
from __future__ import annotations

import errno
import os

import pytest

from ltd_brake_ros import outputs


def _names(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_a_new_file_is_published_complete_with_the_users_permissions(tmp_path):
    target = tmp_path / "series.csv"
    with outputs.new_file(target) as fh:
        fh.write("a,b\n1,2\n")
        assert _names(tmp_path) != ["series.csv"]  # not under its name while it is written
    assert target.read_text() == "a,b\n1,2\n"
    assert _names(tmp_path) == ["series.csv"]
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask
    assert target.stat().st_nlink == 1  # the temporary name is gone


def test_a_new_file_never_replaces_one_and_names_it(tmp_path):
    target = tmp_path / "fitted.yaml"
    target.write_text("mine\n")
    with pytest.raises(FileExistsError) as info:
        outputs.write_new(target, "theirs\n")
    assert info.value.filename == str(target)
    assert target.read_text() == "mine\n"
    assert _names(tmp_path) == ["fitted.yaml"]


def test_a_symbolic_link_in_the_way_is_not_followed(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    target = tmp_path / "out.csv"
    target.symlink_to(elsewhere)  # dangling: following it would create elsewhere
    with pytest.raises(FileExistsError):
        outputs.write_new(target, "x")
    assert not elsewhere.exists()


def test_a_failed_write_leaves_nothing_and_names_the_file(tmp_path):
    target = tmp_path / "speed.png"

    with pytest.raises(OSError) as info:
        with outputs.new_file(target, "wb") as fh:
            fh.write(b"x" * 10)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert info.value.filename == str(target)
    assert _names(tmp_path) == []
    with pytest.raises(KeyboardInterrupt):
        with outputs.new_file(target) as fh:
            fh.write("half")
            raise KeyboardInterrupt
    assert _names(tmp_path) == []


@pytest.mark.parametrize("code", [errno.EPERM, errno.ENOTSUP])
def test_a_file_system_without_hard_links_gets_an_exclusive_create(tmp_path, monkeypatch, code):
    def no_links(src, dst, **kw):
        raise OSError(code, os.strerror(code), str(src), None, str(dst))

    monkeypatch.setattr(os, "link", no_links)
    target = tmp_path / "out.bin"
    outputs.write_new(target, b"\x00complete")
    assert target.read_bytes() == b"\x00complete"
    assert _names(tmp_path) == ["out.bin"]
    with pytest.raises(FileExistsError):
        outputs.write_new(target, b"other")
    assert target.read_bytes() == b"\x00complete"
    assert _names(tmp_path) == ["out.bin"]


def test_a_file_updated_on_purpose_is_replaced_whole_or_not_at_all(tmp_path):
    target = tmp_path / "manifest.json"
    outputs.write_replacing(target, "{}\n")
    outputs.write_replacing(target, '{"a": 1}\n')
    assert target.read_text() == '{"a": 1}\n'
    with pytest.raises(RuntimeError):
        with outputs.replaced_file(target) as fh:
            fh.write("{")
            raise RuntimeError("interrupted")
    assert target.read_text() == '{"a": 1}\n'
    assert _names(tmp_path) == ["manifest.json"]


def test_a_missing_folder_is_one_error_naming_the_file(tmp_path):
    target = tmp_path / "no" / "file.csv"
    with pytest.raises(FileNotFoundError) as info:
        outputs.write_new(target, "x")
    assert info.value.filename == str(target)

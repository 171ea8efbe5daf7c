"""Every kind of input file refuses an unreadable encoding or kind in one line naming it."""
from __future__ import annotations

import pytest

from ltd_brake_ros.inputs import (InputError, load_brake_params, load_command_script,
                                  load_consist, load_coupler_lut, load_track)
from ltd_brake_ros.inputs.adhesion import load_adhesion
from ltd_brake_ros.inputs.campaign import load_campaign

LOADERS = {"consist": (load_consist, ".yaml"), "brake parameters": (load_brake_params, ".yaml"),
           "coupler": (load_coupler_lut, ".yaml"), "track": (load_track, ".yaml"),
           "track table": (load_track, ".csv"), "commands": (load_command_script, ".yaml"),
           "adhesion": (load_adhesion, ".yaml"), "campaign": (load_campaign, ".yaml")}

CONTENTS = {
    "UTF-16": ("\ufeffname: x\n".encode("utf-16-le"), "is UTF-16 text; save it as UTF-8"),
    "UTF-16 BE": (b"\xfe\xff" + "name: x\n".encode("utf-16-be"), "is UTF-16 text"),
    "Latin-1": ("name: Güterwagen\n".encode("latin-1"),
                "is not UTF-8 text (byte 0xFC on line 1"),
    "binary": (bytes(range(256)), "is a binary file, not text (a NUL byte at offset 0)"),
    "empty": (b"", "empty"),
    "folder": (None, "is not a regular file"),
}


@pytest.mark.parametrize("content", sorted(CONTENTS))
@pytest.mark.parametrize("kind", sorted(LOADERS))
def test_a_file_of_the_wrong_encoding_or_kind_is_one_line(kind, content, tmp_path):
    load, suffix = LOADERS[kind]
    data, words = CONTENTS[content]
    path = tmp_path / f"input{suffix}"
    if data is None:
        path.mkdir()
    else:
        path.write_bytes(data)
    with pytest.raises(InputError) as err:
        load(path)
    text = str(err.value)
    assert "\n" not in text and "input" in text
    if not (content == "empty" and suffix == ".csv"):
        assert words in text, text
    else:  # an empty table has no header
        assert "header" in text, text


def test_a_utf8_byte_order_mark_is_read_as_utf8(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_bytes("\ufeffmodel: uic_empirical\nt_app_s: 1.5\n".encode("utf-8"))
    assert load_brake_params(path).pneumatic.t_app_s == 1.5

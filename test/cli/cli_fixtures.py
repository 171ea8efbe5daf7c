"""Fixtures shared by the command-line tests; a test module imports the ones it uses.

Not a ``conftest.py``: the ROS tests import the suite's root ``conftest`` by name, and a second
module of that name in a session shadows it.
"""
from __future__ import annotations

import pytest

from bag_helpers import record_emergency_stop
from ltd_brake_ros.inputs import get_scenario


@pytest.fixture(scope="session")
def folder(tmp_path_factory):
    """A recorded emergency stop of paper scenario 7 (the shortest run), namespace /train1.

    Tests read it and never write into it.
    """
    sc = get_scenario(7)
    path = tmp_path_factory.mktemp("cli_run") / "run"
    record_emergency_stop(path, sc.consist(), sc.speed_kmh, ns="/train1", chunk_size=1 << 16)
    return path


@pytest.fixture
def one_line_error(capsys):
    """Check that a verb failed with one line on stderr, no traceback; return that line."""

    def check(verb: str) -> str:
        err = capsys.readouterr().err
        assert err.startswith(f"ltd-brake {verb}: error:") and err.count("\n") == 1, err
        assert "Traceback" not in err
        return err

    return check

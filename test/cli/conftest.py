"""Shared by the command-line tests."""
from __future__ import annotations

import pytest


@pytest.fixture
def one_line_error(capsys):
    """Check that a verb failed with one line on stderr, no traceback; return that line."""

    def check(verb: str) -> str:
        err = capsys.readouterr().err
        assert err.startswith(f"ltd-brake {verb}: error:") and err.count("\n") == 1, err
        assert "Traceback" not in err
        return err

    return check

"""The example tour of the Python API runs as it is shipped (so it never rots)."""
from __future__ import annotations

import os
import runpy
from pathlib import Path

import pytest

TOUR = Path(__file__).resolve().parents[1] / "examples" / "analysis_tour.py"


def test_the_analysis_tour_runs_and_draws_its_map(tmp_path, monkeypatch, capsys):
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    pytest.importorskip("pyarrow")
    monkeypatch.setenv("LTD_TOUR_OUT", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(TOUR), run_name="__main__")
    text = capsys.readouterr().out
    # scenario 6 as validated (README, Tables 1-2) and a campaign of 24 runs with its tail
    assert "stopping distance 489.2 m" in text and "verdicts: PASS" in text
    assert "24 runs; |peak buff| quantiles [kN]:" in text and "0.99" in text
    assert (tmp_path / "coupler_force_map.png").stat().st_size > 10_000
    assert os.listdir(tmp_path / "tour_campaign" / "batches")

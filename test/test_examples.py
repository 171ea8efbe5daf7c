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
    monkeypatch.setenv("MPLBACKEND", "Agg")  # the tour leaves the backend to its host
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(TOUR), run_name="__main__")
    text = capsys.readouterr().out
    # scenario 6 as validated (README, Tables 1-2) and a campaign of 24 runs with its tail
    assert "stopping distance 489.2 m" in text and "verdicts: PASS" in text
    assert "24 runs; |peak buff| quantiles [kN]:" in text and "0.99" in text
    assert (tmp_path / "coupler_force_map.png").stat().st_size > 10_000
    assert (tmp_path / "buff_exceedance.png").stat().st_size > 5_000
    assert "matplotlib.use" not in TOUR.read_text()  # inline plots in a notebook
    assert os.listdir(tmp_path / "tour_campaign" / "batches")


def test_the_markers_picture_draws_the_plants_markers(tmp_path):
    import importlib.util

    from ltd_brake_ros.plant.markers import train_markers

    path = TOUR.parent / "train_markers_picture.py"
    spec = importlib.util.spec_from_file_location("train_markers_picture", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(["--scenario", "1", "--time-s", "3", "--out", str(tmp_path / "m.png")])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    # the markers drawn: a box per vehicle and per coupler, the couplers at buffer height
    specs = train_markers([0.0, -16.0, -28.6], [19.42, 12.64, 12.64], [5e4, 0.0, 0.0],
                          [1e5, 1e5, 1e5], [2e5, -2.5e6], [8.5e5, 8.5e5], [2e6, 2e6])
    kinds = [(m.ns, m.kind) for m in specs]
    assert kinds.count(("vehicles", "cube")) == 3 and kinds.count(("couplers", "cube")) == 2
    head, wagon = specs[0], specs[1]
    # the head half applied (between grey and orange), the wagon released (grey)
    assert head.rgba[0] > head.rgba[2] + 0.2 and wagon.rgba == (0.62, 0.64, 0.66, 1.0)
    draft, beyond = specs[3], specs[4]
    assert draft.rgba[0] > draft.rgba[2] and beyond.rgba == (0.9, 0.0, 0.9, 1.0)
    assert 0.94 <= draft.z <= 1.065  # UIC 527-1 buffer height [m]

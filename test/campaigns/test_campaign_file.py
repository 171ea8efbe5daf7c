"""Campaign files: the shipped example loads, bad files fail with one line, draws are sound."""
from __future__ import annotations

import numpy as np
import pytest
from campaign_helpers import write_campaign

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError
from ltd_brake_ros.inputs.campaign import Distribution, load_campaign
from ltd_brake_ros.studies.campaign import _hypercube, dimensions, draw, inverse_cdf


def test_shipped_example_loads():
    c = load_campaign("campaigns/example.yaml")
    assert c.runs == 2000 and c.sampling == "latin_hypercube"
    assert c.couplers[0].params.draft_strength_N == 850e3
    assert set(c.uncertainties) == {"k0", "t_fill"}


BAD = [
    ("Shimmns:", "Shimmx:", "families[0].wagon_types.Shimmx", "unknown vehicle type"),
    ("edges: [20.0, 40.0, 58.0]", "edges: [-5.0, 40.0, 58.0]",
     "families[0].wagon_types.Shimmns.payload_t.histogram.edges", "must be >= 0, got -5"),
    ("sd: 0.1", "sd: .nan", "uncertainties.k0.normal.sd", "must be finite"),
    ("runs: 16", "runs: 0", "runs", "between"),
    ("wagons: [3, 5]", "length_m: [2.0, 5.0]", "families[0].length_m", "no train fits"),
    ("wagons: [3, 5]", "wagons: [5, 3]", "families[0].wagons", "exceeds"),
    ("  - {kind: emergency,", "  - {kind: emergency, name: a, speed_kmh: 50.0}\n"
     "  - {name: a, kind: emergency,",
     "manoeuvres[1].name", "used twice"),
]


@pytest.mark.parametrize("old,new,field,reason", BAD, ids=[b[2] for b in BAD])
def test_bad_file_is_one_line_naming_file_and_field(tmp_path, capsys, old, new, field, reason):
    path = write_campaign(tmp_path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert f"{path}: {field}:" in err and reason in err
    assert not (tmp_path / "out").exists()


def test_uncertainty_must_name_a_fittable_parameter(tmp_path):
    path = write_campaign(tmp_path)
    path.write_text(path.read_text().replace("k0:", "k9:"))
    with pytest.raises(InputError, match=r"uncertainties\.k9: not a fittable parameter"):
        load_campaign(path)


def test_inverse_cdfs_hit_their_quantiles():
    u = np.linspace(0.0, 1.0, 11)[:-1] + 0.05
    uni = [inverse_cdf(Distribution("uniform", (10.0, 20.0)), x) for x in u]
    np.testing.assert_allclose(uni, 10.0 + 10.0 * u)
    # histogram: a quarter of the mass in [0, 1], three quarters in [1, 4]
    hist = Distribution("histogram", (0.0, 1.0, 4.0, 1.0, 3.0))
    assert inverse_cdf(hist, 0.25) == pytest.approx(1.0)
    assert inverse_cdf(hist, 0.625) == pytest.approx(2.5)
    # normal truncated to [mean - sd, mean + sd]: the median is the mean, the ends are the bounds
    norm = Distribution("normal", (5.0, 2.0, 3.0, 7.0))
    assert inverse_cdf(norm, 0.5) == pytest.approx(5.0)
    assert inverse_cdf(norm, 0.0) == pytest.approx(3.0)
    assert inverse_cdf(norm, 1.0 - 1e-12) == pytest.approx(7.0)


def test_latin_hypercube_puts_one_run_in_each_stratum(tmp_path):
    c = load_campaign(write_campaign(tmp_path, runs=40, sampling="latin_hypercube"))
    design = _hypercube(c.seed, c.runs, len(dimensions(c)))
    for column in design.T:
        assert sorted(np.floor(column * c.runs).astype(int)) == list(range(c.runs))
    # the drawn speeds are stratified too: one per 0.5 km/h band of [30, 50]
    speeds = [draw(c, i)[0]["speed_kmh"]["emergency"] for i in range(c.runs)]
    assert sorted(np.floor((np.array(speeds) - 30.0) / 0.5).astype(int)) == list(range(40))


def test_draws_follow_the_family(tmp_path):
    c = load_campaign(write_campaign(tmp_path, runs=200))
    samples = [draw(c, i)[0] for i in range(c.runs)]
    assert {s["wagons"] for s in samples} == {3, 4, 5}
    masses = np.concatenate([s["wagon_mass_t"] for s in samples])
    loaded = masses[masses > 22.0]
    assert loaded.min() >= 42.0 and loaded.max() <= 80.0
    # 3 of 4 parts of the payload weight lie in [40, 58] t: loaded mass in [62, 80] t
    assert np.mean(loaded >= 62.0) == pytest.approx(0.75, abs=0.06)
    assert np.mean(masses > 22.0) == pytest.approx(0.7, abs=0.06)
    # a run is the same whenever it is drawn
    assert draw(c, 17) == draw(c, 17)


def test_missing_extra_is_one_line(tmp_path, capsys, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "distributed" else real(name, *a))
    path = write_campaign(tmp_path)
    assert main(["campaign", "run", str(path), "--out", str(tmp_path / "o"), "--dask",
                 "local:1"]) == 2
    assert capsys.readouterr().err.strip() == (
        "ltd-brake campaign: error: distributed: not installed; campaigns need it: "
        "pip install 'ltd_brake_ros[campaign]'")


def test_length_range_sets_the_wagon_count(tmp_path):
    path = write_campaign(tmp_path, runs=50)
    path.write_text(path.read_text().replace("wagons: [3, 5]", "length_m: [200.0, 300.0]"))
    c = load_campaign(path)
    loco, wagon = c.vehicle_lengths_m["E402B"], c.vehicle_lengths_m["Shimmns"]
    lengths = [loco + wagon * draw(c, i)[0]["wagons"] for i in range(c.runs)]
    # wagons are added while the train stays within the drawn length: one wagon short of it
    assert max(lengths) <= 300.0 and min(lengths) > 200.0 - wagon
    assert len(set(lengths)) >= 7  # (300 - 200) / 12.64 m: every count in between occurs

"""The model-form band: every brake model with every coupler model, each member tagged inside or
outside its models' ranges, the band judged by the members inside them."""
from __future__ import annotations

import json

import pytest

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs import InputError, consist_from_mapping, get_scenario
from ltd_brake_ros.inputs.band import load_band
from ltd_brake_ros.studies.band import MemberResult, _verdict, run_band
from ltd_brake_ros.studies.runs import emergency_run, summarize


def member(status="PASS", in_range=True, non_physical=None):
    return MemberResult("b", "c", in_range, (), 1.0, 1.0, 1, -1.0, 1, status, non_physical,
                        0.0)


@pytest.mark.parametrize("members, expected", [
    ([member(), member()], "PASS"),
    ([member(), member("WARN")], "WARN"),
    ([member("FAIL"), member("FAIL")], "FAIL"),
    ([member(), member("FAIL")], "model-dependent"),
    # an out-of-range member does not decide, but is shown
    ([member(), member("FAIL", in_range=False)], "PASS"),
    ([member("FAIL", in_range=False)], "no member in range"),
    # a NON-PHYSICAL member makes the band NON-PHYSICAL, inside its range or not
    ([member(), member("FAIL", in_range=False, non_physical="NON-PHYSICAL: ...")],
     "NON-PHYSICAL"),
])
def test_the_band_is_judged_by_the_members_inside_their_ranges(members, expected):
    assert _verdict(members) == expected


def test_the_paper_train_has_a_narrow_band_that_passes():
    sc = get_scenario(6)
    band, sim = run_band(sc.consist(), sc.speed_kmh)
    # every brake model (empirical; the brake pipe at its nominal first stage and at each end
    # of the range its first seconds are known in) with every coupler model
    assert len(band.members) == load_band().size == 8
    assert band.status == "PASS" and all(m.in_range for m in band.members)
    # the nominal member is the run's own: the paper's method, number for number
    ref = summarize(emergency_run(sc.consist(), sc.speed_kmh, group=True), 1.0)
    nominal = band.members[band.nominal]
    assert (nominal.brake, nominal.coupler) == ("empirical", "buffer-hook table")
    assert nominal.stopping_distance_m == ref.stopping_distance_m
    assert band.kpis["peak_draft_kN"].nominal == ref.peak_draft_kN
    for k in band.kpis.values():
        lo, hi = sorted((k.low, k.high))
        assert lo <= k.nominal <= hi
        values = [getattr(m, k.name) for m in band.members]
        assert {k.low, k.high} == {min(values), max(values)}
    # the members inside the paper's own first seconds agree on the distance within a percent;
    # the peer's slow first stage stops some 4 % longer
    d = band.kpis["stopping_distance_m"]
    assert d.high - d.low < 0.06 * d.nominal
    assert "slow first stage" in d.high_member
    assert sim.stopping_distance_m == nominal.stopping_distance_m


def test_a_train_beyond_every_range_shows_the_spread_and_gives_no_verdict():
    c = consist_from_mapping({"name": "E402B + 150 x 80 t, G", "vehicles": [
        {"type": "E402B", "brake_position": "G"},
        {"type": "Shimmns", "count": 150, "mass_t": 80.0, "brake_position": "G"}]}, "<test>")
    band, _ = run_band(c, 100.0)
    assert band.status == "no member in range" and not band.in_range
    draft = band.kpis["peak_draft_kN"]
    # the brake pipe's wave and the empirical model's build-up differ by an order of magnitude
    assert draft.high > 5.0 * draft.low
    assert "outside its range" in draft.low_member and "outside its range" in draft.high_member
    # the nominal member is the train's default: the brake pipe beyond 500 m
    assert band.members[band.nominal].brake == "brake pipe"
    lines = band.describe()
    assert lines[0].startswith("band             no member in range (0 of 8")
    assert sum("OUTSIDE its range" in line for line in lines) == 8


def test_a_band_file_is_checked_in_one_line(tmp_path):
    path = tmp_path / "band.yaml"
    path.write_text("brake:\n  - {name: a, file: brake_params/paper.yaml}\n"
                    "  - {name: a, file: brake_params/uic_brake_pipe.yaml}\n"
                    "coupler:\n  - {name: t, file: couplers/buffer_hook_pugi.yaml}\n")
    with pytest.raises(InputError, match=r"brake\[1\].name: 'a' is used twice"):
        load_band(path)
    path.write_text("brake: []\ncoupler: []\n")
    with pytest.raises(InputError, match="brake: missing or not a non-empty list"):
        load_band(path)


def test_simulate_prints_the_band_and_refuses_it_with_a_recording(tmp_path, capsys):
    assert main(["simulate", "--scenario", "7", "--band", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    band = out["band"]
    assert band["status"] == "PASS" and len(band["members"]) == 8
    assert band["kpis"]["stopping_distance_m"]["nominal"] == out["stopping_distance_m"]
    assert main(["simulate", "--scenario", "7", "--band", "--record",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--band" in err and "--record" in err

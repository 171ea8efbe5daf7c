"""The paper's Tables 1-2: all 12 emergency stops against the published values.

Distances are a hard test of the brake model (the coupler table hardly moves them: < 0.2 % for
a 4x stiffer table); peak forces are a soft one because the coupler table is a reconstruction
of Fig. 4 (its stiffness moves the peaks by 20-40 %).
"""
import pytest

from ltd_brake_ros.studies.runs import validate

DISTANCE_TOL_PERCENT = {100: 1.0, 50: 1.5}


@pytest.fixture(scope="module")
def rows():
    return {r.scenario.number: r for r in validate(workers=2)}


@pytest.mark.parametrize("number", range(1, 13))
def test_stopping_distance_matches_ltdpolito(rows, number):
    r = rows[number]
    tol = DISTANCE_TOL_PERCENT[int(r.scenario.speed_kmh)]
    assert abs(r.distance_error_percent) <= tol, (
        f"run {number}: {r.result.stopping_distance_m:.1f} m vs "
        f"{r.scenario.paper['ltdpolito_m']} m")


@pytest.mark.parametrize("number", range(1, 12))
def test_peak_draft_force(rows, number):
    r = rows[number]
    paper = r.scenario.paper["draft_kN"]
    assert r.result.peak_draft_kN == pytest.approx(paper, rel=0.20)


@pytest.mark.parametrize("number", range(1, 13))
def test_peak_buff_force_and_position(rows, number):
    r = rows[number]
    paper = r.scenario.paper
    assert -r.result.peak_buff_kN == pytest.approx(paper["buff_kN"], rel=0.40)
    assert abs(r.result.peak_buff_coupler - paper["buff_coupler"]) <= 3


@pytest.mark.parametrize("number", range(1, 13))
def test_runs_are_clean(rows, number):
    res = rows[number].result
    assert res.couplers_beyond_lut == 0      # P-braked short trains stay inside the table
    assert res.newton_iterations_per_step < 2.0
    assert res.max_newton_iterations < 40


def test_uic_distances_within_paper_model_spread(rows):
    # the paper's model is up to 4.6 % (we find 4.8 %) short of UIC 544-1 at 100 km/h with
    # Table 3
    for number in range(1, 7):
        assert -6.0 < rows[number].uic_error_percent < 1.0

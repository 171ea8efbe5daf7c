"""The paper's Tables 1-2: all 12 emergency stops against the published values.

The targets ``ltd-brake validate`` prints: stopping distances within 0.1 % (100 km/h) and 0.7 %
(50 km/h) of LTDPoliTo, a hard test of the brake model (the couplers move a distance by < 0.2 %);
every peak draft within +-10 % and every peak buff within +-20 % of the paper, at its coupler
+-2, with the default coupler (the Fig. 4 reconstruction with its sides scaled to these peaks).
"""
import pytest

from ltd_brake_ros.studies import calibration as cal_mod
from ltd_brake_ros.studies.runs import validate

DISTANCE_TOL_PERCENT = {100: 100 * cal_mod.DISTANCE_TOL[100.0], 50: 100 * cal_mod.DISTANCE_TOL[50.0]}


@pytest.fixture(scope="module")
def rows():
    return {r.scenario.number: r for r in validate(workers=2)}


def test_the_targets_are_those_stated():
    assert (cal_mod.DRAFT_TOL, cal_mod.BUFF_TOL, cal_mod.POSITION_TOL) == (0.10, 0.20, 2)
    assert DISTANCE_TOL_PERCENT == {100: pytest.approx(0.1), 50: pytest.approx(0.7)}


@pytest.mark.parametrize("number", range(1, 13))
def test_stopping_distance_matches_ltdpolito(rows, number):
    r = rows[number]
    tol = DISTANCE_TOL_PERCENT[int(r.scenario.speed_kmh)]
    assert abs(r.distance_error_percent) <= tol, (
        f"run {number}: {r.result.stopping_distance_m:.1f} m vs "
        f"{r.scenario.paper['ltdpolito_m']} m")


@pytest.mark.parametrize("number", range(1, 13))
def test_peak_draft_force_and_position(rows, number):
    r = rows[number]
    paper = r.scenario.paper
    assert r.result.peak_draft_kN == pytest.approx(paper["draft_kN"], rel=cal_mod.DRAFT_TOL)
    assert abs(r.result.peak_draft_coupler - paper["draft_coupler"]) <= cal_mod.POSITION_TOL


@pytest.mark.parametrize("number", range(1, 13))
def test_peak_buff_force_and_position(rows, number):
    r = rows[number]
    paper = r.scenario.paper
    assert -r.result.peak_buff_kN == pytest.approx(paper["buff_kN"], rel=cal_mod.BUFF_TOL)
    assert abs(r.result.peak_buff_coupler - paper["buff_coupler"]) <= cal_mod.POSITION_TOL


def test_validate_reports_every_target_met(rows):
    checks = cal_mod.validation_targets([rows[k] for k in sorted(rows)])
    assert len(checks) == 5
    assert all(ok for _, ok, _ in checks), checks


def test_a_missed_target_is_reported_with_its_worst_run(rows):
    # the unscaled Fig. 4 reconstruction: buff peaks 9-38 % below the paper, run 12's draft twice
    from ltd_brake_ros.inputs import load_coupler_lut

    fig4 = validate(lut=load_coupler_lut("couplers/buffer_hook_fig4.yaml"), scenarios=[1, 12],
                    workers=2)
    checks = {what.split(" within")[0]: (ok, detail)
              for what, ok, detail in cal_mod.validation_targets(fig4)}
    assert checks["peak draft"][0] is False and "(run 12)" in checks["peak draft"][1]
    assert checks["peak buff"][0] is False and "(run 1)" in checks["peak buff"][1]


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


def _peak_draft_kN(job):
    from ltd_brake_ros.inputs import consist_from_mapping
    from ltd_brake_ros.studies.runs import emergency_stop

    n, mass_t, speed = job
    consist = consist_from_mapping({"name": "sweep", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": n, "mass_t": mass_t}]}, "<sweep>")
    return emergency_stop(consist, speed).peak_draft_kN


def test_no_draft_above_500_kN_for_e402b_and_10_to_40_shimmns():
    # the runs that snatch as the train stops (light long trains from 40-50 km/h, up to 2 MN
    # with the Fig. 4 reconstruction) and the extremes of length, load and speed: every peak
    # draft below 500 kN with the default inputs
    from ltd_brake_ros.studies.parallel import map_jobs

    jobs = [(n, m, v) for n in (34, 36, 38, 40) for m in (50.0, 80.0) for v in (40.0, 50.0)]
    jobs += [(n, m, v) for n in (10, 40) for m in (50.0, 80.0) for v in (80.0, 120.0)]
    peaks = map_jobs(_peak_draft_kN, jobs, 2)
    worst = max(zip(peaks, jobs))
    assert worst[0] < cal_mod.DRAFT_LIMIT_N / 1e3 == 500.0, worst

"""Local error control of the integrator: sub-steps through snatches, fixed steps on request.

A 150-wagon train braked from the head in G runs into the end stops of its couplers: the
snatches last tens of milliseconds, and 10 ms steps miss their peaks by several per cent. The
error control takes those nominal steps in sub-steps and must land within the accuracy of a
fine fixed-step solution (1 ms steps: their own error is 0.2 % of the peaks against 0.5 ms).
"""
import numpy as np
import pytest

from ltd_brake_ros.inputs import InputError, consist_from_mapping, get_scenario, load_brake_params
from ltd_brake_ros.physics.kernel import DEFAULT_TOLERANCE_M_S
from ltd_brake_ros.simulator import Commands, Simulator

#: The paper's empirical brake: the integrator's accuracy is judged on it, beyond its range of
#: train lengths too (a default run of these trains takes the brake pipe)
EMPIRICAL = load_brake_params("brake_params/paper.yaml")



def long_train(wagons=150):
    return consist_from_mapping({"name": "long", "vehicles": [
        {"type": "E402B", "brake_position": "G"},
        {"type": "Shimmns", "count": wagons, "mass_t": 80.0, "brake_position": "G"}]}, "<test>")


def run(sim, chunk_s=1.0):
    """An emergency stop from t = 0 until the train stands."""
    sim.advance(chunk_s, Commands(emergency=True))
    while sim.stop_time_s is None:
        sim.advance(chunk_s)
    return sim


def peak_error_percent(sim, ref):
    """Largest peak draft and buff error against ``ref``, relative to each coupler's peak
    (at least a tenth of the largest), as in :func:`ltd_brake_ros.studies.reference.compare`."""
    scale = max(ref.peak_draft_N.max(), -ref.peak_buff_N.min())
    out = []
    for a, b in ((sim.peak_draft_N, ref.peak_draft_N), (sim.peak_buff_N, ref.peak_buff_N)):
        out.append(100.0 * np.max(np.abs(a - b) / np.maximum(np.abs(b), 0.1 * scale)))
    return out


@pytest.fixture(scope="module")
def snatches():
    fine = run(Simulator(long_train(), 100.0, EMPIRICAL, step_s=0.001, tolerance_m_s=0.0))
    fixed = run(Simulator(long_train(), 100.0, EMPIRICAL, tolerance_m_s=0.0))
    controlled = run(Simulator(long_train(), 100.0, EMPIRICAL))
    return fine, fixed, controlled


def test_fixed_10_ms_steps_miss_the_snatches(snatches):
    # the case the error control is for: without it, the peaks are off by far more than 2 %
    fine, fixed, _ = snatches
    assert max(peak_error_percent(fixed, fine)) > 5.0
    assert fixed.stats.rejected_steps == 0 and fixed.stats.smallest_step_s == fixed.step_s


def test_error_control_resolves_the_snatches(snatches):
    fine, _, controlled = snatches
    draft, buff = peak_error_percent(controlled, fine)
    assert draft <= 2.0 and buff <= 2.0
    stats = controlled.stats
    assert stats.rejected_steps > 0
    assert stats.smallest_step_s < 0.1 * controlled.step_s
    # the sub-steps are spent in the snatches, not everywhere
    assert stats.steps < 3 * round(controlled.time_s / controlled.step_s)


def test_chunk_boundaries_are_hit_exactly():
    sim = Simulator(long_train(40), 100.0, EMPIRICAL)
    ref = Simulator(long_train(40), 100.0, EMPIRICAL, tolerance_m_s=0.0)
    sim.advance(0.37, Commands(emergency=True))
    ref.advance(0.37, Commands(emergency=True))
    for _ in range(60):
        sim.advance(0.37)
        ref.advance(0.37)
        assert sim.time_s == ref.time_s  # the same sums of the same nominal steps
    assert sim.stats.steps >= ref.stats.steps


def test_grouping_of_nominal_steps_does_not_change_the_result():
    # sub-steps and their proposals carry over between calls: 1 s and 20 ms chunks of the
    # same 10 ms nominal steps agree bit for bit, through the snatches
    one = Simulator(long_train(150), 100.0, EMPIRICAL)
    many = Simulator(long_train(150), 100.0, EMPIRICAL)
    one.advance(40.0, Commands(emergency=True))  # the run-out snatch comes at about 43 s
    many.advance(40.0, Commands(emergency=True))
    one.advance(4.0)
    for _ in range(200):
        many.advance(0.02)
    # (and through local time stepping: windows sub-stepped within these nominal steps)
    assert one.stats == many.stats and one.stats.rejected_steps > 0
    assert one.stats.refined_steps > 0 and one.stats.local_steps > 0
    a, b = one.snapshot(), many.snapshot()
    assert a.time_s == b.time_s
    for name in ("position_m", "speed_m_s", "block_force_N", "coupler_force_N"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(one.peak_buff_N, many.peak_buff_N)
    assert np.array_equal(one.peak_draft_N, many.peak_draft_N)


def test_zero_tolerance_takes_every_nominal_step_whole():
    sc = get_scenario(6)
    for tolerance in (0.0, None):
        sim = Simulator(sc.consist(), sc.speed_kmh, tolerance_m_s=tolerance)
        sim.advance(5.0, Commands(emergency=True))
        stats = sim.stats
        assert (stats.steps, stats.rejected_steps, stats.smallest_step_s) == (500, 0, 0.01)


def test_default_tolerance_keeps_the_paper_trains_on_their_nominal_step():
    # scenario 6 has no snatches: the error control costs it (almost) nothing
    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh)
    assert sim.tolerance_m_s == DEFAULT_TOLERANCE_M_S
    run(sim)
    assert sim.stats.steps <= 1.02 * round(sim.time_s / sim.step_s)


@pytest.mark.parametrize("bad", [-1e-3, 2.0, float("nan"), float("inf")])
def test_bad_tolerance_is_refused_in_one_line(bad):
    sc = get_scenario(6)
    with pytest.raises(InputError, match=r"tolerance_m_s.*must be between 0 \(fixed steps\) "
                                         r"and 1 m/s") as err:
        Simulator(sc.consist(), sc.speed_kmh, tolerance_m_s=bad)
    assert "\n" not in str(err.value)


def test_command_line_tolerance(capsys):
    import json

    from ltd_brake_ros.cli.main import main

    assert main(["simulate", "--scenario", "6", "--tolerance-m-s", "0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["rejected_steps"] == 0 and out["smallest_step_s"] == 0.01
    assert main(["simulate", "--scenario", "6", "--tolerance-m-s", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tolerance_m_s" in err and "must be between 0" in err


@pytest.mark.parametrize("w", [0.5, 1.0, 2.0])
def test_error_estimate_is_exact_for_a_cubic_speed_history(w):
    # v(t) = t^3 + t: the leading error terms of BDF2 and of the predictor are its only ones,
    # so Milne's estimate (1+w)/(2+3w) |u - q| equals the step's true local error
    from ltd_brake_ros.physics.step_control import _error_ratio

    def v(t):
        return t ** 3 + t

    def a(t):
        return 3.0 * t ** 2 + 1.0

    hs = 0.01
    hp = hs / w
    c1 = (1.0 + w) ** 2 / (1.0 + 2.0 * w)
    c2 = w * w / (1.0 + 2.0 * w)
    beta = (1.0 + w) / (1.0 + 2.0 * w)
    u = c1 * v(0.0) - c2 * v(-hp) + beta * hs * a(hs)  # BDF2 with the exact derivative
    error = abs(u - v(hs))
    none = np.zeros(1, bool)
    ratio = _error_ratio(np.array([u]), np.array([v(0.0)]), np.array([v(-hp)]),
                         np.array([a(0.0)]), none, none, hs, hp, 1.0)
    assert ratio == pytest.approx(error, rel=1e-9)
    # backward Euler after a restart (hp = 0) against the explicit Euler line, a quadratic
    u = v(0.0) + hs * (2.0 * hs + 1.0)  # v(t) = t^2 + t
    error = abs(u - (hs ** 2 + hs))
    ratio = _error_ratio(np.array([u]), np.array([0.0]), np.array([0.0]), np.array([1.0]),
                         none, none, hs, 0.0, 1.0)
    assert ratio == pytest.approx(error, rel=1e-9)


@pytest.mark.parametrize("ratio", [1.05, 1.5, 2.0, 4.0])
def test_retry_after_a_rejection_holds_the_tolerance_at_a_kink(ratio):
    # a kink inside the step (an Eq. 3 switch, an end stop) makes the local error fall in
    # proportion to the step, smooth motion with its cube: the retry must hold the tolerance
    # in both cases, else the controller cycles between rejection and retry
    from ltd_brake_ros.physics.step_control import MAX_SHRINK, _step_factor

    for order in (1.0, 2.0):
        f = _step_factor(ratio, order, True, False)
        assert MAX_SHRINK <= f < 1.0
        assert ratio * f <= 0.95          # first order in the step: accepted
        assert ratio * f ** (order + 1.0) <= 0.95  # smooth: accepted
    # beyond MAX_SHRINK's reach the retry is as short as allowed
    assert _step_factor(50.0, 2.0, True, False) == MAX_SHRINK


def test_step_growth_is_bounded_and_waits_after_a_rejection():
    from ltd_brake_ros.physics.step_control import MAX_GROWTH, _step_factor

    assert _step_factor(0.0, 2.0, False, False) == MAX_GROWTH    # no estimate yet
    assert _step_factor(1e-6, 2.0, False, False) == MAX_GROWTH
    # grows to where a smooth (third-order) error reaches 90 % of the tolerance
    assert 0.5 * _step_factor(0.5, 2.0, False, False) ** 3 == pytest.approx(0.9 ** 3)
    assert _step_factor(0.95, 2.0, False, False) < 1.0         # close to the limit: shrinks
    assert _step_factor(0.1, 2.0, False, True) == 1.0           # right after a rejection
    assert _step_factor(0.99, 2.0, False, True) < 1.0


def test_next_step_is_the_controller_capped_at_the_nominal_step():
    # _next_step skips the controller's power for a whole step with a small estimate: the
    # result must be the rule's, whatever the step, estimate, order or rejection before
    from ltd_brake_ros.physics.step_control import GROWS_SURELY, _next_step, _step_factor

    h = 0.01
    for order in (1.0, 2.0):
        for retried in (False, True):
            for hs in (h, 0.6 * h, 0.2 * h):
                for ratio in np.linspace(0.0, 1.0, 401):
                    rule = min(hs * _step_factor(ratio, order, False, retried), h)
                    assert _next_step(hs, h, ratio, order, retried) == rule, \
                        (order, retried, hs, ratio)
    assert _step_factor(GROWS_SURELY, 2.0, False, False) > 1.0

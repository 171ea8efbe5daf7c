"""Local time stepping: in a long train, only the vehicles that need short steps take them.

Braked from the head, a long G train snatches: a few couplers at a time switch between Eq. 3's
curves or reach their end stops, and their vehicles need sub-steps of tens of microseconds while
the rest of the train moves smoothly. The kernel sub-steps windows around those vehicles alone,
their neighbours outside following the whole train's step, and accepts the step when every
window held the tolerance and passed its neighbours the momentum the train's step gave them.
The result must be as accurate as stepping the whole train shorter (same tolerance), against a
fine fixed-step solution.
"""
import math

import numpy as np
import pytest

from ltd_brake_ros.inputs import consist_from_mapping, get_scenario, load_brake_params
from ltd_brake_ros.physics import kernel, local_steps
from ltd_brake_ros.simulator import Commands, Simulator

#: The paper's empirical brake: the integrator's accuracy is judged on it, beyond its range of
#: train lengths too (a default run of these trains takes the brake pipe)
EMPIRICAL = load_brake_params("brake_params/paper.yaml")


def long_train(wagons):
    return consist_from_mapping({"name": "long", "vehicles": [
        {"type": "E402B", "brake_position": "G"},
        {"type": "Shimmns", "count": wagons, "mass_t": 80.0, "brake_position": "G"}]}, "<test>")


def run(sim, until_s=None):
    """An emergency stop from t = 0 until the train stands (or ``until_s``)."""
    sim.advance(1.0, Commands(emergency=True))
    while sim.stop_time_s is None and (until_s is None or sim.time_s < until_s - 1e-9):
        sim.advance(1.0)
    return sim


def peak_errors_percent(sim, ref):
    """Largest peak draft and buff error against ``ref``, relative to each coupler's peak (at
    least a tenth of the largest), as :func:`ltd_brake_ros.studies.reference.compare` does."""
    scale = max(ref.peak_draft_N.max(), -ref.peak_buff_N.min())
    return [100.0 * np.max(np.abs(a - b) / np.maximum(np.abs(b), 0.1 * scale))
            for a, b in ((sim.peak_draft_N, ref.peak_draft_N),
                         (sim.peak_buff_N, ref.peak_buff_N))]


@pytest.fixture(scope="module")
def stops():
    """150 wagons: 1 ms fixed steps (their own error is 0.2 % of the peaks against 0.5 ms),
    and the default tolerance with and without local time stepping."""
    fine = run(Simulator(long_train(150), 100.0, EMPIRICAL, step_s=0.001, tolerance_m_s=0.0))
    local = run(Simulator(long_train(150), 100.0, EMPIRICAL))
    whole = run(Simulator(long_train(150), 100.0, EMPIRICAL, local_steps=False))
    return fine, local, whole


def test_only_the_windows_take_short_steps(stops):
    _, local, whole = stops
    st = local.stats
    assert st.refined_steps > 0 and st.local_steps > st.refined_steps
    assert whole.stats.refined_steps == whole.stats.local_steps == 0
    # the whole train tries fewer steps, and far fewer are rejected
    assert st.steps + st.rejected_steps < whole.stats.steps + whole.stats.rejected_steps
    assert st.rejected_steps < 0.5 * whole.stats.rejected_steps
    # the sub-steps resolve the snatches: shorter than a tenth of the nominal step
    assert st.smallest_step_s < 0.1 * local.step_s


def test_local_steps_are_as_accurate_as_whole_train_steps(stops):
    # the error control's criterion (2 % of each peak against 1 ms steps), and no worse than
    # stepping the whole train by more than the fine solution's own error (0.2 %)
    fine, local, whole = stops
    draft, buff = peak_errors_percent(local, fine)
    assert draft <= 2.0 and buff <= 2.0
    w_draft, w_buff = peak_errors_percent(whole, fine)
    assert draft <= w_draft + 0.5 and buff <= w_buff + 0.5
    # the stop: the train's motion as a whole is untouched by the windows (1e-4 of 1.5 km is
    # 0.15 m, far beyond the 1 mm the two runs' distances differ by)
    assert local.stopping_distance_m == pytest.approx(fine.stopping_distance_m, rel=1e-4)
    assert local.stop_time_s == pytest.approx(fine.stop_time_s, abs=0.02)


def test_short_trains_step_whole():
    # the paper's trains: a window would be a large part of the train (and their results stay
    # those of the validated runs, bit for bit)
    sc = get_scenario(6)
    sim = run(Simulator(sc.consist(), sc.speed_kmh))
    assert sim.n < kernel.LOCAL_MIN_VEHICLES
    assert sim.stats.refined_steps == sim.stats.local_steps == 0


def test_windows_take_margins_end_outside_the_band_and_merge():
    n = 40
    v = np.linspace(20.0, 19.0, n)  # every coupler closing at 1/39 m/s: outside the band
    u = v.copy()
    err = np.zeros(n)
    windows = np.zeros((n, 2), np.int64)
    band = 1e-4
    m = local_steps.LOCAL_MARGIN
    err[10] = 3.0
    assert local_steps._find_windows(err, v, u, band, windows, n) == 1
    assert tuple(windows[0]) == (10 - m, 10 + m)
    # a coupler inside the band at a window's end is taken in: it ends at the next one outside
    v2 = v.copy()
    v2[10 - m - 1] = v2[10 - m]  # coupler between 10-m-1 and 10-m rigid
    assert local_steps._find_windows(err, v2, v2, band, windows, n) == 1
    assert tuple(windows[0]) == (10 - m - 1, 10 + m)
    # two groups closer than twice the margin: one window; farther apart: two
    err[10 + 2 * m + 1] = 2.0
    assert local_steps._find_windows(err, v, u, band, windows, n) == 1
    assert tuple(windows[0]) == (10 - m, 10 + 3 * m + 1)
    err[:] = 0.0
    err[[5, 30]] = 2.0
    assert local_steps._find_windows(err, v, u, band, windows, n) == 2
    assert tuple(windows[0]) == (5 - m, 5 + m) and tuple(windows[1]) == (30 - m, 30 + m)
    # at the ends of the train, and beyond the budget of vehicles: none
    err[:] = 0.0
    err[[0, n - 1]] = 2.0
    assert local_steps._find_windows(err, v, u, band, windows, n) == 2
    assert tuple(windows[0]) == (0, m) and tuple(windows[1]) == (n - 1 - m, n - 1)
    assert local_steps._find_windows(err, v, u, band, windows, 2 * m + 1) == 0
    err[:] = 1.0  # at the tolerance: no window
    assert local_steps._find_windows(err, v, u, band, windows, n) == 0


def test_kth_largest():
    rng = np.random.default_rng(7)
    values = rng.random(500)
    top = np.empty(500)
    for k in (1, 2, 15, 500):
        assert local_steps._largest(values, k, top) == np.sort(values)[::-1][k - 1]


@pytest.mark.parametrize("s", [0.0, 0.3, 1.0])
def test_prescribed_motion_is_the_cubic_through_the_step_ends(s):
    # the neighbours of a window follow the train's step: exact for a cubic trajectory
    x = lambda t: 1.0 + 2.0 * t - 3.0 * t**2 + 0.5 * t**3  # noqa: E731
    dx = lambda t: 2.0 - 6.0 * t + 1.5 * t**2  # noqa: E731
    h = 0.8
    xs, vs = local_steps._hermite(x(0.0), dx(0.0), x(h), dx(h), h, s)
    assert math.isclose(xs, x(s * h), abs_tol=1e-12)
    assert math.isclose(vs, dx(s * h), abs_tol=1e-12)

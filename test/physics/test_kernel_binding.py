"""The kernel bound once per argument layout: the same compiled loop for the same layout, a
new one for any difference numba types differently."""
from __future__ import annotations

import numpy as np

from ltd_brake_ros.inputs import get_scenario
from ltd_brake_ros.physics import kernel
from ltd_brake_ros.simulator import Commands, Simulator


def test_layout_key_tells_apart_what_numba_types_apart():
    a = np.zeros(5)
    key = kernel._layout_key
    assert key(a) == key(np.ones(5)) == key(np.zeros(7))  # values and length do not matter
    ro = np.zeros(5)
    ro.flags.writeable = False
    others = [np.zeros(5, np.float32), np.zeros((5, 1)), np.zeros(10)[::2], ro,
              np.zeros(5, np.int64)]
    assert len({key(a), *(key(b) for b in others)}) == 1 + len(others)
    assert key((a, 1.0, True, 3)) == key((np.ones(2), 2.0, False, 4))
    assert key((a, 1.0)) != key((a, 1))  # float64 against int64
    assert key((a, object())) is None  # unknown to the key: numba types it


def test_two_trains_of_one_layout_share_the_bound_kernel_and_their_results():
    sc = get_scenario(6)
    first, second = Simulator(sc.consist(), sc.speed_kmh), Simulator(sc.consist(), 60.0)
    assert first._run_loop is second._run_loop
    for sim in (first, second):
        sim.advance(2.0, Commands(emergency=True))
    fresh = Simulator(sc.consist(), 60.0)
    kernel._BOUND.clear()
    fresh._bind_kernel()  # typed anew by numba
    fresh.advance(2.0, Commands(emergency=True))
    np.testing.assert_array_equal(fresh.snapshot().speed_m_s, second.snapshot().speed_m_s)


def test_the_whole_kernel_and_the_loop_with_a_kept_workspace_agree_bit_for_bit():
    # advance keeps the step loop's work arrays from chunk to chunk; run_steps allocates them
    # on each call: nothing left in them may change a result
    sc = get_scenario(6)
    kept, whole = Simulator(sc.consist(), sc.speed_kmh), Simulator(sc.consist(), sc.speed_kmh)
    for sim in (kept, whole):
        sim.advance(0.5, Commands(emergency=True))
    st = whole._state
    for _ in range(4):
        kept.advance(0.5)
        code, t, hp, done = kernel.run_steps(
            50, 0.5 / 50, st.time_s, st.last_step_s, whole.model,
            kernel.Inputs(st.traction_demand, whole.fext_N), st.kinematics, st.brakes, st.events,
            st.stats[0], whole._options, True)
        st.time_s, st.last_step_s = t, hp
        assert (code, done) == (kernel.OK, 50)
    assert st.time_s == kept.time_s and whole.steps == kept.steps > 200
    for name in kernel.KinematicState._fields:
        np.testing.assert_array_equal(getattr(st.kinematics, name),
                                      getattr(kept._state.kinematics, name), err_msg=name)
    np.testing.assert_array_equal(st.brakes.force_N, kept._state.brakes.force_N)

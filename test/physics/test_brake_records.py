"""The step loop's records of each vehicle's brake: as the accept pass states them, vehicle by
vehicle with branches, and as the compiled passes without branches keep them (with their
per-vehicle constants computed once): the same to the last bit."""
from __future__ import annotations

import numpy as np

from ltd_brake_ros.physics import kernel
from ltd_brake_ros.physics.bundles import (ADHESION_SPLIT_SPEED_M_S, FULL_APPLICATION,
                                           MEAN_ADHESION_MIN_SPEED_M_S)

V_STOP = 1e-3  # the simulator's standstill speed [m/s]


def stated(tc, u, fair, x, xp, acc, fa_scale, full_scale, meff, mass, rec):
    """The records of one step as the accept pass states them (``rec`` updated)."""
    pk_fast, pk_fast_t, pk_fast_v, pk_slow, pk_slow_t, pk_slow_v, work, dist = rec
    for i in range(u.shape[0]):
        if u[i] > ADHESION_SPLIT_SPEED_M_S:
            if fair[i] > pk_fast[i]:
                pk_fast[i], pk_fast_t[i], pk_fast_v[i] = fair[i], tc, u[i]
        elif u[i] > V_STOP and fair[i] > pk_slow[i]:
            pk_slow[i], pk_slow_t[i], pk_slow_v[i] = fair[i], tc, u[i]
        if (u[i] >= MEAN_ADHESION_MIN_SPEED_M_S
                and fa_scale[i] >= FULL_APPLICATION * full_scale[i] > 0.0):
            dx = x[i] - xp[i]
            work[i] += (fair[i] + (meff[i] - mass[i]) * acc[i]) * dx
            dist[i] += dx


def test_the_brake_records_of_the_branch_free_passes_are_those_of_the_accept_pass():
    rng = np.random.default_rng(7)
    n = 37  # not a multiple of any vector width: the passes' remainders are exercised
    full_scale = rng.uniform(5e4, 2e5, n)
    full_scale[[3, 11]] = 0.0  # unbraked vehicles
    mass = rng.uniform(2e4, 9e4, n)
    meff = mass * rng.uniform(1.02, 1.2, n)
    # the constants the step loop's workspace computes once
    ws = kernel.new_workspace(
        kernel.TrainModel(kernel.TrainArrays(mass, meff, np.full(n, 4.0), np.zeros(n), 1.0),
                          _Friction(full_scale), None, None, None, None, None),
        kernel.KinematicState.initial(n, 20.0), _Brakes(n), kernel.Options(100, 1e-6, V_STOP,
                                                                          1e-5, 1e-3))
    mine = [np.zeros(n) for _ in range(8)]
    theirs = [np.zeros(n) for _ in range(8)]
    x = np.zeros(n)
    speeds = np.array([ADHESION_SPLIT_SPEED_M_S, MEAN_ADHESION_MIN_SPEED_M_S, V_STOP, 0.0,
                       -0.5, np.nan])
    for step in range(400):
        tc = 0.01 * (step + 1)
        u = rng.uniform(-1.0, 30.0, n)
        u[rng.integers(0, n, 6)] = speeds  # on and around every threshold
        fair = rng.uniform(0.0, 1e5, n)
        same = rng.integers(0, n, 3)
        fair[same] = theirs[0][same]  # equal to the vehicle's peak
        fa_scale = full_scale * rng.choice([FULL_APPLICATION, 0.5, 1.0], n)
        xp, x = x, x + rng.uniform(0.0, 0.3, n)
        acc = rng.uniform(-2.0, 0.5, n)
        stated(tc, u, fair, x, xp, acc, fa_scale, full_scale, meff, mass, theirs)
        kernel._brake_records(tc, V_STOP, u, fair, x, xp, acc, fa_scale, ws.full_on,
                              ws.rotating, *mine)
    names = ("fast peak", "its time", "its speed", "slow peak", "its time", "its speed",
             "work while fully applied", "distance")
    for name, a, b in zip(names, mine, theirs):
        assert a.tobytes() == b.tobytes(), name
    assert np.count_nonzero(theirs[6]) > n // 2 and np.count_nonzero(theirs[3]) > n // 2


class _Friction:
    """What the workspace reads of a train's friction arrays."""

    def __init__(self, full_scale):
        self.full_scale_N = full_scale


class _Brakes:
    """What the workspace reads of a brake model's state."""

    def __init__(self, n):
        self.force_N = np.zeros(n)
        self.level = np.zeros(n)
        self.level_kind = np.zeros(n, np.int64)
        self.next_event = np.zeros(n, np.int64)
        self.extra = np.zeros((n, 0))

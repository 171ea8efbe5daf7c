"""The coupler-model contract (ltd_brake_ros.physics.couplers), checked for every registered model.

The kernel's Newton system is tridiagonal and symmetric positive definite, and its line search
minimises a convex potential, only when every coupler force is non-decreasing in deflection and
in rate: that property is checked on a grid that covers the valid range, beyond it, and rates
across any steep band. ``compile`` refuses parameters outside their declarations.
"""
import dataclasses
import math

import numpy as np
import pytest

from ltd_brake_ros.inputs import consist_from_mapping, load_coupler_lut
from ltd_brake_ros.physics import couplers
from ltd_brake_ros.physics.couplers import buffer_draw_gear, linear
from ltd_brake_ros.physics.parameters import CompileError, Fittable, specs
from ltd_brake_ros.simulator import Commands, Simulator

#: Typical parameters of every registered model (a new model adds its own here).
EXAMPLES = {
    "lut_hysteresis": load_coupler_lut(),
    # draw gear of 20 kN/mm with 10 mm slack either way, lightly damped
    "linear": linear.Params(stiffness_N_m=2e7, damping_N_s_m=2e5, slack_m=0.01, travel_m=0.1,
                            draft_strength_N=1.0e6, buff_strength_N=2.0e6),
    # category A buffers and a draw gear with a solid end (the shipped assumptions)
    "buffer_draw_gear": buffer_draw_gear.Params(draft_strength_N=1.0e6, buff_strength_N=2.0e6),
}
MODELS = sorted(couplers.MODELS)


def test_every_registered_model_has_an_example():
    assert set(EXAMPLES) == set(couplers.MODELS)


def test_registry_ids_are_unique():
    ids = [m.ID for m in couplers.MODELS.values()]
    assert len(set(ids)) == len(ids)


def grid(arrays):
    """Deflections [m] across and beyond the valid range, rates [m/s] across any band."""
    lo, hi = arrays.valid_lo_m, arrays.valid_hi_m
    span = hi - lo
    d = np.linspace(lo - 0.2 * span, hi + 0.2 * span, 801)
    band = arrays.band_m_s or 1e-3
    r = np.concatenate((-np.geomspace(1.0, 1e-3 * band, 40), [0.0],
                        np.geomspace(1e-3 * band, 1.0, 40)))
    r = np.union1d(r, [-band, band, -1.5 * band, 1.5 * band, -0.5 * band, 0.5 * band])
    return d, r


def evaluate(arrays, d, r):
    out = np.empty((3, d.size, r.size))
    for a, x in enumerate(d):
        for b, y in enumerate(r):
            out[:, a, b] = couplers.force_of(arrays, x, y)
    return out


@pytest.mark.parametrize("name", MODELS)
def test_declares_params_and_valid_range(name):
    model = couplers.MODELS[name]
    params = EXAMPLES[name]
    assert model.NAME == name and type(params) is model.Params
    assert couplers.model_of(params) is model
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(params, dataclasses.fields(params)[0].name, 0.0)
    for short, fit in model.FITTABLE.items():
        assert isinstance(fit, Fittable) and fit.field in {f.name for f in
                                                           dataclasses.fields(params)}, short
    arrays = couplers.compile(params)
    assert arrays.model == model.ID
    assert arrays.valid_lo_m < 0.0 < arrays.valid_hi_m
    assert arrays.band_m_s >= 0.0
    assert params.draft_strength_N > 0.0 and params.buff_strength_N > 0.0


@pytest.mark.parametrize("name", MODELS)
def test_compile_refuses_every_field_outside_its_declaration(name):
    params = EXAMPLES[name]
    declared = specs(type(params))
    assert declared, "a model declares its parameters"
    for field, spec in declared.items():
        value = getattr(params, field)
        if spec.sequence:
            bad = (math.nan,) + tuple(value[1:])
        elif spec.lo is not None:
            bad = (spec.lo - 1.0) * spec.scale
        else:
            bad = math.nan
        with pytest.raises(CompileError) as err:
            couplers.compile(dataclasses.replace(params, **{field: bad}))
        assert err.value.field.startswith(spec.key or field), field


@pytest.mark.parametrize("name", MODELS)
def test_force_is_non_decreasing_in_deflection_and_rate(name):
    arrays = couplers.compile(EXAMPLES[name])
    d, r = grid(arrays)
    f, kd, kr = evaluate(arrays, d, r)
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(kd)) and np.all(np.isfinite(kr))
    scale = np.abs(f).max()
    # monotone up to the rounding of the force values
    assert np.all(np.diff(f, axis=0) >= -1e-12 * scale)
    assert np.all(np.diff(f, axis=1) >= -1e-12 * scale)
    assert np.all(kd >= 0.0) and np.all(kr >= 0.0)
    # somewhere stiff: vehicles cannot pass through each other
    assert kd.max() > 1e6


@pytest.mark.parametrize("name", MODELS)
def test_draft_is_positive(name):
    arrays = couplers.compile(EXAMPLES[name])
    far = 0.5 * min(-arrays.valid_lo_m, arrays.valid_hi_m, 0.5)
    for rate in (-0.1, 0.0, 0.1):
        assert couplers.force_of(arrays, far, rate)[0] > 0.0
        assert couplers.force_of(arrays, -far, rate)[0] < 0.0


@pytest.mark.parametrize("name", MODELS)
def test_derivatives_bracketed_by_finite_differences(name):
    # at a kink (table point, end of slack, band edge) the derivative may be either side's
    arrays = couplers.compile(EXAMPLES[name])
    rng = np.random.default_rng(3)
    band = arrays.band_m_s or 1e-3
    for _ in range(300):
        x = rng.uniform(arrays.valid_lo_m, min(arrays.valid_hi_m, 0.3))
        y = rng.choice([-1.0, 1.0]) * band * rng.uniform(0.0, 3.0)
        f, kd, kr = couplers.force_of(arrays, x, y)
        for h, k, step in ((1e-7, kd, lambda e: (x + e, y)), (1e-3 * band, kr,
                                                              lambda e: (x, y + e))):
            left = (f - couplers.force_of(arrays, *step(-h))[0]) / h
            right = (couplers.force_of(arrays, *step(h))[0] - f) / h
            tol = 1e-6 * max(abs(left), abs(right), 1.0)
            assert min(left, right) - tol <= k <= max(left, right) + tol, (x, y)


def consist(wagons=20):
    return consist_from_mapping({"name": "contract", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": wagons, "mass_t": 80.0}]}, "<test>")


@pytest.mark.parametrize("name", MODELS)
def test_momentum_conserved_under_internal_forces(name):
    sim = Simulator(consist(8), 60.0, lut=EXAMPLES[name], resistance=False, brakes=False)
    meff = sim.model.train.meff_kg
    sim.fext_N[0], sim.fext_N[-1] = 150e3, -150e3  # head pulls, tail pushes back
    p0 = float(np.sum(meff * sim.snapshot().speed_m_s))
    loaded = 0.0
    for _ in range(200):
        snap = sim.advance(0.02)
        assert float(np.sum(meff * snap.speed_m_s)) == pytest.approx(p0, rel=1e-12)
        loaded = max(loaded, np.abs(snap.coupler_force_N).max())
    assert loaded > 50e3  # the couplers did carry the pair


@pytest.mark.parametrize("name", MODELS)
def test_a_whole_stop(name):
    # couplers move a stopping distance little: the paper's table within 0.5 % of any
    # reasonable characteristic (a 4x stiffer table moves it < 0.2 %)
    distance = {}
    for key, lut in (("table", EXAMPLES["lut_hysteresis"]), (name, EXAMPLES[name])):
        sim = Simulator(consist(), 100.0, lut=lut)
        sim.advance(1.0, Commands(emergency=True))
        while sim.stop_time_s is None:
            assert sim.time_s < 200.0
            snap = sim.advance(1.0)
        assert math.isfinite(sim.stopping_distance_m)
        assert sim.stats.max_newton_iterations < sim.max_newton_iter // 2
        # stopped: nothing moves forward (a locomotive may be pulled back as the couplers relax)
        assert np.all(snap.speed_m_s <= sim.standstill_m_s)
        distance[key] = sim.stopping_distance_m
    assert distance[name] == pytest.approx(distance["table"], rel=5e-3)


@pytest.mark.parametrize("name", MODELS)
def test_force_near_is_force_whatever_the_segment_guess(name):
    # the kernel passes each coupler's last table segment as a search hint: the force must not
    # depend on it, right or wrong (out of range, another segment, a stale one)
    arrays = couplers.compile(EXAMPLES[name])
    lo, hi = arrays.valid_lo_m, arrays.valid_hi_m
    span = hi - lo
    points = arrays.table[0] if arrays.table.size else []  # on a segment boundary
    deflections = np.concatenate((np.linspace(lo - 0.2 * span, hi + 0.2 * span, 97), points))
    m = len(points)
    guesses = (-5, -1, 0, 1, m // 2, m - 2, m - 1, m + 3)
    for d in deflections:
        for rate in (-1.0, -0.5 * arrays.band_m_s, 0.0, 0.5 * arrays.band_m_s, 1.0):
            want = couplers.force(arrays.model, arrays.table, arrays.coef, float(d), rate)
            found = set()
            for guess in guesses:
                got = couplers.force_near(arrays.model, arrays.table, arrays.coef, float(d),
                                          rate, guess)
                assert got[:3] == want  # bit for bit
                found.add(got[3])
            if m:  # a table model settles on the deflection's segment, whatever it was told
                assert len(found) == 1
            else:  # a model without a table hands the hint back
                assert found == set(guesses)

"""The brake-model contract (ltd_brake_ros.physics.brakes), checked for every registered model."""
import dataclasses
import math

import numpy as np
import pytest

from ltd_brake_ros.inputs import (BrakeParams, brake_params_from_mapping, consist_from_mapping,
                                  load_brake_params)
from ltd_brake_ros.physics import brakes
from ltd_brake_ros.physics.brakes import EMERGENCY, SERVICE, CommandEvents, friction
from ltd_brake_ros.physics.parameters import Fittable, specs
from ltd_brake_ros.simulator import Commands, Simulator

MODELS = sorted(brakes.MODELS)
STEP_S = 0.01
#: Every model with its defaults, and the shipped parameter files that bound a model's range.
CASES = [(name, None) for name in MODELS] + [
    ("uic_brake_pipe", f"brake_params/uic_brake_pipe_first_stage_{end}.yaml")
    for end in ("fast", "slow")]


def train(wagons=10):
    return consist_from_mapping({"name": "contract", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": wagons, "mass_t": 80.0}]}, "<test>")


def compiled(name, params=None):
    """The model and its arrays for :func:`train`; ``params`` a model's ``Params`` or the name
    of a shipped brake-parameter file."""
    model = brakes.MODELS[name]
    consist = train()
    fr = friction.compile(consist, friction.Params())
    if isinstance(params, str):
        params = load_brake_params(params).pneumatic
    arrays = model.compile(consist, params or model.Params(), fr.force_max_N)
    return model, arrays


def emergency_at(t_s):
    return CommandEvents.empty().appended(t_s, 1.0, EMERGENCY, 0)


def history(model, arrays, events, t_end_s, step_s=STEP_S):
    """Block forces [N] at the end of each step of a fresh state, shape (steps + 1, n)."""
    state = model.initial_state(arrays)
    times = np.arange(0.0, t_end_s + 0.5 * step_s, step_s)
    out = [state.force_N.copy()]
    for t0, t1 in zip(times[:-1], times[1:]):
        brakes.advance(arrays, state, events, t0, t1)
        out.append(state.force_N.copy())
    return times, np.array(out)


@pytest.mark.parametrize("name", MODELS)
def test_declares_name_params_and_fittable(name):
    model = brakes.MODELS[name]
    assert model.NAME == name
    params = model.Params()
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(params, dataclasses.fields(params)[0].name, 0.0)
    declared = specs(model.Params)
    # every field says its meaning, unit and range (the loaders read nothing else)
    assert set(declared) == {f.name for f in dataclasses.fields(model.Params)}
    for field, spec in declared.items():
        assert spec.doc.endswith("]") or isinstance(getattr(params, field), bool), field
    for short, fit in model.FITTABLE.items():
        assert isinstance(fit, Fittable)
        assert fit.field in declared, short
        assert fit.lower < fit.upper and fit.scale > 0.0
        assert fit.lower <= getattr(params, fit.field) <= fit.upper, short


def test_registry_ids_are_unique():
    ids = [m.ID for m in brakes.MODELS.values()]
    assert len(set(ids)) == len(ids)


@pytest.mark.parametrize("name", MODELS)
def test_a_file_names_its_model(name):
    params = brake_params_from_mapping({"model": name}, "<test>")
    assert params.model == name
    assert params.pneumatic == brakes.MODELS[name].Params()
    assert params.friction == friction.Params()
    assert BrakeParams(model=name) == dataclasses.replace(params, source="built-in defaults")


def test_a_file_without_model_is_the_paper_model():
    assert brake_params_from_mapping({"t_app_s": 2.0}, "<test>").model == "uic_empirical"


@pytest.mark.parametrize("name, params", CASES)
def test_no_force_before_the_command_reaches_a_vehicle(name, params):
    model, arrays = compiled(name, params)
    assert np.all(np.diff(arrays.delay_s) > 0.0)  # vented at the head
    t_cmd = 0.3
    # force within 1.5 s of the earliest arrival: a slow first stage holds the cylinder below
    # its force threshold for 0.6 s after the distributor applies
    times, force = history(model, arrays, emergency_at(t_cmd), t_cmd + arrays.delay_s[-1] + 1.5)
    for i, delay in enumerate(arrays.delay_s):
        before = times <= t_cmd + delay
        assert np.all(force[before, i] == 0.0), f"vehicle {i}"
        assert force[-1, i] > 0.0, f"vehicle {i}"


@pytest.mark.parametrize("name, params", CASES)
def test_emergency_rises_monotonically_to_the_full_force(name, params):
    model, arrays = compiled(name, params)
    times, force = history(model, arrays, emergency_at(0.0), 60.0)
    assert np.all(np.diff(force, axis=0) >= 0.0)
    assert np.all(force <= arrays.force_max_N * (1.0 + 1e-12))
    # the shipped models fill within 30 s (P and G); a minute leaves less than 5 % to go
    assert np.all(force[-1] >= 0.95 * arrays.force_max_N)


@pytest.mark.parametrize("name, params", CASES)
def test_release_decays_the_force(name, params):
    model, arrays = compiled(name, params)
    t_release = 40.0
    events = emergency_at(0.0).appended(t_release, 0.0, SERVICE, 0)
    times, force = history(model, arrays, events, 160.0)
    for i, delay in enumerate(arrays.delay_s):
        # fully applied when the release reaches the vehicle; from the step where the force
        # first falls, it only falls (an empirical law falls at once, a brake pipe only once it
        # has been recharged above the distributor's release threshold)
        k = np.searchsorted(times, t_release + delay)
        assert force[k - 1, i] > 0.9 * arrays.force_max_N[i]
        falls = np.flatnonzero(np.diff(force[k - 1:, i]) < 0.0)
        assert falls.size, f"vehicle {i} never releases"
        assert np.all(np.diff(force[k - 1 + falls[0]:, i]) <= 0.0), f"vehicle {i}"
    # the release times of the shipped models are at most 60 s: two minutes leave < 5 %
    assert np.all(force[-1] <= 0.05 * arrays.force_max_N)


@pytest.mark.parametrize("name, params", CASES)
def test_two_pieces_equal_one(name, params):
    model, arrays = compiled(name, params)
    # commands that reach vehicles inside both pieces: service, emergency, release
    events = (CommandEvents.empty().appended(0.0, 0.4, SERVICE, 0)
              .appended(2.0, 1.0, EMERGENCY, 0).appended(9.0, 0.0, SERVICE, 0))
    one, two = model.initial_state(arrays), model.initial_state(arrays)
    brakes.advance(arrays, one, events, 0.0, 12.0)
    brakes.advance(arrays, two, events, 0.0, 4.7)
    brakes.advance(arrays, two, events, 4.7, 12.0)
    # exact integration: equal to rounding (exp(a) exp(b) vs exp(a + b))
    assert np.allclose(one.force_N, two.force_N, rtol=1e-12, atol=1e-9)
    assert np.array_equal(one.next_event, two.next_event)
    assert np.array_equal(one.level, two.level)
    assert one.force_N.max() > 0.0


@pytest.mark.parametrize("name", MODELS)
def test_a_whole_stop_dissipates_no_more_than_the_kinetic_energy(name):
    sim = Simulator(train(), 100.0, BrakeParams(model=name))
    meff = sim.model.train.meff_kg

    def kinetic(snap):
        return 0.5 * float(np.sum(meff * snap.speed_m_s ** 2))

    prev = sim.snapshot()
    ke0 = kinetic(prev)
    work = 0.0
    snap = sim.advance(STEP_S, Commands(emergency=True))
    while sim.stop_time_s is None:
        assert sim.time_s < 200.0
        prev, snap = snap, sim.advance(STEP_S)
        work += 0.5 * STEP_S * float(np.sum(prev.brake_force_N * np.abs(prev.speed_m_s)
                                            + snap.brake_force_N * np.abs(snap.speed_m_s)))
        assert kinetic(snap) <= ke0 * (1 + 1e-12)
    assert sim.stopped and math.isfinite(sim.stopping_distance_m)
    # the brakes take most of the energy, running resistance the rest; the trapezoidal work
    # errs by well under 1 % at 10 ms steps
    assert 0.9 * ke0 <= work <= 1.005 * ke0
    assert np.all(np.abs(snap.coupler_force_N) < 1e6)


def test_linear_ramp_loses_the_distance_its_slower_rise_predicts():
    # same delays and fill time; the ramp has delivered its full force-time only t_fill / 2
    # after the onset, the exponential t_fill / ln 20 after it (Eq. 5, 7): the ramp stops
    # further by about v0 times the difference, less since the train already slows
    # during the fill (by under a quarter of v0 at 100 km/h)
    consist, v0 = train(), 100.0 / 3.6
    distance = {}
    for name in ("uic_empirical", "linear_ramp"):
        sim = Simulator(consist, 100.0, BrakeParams(model=name))
        sim.advance(1.0, Commands(emergency=True))
        while sim.stop_time_s is None:
            sim.advance(1.0)
        distance[name] = sim.stopping_distance_m
    t_fill = BrakeParams().t_fill_s
    predicted = v0 * (t_fill / 2.0 - t_fill / math.log(20.0))
    extra = distance["linear_ramp"] - distance["uic_empirical"]
    assert 0.75 * predicted <= extra <= predicted

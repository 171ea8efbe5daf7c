"""The one emergency-stop loop: grouped chunks take the steps of one chunk per call, and the
API, the command line and campaigns run the same stop."""
import dataclasses

import numpy as np
import pytest

from ltd_brake_ros.inputs import get_scenario, load_brake_params
from ltd_brake_ros.physics.kernel import SETTLE_S
from ltd_brake_ros.simulator import Commands, SimulationError, Simulator
from ltd_brake_ros.studies.runs import emergency_run, emergency_stop, summarize

PIPE = "brake_params/uic_brake_pipe.yaml"


def counted_advance(monkeypatch):
    """Record the duration of every Simulator.advance call."""
    calls = []
    advance = Simulator.advance

    def counted(sim, duration_s, commands=None):
        calls.append(duration_s)
        return advance(sim, duration_s, commands)

    monkeypatch.setattr(Simulator, "advance", counted)
    return calls


@pytest.mark.parametrize("number, params, step_s", [
    (6, None, 0.01), (12, None, 0.01), (6, PIPE, 0.01), (1, None, 0.02), (2, None, 0.025)])
def test_grouped_chunks_give_the_stop_of_one_chunk_per_call(monkeypatch, number, params,
                                                             step_s):
    sc = get_scenario(number)
    p = load_brake_params(params)
    calls = counted_advance(monkeypatch)
    one = emergency_run(sc.consist(), sc.speed_kmh, p, step_s=step_s)
    chunked = list(calls)
    calls.clear()
    grouped = emergency_run(sc.consist(), sc.speed_kmh, p, step_s=step_s, group=True)
    # one chunk per call up to the chunk in which the train settled (2 s at rest)
    assert chunked == [1.0] * len(chunked) and len(chunked) == pytest.approx(
        one.settled_time_s + SETTLE_S, abs=1.0)
    # the same steps give the same numbers bit for bit
    a, b = (dataclasses.asdict(summarize(s, 1.0)) for s in (one, grouped))
    assert a == b
    assert grouped.time_s == one.time_s and grouped.steps == one.steps
    assert calls[-1] == 1.0  # the stop falls in a single chunk, as one chunk per call
    assert max(calls) > 1.0 and len(calls) < len(chunked) - 1


@pytest.mark.parametrize("chunk_s, step_s", [(1.0, 0.03), (0.015, 0.01), (0.005, 0.01)])
def test_a_chunk_that_is_no_whole_number_of_steps_is_refused(chunk_s, step_s):
    # such a chunk would be taken in shorter steps and move the results by centimetres
    sc = get_scenario(1)
    with pytest.raises(ValueError, match=f"chunk_s: {chunk_s:g} s is not a whole number of "
                                         f"integration steps of {step_s:g} s"):
        emergency_run(sc.consist(), sc.speed_kmh, chunk_s=chunk_s, step_s=step_s)
    sim = Simulator(sc.consist(), sc.speed_kmh, step_s=step_s)
    with pytest.raises(ValueError, match="not a whole number of integration steps"):
        sim.advance(chunk_s)


def test_chunks_of_whole_steps_give_the_result_of_one_call_bit_for_bit():
    sc = get_scenario(6)
    one, many = (Simulator(sc.consist(), sc.speed_kmh) for _ in range(2))
    one.advance(30.0, Commands(emergency=True))
    many.advance(0.07, Commands(emergency=True))
    while many.time_s < 30.0 - 1e-9:
        many.advance(min(0.13, round((30.0 - many.time_s) / 0.01) * 0.01))
    assert many.stopping_distance_m == one.stopping_distance_m
    assert np.array_equal(many.peak_draft_N, one.peak_draft_N)
    assert np.array_equal(many.snapshot().position_m, one.snapshot().position_m)


def test_the_api_groups_only_without_a_callback(monkeypatch):
    sc = get_scenario(6)
    calls = counted_advance(monkeypatch)
    quiet = emergency_stop(sc.consist(), sc.speed_kmh)
    grouped = len(calls)
    calls.clear()
    seen = []
    watched = emergency_stop(sc.consist(), sc.speed_kmh, on_chunk=seen.append)
    assert len(seen) == len(calls) > grouped  # every chunk handed on
    assert [s.time_s for s in seen] == pytest.approx([k + 1.0 for k in range(len(seen))])
    skip = {"wall_time_s", "real_time_factor"}
    assert {k: v for k, v in quiet.as_dict().items() if k not in skip} == \
        {k: v for k, v in watched.as_dict().items() if k not in skip}


def test_a_train_that_does_not_stop_in_time_is_an_error():
    sc = get_scenario(6)
    with pytest.raises(SimulationError, match="had not stopped after 5 s"):
        emergency_run(sc.consist(), sc.speed_kmh, max_time_s=5.0, group=True)

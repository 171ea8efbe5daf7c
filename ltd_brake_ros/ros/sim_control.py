"""ROS 2's standard simulation control (the ``simulation_interfaces`` services) for sim_node.

Served when the ``simulation_interfaces`` package is installed (a ROS installation has it;
``./dev.sh`` builds it from ``interfaces/``), beside the node's ``std_srvs`` services, under
the node's private names as other simulators serve them:

* ``~/get_simulator_features`` (``GetSimulatorFeatures``): what this plant supports;
* ``~/get_simulation_state`` (``GetSimulationState``) and ``~/set_simulation_state``
  (``SetSimulationState``): playing, paused, stopped, quitting
  (:meth:`~ltd_brake_ros.plant.runner.PlantRunner.simulation_state`);
* ``~/step_simulation`` (``StepSimulation``): ``steps`` chunks of ``chunk_s``, as ``~/step``
  with a count of its own;
* ``~/reset_simulation`` (``ResetSimulation``): as ``~/reset`` (time and state together:
  scopes ``SCOPE_DEFAULT``, ``SCOPE_ALL`` or any that holds both ``SCOPE_TIME`` and
  ``SCOPE_STATE``; the plant spawns nothing, so ``SCOPE_SPAWNED`` asks nothing more).

A request that fails answers ``RESULT_OPERATION_FAILED`` (a refused step, a reset that could
not happen), ``RESULT_FEATURE_UNSUPPORTED`` (a scope or state this plant does not have) or a
code of ``SetSimulationState`` (already in the state, a transition not possible from here, a
failed one), with the reason in ``result.error_message``.
"""
from __future__ import annotations

from typing import Callable

from ..plant.runner import PAUSED, PLAYING, QUITTING, STOPPED, PlantRunner

try:
    from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
    from simulation_interfaces.srv import (GetSimulationState, GetSimulatorFeatures,
                                           ResetSimulation, SetSimulationState, StepSimulation)
except ImportError:  # not installed: the node serves its std_srvs services only
    Result = None

__all__ = ["available", "serve", "features"]

#: Service names (private to the node).
SERVICES = ("get_simulator_features", "get_simulation_state", "set_simulation_state",
            "step_simulation", "reset_simulation")


def available() -> bool:
    """Whether the ``simulation_interfaces`` package is installed."""
    return Result is not None


def features(lockstep: bool, follow_clock: bool) -> list[int]:
    """``SimulatorFeatures`` codes of a plant.

    Parameters
    ----------
    lockstep, follow_clock : bool
        The plant's mode: a follower is neither stepped nor paused.

    Returns
    -------
    list of int
    """
    f = SimulatorFeatures
    out = [f.SIMULATION_RESET, f.SIMULATION_STATE_GETTING]
    if not follow_clock:
        out += [f.SIMULATION_STATE_SETTING, f.SIMULATION_STATE_PAUSE,
                f.STEP_SIMULATION_SINGLE, f.STEP_SIMULATION_MULTIPLE]
    return out


def _states():
    s = SimulationState
    return {PLAYING: s.STATE_PLAYING, PAUSED: s.STATE_PAUSED, STOPPED: s.STATE_STOPPED,
            QUITTING: s.STATE_QUITTING}


def _outcomes():
    r = SetSimulationState.Response
    return {"ok": Result.RESULT_OK, "already": r.ALREADY_IN_TARGET_STATE,
            "refused": r.INCORRECT_TRANSITION, "failed": r.STATE_TRANSITION_ERROR}


def _result(ok: bool, text: str, failure: int | None = None):
    code = Result.RESULT_OK if ok else (Result.RESULT_OPERATION_FAILED if failure is None
                                        else failure)
    return Result(result=code, error_message="" if ok else text)


def serve(node, runner: Callable[[], PlantRunner], step: Callable[[int], tuple[bool, str]],
          reset: Callable[[bool], tuple[bool, str]], info: str, *, plant_group,
          control_group) -> list:
    """Create the services on ``node``.

    Parameters
    ----------
    node : rclpy.node.Node
    runner : callable
        ``runner()`` -> the plant's runner.
    step : callable
        ``step(chunks) -> (success, message)``: what ``~/step`` does, with a count.
    reset : callable
        ``reset(hold) -> (success, message)``: what ``~/reset`` does (``hold``: a stop).
    info : str
        ``custom_info`` of the features.
    plant_group, control_group : rclpy callback groups
        Of the requests that wait for the plant's queue (step, reset, stop) and of those
        served during a step (state, features, play and pause).

    Returns
    -------
    list of rclpy.service.Service
    """
    states = _states()

    def get_features(request, response):
        s = runner().settings
        response.features.features = features(s.lockstep, s.follow_clock)
        response.features.custom_info = info
        return response

    def get_state(request, response):
        state, why = runner().simulation_state()
        response.state.state = states[state]
        response.result = Result(result=Result.RESULT_OK, error_message=why)
        return response

    def set_state(request, response):
        target = next((name for name, code in states.items()
                       if code == request.state.state), None)
        if target is None:
            response.result = Result(result=Result.RESULT_FEATURE_UNSUPPORTED, error_message=(
                f"state {request.state.state} is not one of this plant's: playing (1), "
                "paused (2), stopped (0), quitting (3)"))
            return response
        plant = runner()
        if target == STOPPED:
            refusal = plant.stop_refusal()
            if refusal:
                outcome, text = refusal
            else:
                ok, text = reset(True)
                outcome = "ok" if ok else "failed"
        else:
            outcome, text = plant.result(plant.set_simulation_state(target))
        code = _outcomes()[outcome]
        response.result = Result(result=code, error_message="" if outcome == "ok" else text)
        return response

    def step_simulation(request, response):
        ok, text = step(request.steps)
        response.result = _result(ok, text)
        return response

    def reset_simulation(request, response):
        scope, r = request.scope, ResetSimulation.Request
        both = r.SCOPE_TIME | r.SCOPE_STATE
        if scope not in (r.SCOPE_DEFAULT, r.SCOPE_ALL) and scope & both != both:
            response.result = Result(result=Result.RESULT_FEATURE_UNSUPPORTED, error_message=(
                f"scope {scope}: this plant resets time and state together (SCOPE_DEFAULT, "
                "SCOPE_ALL, or SCOPE_TIME | SCOPE_STATE)"))
            return response
        ok, text = reset(False)
        response.result = _result(ok, text)
        return response

    return [
        node.create_service(GetSimulatorFeatures, "~/get_simulator_features", get_features,
                            callback_group=control_group),
        node.create_service(GetSimulationState, "~/get_simulation_state", get_state,
                            callback_group=control_group),
        node.create_service(SetSimulationState, "~/set_simulation_state", set_state,
                            callback_group=control_group),
        node.create_service(StepSimulation, "~/step_simulation", step_simulation,
                            callback_group=plant_group),
        node.create_service(ResetSimulation, "~/reset_simulation", reset_simulation,
                            callback_group=plant_group),
    ]

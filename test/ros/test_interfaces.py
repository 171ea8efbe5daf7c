"""The interface packages ./dev.sh generates from ``interfaces/`` are the released ones: the same
type hashes (REP 2011: names and types of every field, nested types included), so a node of a
ROS installation talks to the plant, and the constants the plant answers with.
"""
from __future__ import annotations

import pytest

from ltd_brake_ros.recording.ros_types import installed_type_hash

pytestmark = pytest.mark.ros

#: RIHS01 hashes of simulation_interfaces 1.5.1 (the Jazzy release), as rosidl generates them
#: from its definitions, and of tf2_msgs/msg/TFMessage (Jazzy; rosbags' Jazzy type store
#: computes the same).
RELEASED = {
    "simulation_interfaces/msg/Result":
        "RIHS01_cf43a306adff3337a0a47143d8f5689933bc70a30478f13b077dc1fe3bc5ad17",
    "simulation_interfaces/msg/SimulationState":
        "RIHS01_bb9f87ccdd98fba113052a512d9801e84ce732d0a2b3c2b0cb281828de36e415",
    "simulation_interfaces/msg/SimulatorFeatures":
        "RIHS01_8b101c8529bc0ea3dcf056078254768f39832b9ef0adaf93bd5cea96c0de3305",
    "simulation_interfaces/srv/GetSimulationState":
        "RIHS01_3362dcebee4b1afebbf9c4beee5c79c1455385aded62092a892d61fde8644f30",
    "simulation_interfaces/srv/GetSimulatorFeatures":
        "RIHS01_abb9439c8cf196722a469fb6c68b44b484f198c2a1356ac38849a29c2a20a794",
    "simulation_interfaces/srv/ResetSimulation":
        "RIHS01_4ce285d7ff9b8ac70dcc95161f32bf54c05a6f4b13427990e41ab40c36c39646",
    "simulation_interfaces/srv/SetSimulationState":
        "RIHS01_a868b916dce49974f637ba252141258c4b07b0c06858b88af560e3eb6bfbcb30",
    "simulation_interfaces/srv/StepSimulation":
        "RIHS01_913fe0653690ce6bf8f09f316e6a626747012e9fca31e26719910d417aa8565c",
    "tf2_msgs/msg/TFMessage":
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
}


@pytest.mark.parametrize("msg_type", sorted(RELEASED))
def test_the_generated_types_hash_as_the_released_ones(msg_type):
    pytest.importorskip(msg_type.split("/")[0], reason="./dev.sh builds it")
    assert installed_type_hash(msg_type) == RELEASED[msg_type]


def test_the_constants_the_plant_answers_with():
    pytest.importorskip("simulation_interfaces", reason="./dev.sh builds it")
    from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
    from simulation_interfaces.srv import ResetSimulation, SetSimulationState, StepSimulation

    assert (Result.RESULT_FEATURE_UNSUPPORTED, Result.RESULT_OK, Result.RESULT_NOT_FOUND,
            Result.RESULT_INCORRECT_STATE, Result.RESULT_OPERATION_FAILED) == (0, 1, 2, 3, 4)
    s = SimulationState
    assert (s.STATE_STOPPED, s.STATE_PLAYING, s.STATE_PAUSED, s.STATE_QUITTING,
            s.STATE_NO_WORLD, s.STATE_LOADING_WORLD) == (0, 1, 2, 3, 4, 5)
    f = SimulatorFeatures
    assert (f.SIMULATION_RESET, f.SIMULATION_STATE_GETTING, f.SIMULATION_STATE_SETTING,
            f.SIMULATION_STATE_PAUSE, f.STEP_SIMULATION_SINGLE,
            f.STEP_SIMULATION_MULTIPLE) == (20, 24, 25, 26, 31, 32)
    r = ResetSimulation.Request
    assert (r.SCOPE_DEFAULT, r.SCOPE_TIME, r.SCOPE_STATE, r.SCOPE_SPAWNED, r.SCOPE_ALL) == \
        (0, 1, 2, 4, 255)
    t = SetSimulationState.Response
    assert (t.ALREADY_IN_TARGET_STATE, t.STATE_TRANSITION_ERROR, t.INCORRECT_TRANSITION) == \
        (101, 102, 103)
    assert StepSimulation.Request().steps == 1

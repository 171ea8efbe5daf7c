"""The plant's topics as a recording declares them: names, message types, offered QoS.

The same table as the ``sim_node`` publishers and subscriptions (topic names relative to the
node's namespace, ``/clock`` absolute; QoS as ``ros.messages`` sets it: reliable, volatile,
keep-last 10 for state, 1 for the clock, 1000 for commands; liveliness ``system_default``,
rclpy's default), readable without ROS so an offline run records what the node would.
"""
from __future__ import annotations

from .qos import qos_profiles_yaml

__all__ = ["ARRAY_TOPICS", "CLOCK_TOPIC", "COMMAND_TOPICS", "plant_topics", "qualify"]

#: Published arrays (``std_msgs/msg/Float64MultiArray``): topic, Snapshot attribute,
#: ``layout.dim[0].label``.
ARRAY_TOPICS = (
    ("vehicles/speed", "speed_m_s", "vehicle"),
    ("vehicles/position", "position_m", "vehicle"),
    ("vehicles/brake_force", "brake_force_N", "vehicle"),
    ("vehicles/traction_force", "traction_force_N", "vehicle"),
    ("couplers/force", "coupler_force_N", "coupler"),
)
CLOCK_TOPIC = "/clock"
#: Command topics: message type and the plant input each one sets.
COMMAND_TOPICS = {"brake_command": ("std_msgs/msg/Bool", "emergency"),
                  "brake_demand": ("std_msgs/msg/Float64", "brake_demand"),
                  "traction_command": ("std_msgs/msg/Float64", "traction")}

_F64_ARRAY = "std_msgs/msg/Float64MultiArray"


def qualify(namespace: str, topic: str) -> str:
    """Fully qualified name of a node-relative ``topic`` in ``namespace`` (``/`` or ``/ns``)."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def plant_topics(namespace: str = "/") -> list[tuple[str, str, str]]:
    """Every topic a plant recording declares, as :class:`~..plant.recorder.Recorder` takes them.

    Parameters
    ----------
    namespace : str, optional
        The node's namespace.

    Returns
    -------
    list of (str, str, str)
        Fully qualified name, message type, ``offered_qos_profiles`` text: the arrays,
        ``/clock``, then the command topics.
    """
    def qos(depth: int) -> str:
        return qos_profiles_yaml(depth=depth, liveliness="system_default")

    return ([(qualify(namespace, t), _F64_ARRAY, qos(10)) for t, _, _ in ARRAY_TOPICS]
            + [(CLOCK_TOPIC, "rosgraph_msgs/msg/Clock", qos(1))]
            + [(qualify(namespace, t), msg_type, qos(1000))
               for t, (msg_type, _) in COMMAND_TOPICS.items()])

"""Messages and QoS profiles of the nodes: labelled arrays, simulated time, diagnostics."""
from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from ..plant.diagnostics import PlantStatus

#: State topics: lossless for a subscriber that keeps up, never latched.
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Only the newest time matters; a reliable writer also serves best-effort readers
#: (rclpy's and rclcpp's time sources subscribe best-effort).
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Commands are precious: a deep reader queue keeps a burst (a controller catching up, a script)
#: while the executor is busy; only a sustained flood beyond what rclpy takes is dropped.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
DIAGNOSTICS_QOS = STATE_QOS
#: The train description: latched, so a subscriber joining late (RViz, Foxglove, a logger)
#: receives the current run's.
DESCRIPTION_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: The stops' events: rare and each one kept (a reader joining late misses them; the recording
#: keeps them all).
STOPS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: /tf: as tf2_ros broadcasts it (reliable, volatile, a deep queue for bursts of transforms).
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
#: Markers: only the newest picture matters.
MARKERS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)


def time_msg(time_ns: int) -> Time:
    """``builtin_interfaces/Time`` for a simulated time in nanoseconds."""
    return Time(sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000)


def array_msg(label: str, values: np.ndarray) -> Float64MultiArray:
    """A one-dimensional ``Float64MultiArray`` with a labelled layout.

    Parameters
    ----------
    label : str
        ``layout.dim[0].label`` (``vehicle`` or ``coupler``).
    values : ndarray
        The data (SI units).

    Returns
    -------
    Float64MultiArray
    """
    n = int(values.size)
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    msg.layout.data_offset = 0
    # an array('d') skips rclpy's per-element Python checks
    msg.data = array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return msg


def diagnostics_msg(status: PlantStatus, name: str, hardware_id: str,
                    time_ns: int) -> DiagnosticArray:
    """``diagnostic_msgs/DiagnosticArray`` holding one plant report.

    Parameters
    ----------
    status : PlantStatus
    name : str
        Status name (``<node>: train plant``).
    hardware_id : str
        The train's name.
    time_ns : int
        Simulated time of the report [ns].

    Returns
    -------
    DiagnosticArray
    """
    msg = DiagnosticArray(status=[DiagnosticStatus(
        level=bytes([status.level]), name=name, message=status.message, hardware_id=hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in status.values.items()])])
    msg.header.stamp = time_msg(time_ns)
    return msg


def marker_array_msg(specs, frame_id: str, time_ns: int, prefix: str = ""):
    """``visualization_msgs/MarkerArray`` of :func:`~ltd_brake_ros.plant.markers.train_markers`.

    Parameters
    ----------
    specs : list of MarkerSpec
    frame_id : str
        The track frame.
    time_ns : int
        Simulated time of the state [ns].
    prefix : str, optional
        Prepended to each marker namespace (the node's namespace), so several trains'
        markers do not replace each other.

    Returns
    -------
    visualization_msgs.msg.MarkerArray
    """
    from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker, MarkerArray

    stamp = time_msg(time_ns)
    kinds = {"cube": Marker.CUBE, "text": Marker.TEXT_VIEW_FACING}
    out = MarkerArray()
    for m in specs:
        # frame_locked: a view moves the markers with their frame between two pictures
        marker = Marker(ns=f"{prefix}{m.ns}", id=int(m.id), type=kinds[m.kind],
                        action=Marker.ADD, text=m.text, frame_locked=True,
                        pose=Pose(position=Point(x=m.x, y=m.y, z=m.z),
                                  orientation=Quaternion(w=1.0)),
                        scale=Vector3(x=float(m.size[0]), y=float(m.size[1]),
                                      z=float(m.size[2])),
                        color=ColorRGBA(r=m.rgba[0], g=m.rgba[1], b=m.rgba[2], a=m.rgba[3]))
        marker.header.frame_id = frame_id
        marker.header.stamp = stamp
        out.markers.append(marker)
    return out


def clear_markers_msg(frame_id: str):
    """A ``MarkerArray`` that deletes every marker shown (a new run, another train)."""
    from visualization_msgs.msg import Marker, MarkerArray

    marker = Marker(action=Marker.DELETEALL)
    marker.header.frame_id = frame_id
    return MarkerArray(markers=[marker])

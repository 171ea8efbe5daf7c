"""Test helpers: record a simulated emergency stop the way the node publishes it."""
from __future__ import annotations

import array

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64MultiArray, MultiArrayDimension

from ltd_brake_ros.recording.bag import BagWriter, qos_profiles_yaml
from ltd_brake_ros.inputs import load_brake_params, load_coupler_lut
from ltd_brake_ros.recording.metadata import run_metadata
from ltd_brake_ros.simulator import Commands, Simulator

F64 = "std_msgs/msg/Float64MultiArray"
ARRAYS = (("vehicles/speed", "vehicle"), ("vehicles/position", "vehicle"),
          ("vehicles/brake_force", "vehicle"), ("vehicles/traction_force", "vehicle"),
          ("couplers/force", "coupler"))


def array_msg(values, label: str) -> Float64MultiArray:
    """Float64MultiArray with a named first dimension, as the node fills it."""
    m = Float64MultiArray()
    m.layout.dim = [MultiArrayDimension(label=label, size=len(values), stride=len(values))]
    data = array.array("d")
    data.frombytes(np.ascontiguousarray(values, dtype=float).tobytes())
    m.data = data
    return m


def snapshot_arrays(snap) -> list[np.ndarray]:
    """Arrays of a snapshot in ARRAYS order."""
    traction = getattr(snap, "traction_force_N", None)
    if traction is None:
        traction = np.zeros_like(snap.speed_m_s)
    return [snap.speed_m_s, snap.position_m, snap.brake_force_N, traction,
            snap.coupler_force_N]


def declare_topics(writer: BagWriter, ns: str) -> None:
    for name, _ in ARRAYS:
        writer.add_topic(f"{ns}/{name}", F64)
    writer.add_topic(f"{ns}/brake_command", "std_msgs/msg/Bool")
    writer.add_topic("/clock", "rosgraph_msgs/msg/Clock",
                     qos_profiles_yaml(depth=1, reliability="best_effort"))
    writer.add_topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")


def record_emergency_stop(folder, consist, speed_kmh: float, *, ns: str = "/train",
                          chunk_s: float = 0.02, after_stop_s: float = 0.2,
                          max_time_s: float = 300.0, keep: bool = False, **writer_kw):
    """Drive the simulator in chunks with the emergency brake applied at t = 0 and record.

    Returns
    -------
    (Simulator, list)
        The simulator after the run, and (with ``keep``) every recorded
        ``(topic, msg_type, log_time_ns, data)`` in order.
    """
    sim = Simulator(consist, speed_kmh, load_brake_params(), load_coupler_lut())
    published = []
    with BagWriter(folder, metadata=run_metadata(sim, scenario="test"), **writer_kw) as w:
        declare_topics(w, ns)

        def put(topic, msg_type, msg, t_ns):
            data = serialize_message(msg)
            w.write(topic, data, t_ns)
            if keep:
                published.append((topic, msg_type, t_ns, data))

        def publish(snap):
            t_ns = round(snap.time_s * 1e9)
            put("/clock", "rosgraph_msgs/msg/Clock",
                Clock(clock=_time(t_ns)), t_ns)
            for (name, label), values in zip(ARRAYS, snapshot_arrays(snap)):
                put(f"{ns}/{name}", F64, array_msg(values, label), t_ns)
            return t_ns

        t_ns = publish(sim.snapshot())
        put(f"{ns}/brake_command", "std_msgs/msg/Bool", Bool(data=True), t_ns)
        next_diag = 0.0
        while sim.time_s < max_time_s:
            snap = sim.advance(chunk_s, Commands(emergency=True))
            t_ns = publish(snap)
            if snap.time_s >= next_diag:
                next_diag += 1.0
                peak_kN = np.abs(snap.coupler_force_N).max() / 1e3
                status = DiagnosticStatus(level=DiagnosticStatus.OK, name="sim_node: plant",
                                          message="running", hardware_id="sim",
                                          values=[KeyValue(key="max_coupler_force_kN",
                                                           value=f"{peak_kN:.1f}")])
                msg = DiagnosticArray(status=[status])
                msg.header.stamp = _time(t_ns)
                put("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", msg, t_ns)
            if sim.stop_time_s is not None and sim.time_s >= sim.stop_time_s + after_stop_s:
                break
    return sim, published


def _time(t_ns: int):
    from builtin_interfaces.msg import Time

    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)

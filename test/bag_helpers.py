"""Test helpers: record a simulated emergency stop the way the node publishes it; a full disk."""
from __future__ import annotations

import array
import errno
import os

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
#: The last bytes of every complete PNG file (the IEND chunk and its CRC).
PNG_END = b"IEND\xaeB`\x82"
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


def write_messages(folder, messages, *, metadata=None, **writer_kw):
    """Record ``(topic, msg_type, log_time_ns, data)`` tuples as given (order, times, types).

    Returns
    -------
    pathlib.Path
        The ``.mcap`` file written.
    """
    with BagWriter(folder, metadata=metadata, **writer_kw) as w:
        for topic, msg_type, *_ in messages:
            w.add_topic(topic, msg_type)
        for topic, _type, t_ns, data in messages:
            w.write(topic, data, t_ns)
    return w.path


def plant_messages(n_vehicles: int = 3, samples: int = 40, *, ns: str = "/train",
                   step_ns: int = 50_000_000):
    """A small made-up plant recording: emergency at t = 0, braking at 0.5 m/s² throughout.

    Returns
    -------
    list
        ``(topic, msg_type, log_time_ns, data)`` in time order, as :func:`write_messages` takes.
    """
    out = [(f"{ns}/brake_command", "std_msgs/msg/Bool", 0, serialize_message(Bool(data=True)))]
    for i in range(samples):
        t_s = i * step_ns * 1e-9
        v = max(10.0 - 0.5 * t_s, 0.0) * np.ones(n_vehicles)
        values = {"vehicles/speed": v, "vehicles/position": 10.0 * t_s - np.arange(n_vehicles),
                  "vehicles/brake_force": np.full(n_vehicles, 1e4 * min(t_s, 1.0)),
                  "vehicles/traction_force": np.zeros(n_vehicles),
                  "couplers/force": np.sin(np.arange(1, n_vehicles) + t_s) * 1e5}
        for name, label in ARRAYS:
            out.append((f"{ns}/{name}", F64, i * step_ns,
                        serialize_message(array_msg(values[name], label))))
    return out


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


_REAL_WRITEV = os.writev


class DiskFull:
    """A disk that fills up: ``budget`` bytes in all, then every write fails with ENOSPC.

    Patch :meth:`open` in for the ``open`` of a module (its files take from the budget),
    :meth:`writev` for ``os.writev`` (what :class:`BagWriter` writes with) and :meth:`stream`
    for ``sys.stdout``.
    """

    def __init__(self, budget: int):
        self.left = budget

    def take(self, n: int) -> None:
        if n > self.left:
            self.left = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.left -= n

    def open(self, path, mode="r", **kw):
        disk, real = self, open(path, mode, **kw)  # noqa: SIM115 - closed by the caller

        class File:
            def write(self, data):
                disk.take(len(data))
                return real.write(data)

            def __getattr__(self, name):
                if name == "fileno":  # writers fall back to write()
                    raise AttributeError(name)
                return getattr(real, name)

        return File()

    def writev(self, fd, parts):
        self.take(sum(len(p) for p in parts))
        return _REAL_WRITEV(fd, parts)

    def stream(self):
        """A text stream on this disk; what reached it is in its ``written`` list."""
        disk = self

        class Stream:
            def __init__(self):
                self.written = []

            def write(self, text):
                disk.take(len(text))
                self.written.append(text)
                return len(text)

            def flush(self):
                pass

        return Stream()

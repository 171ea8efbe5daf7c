"""Where the train is, as ROS tools follow it: the frame tree on ``/tf`` and the odometry.

The track is drawn straight and level: x along the track (the chainage [m]), y to the left,
z up, the rail at z = 0. Frames of a plant in namespace ``/train1`` carry the prefix ``train1/``
(none in the root namespace), so several trains share ``/tf``:

* ``map`` — fixed: x = chainage [m];
* ``<prefix>base_link`` — the head vehicle's centre, child of ``map``, on ``/tf`` with every
  published chunk (the same stamp as the chunk's state);
* ``<prefix>vehicle_<i>`` — vehicle i's centre, child of ``<prefix>base_link`` (x = its
  distance from the head's centre along the track, negative behind; ``vehicle_0`` is at the
  head's origin), at ``vehicle_rate_hz`` of simulated time (0: never). Relative to the head a
  vehicle moves only by the couplers' play, so a low rate still draws the train whole.

``odom`` (``nav_msgs/msg/Odometry``, with every published chunk): frame ``map``, child
``<prefix>base_link``; the head's centre at (chainage, 0, 0), its speed as the linear x velocity
in its own frame [m/s]; covariances zero (the simulated state is exact).

The plant's markers (``train/markers``) are drawn in ``<prefix>base_link``, so a 3D view that
follows that frame follows the train.
"""
from __future__ import annotations

import math

import numpy as np

from .cdr_encode import OdometryEncoder, TFMessageEncoder

__all__ = ["TF_TOPIC", "TF_TYPE", "ODOM_TOPIC", "ODOM_TYPE", "MARKERS_TOPIC", "MARKERS_TYPE",
           "FIXED_FRAME", "HEAD_FRAME", "frame_prefix", "vehicle_frame", "FramesEncoder"]

TF_TOPIC = "/tf"
TF_TYPE = "tf2_msgs/msg/TFMessage"
ODOM_TOPIC = "odom"
ODOM_TYPE = "nav_msgs/msg/Odometry"
#: The train as markers for RViz and Foxglove (``visualization_msgs/MarkerArray``).
MARKERS_TOPIC = "train/markers"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
FIXED_FRAME = "map"
#: The head vehicle's frame, after the node's prefix.
HEAD_FRAME = "base_link"
#: Tolerance when comparing simulated times built from summed chunks [s].
_EPS_S = 1e-9


def frame_prefix(namespace: str) -> str:
    """The frame prefix of a node in ``namespace``: ``train1/`` for ``/train1``, ``""`` for
    ``/``."""
    prefix = namespace.strip("/")
    return f"{prefix}/" if prefix else ""


def vehicle_frame(prefix: str, index: int) -> str:
    """The frame of vehicle ``index`` (0 = the head)."""
    return f"{prefix}vehicle_{index}"


class FramesEncoder:
    """The ``/tf`` and ``odom`` payloads of a train's states, in the frame tree above.

    Parameters
    ----------
    prefix : str
        Frame prefix (:func:`frame_prefix`).
    n_vehicles : int
    vehicle_rate_hz : float
        Rate of the vehicles' transforms in simulated time [Hz]; 0 = never.
    tf : bool, optional
        Encode ``/tf`` (False: the odometry only, where ``tf2_msgs`` is not installed).
    """

    def __init__(self, prefix: str, n_vehicles: int, vehicle_rate_hz: float, tf: bool = True):
        self.head_frame = f"{prefix}{HEAD_FRAME}"
        self._tf = tf
        self._period_s = 1.0 / vehicle_rate_hz if vehicle_rate_hz > 0.0 else math.inf
        self._next_s = 0.0 if vehicle_rate_hz > 0.0 else math.inf
        self._odom = OdometryEncoder(FIXED_FRAME, self.head_frame)
        self._head = TFMessageEncoder([(FIXED_FRAME, self.head_frame)])
        self._vehicles = TFMessageEncoder([(self.head_frame, vehicle_frame(prefix, i))
                                           for i in range(n_vehicles)])
        #: Whether the last :meth:`encode` sent the vehicles' transforms.
        self.vehicles_sent = False

    def encode(self, time_s: float, position_m, speed_m_s, stamp_ns: int
               ) -> list[tuple[str, bytes]]:
        """``(topic, payload)`` of one published state: ``odom``, then ``/tf`` (the head's
        transform, and the vehicles' when due).

        Parameters
        ----------
        time_s : float
            Simulated time of the state [s] (schedules the vehicles' transforms).
        position_m, speed_m_s : ndarray
            Each vehicle's centre chainage [m] and speed [m/s], head first.
        stamp_ns : int
            Stamp [ns].
        """
        x = np.asarray(position_m, dtype=float)
        out = [(ODOM_TOPIC, self._odom.encode(stamp_ns, x[0], float(speed_m_s[0])))]
        self.vehicles_sent = False
        if not self._tf:
            return out
        out.append((TF_TOPIC, self._head.encode(stamp_ns, x[:1])))
        if time_s >= self._next_s - _EPS_S:
            self._next_s = (math.floor(time_s / self._period_s + _EPS_S) + 1) * self._period_s
            out.append((TF_TOPIC, self._vehicles.encode(stamp_ns, x - x[0])))
            self.vehicles_sent = True
        return out

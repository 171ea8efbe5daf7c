"""The train as boxes along the track: what a plant shows in RViz and Foxglove's 3D panel.

Built from a snapshot without ROS (the node turns them into ``visualization_msgs/Marker``, the
documentation renders them with matplotlib), in the frame of the track: x along the track [m]
(the vehicles' centre positions, the head the furthest ahead), z up, the rail at z = 0.

* one box per vehicle (namespace ``vehicles``, id = vehicle index), its length less a gap for
  the couplers, coloured from grey (brake released) to orange (fully applied: the block force
  over the full block force);
* one small box per coupler (``couplers``, id = coupler number, 1 behind the head) between the
  two vehicles it joins, at the buffers' height, coloured by its force relative to its
  strength: grey at 0, red in draft, blue in buff, the colour's share the square root of the
  force's (a tenth of the strength shows a third of the colour), magenta beyond the strength;
* a label over each vehicle (``labels``: index and type; every 10th vehicle of a train of more
  than 100).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MarkerSpec", "train_markers", "VEHICLE_HEIGHT_M", "VEHICLE_WIDTH_M"]

#: Size of a vehicle's box across the track and in height [m] (a freight wagon's gauge).
VEHICLE_WIDTH_M, VEHICLE_HEIGHT_M = 3.0, 3.5
#: Gap left between two boxes where the coupler is drawn [m].
COUPLER_GAP_M = 1.0
#: Height of the box bottoms above the rail (wheels and bogies) [m].
FLOOR_M = 0.6
#: Height of the couplers' boxes above the rail: the buffer centre line, 940-1 065 mm (UIC
#: 527-1) [m].
COUPLER_HEIGHT_M = 1.0
#: Trains longer than this label every 10th vehicle only.
LABEL_ALL_UP_TO = 100

_GREY = np.array([0.62, 0.64, 0.66])
_ORANGE = np.array([1.0, 0.55, 0.0])
_RED = np.array([0.85, 0.05, 0.05])
_BLUE = np.array([0.05, 0.25, 0.9])
_MAGENTA = (0.9, 0.0, 0.9, 1.0)


@dataclass(frozen=True)
class MarkerSpec:
    """One marker: a box or a text label, in the track frame.

    Attributes
    ----------
    ns : str
        ``vehicles``, ``couplers`` or ``labels``.
    id : int
        Vehicle index or coupler number.
    kind : str
        ``cube`` or ``text``.
    x, y, z : float
        Centre [m].
    size : tuple of float
        Box edges along, across, up [m]; for text, the height of its letters in ``size[2]``.
    rgba : tuple of float
        Colour, 0-1.
    text : str
        The label (text only).
    """

    ns: str
    id: int
    kind: str
    x: float
    y: float
    z: float
    size: tuple
    rgba: tuple
    text: str = ""


def _mix(a: np.ndarray, b: np.ndarray, share: float) -> tuple:
    s = float(np.clip(share, 0.0, 1.0))
    return (*(a + (b - a) * s).round(4).tolist(), 1.0)


def train_markers(position_m, length_m, block_force_N, max_block_force_N, coupler_force_N,
                  draft_strength_N, buff_strength_N, names=None) -> list[MarkerSpec]:
    """The markers of a train in one state.

    Parameters
    ----------
    position_m : array_like
        Each vehicle's centre along the track, head first [m].
    length_m : array_like
        Each vehicle's length over buffers [m].
    block_force_N : array_like
        Each vehicle's force on its blocks or pads [N].
    max_block_force_N : array_like
        Each vehicle's full block force [N] (0: unbraked).
    coupler_force_N : array_like
        Each coupler's force, coupler 1 first [N, draft positive].
    draft_strength_N, buff_strength_N : array_like
        Each coupler's strengths, magnitudes [N] (inf: unknown; then 1 MN sets the colour).
    names : sequence of str, optional
        Vehicle type names for the labels.

    Returns
    -------
    list of MarkerSpec
        Vehicles, couplers, then labels.
    """
    x = np.asarray(position_m, float)
    length = np.asarray(length_m, float)
    brake = np.asarray(block_force_N, float)
    scale = np.asarray(max_block_force_N, float)
    force = np.asarray(coupler_force_N, float)
    n = x.size
    out = []
    z_box = FLOOR_M + VEHICLE_HEIGHT_M / 2
    for i in range(n):
        share = brake[i] / scale[i] if scale[i] > 0 else 0.0
        out.append(MarkerSpec("vehicles", i, "cube", float(x[i]), 0.0, z_box,
                              (max(float(length[i]) - COUPLER_GAP_M, 0.5), VEHICLE_WIDTH_M,
                               VEHICLE_HEIGHT_M), _mix(_GREY, _ORANGE, share)))
    for j in range(1, n):
        rear = x[j - 1] - length[j - 1] / 2  # of the vehicle ahead
        front = x[j] + length[j] / 2  # of the vehicle behind
        f = float(force[j - 1])
        limit = float(draft_strength_N[j - 1] if f >= 0 else buff_strength_N[j - 1])
        limit = limit if np.isfinite(limit) and limit > 0 else 1e6
        share = abs(f) / limit
        rgba = _MAGENTA if share > 1.0 else _mix(_GREY, _RED if f >= 0 else _BLUE,
                                                 share ** 0.5)
        out.append(MarkerSpec("couplers", j, "cube", float((rear + front) / 2), 0.0,
                              COUPLER_HEIGHT_M,
                              (COUPLER_GAP_M, 0.6, 0.6), rgba))
    every = 1 if n <= LABEL_ALL_UP_TO else 10
    for i in range(0, n, every):
        label = f"{i}" if names is None else f"{i} {names[i]}"
        out.append(MarkerSpec("labels", i, "text", float(x[i]), 0.0,
                              FLOOR_M + VEHICLE_HEIGHT_M + 1.0, (0.0, 0.0, 1.2),
                              (1.0, 1.0, 1.0, 1.0), label))
    return out

"""What every brake model shares: the bundles the kernel passes, the command events, Eq. 6.

See the contract in :mod:`ltd_brake_ros.physics.brakes`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..equations import centre_offsets_m
from ..parameters import CompileError  # noqa: F401 (part of this family's interface)

#: Kinds of command events: an emergency application, a service application/release, or a
#: release with overcharge (level 0; a model without overcharge treats it as a release).
EMERGENCY, SERVICE, OVERCHARGE = 0, 1, 2


class BrakeArrays(NamedTuple):
    """A brake model compiled for one train: built once, never mutated.

    Attributes
    ----------
    model : int
        Registry id of the model (selects its branch of the one jitted dispatch).
    delay_s : ndarray
        When a command reaches each vehicle's brake, after it was issued [s] (see
        :func:`vent_delay_s`).
    force_max_N : ndarray
        Full block force of each vehicle, 1000 * sum(F_dyn) (Eq. 4 inverted) [N]; zeros when
        the brakes are switched off.
    coef : ndarray, shape (n, k)
        The model's other per-vehicle constants, columns named by the model.
    """

    model: int
    delay_s: np.ndarray
    force_max_N: np.ndarray
    coef: np.ndarray


class BrakeState(NamedTuple):
    """The mutable state of a brake model (arrays updated in place by the advance).

    Attributes
    ----------
    force_N : ndarray
        Total block force of each vehicle, F_B,tot [N].
    level : ndarray
        Level (0-1 of the full force) of the last command each vehicle has received.
    level_kind : ndarray of int
        Kind of that command (:data:`EMERGENCY`, :data:`SERVICE` or :data:`OVERCHARGE`).
    next_event : ndarray of int
        Index of the next command event each vehicle has not yet received.
    extra : ndarray, shape (n, k)
        The model's other state, columns named by the model (k = 0 for none).
    work : ndarray, shape (k, n)
        Scratch rows of the model's advance, which allocates nothing (k = 0 for none); no
        state: their contents mean nothing between advances.
    """

    force_N: np.ndarray
    level: np.ndarray
    level_kind: np.ndarray
    next_event: np.ndarray
    extra: np.ndarray
    work: np.ndarray

    def copy(self) -> "BrakeState":
        """An independent copy."""
        return BrakeState(*(a.copy() for a in self))


class CommandEvents(NamedTuple):
    """Brake commands issued by the driver's brake valve, oldest first.

    Attributes
    ----------
    time_s : ndarray
        When each was issued [s].
    level : ndarray
        Demanded fraction of the full block force (0 = release).
    kind : ndarray of int
        :data:`EMERGENCY`, :data:`SERVICE` or :data:`OVERCHARGE`.
    count : int
        Number of valid entries.
    """

    time_s: np.ndarray
    level: np.ndarray
    kind: np.ndarray
    count: int

    @classmethod
    def empty(cls, capacity: int = 8) -> "CommandEvents":
        """No command yet."""
        return cls(np.zeros(capacity), np.zeros(capacity), np.zeros(capacity, np.int64), 0)

    def copy(self) -> "CommandEvents":
        """An independent copy."""
        return CommandEvents(self.time_s.copy(), self.level.copy(), self.kind.copy(), self.count)

    def appended(self, time_s: float, level: float, kind: int,
                 received: int) -> "CommandEvents":
        """These events without the first ``received`` (every vehicle has them), plus one.

        Parameters
        ----------
        time_s, level, kind
            The new command.
        received : int
            Leading events every vehicle has already received.

        Returns
        -------
        CommandEvents
            Arrays are reused (and grown when full).
        """
        t, lv, kd, n = self.time_s, self.level, self.kind, self.count
        if received:
            m = n - received
            t[:m] = t[received:n].copy()
            lv[:m] = lv[received:n].copy()
            kd[:m] = kd[received:n].copy()
            n = m
        if n == t.size:
            t = np.concatenate((t, np.zeros(t.size)))
            lv = np.concatenate((lv, np.zeros(lv.size)))
            kd = np.concatenate((kd, np.zeros(kd.size, np.int64)))
        t[n], lv[n], kd[n] = time_s, level, kind
        return CommandEvents(t, lv, kd, n + 1)


def released_state(n: int, extra_columns: int = 0, work_rows: int = 0) -> BrakeState:
    """Brake state of a released train that has received no command.

    Parameters
    ----------
    n : int
        Vehicles.
    extra_columns : int, optional
        Columns of the model's own state.
    work_rows : int, optional
        Scratch rows of n values for the model's advance.

    Returns
    -------
    BrakeState
    """
    return BrakeState(np.zeros(n), np.zeros(n), np.zeros(n, np.int64), np.zeros(n, np.int64),
                      np.zeros((n, extra_columns)), np.zeros((work_rows, n)))


def vent_delay_s(consist, t_app_s: float, v_air_m_s: float, simultaneous: bool) -> np.ndarray:
    """Delay of each vehicle's brake after a command, Eq. 5-6, timed from the venting vehicle.

    The driver's brake valve vents the brake pipe in the venting vehicle
    (``consist.venting_vehicle``: the leading locomotive unless the consist names another);
    the pressure drop travels from there both ways along the train. Each vehicle's delay is
    t_app + t_del, t_del = |distance| / v_air between the venting vehicle's centre and its own
    (0 when every vehicle is commanded at once). For a train vented at vehicle 0 this is Eq. 6
    as the paper states it, distance from the head.

    Parameters
    ----------
    consist : Consist
        The train, head first (vehicle lengths, venting vehicle).
    t_app_s : float
        Delay from the command to the pressure rise at the venting vehicle [s].
    v_air_m_s : float
        Propagation speed of the brake-pipe pressure drop [m/s].
    simultaneous : bool
        The command reaches every vehicle at once.

    Returns
    -------
    ndarray
        [s].
    """
    centre = centre_offsets_m(np.array([v.length_m for v in consist.vehicles]))
    distance = np.abs(centre - centre[int(getattr(consist, "venting_vehicle", 0))])
    return t_app_s + (0.0 * distance if simultaneous else distance / v_air_m_s)

"""Adhesion curve files: the rail's available adhesion against speed, with its source."""
from __future__ import annotations

import os

import numpy as np

from ..physics.brakes.adhesion import SLIDING_RATIO, AdhesionCondition
from .schema import Fields, InputError, load_yaml, resolve_config_path

__all__ = ["adhesion_condition", "load_adhesion"]


def adhesion_condition(spec, where: str, field: str = "") -> AdhesionCondition | None:
    """A rail's adhesion condition as a user gives it (None: not given).

    Parameters
    ----------
    spec : None, str, float, path-like or AdhesionCondition
        ``dry``, ``wet``, ``low``, ``off``, a constant mu in (0, 1], an adhesion YAML file
        (:func:`load_adhesion`) or a condition.
    where, field : str
        Named in the error (e.g. ``command line``, ``--rail``).

    Returns
    -------
    AdhesionCondition or None

    Raises
    ------
    InputError
        An unknown name, a number outside (0, 1], a file that does not load.
    """
    from ..physics.brakes import adhesion

    if spec is None:
        return None
    if isinstance(spec, os.PathLike) or (isinstance(spec, str) and spec.strip().lower()
                                         .endswith((".yaml", ".yml"))):
        return load_adhesion(spec)
    try:
        return adhesion.condition(spec)
    except (ValueError, TypeError) as exc:
        raise InputError(where, field, str(exc)) from None


def load_adhesion(path: str | os.PathLike) -> AdhesionCondition:
    """Load an adhesion curve: ``speed_kmh`` (strictly increasing, from 0), ``mu`` (each in
    (0, 1]), ``source`` (where the values come from; required) and optionally
    ``sliding_ratio`` (the sliding friction of locked wheelsets over mu, in (0, 1]; default
    :data:`~ltd_brake_ros.physics.brakes.adhesion.SLIDING_RATIO`).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    AdhesionCondition

    Raises
    ------
    InputError
        Naming the file, the field and the reason.
    """
    p = resolve_config_path(path)
    f = Fields(load_yaml(p), str(p))
    f.reject_unknown({"name", "description", "source", "speed_kmh", "mu", "sliding_ratio"})
    speeds = f.numbers("speed_kmh")
    mu = f.numbers("mu")
    if len(speeds) < 1 or len(speeds) != len(mu):
        raise f.error("mu", f"give one value per speed ({len(speeds)} speeds, {len(mu)} values)")
    if speeds[0] < 0.0 or any(b <= a for a, b in zip(speeds, speeds[1:])):
        raise f.error("speed_kmh", "must start at 0 or above and increase strictly")
    if any(not 0.0 < m <= 1.0 for m in mu):
        raise f.error("mu", "every value must lie in (0, 1]")
    source = f.string("source", "")
    if not source.strip():
        raise f.error("source", "missing: say where the curve comes from")
    ratio = f.number("sliding_ratio", SLIDING_RATIO, lo=0.0, lo_open=True, hi=1.0)
    return AdhesionCondition(f.string("name", p.stem), np.array([np.array(speeds) / 3.6, mu]),
                             source, ratio)

"""Brake-parameter files: the brake model they name and its and the friction law's values."""
from __future__ import annotations

import os
from typing import Any

from ..physics import brakes
from ..physics.brakes import BrakeParams
from .schema import Fields, file_keys, load_once, params_from_fields, resolve_config_path

__all__ = ["BrakeParams", "brake_params_from_mapping", "load_brake_params"]


def brake_params_from_mapping(data: Any, source: str) -> BrakeParams:
    """Validate brake parameters given as a mapping (a YAML document or ROS parameters).

    Parameters
    ----------
    data : mapping
        ``model`` (a registered brake model, default ``uic_empirical``) and the fields of that
        model's, the friction law's and the brake-heat model's ``Params``; missing fields take
        their defaults.
    source : str
        Where the values came from, for error messages.

    Returns
    -------
    BrakeParams
    """
    f = Fields(data, source)
    name = f.string("model", brakes.DEFAULT_MODEL, choices=tuple(brakes.MODELS))
    model = brakes.MODELS[name]
    f.reject_unknown(file_keys(model.Params) | file_keys(brakes.friction.Params)
                     | file_keys(brakes.thermal.Params) | {"model", "name", "description"})
    pneumatic = params_from_fields(model.Params, f)
    try:
        brakes.check_fields(pneumatic)
    except brakes.CompileError as exc:
        raise f.error(exc.field, exc.reason) from None
    return BrakeParams(pneumatic, params_from_fields(brakes.friction.Params, f), str(source),
                       thermal=params_from_fields(brakes.thermal.Params, f))


def load_brake_params(path: str | os.PathLike | None = None) -> BrakeParams:
    """Load a brake-parameter YAML file (default: the shipped ``brake_params/paper.yaml``).

    Parameters
    ----------
    path : str or path-like, optional
        The file; relative names are also looked up in the shipped config directory.

    Returns
    -------
    BrakeParams
    """
    # read once per version of the file: the parameters are immutable
    return load_once(resolve_config_path(path or "brake_params/paper.yaml"),
                     brake_params_from_mapping)

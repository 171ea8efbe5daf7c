"""Brake-parameter files: the brake model they name and its and the friction law's values."""
from __future__ import annotations

import os
from typing import Any

from ..physics import brakes
from ..physics.brakes import BrakeParams
from .schema import Fields, file_keys, load_once, params_from_fields, resolve_config_path

__all__ = ["BrakeParams", "DEFAULT_FILES", "brake_params_from_mapping", "default_brake_params",
           "load_brake_params"]

#: The shipped brake-parameter files a train runs with when none is named: the paper's
#: empirical model, then the UIC brake pipe.
DEFAULT_FILES = ("brake_params/paper.yaml", "brake_params/uic_brake_pipe.yaml")


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


def default_brake_params(consist) -> BrakeParams:
    """The brake parameters a train runs with when none are named.

    The paper's empirical model (``brake_params/paper.yaml``) within its validated range
    (:func:`~ltd_brake_ros.physics.brakes.validity`: trains up to 500 m), the UIC brake pipe
    (``brake_params/uic_brake_pipe.yaml``) beyond, also where no model covers the train (a
    run says so: :func:`model_warnings`).

    Parameters
    ----------
    consist : Consist

    Returns
    -------
    BrakeParams
        Its ``source`` names the file and why it was chosen.
    """
    empirical, pipe = (load_brake_params(f) for f in DEFAULT_FILES)
    outside = brakes.validity(consist, empirical)
    if not outside:
        return empirical
    return BrakeParams(pipe.pneumatic, pipe.friction, f"{pipe.source} (the default beyond the "
                       "empirical model's range)", thermal=pipe.thermal)


def model_warnings(consist, params: BrakeParams, coupler=None) -> list[str]:
    """Where a run of ``consist`` leaves its models' validated ranges (empty: inside them).

    Vehicles heavier per axle than the line categories (:func:`~.consist.axle_load_warnings`),
    the brake model's range (:func:`~ltd_brake_ros.physics.brakes.validity`), a note when no
    brake model covers the train, and the coupler model's (its buffers' declared end force,
    :func:`~ltd_brake_ros.physics.couplers.validity`).

    Parameters
    ----------
    consist : Consist
    params : BrakeParams
    coupler : dataclass, optional
        The run's coupler model parameters.

    Returns
    -------
    list of str
    """
    from ..physics import couplers
    from .consist import axle_load_warnings

    out = axle_load_warnings(consist) + brakes.validity(consist, params)
    if out and all(brakes.validity(consist, load_brake_params(f)) for f in DEFAULT_FILES):
        out.append("no brake model covers this train: the brake pipe runs it (the default "
                   "beyond the empirical model's range); its results are an extrapolation")
    if coupler is not None:
        out += couplers.validity(coupler)
    return out

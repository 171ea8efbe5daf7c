"""Coupler files: the coupler model they name and its parameters."""
from __future__ import annotations

import os
from dataclasses import replace

from ..physics import couplers
from ..physics.couplers import lut_hysteresis
from ..physics.couplers.lut_hysteresis import Params as CouplerLUT
from ..physics.parameters import out_of_range, specs
from .schema import (Fields, InputError, file_keys, load_once, params_from_fields,
                     resolve_config_path)

__all__ = ["CouplerLUT", "load_coupler_lut"]


def load_coupler_lut(path: str | os.PathLike | None = None, v_th_mm_s: float | None = None):
    """Load a coupler file (default: the shipped buffer-hook reconstruction).

    The file may name its coupler model with ``model`` (default ``lut_hysteresis``) and holds
    the fields that model's ``Params`` declares: for ``lut_hysteresis`` ``deflection_mm``,
    ``loading_kN``, ``unloading_kN``, optional ``v_th_mm_s`` and the optional strength limits
    ``draft_strength_kN``, ``buff_strength_kN``; for ``linear`` ``stiffness_kN_per_mm``,
    ``damping_kN_s_per_m``, ``slack_mm``, ... Every precondition of the model (its
    ``compile``) is checked here.

    Parameters
    ----------
    path : str or path-like, optional
        The file; relative names are also looked up in the shipped config directory.
    v_th_mm_s : float, optional
        Overrides the file's Eq. 3 threshold speed [mm/s] (``lut_hysteresis`` only).

    Returns
    -------
    CouplerLUT or another registered coupler model's Params

    Raises
    ------
    InputError
        Naming the file (or ``v_th_mm_s``), the field and the reason.
    """
    # read once per version of the file (the parameters are immutable; a simulator built
    # without a table reads the shipped one)
    return load_once(resolve_config_path(path or "couplers/buffer_hook_pugi.yaml"), _coupler,
                     v_th_mm_s)


def _coupler(data, p: str, v_th_mm_s: float | None):
    """The coupler parameters of file ``p`` holding ``data`` (see :func:`load_coupler_lut`)."""
    f = Fields(data, p)
    name = f.string("model", couplers.DEFAULT_MODEL, choices=tuple(couplers.MODELS))
    if v_th_mm_s is not None and name != lut_hysteresis.NAME:
        raise InputError("v_th_mm_s", "", f"applies to {lut_hysteresis.NAME} couplers only; "
                         f"{p} holds a {name} coupler")
    model = couplers.MODELS[name]
    f.reject_unknown(file_keys(model.Params) | {"model", "name", "description"})
    params = params_from_fields(model.Params, f, source=p)
    if v_th_mm_s is not None:
        spec = specs(CouplerLUT)["v_th_m_s"]
        reason = out_of_range(float(v_th_mm_s), spec.lo, spec.hi, spec.lo_open)
        if reason:
            raise InputError("v_th_mm_s", "", reason)
        params = replace(params, v_th_m_s=spec.scale * float(v_th_mm_s))
    try:
        couplers.compile(params)
    except couplers.CompileError as exc:
        raise InputError(p, exc.field, exc.reason) from None
    return params

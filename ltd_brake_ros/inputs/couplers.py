"""Coupler files: the coupler model they name and its parameters."""
from __future__ import annotations

import math
import os

from ..physics import couplers
from ..physics.couplers import lut_hysteresis
from ..physics.couplers.lut_hysteresis import Params as CouplerLUT
from .schema import (Fields, InputError, file_keys, load_yaml, params_from_fields,
                     resolve_config_path)

__all__ = ["CouplerLUT", "load_coupler_lut"]


def load_coupler_lut(path: str | os.PathLike | None = None, v_th_mm_s: float | None = None):
    """Load a coupler file (default: the shipped buffer-hook reconstruction).

    The file may name its coupler model with ``model`` (default ``lut_hysteresis``). A
    ``lut_hysteresis`` file holds ``deflection_mm``, ``loading_kN``, ``unloading_kN``, optional
    ``v_th_mm_s`` and the optional strength limits ``draft_strength_kN``, ``buff_strength_kN``;
    another model's file holds the fields its ``Params`` declares (e.g. ``linear``:
    ``stiffness_kN_per_mm``, ``damping_kN_s_per_m``, ``slack_mm``, ...).

    Parameters
    ----------
    path : str or path-like, optional
        The file; relative names are also looked up in the shipped config directory.
    v_th_mm_s : float, optional
        Overrides the file's Eq. 3 threshold speed [mm/s] (``lut_hysteresis`` only).

    Returns
    -------
    CouplerLUT or another registered coupler model's Params
    """
    p = resolve_config_path(path or "couplers/buffer_hook_pugi.yaml")
    f = Fields(load_yaml(p), str(p))
    name = f.string("model", couplers.DEFAULT_MODEL, choices=tuple(couplers.MODELS))
    if name == lut_hysteresis.NAME:
        return _load_table(f, p, v_th_mm_s)
    if v_th_mm_s is not None:
        raise InputError("v_th_mm_s", "", f"applies to {lut_hysteresis.NAME} couplers only; "
                         f"{p} holds a {name} coupler")
    model = couplers.MODELS[name]
    f.reject_unknown(file_keys(model.Params) | {"model", "name", "description"})
    return params_from_fields(model.Params, f, source=str(p))


def _load_table(f: Fields, p, v_th_mm_s: float | None) -> CouplerLUT:
    f.reject_unknown({"model", "name", "description", "deflection_mm", "loading_kN",
                      "unloading_kN", "v_th_mm_s", "draft_strength_kN", "buff_strength_kN"})
    d = f.numbers("deflection_mm")
    fl = f.numbers("loading_kN")
    fu = f.numbers("unloading_kN")
    if len(d) < 2:
        raise f.error("deflection_mm", f"needs at least 2 points, got {len(d)}")
    for name, col in (("loading_kN", fl), ("unloading_kN", fu)):
        if len(col) != len(d):
            raise f.error(name, f"has {len(col)} values but deflection_mm has {len(d)}")
    for i in range(1, len(d)):
        if not d[i] > d[i - 1]:
            raise InputError(p, f"deflection_mm[{i}]",
                             f"must be strictly increasing ({d[i - 1]:g} then {d[i]:g})")
    for name, col in (("loading_kN", fl), ("unloading_kN", fu)):
        for i in range(1, len(col)):
            if col[i] < col[i - 1]:
                raise InputError(p, f"{name}[{i}]", f"must not decrease with deflection "
                                 f"({col[i - 1]:g} then {col[i]:g} kN): a coupler never pulls "
                                 "back harder when compressed further")
        if col[0] == col[-1]:
            raise f.error(name, "is flat: the coupler would have no stiffness")
    vth = f.number("v_th_mm_s", 0.1, lo=0.0, lo_open=True, hi=1e4)
    if v_th_mm_s is not None:
        if not (math.isfinite(v_th_mm_s) and v_th_mm_s > 0):
            raise InputError("v_th_mm_s", "", f"must be a positive number, got {v_th_mm_s}")
        vth = float(v_th_mm_s)
    draft = f.number("draft_strength_kN", math.inf, lo=0.0, lo_open=True)
    buff = f.number("buff_strength_kN", math.inf, lo=0.0, lo_open=True)
    return CouplerLUT(tuple(x * 1e-3 for x in d), tuple(x * 1e3 for x in fl),
                      tuple(x * 1e3 for x in fu), vth * 1e-3, str(p), draft * 1e3, buff * 1e3)

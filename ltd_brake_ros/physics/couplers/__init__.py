"""Coupler models: the contract every model implements, the registry and the one dispatch.

Every coupler of a train has the same characteristic; coupler j joins vehicles j and j + 1
(numbered from 0 at the head) with deflection x_j - x_{j+1} and rate v_j - v_{j+1}, both
draft positive.

Contract
--------
A coupler model is one module of this package that defines:

1. ``NAME`` (the ``model:`` value of a coupler file), ``ID`` (its branch of :func:`force`), a
   frozen ``Params`` dataclass (units in the field names; fields declared with
   :func:`~ltd_brake_ros.physics.parameters.parameter` are read from a file by the input
   layer's shared field checks), ``FITTABLE`` (as for brake models; may be empty) and
   ``compile(params)`` -> :class:`CouplerArrays`, built once, never mutated. ``compile``
   first checks every precondition of the parameters (declared ranges with
   :func:`~ltd_brake_ros.physics.parameters.check`, and the model's physics: a table's
   shape, signs, bounds, monotonicity and energy balance) and raises
   :class:`~ltd_brake_ros.physics.parameters.CompileError` naming the field as a file spells
   it; the loaders run it at load time, the simulator for parameters built in code. Forces,
   deflections and slopes stay within :mod:`.base`'s ``MAX_FORCE_N``, ``MAX_DEFLECTION_M`` and
   ``MAX_STIFFNESS_N_M``.
2. ``force(table, coef, defl_m, rate_m_s)``, compiled with numba (inlined into the kernel's
   loops, so it takes the arrays of its :class:`CouplerArrays`, not the bundle): the force
   [N, draft positive], d(force)/d(deflection) [N/m] and d(force)/d(rate) [N/(m/s)]. A model
   that looks the deflection up in a table may also define ``force_near`` (the same, with the
   table segment of the coupler's last lookup tried first, see :func:`force_near`).
3. **Monotone**: the force is non-decreasing in deflection and in rate, both derivatives are
   >= 0. The kernel's Newton system is tridiagonal and symmetric positive definite, and its
   line search minimises a convex potential, only then. The contract tests check it on a grid.
4. ``CouplerArrays.band_m_s``: the half-width of any steep band in rate (Eq. 3's v_th; 0 if
   none), which the kernel's safeguard keeps Newton updates from jumping across.
5. ``CouplerArrays.valid_lo_m``/``valid_hi_m``: the deflections the characteristic is valid for
   (the simulator reports how far a coupler went beyond them); ``Params.draft_strength_N`` and
   ``Params.buff_strength_N``: the strength limits (magnitudes, inf when unknown) that
   verdicts on a run use; ``Params.buffer_end_force_N`` (:func:`.base.buffer_end_force_field`):
   the declared end force of one side buffer, its category's, independent of the force curve:
   a coupling beyond twice it is a limit state and marks the run non-physical
   (:func:`buffer_limit`, :func:`validity`).
6. Register: one line in :data:`MODELS` and one branch in :func:`force` (and in
   :func:`force_near` for a model that defines its own).
7. The contract tests (``test/physics/test_coupler_contract.py``) run over every registered
   model.
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

from .. import parameters
from ..equations import jit_inline
from ..parameters import CompileError
from . import buffer_draw_gear, linear, lut_hysteresis
from .base import (BUFFER_SIDES, DEFAULT_BUFFER_END_FORCE_N, DEFAULT_BUFFER_END_FORCE_ORIGIN,
                   CouplerArrays, buffer_end_force_declared, buffer_end_force_N)

__all__ = ["BufferLimit", "CompileError", "CouplerArrays", "DEFAULT_MODEL", "MODELS",
           "buffer_limit", "force", "force_near", "force_of", "model_of", "validity"]

#: Registered coupler models by name.
MODELS = {m.NAME: m for m in (
    lut_hysteresis,
    linear,
    buffer_draw_gear,
)}
#: The model of a coupler file that names none.
DEFAULT_MODEL = lut_hysteresis.NAME


@jit_inline
def force(model, table, coef, defl_m, rate_m_s):
    """Force [N], d/d(deflection) [N/m] and d/d(rate) [N/(m/s)] of a registered model.

    ``model``, ``table`` and ``coef`` are the fields of the model's :class:`CouplerArrays`.
    """
    if model == lut_hysteresis.ID or model == buffer_draw_gear.ID:  # both tabulated, Eq. 3
        return lut_hysteresis.force(table, coef, defl_m, rate_m_s)
    if model == linear.ID:
        return linear.force(table, coef, defl_m, rate_m_s)
    return math.nan, 0.0, 0.0


@jit_inline
def force_near(model, table, coef, defl_m, rate_m_s, segment):
    """:func:`force`, plus a table segment to look the deflection up from first.

    For the kernel, which evaluates each coupler several times per step at nearly the same
    deflection: ``segment`` is what the last call for this coupler returned (any int at
    first); the force is the same whatever it is. A model without a table returns it as is.

    Returns
    -------
    force_N, dforce_ddefl_N_m, dforce_drate_N_s_m : float
    segment : int
        The segment to pass in the next call for this coupler.
    """
    if model == lut_hysteresis.ID or model == buffer_draw_gear.ID:
        return lut_hysteresis.force_near(table, coef, defl_m, rate_m_s, segment)
    f, kd, kr = force(model, table, coef, defl_m, rate_m_s)
    return f, kd, kr, segment


def force_of(arrays: CouplerArrays, defl_m: float, rate_m_s: float) -> tuple[float, float, float]:
    """:func:`force` of compiled arrays, for use from Python.

    Parameters
    ----------
    arrays : CouplerArrays
    defl_m : float
        Deflection, draft positive [m].
    rate_m_s : float
        Deflection rate [m/s].

    Returns
    -------
    force_N, dforce_ddefl_N_m, dforce_drate_N_s_m : float
    """
    return force(arrays.model, arrays.table, arrays.coef, float(defl_m), float(rate_m_s))


def model_of(params) -> Any:
    """The registered coupler model whose ``Params`` type ``params`` is (its module)."""
    return parameters.model_of(MODELS, params)


def compile(params) -> CouplerArrays:  # noqa: A001 - the contract's name
    """Compile any registered coupler model's parameters.

    Parameters
    ----------
    params : dataclass
        A registered model's ``Params``.

    Returns
    -------
    CouplerArrays

    Raises
    ------
    CompileError
        A precondition of the model does not hold.
    """
    return model_of(params).compile(params)


class BufferLimit(NamedTuple):
    """The buffers' limit state of a coupler model: where its elastic force ends.

    Attributes
    ----------
    end_force_N : float
        Declared end force of one side buffer [N].
    coupling_force_N : float
        The limit per coupling, :data:`~.base.BUFFER_SIDES` x ``end_force_N`` (both buffers of
        each side solid) [N]: beyond it the underframes carry the force.
    declared : bool
        The coupler file declares the end force (False: the category default is assumed).
    reached_at_m : float
        Buff deflection at which the loading curve reaches ``coupling_force_N`` before the
        buffers' full stroke [m] (negative); NaN when it does not.
    full_stroke_m : float
        The buffers' full stroke, the buff end of the model's valid range [m] (-inf: none).
    origin : str
        Where the limit comes from, for the verdicts' source line.
    """

    end_force_N: float
    coupling_force_N: float
    declared: bool
    reached_at_m: float
    full_stroke_m: float
    origin: str


#: Deflection step of :func:`buffer_limit`'s scan of the loading curve [m].
_SCAN_STEP_M = 5e-4


def buffer_limit(params, arrays: CouplerArrays | None = None) -> BufferLimit:
    """The buffers' limit state of a coupler model's parameters.

    Parameters
    ----------
    params : dataclass
        A registered coupler model's ``Params``.
    arrays : CouplerArrays, optional
        Its compiled arrays (default: compiled here).

    Returns
    -------
    BufferLimit
    """
    if arrays is None:
        arrays = model_of(params).compile(params)
    end = buffer_end_force_N(params)
    limit = BUFFER_SIDES * end
    declared = buffer_end_force_declared(params)
    stroke = float(arrays.valid_lo_m)
    # the loading curve in buff: compressing faster than Eq. 3's band
    rate = -2.0 * float(arrays.band_m_s)
    reached = math.nan
    deepest = stroke if math.isfinite(stroke) else -0.5
    for k in range(1, int(-deepest / _SCAN_STEP_M) + 1):
        d = -k * _SCAN_STEP_M
        if -force_of(arrays, d, rate)[0] > limit:
            reached = d
            break
    origin = (f"twice the end force of one side buffer per coupling (both buffers of a side "
              f"solid, the underframe loaded beyond: a limit state, not an elastic buffer "
              f"force), {limit / 1e3:.0f} kN; "
              + (f"coupler file: {end / 1e3:.0f} kN per buffer" if declared
                 else DEFAULT_BUFFER_END_FORCE_ORIGIN))
    if math.isfinite(reached) and math.isfinite(stroke):
        origin += (f"; the coupler curve reaches it at {reached * 1e3:.0f} mm, before the "
                   f"buffers' full stroke ({stroke * 1e3:.0f} mm)")
    return BufferLimit(end, limit, declared, reached, stroke, origin)


def validity(params) -> list[str]:
    """Where a coupler model's parameters leave what is known of the couplings.

    Parameters
    ----------
    params : dataclass
        A registered coupler model's ``Params``.

    Returns
    -------
    list of str
        One sentence per reason (empty: none).
    """
    if buffer_end_force_declared(params):
        return []
    source = getattr(params, "source", "") or "the coupler"
    return [f"{source} declares no buffer end force (buffer_end_force_kN): "
            f"{DEFAULT_BUFFER_END_FORCE_ORIGIN}; a coupling beyond twice it, "
            f"{BUFFER_SIDES * DEFAULT_BUFFER_END_FORCE_N / 1e3:.0f} kN, marks the run "
            "non-physical"]

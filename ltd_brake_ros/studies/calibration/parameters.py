"""What calibration can fit: the parameters, their bounds, ``--fit``, ``--set``, ``--bounds``."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

from ...inputs import BrakeParams, InputError
from ...physics import brakes, couplers
from ...physics.brakes import friction
from ...physics.parameters import specs


#: Coefficients of the UIC 544-1 reference curve S = C / lambda + D at 100 km/h [m %], [m].
UIC_C_M_PERCENT = 50752.0
UIC_D_M = 53.45
#: The only initial speed at which UIC 544-1 reference distances are available here [km/h].
UIC_SPEED_KMH = 100.0

#: Thresholds of the identifiability warnings.
MAX_ABS_CORRELATION = 0.95
MAX_RELATIVE_CI = 0.5
#: Correlation beyond which two fitted parameters are not separately identifiable and the
#: later one is held (when asked to fit only what the targets determine): at one initial
#: speed t_app and t_fill correlate at -1.000, while K0 and t_app, told apart by trains of
#: different braked-weight percentages, stay near -0.98 with tight intervals.
HOLD_CORRELATION = 0.99

#: Fraction of a parameter's range within which a fitted value counts as on its bound.
BOUND_TOL = 1e-4

#: Significant digits of the values written to a parameter file; the "after" residuals are
#: evaluated at the written values, so the file reproduces the report exactly.
WRITE_DIGITS = 5


@dataclass(frozen=True)
class FitParameter:
    """A parameter that can be fitted: a short name and its model's ``FITTABLE`` entry.

    Attributes
    ----------
    name : str
        Short name used on the command line (``t_app``).
    field, unit, lower, upper, scale, meaning
        As in :class:`~ltd_brake_ros.physics.parameters.Fittable`; ``field`` is readable on
        :class:`~ltd_brake_ros.inputs.BrakeParams` (``part`` brake) or on the coupler model's
        ``Params`` (``part`` coupler), the fit works in ``value / scale`` and takes
        finite-difference steps relative to it.
    part : str
        ``brake`` or ``coupler``.
    """

    name: str
    field: str
    unit: str
    lower: float
    upper: float
    scale: float
    meaning: str
    part: str = "brake"


def fit_parameters(model: str = brakes.DEFAULT_MODEL) -> dict[str, FitParameter]:
    """The parameters a brake model lets calibration fit: its ``FITTABLE``, then the friction's.

    Parameters
    ----------
    model : str, optional
        Registered brake model (default: the paper's).

    Returns
    -------
    dict of str to FitParameter
        By short name.
    """
    table = {**brakes.MODELS[model].FITTABLE, **friction.FITTABLE}
    return {name: FitParameter(name, *fit) for name, fit in table.items()}


#: The parameters that can be fitted with the paper's brake model.
FIT_PARAMETERS: dict[str, FitParameter] = fit_parameters()


def coupler_fit_parameters(model: str = couplers.DEFAULT_MODEL) -> dict[str, FitParameter]:
    """The parameters a coupler model lets calibration fit: its ``FITTABLE``.

    Parameters
    ----------
    model : str, optional
        Registered coupler model (default: the paper's look-up table).

    Returns
    -------
    dict of str to FitParameter
        By short name.
    """
    return {name: FitParameter(name, *fit, part="coupler")
            for name, fit in couplers.MODELS[model].FITTABLE.items()}


def _known(model: str, part: str) -> dict[str, FitParameter]:
    return fit_parameters(model) if part == "brake" else coupler_fit_parameters(model)


def _resolve(fit: Sequence[FitParameter | str], model: str, part: str = "brake"
             ) -> list[FitParameter]:
    """Names resolved against a model; FitParameters (possibly with narrowed bounds) kept."""
    names = [p.name if isinstance(p, FitParameter) else p for p in fit]
    given = {p.name: p for p in fit if isinstance(p, FitParameter)}
    return [given.get(p.name, p) for p in parse_fit(names, model, part=part)]


def with_bounds(fit: Sequence[FitParameter], text: str) -> list[FitParameter]:
    """Narrow the bounds of fitted parameters, e.g. ``v_air=250:290``.

    Parameters
    ----------
    fit : sequence of FitParameter
    text : str
        Comma-separated ``name=lower:upper`` in each parameter's unit, within its model's
        bounds; a side left empty keeps the model's.

    Returns
    -------
    list of FitParameter

    Raises
    ------
    InputError
        Not of that form, a parameter not fitted, or bounds outside the model's.
    """
    by_name = {p.name: p for p in fit}
    by_name.update({p.field: p for p in fit})
    new = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, sep, rng = item.partition("=")
        lo_text, sep2, hi_text = rng.partition(":")
        p = by_name.get(name.strip())
        if not (sep and sep2):
            raise InputError("command line", "--bounds", f"expected name=lower:upper, e.g. "
                             f"v_air=250:290, got {item!r}")
        if p is None:
            raise InputError("command line", "--bounds", f"{name.strip()!r} is not fitted "
                             f"(--fit {','.join(q.name for q in fit)})")
        try:
            lo = float(lo_text) if lo_text.strip() else p.lower
            hi = float(hi_text) if hi_text.strip() else p.upper
        except ValueError:
            raise InputError("command line", "--bounds", f"{item!r}: bounds must be numbers "
                             f"in {p.unit}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and p.lower <= lo < hi <= p.upper):
            raise InputError("command line", "--bounds", f"{p.name} bounds {lo:g}:{hi:g} must "
                             f"increase within the model's {p.lower:g}:{p.upper:g} {p.unit}")
        new[p.name] = replace(p, lower=lo, upper=hi)
    return [new.get(p.name, p) for p in fit]


def parse_values(text: str, model: str, part: str = "brake") -> dict[str, float]:
    """Start values given on the command line, e.g. ``t_fill=4,t_app=0.5``.

    Parameters
    ----------
    text : str
        Comma-separated ``name=value`` of fittable parameters, in their units.
    model : str
        Model whose parameters may be named.
    part : {'brake', 'coupler'}

    Returns
    -------
    dict of str to float
        Field name -> value.

    Raises
    ------
    InputError
        Not of that form, or an unknown parameter.
    """
    known = _known(model, part)
    by_field = {p.field: p for p in known.values()}
    out = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, sep, value = item.partition("=")
        p = known.get(name.strip()) or by_field.get(name.strip())
        if not sep or p is None:
            raise InputError("command line", "--set", f"expected name=value with a parameter "
                             f"of {', '.join(known)}, got {item!r}")
        try:
            out[p.field] = float(value)
        except ValueError:
            raise InputError("command line", "--set", f"{item!r}: the value must be a number "
                             f"in {p.unit}") from None
        if not math.isfinite(out[p.field]):
            raise InputError("command line", "--set", f"{item!r}: the value must be finite")
    return out


def _field_comment(params: BrakeParams, name: str) -> str:
    """Meaning and unit of a parameter field, as its model declares them."""
    for part in (params.pneumatic, params.friction, params.thermal):
        declared = specs(type(part))
        if name in declared:
            return declared[name].doc
    raise KeyError(name)


def parse_fit(text: str | Sequence[str], model: str = brakes.DEFAULT_MODEL, *,
              part: str = "brake") -> list[FitParameter]:
    """Parse the parameters to fit.

    Parameters
    ----------
    text : str or sequence of str
        Comma-separated names, short (``t_app``) or field names (``t_app_s``).
    model : str, optional
        Brake model (or coupler model, ``part`` coupler) whose parameters may be named
        (default: the paper's brake model).
    part : {'brake', 'coupler'}, optional

    Returns
    -------
    list of FitParameter
        In the order given, without duplicates.

    Raises
    ------
    InputError
        An unknown name, or none at all.
    """
    names = text.split(",") if isinstance(text, str) else list(text)
    known = _known(model, part)
    by_field = {p.field: p for p in known.values()}
    out: list[FitParameter] = []
    for raw in names:
        name = raw.strip()
        if not name:
            continue
        p = known.get(name) or by_field.get(name)
        if p is None:
            raise InputError("command line", "--fit", f"unknown parameter {name!r}; choose from "
                             f"{', '.join(known)}")
        if p not in out:
            out.append(p)
    if not out:
        raise InputError("command line", "--fit", "give at least one parameter to fit, e.g. "
                         + ",".join(known))
    return out

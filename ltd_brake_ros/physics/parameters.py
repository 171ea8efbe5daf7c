"""Model parameters: frozen dataclass fields that carry their meaning, units and valid range.

Every model's ``Params`` declares its fields with :func:`parameter`; the input layer builds them
from a mapping (a YAML file, ROS parameters) with its shared field checks, reading the range and
the file spelling from here, so a new model needs no change in the loaders.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

#: Marks a parameter without a default (the file must give it).
REQUIRED = dataclasses.MISSING


class CompileError(ValueError):
    """A model cannot be compiled from these inputs: a precondition does not hold.

    Parameters
    ----------
    field : str
        Path of the offending input as a file spells it, e.g. ``vehicles[3].brake`` or
        ``loading_kN[4]``.
    reason : str
        What is wrong.
    """

    def __init__(self, field: str, reason: str):
        self.field, self.reason = field, reason
        super().__init__(f"{field}: {reason}")


class Fittable(NamedTuple):
    """A parameter that calibration may fit.

    Attributes
    ----------
    field : str
        Field of the model's ``Params``.
    unit : str
        Unit of the value (``-`` for none).
    lower, upper : float
        Physical bounds of the fit.
    scale : float
        Typical magnitude: the fit works in ``value / scale``.
    meaning : str
        One line for help texts.
    """

    field: str
    unit: str
    lower: float
    upper: float
    scale: float
    meaning: str


class Spec(NamedTuple):
    """How a parameter is read from a file (see :func:`parameter`)."""

    doc: str
    lo: float | None
    hi: float | None
    lo_open: bool
    key: str | None
    scale: float
    sequence: bool = False


def parameter(default: Any, doc: str, *, lo: float | None = None, hi: float | None = None,
              lo_open: bool = False, key: str | None = None, scale: float = 1.0,
              sequence: bool = False) -> Any:
    """A ``Params`` dataclass field with its meaning and accepted range.

    Parameters
    ----------
    default : float, bool or REQUIRED
        Value when the file does not give one; :data:`REQUIRED`: the file must.
    doc : str
        Meaning with the unit in brackets, e.g. ``"filling time (Eq. 7) [s]"``.
    lo, hi : float, optional
        Accepted range of the value as written in the file.
    lo_open : bool, optional
        ``lo`` itself is excluded.
    key : str, optional
        Name in the file when it differs from the field (another unit), e.g.
        ``stiffness_kN_per_mm`` for the field ``stiffness_N_m``.
    scale : float, optional
        Field value = file value * scale.
    sequence : bool, optional
        The value is a tuple of numbers (a table column); ``lo`` and ``hi`` bound each.

    Returns
    -------
    dataclasses.Field
    """
    meta = {"spec": Spec(doc, lo, hi, lo_open, key, float(scale), bool(sequence))}
    if default is REQUIRED:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def specs(params_type) -> dict[str, Spec]:
    """Field name -> :class:`Spec` of a ``Params`` dataclass, in declaration order.

    Parameters
    ----------
    params_type : type
        A dataclass whose fields were declared with :func:`parameter`.

    Returns
    -------
    dict of str to Spec
    """
    return {f.name: f.metadata["spec"] for f in dataclasses.fields(params_type)
            if "spec" in f.metadata}


def file_key(params_type, name: str) -> str:
    """Name of field ``name`` in a file."""
    return specs(params_type)[name].key or name


def out_of_range(value: float, lo: float | None, hi: float | None, lo_open: bool = False,
                 scale: float = 1.0) -> str | None:
    """Why a value is outside its accepted range, or None when it is inside.

    Parameters
    ----------
    value : float
        The value in the model's unit (file value * ``scale``).
    lo, hi, lo_open
        Accepted range in the file's unit, as declared with :func:`parameter`.
    scale : float, optional
        Model unit per file unit (> 0); the comparison is made in the model's unit, the message
        speaks the file's.

    Returns
    -------
    str or None
    """
    if not math.isfinite(value):
        return f"must be finite, got {value}"
    if lo is not None and (value < lo * scale or (lo_open and value == lo * scale)):
        return f"must be {'>' if lo_open else '>='} {lo:g}, got {value / scale:g}"
    if hi is not None and value > hi * scale:
        return f"must be <= {hi:g}, got {value / scale:g}"
    return None


def check(params) -> None:
    """Check every declared field of a model's ``Params`` against its declaration.

    Numbers must be finite (or equal their default, e.g. an unknown strength of inf, or a
    value not given, NaN, where that is the default) and
    within the declared range; sequences must hold finite numbers within it; flags must be
    true or false.

    Parameters
    ----------
    params : dataclass
        A model's ``Params``.

    Raises
    ------
    CompileError
        For the first field that fails, named as a file spells it.
    """
    defaults = {f.name: f.default for f in dataclasses.fields(params)}
    for name, spec in specs(type(params)).items():
        value, key, default = getattr(params, name), spec.key or name, defaults[name]
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise CompileError(key, f"must be true or false, got {value!r}")
            continue
        if not spec.sequence:
            items = [(None, value)]
        elif isinstance(value, (tuple, list)):
            items = list(enumerate(value))
        else:
            raise CompileError(key, f"must be a list of numbers, got {value!r}")
        for i, item in items:
            where = key if i is None else f"{key}[{i}]"
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise CompileError(where, f"must be a number, got {item!r}")
            if i is None and (item == default or (math.isnan(item) and isinstance(default, float)
                                                   and math.isnan(default))):
                continue
            reason = out_of_range(float(item), spec.lo, spec.hi, spec.lo_open, spec.scale)
            if reason:
                raise CompileError(where, reason)


def model_of(models: dict, params) -> Any:
    """The model module of a family whose ``Params`` type ``params`` is.

    Parameters
    ----------
    models : dict of str to module
        A family's registry.
    params : dataclass
        A model's ``Params``.

    Returns
    -------
    module

    Raises
    ------
    TypeError
        ``params`` belongs to no registered model.
    """
    for module in models.values():
        if type(params) is module.Params:
            return module
    raise TypeError(f"{type(params).__name__} is not the Params of a registered model "
                    f"({', '.join(models)})")

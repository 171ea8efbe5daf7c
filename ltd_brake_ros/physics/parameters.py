"""Model parameters: frozen dataclass fields that carry their meaning, units and valid range.

Every model's ``Params`` declares its fields with :func:`parameter`; the input layer builds them
from a mapping (a YAML file, ROS parameters) with its shared field checks, reading the range and
the file spelling from here, so a new model needs no change in the loaders.
"""
from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

#: Marks a parameter without a default (the file must give it).
REQUIRED = dataclasses.MISSING


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


def parameter(default: Any, doc: str, *, lo: float | None = None, hi: float | None = None,
              lo_open: bool = False, key: str | None = None, scale: float = 1.0) -> Any:
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

    Returns
    -------
    dataclasses.Field
    """
    meta = {"spec": Spec(doc, lo, hi, lo_open, key, float(scale))}
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

"""Model-form band files: which brake and coupler models a band runs, with their sources."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .brake_params import load_brake_params
from .couplers import load_coupler_lut
from .schema import Fields, InputError, kind_of, load_once, resolve_config_path

__all__ = ["BandMember", "ModelFormBand", "load_band"]

#: The shipped band (:func:`load_band`'s default).
DEFAULT_BAND = "bands/model_form.yaml"


@dataclass(frozen=True)
class BandMember:
    """One model of a family in a band.

    Attributes
    ----------
    name : str
        How outputs name it.
    params : BrakeParams or a coupler model's Params
        Its parameters, loaded and checked.
    source : str
        Where its values come from.
    """

    name: str
    params: Any
    source: str


@dataclass(frozen=True)
class ModelFormBand:
    """The models a model-form band crosses: every brake model with every coupler model.

    Attributes
    ----------
    name : str
    brake : tuple of BandMember
        Brake models (:class:`~ltd_brake_ros.inputs.BrakeParams` each).
    coupler : tuple of BandMember
        Coupler models.
    source : str
        The file.
    """

    name: str
    brake: tuple
    coupler: tuple
    source: str

    @property
    def size(self) -> int:
        """Members of the band (brake models x coupler models)."""
        return len(self.brake) * len(self.coupler)


def load_band(path: str | os.PathLike | None = None) -> ModelFormBand:
    """Load a model-form band file (default: the shipped ``bands/model_form.yaml``).

    The file holds ``name`` and two lists, ``brake`` and ``coupler``, of ``{name, file,
    source}``: a brake-parameter file and a coupler file each, their names distinct within a
    list.

    Parameters
    ----------
    path : str or path-like, optional
        The file; relative names are also looked up in the shipped config directory.

    Returns
    -------
    ModelFormBand

    Raises
    ------
    InputError
        Naming the file, the field and the reason (a member's file: that file's error).
    """
    return load_once(resolve_config_path(path or DEFAULT_BAND), _band)


def _band(data: Any, source: str) -> ModelFormBand:
    f = Fields(data, source)
    f.reject_unknown({"name", "description", "brake", "coupler"})
    base = Path(source).parent
    families = {}
    for family, load in (("brake", load_brake_params), ("coupler", load_coupler_lut)):
        entries = f.data.get(family)
        if not isinstance(entries, list) or not entries:
            raise f.error(family, f"missing or not a non-empty list of {{name, file, source}}, "
                          f"got {kind_of(entries)}")
        members = []
        for i, entry in enumerate(entries):
            e = Fields(entry, source, f"{family}[{i}]")
            e.reject_unknown({"name", "file", "source"})
            path = resolve_config_path(e.string("file"), base)
            members.append(BandMember(e.string("name"), load(path),
                                      e.string("source", "not given")))
        names = [m.name for m in members]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise InputError(source, f"{family}[{i}].name", f"{name!r} is used twice; give "
                                 "each member a distinct name")
        families[family] = tuple(members)
    return ModelFormBand(f.string("name", "model-form band"), families["brake"],
                         families["coupler"], str(source))

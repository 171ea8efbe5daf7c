"""What every input file shares: errors, where files are found, YAML parsing, field checks.

Every file is validated once, at load, into immutable dataclasses whose field names carry their
units. Bad input raises :class:`InputError` naming the file, the field path and the reason.
"""
from __future__ import annotations

import dataclasses
import math
import os
import sys
from pathlib import Path
from typing import Any, Mapping

import yaml


class InputError(ValueError):
    """A bad input file or value.

    Parameters
    ----------
    source : str
        File (or topic / parameter) the value came from.
    field : str
        Path of the offending field, e.g. ``vehicles[3].mass_t``; empty for the whole file.
    reason : str
        What is wrong, in words a user can act on.
    """

    def __init__(self, source: str, field: str, reason: str):
        self.source, self.field, self.reason = str(source), field, reason
        where = f"{self.source}: {field}" if field else self.source
        super().__init__(f"{where}: {reason}")


# --------------------------------------------------------------------------- config location


def config_dir() -> Path:
    """Directory of the shipped configuration files.

    Returns
    -------
    pathlib.Path
        The first of: ``$LTD_BRAKE_CONFIG``, the source checkout's ``config/``, the installed
        ``share/ltd_brake_ros/config`` (pip or colcon prefix).
    """
    candidates = []
    if os.environ.get("LTD_BRAKE_CONFIG"):
        candidates.append(Path(os.environ["LTD_BRAKE_CONFIG"]))
    candidates.append(Path(__file__).resolve().parents[2] / "config")
    candidates.append(Path(sys.prefix) / "share" / "ltd_brake_ros" / "config")
    for path in candidates:
        if (path / "scenarios.yaml").is_file():
            return path
    try:  # colcon / ROS install space
        from ament_index_python.packages import get_package_share_directory

        path = Path(get_package_share_directory("ltd_brake_ros")) / "config"
        if path.is_dir():
            return path
    except Exception:  # noqa: BLE001 - ament index absent or package not registered
        pass
    raise InputError("config", "", "cannot find the shipped config/ directory; set LTD_BRAKE_CONFIG")


def resolve_config_path(path: str | os.PathLike, base: Path | None = None) -> Path:
    """Resolve a file name against the working directory, ``base`` and the shipped config.

    Parameters
    ----------
    path : str or path-like
        Absolute path, path relative to the working directory or to ``base``, or a path
        relative to the shipped ``config/`` directory (e.g. ``couplers/buffer_hook_pugi.yaml``).
    base : pathlib.Path, optional
        Directory of the file that refers to ``path``.

    Returns
    -------
    pathlib.Path
        An existing file; if none exists, ``path`` unchanged so that loading names it.
    """
    p = Path(path).expanduser()
    if p.is_absolute():
        return p
    for root in ([base] if base else []) + [Path.cwd(), config_dir()]:
        if (root / p).is_file():
            return root / p
    return p


def load_yaml(path: str | os.PathLike) -> Any:
    """Parse a YAML file, turning every I/O or syntax problem into :class:`InputError`.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    object
        The parsed document.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(p, "", "file does not exist")
    if not p.is_file():
        raise InputError(p, "", "is not a regular file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(p, "", f"cannot read: {exc}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(p, "", f"not valid YAML{where}: {problem}") from None


# --------------------------------------------------------------------------- field readers


class Fields:
    """Typed access to a mapping, raising :class:`InputError` with the field path.

    Parameters
    ----------
    data : mapping
        The values.
    source : str
        File (or topic) they came from.
    path : str, optional
        Path of the mapping inside the file, e.g. ``vehicles[3]``.
    """

    def __init__(self, data: Any, source: str, path: str = ""):
        if data is None and not path:
            raise InputError(source, "", "is empty")
        if not isinstance(data, Mapping):
            raise InputError(source, path, f"must be a mapping, got {kind_of(data)}")
        self.data, self.source, self.path = data, source, path

    def sub(self, name: str) -> str:
        """Path of field ``name``."""
        return f"{self.path}.{name}" if self.path else name

    def error(self, name: str, reason: str) -> InputError:
        """The error for field ``name``."""
        return InputError(self.source, self.sub(name), reason)

    def has(self, name: str) -> bool:
        """Field ``name`` is given (and not null)."""
        return name in self.data and self.data[name] is not None

    def number(self, name: str, default: float | None = None, *, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False) -> float:
        """A finite number within [lo, hi] (``lo`` excluded with ``lo_open``)."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required number)")
            return float(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(name, f"must be a number, got {kind_of(value)} {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(name, f"must be finite, got {value}")
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise self.error(name, f"must be {'>' if lo_open else '>='} {lo:g}, got {value:g}")
        if hi is not None and value > hi:
            raise self.error(name, f"must be <= {hi:g}, got {value:g}")
        return value

    def integer(self, name: str, default: int | None = None, *, lo: int = 0,
                hi: int | None = None) -> int:
        """A whole number within [lo, hi]."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required whole number)")
            return int(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"must be a whole number, got {kind_of(value)} {value!r}")
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f">= {lo}"
            raise self.error(name, f"must be {bound}, got {value}")
        return value

    def boolean(self, name: str, default: bool) -> bool:
        """true or false."""
        if not self.has(name):
            return default
        value = self.data[name]
        if not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {kind_of(value)} {value!r}")
        return value

    def string(self, name: str, default: str | None = None,
               choices: tuple[str, ...] | None = None) -> str:
        """Text, one of ``choices`` when given."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required text)")
            return default
        value = self.data[name]
        if not isinstance(value, str):
            raise self.error(name, f"must be text, got {kind_of(value)} {value!r}")
        if choices and value not in choices:
            raise self.error(name, f"unknown value {value!r}; expected one of {', '.join(choices)}")
        return value

    def numbers(self, name: str) -> list[float]:
        """A list of finite numbers."""
        if not self.has(name):
            raise self.error(name, "missing (required list of numbers)")
        values = self.data[name]
        if not isinstance(values, list):
            raise self.error(name, f"must be a list of numbers, got {kind_of(values)}")
        out = []
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(self.source, f"{self.sub(name)}[{i}]",
                                 f"must be a finite number, got {v!r}")
            out.append(float(v))
        return out

    def reject_unknown(self, allowed: set[str]) -> None:
        """Raise for the first field not in ``allowed``."""
        for key in self.data:
            if key not in allowed:
                raise self.error(str(key), f"unknown field; expected one of {', '.join(sorted(allowed))}")


def kind_of(value: Any) -> str:
    """How a value reads in an error message ("text", "a list", ...)."""
    return {type(None): "nothing", bool: "true/false", str: "text", list: "a list",
            dict: "a mapping"}.get(type(value), type(value).__name__)


def params_from_fields(params_type, f: Fields, **fixed):
    """Build a model's ``Params`` from the fields it declares.

    Each field declared with :func:`~ltd_brake_ros.physics.parameters.parameter` is read under
    its file name, checked against its range and scaled to the field's unit; missing fields take
    their defaults.

    Parameters
    ----------
    params_type : type
        A model's ``Params`` dataclass.
    f : Fields
        The mapping to read.
    **fixed
        Values of fields that do not come from the mapping (e.g. ``source``).

    Returns
    -------
    params_type
    """
    from ..physics.parameters import specs

    values = {}
    for name, spec in specs(params_type).items():
        key = spec.key or name
        default = params_type.__dataclass_fields__[name].default
        if isinstance(default, bool):
            values[name] = f.boolean(key, default)
            continue
        if default is dataclasses.MISSING:
            default = None
        elif spec.scale != 1.0:
            default = default / spec.scale
        values[name] = spec.scale * f.number(key, default, lo=spec.lo, hi=spec.hi,
                                             lo_open=spec.lo_open)
    return params_type(**values, **fixed)


def file_keys(params_type) -> set[str]:
    """Names a file may use for the fields of a model's ``Params``."""
    from ..physics.parameters import specs

    return {spec.key or name for name, spec in specs(params_type).items()}

"""Input files: consist, coupler look-up table and brake parameters.

Every file is validated once, at load, into immutable dataclasses whose field names carry their
units. Bad input raises :class:`InputError` naming the file, the field path and the reason.
"""
from __future__ import annotations

import dataclasses
import math
import os
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Mapping

import yaml

from ..physics.brakes import BrakeParams  # noqa: F401 (part of this module's interface)
from ..physics.couplers.lut_hysteresis import Params as CouplerLUT
from .commands import COMMAND_RANGES

#: Largest consist accepted [vehicles]; far above any real train, it guards memory and time.
MAX_VEHICLES = 5000


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


class _Fields:
    """Typed access to a mapping, raising InputError with the field path."""

    def __init__(self, data: Any, source: str, path: str = ""):
        if data is None and not path:
            raise InputError(source, "", "is empty")
        if not isinstance(data, Mapping):
            raise InputError(source, path, f"must be a mapping, got {_kind(data)}")
        self.data, self.source, self.path = data, source, path

    def sub(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def error(self, name: str, reason: str) -> InputError:
        return InputError(self.source, self.sub(name), reason)

    def has(self, name: str) -> bool:
        return name in self.data and self.data[name] is not None

    def number(self, name: str, default: float | None = None, *, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False) -> float:
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required number)")
            return float(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(name, f"must be a number, got {_kind(value)} {value!r}")
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
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required whole number)")
            return int(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"must be a whole number, got {_kind(value)} {value!r}")
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f">= {lo}"
            raise self.error(name, f"must be {bound}, got {value}")
        return value

    def boolean(self, name: str, default: bool) -> bool:
        if not self.has(name):
            return default
        value = self.data[name]
        if not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {_kind(value)} {value!r}")
        return value

    def string(self, name: str, default: str | None = None,
               choices: tuple[str, ...] | None = None) -> str:
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required text)")
            return default
        value = self.data[name]
        if not isinstance(value, str):
            raise self.error(name, f"must be text, got {_kind(value)} {value!r}")
        if choices and value not in choices:
            raise self.error(name, f"unknown value {value!r}; expected one of {', '.join(choices)}")
        return value

    def numbers(self, name: str) -> list[float]:
        if not self.has(name):
            raise self.error(name, "missing (required list of numbers)")
        values = self.data[name]
        if not isinstance(values, list):
            raise self.error(name, f"must be a list of numbers, got {_kind(values)}")
        out = []
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(self.source, f"{self.sub(name)}[{i}]",
                                 f"must be a finite number, got {v!r}")
            out.append(float(v))
        return out

    def reject_unknown(self, allowed: set[str]) -> None:
        for key in self.data:
            if key not in allowed:
                raise self.error(str(key), f"unknown field; expected one of {', '.join(sorted(allowed))}")


def _kind(value: Any) -> str:
    return {type(None): "nothing", bool: "true/false", str: "text", list: "a list",
            dict: "a mapping"}.get(type(value), type(value).__name__)


# --------------------------------------------------------------------------- brake parameters


def _params_from_fields(params_type, f: "_Fields"):
    """Build a model's ``Params`` from the fields it declares (ranges and file names there)."""
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
    return params_type(**values)


def _file_keys(params_type) -> set[str]:
    from ..physics.parameters import specs

    return {spec.key or name for name, spec in specs(params_type).items()}


def brake_params_from_mapping(data: Any, source: str) -> BrakeParams:
    """Validate brake parameters given as a mapping (a YAML document or ROS parameters).

    Parameters
    ----------
    data : mapping
        ``model`` (a registered brake model, default ``uic_empirical``) and the fields of that
        model's and the friction law's ``Params``; missing fields take their defaults.
    source : str
        Where the values came from, for error messages.

    Returns
    -------
    BrakeParams
    """
    from ..physics import brakes

    f = _Fields({} if data is None else data, source)
    name = f.string("model", brakes.DEFAULT_MODEL, choices=tuple(brakes.MODELS))
    model = brakes.MODELS[name]
    f.reject_unknown(_file_keys(model.Params) | _file_keys(brakes.friction.Params)
                     | {"model", "name", "description"})
    return BrakeParams(_params_from_fields(model.Params, f),
                       _params_from_fields(brakes.friction.Params, f), str(source))


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
    p = resolve_config_path(path or "brake_params/paper.yaml")
    return brake_params_from_mapping(load_yaml(p), str(p))


# --------------------------------------------------------------------------- coupler LUT


def load_coupler_lut(path: str | os.PathLike | None = None,
                     v_th_mm_s: float | None = None) -> CouplerLUT:
    """Load a coupler LUT YAML file (default: the shipped buffer-hook reconstruction).

    Parameters
    ----------
    path : str or path-like, optional
        File with ``deflection_mm``, ``loading_kN``, ``unloading_kN`` and optional ``v_th_mm_s``.
    v_th_mm_s : float, optional
        Overrides the file's Eq. 3 threshold speed [mm/s].

    Returns
    -------
    CouplerLUT
    """
    p = resolve_config_path(path or "couplers/buffer_hook_pugi.yaml")
    f = _Fields(load_yaml(p), str(p))
    f.reject_unknown({"name", "description", "deflection_mm", "loading_kN", "unloading_kN",
                      "v_th_mm_s"})
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
    return CouplerLUT(tuple(x * 1e-3 for x in d), tuple(x * 1e3 for x in fl),
                      tuple(x * 1e3 for x in fu), vth * 1e-3, str(p))


# --------------------------------------------------------------------------- consist


@dataclass(frozen=True)
class BlockBrake:
    """Tread brake with P10 cast-iron blocks (Eq. 4, 8, 9).

    Attributes
    ----------
    blocks : int
        Number of brake blocks on the vehicle.
    arrangement : str
        ``Bg`` (one block per wheel) or ``Bgu`` (two blocks per wheel).
    braked_weight_t : float
        Braked weight in P for the vehicle's mass (after any empty/loaded changeover) [t].
    braked_weight_G_t : float or None
        Braked weight in G [t]; ``None``: the same as in P.
    """

    blocks: int
    arrangement: str
    braked_weight_t: float
    braked_weight_G_t: float | None = None
    #: The ``type`` of a vehicle's brake in a consist file.
    type: ClassVar[str] = "blocks"


@dataclass(frozen=True)
class DiscBrake:
    """Disc brake with constant k and effective friction (Eq. 4 with k_loco, Eq. 10).

    Attributes
    ----------
    braked_weight_t : float
        Braked weight in P [t].
    k : float or None
        Constant k factor; ``None`` takes ``k_loco`` from the brake parameters.
    mu_eff : float or None
        Effective friction coefficient; ``None`` takes ``mu_eff`` from the brake parameters.
    braked_weight_G_t : float or None
        Braked weight in G [t]; ``None``: the same as in P.
    """

    braked_weight_t: float
    k: float | None = None
    mu_eff: float | None = None
    braked_weight_G_t: float | None = None
    #: The ``type`` of a vehicle's brake in a consist file.
    type: ClassVar[str] = "disc"


@dataclass(frozen=True)
class Traction:
    """Tractive-effort and dynamic-brake curves of a powered vehicle, F(v) = min(F_max, P/v).

    Attributes
    ----------
    max_force_N, max_power_W : float
        Traction limits [N], [W].
    brake_max_force_N, brake_max_power_W : float
        Dynamic-brake limits [N], [W] (0: no dynamic brake).
    rate_limit_N_s : float
        Largest change of the applied force per second [N/s].
    time_constant_s : float
        First-order lag between demand and applied force [s].
    fade_speed_m_s : float
        Below this speed the dynamic brake fades linearly to zero [m/s].
    """

    max_force_N: float
    max_power_W: float
    brake_max_force_N: float = 0.0
    brake_max_power_W: float = 0.0
    rate_limit_N_s: float = 50e3
    time_constant_s: float = 1.0
    fade_speed_m_s: float = 5.0 / 3.6


@dataclass(frozen=True)
class Vehicle:
    """One vehicle of the consist.

    Attributes
    ----------
    name : str
        Vehicle type name.
    mass_kg : float
        Weight on rails [kg].
    length_m : float
        Length over buffers [m].
    axles : int
        Number of axles.
    inertia_factor : float
        Rotating-mass factor rho of Eq. 1 [-].
    brake : BlockBrake, DiscBrake or None
        Air brake; ``None`` for an unbraked vehicle.
    brake_position : str
        ``P`` (passenger, the validated position) or ``G`` (goods).
    traction : Traction or None
        Traction and dynamic brake of a powered vehicle.
    """

    name: str
    mass_kg: float
    length_m: float
    axles: int
    inertia_factor: float
    brake: BlockBrake | DiscBrake | None
    brake_position: str = "P"
    traction: Traction | None = None

    @property
    def braked_weight_t(self) -> float:
        """Braked weight in the vehicle's brake position [t] (0 when unbraked).

        A vehicle set to G inside a train braked in P counts with its braked weight in G (the
        braked weight belongs to the position the brake is set to).
        """
        if self.brake is None:
            return 0.0
        if self.brake_position == "G" and self.brake.braked_weight_G_t is not None:
            return self.brake.braked_weight_G_t
        return self.brake.braked_weight_t


@dataclass(frozen=True)
class Consist:
    """A train, vehicles listed from the head.

    Attributes
    ----------
    name : str
        Human-readable name.
    vehicles : tuple of Vehicle
        Vehicle 0 is the head.
    source : str
        File the consist came from.
    """

    name: str
    vehicles: tuple[Vehicle, ...]
    source: str = ""

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return len(self.vehicles)

    @property
    def length_m(self) -> float:
        """Train length over buffers [m]."""
        return sum(v.length_m for v in self.vehicles)

    @property
    def mass_kg(self) -> float:
        """Total weight on rails [kg]."""
        return sum(v.mass_kg for v in self.vehicles)


_VEHICLE_FIELDS = {"type", "count", "description", "mass_t", "length_m", "axles",
                   "inertia_factor", "brake", "brake_position", "traction"}
_BRAKE_TYPES = ("blocks", "disc", "none")


def _parse_brake(data: Any, mass_t: float, source: str, path: str) -> BlockBrake | DiscBrake | None:
    f = _Fields(data, source, path)
    kind = f.string("type", choices=_BRAKE_TYPES)
    if kind == "none":
        f.reject_unknown({"type"})
        return None
    if kind == "disc":
        f.reject_unknown({"type", "braked_weight_t", "braked_weight_G_t", "k", "mu_eff"})
        b = f.number("braked_weight_t", lo=0.0, lo_open=True)
        _check_braked_weight(f, "braked_weight_t", b, mass_t)
        k = f.number("k", lo=0.0, lo_open=True) if f.has("k") else None
        mu = f.number("mu_eff", lo=0.0, lo_open=True, hi=1.0) if f.has("mu_eff") else None
        return DiscBrake(b, k, mu, _braked_weight_g(f, mass_t))
    f.reject_unknown({"type", "blocks", "arrangement", "braked_weight_t", "braked_weight_empty_t",
                      "braked_weight_loaded_t", "changeover_mass_t", "braked_weight_G_t"})
    blocks = f.integer("blocks", lo=1, hi=64)
    arrangement = f.string("arrangement", "Bg", choices=("Bg", "Bgu"))
    if f.has("braked_weight_t"):
        for other in ("braked_weight_empty_t", "braked_weight_loaded_t", "changeover_mass_t"):
            if f.has(other):
                raise f.error(other, "give either braked_weight_t or an empty/loaded device, not both")
        b = f.number("braked_weight_t", lo=0.0, lo_open=True)
        _check_braked_weight(f, "braked_weight_t", b, mass_t)
    else:
        if not (f.has("braked_weight_loaded_t") or f.has("braked_weight_empty_t")):
            raise f.error("braked_weight_t", "missing: give braked_weight_t, or "
                          "braked_weight_empty_t + braked_weight_loaded_t + changeover_mass_t")
        empty = f.number("braked_weight_empty_t", lo=0.0, lo_open=True)
        loaded = f.number("braked_weight_loaded_t", lo=0.0, lo_open=True)
        change = f.number("changeover_mass_t", lo=0.0, lo_open=True)
        if loaded < empty:
            raise f.error("braked_weight_loaded_t",
                          f"({loaded:g} t) is below braked_weight_empty_t ({empty:g} t)")
        name, b = ("braked_weight_loaded_t", loaded) if mass_t >= change else (
            "braked_weight_empty_t", empty)
        _check_braked_weight(f, name, b, mass_t)
    return BlockBrake(blocks, arrangement, b, _braked_weight_g(f, mass_t))


def _braked_weight_g(f: "_Fields", mass_t: float) -> float | None:
    if not f.has("braked_weight_G_t"):
        return None
    b = f.number("braked_weight_G_t", lo=0.0, lo_open=True)
    _check_braked_weight(f, "braked_weight_G_t", b, mass_t)
    return b


def _parse_traction(data: Any, source: str, path: str) -> Traction:
    f = _Fields(data, source, path)
    f.reject_unknown({"max_force_kN", "max_power_kW", "brake_max_force_kN", "brake_max_power_kW",
                      "rate_limit_kN_s", "time_constant_s", "fade_speed_kmh"})
    return Traction(
        max_force_N=1e3 * f.number("max_force_kN", lo=0.0, lo_open=True, hi=2000.0),
        max_power_W=1e3 * f.number("max_power_kW", lo=0.0, lo_open=True, hi=50000.0),
        brake_max_force_N=1e3 * f.number("brake_max_force_kN", 0.0, lo=0.0, hi=2000.0),
        brake_max_power_W=1e3 * f.number("brake_max_power_kW", 0.0, lo=0.0, hi=50000.0),
        rate_limit_N_s=1e3 * f.number("rate_limit_kN_s", 50.0, lo=0.0, lo_open=True, hi=1e5),
        time_constant_s=f.number("time_constant_s", 1.0, lo=0.0, lo_open=True, hi=60.0),
        fade_speed_m_s=f.number("fade_speed_kmh", 5.0, lo=0.0, lo_open=True, hi=100.0) / 3.6)


def _check_braked_weight(f: _Fields, name: str, b_t: float, mass_t: float) -> None:
    # Braked-weight percentages above 200 % do not exist on real vehicles (UIC 544-1 tables
    # stop well below); such a value is a unit or typing error.
    if b_t > 2.0 * mass_t:
        raise f.error(name, f"{b_t:g} t is more than twice the vehicle mass ({mass_t:g} t)")


def _vehicle_types(source: str, data: Any, path: str) -> dict[str, dict]:
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise InputError(source, path, f"must be a mapping of type name to fields, got {_kind(data)}")
    out = {}
    for name, fields in data.items():
        if not isinstance(fields, Mapping):
            raise InputError(source, f"{path}.{name}", f"must be a mapping, got {_kind(fields)}")
        out[str(name)] = dict(fields)
    return out


def consist_from_mapping(data: Any, source: str, base: Path | None = None) -> Consist:
    """Validate a consist document.

    Parameters
    ----------
    data : mapping
        ``name``, optional ``vehicle_types`` (merged over the shipped ``vehicles.yaml``) and
        ``vehicles``: a list from the head, each entry a ``type`` with optional ``count`` and
        field overrides, or a complete vehicle.
    source : str
        File name for error messages.
    base : pathlib.Path, optional
        Directory of the file.

    Returns
    -------
    Consist
    """
    top = _Fields(data, source)
    top.reject_unknown({"name", "description", "vehicle_types", "vehicles"})
    library = _vehicle_types(str(config_dir() / "vehicles.yaml"),
                             (load_yaml(config_dir() / "vehicles.yaml") or {}).get("vehicle_types"),
                             "vehicle_types")
    library.update(_vehicle_types(source, top.data.get("vehicle_types"), "vehicle_types"))
    entries = top.data.get("vehicles")
    if not isinstance(entries, list):
        raise top.error("vehicles", "missing or not a list of vehicles (head first)")
    if not entries:
        raise top.error("vehicles", "is empty: a train needs at least one vehicle")
    vehicles: list[Vehicle] = []
    for i, entry in enumerate(entries):
        path = f"vehicles[{i}]"
        f = _Fields(entry, source, path)
        f.reject_unknown(_VEHICLE_FIELDS)
        merged: dict[str, Any] = {}
        if f.has("type"):
            tname = f.string("type")
            if tname not in library:
                raise f.error("type", f"unknown vehicle type {tname!r}; known: "
                              f"{', '.join(sorted(library)) or 'none'}")
            merged.update(library[tname])
        merged.update({k: v for k, v in f.data.items() if k not in ("count", "type")})
        count = f.integer("count", 1, lo=1, hi=MAX_VEHICLES)
        if len(vehicles) + count > MAX_VEHICLES:
            raise f.error("count", f"the train would exceed {MAX_VEHICLES} vehicles")
        g = _Fields(merged, source, path)
        mass_t = g.number("mass_t", lo=0.0, lo_open=True, hi=500.0)
        length = g.number("length_m", lo=0.0, lo_open=True, hi=100.0)
        axles = g.integer("axles", lo=1, hi=32)
        rho = g.number("inertia_factor", 1.04, lo=1.0, hi=3.0)
        if not g.has("brake"):
            raise g.error("brake", "missing: give a brake (type blocks, disc or none)")
        brake = _parse_brake(g.data["brake"], mass_t, source, g.sub("brake"))
        position = g.string("brake_position", "P", choices=("P", "G"))
        traction = _parse_traction(g.data["traction"], source, g.sub("traction")) \
            if g.has("traction") else None
        name = str(f.data.get("type", f"vehicle {i}"))
        vehicles.extend([Vehicle(name, mass_t * 1e3, length, axles, rho, brake, position,
                                 traction)] * count)
    return Consist(str(top.data.get("name") or Path(source).stem), tuple(vehicles), str(source))


def load_consist(path: str | os.PathLike) -> Consist:
    """Load a consist YAML file.

    Parameters
    ----------
    path : str or path-like
        The file; relative names are also looked up in the shipped config directory.

    Returns
    -------
    Consist
    """
    p = resolve_config_path(path)
    return consist_from_mapping(load_yaml(p), str(p), p.parent)


def with_wagon_mass(consist: Consist, mass_t: float) -> Consist:
    """Return the consist with every block-braked vehicle's mass set to ``mass_t``.

    Parameters
    ----------
    consist : Consist
    mass_t : float
        New weight on rails of the wagons [t].

    Returns
    -------
    Consist
    """
    return replace(consist, vehicles=tuple(
        replace(v, mass_kg=mass_t * 1e3) if isinstance(v.brake, BlockBrake) else v
        for v in consist.vehicles))


# --------------------------------------------------------------------------- scenario catalogue


@dataclass(frozen=True)
class Scenario:
    """One run of the paper's Tables 1-2.

    Attributes
    ----------
    number : int
        Simulation number in the paper.
    consist_file : str
        Consist file (relative to the shipped config directory).
    speed_kmh : float
        Initial speed [km/h].
    paper : dict
        Reference values: ``lambda_percent``, ``uic_m`` (None at 50 km/h), ``pugi_m``,
        ``ltdpolito_m``, ``draft_kN``, ``draft_coupler``, ``buff_kN``, ``buff_coupler``.
    """

    number: int
    consist_file: str
    speed_kmh: float
    paper: dict = field(default_factory=dict)

    def consist(self) -> Consist:
        """Load the scenario's consist."""
        return load_consist(self.consist_file)


def load_scenarios() -> dict[int, Scenario]:
    """Load the shipped scenario catalogue (``config/scenarios.yaml``).

    Returns
    -------
    dict of int to Scenario
    """
    p = config_dir() / "scenarios.yaml"
    data = _Fields(load_yaml(p), str(p)).data.get("scenarios") or {}
    out = {}
    for key, row in data.items():
        f = _Fields(row, str(p), f"scenarios.{key}")
        paper = {k: v for k, v in row.items() if k not in ("consist", "speed_kmh")}
        out[int(key)] = Scenario(int(key), f.string("consist"), f.number("speed_kmh", lo=0.0), paper)
    return out


def get_scenario(name: str | int) -> Scenario:
    """Look up a scenario by number (``6``, ``"6"`` or ``"scenario_6"``).

    Parameters
    ----------
    name : str or int

    Returns
    -------
    Scenario
    """
    catalogue = load_scenarios()
    text = str(name).strip().lower().removeprefix("scenario").strip("_ -")
    if text.isdigit() and int(text) in catalogue:
        return catalogue[int(text)]
    raise InputError("scenario", "", f"unknown scenario {name!r}; known: "
                     f"{', '.join(str(k) for k in sorted(catalogue))}")


# --------------------------------------------------------------------------- track


@dataclass(frozen=True)
class Track:
    """Track profile: sections starting at given chainages.

    Attributes
    ----------
    chainage_m : tuple of float
        Start of each section, strictly increasing [m]; a section runs to the next start, the
        last to infinity; before the first start the first section applies.
    gradient_permille : tuple of float
        Gradient of each section, positive uphill in the direction of travel [per mille].
    radius_m : tuple of float
        Curve radius of each section, 0 on straight track [m].
    start_chainage_m : float
        Chainage of the head's front at t = 0 [m].
    source : str
        File the profile came from.
    """

    chainage_m: tuple[float, ...] = (0.0,)
    gradient_permille: tuple[float, ...] = (0.0,)
    radius_m: tuple[float, ...] = (0.0,)
    start_chainage_m: float = 0.0
    source: str = "level straight track"


#: Smallest curve radius accepted [m] (Roeckl's formula holds for main-line curves).
MIN_RADIUS_M = 100.0


def load_track(path: str | os.PathLike, start_chainage_m: float | None = None) -> Track:
    """Load a track profile from YAML or CSV.

    YAML: ``start_chainage_m`` (optional) and ``sections``, a list of mappings with
    ``from_m``, ``gradient_permille`` (default 0) and ``radius_m`` (default 0 = straight).
    CSV: a header ``chainage_m,gradient_permille,radius_m`` and one row per section.

    Parameters
    ----------
    path : str or path-like
    start_chainage_m : float, optional
        Overrides the file's start chainage of the head [m].

    Returns
    -------
    Track
    """
    p = resolve_config_path(path)
    rows: list[tuple[float, float, float]] = []
    start = 0.0
    if p.suffix.lower() == ".csv":
        import csv

        if not p.is_file():
            raise InputError(p, "", "file does not exist")
        with open(p, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            need = {"chainage_m", "gradient_permille"}
            if not reader.fieldnames or not need <= set(reader.fieldnames):
                raise InputError(p, "header", "needs columns chainage_m, gradient_permille "
                                 "and optionally radius_m")
            for i, row in enumerate(reader):
                f = _Fields({k: _csv_number(v) for k, v in row.items() if k}, str(p), f"row {i + 2}")
                rows.append((f.number("chainage_m"), f.number("gradient_permille", lo=-100, hi=100),
                             f.number("radius_m", 0.0, lo=0.0)))
    else:
        top = _Fields(load_yaml(p), str(p))
        top.reject_unknown({"name", "description", "start_chainage_m", "sections"})
        start = top.number("start_chainage_m", 0.0)
        sections = top.data.get("sections")
        if not isinstance(sections, list) or not sections:
            raise top.error("sections", "missing or empty: give a list of sections with from_m")
        for i, sec in enumerate(sections):
            f = _Fields(sec, str(p), f"sections[{i}]")
            f.reject_unknown({"from_m", "gradient_permille", "radius_m"})
            rows.append((f.number("from_m"), f.number("gradient_permille", 0.0, lo=-100, hi=100),
                         f.number("radius_m", 0.0, lo=0.0)))
    if not rows:
        raise InputError(p, "", "has no sections")
    for i, (ch, _g, r) in enumerate(rows):
        if i and not ch > rows[i - 1][0]:
            raise InputError(p, f"sections[{i}]", f"chainage {ch:g} m is not after {rows[i - 1][0]:g} m")
        if 0.0 < r < MIN_RADIUS_M:
            raise InputError(p, f"sections[{i}].radius_m",
                             f"{r:g} m is below {MIN_RADIUS_M:g} m (0 means straight)")
    if start_chainage_m is not None:
        start = float(start_chainage_m)
    return Track(tuple(r[0] for r in rows), tuple(r[1] for r in rows), tuple(r[2] for r in rows),
                 start, str(p))


def _csv_number(text: str | None) -> Any:
    if text is None or text.strip() == "":
        return None
    try:
        return float(text)
    except ValueError:
        return text


# --------------------------------------------------------------------------- command scripts


@dataclass(frozen=True)
class CommandScript:
    """Timed driver inputs for an offline run.

    Attributes
    ----------
    steps : tuple of (float, dict)
        (time [s], fields that change then: ``emergency`` bool, ``brake_demand`` 0-1,
        ``traction`` -1-1), sorted by time.
    duration_s : float or None
        Length of the run [s]; ``None``: until the train stops after a brake command.
    source : str
        File the script came from.
    """

    steps: tuple
    duration_s: float | None = None
    source: str = ""


def load_command_script(path: str | os.PathLike) -> CommandScript:
    """Load a command script YAML file.

    The file holds ``duration_s`` (optional) and ``commands``, a list of mappings with ``t_s``
    and any of ``emergency``, ``brake_demand``, ``traction``; each holds from its time on.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    CommandScript
    """
    p = resolve_config_path(path)
    top = _Fields(load_yaml(p), str(p))
    top.reject_unknown({"name", "description", "duration_s", "commands"})
    duration = top.number("duration_s", lo=0.0, lo_open=True, hi=1e6) if top.has("duration_s") else None
    entries = top.data.get("commands")
    if not isinstance(entries, list) or not entries:
        raise top.error("commands", "missing or empty: give a list of {t_s, ...} entries")
    steps = []
    for i, entry in enumerate(entries):
        f = _Fields(entry, str(p), f"commands[{i}]")
        f.reject_unknown({"t_s", "emergency", "brake_demand", "traction"})
        t = f.number("t_s", lo=0.0)
        if steps and t < steps[-1][0]:
            raise f.error("t_s", f"{t:g} s comes before the previous entry ({steps[-1][0]:g} s)")
        change: dict[str, Any] = {}
        if f.has("emergency"):
            if not isinstance(f.data["emergency"], bool):
                raise f.error("emergency", f"must be true or false, got {f.data['emergency']!r}")
            change["emergency"] = f.data["emergency"]
        if f.has("brake_demand"):
            lo, hi = COMMAND_RANGES["brake_demand"]
            change["brake_demand"] = f.number("brake_demand", lo=lo, hi=hi)
        if f.has("traction"):
            lo, hi = COMMAND_RANGES["traction"]
            change["traction"] = f.number("traction", lo=lo, hi=hi)
        steps.append((t, change))
    return CommandScript(tuple(steps), duration, str(p))

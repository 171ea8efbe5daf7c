"""Consist files: the train, vehicle by vehicle from the head, with the shipped vehicle types."""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, ClassVar, Mapping

from .schema import (Fields, InputError, built_once, config_dir, kind_of, read_input,
                     resolve_config_path)

#: Largest consist accepted [vehicles]; far above any real train, it guards memory and time.
MAX_VEHICLES = 5000


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
class VehicleLimits:
    """Limits the verdicts on a run hold a vehicle to; ``None``: not given here (the coupler
    model's, else the standard default of :mod:`ltd_brake_ros.verdicts`).

    Attributes
    ----------
    draft_strength_N : float or None
        Breaking load of its draw gear (draw hook, screw coupling) [N].
    buff_strength_N : float or None
        Compressive strength of its buffers and end structure, magnitude [N].
    endurable_lcf_N : float or None
        Endurable longitudinal compressive force: the buff force it runs safely under
        (EN 15839, from the UIC 530-2 tests), magnitude [N].
    adhesion_limit : float or None
        Limit of its mean utilised adhesion over a stop, mean brake force at the rails /
        weight [-] (None: the default of :mod:`ltd_brake_ros.verdicts`, by
        ``wheel_slide_protection``).
    wheel_slide_protection : bool
        It has wheel-slide protection (EN 15595): the default mean-adhesion limit is then
        0.15 instead of 0.12.
    """

    draft_strength_N: float | None = None
    buff_strength_N: float | None = None
    endurable_lcf_N: float | None = None
    adhesion_limit: float | None = None
    wheel_slide_protection: bool = False


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
        Traction and dynamic brake of a powered vehicle (a locomotive).
    limits : VehicleLimits
        Strength and adhesion limits of the vehicle for the verdicts on a run.
    max_speed_kmh : float or None
        Its declared maximum speed [km/h]: the speed of the adhesion design check's stop
        (None: not declared, :data:`~ltd_brake_ros.verdicts.DEFAULT_MAX_SPEED_KMH` assumed).
    """

    name: str
    mass_kg: float
    length_m: float
    axles: int
    inertia_factor: float
    brake: BlockBrake | DiscBrake | None
    brake_position: str = "P"
    traction: Traction | None = None
    limits: VehicleLimits = VehicleLimits()
    max_speed_kmh: float | None = None

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
    venting : int or None
        Index of the vehicle whose driver's brake valve vents the brake pipe, as the file
        names it (``venting_vehicle``); ``None``: the leading locomotive (see
        :attr:`venting_vehicle`).

    Examples
    --------
    >>> from ltd_brake_ros import load_consist
    >>> train = load_consist("scenario_6")
    >>> train.n, round(train.length_m, 1), train.vehicles[1].brake_position
    (33, 423.9, 'P')
    """

    name: str
    vehicles: tuple[Vehicle, ...]
    source: str = ""
    venting: int | None = None

    @property
    def venting_vehicle(self) -> int:
        """Index of the vehicle that vents the brake pipe (Eq. 6's delays count from it).

        The one the file names, else the leading locomotive: the first vehicle with traction
        (the driver's brake valve is in the driving cab), else vehicle 0.
        """
        if self.venting is not None:
            return self.venting
        return next((i for i, v in enumerate(self.vehicles) if v.traction is not None), 0)

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return len(self.vehicles)

    # summed once per consist (it is immutable)
    @functools.cached_property
    def length_m(self) -> float:
        """Train length over buffers [m]."""
        return sum(v.length_m for v in self.vehicles)

    @functools.cached_property
    def mass_kg(self) -> float:
        """Total weight on rails [kg]."""
        return sum(v.mass_kg for v in self.vehicles)

    def _groups(self) -> list:
        from .._display import groups

        return groups(self.vehicles)

    def __repr__(self) -> str:
        parts = [f"{k} x {v.name}" if k > 1 else v.name for v, k in self._groups()]
        shown = " + ".join(parts[:6]) + (f" + ... ({len(parts) - 6} more groups)"
                                         if len(parts) > 6 else "")
        return (f"Consist({self.name!r}: {self.n} vehicles, {self.length_m:.1f} m, "
                f"{self.mass_kg / 1e3:.0f} t: {shown})")

    def _repr_html_(self) -> str:
        from .._display import html_table, number

        rows = [(k, v.name, number(v.mass_kg / 1e3, ".1f"), v.axles,
                 number(v.mass_kg / 1e3 / v.axles, ".2f"), v.brake_position,
                 "none" if v.brake is None else v.brake.type,
                 number(v.braked_weight_t, ".1f"))
                for v, k in self._groups()[:30]]
        return html_table(f"Consist {self.name}: {self.n} vehicles, {self.length_m:.1f} m, "
                          f"{self.mass_kg / 1e3:.0f} t (head first)", rows,
                          ["count", "type", "mass [t]", "axles", "axle load [t]",
                           "brake position", "brake", "braked weight [t]"])


_VEHICLE_FIELDS = {"type", "count", "description", "mass_t", "length_m", "axles",
                   "inertia_factor", "brake", "brake_position", "traction", "limits",
                   "max_speed_kmh"}
_BRAKE_TYPES = ("blocks", "disc", "none")


def _parse_brake(data: Any, mass_t: float, source: str, path: str) -> BlockBrake | DiscBrake | None:
    f = Fields(data, source, path)
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


def _braked_weight_g(f: Fields, mass_t: float) -> float | None:
    if not f.has("braked_weight_G_t"):
        return None
    b = f.number("braked_weight_G_t", lo=0.0, lo_open=True)
    _check_braked_weight(f, "braked_weight_G_t", b, mass_t)
    return b


def _parse_traction(data: Any, source: str, path: str) -> Traction:
    f = Fields(data, source, path)
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


def _parse_limits(data: Any, source: str, path: str, base: VehicleLimits) -> VehicleLimits:
    """Limits given in a ``limits`` mapping, the others from ``base``."""
    f = Fields(data, source, path)
    f.reject_unknown({"draft_strength_kN", "buff_strength_kN", "endurable_lcf_kN",
                      "adhesion_limit", "wheel_slide_protection"})
    # forces up to 20 000 kN, ten times a wagon body's proof load (as the coupler tables)
    values = {name: 1e3 * f.number(key, lo=0.0, lo_open=True, hi=20000.0)
              for name, key in (("draft_strength_N", "draft_strength_kN"),
                                ("buff_strength_N", "buff_strength_kN"),
                                ("endurable_lcf_N", "endurable_lcf_kN")) if f.has(key)}
    if f.has("adhesion_limit"):
        values["adhesion_limit"] = f.number("adhesion_limit", lo=0.0, lo_open=True, hi=1.0)
    if f.has("wheel_slide_protection"):
        values["wheel_slide_protection"] = f.boolean("wheel_slide_protection", False)
    out = replace(base, **values)
    if None not in (out.endurable_lcf_N, out.draft_strength_N) and \
            out.endurable_lcf_N > out.draft_strength_N:
        key = "endurable_lcf_kN" if f.has("endurable_lcf_kN") else "draft_strength_kN"
        raise f.error(key, f"the endurable fatigue load ({out.endurable_lcf_N / 1e3:g} kN) "
                      f"exceeds the draft strength ({out.draft_strength_N / 1e3:g} kN): "
                      "endurable_lcf_kN must not exceed draft_strength_kN")
    return out


def _check_braked_weight(f: Fields, name: str, b_t: float, mass_t: float) -> None:
    # Braked-weight percentages above 200 % do not exist on real vehicles (UIC 544-1 tables
    # stop well below); such a value is a unit or typing error.
    if b_t > 2.0 * mass_t:
        raise f.error(name, f"{b_t:g} t is more than twice the vehicle mass ({mass_t:g} t)")


def _vehicle_types(source: str, data: Any, path: str) -> dict[str, dict]:
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise InputError(source, path, f"must be a mapping of type name to fields, got {kind_of(data)}")
    out = {}
    for name, fields in data.items():
        if not isinstance(fields, Mapping):
            raise InputError(source, f"{path}.{name}", f"must be a mapping, got {kind_of(fields)}")
        out[str(name)] = dict(fields)
    return out


def _shipped_library() -> tuple[str, bytes]:
    """The shipped vehicle library ``vehicles.yaml``: its name and contents."""
    shipped = os.path.join(config_dir(), "vehicles.yaml")
    return shipped, read_input(shipped)


def _library_types(data: Any, source: str) -> dict[str, dict]:
    """The vehicle types of a vehicle library holding ``data``."""
    return _vehicle_types(source, (data or {}).get("vehicle_types"), "vehicle_types")


def consist_from_mapping(data: Any, source: str, base: Path | None = None) -> Consist:
    """Validate a consist document.

    Parameters
    ----------
    data : mapping
        ``name``, optional ``vehicle_types`` (merged over the shipped ``vehicles.yaml``),
        ``vehicles``: a list from the head, each entry a ``type`` with optional ``count`` and
        field overrides, or a complete vehicle; optional ``venting_vehicle`` (index of the
        vehicle that vents the brake pipe; default the leading locomotive) and ``limits``
        (the verdicts' limits of every vehicle that does not give its own).
    source : str
        File name for error messages.
    base : pathlib.Path, optional
        Directory of the file.

    Returns
    -------
    Consist
    """
    # the shipped library parsed once per version of the file (a campaign builds thousands
    # of trains from it); copied before merging
    return _consist(data, source, built_once(_library_types, *_shipped_library()))


def _consist(data: Any, source: str, shipped: dict[str, dict]) -> Consist:
    """:func:`consist_from_mapping` with the shipped vehicle types ``shipped``."""
    top = Fields(data, source)
    top.reject_unknown({"name", "description", "vehicle_types", "vehicles", "venting_vehicle",
                        "limits"})
    train_limits = _parse_limits(top.data["limits"], source, "limits", VehicleLimits()) \
        if top.has("limits") else VehicleLimits()
    train_name = top.string("name", "") or Path(source).stem
    library = dict(shipped)
    library.update(_vehicle_types(source, top.data.get("vehicle_types"), "vehicle_types"))
    entries = top.data.get("vehicles")
    if not isinstance(entries, list):
        raise top.error("vehicles", "missing or not a list of vehicles (head first)")
    if not entries:
        raise top.error("vehicles", "is empty: a train needs at least one vehicle")
    vehicles: list[Vehicle] = []
    for i, entry in enumerate(entries):
        path = f"vehicles[{i}]"
        f = Fields(entry, source, path)
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
        g = Fields(merged, source, path)
        mass_t = g.number("mass_t", lo=0.0, lo_open=True, hi=500.0)
        length = g.number("length_m", lo=0.0, lo_open=True, hi=100.0)
        axles = g.integer("axles", lo=1, hi=32)
        rho = g.number("inertia_factor", 1.04, lo=1.0, hi=3.0)
        if not g.has("brake"):
            raise g.error("brake", "missing: give a brake (type blocks, disc or none)")
        brake = _parse_brake(g.data["brake"], mass_t, source, g.sub("brake"))
        position = g.string("brake_position", "P", choices=("P", "G"))
        if brake is None and position == "G" and "brake_position" in f.data:
            raise g.error("brake_position", "G has no effect on a vehicle without a brake "
                          "(brake type none): remove one of the two")
        traction = _parse_traction(g.data["traction"], source, g.sub("traction")) \
            if g.has("traction") else None
        limits = _parse_limits(g.data["limits"], source, g.sub("limits"), train_limits) \
            if g.has("limits") else train_limits
        name = str(f.data.get("type", f"vehicle {i}"))
        vmax = g.number("max_speed_kmh", lo=10.0, hi=400.0) if g.has("max_speed_kmh") else None
        vehicles.extend([Vehicle(name, mass_t * 1e3, length, axles, rho, brake, position,
                                 traction, limits, vmax)] * count)
    venting = top.integer("venting_vehicle", lo=0, hi=len(vehicles) - 1) \
        if top.has("venting_vehicle") else None
    return Consist(train_name, tuple(vehicles), str(source), venting)


#: Largest axle load of the heaviest line category of EN 15528 (E) and of the one below it
#: (D) [t]; not verified in the standard's text.
AXLE_LOAD_E_T, AXLE_LOAD_D_T = 25.0, 22.5


def axle_load_warnings(consist: Consist) -> list[str]:
    """Vehicles whose axle load needs a category E line, or exceeds every line category.

    EN 15528 classes lines by the axle load they carry: up to 22.5 t for category D, 25 t for
    E, the heaviest (limits as commonly quoted, not verified in the standard's text).

    Parameters
    ----------
    consist : Consist

    Returns
    -------
    list of str
        One sentence per group of like vehicles above 22.5 t an axle, naming the vehicle.

    Examples
    --------
    >>> c = consist_from_mapping({"vehicles": [{"type": "Shimmns", "mass_t": 102.0}]}, "demo")
    >>> axle_load_warnings(c)  # doctest: +ELLIPSIS
    ['vehicle 0 (Shimmns): axle load 25.5 t (102 t on 4 axles) is beyond every EN 15528 ...']
    """
    out, i = [], 0
    for v, k in consist._groups():
        load = v.mass_kg / 1e3 / v.axles
        where = f"vehicle {i}" if k == 1 else f"vehicles {i}-{i + k - 1}"
        what = f"{where} ({v.name}): axle load {load:.1f} t ({v.mass_kg / 1e3:g} t on " \
               f"{v.axles} axles)"
        if load > AXLE_LOAD_E_T:
            out.append(f"{what} is beyond every EN 15528 line category (E: {AXLE_LOAD_E_T:g} "
                       "t; limits not verified)")
        elif load > AXLE_LOAD_D_T:
            out.append(f"{what} needs a category E line (EN 15528: above {AXLE_LOAD_D_T:g} t; "
                       "limits not verified)")
        i += k
    return out


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
    raw = read_input(p)
    # built once per version of the file and of the shipped library (a consist is immutable)
    return built_once(_consist_of_file, str(p), raw, *_shipped_library())


def _consist_of_file(data: Any, source: str, library: str, library_raw: bytes) -> Consist:
    """The consist of file ``source`` holding ``data``, with the shipped library ``library``
    of contents ``library_raw``."""
    return _consist(data, source, built_once(_library_types, library, library_raw))


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

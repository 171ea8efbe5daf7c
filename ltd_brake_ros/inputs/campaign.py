"""Campaign files: randomised train families, parameter uncertainties, manoeuvres, sampling.

A campaign describes thousands of runs by distributions instead of listing them; the studies
layer (:mod:`ltd_brake_ros.studies.campaign`) draws each run from it. Every distribution is
validated here, at load, so that a bad file fails before the first run.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from ..physics import brakes, couplers
from ..physics.parameters import out_of_range
from .brake_params import BrakeParams, load_brake_params
from .consist import MAX_VEHICLES, consist_from_mapping
from .couplers import load_coupler_lut
from .schema import Fields, InputError, config_dir, kind_of, load_yaml, resolve_config_path

__all__ = ["Campaign", "Distribution", "Family", "Locomotives", "Manoeuvre", "Variant",
           "WagonType", "campaign_from_mapping", "file_digest", "fittable_parameters",
           "load_campaign"]

#: Most runs one campaign may hold; a guard against a typing error in ``runs``.
MAX_RUNS = 100_000_000
#: Distribution kinds a file may name.
DISTRIBUTIONS = ("fixed", "uniform", "normal", "histogram")
#: Manoeuvres a campaign may run.
MANOEUVRES = ("emergency", "service", "traction_start")
#: Where additional locomotives may stand.
LOCO_POSITIONS = ("head", "middle", "tail")


@dataclass(frozen=True)
class Distribution:
    """A one-dimensional distribution, sampled by its inverse CDF.

    Attributes
    ----------
    kind : str
        ``fixed``, ``uniform``, ``normal`` (truncated to [lo, hi]) or ``histogram``.
    values : tuple of float
        ``fixed``: (value,); ``uniform``: (lo, hi); ``normal``: (mean, sd, lo, hi);
        ``histogram``: bin edges followed by the bin weights (len(edges) - 1 of them).
    """

    kind: str
    values: tuple

    @property
    def support(self) -> tuple[float, float]:
        """Smallest and largest value the distribution can produce."""
        if self.kind == "fixed":
            return self.values[0], self.values[0]
        if self.kind == "histogram":
            n = (len(self.values) + 1) // 2
            return self.values[0], self.values[n - 1]
        return self.values[-2], self.values[-1]


@dataclass(frozen=True)
class WagonType:
    """A wagon type of a family: its share of the wagons and its load.

    Attributes
    ----------
    type : str
        Vehicle type name (shipped ``vehicles.yaml`` or the campaign's ``vehicle_types``).
    share : float
        Relative frequency among the family's wagons [-].
    tare_t : float
        Empty mass [t].
    payload_t : Distribution
        Payload of a loaded wagon [t].
    loaded_fraction : float
        Probability that a wagon is loaded [-].
    """

    type: str
    share: float
    tare_t: float
    payload_t: Distribution
    loaded_fraction: float


@dataclass(frozen=True)
class Locomotives:
    """Locomotives of a family: type, how many, where the second and further ones stand.

    Attributes
    ----------
    type : str
        Vehicle type name.
    count : tuple of int
        Smallest and largest number (drawn uniformly).
    positions : tuple of str
        Position of the 1st, 2nd, ... locomotive: ``head``, ``middle`` or ``tail``.
    """

    type: str
    count: tuple
    positions: tuple


@dataclass(frozen=True)
class Variant:
    """A model variant (coupler or brake parameters) and its relative frequency.

    Attributes
    ----------
    name : str
        Label in the results (the file's stem unless given).
    params : object
        Coupler model ``Params`` or :class:`~ltd_brake_ros.inputs.BrakeParams`.
    weight : float
        Relative frequency [-].
    """

    name: str
    params: Any
    weight: float


@dataclass(frozen=True)
class Family:
    """One train family: how its trains are composed.

    Attributes
    ----------
    name : str
    weight : float
        Relative frequency of the family among the campaign's runs [-].
    wagons : tuple of int or None
        Smallest and largest wagon count, or None when ``length_m`` sets it.
    length_m : tuple of float or None
        Smallest and largest train length over buffers [m]: wagons are added while the train
        stays within the drawn length.
    wagon_types : tuple of WagonType
    g_fraction : float
        Probability that a wagon's brake is set to G [-].
    isolated_fraction : float
        Probability that a wagon's brake is isolated (cut out) [-].
    locomotives : Locomotives
    """

    name: str
    weight: float
    wagons: tuple | None
    length_m: tuple | None
    wagon_types: tuple
    g_fraction: float
    isolated_fraction: float
    locomotives: Locomotives


@dataclass(frozen=True)
class Manoeuvre:
    """One thing every train of the campaign does (each train does each manoeuvre).

    Attributes
    ----------
    name : str
        Label in the results (default: the kind).
    kind : str
        ``emergency`` (from speed until standstill), ``service`` (an application of
        ``demand`` at t = 0, released at ``release_s``, run for ``duration_s``) or
        ``traction_start`` (full ``demand`` of traction from standstill for ``duration_s``).
    speed_kmh : Distribution
        Initial speed [km/h].
    demand : float
        Brake or traction demand, 0-1.
    release_s : float or None
        Time of the release of a service application [s].
    duration_s : float or None
        Length of a service or traction run [s].
    """

    name: str
    kind: str
    speed_kmh: Distribution
    demand: float = 1.0
    release_s: float | None = None
    duration_s: float | None = None


@dataclass(frozen=True)
class Campaign:
    """A validated campaign file.

    Attributes
    ----------
    name : str
    source : str
        The file.
    digest : str
        SHA-256 of the file's bytes: a results folder belongs to one campaign.
    seed : int
        Campaign seed; run i draws from (seed, i).
    runs : int
        Trains drawn; each runs every manoeuvre.
    sampling : str
        ``monte_carlo`` or ``latin_hypercube`` (over the run-level dimensions).
    batch_size : int
        Runs per task.
    families : tuple of Family
    couplers, brake_params : tuple of Variant
    uncertainties : dict
        Fittable parameter short name -> Distribution.
    manoeuvres : tuple of Manoeuvre
        Each train runs each of them (one row per train and manoeuvre).
    adhesion_limit : float or None
        Limit of every vehicle's mean utilised adhesion [-] (None: the verdicts' defaults,
        which depend on wheel-slide protection, see :mod:`ltd_brake_ros.verdicts`).
    step_s : float
        Integration step [s].
    vehicle_types : dict
        Extra vehicle types (as in a consist file).
    vehicle_lengths_m : dict
        Length over buffers of every known vehicle type [m].
    document : mapping or None
        The document a campaign built from a mapping (not a file) was read from: a results
        folder keeps it as its ``campaign.yaml``.
    inputs : dict
        Every file the campaign reads (its own file, the shipped vehicle types, each model
        variant's file), resolved path -> SHA-256 of its bytes: a results folder is pinned to
        them.
    """

    name: str
    source: str
    digest: str
    seed: int
    runs: int
    sampling: str
    batch_size: int
    families: tuple
    couplers: tuple
    brake_params: tuple
    uncertainties: dict
    manoeuvres: tuple
    adhesion_limit: float | None
    step_s: float
    vehicle_types: dict
    vehicle_lengths_m: dict
    document: Any = None
    inputs: dict = dataclasses.field(default_factory=dict)

    @property
    def batches(self) -> int:
        """Number of batches of ``batch_size`` runs."""
        return -(-self.runs // self.batch_size)


def fittable_parameters() -> dict:
    """Every parameter an uncertainty may name: short name -> (part, Fittable).

    Returns
    -------
    dict
        ``part`` is ``"brake"`` (brake model or friction law, set on the brake parameters) or
        ``"coupler"``.
    """
    out: dict = {}
    for model in brakes.MODELS.values():
        out.update({k: ("brake", v) for k, v in model.FITTABLE.items()})
    out.update({k: ("brake", v) for k, v in brakes.friction.FITTABLE.items()})
    for model in couplers.MODELS.values():
        out.update({k: ("coupler", v) for k, v in model.FITTABLE.items()})
    return out


def _distribution(f: Fields, name: str, *, lo: float | None = None, hi: float | None = None,
                  default: float | None = None) -> Distribution:
    """Read a distribution: a number, or a mapping with one of :data:`DISTRIBUTIONS`."""
    where = f.sub(name)
    if not f.has(name):
        if default is None:
            raise f.error(name, "missing (a number or a distribution: uniform, normal, histogram)")
        return Distribution("fixed", (float(default),))
    value = f.data[name]
    if not isinstance(value, Mapping):
        x = f.number(name, lo=lo, hi=hi)
        return Distribution("fixed", (x,))
    d = Fields(value, f.source, where)
    if len(value) != 1:
        raise InputError(f.source, where, "give exactly one of " + ", ".join(DISTRIBUTIONS[1:]))
    d.reject_unknown(set(DISTRIBUTIONS))
    kind = next(iter(value))
    if kind == "fixed":
        x = d.number("fixed", lo=lo, hi=hi)
        return Distribution("fixed", (x,))
    if kind == "uniform":
        a, b = _pair(d, "uniform", lo, hi)
        return Distribution("uniform", (a, b))
    if kind == "normal":
        n = Fields(value["normal"], f.source, d.sub("normal"))
        n.reject_unknown({"mean", "sd", "min", "max"})
        mean = n.number("mean", lo=lo, hi=hi)
        sd = n.number("sd", lo=0.0, lo_open=True)
        a = n.number("min", lo if lo is not None else mean - 6 * sd, lo=lo, hi=hi)
        b = n.number("max", hi if hi is not None else mean + 6 * sd, lo=lo, hi=hi)
        if not a < b:
            raise n.error("max", f"({b:g}) must exceed min ({a:g})")
        if not a <= mean <= b:
            raise n.error("mean", f"({mean:g}) lies outside [{a:g}, {b:g}]")
        return Distribution("normal", (mean, sd, a, b))
    h = Fields(value["histogram"], f.source, d.sub("histogram"))
    h.reject_unknown({"edges", "weights"})
    edges, weights = h.numbers("edges"), h.numbers("weights")
    if len(edges) < 2 or len(weights) != len(edges) - 1:
        raise h.error("weights", f"needs one weight per bin: {len(edges)} edges give "
                      f"{max(len(edges) - 1, 0)} bins, got {len(weights)} weights")
    if any(b <= a for a, b in zip(edges, edges[1:])):
        raise h.error("edges", "must increase strictly")
    for e in (edges[0], edges[-1]):
        reason = out_of_range(e, lo, hi)
        if reason:
            raise h.error("edges", reason)
    if any(w < 0 for w in weights) or sum(weights) <= 0:
        raise h.error("weights", "must be >= 0 with a positive sum")
    return Distribution("histogram", tuple(edges) + tuple(weights))


def _pair(f: Fields, name: str, lo: float | None, hi: float | None) -> tuple[float, float]:
    """A [smallest, largest] list of two finite numbers within [lo, hi]."""
    values = f.numbers(name)
    if len(values) != 2:
        raise f.error(name, f"must be [smallest, largest], got {len(values)} numbers")
    a, b = values
    for x in values:
        reason = out_of_range(x, lo, hi)
        if reason:
            raise f.error(name, reason)
    if a > b:
        raise f.error(name, f"smallest ({a:g}) exceeds largest ({b:g})")
    return a, b


def _int_pair(f: Fields, name: str, lo: int, hi: int) -> tuple[int, int]:
    a, b = _pair(f, name, lo, hi)
    if a != int(a) or b != int(b):
        raise f.error(name, "must be whole numbers")
    return int(a), int(b)


def file_digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes, in hexadecimal.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    str
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _variants(f: Fields, name: str, default: str, load, base: Path,
              files: dict | None = None) -> tuple:
    """``[{file, weight, ...}]`` model variants, each file loaded and validated once.

    The resolved path and digest of each file go into ``files``."""
    entries = f.data.get(name) or [{"file": default}]
    if not isinstance(entries, list):
        raise f.error(name, f"must be a list of {{file, weight}}, got {kind_of(entries)}")
    out = []
    for i, entry in enumerate(entries):
        v = Fields(entry, f.source, f"{f.sub(name)}[{i}]")
        v.reject_unknown({"file", "weight", "name", "draft_strength_kN", "buff_strength_kN"})
        path = resolve_config_path(v.string("file"), base)
        params = load(path)
        if files is not None:
            files[str(Path(path).resolve())] = file_digest(path)
        for key in ("draft_strength_kN", "buff_strength_kN"):
            if v.has(key):
                if name != "couplers":
                    raise v.error(key, "applies to couplers only")
                params = dataclasses.replace(params, **{key.replace("_kN", "_N"):
                                                        1e3 * v.number(key, lo=0.0, lo_open=True)})
        out.append(Variant(v.string("name", Path(path).stem), params,
                           v.number("weight", 1.0, lo=0.0, lo_open=True)))
    if len({x.name for x in out}) != len(out):
        raise f.error(name, "two variants share a name; give each a distinct name")
    return tuple(out)


def _check_masses(w: Fields, tname: str, tare: float, payload: Distribution,
                  loaded_fraction: float, extra: Mapping) -> None:
    """Every mass a wagon type can be drawn with must make a vehicle its type can be.

    The lightest empty and the lightest and heaviest loaded wagon are built in both brake
    positions; a mass that its type's braked weight (or any other of its fields) refuses names
    the campaign field and the vehicle type's field.
    """
    cases = []
    if loaded_fraction < 1.0:
        cases.append(("tare_t", "an empty", tare))
    if loaded_fraction > 0.0:
        cases += [("payload_t", "the lightest loaded", tare + payload.support[0]),
                  ("payload_t", "the heaviest loaded", tare + payload.support[1])]
    for key, what, mass in cases:
        for position in ("P", "G"):
            try:
                consist_from_mapping({"vehicle_types": dict(extra), "vehicles": [
                    {"type": tname, "mass_t": mass, "brake_position": position}]}, w.source)
            except InputError as exc:
                field = exc.field.replace("vehicles[0].", f"{tname}.")
                raise w.error(key, f"{what} {tname} ({mass:g} t) is not a vehicle its type can "
                              f"be: {field}: {exc.reason}") from None


def _family(data: Any, source: str, path: str, library: dict, extra: Mapping) -> Family:
    f = Fields(data, source, path)
    f.reject_unknown({"name", "weight", "wagons", "length_m", "wagon_types", "g_fraction",
                      "isolated_fraction", "locomotives"})
    if f.has("wagons") == f.has("length_m"):
        raise f.error("wagons", "give either wagons: [min, max] or length_m: [min, max]")
    wagons = _int_pair(f, "wagons", 1, MAX_VEHICLES - 10) if f.has("wagons") else None
    length = _pair(f, "length_m", 1.0, 100.0 * MAX_VEHICLES) if f.has("length_m") else None
    types = f.data.get("wagon_types")
    if not isinstance(types, Mapping) or not types:
        raise f.error("wagon_types", "missing or not a mapping of vehicle type -> share, tare, payload")
    wagon_types = []
    for tname, entry in types.items():
        w = Fields(entry, source, f"{f.sub('wagon_types')}.{tname}")
        if str(tname) not in library:
            raise InputError(source, f"{f.sub('wagon_types')}.{tname}",
                             f"unknown vehicle type {tname!r}; known: {', '.join(sorted(library))}")
        w.reject_unknown({"share", "tare_t", "payload_t", "loaded_fraction"})
        tare = w.number("tare_t", lo=0.0, lo_open=True, hi=500.0)
        payload = _distribution(w, "payload_t", lo=0.0, hi=500.0)
        if tare + payload.support[1] > 500.0:
            raise w.error("payload_t", f"tare + payload reaches {tare + payload.support[1]:g} t, "
                          "beyond 500 t per vehicle")
        loaded_fraction = w.number("loaded_fraction", 1.0, lo=0.0, hi=1.0)
        _check_masses(w, str(tname), tare, payload, loaded_fraction, extra)
        wagon_types.append(WagonType(str(tname), w.number("share", 1.0, lo=0.0, lo_open=True),
                                     tare, payload, loaded_fraction))
    wagon_types.sort(key=lambda w: w.type)  # draws do not depend on the file's key order
    shortest = min(library[t.type] for t in wagon_types)  # [m]
    loco = Fields(f.data.get("locomotives") or {}, source, f.sub("locomotives"))
    loco.reject_unknown({"type", "count", "positions"})
    ltype = loco.string("type", "E402B")
    if ltype not in library:
        raise loco.error("type", f"unknown vehicle type {ltype!r}; known: {', '.join(sorted(library))}")
    count = _int_pair(loco, "count", 1, 8) if loco.has("count") else (1, 1)
    positions = loco.data.get("positions", ["head", "tail", "middle"])
    if not isinstance(positions, list) or len(positions) < count[1] or any(
            p not in LOCO_POSITIONS for p in positions) or positions[0] != "head":
        raise loco.error("positions", f"must list a position ({', '.join(LOCO_POSITIONS)}) for "
                         f"each of up to {count[1]} locomotives, the first at head")
    least_m = count[0] * library[ltype] + shortest
    if length is not None and length[1] < least_m:
        raise f.error("length_m", f"no train fits: {count[0]} {ltype} and the shortest wagon "
                      f"are {least_m:g} m long, more than {length[1]:g} m")
    return Family(f.string("name", path), f.number("weight", 1.0, lo=0.0, lo_open=True), wagons,
                  length, tuple(wagon_types), f.number("g_fraction", 0.0, lo=0.0, hi=1.0),
                  f.number("isolated_fraction", 0.0, lo=0.0, hi=1.0),
                  Locomotives(ltype, count, tuple(positions)))


def _library(extra: Mapping, source: str) -> dict[str, float]:
    """Vehicle types known to the campaign and their lengths over buffers [m]."""
    shipped = (load_yaml(config_dir() / "vehicles.yaml") or {}).get("vehicle_types") or {}
    return {name: consist_from_mapping({"vehicle_types": dict(extra),
                                        "vehicles": [{"type": name}]}, source).length_m
            for name in sorted(set(shipped) | set(extra))}


def _manoeuvre(data: Any, source: str, path: str) -> Manoeuvre:
    f = Fields(data, source, path)
    kind = f.string("kind", choices=MANOEUVRES)
    name = f.string("name", kind)
    if kind == "emergency":
        f.reject_unknown({"name", "kind", "speed_kmh"})
        return Manoeuvre(name, kind, _distribution(f, "speed_kmh", lo=1.0, hi=400.0))
    if kind == "service":
        f.reject_unknown({"name", "kind", "speed_kmh", "demand", "release_s", "duration_s"})
        duration = f.number("duration_s", lo=0.0, lo_open=True, hi=3600.0)
        release = f.number("release_s", duration, lo=0.0, lo_open=True, hi=duration)
        return Manoeuvre(name, kind, _distribution(f, "speed_kmh", lo=0.0, hi=400.0),
                         f.number("demand", 1.0, lo=0.0, lo_open=True, hi=1.0), release, duration)
    f.reject_unknown({"name", "kind", "speed_kmh", "demand", "duration_s"})
    return Manoeuvre(name, kind, _distribution(f, "speed_kmh", lo=0.0, hi=400.0, default=0.0),
                     f.number("demand", 1.0, lo=0.0, lo_open=True, hi=1.0), None,
                     f.number("duration_s", lo=0.0, lo_open=True, hi=3600.0))


def _manoeuvres(f: Fields) -> tuple:
    entries = f.data.get("manoeuvres")
    if not isinstance(entries, list) or not entries:
        raise f.error("manoeuvres", "missing or not a non-empty list (each with kind: "
                      f"{', '.join(MANOEUVRES)})")
    out = tuple(_manoeuvre(e, f.source, f"manoeuvres[{i}]") for i, e in enumerate(entries))
    names = [m.name for m in out]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise InputError(f.source, f"manoeuvres[{i}].name", f"{name!r} is used twice; give "
                             "each manoeuvre a distinct name")
    return out


def campaign_from_mapping(data: Any, source: str, digest: str = "",
                          base: Path | None = None) -> Campaign:
    """Validate a campaign document.

    Parameters
    ----------
    data : mapping
        The document (see ``config/campaigns/example.yaml``).
    source : str
        File name for error messages.
    digest : str, optional
        Hash of the file.
    base : pathlib.Path, optional
        Directory that relative model files are looked up in first.

    Returns
    -------
    Campaign

    Raises
    ------
    InputError
        One line naming the file, the field and the reason.
    """
    f = Fields(data, source)
    f.reject_unknown({"name", "description", "seed", "runs", "sampling", "batch_size", "families",
                      "couplers", "brake_params", "uncertainties", "manoeuvres", "adhesion_limit",
                      "step_s", "vehicle_types"})
    runs = f.integer("runs", lo=1, hi=MAX_RUNS)
    extra = f.data.get("vehicle_types") or {}
    if not isinstance(extra, Mapping):
        raise f.error("vehicle_types", f"must be a mapping, got {kind_of(extra)}")
    library = _library(extra, source)
    fams = f.data.get("families")
    if not isinstance(fams, list) or not fams:
        raise f.error("families", "missing or not a non-empty list of train families")
    families = tuple(_family(x, source, f"families[{i}]", library, extra)
                     for i, x in enumerate(fams))
    base = base or Path.cwd()
    files = {}
    if Path(source).is_file():
        files[str(Path(source).resolve())] = digest or file_digest(source)
    else:  # built from a mapping: the document is the input
        import json

        digest = digest or hashlib.sha256(json.dumps(data, sort_keys=True, default=str)
                                          .encode()).hexdigest()
    shipped = config_dir() / "vehicles.yaml"
    files[str(shipped.resolve())] = file_digest(shipped)
    coupler_variants = _variants(f, "couplers", "couplers/buffer_hook_pugi.yaml",
                                 load_coupler_lut, base, files)
    brake_variants = _variants(f, "brake_params", "brake_params/paper.yaml", load_brake_params,
                               base, files)
    known = fittable_parameters()
    unc = Fields(f.data.get("uncertainties") or {}, source, "uncertainties")
    uncertainties = {}
    for key in sorted(unc.data):
        if key not in known:
            raise unc.error(str(key), f"not a fittable parameter; known: {', '.join(sorted(known))}")
        part, fit = known[key]
        dist = _distribution(unc, key, lo=fit.lower, hi=fit.upper)
        models = [v.params for v in (brake_variants if part == "brake" else coupler_variants)]
        if not any(_has_field(p, fit.field) for p in models):
            raise unc.error(str(key), f"no {part} variant of the campaign has the field "
                            f"{fit.field}")
        uncertainties[str(key)] = dist
    step = f.number("step_s", 0.01, lo=1e-4, hi=0.1)
    return Campaign(
        name=f.string("name", Path(source).stem), source=str(source), digest=digest,
        seed=f.integer("seed", lo=0, hi=2**63 - 1), runs=runs,
        sampling=f.string("sampling", "monte_carlo", choices=("monte_carlo", "latin_hypercube")),
        batch_size=f.integer("batch_size", 50, lo=1, hi=100_000), families=families,
        couplers=coupler_variants, brake_params=brake_variants, uncertainties=uncertainties,
        manoeuvres=_manoeuvres(f),
        adhesion_limit=(f.number("adhesion_limit", lo=0.0, lo_open=True, hi=1.0)
                        if f.has("adhesion_limit") else None),
        step_s=step, vehicle_types=dict(extra), vehicle_lengths_m=library,
        document=None if Path(source).is_file() else data, inputs=files)


def _has_field(params: Any, field: str) -> bool:
    if isinstance(params, BrakeParams):
        return any(field in {x.name for x in dataclasses.fields(p)}
                   for p in (params.pneumatic, params.friction))
    return field in {x.name for x in dataclasses.fields(params)}


def load_campaign(path: str | os.PathLike) -> Campaign:
    """Load and validate a campaign YAML file.

    Parameters
    ----------
    path : str or path-like
        The file; relative names are also looked up in the shipped config directory.

    Returns
    -------
    Campaign
    """
    p = resolve_config_path(path)
    data = load_yaml(p)
    digest = hashlib.sha256(p.read_bytes()).hexdigest()
    return campaign_from_mapping(data, str(p), digest, p.parent)


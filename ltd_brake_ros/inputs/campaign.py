"""Campaign files: randomised train families, parameter uncertainties, manoeuvres, sampling.

A campaign describes thousands of runs by distributions instead of listing them; the studies
layer (:mod:`ltd_brake_ros.studies.campaign`) draws each run from it. Every distribution is
validated here, at load, so that a bad file fails before the first run.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
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

__all__ = ["Campaign", "Design", "Distribution", "Family", "Locomotives", "Manoeuvre", "Variant",
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
#: Sampling of a campaign: random samples of trains, then designed experiments (:class:`Design`).
SAMPLINGS = ("monte_carlo", "latin_hypercube", "grid", "sobol", "morris")
#: The designed experiments among :data:`SAMPLINGS`.
DESIGNS = ("grid", "sobol", "morris")
#: Train-level inputs a design may vary besides the uncertainties (and ``speed_kmh:NAME``, the
#: initial speed of one manoeuvre); ``wagons`` and ``length_m`` set the train's size.
TRAIN_INPUTS = ("family", "wagons", "length_m", "locomotives", "payload_t", "coupler",
                "brake_params", "speed_kmh")
#: Inputs that take the name of a variant (a family, coupler or brake-parameter variant).
NAMED_INPUTS = ("family", "coupler", "brake_params")
#: Most levels of one grid input, and most Morris levels.
MAX_LEVELS, MAX_MORRIS_LEVELS = 1000, 20


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
class Design:
    """A designed experiment: which inputs vary, and the design's size.

    Each input sets one or more of the run-level draws of
    :func:`~ltd_brake_ros.studies.campaign.dimensions` (``wagons`` and ``length_m`` set
    ``size``; ``speed_kmh`` every manoeuvre's ``speed_kmh:NAME``; ``payload_t`` the payload
    quantile that every loaded wagon of the train shares), each from a probability u in
    [0, 1] through the inverse CDF of its distribution, as a random draw would. The draws that
    no input sets are held: for ``sobol`` and ``morris`` the run-level draws at their median
    (u = 0.5) and every wagon's draws (type, load, brake position, isolation) those of train
    0, so that the runs differ in the inputs alone; for ``grid`` they are those of replicate j
    (``runs`` replicates of every grid point, replicate j the same train at every point).

    Attributes
    ----------
    kind : str
        ``grid`` (full factorial), ``sobol`` (Saltelli's design for Sobol' indices) or
        ``morris`` (Morris's elementary-effects trajectories).
    inputs : tuple of str
        The varied inputs, in the design's column order.
    dimensions : tuple of tuple of str
        Per input, the run-level draws it sets.
    base_runs : int
        The file's ``runs``: sobol the base sample N, morris the trajectories r, grid the
        replicates of every grid point.
    second_order : bool
        sobol: the design also estimates second-order indices (N (2 D + 2) runs rather than
        N (D + 2)).
    levels : int
        morris: the levels p of every input; level k is the probability (k + 0.5) / p.
    grid : tuple
        grid: per input ``("levels", values)`` (values as given: numbers, or variant names)
        or ``("points", n)`` (the values at probabilities (k + 0.5) / n, k = 0 ... n - 1).
    """

    kind: str
    inputs: tuple
    dimensions: tuple
    base_runs: int
    second_order: bool = True
    levels: int = 4
    grid: tuple = ()

    @property
    def block(self) -> int:
        """Runs of one block: a Saltelli block (2 D + 2 or D + 2), a Morris trajectory
        (D + 1) or the replicates of one grid point."""
        d = len(self.inputs)
        if self.kind == "sobol":
            return 2 * d + 2 if self.second_order else d + 2
        return d + 1 if self.kind == "morris" else self.base_runs

    @property
    def shape(self) -> tuple:
        """grid: the number of levels of each input."""
        return tuple(len(v) if k == "levels" else v for k, v in self.grid)

    @property
    def runs(self) -> int:
        """Trains of the design."""
        if self.kind == "grid":
            return self.base_runs * math.prod(self.shape)
        return self.base_runs * self.block


@dataclass(frozen=True)
class Campaign:
    """A validated campaign file.

    Attributes
    ----------
    name : str
    source : str
        The file.
    digest : str
        SHA-256 of the file's meaning (:func:`document_digest` of its parsed content: a
        comment or layout edit keeps it, a changed value does not): a results folder belongs
        to one campaign.
    seed : int
        Campaign seed; run i draws from (seed, i).
    runs : int
        Trains drawn; each runs every manoeuvre (with a design: all the design's trains).
    sampling : str
        ``monte_carlo`` or ``latin_hypercube`` (over the run-level dimensions), or a
        designed experiment: ``grid``, ``sobol`` or ``morris`` (see ``design``).
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
        variant's file), resolved path -> :func:`content_digest` of it: a results folder is
        pinned to what they say.
    design : Design or None
        The designed experiment of ``grid``, ``sobol`` and ``morris``; None for a random
        sample.
    band : ModelFormBand or None
        Each emergency stop also runs this model-form band (the ``band`` key: true for the
        shipped one, or a band file): its verdict and each key number's ends are columns.
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
    design: Design | None = None
    band: Any = None

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


def document_digest(data: Any) -> str:
    """SHA-256 of a parsed document's meaning: its canonical JSON (keys sorted), so that a
    comment, the layout or the quoting of a file does not change it and any value does.

    Parameters
    ----------
    data : object
        A parsed YAML document (mappings, lists, numbers, text, booleans, null).

    Returns
    -------
    str
        Hexadecimal.

    Examples
    --------
    >>> document_digest({"a": 1, "b": [2.5]}) == document_digest({"b": [2.5], "a": 1})
    True
    >>> document_digest({"a": 1}) == document_digest({"a": 2})
    False
    """
    import json

    text = json.dumps(data, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def content_digest(path: str | os.PathLike) -> str:
    """:func:`document_digest` of a YAML input file (what it means, not its bytes).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    str
    """
    return document_digest(load_yaml(path))


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
            files[str(Path(path).resolve())] = content_digest(path)
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
        reason = _vehicle_reason(tname, mass, extra, w.source)
        if reason:
            raise w.error(key, f"{what} {tname} ({mass:g} t) {reason}")


def _vehicle_reason(tname: str, mass: float, extra: Mapping, source: str) -> str:
    """Why a wagon of type ``tname`` and ``mass`` [t] cannot be built in brake position P or G
    ('' when it can)."""
    for position in ("P", "G"):
        try:
            consist_from_mapping({"vehicle_types": dict(extra), "vehicles": [
                {"type": tname, "mass_t": mass, "brake_position": position}]}, source)
        except InputError as exc:
            field = exc.field.replace("vehicles[0].", f"{tname}.")
            return f"is not a vehicle its type can be: {field}: {exc.reason}"
    return ""


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
        # a service application brakes from speed, as an emergency stop (traction starts at rest)
        return Manoeuvre(name, kind, _distribution(f, "speed_kmh", lo=1.0, hi=400.0),
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


def _input_dimensions(name: str, err, families: tuple, uncertainties: dict,
                      manoeuvres: tuple) -> tuple:
    """The run-level draws that design input ``name`` sets; ``err(reason)`` makes the error."""
    if name in uncertainties or name in ("family", "locomotives", "payload_t", "coupler",
                                         "brake_params"):
        return (name,)
    if name in ("wagons", "length_m"):
        other = [fam.name for fam in families if getattr(fam, name) is None]
        if other:
            given = "length_m" if name == "wagons" else "wagons"
            raise err(f"family {other[0]} gives {given}, not {name}: vary {given} instead")
        return ("size",)
    names = [m.name for m in manoeuvres]
    if name == "speed_kmh":
        return tuple(f"speed_kmh:{m}" for m in names)
    if name.startswith("speed_kmh:"):
        if name[len("speed_kmh:"):] not in names:
            raise err(f"no manoeuvre {name[len('speed_kmh:'):]!r}; the campaign has "
                      f"{', '.join(names)}")
        return (name,)
    if name in fittable_parameters():
        raise err(f"{name} is not among the campaign's uncertainties: give it a distribution "
                  "under uncertainties")
    raise err(f"unknown input {name!r}; known: {', '.join(TRAIN_INPUTS)}, speed_kmh:NAME and "
              f"the uncertainties ({', '.join(sorted(uncertainties)) or 'none'})")


def _check_disjoint(inputs: list, dims: list, err) -> None:
    """Two inputs may not set the same draw (``speed_kmh`` and ``speed_kmh:NAME``)."""
    for i, a in enumerate(dims):
        for j in range(i):
            common = set(a) & set(dims[j])
            if common:
                raise err(i, f"{inputs[i]} and {inputs[j]} both vary {sorted(common)[0]}; "
                          "keep one")


def _input_distributions(name: str, families: tuple, uncertainties: dict,
                         manoeuvres: tuple) -> list:
    """The distributions that a grid's ``points`` of input ``name`` are taken from, as
    (what, Distribution) pairs; sizes and counts as uniform ones."""
    if name in uncertainties:
        return [(f"the uncertainty {name}", uncertainties[name])]
    if name == "payload_t":
        return [(f"the payload of {w.type} in family {fam.name}", w.payload_t)
                for fam in families for w in fam.wagon_types if w.loaded_fraction > 0.0]
    if name in ("wagons", "length_m", "locomotives"):
        return [(f"family {fam.name}", Distribution("uniform", tuple(
            fam.locomotives.count if name == "locomotives" else getattr(fam, name))))
                for fam in families]
    wanted = {m.name for m in manoeuvres} if name == "speed_kmh" else {name.split(":", 1)[1]}
    return [(f"the speed of manoeuvre {m.name}", m.speed_kmh) for m in manoeuvres
            if m.name in wanted]


def _grid_levels(g: Fields, name: str, values: list, c: dict) -> tuple:
    """Explicit levels of grid input ``name``, checked to be values the input can take."""
    path = g.sub("levels")

    def bad(i: int, reason: str) -> InputError:
        return InputError(g.source, f"{path}[{i}]", reason)

    if name in NAMED_INPUTS:
        known = [x.name for x in c[{"family": "families", "coupler": "couplers",
                                    "brake_params": "brake_params"}[name]]]
        for i, v in enumerate(values):
            if v not in known:
                raise bad(i, f"unknown {name} {v!r}; the campaign has {', '.join(known)}")
        out = tuple(values)
    else:
        out = tuple(g.numbers("levels"))
        for i, v in enumerate(out):
            reason = _level_reason(name, v, c)
            if reason:
                raise bad(i, reason)
        if name in ("wagons", "locomotives"):
            out = tuple(int(v) for v in out)
    for i, v in enumerate(out):
        if v in out[:i]:
            raise bad(i, f"repeats the level {v!r}; give each level once")
    return out


def _level_reason(name: str, v: float, c: dict) -> str:
    """Why ``v`` cannot be a level of numeric grid input ``name`` ('' when it can)."""
    if name in c["uncertainties"]:
        fit = fittable_parameters()[name][1]
        return out_of_range(v, fit.lower, fit.upper)
    if name in ("wagons", "locomotives"):
        if v != int(v):
            return f"must be a whole number, got {v:g}"
        if name == "wagons":
            return out_of_range(v, 1, MAX_VEHICLES - 10)
        for fam in c["families"]:
            lo, hi = fam.locomotives.count
            if not lo <= v <= hi:
                return (f"family {fam.name} takes {lo} to {hi} locomotives (a position "
                        f"each), not {v:g}")
        return ""
    if name == "length_m":
        return out_of_range(v, 1.0, 100.0 * MAX_VEHICLES)
    if name == "payload_t":
        for fam in c["families"]:
            for w in fam.wagon_types:
                if w.loaded_fraction > 0.0:
                    reason = out_of_range(v, 0.0, 500.0 - w.tare_t)
                    if reason:
                        return f"payload of a {w.type} (tare {w.tare_t:g} t): {reason}"
                    reason = _vehicle_reason(w.type, w.tare_t + v, c["vehicle_types"], "")
                    if reason:
                        return f"a {w.type} loaded with {v:g} t {reason}"
        return ""
    emergency = any(m.kind == "emergency" and (name == "speed_kmh" or name == f"speed_kmh:"
                                               f"{m.name}") for m in c["manoeuvres"])
    return out_of_range(v, 1.0 if emergency else 0.0, 400.0)


def _grid_points(g: Fields, name: str, c: dict) -> int:
    """``points: n`` of grid input ``name``: n distinct values at probabilities (k + 0.5) / n."""
    if name in NAMED_INPUTS:
        raise g.error("points", f"applies to numeric inputs; list the {name} names under "
                      "levels")
    n = g.integer("points", lo=1, hi=MAX_LEVELS)
    for what, dist in _input_distributions(name, c["families"], c["uncertainties"],
                                           c["manoeuvres"]):
        lo, hi = dist.support
        if n > 1 and lo == hi:
            raise g.error("points", f"{what} is fixed at {lo:g}: {n} points would repeat it; "
                          "list the values under levels")
        if name in ("wagons", "locomotives") and n > hi - lo + 1:
            raise g.error("points", f"{what} takes {hi - lo + 1:g} counts of {name} ({lo:g} "
                          f"to {hi:g}), fewer than {n} points")
    return n


def _design(f: Fields, runs: int, c: dict) -> Design | None:
    """The designed experiment of ``sampling`` (None for a random sample of trains).

    ``c`` holds the campaign's parts read so far: ``families``, ``couplers``,
    ``brake_params``, ``uncertainties``, ``manoeuvres`` and ``vehicle_types``.
    """
    value = f.data.get("sampling")
    if value is None or isinstance(value, str):
        kind = f.string("sampling", "monte_carlo", choices=SAMPLINGS)
        if kind not in DESIGNS:
            return None
        if kind == "grid":
            raise f.error("sampling", "a grid needs its levels: write sampling: {design: "
                          "grid, inputs: {NAME: {levels: [...]}}}")
        value = {"design": kind}
    elif not isinstance(value, Mapping):
        raise f.error("sampling", f"must be a name ({', '.join(SAMPLINGS)}) or a mapping "
                      f"with design: {', '.join(DESIGNS)}; got {kind_of(value)}")
    d = Fields(value, f.source, "sampling")
    kind = d.string("design", choices=DESIGNS)
    d.reject_unknown({"design", "inputs", "second_order", "levels"} if kind != "grid" else
                     {"design", "inputs"})
    if kind == "sobol" and "levels" in d.data:
        raise d.error("levels", "applies to morris designs only")
    if kind == "morris" and "second_order" in d.data:
        raise d.error("second_order", "applies to sobol designs only")
    parts = (c["families"], c["uncertainties"], c["manoeuvres"])
    if kind == "grid":
        spec = d.data.get("inputs")
        if not isinstance(spec, Mapping) or not spec:
            raise d.error("inputs", "missing or not a mapping of input -> {levels: [...]} or "
                          "{points: N}")
        names = [str(k) for k in spec]
        dims, grid = [], []
        for name in names:
            where = d.sub(f"inputs.{name}")
            dims.append(_input_dimensions(
                name, lambda r, w=where: InputError(f.source, w, r), *parts))
            entry = spec[name]
            g = Fields(entry if isinstance(entry, Mapping) else {"levels": entry}, f.source,
                       where)
            g.reject_unknown({"levels", "points"})
            if g.has("levels") == g.has("points"):
                raise InputError(f.source, where, "give either levels: [values] or points: N")
            if g.has("levels") and (not isinstance(g.data["levels"], list)
                                    or not g.data["levels"]):
                raise g.error("levels", f"must be a non-empty list, got "
                              f"{kind_of(g.data['levels'])}")
            grid.append(("levels", _grid_levels(g, name, g.data["levels"], c))
                        if g.has("levels") else ("points", _grid_points(g, name, c)))
        _check_disjoint(names, dims, lambda i, r: InputError(
            f.source, d.sub(f"inputs.{names[i]}"), r))
        out = Design("grid", tuple(names), tuple(dims), runs, grid=tuple(grid))
    else:
        given = d.data.get("inputs")
        if given is None:
            if not c["uncertainties"]:
                raise d.error("inputs", f"missing: a {kind} design varies the uncertainties "
                              "unless inputs lists others, and the campaign has none")
            given = sorted(c["uncertainties"])
        if not isinstance(given, list) or not given or not all(
                isinstance(x, str) for x in given):
            raise d.error("inputs", f"must be a non-empty list of input names, got "
                          f"{kind_of(given)}")
        dims = [_input_dimensions(name, lambda r, i=i: InputError(
            f.source, d.sub(f"inputs[{i}]"), r), *parts) for i, name in enumerate(given)]
        _check_disjoint(given, dims, lambda i, r: InputError(f.source, d.sub(f"inputs[{i}]"),
                                                               r))
        if kind == "sobol":
            if runs & (runs - 1):
                below = 1 << (runs.bit_length() - 1)
                raise f.error("runs", f"a sobol design's base sample N must be a power of 2 "
                              f"(the Sobol' sequence is balanced only then), got {runs}: take "
                              f"{below} or {2 * below}")
            out = Design("sobol", tuple(given), tuple(dims), runs,
                         second_order=d.boolean("second_order", True))
        else:
            p = d.integer("levels", 4, lo=2, hi=MAX_MORRIS_LEVELS)
            if p % 2:
                raise d.error("levels", f"must be even (Morris's step of p / (2 (p - 1)) "
                              f"then reaches every level equally often), got {p}")
            out = Design("morris", tuple(given), tuple(dims), runs, levels=p)
    if out.runs > MAX_RUNS:
        raise f.error("runs", f"the {kind} design has {out.runs} runs, more than {MAX_RUNS}")
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
                      "step_s", "vehicle_types", "band"})
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
    digest = digest or document_digest(data)
    if Path(source).is_file():
        files[str(Path(source).resolve())] = digest
    shipped = config_dir() / "vehicles.yaml"
    files[str(shipped.resolve())] = content_digest(shipped)
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
    if abs(0.5 - round(0.5 / step) * step) > 1e-6 * step:  # the runs' chunks: 0.5 s and 1 s
        raise f.error("step_s", f"{step:g} s does not divide the 0.5 s chunks the runs advance "
                      "in into whole steps (others would change the results): e.g. 0.005, "
                      "0.01, 0.02, 0.025 or 0.05")
    manoeuvres = _manoeuvres(f)
    design = _design(f, runs, {"families": families, "couplers": coupler_variants,
                               "brake_params": brake_variants, "uncertainties": uncertainties,
                               "manoeuvres": manoeuvres, "vehicle_types": dict(extra)})
    if design is not None and design.kind != "grid":
        _require_salib(f, design.kind)
    return Campaign(
        name=f.string("name", Path(source).stem), source=str(source), digest=digest,
        seed=f.integer("seed", lo=0, hi=2**63 - 1),
        runs=design.runs if design is not None else runs,
        sampling=design.kind if design is not None else f.string("sampling", "monte_carlo"),
        batch_size=f.integer("batch_size", 50, lo=1, hi=100_000), families=families,
        couplers=coupler_variants, brake_params=brake_variants, uncertainties=uncertainties,
        manoeuvres=manoeuvres,
        adhesion_limit=(f.number("adhesion_limit", lo=0.0, lo_open=True, hi=1.0)
                        if f.has("adhesion_limit") else None),
        step_s=step, vehicle_types=dict(extra), vehicle_lengths_m=library,
        document=None if Path(source).is_file() else data, inputs=files, design=design,
        band=_band(f, files))


def _band(f: Fields, files: dict):
    """``band``: true (the shipped model-form band), a band file, or false (none)."""
    if not f.has("band") or f.data["band"] is False:
        return None
    from .band import DEFAULT_BAND, load_band

    value = f.data["band"]
    if value is True:
        path = resolve_config_path(DEFAULT_BAND)
    elif isinstance(value, str) and value.strip():
        path = resolve_config_path(value, Path(f.source).parent)
    else:
        raise f.error("band", f"must be true, false or a band file, got {kind_of(value)}")
    band = load_band(path)
    files[str(Path(path).resolve())] = content_digest(path)
    return band


def _require_salib(f: Fields, kind: str) -> None:
    """One line, before any run, when SALib (which samples sobol and morris designs) is
    missing."""
    from importlib.util import find_spec

    if find_spec("SALib") is None:
        raise f.error("sampling", f"a {kind} design needs SALib, which is not installed: pip "
                      "install 'ltd_brake_ros[campaign]'")


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
    return campaign_from_mapping(data, str(p), document_digest(data), p.parent)


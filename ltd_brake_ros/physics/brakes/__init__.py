"""Brake models: the contract every model implements, the registry and the one dispatch.

A brake model turns the driver's brake commands into the block force of every vehicle; the
friction law (:mod:`.friction`, Eq. 4 and 8-10, shared by every model) turns block force into
retarding force at the wheels, whose work heats the blocks and wheels (:mod:`.thermal`, shared
by every model too).

Contract
--------
A brake model is one module of this package that defines:

1. ``NAME`` (the ``model:`` value of a brake-parameter file), ``ID`` (its branch of
   :func:`advance`), a frozen ``Params`` dataclass whose fields carry their units in their
   names and are declared with :func:`~ltd_brake_ros.physics.parameters.parameter` (meaning and
   accepted range; the input layer builds ``Params`` from a mapping with its shared field
   checks), and ``FITTABLE`` = {short name: :class:`~ltd_brake_ros.physics.parameters.Fittable`
   (field, unit, lower, upper, scale, meaning)}: calibration reads it, so a new model needs no
   change there. Optionally ``check_fields(params)``: combinations of fields that no brake can
   have (each field may be within its range), raised as :class:`CompileError` naming both
   fields; the input layer calls it whenever a ``Params`` is built. Optionally
   ``validity(consist, params)``: the sentences saying where a train leaves the model's
   validated range (empty inside it); every output of a run repeats them.
2. ``compile(consist, params, force_max_N)`` -> :class:`BrakeArrays`: per-vehicle arrays, built
   once, never mutated; ``force_max_N`` is the full block force from :func:`friction.compile`.
3. ``initial_state(arrays)`` -> :class:`BrakeState`: the model's only mutable state, released
   brakes (with the scratch rows its advance needs in ``work``); the simulator's reset copies it.
4. ``advance(arrays, state, events, t0, t1)``, compiled with numba without reference counting
   (:func:`~ltd_brake_ros.physics.equations.jit_step`: it allocates nothing): every vehicle's
   block force from t0 to t1 [s] under the :class:`CommandEvents` issued at the venting
   vehicle (the driver's brake valve), in place; a command reaches vehicle i
   ``arrays.delay_s[i]`` after it was issued. The result must not depend on how [t0, t1] is
   split into steps.
5. Events and snapshot: the simulator raises ``brake_applied`` and ``brake_released`` when the
   commands change; ``snapshot_extras(arrays, state)`` returns the model's further quantities
   (per-vehicle arrays, units in the keys; ``{}`` for none), the snapshot always shows the
   block forces.
6. Register: one line in :data:`MODELS` and one branch in :func:`advance`.
7. The contract tests (``test/physics/test_brake_contract.py``) run over every registered
   model: no force before the command reaches a vehicle, a monotone rise under emergency, a
   monotone decay once a release takes effect, two pieces equal one piece, and a whole stop.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import equations, parameters
from ..equations import jit_step_inner
from . import friction, linear_ramp, thermal, uic_empirical, uic_pipe
from .base import EMERGENCY, SERVICE, BrakeArrays, BrakeState, CommandEvents, CompileError

__all__ = ["EMERGENCY", "SERVICE", "BrakeArrays", "BrakeState", "BrakeParams", "CommandEvents",
           "CompileError", "DEFAULT_MODEL", "MODELS", "advance", "check_fields", "friction",
           "validity",
           "model_of", "thermal"]

#: Registered brake models by name.
MODELS = {m.NAME: m for m in (
    uic_empirical,
    linear_ramp,
    uic_pipe,
)}
#: The model of a parameter file that names none: the paper's.
DEFAULT_MODEL = uic_empirical.NAME


@jit_step_inner
def advance(arrays, state, events, t0, t1):
    """Advance the block forces of the model ``arrays.model`` from t0 to t1 [s] (in place)."""
    if arrays.model == uic_empirical.ID:
        uic_empirical.advance(arrays, state, events, t0, t1)
    elif arrays.model == linear_ramp.ID:
        linear_ramp.advance(arrays, state, events, t0, t1)
    elif arrays.model == uic_pipe.ID:
        uic_pipe.advance(arrays, state, events, t0, t1)


#: The package whose sources are compiled into the cached dispatchers (models, kernel, equations).
PHYSICS_DIR = Path(__file__).resolve().parent.parent


def sources_stamp(root: Path = PHYSICS_DIR) -> str:
    """SHA-256 of every Python source under ``root``: relative paths and contents, sorted.

    Parameters
    ----------
    root : Path, optional
        Directory (default: the physics package).

    Returns
    -------
    str
        Hex digest.
    """
    digest = hashlib.sha256()
    for path in sorted(Path(root).rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def refresh_stale_cache(dispatcher, stamp: str | None = None) -> bool:
    """Empty a numba dispatcher's disk cache when the sources compiled into it have changed.

    numba invalidates a cached function when its own source file changes, not when a function
    it calls (and compiles into itself) does: after a brake model's file changes,
    :func:`advance` would keep running the old model. The stamp of the sources is kept beside
    the function's cache; call this before the dispatcher's first call.

    Parameters
    ----------
    dispatcher
        A function compiled with ``cache=True`` (anything else is left alone).
    stamp : str, optional
        Stamp of the sources it depends on (default: :func:`sources_stamp` of the physics
        package).

    Returns
    -------
    bool
        The cache was emptied (a first run counts: no stamp yet).
    """
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "cache_path", None)
    if path is None or not hasattr(cache, "flush"):
        return False  # not cached (or numba absent)
    stamp = stamp if stamp is not None else sources_stamp()
    func = dispatcher.py_func
    module = os.path.splitext(os.path.basename(func.__code__.co_filename))[0]
    stamp_file = Path(path) / f"{module}.{func.__qualname__}.sources"
    try:
        if stamp_file.read_text() == stamp:
            return False
    except OSError:
        pass
    try:
        from ...outputs import write_replacing

        cache.flush()
        write_replacing(stamp_file, stamp)
    except OSError:  # a read-only cache: numba does not write there either
        return False
    return True


def refresh_stale_caches(namespace: dict, stamp: str | None = None) -> int:
    """:func:`refresh_stale_cache` for every cached function a module defines.

    Parameters
    ----------
    namespace : dict
        The module's ``globals()`` (or ``vars(module)``).
    stamp : str, optional
        As for :func:`refresh_stale_cache`, computed once.

    Returns
    -------
    int
        How many caches were emptied.
    """
    stamp = stamp if stamp is not None else sources_stamp()
    name = namespace.get("__name__")
    return sum(refresh_stale_cache(f, stamp) for f in list(namespace.values())
               if getattr(getattr(f, "py_func", None), "__module__", None) == name)


#: :func:`sources_stamp` of this installation, computed once at import.
SOURCES_STAMP = sources_stamp()
# a compiled function's twin for calls from Python compiles the same sources
equations.on_python_twin(lambda twin: refresh_stale_cache(twin, SOURCES_STAMP))
for _namespace in (globals(), *(vars(m) for m in MODELS.values())):
    refresh_stale_caches(_namespace, SOURCES_STAMP)
del _namespace


def check_fields(params) -> None:
    """Check the combinations of a model's fields (its optional ``check_fields``).

    Parameters
    ----------
    params : dataclass
        A brake model's ``Params``.

    Raises
    ------
    CompileError
        Naming the first field of a combination that cannot be, and the other in the reason.
    """
    check = getattr(model_of(params), "check_fields", None)
    if check is not None:
        check(params)


def validity(consist, params) -> list[str]:
    """Where a run of ``consist`` leaves its brake model's validated range (the model's
    optional ``validity(consist, params)``).

    Parameters
    ----------
    consist : Consist
    params : BrakeParams or dataclass
        The run's brake parameters, or its model's ``Params``.

    Returns
    -------
    list of str
        One sentence per reason; empty inside the range (or for a model without one).
    """
    pneumatic = getattr(params, "pneumatic", params)
    check = getattr(model_of(pneumatic), "validity", None)
    return [] if check is None else list(check(consist, pneumatic))


def model_of(params) -> Any:
    """The registered brake model whose ``Params`` type ``params`` is (its module)."""
    return parameters.model_of(MODELS, params)


@dataclass(frozen=True, init=False)
class BrakeParams:
    """Brake parameters of a run: the brake model's, the friction law's, the brake-heat
    model's, and their file.

    Besides ``pneumatic``, ``friction`` and ``thermal``, every field of the three is readable
    as an attribute (``params.t_app_s``, ``params.k0``) and may be given by name to the
    constructor or to :func:`dataclasses.replace`.

    Parameters
    ----------
    pneumatic : dataclass, optional
        The brake model's ``Params`` (default: ``model``'s defaults).
    friction : friction.Params, optional
        Friction parameters (default: the paper's).
    source : str, optional
        File the values came from.
    thermal : thermal.Params, optional
        Block and wheel temperature parameters (default: :class:`.thermal.Params`).
    model : str, optional
        Registered model name, when ``pneumatic`` is not given (default :data:`DEFAULT_MODEL`).
    **fields
        Values of individual fields of any part.

    Attributes
    ----------
    pneumatic : dataclass
    friction : friction.Params
    thermal : thermal.Params
    source : str

    Examples
    --------
    >>> from ltd_brake_ros import load_brake_params
    >>> p = load_brake_params()  # the paper's Table 3, K0 = 2.72
    >>> p.pneumatic.t_fill_s     # doctest: +SKIP
    """

    pneumatic: Any
    friction: friction.Params
    thermal: thermal.Params
    source: str

    def __init__(self, pneumatic=None, friction=None, source: str = "built-in defaults", *,
                 thermal=None, model: str | None = None, **fields):
        from . import friction as friction_module
        from . import thermal as thermal_module

        if pneumatic is None:
            name = model or DEFAULT_MODEL
            if name not in MODELS:
                raise ValueError(f"unknown brake model {name!r}; known: {', '.join(MODELS)}")
            pneumatic = MODELS[name].Params()
        elif model is not None and model_of(pneumatic).NAME != model:
            raise ValueError(f"model {model!r} does not match {type(pneumatic).__qualname__}")
        friction = friction_module.Params() if friction is None else friction
        thermal = thermal_module.Params() if thermal is None else thermal
        parts = {"pneumatic": pneumatic, "friction": friction, "thermal": thermal}
        for part, value in parts.items():
            names = {f.name for f in dataclasses.fields(value)}
            mine = {k: fields.pop(k) for k in list(fields) if k in names}
            if mine:
                parts[part] = dataclasses.replace(value, **mine)
        if fields:
            raise TypeError(f"brake model {model_of(pneumatic).NAME!r} has no parameter "
                            f"{', '.join(map(repr, fields))}")
        object.__setattr__(self, "pneumatic", parts["pneumatic"])
        object.__setattr__(self, "friction", parts["friction"])
        object.__setattr__(self, "thermal", parts["thermal"])
        object.__setattr__(self, "source", str(source))

    @property
    def model(self) -> str:
        """Name of the brake model."""
        return model_of(self.pneumatic).NAME

    def __getattr__(self, name: str):
        # only called for names that are not attributes: the fields of the two parts
        if not name.startswith("_"):
            for part in ("pneumatic", "friction", "thermal"):
                value = self.__dict__.get(part)
                if value is not None and hasattr(value, name):
                    return getattr(value, name)
        raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")

"""Trains compiled for the kernel: the model arrays of a set of inputs (built once and kept
for the simulators that follow), and whether the kernels themselves are compiled yet."""
from __future__ import annotations

import threading

import numpy as np

from .inputs import BrakeParams, Consist, InputError, Track, model_warnings
from .physics import brakes as brakes_module
from .physics import couplers, kernel
from .physics.brakes import friction, thermal
from .physics.equations import centre_offsets_m, curve_resistance_N_per_kN
from .verdicts import TrainLimits, train_limits

__all__ = ["build_model", "compile_kind", "compile_notice", "compiled_train", "kernels_cached"]


class _Compiled:
    """A train compiled for the kernel, its limits and the kernel bound for its arguments."""

    __slots__ = ("consist", "model", "limits", "run_loop", "braked_weight_percent", "warnings")

    def __init__(self, consist: Consist, model: kernel.TrainModel, limits: TrainLimits,
                 warnings: tuple = ()):
        self.consist, self.model, self.limits, self.run_loop = consist, model, limits, None
        self.braked_weight_percent: float | None = None  # Eq. 11, once asked for
        self.warnings = warnings


#: Trains compiled by :func:`compiled_train`, most recent last.
_COMPILED: dict[tuple, _Compiled] = {}
#: How many :data:`_COMPILED` keeps.
_COMPILED_KEPT = 8
_COMPILED_LOCK = threading.Lock()


def kernels_cached(brake_model: str | None = None, local_steps: bool = False) -> bool | None:
    """Whether a run's compiled step loop is in numba's on-disk cache already.

    Parameters
    ----------
    brake_model : str, optional
        Name of the run's brake model (default: the paper's).
    local_steps : bool, optional
        The run can sub-step part of the train
        (:func:`~ltd_brake_ros.physics.kernel.local_steps_run`).

    Returns
    -------
    bool or None
        False: the next simulator compiles it (seconds, once per installation, machine and
        brake model); True: it loads it; None: numba does not say.
    """
    model = brakes_module.MODELS.get(brake_model or brakes_module.DEFAULT_MODEL)
    if model is None:
        return None
    try:
        # an index holding a compiled overload (the stale-cache check leaves an empty index
        # behind: that is not a compiled kernel)
        loop = kernel._loop(model.ID, bool(local_steps))
        return bool(loop._cache._cache_file._load_index())
    except (AttributeError, OSError, EOFError, ValueError):  # another numba, or no numba
        return None


def compile_kind(consist: Consist | None = None, params: BrakeParams | None = None,
                 tolerance_m_s: float | None = kernel.DEFAULT_TOLERANCE_M_S
                 ) -> tuple[str, bool]:
    """Which compiled step loop a run of ``consist`` uses: its brake model's name and whether
    local time stepping is compiled in (the arguments as for :func:`compile_notice`)."""
    model = brakes_module.DEFAULT_MODEL if params is None else brakes_module.model_of(
        getattr(params, "pneumatic", params)).NAME
    local = consist is not None and kernel.local_steps_run(
        len(consist.vehicles), tolerance_m_s=tolerance_m_s or 0.0)
    return model, bool(local)


def compile_notice(consist: Consist | None = None, params: BrakeParams | None = None,
                   tolerance_m_s: float | None = kernel.DEFAULT_TOLERANCE_M_S,
                   background: bool = False) -> str | None:
    """What to tell the user before a run of ``consist`` that compiles its kernels.

    Parameters
    ----------
    consist : Consist, optional
        The run's train (its length decides whether local time stepping is compiled in).
    params : BrakeParams, optional
        The run's brake parameters (default: the paper's model).
    tolerance_m_s : float, optional
        The run's error tolerance [m/s] (0 or None: fixed steps, without local time stepping).
    background : bool, optional
        The kernels compile in a background process while the run starts as plain Python
        (:mod:`~ltd_brake_ros.first_run`).

    Returns
    -------
    str or None
        One line with the compile's estimated duration
        (:func:`~ltd_brake_ros.user_files.compile_estimate`: the last compile's, or scaled by
        the cores and load the first time); None when the kernels are cached (or numba does
        not say).
    """
    from .user_files import compile_estimate

    model, local = compile_kind(consist, params, tolerance_m_s)
    if kernels_cached(model, local) is not False:
        return None
    seconds, basis = compile_estimate(model, local, beside_a_run=background)
    what = (f"first run only; the {model} brake model{' with local time steps' if local else ''}"
            f", about {seconds:.0f} s {basis}")
    if background:
        return (f"compiling the simulation kernels in the background ({what}): this run starts "
                "at once with them as plain Python, slower, and goes on compiled when they "
                "are ready")
    return f"compiling the simulation kernels ({what})"


def compiled_train(consist: Consist, params: BrakeParams, coupler, track: Track, resistance: bool,
              brakes_on: bool, adhesion=None, rail=None) -> _Compiled:
    """:func:`build_model` and the train's limits, once per set of inputs.

    The inputs are immutable (a consist is known by its identity, held by the entry so that
    the identity stays its own; the others by value) and so is a compiled train: the kernel
    only reads it. A simulator built again from the same loaded files (input files are read
    once per version) takes the train compiled before.
    """
    key = (id(consist), params, coupler, track, resistance, brakes_on, adhesion, rail)
    try:
        with _COMPILED_LOCK:
            hit = _COMPILED.pop(key, None)
            if hit is not None:
                _COMPILED[key] = hit  # the most recent now
                return hit
    except TypeError:  # an input that is not hashable: compiled every time
        key = None
    model = build_model(consist, params, coupler, track, resistance, brakes_on, adhesion)
    hit = _Compiled(consist, model, train_limits(consist, coupler,
                                                 friction_arrays=model.friction,
                                                 coupler_arrays=model.couplers, rail=rail),
                    tuple(model_warnings(consist, params, coupler)))
    if key is not None:
        with _COMPILED_LOCK:
            _COMPILED[key] = hit
            while len(_COMPILED) > _COMPILED_KEPT:
                del _COMPILED[next(iter(_COMPILED))]
    return hit


def build_model(consist: Consist, params: BrakeParams, coupler, track: Track, resistance: bool,
             brakes_on: bool, adhesion=None) -> kernel.TrainModel:
    """The train, its brakes, couplers, traction, track and heat model as the kernel's arrays
    (:class:`~ltd_brake_ros.physics.kernel.TrainModel`).

    Raises
    ------
    InputError
        A model input its model cannot compile (named by file and field).
    """
    vs = consist.vehicles
    n = len(vs)
    mass = np.array([v.mass_kg for v in vs])
    length = np.array([v.length_m for v in vs])
    train = kernel.TrainArrays(mass, mass * np.array([v.inertia_factor for v in vs]),
                               np.array([float(v.axles) for v in vs]),
                               centre_offsets_m(length), 1.0 if resistance else 0.0)
    try:
        fr = friction.compile(consist, params.friction, adhesion)
    except brakes_module.CompileError as exc:
        raise InputError(consist.source, exc.field, exc.reason) from None
    brake_model = brakes_module.model_of(params.pneumatic)
    ba = brake_model.compile(consist, params.pneumatic,
                             fr.force_max_N if brakes_on else np.zeros(n))
    # traction and dynamic brake of powered vehicles (zeros elsewhere)
    tr = [v.traction for v in vs]
    tr_arrays = kernel.TractionArrays(*(
        np.array([getattr(t, name) if t else 0.0 for t in tr])
        for name in kernel.TractionArrays._fields))
    tr_arrays.time_constant_s[tr_arrays.time_constant_s <= 0] = 1.0
    tr_arrays.fade_speed_m_s[tr_arrays.fade_speed_m_s <= 0] = 1.0
    tk = kernel.TrackArrays(float(track.start_chainage_m), np.array(
        [track.chainage_m, track.gradient_permille,
         [curve_resistance_N_per_kN(r) for r in track.radius_m]], float))
    try:
        coupler_arrays = couplers.compile(coupler)
    except couplers.CompileError as exc:
        raise InputError(getattr(coupler, "source", "") or "coupler", exc.field,
                         exc.reason) from None
    return kernel.TrainModel(train, fr, ba, coupler_arrays, tr_arrays, tk,
                             thermal.compile(consist, params.thermal))

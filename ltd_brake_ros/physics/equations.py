"""Equations of the train as a whole, one function each (no ROS, no state).

Scalar functions are compiled with numba so that the integration kernel and the reference
right-hand side share them; they run as plain Python where numba is absent. Units are SI unless
the name says otherwise (``_kmh``, ``_kN``, ``_t``).
"""
from __future__ import annotations

from types import FunctionType as _FunctionType
from types import ModuleType as _ModuleType

import numpy as np


def renamed_copy(fn, qualname: str, **names):
    """A copy of the Python function ``fn`` under another qualified name (numba keeps one disk
    cache per name), with the globals ``names`` replaced."""
    copy = _FunctionType(fn.__code__, dict(fn.__globals__, **names) if names
                         else fn.__globals__, fn.__name__, fn.__defaults__, fn.__closure__)
    copy.__qualname__, copy.__module__, copy.__doc__ = qualname, fn.__module__, fn.__doc__
    return copy


try:  # pragma: no cover - exercised implicitly
    from numba.core.registry import CPUDispatcher

    def _compiled(fn, options, cls=None):
        """The dispatcher of ``fn`` compiled with numba's ``options`` (nopython, cached on
        disk, without the C entry point, which only a ``cfunc`` caller would use and which
        costs compile time)."""
        opts = dict(options, nopython=True, nogil=True, no_cfunc_wrapper=True)
        disp = (cls or _Jit)(py_func=fn, locals={}, targetoptions=opts)
        disp.enable_caching()
        return disp

    def jit(fn):
        """Compile ``fn`` with numba (cached on disk)."""
        return _compiled(fn, {})

    def jit_inline(fn):
        """Compile ``fn`` with numba, inlined into compiled callers.

        For small functions called in the innermost loops with bundles (NamedTuples of
        arrays): a call that is not inlined passes every array of the bundle.
        """
        return _compiled(fn, {"inline": "always"})

    def jit_step(fn):
        """Compile ``fn`` with numba without reference counting of its arrays.

        For the integration step's functions, which allocate nothing and are called several
        times per step with bundles of arrays: numba would otherwise count a reference to
        every array passed in and out of each call (an atomic operation each), which costs
        more than the arithmetic of a short train. Such a function must not create arrays.
        """
        return _compiled(fn, {"_nrt": False})

    def jit_vector(fn):
        """:func:`jit_step` with IEEE division (x / 0 gives inf or NaN instead of raising).

        For loops the compiler should vectorise: a zero check before each division keeps it
        from doing so. Only for divisions whose divisor cannot be zero.
        """
        return _compiled(fn, {"_nrt": False, "error_model": "numpy"})

    def jit_inner(fn):
        """:func:`jit` for a function that compiled code calls (see :class:`_Inner`)."""
        return _Inner.create(fn, {})

    def jit_step_inner(fn):
        """:func:`jit_step` for a function that compiled code calls (see :class:`_Inner`)."""
        return _Inner.create(fn, {"_nrt": False})

    class _Jit(CPUDispatcher):
        """A compiled function of the package: a call from Python runs its plain-Python
        version instead while :func:`run_plain_while` says so."""

        def __call__(self, *args, **kwargs):
            if _plain_while is not None and plain_now():
                return plain(self)(*args, **kwargs)
            return CPUDispatcher.__call__(self, *args, **kwargs)

    class _Inner(_Jit):
        """A compiled function without the entry points a call from Python needs.

        numba builds, for every compiled function, a CPython wrapper that unboxes each
        argument (every array of every bundle, with its checks) and a C wrapper, and compiles
        both to machine code: for the kernel's inner functions, most of the first run's
        compile time, and never used (compiled callers call the native function). A call from
        Python goes to a twin compiled with the wrappers on first use (cached apart).
        """

        #: Called with each twin before its first compile (the physics package checks there
        #: whether its disk cache is stale, see ``brakes.refresh_stale_cache``).
        on_twin = None

        @classmethod
        def create(cls, fn, options):
            """The dispatcher of ``fn`` compiled with numba's ``options`` (cached on disk)."""
            disp = _compiled(fn, dict(options, no_cpython_wrapper=True), cls)
            disp._twin_options = dict(options)
            return disp

        def __call__(self, *args, **kwargs):
            if _plain_while is not None and plain_now():
                return plain(self)(*args, **kwargs)
            twin = self.__dict__.get("_twin")
            if twin is None:
                fn = self.py_func
                twin = _compiled(renamed_copy(fn, fn.__qualname__ + "_from_python"),
                                 self._twin_options)
                if _Inner.on_twin is not None:
                    _Inner.on_twin(twin)
                self._twin = twin
            return twin(*args, **kwargs)

    def on_python_twin(hook):
        """Call ``hook(dispatcher)`` with each twin for calls from Python (see :class:`_Inner`)
        before its first compile."""
        _Inner.on_twin = staticmethod(hook)

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - fallback keeps the package usable, only slower
    CPUDispatcher = None

    def jit(fn):
        """No-op stand-in for the numba decorator."""
        return fn

    jit_inline = jit_step = jit_vector = jit_inner = jit_step_inner = jit

    def on_python_twin(hook):
        """No twins without numba."""

    HAVE_NUMBA = False


# The plain-Python kernels. numba compiles a function on its first call (seconds for the step
# loop, cached on disk afterwards); the same function run as Python gives the same floats
# (IEEE arithmetic, the same libm), a few hundred times slower. A first run can so start at
# once while its kernels compile elsewhere (:mod:`ltd_brake_ros.first_run`).

#: While set: a callable that is true as long as calls from Python into compiled functions run
#: their plain-Python versions (see :func:`run_plain_while`).
_plain_while = None
#: Plain-Python version of each compiled function, by dispatcher (see :func:`plain`).
_PLAIN: dict = {}


def run_plain_while(predicate) -> None:
    """Run the package's compiled functions as plain Python (when called from Python) as long
    as ``predicate()`` is true; it is asked at such calls, and once it is false the compiled
    functions run again for good.

    Parameters
    ----------
    predicate : callable or None
        Cheap to call (it is asked at each call from Python). None: compiled from now on.
    """
    global _plain_while
    _plain_while = predicate


def plain_now() -> bool:
    """Whether calls from Python into compiled functions run as plain Python now
    (:func:`run_plain_while`)."""
    global _plain_while
    predicate = _plain_while
    if predicate is None:
        return False
    if predicate():
        return True
    _plain_while = None
    return False


def _names(code) -> set:
    """Global names a code object (and the functions defined in it) may read."""
    names = set(code.co_names)
    for const in code.co_consts:
        if hasattr(const, "co_names"):
            names |= _names(const)
    return names


def plain(fn):
    """The plain-Python version of a compiled function: its Python source, calling the plain
    versions of the compiled functions it calls (anything else: returned as is).

    Parameters
    ----------
    fn : numba dispatcher or callable

    Returns
    -------
    callable
        Same arguments and results (the same floats) as ``fn``; ``is_plain`` is true of it.
    """
    if CPUDispatcher is None or not isinstance(fn, CPUDispatcher):
        return fn
    py = _PLAIN.get(fn)
    if py is not None:
        return py
    src = fn.py_func
    scope = dict(src.__globals__)
    py = _FunctionType(src.__code__, scope, src.__name__, src.__defaults__, src.__closure__)
    py.__qualname__, py.__module__, py.__doc__ = src.__qualname__, src.__module__, src.__doc__
    py.plain_of = fn
    _PLAIN[fn] = py  # before the callees: a function may call itself
    for name in _names(src.__code__):
        value = scope.get(name)
        if isinstance(value, CPUDispatcher):
            scope[name] = plain(value)
        elif isinstance(value, _ModuleType) and value.__name__.startswith(_PACKAGE):
            scope[name] = _PlainModule(value)  # ``friction.force_scale(...)`` and the like
    return py


_PACKAGE = __name__.split(".", 1)[0] + "."


class _PlainModule:
    """A module of the package as a plain-Python function sees it: its compiled functions
    replaced by their plain versions (so that a plain function never calls compiled code)."""

    def __init__(self, module):
        self._module = module

    def __getattr__(self, name):
        value = getattr(self._module, name)
        if isinstance(value, CPUDispatcher):
            value = plain(value)
        elif isinstance(value, _ModuleType) and value.__name__.startswith(_PACKAGE):
            value = _PlainModule(value)
        setattr(self, name, value)  # looked up once
        return value


def is_plain(fn) -> bool:
    """Whether ``fn`` is a compiled function's plain-Python version (:func:`plain`)."""
    return getattr(fn, "plain_of", None) is not None


from .constants import G, KMH_PER_MS  # noqa: F401 (re-exported)

# The brake equations (Eq. 4-10) live in the brakes family, the coupler's (Eq. 3) in the
# couplers family.


@jit
def resistance_coefficients(mass_kg, axles):
    """Coefficients of Eq. 2 written as F = a0 + a1*V + a2*V^2 (V in km/h).

    Parameters
    ----------
    mass_kg : float
        Weight on rails [kg].
    axles : float
        Number of axles.

    Returns
    -------
    a0 : float
        [N].
    a1 : float
        [N/(km/h)].
    a2 : float
        [N/(km/h)^2].
    """
    q_ax = mass_kg / 1000.0 / axles
    m_t = mass_kg / 1000.0
    return m_t * (2.943 + 89.2 / q_ax), m_t * 0.0306, m_t * 0.122 / (q_ax * axles)


@jit
def resistance_N(mass_kg, axles, speed_m_s):
    """Running resistance, Eq. 2, and its derivative.

    F = M/1000 * (2.943 + 89.2/Q_ax + 0.0306 V + 0.122 V^2 / (Q_ax N_ax)), Q_ax in t, V in km/h.

    Parameters
    ----------
    mass_kg : float
        Weight on rails [kg].
    axles : float
        Number of axles.
    speed_m_s : float
        Speed magnitude [m/s] (>= 0).

    Returns
    -------
    force_N : float
        Resistance magnitude [N].
    dforce_dspeed : float
        Derivative with respect to speed [N/(m/s)].
    """
    a0, a1, a2 = resistance_coefficients(mass_kg, axles)
    v_kmh = KMH_PER_MS * speed_m_s
    return a0 + (a1 + a2 * v_kmh) * v_kmh, (a1 + 2.0 * a2 * v_kmh) * KMH_PER_MS


@jit_inline
def lut_segment(table, x):
    """Index k of the table segment [table[0, k], table[0, k+1]] holding x; -1 below, m-1 above.

    A binary search whose trip count depends on the table's size only, each halving a
    conditional move: no branch to mispredict in the kernel's innermost loops.

    Parameters
    ----------
    table : ndarray, shape (rows, m)
        Row 0 strictly increasing; the other rows hold the values at those points.
    x : float

    Returns
    -------
    int
    """
    n = table.shape[1]
    if x < table[0, 0]:
        return -1
    if x >= table[0, n - 1]:
        return n - 1
    # the segment lies in [lo, lo + size)
    lo, size = 0, n - 1
    while size > 1:
        half = size >> 1
        lo = lo + half if table[0, lo + half] <= x else lo
        size -= half
    return lo


@jit_inline
def lut_segment_near(table, x, guess):
    """:func:`lut_segment`, trying segment ``guess`` first (an earlier lookup's result).

    The kernel looks each coupler's deflection up several times per step, and it moves little
    between lookups: the guess almost always holds, which spares the search (whose branches
    the processor cannot predict).

    Parameters
    ----------
    table : ndarray, shape (rows, m)
        As for :func:`lut_segment`.
    x : float
    guess : int
        A segment index (any value: one outside 0 to m - 2 is ignored).

    Returns
    -------
    int
        The same as ``lut_segment(table, x)``.
    """
    if 0 <= guess < table.shape[1] - 1 and table[0, guess] <= x < table[0, guess + 1]:
        return guess
    return lut_segment(table, x)


@jit
def curve_resistance_N_per_kN(radius_m):
    """Curve resistance per unit weight, Roeckl's formula for standard gauge.

    r = 650 / (R - 55) for R >= 300 m, 500 / (R - 30) for R < 300 m [N/kN]; 0 on straight
    track (R = 0).

    Parameters
    ----------
    radius_m : float
        Curve radius [m] (0 = straight).

    Returns
    -------
    float
        [N/kN], numerically the same as per mille of equivalent gradient.
    """
    if radius_m <= 0.0:
        return 0.0
    if radius_m >= 300.0:
        return 650.0 / (radius_m - 55.0)
    return 500.0 / (radius_m - 30.0)


def centre_offsets_m(length_m: np.ndarray) -> np.ndarray:
    """Distance of each vehicle's centre behind the head's front [m].

    Parameters
    ----------
    length_m : ndarray
        Length over buffers of each vehicle, head first [m].

    Returns
    -------
    ndarray
    """
    front = np.concatenate(([0.0], np.cumsum(length_m)[:-1]))
    return front + 0.5 * length_m


def k_uic(train_length_m: float) -> float:
    """Length correction of the braked-weight percentage (Eq. 11).

    1 up to 500 m; 0.95 for 501-600 m; 0.90 above 600 m (a national operating rule for trains
    braked in P, confidence M).

    Parameters
    ----------
    train_length_m : float

    Returns
    -------
    float
    """
    if train_length_m <= 500.0:
        return 1.0
    return 0.95 if train_length_m <= 600.0 else 0.90


def train_braked_weight_percent(braked_weights_t, masses_t, train_length_m: float) -> float:
    """Train braked-weight percentage lambda, Eq. 11.

    Parameters
    ----------
    braked_weights_t : array_like
        Braked weight of every vehicle [t] (0 for unbraked ones).
    masses_t : array_like
        Weight on rails of every vehicle [t].
    train_length_m : float
        Length over buffers [m].

    Returns
    -------
    float
        lambda [%].
    """
    return k_uic(train_length_m) * float(np.sum(braked_weights_t)) / float(np.sum(masses_t)) * 100.0

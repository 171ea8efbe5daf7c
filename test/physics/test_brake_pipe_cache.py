"""numba's disk cache of a dispatcher is emptied when a function compiled into it changes."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

from ltd_brake_ros.physics.brakes import refresh_stale_cache, sources_stamp

CALLER = """
import sys
from numba import njit
from model import value

@njit(cache=True)
def dispatch():
    return value()

if sys.argv[1] == "refresh":
    from ltd_brake_ros.physics.brakes import refresh_stale_caches, sources_stamp
    assert refresh_stale_caches(globals(), sources_stamp(sys.argv[2])) == 1
print(dispatch())
"""


def _model(folder, value):
    (folder / "model.py").write_text(textwrap.dedent(f"""
        from numba import njit

        @njit(cache=True)
        def value():
            return {value}
        """))


def _run(folder, mode):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(folder), *sys.path]))
    env.pop("NUMBA_CACHE_DIR", None)  # the cache beside the sources, in the temporary folder
    out = subprocess.run([sys.executable, str(folder / "caller.py"), mode, str(folder)],
                         env=env, capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


def test_a_changed_model_reaches_the_cached_dispatcher_only_with_the_refresh(tmp_path):
    (tmp_path / "caller.py").write_text(CALLER)
    _model(tmp_path, 1)
    assert _run(tmp_path, "plain") == 1  # compiled and cached
    _model(tmp_path, 2)
    # numba checks the caller's file only: the cached caller keeps the old model
    assert _run(tmp_path, "plain") == 1
    # with the stamp of the sources it sees the change; the stamp is kept beside the cache
    assert _run(tmp_path, "refresh") == 2
    assert (tmp_path / "__pycache__" / "caller.dispatch.sources").read_text() == \
        sources_stamp(tmp_path)


def test_stamp_follows_contents_and_names(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    first = sources_stamp(tmp_path)
    assert sources_stamp(tmp_path) == first
    (tmp_path / "a.py").write_text("x = 2\n")
    assert sources_stamp(tmp_path) != first
    (tmp_path / "a.py").write_text("x = 1\n")
    assert sources_stamp(tmp_path) == first
    (tmp_path / "a.py").rename(tmp_path / "b.py")
    assert sources_stamp(tmp_path) != first


def test_functions_without_a_disk_cache_are_left_alone():
    assert refresh_stale_cache(len) is False


def test_the_kernel_step_loops_carry_the_stamp_of_the_models_they_compile_in():
    from pathlib import Path

    from ltd_brake_ros.physics import brakes, kernel

    for loop in (kernel.run_loop, kernel._loop(0, False), kernel._loop(2, True)):
        cache_path = getattr(getattr(loop, "_cache", None), "cache_path", None)
        assert cache_path is not None, f"{loop} must be compiled with a disk cache"
        stamp = Path(cache_path) / f"kernel.{loop.py_func.__qualname__}.sources"
        assert stamp.read_text() == brakes.SOURCES_STAMP


def test_a_python_call_of_an_inner_function_compiles_a_stamped_twin():
    """Inner functions have no entry point for Python: a call from Python goes to a twin
    compiled apart, whose cache is checked against the sources like every other."""
    from pathlib import Path

    import numpy as np

    from ltd_brake_ros.physics import brakes, step_control

    ratio = step_control._error_ratio
    u = np.array([1.0, 2.0])
    got = ratio(u, u.copy(), u.copy(), np.zeros(2), np.zeros(2, bool), np.zeros(2, bool), 0.01,
                0.01, 1e-3)
    assert got == 0.0  # no change: no error
    twin = ratio._twin
    assert twin.py_func.__qualname__ == "_error_ratio_from_python"
    stamp = Path(twin._cache.cache_path) / "step_control._error_ratio_from_python.sources"
    assert stamp.read_text() == brakes.SOURCES_STAMP

"""Start-up of ``ltd-brake simulate --scenario 6`` as a user meets it: first run, later runs.

Each run is a fresh process (as a user starts it) with its own numba cache folder. The first run
with an empty cache starts at once with the kernels as plain Python while a background process
compiles them (the default); the benchmark then waits for that compile to end, and the later
runs load the kernels, each in its own process. For comparison, a first run that compiles
before it runs (``LTD_BRAKE_FIRST_RUN=wait``, another empty cache) times the compile itself.
Printed, one Markdown table: the whole command's wall time, the start-up the command reports,
the real-time factor it reports (plain Python for the first run), and whether it says it
compiles; then the best of the later runs (the target: a warm whole command <= 1.0 s on an
idle machine), the background compile's duration, the load average while it ran and the
import of the command line alone. The numba caches are the benchmark's own; the user's
private folder (the compile estimates) is a temporary one too.

With ``--kinds``, it compiles each kind of kernels instead (every brake model, a short train
and one with local steps), each in a fresh process with an empty numba cache, and prints the
wall and CPU time of each compile: the CPU time of an idle machine is the first-compile
estimate of :data:`ltd_brake_ros.user_files.FIRST_COMPILE_S`.

Usage::

    python benchmarks/bench_startup.py             # about a minute
    python benchmarks/bench_startup.py --warm 10
    python benchmarks/bench_startup.py --kinds     # a few minutes
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time


#: CPU time [s] (user and system) of every child of this process waited for so far.
_CPU = [0.0]


def _cpu_of_children() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def _run(argv: list[str], env: dict) -> tuple[float, str]:
    """Run ``argv``; its wall time [s] and output. Its CPU time is left in ``_CPU[0]``."""
    before = _cpu_of_children()
    start = time.perf_counter()
    out = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    _CPU[0] = _cpu_of_children() - before
    return wall, out.stdout + out.stderr


def _figures(text: str) -> tuple[float, float]:
    startup = float(re.search(r"start-up\s+([\d.]+) s", text).group(1))
    rtf = float(re.search(r"cost\s+\d+ ms wall, (\d+)x real time", text).group(1))
    return startup, rtf


_FLOOR = """
import gc, sys, time
gc.set_threshold(50_000, 10, 10)  # the garbage collection of ltd-brake, for a fair share
t0 = time.perf_counter()
import numpy as np
import numba
t1 = time.perf_counter()
@numba.njit(cache=True)
def total(a):
    s = 0.0
    for x in a:
        s += x
    return s
total(np.ones(3))
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
gc.freeze()
"""


def _numba_floor(env: dict) -> dict:
    """What importing numba and loading one cached function cost, in fresh processes [s]."""
    folder = tempfile.mkdtemp(prefix="ltd-brake-floor-")
    try:
        script = os.path.join(folder, "floor.py")
        with open(script, "w") as f:
            f.write(_FLOOR)
        runs = []
        for k in range(6):  # the first compiles and caches it
            wall, text = _run([sys.executable, script], env)
            if k:
                runs.append((wall, *map(float, text.split()[-2:])))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    best = min(runs)
    return {"whole program": best[0], "import numpy and numba": best[1],
            "loading the function (numba's code generator set up)": best[2]}


_KIND = """
import sys, time
from ltd_brake_ros.inputs import brake_params_from_mapping, consist_from_mapping
from ltd_brake_ros.simulator import Simulator

model, n = sys.argv[1], int(sys.argv[2])
consist = consist_from_mapping({"name": "kind", "vehicles": [
    {"type": "E402B"}, {"type": "Shimmns", "mass_t": 80.0, "count": n - 1}]}, "kind")
params = brake_params_from_mapping({"model": model}, "kind")
start = time.perf_counter()  # building the simulator compiles part of the kernels
Simulator(consist, 100.0, params).warm_up()
print(time.perf_counter() - start)
"""


def kinds() -> None:
    """Compile every kind of kernels from an empty cache; print wall and CPU time."""
    from ltd_brake_ros.physics.brakes import MODELS
    from ltd_brake_ros.physics.kernel import LOCAL_MIN_VEHICLES

    print(f"| brake model | vehicles | local steps | compile, wall [s] | compile, CPU [s] |")
    print("|---|---:|---|---:|---:|")
    for model in MODELS:
        for n, local in ((33, "no"), (max(101, LOCAL_MIN_VEHICLES), "yes")):
            cache = tempfile.mkdtemp(prefix="ltd-brake-numba-")
            try:
                wall, text = _run([sys.executable, "-c", _KIND, model, str(n)],
                                  dict(os.environ, NUMBA_CACHE_DIR=cache))
            finally:
                shutil.rmtree(cache, ignore_errors=True)
            print(f"| {model} | {n} | {local} | {float(text.split()[-1]):.1f} | "
                  f"{_CPU[0]:.1f} |", flush=True)
    print(f"\nload average (1 min) at the end: {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warm", type=int, default=5, help="later runs (default 5)")
    ap.add_argument("--kinds", action="store_true",
                    help="compile each kind of kernels from an empty cache instead")
    args = ap.parse_args()
    if args.kinds:
        return kinds()
    from ltd_brake_ros.first_run import wait_for_compile

    exe = shutil.which("ltd-brake") or sys.exit("ltd-brake is not on PATH (./dev.sh run ...)")
    argv = [exe, "simulate", "--scenario", "6"]
    caches = [tempfile.mkdtemp(prefix="ltd-brake-numba-") for _ in range(2)]
    private = tempfile.mkdtemp(prefix="ltd-brake-cache-")
    os.environ["XDG_CACHE_HOME"] = private  # where wait_for_compile finds the compile's lock
    env = dict(os.environ, NUMBA_CACHE_DIR=caches[0], LTD_BRAKE_FIRST_RUN="background")
    try:
        rows = []
        start = time.perf_counter()
        wall, text = _run(argv, env)
        rows.append(("first (empty cache)", wall, *_figures(text),
                     "compiling the simulation kernels" in text))
        ended = time.perf_counter()
        wait_for_compile(caches[0])
        waited = time.perf_counter() - ended
        compile_s = time.perf_counter() - start
        warm, cpu = [], []
        for k in range(1, 1 + args.warm):
            wall, text = _run(argv, env)
            warm.append(wall)
            cpu.append(_CPU[0])
            rows.append((f"later #{k}", wall, *_figures(text),
                         "compiling the simulation kernels" in text))
        # the same command without the program's garbage-collection settings (for comparison)
        plain_gc = [sys.executable, "-c", "import sys; from ltd_brake_ros.cli.main import "
                    "_main; sys.exit(_main(['simulate', '--scenario', '6']))"]
        default_gc = []
        for _ in range(args.warm):
            wall, _text = _run(plain_gc, env)
            default_gc.append((wall, _CPU[0]))
        wait_env = dict(env, NUMBA_CACHE_DIR=caches[1], LTD_BRAKE_FIRST_RUN="wait")
        wall, text = _run(argv, wait_env)
        rows.append(("first, compiling before it runs (LTD_BRAKE_FIRST_RUN=wait)", wall,
                     *_figures(text), "compiling the simulation kernels" in text))
        imp, _ = _run([sys.executable, "-c", "import ltd_brake_ros.cli.main"], env)
        floor = _numba_floor(env)
    finally:
        for folder in (*caches, private):
            shutil.rmtree(folder, ignore_errors=True)
    print("| run | whole command [s] | reported start-up [s] | real-time factor | says it "
          "compiles |")
    print("|---|---:|---:|---:|---|")
    for name, wall, startup, rtf, says in rows:
        print(f"| {name} | {wall:.2f} | {startup:.2f} | {rtf:.0f}x | {'yes' if says else 'no'} |")
    print(f"\nwarm whole command, best of {len(warm)}: {min(warm):.2f} s (all: "
          f"{', '.join(f'{w:.2f}' for w in warm)} s); its CPU time (user and system, what "
          f"an idle machine's wall time would be): best {min(cpu):.2f} s (all: "
          f"{', '.join(f'{c:.2f}' for c in cpu)} s)")
    print(f"the same command with Python's default garbage collection, best of "
          f"{len(default_gc)}: {min(w for w, _ in default_gc):.2f} s, CPU time "
          f"{min(c for _, c in default_gc):.2f} s")
    print(f"background compile of the first run: done {compile_s:.1f} s after the command "
          f"started ({waited:.1f} s after it ended)")
    print(f"import of the command line alone: {imp:.2f} s (a fresh interpreter)")
    print("numba's share, in a program that loads one cached numba function (best of 5): "
          + ", ".join(f"{name} {value:.2f} s" for name, value in floor.items()))
    print(f"load average (1 min) at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} "
          "cores")


if __name__ == "__main__":
    main()

"""Start-up of ``ltd-brake simulate --scenario 6`` as a user meets it: first run, later runs.

Each run is a fresh process (as a user starts it) with its own numba cache folder. The first run
with an empty cache starts at once with the kernels as plain Python while a background process
compiles them (the default); the benchmark then waits for that compile to end, and the later
runs load the kernels, each in its own process (``LTD_BRAKE_SERVER=off``) and then handed to
the resident server that the first run started (the default; its socket folder is the
benchmark's own, and it is stopped at the end). For comparison, a first run that compiles before it runs
(``LTD_BRAKE_FIRST_RUN=wait``, another empty cache) times the compile itself. Printed, one
Markdown table: the whole command's wall time, the start-up the command reports, the real-time
factor it reports (plain Python for the first run), and whether it says it compiles; then the
background compile's duration and the import of the command line alone. Targets: first run
<= 10 s on an idle 2-core machine, a later whole command <= 0.5 s, the real-time factor of
scenario 6 >= 3 000x.

Usage::

    python benchmarks/bench_startup.py             # about a minute
    python benchmarks/bench_startup.py --warm 5
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time


def _run(argv: list[str], env: dict) -> tuple[float, str]:
    start = time.perf_counter()
    out = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, out.stdout + out.stderr


def _figures(text: str) -> tuple[float, float]:
    startup = float(re.search(r"start-up\s+([\d.]+) s", text).group(1))
    rtf = float(re.search(r"cost\s+\d+ ms wall, (\d+)x real time", text).group(1))
    return startup, rtf


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warm", type=int, default=3, help="later runs (default 3)")
    args = ap.parse_args()
    from ltd_brake_ros.first_run import wait_for_compile

    exe = shutil.which("ltd-brake") or sys.exit("ltd-brake is not on PATH (./dev.sh run ...)")
    argv = [exe, "simulate", "--scenario", "6"]
    caches = [tempfile.mkdtemp(prefix="ltd-brake-numba-") for _ in range(2)]
    sockets = tempfile.mkdtemp(prefix="ltds-", dir="/tmp")
    env = dict(os.environ, NUMBA_CACHE_DIR=caches[0], LTD_BRAKE_FIRST_RUN="background",
               LTD_BRAKE_SERVER="auto", LTD_BRAKE_SERVER_DIR=sockets)
    alone = dict(env, LTD_BRAKE_SERVER="off")
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
        for k in range(1, 1 + args.warm):
            wall, text = _run(argv, alone)
            rows.append((f"later #{k}, in its own process", wall, *_figures(text),
                         "compiling the simulation kernels" in text))
        _run([exe, "server", "start"], env)  # the first run started it: wait until it answers
        for k in range(1, 1 + args.warm):
            wall, text = _run(argv, env)
            assert "run by the ltd-brake server" in text, text
            rows.append((f"later #{k}, by the resident server", wall, *_figures(text),
                         "compiling the simulation kernels" in text))
        wait_env = dict(alone, NUMBA_CACHE_DIR=caches[1], LTD_BRAKE_FIRST_RUN="wait")
        wall, text = _run(argv, wait_env)
        rows.append(("first, compiling before it runs (LTD_BRAKE_FIRST_RUN=wait)", wall,
                     *_figures(text), "compiling the simulation kernels" in text))
        imp, _ = _run([sys.executable, "-c", "import ltd_brake_ros.cli.main"], env)
    finally:
        subprocess.run([exe, "server", "stop"], env=env, capture_output=True)
        for folder in (*caches, sockets):
            shutil.rmtree(folder, ignore_errors=True)
    print("| run | whole command [s] | reported start-up [s] | real-time factor | says it "
          "compiles |")
    print("|---|---:|---:|---:|---|")
    for name, wall, startup, rtf, says in rows:
        print(f"| {name} | {wall:.2f} | {startup:.2f} | {rtf:.0f}x | {'yes' if says else 'no'} |")
    print(f"\nbackground compile of the first run: done {compile_s:.1f} s after the command "
          f"started ({waited:.1f} s after it ended)")
    print(f"import of the command line alone: {imp:.2f} s (a fresh interpreter)")


if __name__ == "__main__":
    main()

"""Start-up of ``ltd-brake simulate --scenario 6`` as a user meets it: first run, later runs.

Each run is a fresh process (as a user starts it) with its own numba cache folder: the first
run with an empty cache compiles every simulation kernel, the later ones load them. Printed,
one Markdown table: the whole command's wall time, the start-up the command reports
(compiling or loading the kernels), the simulation's own real-time factor, and the import of
the command line alone. Targets: first run <= 10 s on an idle 2-core machine, a later whole
command <= 0.5 s, the real-time factor of scenario 6 >= 3 000x.

Usage::

    python benchmarks/bench_startup.py             # one cold run, three warm (about a minute)
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
    exe = shutil.which("ltd-brake") or sys.exit("ltd-brake is not on PATH (./dev.sh run ...)")
    cache = tempfile.mkdtemp(prefix="ltd-brake-numba-")
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    try:
        rows = []
        for k in range(1 + args.warm):
            wall, text = _run([exe, "simulate", "--scenario", "6"], env)
            startup, rtf = _figures(text)
            rows.append(("first (empty cache)" if k == 0 else f"later #{k}", wall, startup,
                         rtf, "compiling the simulation kernels" in text))
        imp, _ = _run([sys.executable, "-c", "import ltd_brake_ros.cli.main"], env)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    print("| run | whole command [s] | reported start-up [s] | real-time factor | says it "
          "compiles |")
    print("|---|---:|---:|---:|---|")
    for name, wall, startup, rtf, says in rows:
        print(f"| {name} | {wall:.2f} | {startup:.2f} | {rtf:.0f}x | {'yes' if says else 'no'} |")
    print(f"\nimport of the command line alone: {imp:.2f} s (a fresh interpreter)")


if __name__ == "__main__":
    main()

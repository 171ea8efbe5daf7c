"""Speed and accuracy of the compiled integrator, printed as one Markdown table.

For each train (E402B + N Shimmns) an emergency stop from 100 km/h is timed on one core in 1 s
chunks (best of a few runs). Where the train is short enough, the same stop is integrated with
``scipy.integrate.solve_ivp``: BDF at the paper's tolerances (rtol 1e-7, atol 1e-8) for the speed
ratio, once with the analytical sparse Jacobian and once with solve_ivp's default dense
finite-difference one, and Radau at rtol 1e-8 as the accuracy reference (stopping distance, per-coupler peak
draft and buff, RMS force-history error, total-variation ratio; see
:func:`ltd_brake_ros.studies.reference.compare`). Then start-up time in a fresh process and a memory
check over a long session.

Usage::

    python benchmarks/bench_integrator.py            # full run (about 5-10 minutes)
    python benchmarks/bench_integrator.py --quick    # a fast subset (about 1 minute)
"""
from __future__ import annotations

import os

# one core: no BLAS/OpenMP threads in the scipy reference (numba runs single-threaded)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402

from ltd_brake_ros.inputs import (consist_from_mapping, get_scenario,  # noqa: E402
                                  load_brake_params)
from ltd_brake_ros.studies.reference import compare, record_stop, reference_stop  # noqa: E402
from ltd_brake_ros.simulator import Commands, SimulationError, Simulator  # noqa: E402

SPEED_KMH = 100.0
PARAMS_FILE = "brake_params/paper.yaml"


@dataclass(frozen=True)
class Case:
    """One row of the table.

    Attributes
    ----------
    wagons : int
        Shimmns wagons behind the E402B.
    mass_t : float
        Wagon mass [t].
    position : str
        Brake position of every vehicle, ``P`` or ``G``.
    simultaneous : bool
        Every vehicle receives the command at once (t_del = 0 in Eq. 6, brake parameter simultaneous: true).
    reference : bool
        Also integrate with solve_ivp.
    repeats : int
        Timed runs (the best counts).
    """

    wagons: int
    mass_t: float
    position: str
    simultaneous: bool = False
    reference: bool = False
    repeats: int = 3

    @property
    def brakes(self) -> str:
        """Short description of the brake setting."""
        if self.position == "P":
            text = f"P, t_fill {self.params().t_fill_s:g} s"
        else:
            text = f"G, t_fill {self.params().t_fill_G_s:g} s"
        return text + (", simultaneous" if self.simultaneous else "")

    @property
    def train(self) -> str:
        """Short description of the train."""
        text = f"E402B + {self.wagons} × {self.mass_t:g} t"
        if (self.wagons, self.mass_t, self.position, self.simultaneous) == (32, 50.0, "P", False):
            text += " (scenario 6)"
        return text

    def params(self):
        """Brake parameters of this case."""
        p = load_brake_params(PARAMS_FILE)
        return dataclasses.replace(p, simultaneous=True) if self.simultaneous else p

    def simulator(self) -> Simulator:
        """A fresh simulator at the initial speed."""
        doc = {"name": self.train, "vehicles": [
            {"type": "E402B", "brake_position": self.position},
            {"type": "Shimmns", "count": self.wagons, "mass_t": self.mass_t,
             "brake_position": self.position}]}
        return Simulator(consist_from_mapping(doc, "<generated>"), SPEED_KMH, self.params())


def full_cases() -> list[Case]:
    """Rows of the full benchmark."""
    return [
        Case(8, 80.0, "P", reference=True, repeats=7),
        Case(32, 50.0, "P", reference=True, repeats=7),  # scenario 6
        Case(64, 80.0, "G", reference=True, repeats=5),
        Case(150, 80.0, "G", reference=True, repeats=5),
        Case(300, 80.0, "G", repeats=2),
        Case(1000, 80.0, "G", repeats=1),
        Case(150, 80.0, "G", simultaneous=True, reference=True, repeats=5),
        Case(300, 80.0, "G", simultaneous=True, repeats=3),
        Case(1000, 80.0, "G", simultaneous=True, repeats=3),
    ]


def quick_cases() -> list[Case]:
    """Rows of ``--quick``."""
    return [
        Case(32, 50.0, "P", reference=True, repeats=3),
        Case(150, 80.0, "G", repeats=2),
        Case(1000, 80.0, "G", simultaneous=True, repeats=1),
    ]


def log(msg: str) -> None:
    """Progress on stderr (the table goes to stdout)."""
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- measurements


def time_stop(case: Case, chunk_s: float = 1.0, max_time_s: float = 400.0) -> dict:
    """Time an emergency stop in chunks; best wall time of ``case.repeats`` runs."""
    best = None
    for _ in range(case.repeats):
        sim = case.simulator()
        failed_at = None
        start = time.perf_counter()
        try:
            sim.advance(chunk_s, Commands(emergency=True))
            while sim.stop_time_s is None and sim.time_s < max_time_s:
                sim.advance(chunk_s)
        except SimulationError:
            failed_at = sim.time_s
        wall = time.perf_counter() - start
        if best is None or wall < best["wall_s"]:
            exc = sim.lut_excursion_m
            best = dict(wall_s=wall, sim_s=sim.time_s, steps=sim.steps,
                        iters=sim.newton_iterations, max_iters=sim.max_newton_iterations,
                        failed_at=failed_at, stopped=sim.stop_time_s is not None,
                        distance_m=sim.stopping_distance_m,
                        lut_out=int(np.count_nonzero(exc)), lut_out_mm=float(exc.max()) * 1e3,
                        draft_kN=float(sim.peak_draft_N.max()) / 1e3,
                        buff_kN=float(sim.peak_buff_N.min()) / 1e3)
    return best


def accuracy(case: Case) -> dict | None:
    """solve_ivp references of the case and the simulator's errors against the tight one."""
    sim = case.simulator()
    try:
        time_s, force_N = record_stop(sim)
    except SimulationError as exc:
        log(f"  no comparison: {exc}")
        return None
    log(f"  solve_ivp BDF rtol 1e-7 ({sim.n} vehicles), sparse analytical Jacobian ...")
    fast = reference_stop(case.simulator(), time_s, method="BDF", rtol=1e-7, atol=1e-8)
    log(f"    {fast.wall_time_s:.1f} s, {fast.steps} steps; dense finite-difference Jacobian ...")
    dense = reference_stop(case.simulator(), time_s, method="BDF", rtol=1e-7, atol=1e-8,
                           jacobian="fd")
    log(f"    {dense.wall_time_s:.1f} s, {dense.steps} steps; Radau rtol 1e-8 ...")
    # peaks from a fine grid: 1 ms (2 ms for long trains, to bound the stored samples)
    tight = reference_stop(case.simulator(), time_s, method="Radau", rtol=1e-8, atol=1e-9,
                           peak_dt_s=1e-3 if sim.n <= 50 else 2e-3)
    log(f"    {tight.wall_time_s:.1f} s, {tight.steps} steps")
    acc = compare(tight, time_s, force_N, sim.stopping_distance_m, sim.peak_draft_N,
                  sim.peak_buff_N)
    return dict(fast=fast, dense=dense, tight=tight, acc=acc)


def startup_s(repeats: int = 3) -> tuple[float, float, float]:
    """Import-to-first-chunk time in fresh processes, after one run that warms the cache.

    Returns
    -------
    best_s, worst_s : float
        Shortest and longest import-to-first-chunk time [s].
    process_s : float
        Shortest wall time of a whole process, interpreter start-up included [s].
    """
    code = textwrap.dedent("""
        import time
        t0 = time.perf_counter()
        from ltd_brake_ros.inputs import get_scenario, load_brake_params
        from ltd_brake_ros.simulator import Commands, Simulator
        sc = get_scenario(6)
        sim = Simulator(sc.consist(), sc.speed_kmh, load_brake_params())
        sim.advance(1.0, Commands(emergency=True))
        print(time.perf_counter() - t0)
    """)
    inner, whole = [], []
    for k in range(repeats + 1):
        start = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True)
        if k:
            inner.append(float(out.stdout.split()[-1]))
            whole.append(time.perf_counter() - start)
    return min(inner), max(inner), min(whole)


def rss_kB() -> int:
    """Resident set size of this process [kB]."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return -1


def memory_check(t1_s: float, t2_s: float) -> dict:
    """RSS after t1_s and t2_s of simulated time: scenario 6 stopped, then held at standstill."""
    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh, load_brake_params())
    sim.advance(1.0, Commands(emergency=True))
    marks = {}
    for mark in (t1_s, t2_s):
        while sim.time_s < mark - 1e-9:
            sim.advance(1.0)
        marks[mark] = rss_kB()
    return dict(rss1=marks[t1_s], rss2=marks[t2_s], steps=sim.steps, stopped=sim.stopped)


# --------------------------------------------------------------------------- table


def fmt(x: float, digits: int = 2) -> str:
    """Number or an em dash."""
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else \
        f"{x:.{digits}f}"


def row(case: Case, t: dict, ref: dict | None) -> str:
    """One Markdown table row."""
    rtf = t["sim_s"] / t["wall_s"]
    its = t["iters"] / max(t["steps"], 1)
    fails = "0" if t["failed_at"] is None else f"1 (t = {t['failed_at']:.2f} s)"
    lut = "0" if not t["lut_out"] else f"{t['lut_out']} (≤ {t['lut_out_mm']:.1f} mm)"
    cells = [case.train, case.brakes, f"{t['sim_s']:.0f}", f"{t['wall_s']:.3f}",
             f"{rtf:,.0f}×", f"{t['steps']}", f"{its:.2f} ({t['max_iters']})", fails]
    if ref:
        acc = ref["acc"]
        cells += [f"{ref['fast'].wall_time_s / t['wall_s']:,.0f}× / "
                  f"{ref['dense'].wall_time_s / t['wall_s']:,.0f}×",
                  f"{acc.stopping_distance_percent:+.4f}",
                  f"{acc.peak_draft_percent:.2f} / {acc.peak_buff_percent:.2f}",
                  f"{acc.force_rms_percent:.2f}", f"{acc.total_variation_ratio:.3f}"]
    else:
        cells += ["—"] * 5
    cells += [f"{t['draft_kN']:.0f} / {t['buff_kN']:.0f}", lut]
    return "| " + " | ".join(cells) + " |"


HEADER = ("| train | brakes | sim. time [s] | wall [s] | real-time factor | steps "
          "| Newton it./step (max) | failures | vs solve_ivp BDF (sparse / dense Jac.) "
          "| stop. dist. err. [%] "
          "| peak draft / buff err. [%] | force RMS err. [% of peak] | TV ratio "
          "| peak draft / buff [kN] | couplers beyond LUT |\n"
          "|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---|")


def main(argv=None) -> int:
    """Run the benchmark and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a fast subset")
    args = ap.parse_args(argv)
    cases = quick_cases() if args.quick else full_cases()
    started = time.perf_counter()

    log("warming up the compiled kernel ...")
    warm = Case(2, 80.0, "P", repeats=1)
    time_stop(warm)
    rows, refs = [], []
    for case in cases:
        log(f"{case.train}, {case.brakes}: timing ...")
        t = time_stop(case)
        ref = accuracy(case) if case.reference else None
        rows.append(row(case, t, ref))
        if ref:
            refs.append((case, ref))
    log("start-up ...")
    start_best, start_worst, process_s = startup_s()
    t1, t2 = (120.0, 600.0) if args.quick else (600.0, 3600.0)
    log(f"memory over {t2:.0f} s of simulated time ...")
    mem = memory_check(t1, t2)

    print(f"Emergency stop from {SPEED_KMH:g} km/h, 10 ms BDF2 steps, 1 s chunks, one core "
          f"(best of repeated runs). Errors against solve_ivp Radau (rtol 1e-8, atol 1e-9). "
          f"Speed ratio against solve_ivp BDF at the paper's tolerances (rtol 1e-7, atol "
          f"1e-8) on the same compiled right-hand side, measured in the same run: with the "
          f"analytical sparse Jacobian / with solve_ivp's default dense finite-difference "
          f"Jacobian.\n")
    print(HEADER)
    for line in rows:
        print(line)
    print()
    for case, ref in refs:
        f, d, g = ref["fast"], ref["dense"], ref["tight"]
        print(f"* {case.train} ({case.brakes}): solve_ivp BDF {f.wall_time_s:.2f} s wall "
              f"with the sparse Jacobian ({f.steps} steps, {f.nfev} RHS calls), "
              f"{d.wall_time_s:.2f} s with the dense one ({d.steps} steps); Radau "
              f"{g.wall_time_s:.2f} s ({g.steps} steps); reference stop at "
              f"{g.end_time_s:.2f} s, {g.stopping_distance_m:.3f} m.")
    print(f"* Start-up (fresh process, warm compilation cache, scenario 6): import to first "
          f"1 s chunk {start_best:.2f} s (slowest of 3: {start_worst:.2f} s); whole process "
          f"{process_s:.2f} s.")
    print(f"* Memory (scenario 6 stopped, then held at standstill in 1 s chunks): RSS "
          f"{mem['rss1'] / 1024:.1f} MB after {t1 / 60:.0f} min, {mem['rss2'] / 1024:.1f} MB "
          f"after {t2 / 60:.0f} min of simulated time (growth {mem['rss2'] - mem['rss1']} kB, "
          f"{mem['steps']} steps).")
    print(f"* Brake settings: {PARAMS_FILE} (Table 3 of the paper). P: t_fill as there; G: "
          f"every vehicle in brake position G (UIC 540 filling time t_fill_G_s, release "
          f"t_release_G_s), head-end command propagating at v_air; simultaneous: every vehicle "
          f"commanded at once (t_del = 0 in Eq. 6, brake parameter simultaneous: true). Peak forces and LUT excursions are "
          f"from the timed run.")
    print(f"* Total benchmark time {time.perf_counter() - started:.0f} s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())

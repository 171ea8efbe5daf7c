"""Speed and accuracy of the compiled integrator, printed as Markdown tables.

For each train (E402B + N Shimmns) an emergency stop from 100 km/h is timed on one core in 1 s
chunks (best of a few runs, or of as many as fit in 2 s for short rows; CPU time of this process,
so that other load on the machine counts less), with the simulator's default local error control
(``tolerance_m_s``) and nominal step (10 ms) unless the row says otherwise ("fixed 10 ms": no error
control). Per row: real-time factor, steps taken, rejected and the smallest step, Newton iterations
and failures, and the accuracy against a reference: for trains short enough,
``scipy.integrate.solve_ivp`` Radau at rtol 1e-8 (:func:`ltd_brake_ros.studies.reference.compare`:
stopping distance, per-coupler peak draft and buff, RMS force-history error as a percentage of the
peak, total-variation ratio), with the speed ratio against solve_ivp BDF at the paper's tolerances
(analytical sparse / default dense Jacobian); for the longest trains the same kernel at a 10x
smaller tolerance. Then the cost of the whole path (the ``emergency_stop`` API and ``ltd-brake
simulate`` in this process) against the kernel's own time, the per-call cost of
``Simulator.advance``, start-up in a fresh process and memory over a long session.

Usage::

    python benchmarks/bench_integrator.py            # full run (about 15-25 minutes)
    python benchmarks/bench_integrator.py --quick    # a fast subset (about 1-2 minutes)
    python benchmarks/bench_integrator.py --end-to-end   # the whole-path figures alone (~10 s)
"""
from __future__ import annotations

import os

# one core: no BLAS/OpenMP threads in the scipy reference (numba runs single-threaded)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import dataclasses  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402

from ltd_brake_ros.inputs import (consist_from_mapping, get_scenario,  # noqa: E402
                                  load_brake_params)
from ltd_brake_ros.physics.kernel import DEFAULT_TOLERANCE_M_S  # noqa: E402
from ltd_brake_ros.studies.reference import (ReferenceResult, compare, record_stop,  # noqa: E402
                                             reference_stop)
from ltd_brake_ros.simulator import Commands, SimulationError, Simulator  # noqa: E402

SPEED_KMH = 100.0
PARAMS_FILE = "brake_params/paper.yaml"


#: References: solve_ivp Radau at rtol 1e-8 ("ivp"), or this kernel at a 10x smaller tolerance
#: ("tight"), for trains too long for solve_ivp.
IVP, TIGHT = "ivp", "tight"


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
        Every vehicle receives the command at once (t_del = 0 in Eq. 6, brake parameter
        simultaneous: true).
    reference : str or None
        :data:`IVP`, :data:`TIGHT` or None (no accuracy figures).
    repeats : int
        Timed runs (the best counts).
    tolerance_m_s : float
        The simulator's local error tolerance [m/s] (0: fixed steps).
    step_s : float
        Nominal step [s].
    local_steps : bool
        Local time stepping (the simulator's default); False: the whole train steps shorter.
    """

    wagons: int
    mass_t: float
    position: str
    simultaneous: bool = False
    reference: str | None = None
    repeats: int = 3
    tolerance_m_s: float = DEFAULT_TOLERANCE_M_S
    step_s: float = 0.01
    local_steps: bool = True

    @property
    def brakes(self) -> str:
        """Short description of the brake setting, its model named (the paper's empirical one
        on every row, long trains beyond its 500 m range included: the integrator is timed on
        the same model throughout)."""
        model = "empirical" if self.params().model == "uic_empirical" else self.params().model
        if self.position == "P":
            text = f"{model}, P, t_fill {self.params().t_fill_s:g} s"
        else:
            text = f"{model}, G, t_fill {self.params().t_fill_G_s:g} s"
        return text + (", simultaneous" if self.simultaneous else ", from the head")

    @property
    def train(self) -> str:
        """Short description of the train."""
        text = f"E402B + {self.wagons} × {self.mass_t:g} t"
        if (self.wagons, self.mass_t, self.position, self.simultaneous) == (32, 50.0, "P", False):
            text += " (scenario 6)"
        return text

    @property
    def steps(self) -> str:
        """Short description of the step control."""
        nominal = f"{self.step_s * 1e3:g} ms"
        if not self.tolerance_m_s:
            return f"fixed {nominal}"
        text = f"tol. {self.tolerance_m_s:g} m/s"
        if not self.local_steps:
            text += ", whole-train steps"
        return text if self.step_s == 0.01 else f"{text}, nominal {nominal}"

    def params(self):
        """Brake parameters of this case."""
        p = load_brake_params(PARAMS_FILE)
        return dataclasses.replace(p, simultaneous=True) if self.simultaneous else p

    def simulator(self, tolerance_m_s: float | None = None) -> Simulator:
        """A fresh simulator at the initial speed (with this case's tolerance by default)."""
        doc = {"name": self.train, "vehicles": [
            {"type": "E402B", "brake_position": self.position},
            {"type": "Shimmns", "count": self.wagons, "mass_t": self.mass_t,
             "brake_position": self.position}]}
        tol = self.tolerance_m_s if tolerance_m_s is None else tolerance_m_s
        return Simulator(consist_from_mapping(doc, "<generated>"), SPEED_KMH, self.params(),
                         step_s=self.step_s, tolerance_m_s=tol, local_steps=self.local_steps)


def full_cases() -> list[Case]:
    """Rows of the full benchmark."""
    return [
        Case(8, 80.0, "P", reference=IVP, repeats=7),
        Case(32, 50.0, "P", reference=IVP, repeats=7),  # scenario 6
        Case(32, 50.0, "P", reference=IVP, repeats=7, tolerance_m_s=0.0),
        # the nominal step bounds the peaks' accuracy too: twice as long at the same tolerance
        Case(32, 50.0, "P", reference=IVP, repeats=7, step_s=0.02),
        Case(64, 80.0, "G", reference=IVP, repeats=5),
        Case(150, 80.0, "G", reference=IVP, repeats=5),
        Case(150, 80.0, "G", reference=IVP, repeats=5, tolerance_m_s=0.0),
        Case(300, 80.0, "G", reference=TIGHT, repeats=2),
        Case(1000, 80.0, "G", reference=TIGHT, repeats=3),
        Case(1000, 80.0, "G", reference=TIGHT, repeats=1, local_steps=False),
        Case(1000, 80.0, "G", reference=TIGHT, repeats=1, tolerance_m_s=0.0),
        Case(1000, 80.0, "G", reference=TIGHT, repeats=1, tolerance_m_s=0.01),
        Case(150, 80.0, "G", simultaneous=True, reference=IVP, repeats=5),
        Case(1000, 80.0, "G", simultaneous=True, reference=TIGHT, repeats=3),
    ]


def quick_cases() -> list[Case]:
    """Rows of ``--quick``."""
    return [
        Case(32, 50.0, "P", reference=IVP, repeats=3),
        Case(150, 80.0, "G", reference=TIGHT, repeats=2),
        Case(1000, 80.0, "G", simultaneous=True, repeats=1),
    ]


def log(msg: str) -> None:
    """Progress on stderr (the tables go to stdout)."""
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- measurements


def cpu_s() -> float:
    """CPU time of this process [s]."""
    return time.process_time()


#: Short rows repeat until their runs add up to this much CPU time [s] (at most
#: :data:`MAX_REPEATS` runs): on a shared machine a few back-to-back runs of a few
#: milliseconds can all fall in one slow moment.
MIN_TIMED_S, MAX_REPEATS = 2.0, 300


def time_stop(case: Case, chunk_s: float = 1.0, max_time_s: float = 400.0) -> dict:
    """Time an emergency stop in chunks; best CPU time of ``case.repeats`` runs, or of as
    many more as fit in :data:`MIN_TIMED_S`."""
    best = None
    runs = spent = 0
    while runs < case.repeats or (spent < MIN_TIMED_S and runs < MAX_REPEATS):
        runs += 1
        sim = case.simulator()
        failed_at = None
        start = cpu_s()
        try:
            sim.advance(chunk_s, Commands(emergency=True))
            while sim.stop_time_s is None and sim.time_s < max_time_s:
                sim.advance(chunk_s)
        except SimulationError:
            failed_at = sim.time_s
        wall = cpu_s() - start
        spent += wall
        if best is None or wall < best["wall_s"]:
            exc = sim.lut_excursion_m
            best = dict(wall_s=wall, sim_s=sim.time_s, stats=sim.stats, failed_at=failed_at,
                        stopped=sim.stop_time_s is not None, distance_m=sim.stopping_distance_m,
                        lut_out=int(np.count_nonzero(exc)), lut_out_mm=float(exc.max()) * 1e3,
                        draft_kN=float(sim.peak_draft_N.max()) / 1e3,
                        buff_kN=float(sim.peak_buff_N.min()) / 1e3)
    return best


def kernel_reference(case: Case) -> ReferenceResult:
    """The case run by this kernel at a 10x smaller tolerance than the default, the whole
    train stepping together (no local time stepping: a reference independent of it), sampled
    at the end of every nominal step."""
    tolerance = DEFAULT_TOLERANCE_M_S / 10.0
    sim = dataclasses.replace(case, local_steps=False).simulator(tolerance)
    start = cpu_s()
    t, f = record_stop(sim)
    wall = cpu_s() - start
    st = sim.stats
    return ReferenceResult(
        method="kernel", rtol=tolerance, atol=0.0, jacobian="tridiagonal",
        stopped=True, end_time_s=sim.time_s, stopping_distance_m=sim.stopping_distance_m,
        sample_time_s=t, coupler_force_N=f, speed_m_s=np.zeros((t.size, 0)),
        peak_draft_N=sim.peak_draft_N, peak_buff_N=sim.peak_buff_N, steps=st.steps,
        nfev=st.newton_iterations + st.steps, njev=0, nlu=st.newton_iterations,
        wall_time_s=wall)


_REFERENCES: dict = {}


def accuracy(case: Case) -> dict | None:
    """References of the case and the simulator's errors against the tight one."""
    sim = case.simulator()
    try:
        time_s, force_N = record_stop(sim)
    except SimulationError as exc:
        log(f"  no comparison: {exc}")
        return None
    out = {}
    key = (case.wagons, case.mass_t, case.position, case.simultaneous)
    if case.reference == TIGHT:
        if key not in _REFERENCES:
            log(f"  this kernel at tolerance {DEFAULT_TOLERANCE_M_S / 10.0:g} m/s ...")
            _REFERENCES[key] = {"tight": kernel_reference(case)}
        out.update(_REFERENCES[key])
    else:
        if key not in _REFERENCES:
            ref = {}
            log(f"  solve_ivp BDF rtol 1e-7 ({sim.n} vehicles), sparse analytical Jacobian ...")
            ref["fast"] = reference_stop(case.simulator(), time_s, method="BDF", rtol=1e-7,
                                         atol=1e-8)
            log(f"    {ref['fast'].wall_time_s:.1f} s; dense finite-difference Jacobian ...")
            ref["dense"] = reference_stop(case.simulator(), time_s, method="BDF", rtol=1e-7,
                                          atol=1e-8, jacobian="fd")
            log(f"    {ref['dense'].wall_time_s:.1f} s; Radau rtol 1e-8 ...")
            # reference samples every 5 ms (the nominal steps' ends are among them), peaks
            # from a 1 ms grid (2 ms for long trains, to bound the stored samples)
            ref["tight"] = reference_stop(case.simulator(), np.arange(0.0, 600.0, 0.005),
                                          method="Radau", rtol=1e-8, atol=1e-9,
                                          peak_dt_s=1e-3 if sim.n <= 50 else 2e-3)
            log(f"    {ref['tight'].wall_time_s:.1f} s")
            _REFERENCES[key] = ref
        out.update(_REFERENCES[key])
    out["acc"] = compare(out["tight"], time_s, force_N, sim.stopping_distance_m,
                         sim.peak_draft_N, sim.peak_buff_N)
    return out


def end_to_end(repeats: int = 60) -> dict:
    """Scenario 6 through the kernel, the ``emergency_stop`` API and ``ltd-brake simulate``.

    The kernel: a constructed simulator advanced in 1 s chunks to the stop. The API: one
    :func:`~ltd_brake_ros.studies.runs.emergency_stop` call from a loaded consist (simulator
    construction, run with its chunks grouped while the stop is far, summary). The command:
    ``ltd-brake simulate --scenario 6 --json`` in this process (arguments, input files,
    construction, run, summary, verdicts, JSON), and the cost of its run and summary as it
    reports it, on this process's CPU clock. Best CPU time of ``repeats`` runs each,
    interleaved.
    """
    from unittest import mock

    from ltd_brake_ros.cli.main import main
    from ltd_brake_ros.studies.runs import emergency_stop

    sc = get_scenario(6)
    consist, params = sc.consist(), load_brake_params()

    def kernel():
        sim = Simulator(consist, sc.speed_kmh, params)
        start = cpu_s()
        sim.advance(1.0, Commands(emergency=True))
        while sim.stop_time_s is None:
            sim.advance(1.0)
        return cpu_s() - start, sim.time_s

    def api():
        start = cpu_s()
        emergency_stop(consist, sc.speed_kmh, params)
        return cpu_s() - start

    def command():
        out = io.StringIO()
        start = cpu_s()
        # the command times its run with time.perf_counter: the wall clock, which other load
        # on the machine stretches; here it reads CPU time, as everything timed here does
        with contextlib.redirect_stdout(out), mock.patch("time.perf_counter", cpu_s):
            main(["simulate", "--scenario", "6", "--json"])
        # and the run's own cost as the command reports it (run and summary)
        return cpu_s() - start, json.loads(out.getvalue())["wall_time_s"]

    kernel(), api(), command()  # warm: compiled code and input files loaded once
    k, a, c, r = [], [], [], []
    for _ in range(repeats):
        k.append(kernel()[0])
        a.append(api())
        whole, run = command()
        c.append(whole)
        r.append(run)
    sim_s = kernel()[1]
    return dict(sim_s=sim_s, kernel_s=min(k), api_s=min(a), command_s=min(c),
                command_run_s=min(r))


def end_to_end_line(e2e: dict) -> str:
    """The end-to-end figures of :func:`end_to_end` as one Markdown bullet."""
    k = e2e["kernel_s"]
    return (f"* End to end, scenario 6 ({e2e['sim_s']:.1f} s simulated, best CPU time): kernel "
            f"(Simulator.advance in 1 s chunks) {k * 1e3:.1f} ms ({e2e['sim_s'] / k:,.0f}×); "
            f"emergency_stop API {e2e['api_s'] * 1e3:.1f} ms ({e2e['api_s'] / k:.2f}× the "
            f"kernel, {e2e['sim_s'] / e2e['api_s']:,.0f}×); `ltd-brake simulate --scenario 6 "
            f"--json`: its run and summary (the time it reports, on the CPU clock) "
            f"{e2e['command_run_s'] * 1e3:.1f} ms ({e2e['command_run_s'] / k:.2f}× the kernel, "
            f"{e2e['sim_s'] / e2e['command_run_s']:,.0f}×), the whole command in-process "
            f"(arguments, input files, construction, verdicts, JSON) "
            f"{e2e['command_s'] * 1e3:.1f} ms ({e2e['command_s'] / k:.2f}×, "
            f"{e2e['sim_s'] / e2e['command_s']:,.0f}×).")


def advance_overhead(calls: int = 3000) -> dict:
    """Per-call cost of :meth:`Simulator.advance` against the compiled kernel alone.

    Scenario 6 coasting, one 10 ms step per call: through ``advance`` (commands, snapshot,
    events), through the step loop bound by the simulator called directly with the same bundles
    and work arrays, and through numba's dispatcher of the whole kernel (which types every
    bundle and allocates the work arrays on every call).
    """
    from ltd_brake_ros.physics import kernel

    sc = get_scenario(6)
    sim = Simulator(sc.consist(), sc.speed_kmh, load_brake_params())
    sim.advance(0.01)
    st = sim._state  # the benchmark reaches into the simulator to call its kernel alone
    inputs = kernel.Inputs(st.traction_demand, sim.fext_N)
    ws = sim._workspace[2]  # the work arrays advance keeps between chunks
    best_adv = best_ker = best_disp = math.inf
    args = (sim.model, inputs, st.kinematics, st.brakes, st.events, st.stats[0], sim._options,
            False)
    for _ in range(5):
        start = cpu_s()
        for _ in range(calls):
            sim.advance(0.01)
        best_adv = min(best_adv, (cpu_s() - start) / calls)
        start = cpu_s()
        for _ in range(calls):
            sim._run_loop(1, 0.01, st.time_s, st.last_step_s, sim.model, inputs, st.kinematics,
                          st.brakes, st.events, st.stats[0], sim._options, False, ws)
        best_ker = min(best_ker, (cpu_s() - start) / calls)
        start = cpu_s()
        for _ in range(calls):
            kernel.run_steps(1, 0.01, st.time_s, st.last_step_s, *args)
        best_disp = min(best_disp, (cpu_s() - start) / calls)
    return dict(advance_us=best_adv * 1e6, kernel_us=best_ker * 1e6, dispatch_us=best_disp * 1e6)


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


def coupler_switches(case: Case, sample_s: float = 1e-3) -> dict:
    """Switches of the couplers between Eq. 3's loading and unloading curves in a stop.

    Counted as sign changes of a coupler's deflection rate beyond the band of Eq. 3 between
    samples ``sample_s`` apart (a lower bound: two switches within one sample count as none),
    with the integration's tries (steps taken and rejected) of the case's own timed run per
    switch.
    """
    sim = case.simulator()
    band = float(sim.model.couplers.band_m_s)
    k = sim._state.kinematics  # the benchmark reads the simulator's live state every sample
    sim.advance(sample_s, Commands(emergency=True))
    last = np.zeros(sim.n - 1)
    times = []
    while sim.stop_time_s is None and sim.time_s < 400.0:
        sim.advance(sample_s)
        rate = k.v_m_s[:-1] - k.v_m_s[1:]
        sign = np.where(rate > band, 1.0, np.where(rate < -band, -1.0, 0.0))
        flips = int(np.count_nonzero(sign * last < 0.0))
        times += [sim.time_s] * flips
        last = np.where(sign != 0.0, sign, last)
    return dict(switches=len(times), times=np.array(times))


def error_locality(case: Case, step_s: float = 2e-3, start_s: float = 20.0,
                   end_s: float = 50.0, every_s: float = 0.5) -> dict:
    """How many vehicles one step of the whole train leaves beyond the tolerance.

    Every ``every_s`` from ``start_s`` to ``end_s`` of the case's stop: one step of ``step_s``
    for the whole train from the state at that instant (fixed step), against the same interval
    under a hundredfold smaller tolerance. The vehicles whose speeds then differ by more than
    the case's tolerance are the ones that needed a shorter step; the others did not.

    Returns
    -------
    dict
        ``counts``: such vehicles at each instant; ``vehicles``: the train's vehicles.
    """
    sim = case.simulator()
    fixed = dataclasses.replace(case, step_s=step_s, tolerance_m_s=0.0).simulator()
    tight = dataclasses.replace(case, tolerance_m_s=case.tolerance_m_s / 100.0).simulator()
    sim.advance(every_s, Commands(emergency=True))
    counts = []
    while sim.stop_time_s is None and sim.time_s < end_s - 1e-9:
        sim.advance(every_s)
        if sim.time_s < start_s - 1e-9:
            continue
        for other in (fixed, tight):  # both from this instant's state (the benchmark's licence)
            other._state = sim._state.copy()
            other.advance(step_s)
        err = np.abs(fixed._state.kinematics.v_m_s - tight._state.kinematics.v_m_s)
        counts.append(int(np.count_nonzero(err > case.tolerance_m_s)))
    return dict(counts=np.array(counts), vehicles=sim.n, step_s=step_s, start_s=start_s,
                end_s=end_s)


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


# --------------------------------------------------------------------------- tables


def fmt(x: float, digits: int = 2) -> str:
    """Number or an em dash."""
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else \
        f"{x:.{digits}f}"


def row(case: Case, t: dict, ref: dict | None) -> str:
    """One Markdown table row."""
    st = t["stats"]
    rtf = t["sim_s"] / t["wall_s"]
    its = st.newton_iterations / max(st.steps + st.local_steps, 1)  # per step, local ones too
    fails = "0" if t["failed_at"] is None else f"1 (t = {t['failed_at']:.2f} s)"
    lut = "0" if not t["lut_out"] else f"{t['lut_out']} (≤ {t['lut_out_mm']:.1f} mm)"
    cells = [case.train, case.brakes, case.steps, f"{t['sim_s']:.0f}", f"{t['wall_s']:.3f}",
             f"{rtf:,.0f}×", f"{st.steps}" + (f" (+{st.local_steps} local)" if st.local_steps
                                               else ""),
             f"{st.rejected_steps}" + (f" (+{st.local_rejected_steps} local)"
                                      if st.local_rejected_steps else ""),
             f"{st.smallest_step_s * 1e3:.2g}", f"{its:.2f} ({st.max_newton_iterations})", fails]
    if ref:
        acc = ref["acc"]
        if "fast" in ref:
            vs = (f"{ref['fast'].wall_time_s / t['wall_s']:,.0f}× / "
                  f"{ref['dense'].wall_time_s / t['wall_s']:,.0f}×")
            against = "Radau"
        else:
            vs = "—"
            against = f"tol. {ref['tight'].rtol:g}"
        cells += [against, vs, f"{acc.stopping_distance_percent:+.4f}",
                  f"{acc.peak_draft_percent:.2f} / {acc.peak_buff_percent:.2f}",
                  f"{acc.force_rms_percent:.2f}", f"{acc.total_variation_ratio:.3f}"]
    else:
        cells += ["—"] * 6
    cells += [f"{round(t['draft_kN'])} / {round(t['buff_kN'])}", lut]
    return "| " + " | ".join(cells) + " |"


HEADER = ("| train | brakes | steps | sim. time [s] | CPU [s] | real-time factor | steps taken "
          "| rejected | smallest step [ms] | Newton it./step (max) | failures | reference "
          "| vs solve_ivp BDF (sparse / dense Jac.) | stop. dist. err. [%] "
          "| peak draft / buff err. [%] | force RMS err. [% of peak] | TV ratio "
          "| peak draft / buff [kN] | couplers beyond LUT |\n"
          "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---|")


def main(argv=None) -> int:
    """Run the benchmark and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a fast subset")
    ap.add_argument("--end-to-end", action="store_true",
                    help="only the end-to-end figures of scenario 6 (kernel, emergency_stop API, "
                         "ltd-brake simulate in this process)")
    ap.add_argument("--repeats", type=int, default=None, metavar="N",
                    help="timed runs of each end-to-end path (default 60, interleaved: a run "
                         "costs 6-8 ms, and the best of a few is noisy on a loaded machine)")
    args = ap.parse_args(argv)
    if args.end_to_end:
        log("end to end ...")
        print(end_to_end_line(end_to_end(args.repeats or 60)))
        return 0
    cases = quick_cases() if args.quick else full_cases()
    started = time.perf_counter()

    log("warming up the compiled kernel ...")
    time_stop(Case(2, 80.0, "P", repeats=1))
    rows, refs, timings = [], [], []
    for case in cases:
        log(f"{case.train}, {case.brakes}, {case.steps}: timing ...")
        t = time_stop(case)
        timings.append(t)
        ref = accuracy(case) if case.reference else None
        rows.append(row(case, t, ref))
        if ref and "fast" in ref and case.tolerance_m_s and case.step_s == 0.01:
            refs.append((case, ref))
    switches = None
    if not args.quick:
        long_case, timed = next((c, r) for c, r in zip(cases, timings)
                                if (c.wagons, c.simultaneous, c.tolerance_m_s, c.step_s)
                                == (1000, False, DEFAULT_TOLERANCE_M_S, 0.01))
        log(f"{long_case.train}, {long_case.brakes}: switches of Eq. 3's curves ...")
        switches = coupler_switches(long_case)
        switches["stats"] = timed["stats"]
        log(f"{long_case.train}, {long_case.brakes}: vehicles beyond the tolerance after one "
            f"step of the whole train ...")
        locality = error_locality(long_case, step_s=long_case.step_s)
    log("end to end ...")
    e2e = end_to_end(args.repeats or 60)
    over = advance_overhead(1000 if args.quick else 3000)
    log("start-up ...")
    start_best, start_worst, process_s = startup_s()
    t1, t2 = (120.0, 600.0) if args.quick else (600.0, 3600.0)
    log(f"memory over {t2:.0f} s of simulated time ...")
    mem = memory_check(t1, t2)

    print(f"Emergency stop from {SPEED_KMH:g} km/h, nominal step 10 ms unless the row says "
          f"otherwise, 1 s chunks, one core "
          f"(best CPU time of repeated runs, at least {MIN_TIMED_S:g} s of them). Errors against "
          f"solve_ivp Radau (rtol 1e-8, atol 1e-9), or for the longest trains against this kernel at a 10× smaller tolerance, the whole train stepping together. "
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
    if switches:
        t = switches["times"]
        st = switches["stats"]
        busiest = int(np.count_nonzero((t >= 20.0) & (t < 60.0)))
        print(f"* E402B + 1000 × 80 t, G from the head: the couplers switch between Eq. 3's "
              f"loading and unloading curves {switches['switches']:,} times in the stop "
              f"({busiest:,} between 20 and 60 s; deflection rate changing sign beyond the "
              f"band, sampled every 1 ms: a lower bound); the timed run took "
              f"{(st.steps + st.rejected_steps) / max(switches['switches'], 1):.1f} tries of "
              f"the whole train (steps taken and rejected) and "
              f"{(st.local_steps + st.local_rejected_steps) / max(switches['switches'], 1):.1f} "
              f"local sub-steps per switch.")
        k = locality["counts"]
        print(f"* The same train, one {locality['step_s'] * 1e3:g} ms step for the whole train "
              f"every 0.5 s from {locality['start_s']:g} to {locality['end_s']:g} s, against a "
              f"hundredfold smaller tolerance: {np.median(k):g} of its {locality['vehicles']} "
              f"vehicles (median; at most {k.max()}) miss the tolerance, the others hold it: "
              f"what local time stepping sub-steps and what it leaves to the whole train's "
              f"step.")
    print(end_to_end_line(e2e))
    print(f"* Simulator.advance per call (one 10 ms step, scenario 6): {over['advance_us']:.1f} µs "
          f"against {over['kernel_us']:.1f} µs for the bound step loop alone "
          f"({over['advance_us'] - over['kernel_us']:.1f} µs of commands, snapshot and events); "
          f"the whole kernel through numba's dispatcher, which types every bundle and allocates "
          f"its work arrays on every call, {over['dispatch_us']:.1f} µs.")
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
          f"commanded at once (t_del = 0 in Eq. 6, brake parameter simultaneous: true). Peak "
          f"forces and LUT excursions are from the timed run.")
    print(f"* Total benchmark time {time.perf_counter() - started:.0f} s.")
    return 0


if __name__ == "__main__":
    sys.exit(main())

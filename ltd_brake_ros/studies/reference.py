"""Reference integration of an emergency stop with scipy's adaptive stiff solvers.

The same model as the simulator (Eq. 1-3, 5, 8-10), integrated independently of the compiled
fixed-step kernel: the state is [x (n), v (n)], ``scipy.integrate.solve_ivp`` (BDF or Radau)
controls the error, the brake force is the closed form of Eq. 5 for an emergency command at
t = 0, and the right-hand side and its banded Jacobian are compiled with numba from the
functions of :mod:`ltd_brake_ros.physics`.

Standstill is regularised: the retarding forces act along sign(v) smoothed to
clip(v / v_eps, -1, 1), with v_eps the simulator's standstill band (``stick_band_m_s``) or a very
small default, so a vehicle held by its brakes creeps at most at v_eps. The integration ends when
every vehicle is slower than the simulator's ``standstill_m_s`` (a terminal event), and
comparisons stop there.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.sparse import csc_matrix

from ..physics import couplers
from ..physics.brakes import uic_empirical
from ..physics.brakes.friction import BRAKE_BLOCKS, BRAKE_DISC, block_mu
from ..physics.brakes.uic_empirical import rise_fraction
from ..physics.equations import jit, resistance_N

#: Default half-width of the regularised sign(v) of the retarding forces [m/s].
V_EPS_M_S = 1e-6


# --------------------------------------------------------------------------- compiled model


@jit
def _retarding(t, i, v, mass, axles, kind, blocks, arrangement, mu_disc, fmax, delay, tau,
               resist, v_eps):
    """Retarding force along the motion of vehicle i (Eq. 2, 5, 8-10) and d/dv [N, N s/m]."""
    speed = abs(v)
    fr, dfr = resistance_N(mass[i], axles[i], speed)
    fr *= resist
    dfr *= resist
    fb = fmax[i] * rise_fraction(t - delay[i], tau[i])
    fa, dfa = 0.0, 0.0
    if kind[i] == BRAKE_BLOCKS and fb > 0.0:
        mu, dmu = block_mu(speed, fb / (1000.0 * blocks[i]), arrangement[i])
        fa, dfa = mu * fb, dmu * fb
    elif kind[i] == BRAKE_DISC:
        fa = mu_disc[i] * fb
    mag = fa + fr
    dmag = dfa + dfr
    r = v / v_eps
    if r >= 1.0:
        return mag, dmag
    if r <= -1.0:
        return -mag, dmag
    # inside the band: s(v) = v / v_eps, d(s * mag)/dv = mag / v_eps + s * dmag * sign(v)
    return r * mag, mag / v_eps + abs(r) * dmag


@jit
def _rhs(t, y, out, meff, mass, axles, kind, blocks, arrangement, mu_disc, fext, fmax, delay,
         tau, resist, cp_model, cp_table, cp_coef, v_eps):
    """dy/dt of y = [x, v] (written to ``out``)."""
    n = meff.shape[0]
    for i in range(n):
        out[i] = y[n + i]
        out[n + i] = fext[i]
    for j in range(n - 1):
        f, _kd, _kr = couplers.force(cp_model, cp_table, cp_coef, y[j] - y[j + 1],
                                     y[n + j] - y[n + j + 1])
        out[n + j] -= f
        out[n + j + 1] += f
    for i in range(n):
        ret, _d = _retarding(t, i, y[n + i], mass, axles, kind, blocks, arrangement, mu_disc,
                             fmax, delay, tau, resist, v_eps)
        out[n + i] = (out[n + i] - ret) / meff[i]


@jit
def _jac_data(t, y, data, meff, mass, axles, kind, blocks, arrangement, mu_disc, fmax, delay,
              tau, resist, cp_model, cp_table, cp_coef, v_eps):
    """Non-zeros of d(dy/dt)/dy in the column order of :func:`_jac_pattern`."""
    n = meff.shape[0]
    kd = np.zeros(n + 1)  # kd[j + 1]: stiffness of coupler j; kd[0] = kd[n] = 0 (train ends)
    kr = np.zeros(n + 1)
    for j in range(n - 1):
        _f, a, b = couplers.force(cp_model, cp_table, cp_coef, y[j] - y[j + 1],
                                  y[n + j] - y[n + j + 1])
        kd[j + 1] = a
        kr[j + 1] = b
    k = 0
    for j in range(n):  # columns x_j
        if j > 0:
            data[k] = kd[j] / meff[j - 1]
            k += 1
        data[k] = -(kd[j + 1] + kd[j]) / meff[j]
        k += 1
        if j < n - 1:
            data[k] = kd[j + 1] / meff[j + 1]
            k += 1
    for j in range(n):  # columns v_j
        data[k] = 1.0
        k += 1
        if j > 0:
            data[k] = kr[j] / meff[j - 1]
            k += 1
        _r, dret = _retarding(t, j, y[n + j], mass, axles, kind, blocks, arrangement, mu_disc,
                              fmax, delay, tau, resist, v_eps)
        data[k] = -(kr[j + 1] + kr[j] + dret) / meff[j]
        k += 1
        if j < n - 1:
            data[k] = kr[j + 1] / meff[j + 1]
            k += 1


@jit
def _coupler_forces(y, n, cp_model, cp_table, cp_coef, out):
    """Coupler forces (draft positive) of the states in the columns of ``y`` [N]."""
    for k in range(y.shape[1]):
        for j in range(n - 1):
            f, _kd, _kr = couplers.force(cp_model, cp_table, cp_coef, y[j, k] - y[j + 1, k],
                                         y[n + j, k] - y[n + j + 1, k])
            out[k, j] = f


def _jac_pattern(n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSC row indices and column pointers of the 2n x 2n Jacobian."""
    indices, indptr = [], [0]
    for j in range(n):
        indices += [n + r for r in (j - 1, j, j + 1) if 0 <= r < n]
        indptr.append(len(indices))
    for j in range(n):
        indices += [j] + [n + r for r in (j - 1, j, j + 1) if 0 <= r < n]
        indptr.append(len(indices))
    return np.array(indices, np.int32), np.array(indptr, np.int32)


# --------------------------------------------------------------------------- model data


class ReferenceModel:
    """Arrays of the model, read off a constructed simulator so that the data are identical.

    Every per-vehicle array (masses, friction, maximum block forces, brake delays and time
    constants) and the coupler model are the simulator's compiled ones; the brake force is the
    closed form of Eq. 5, so the simulator must run the empirical UIC brake model.

    Parameters
    ----------
    sim : Simulator
        A freshly constructed simulator (its state is not used).
    resistance : bool, optional
        Apply running resistance, Eq. 2 (must match the simulator's setting).
    v_eps_m_s : float, optional
        Half-width of the regularised sign(v) of the retarding forces [m/s] (default: the
        simulator's standstill band, else :data:`V_EPS_M_S`).

    Raises
    ------
    ValueError
        The simulator runs on a track with gradients or curves, or another brake model than
        the empirical UIC one (not modelled here).
    """

    def __init__(self, sim, *, resistance: bool = True, v_eps_m_s: float | None = None):
        track = getattr(sim, "track", None)
        if track is not None and (any(track.gradient_permille) or any(track.radius_m)):
            raise ValueError("the reference integrates level straight track only")
        model = sim.model
        if model.brakes.model != uic_empirical.ID:
            raise ValueError("the reference integrates the empirical UIC brake model (Eq. 5) "
                             "only")
        self.n = sim.n
        self.v0_m_s = sim.speed_kmh / 3.6
        self.mass = model.train.mass_kg
        self.meff = model.train.meff_kg
        self.axles = model.train.axles
        fr = model.friction
        self.kind, self.blocks, self.arrangement, self.mu_disc = (fr.kind, fr.blocks,
                                                                  fr.arrangement, fr.mu_disc)
        self.fext = np.array(sim.fext_N, float)
        self.fmax = fr.force_max_N
        self.delay = model.brakes.delay_s
        # Eq. 7 with each vehicle's filling time (UIC 540: G fills slower than P)
        self.tau = np.ascontiguousarray(model.brakes.coef[:, uic_empirical.TAU_EMERGENCY])
        self.resist = 1.0 if resistance else 0.0
        cp = model.couplers
        self.coupler_model, self.coupler_table, self.coupler_coef = cp.model, cp.table, cp.coef
        if v_eps_m_s is None:
            v_eps_m_s = getattr(sim, "stick_band_m_s", V_EPS_M_S)
        self.v_eps = float(v_eps_m_s)
        self.v_stop = float(sim.standstill_m_s)
        self._indices, self._indptr = _jac_pattern(self.n)

    def initial_state(self) -> np.ndarray:
        """y(0): every vehicle at the initial speed, couplers unloaded."""
        return np.concatenate((np.zeros(self.n), np.full(self.n, self.v0_m_s)))

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt at time ``t`` [s] (a new array)."""
        out = np.empty(2 * self.n)
        _rhs(t, y, out, self.meff, self.mass, self.axles, self.kind, self.blocks,
             self.arrangement, self.mu_disc, self.fext, self.fmax, self.delay, self.tau,
             self.resist, self.coupler_model, self.coupler_table, self.coupler_coef, self.v_eps)
        return out

    def jac(self, t: float, y: np.ndarray) -> csc_matrix:
        """Analytical Jacobian d(dy/dt)/dy as a sparse (banded) matrix."""
        data = np.empty(self._indices.size)
        _jac_data(t, y, data, self.meff, self.mass, self.axles, self.kind, self.blocks,
                  self.arrangement, self.mu_disc, self.fmax, self.delay, self.tau, self.resist,
                  self.coupler_model, self.coupler_table, self.coupler_coef, self.v_eps)
        m = 2 * self.n
        return csc_matrix((data, self._indices, self._indptr), shape=(m, m))

    def coupler_forces(self, y: np.ndarray) -> np.ndarray:
        """Coupler forces of one state [2n] or of states in columns [2n, k] [N]."""
        y = np.asarray(y, float)
        cols = np.ascontiguousarray(y.reshape(2 * self.n, -1))
        out = np.zeros((cols.shape[1], max(self.n - 1, 0)))
        _coupler_forces(cols, self.n, self.coupler_model, self.coupler_table, self.coupler_coef,
                        out)
        return out if y.ndim == 2 else out[0]


# --------------------------------------------------------------------------- whole stop


@dataclass(frozen=True)
class ReferenceResult:
    """An emergency stop integrated by :func:`reference_stop` (units in the names).

    Attributes
    ----------
    method : str
    rtol, atol : float
        Tolerances given to ``solve_ivp``.
    jacobian : str
        ``"sparse"`` (analytical) or ``"fd"`` (solve_ivp's dense finite differences).
    stopped : bool
        The standstill event fired before ``max_time_s``.
    end_time_s : float
        Time of the standstill event (or the time limit) [s].
    stopping_distance_m : float
        Head displacement at ``end_time_s`` [m].
    sample_time_s : ndarray
        Requested sample times not later than ``end_time_s`` [s].
    coupler_force_N : ndarray
        Coupler forces at those times, shape (samples, n - 1), draft positive [N].
    speed_m_s : ndarray
        Vehicle speeds at those times, shape (samples, n) [m/s].
    peak_draft_N, peak_buff_N : ndarray
        Largest draft (>= 0) and buff (<= 0) force per coupler over the samples, the peak grid
        and the end point [N].
    steps : int
        Accepted solver steps (event evaluations, one per step).
    nfev, njev, nlu : int
        Right-hand-side and Jacobian evaluations, LU factorisations.
    wall_time_s : float
        Wall time of the ``solve_ivp`` call [s].
    """

    method: str
    rtol: float
    atol: float
    jacobian: str
    stopped: bool
    end_time_s: float
    stopping_distance_m: float
    sample_time_s: np.ndarray
    coupler_force_N: np.ndarray
    speed_m_s: np.ndarray
    peak_draft_N: np.ndarray
    peak_buff_N: np.ndarray
    steps: int
    nfev: int
    njev: int
    nlu: int
    wall_time_s: float

    def forces_at(self, times_s) -> np.ndarray:
        """Coupler forces linearly interpolated at ``times_s`` (within the samples) [N]."""
        times_s = np.asarray(times_s, float)
        return np.column_stack([np.interp(times_s, self.sample_time_s, self.coupler_force_N[:, j])
                                for j in range(self.coupler_force_N.shape[1])])


def reference_stop(sim, sample_times_s=None, *, method: str = "BDF", rtol: float = 1e-7,
                   atol: float = 1e-8, peak_dt_s: float | None = None,
                   max_time_s: float = 600.0, resistance: bool = True,
                   v_eps_m_s: float | None = None, first_step_s: float | None = None,
                   jacobian: str = "sparse") -> ReferenceResult:
    """Integrate an emergency stop commanded at t = 0 until every vehicle stands still.

    Parameters
    ----------
    sim : Simulator
        Supplies the train, brake data, coupler table, initial speed and standstill speed.
    sample_times_s : array_like, optional
        Times at which to return coupler forces and speeds [s] (default: every 5 ms, the
        paper's output rate).
    method : str, optional
        ``"BDF"`` or ``"Radau"`` (any implicit ``solve_ivp`` method that takes ``jac``).
    rtol, atol : float, optional
        Solver tolerances (the paper's ode15s used 1e-7 and 1e-8).
    peak_dt_s : float, optional
        Extra sampling interval for the peak forces only [s] (default: the samples alone).
    max_time_s : float, optional
        Time limit [s].
    resistance : bool, optional
        Running resistance on (must match the simulator).
    v_eps_m_s : float, optional
        Half-width of the regularised sign(v) [m/s] (default: see :class:`ReferenceModel`).
    first_step_s : float, optional
        Initial step given to the solver [s].
    jacobian : str, optional
        ``"sparse"``: the analytical banded Jacobian as a sparse matrix (sparse LU);
        ``"fd"``: none given, so ``solve_ivp`` estimates a dense one by finite differences
        (dense LU), its default.

    Returns
    -------
    ReferenceResult
    """
    if jacobian not in ("sparse", "fd"):
        raise ValueError(f"jacobian must be 'sparse' or 'fd', got {jacobian!r}")
    model = ReferenceModel(sim, resistance=resistance, v_eps_m_s=v_eps_m_s)
    n = model.n
    if sample_times_s is None:
        sample_times_s = np.arange(0.0, max_time_s, 0.005)
    samples = np.asarray(sample_times_s, float)
    samples = samples[(samples >= 0.0) & (samples <= max_time_s)]
    grid = samples
    if peak_dt_s:
        fine = np.arange(0.0, max_time_s, float(peak_dt_s))
        grid = np.union1d(samples, fine)
    steps = [0, -1.0]  # accepted steps, latest time seen
    v_stop = model.v_stop

    def standstill(t, y):
        # called once per accepted step, plus root-finding calls inside the last one
        if t > steps[1]:
            steps[0] += 1
            steps[1] = t
        return float(np.max(y[n:])) - v_stop  # no vehicle moves forward any more

    standstill.terminal = True
    standstill.direction = -1.0
    y0 = model.initial_state()
    model.rhs(0.0, y0)  # load the compiled functions before timing
    model.jac(0.0, y0)
    start = time.perf_counter()
    sol = solve_ivp(model.rhs, (0.0, max_time_s), y0, method=method,
                    t_eval=grid, events=standstill, rtol=rtol, atol=atol,
                    jac=model.jac if jacobian == "sparse" else None,
                    first_step=first_step_s)
    wall = time.perf_counter() - start
    if sol.status < 0:
        raise RuntimeError(f"reference integration failed: {sol.message}")
    stopped = sol.status == 1
    if stopped:
        t_end, y_end = float(sol.t_events[0][0]), sol.y_events[0][0]
    else:
        t_end, y_end = float(sol.t[-1]), sol.y[:, -1]
    forces = model.coupler_forces(sol.y).reshape(sol.t.size, max(n - 1, 0))
    f_end = model.coupler_forces(y_end)
    peak_draft = np.maximum(np.max(forces, axis=0, initial=0.0), np.maximum(f_end, 0.0))
    peak_buff = np.minimum(np.min(forces, axis=0, initial=0.0), np.minimum(f_end, 0.0))
    keep = np.isin(sol.t, samples)
    return ReferenceResult(
        method=method, rtol=rtol, atol=atol, jacobian=jacobian, stopped=stopped, end_time_s=t_end,
        stopping_distance_m=float(y_end[0]), sample_time_s=sol.t[keep],
        coupler_force_N=forces[keep], speed_m_s=sol.y[n:, keep].T.copy(),
        peak_draft_N=peak_draft, peak_buff_N=peak_buff, steps=max(steps[0] - 1, 0),
        nfev=int(sol.nfev), njev=int(sol.njev), nlu=int(sol.nlu), wall_time_s=wall)


# --------------------------------------------------------------------------- comparison


def record_stop(sim, chunk_s: float | None = None, max_time_s: float = 600.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """Run an emergency stop on a fresh simulator, recording the coupler forces every chunk.

    Parameters
    ----------
    sim : Simulator
        At time 0, brake released; left stopped at the end of the chunk where it stopped.
    chunk_s : float, optional
        Simulated time per :meth:`Simulator.advance` call [s] (default: one step).
    max_time_s : float, optional
        Give up after this time [s].

    Returns
    -------
    time_s : ndarray
        Sample times, starting at 0 [s].
    coupler_force_N : ndarray
        Coupler forces at those times, shape (samples, n - 1) [N].

    Raises
    ------
    SimulationError
        A step failed.
    RuntimeError
        The train had not stopped after ``max_time_s``.
    """
    from ..simulator import Commands

    chunk_s = chunk_s or sim.step_s
    times = [sim.time_s]
    forces = [sim.snapshot().coupler_force_N]
    commands = Commands(emergency=True)
    while sim.stop_time_s is None:
        if sim.time_s >= max_time_s:
            raise RuntimeError(f"the train had not stopped after {max_time_s:g} s")
        snap = sim.advance(chunk_s, commands)
        commands = None
        times.append(snap.time_s)
        forces.append(snap.coupler_force_N)
    return np.array(times), np.array(forces)



@dataclass(frozen=True)
class Accuracy:
    """Errors of a simulated stop against a reference (percentages, worst coupler).

    Attributes
    ----------
    stopping_distance_percent : float
        Signed stopping-distance error [%].
    peak_draft_percent, peak_buff_percent : float
        Largest peak-force error over the couplers, relative to the coupler's own reference
        peak or, for couplers whose peak is below ``tiny_fraction`` of the overall peak
        magnitude, to ``tiny_fraction`` x that magnitude [%].
    peak_draft_coupler, peak_buff_coupler : int
        Couplers (numbered from 1) where those errors occur.
    force_rms_percent : float
        Largest RMS difference of a coupler's force history, as a percentage of the reference's
        overall peak force magnitude [%].
    total_variation_ratio : float
        Largest ratio of a coupler's total variation (sum of |dF| between samples) to the
        reference's over the same samples (couplers with a non-negligible reference variation).
    samples : int
        Number of common samples compared.
    """

    stopping_distance_percent: float
    peak_draft_percent: float
    peak_draft_coupler: int
    peak_buff_percent: float
    peak_buff_coupler: int
    force_rms_percent: float
    total_variation_ratio: float
    samples: int


def compare(ref: ReferenceResult, time_s, coupler_force_N, stopping_distance_m: float,
            peak_draft_N, peak_buff_N, *, tiny_fraction: float = 0.1) -> Accuracy:
    """Compare a simulated stop with a reference stop.

    Parameters
    ----------
    ref : ReferenceResult
    time_s : array_like
        Sample times of the simulated force histories [s] (the reference is interpolated there;
        it is exact when they are among ``ref.sample_time_s``).
    coupler_force_N : array_like
        Simulated coupler forces, shape (samples, n - 1) [N].
    stopping_distance_m : float
        Simulated stopping distance [m].
    peak_draft_N, peak_buff_N : array_like
        Simulated peak forces per coupler [N].
    tiny_fraction : float, optional
        Peaks below this fraction of the overall peak magnitude are judged against it.

    Returns
    -------
    Accuracy
    """
    t = np.asarray(time_s, float)
    f = np.asarray(coupler_force_N, float)
    keep = t <= ref.sample_time_s[-1] + 1e-9
    t, f = t[keep], f[keep]
    fr = ref.forces_at(t)
    overall = max(float(np.max(np.abs(ref.peak_draft_N))), float(np.max(np.abs(ref.peak_buff_N))))
    floor = tiny_fraction * overall

    def peak_error(sim_peak, ref_peak):
        err = np.abs(np.asarray(sim_peak, float) - ref_peak) / np.maximum(np.abs(ref_peak), floor)
        j = int(np.argmax(err))
        return 100.0 * float(err[j]), j + 1

    pd, jd = peak_error(peak_draft_N, ref.peak_draft_N)
    pb, jb = peak_error(peak_buff_N, ref.peak_buff_N)
    rms = np.sqrt(np.mean((f - fr) ** 2, axis=0))
    tv_sim = np.sum(np.abs(np.diff(f, axis=0)), axis=0)
    tv_ref = np.sum(np.abs(np.diff(fr, axis=0)), axis=0)
    judged = tv_ref > 1e-3 * tv_ref.max()
    return Accuracy(
        stopping_distance_percent=100.0 * (stopping_distance_m - ref.stopping_distance_m)
        / ref.stopping_distance_m,
        peak_draft_percent=pd, peak_draft_coupler=jd, peak_buff_percent=pb, peak_buff_coupler=jb,
        force_rms_percent=100.0 * float(rms.max()) / overall,
        total_variation_ratio=float(np.max(tv_sim[judged] / tv_ref[judged])),
        samples=int(t.size))

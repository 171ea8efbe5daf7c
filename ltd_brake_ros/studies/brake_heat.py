"""The freight-wagon TSI's thermal reference case, run through the simulator, beside the lumped
brake-heat model's analytic solution (:mod:`~ltd_brake_ros.physics.brakes.thermal`).

The case (TSI freight wagons, Decision 2006/861/EC, thermal capacity; NL/DE text at
wordscope.be): a descent of 21 per mille at 70 km/h over 40 km, 45 kW per wheel for 34 min,
920 mm wheels, 22.5 t axle load. Here one wagon of 90 t on four axles (the Shimmns type: one
P10 Bg block per wheel) runs down a constant 21 per mille gradient, its speed held at 70 km/h
by the service brake (a PI loop on the brake demand, one command per chunk), for 40 km.

``python -m ltd_brake_ros.studies.brake_heat`` prints the numbers of the documentation's
brake-heat page for both brake models.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..inputs import BrakeParams, Consist, Track, load_brake_params
from ..inputs.consist import consist_from_mapping
from ..physics.brakes.thermal import VALIDATION, ThermalArrays
from ..physics.constants import G, KMH_PER_MS
from ..physics.equations import resistance_N
from ..simulator import Commands, Simulator

__all__ = ["DISTANCE_M", "DragBraking", "GRADIENT_PERMILLE", "SPEED_KMH", "WHEEL_POWER_W",
           "drag_braking", "history_bound", "history_response", "impulse_response", "response",
           "steady_state", "tsi_wagon"]

#: The TSI reference case: gradient [per mille, uphill positive], speed [km/h], length [m],
#: axle load [t], braking power per wheel [W] and its duration [s] (Decision 2006/861/EC;
#: medium to high on the numbers). 40 km at 70 km/h take 34.3 min.
GRADIENT_PERMILLE, SPEED_KMH, DISTANCE_M = -21.0, 70.0, 40e3
AXLE_LOAD_T, WHEEL_POWER_W, DURATION_S = 22.5, 45e3, 34 * 60.0
#: The speed loop: proportional gain [1/(m/s)], integral gain [1/m] (tuned on the empirical
#: model: it holds 70 km/h within 0.01 km/h after 5 min).
GAIN_P, GAIN_I = 0.5, 0.02


def tsi_wagon() -> Consist:
    """A 90 t four-axle wagon of the Shimmns type (one P10 Bg block per wheel): 22.5 t axles."""
    return consist_from_mapping({"name": "TSI thermal reference wagon (90 t)", "vehicles": [
        {"type": "Shimmns", "mass_t": 4 * AXLE_LOAD_T}]}, "TSI thermal reference case")


def _matrix(arrays: ThermalArrays, i: int, speed_m_s: float, applied: bool = True):
    """x' = M x + s w of vehicle ``i``'s wheel, x = T - T_a, w the friction power [W]."""
    vf = speed_m_s ** 0.8
    gb = arrays.block_still_W_K[i] + arrays.block_speed_W_K[i] * vf
    gw = arrays.wheel_still_W_K[i] + arrays.wheel_speed_W_K[i] * vf
    gc = arrays.contact_W_K[i] if applied else 0.0
    cb, cw = arrays.block_capacity_J_K[i], arrays.wheel_capacity_J_K[i]
    m = np.array([[-(gc + gb) / cb, gc / cb], [gc / cw, -(gc + gw) / cw]])
    share = arrays.wheel_share[i]
    return m, np.array([(1.0 - share) / cb, share / cw])


def steady_state(arrays: ThermalArrays, i: int, power_W: float, speed_m_s: float):
    """Blocks' and wheel's temperature [K] after constant friction power per wheel [W] at a
    constant speed [m/s] for ever, the brake applied: T_a - M^-1 s P."""
    m, s = _matrix(arrays, i, speed_m_s)
    return tuple(arrays.ambient_K - np.linalg.solve(m, s * power_W))


def response(arrays: ThermalArrays, i: int, power_W: float, speed_m_s: float, t_s: float):
    """Blocks' and wheel's temperature [K] ``t_s`` after starting at the air's temperature,
    under constant friction power per wheel [W] and speed [m/s] (matrix exponential)."""
    m, s = _matrix(arrays, i, speed_m_s)
    steady = -np.linalg.solve(m, s * power_W)
    return tuple(arrays.ambient_K + steady - expm(m * t_s) @ steady)


def impulse_response(arrays: ThermalArrays, i: int, speed_m_s: float, lags_s):
    """Blocks' and wheel's temperature rise per joule of friction heat [K/J], ``lags_s`` after
    it entered (rows: blocks, wheel)."""
    m, s = _matrix(arrays, i, speed_m_s)
    return np.array([expm(m * lag) @ s for lag in np.asarray(lags_s, float)]).T


def history_response(arrays: ThermalArrays, i: int, time_s, work_J, speed_m_s):
    """Blocks' and wheel's temperature [K] at the end of a run of chunks, each chunk's heat
    entering at its mean power and speed (exactly, chunk after chunk).

    Parameters
    ----------
    arrays : ThermalArrays
    i : int
        The vehicle.
    time_s : array_like
        End of each chunk, the run starting at 0 [s].
    work_J : array_like
        Brake work per wheel in each chunk [J].
    speed_m_s : array_like
        Speed at each chunk's end [m/s] (the first chunk starts at the first's).

    Returns
    -------
    tuple of float
    """
    t = np.concatenate(([0.0], np.asarray(time_s, float)))
    v = np.asarray(speed_m_s, float)
    v = 0.5 * (np.concatenate(([v[0]], v[:-1])) + v)
    x = np.zeros(2)
    for k, work in enumerate(np.asarray(work_J, float)):
        dt = t[k + 1] - t[k]
        m, s = _matrix(arrays, i, v[k])
        steady = -np.linalg.solve(m, s * work / dt)
        x = steady + expm(m * dt) @ (x - steady)
    return tuple(arrays.ambient_K + x)


def history_bound(arrays: ThermalArrays, time_s, work_J, speed_m_s) -> tuple:
    """How far the run may lie from :func:`history_response` [K]: within a chunk the heat
    arrives up to the chunk's length earlier or later than at its mean power, which moves the
    end temperatures by at most that length times the largest slope of the impulse response
    over the chunk's lags; and the speed varies within a chunk, at most by its change, moving
    the cooling as :meth:`DragBraking.bound`."""
    t = np.asarray(time_s, float)
    start = np.concatenate(([0.0], t[:-1]))
    v_ref = SPEED_KMH / KMH_PER_MS
    m, s = _matrix(arrays, 0, v_ref)
    lags = np.concatenate((t[-1] - start, t[-1] - t))
    slope = np.abs(np.array([m @ expm(m * lag) @ s for lag in lags]).T)
    steepest = np.maximum(slope[:, : t.size], slope[:, t.size:])
    timing = steepest @ (np.asarray(work_J, float) * (t - start))
    v = np.asarray(speed_m_s, float)
    change = np.max(np.abs(np.diff(v))) if v.size > 1 else 0.0
    mean = np.sum(work_J) / t[-1]
    dv = 0.01
    hi, lo = (np.array(response(arrays, 0, mean, v_ref + sign * dv, t[-1])) for sign in (1, -1))
    return tuple(timing + np.abs(hi - lo) / (2.0 * dv) * change)


@dataclass(frozen=True)
class DragBraking:
    """The reference case as run, and the model's analytic solution beside it.

    Attributes
    ----------
    model : str
        The brake model.
    time_s, speed_m_s : ndarray
        End of each chunk [s] and the wagon's speed then [m/s].
    work_J : ndarray
        Brake work per wheel in each chunk [J].
    distance_m : float
        Distance run [m].
    energy_J : float
        Brake work per wheel over the run [J].
    expected_energy_J : float
        Per wheel, the potential energy released less the running resistance (Eq. 2) at
        70 km/h over the distance run, less the kinetic energy gained [J].
    block_K, wheel_K : float
        Temperatures at the end [K].
    reference_K : tuple of float
        Blocks' and wheel's temperature at the end under the run's mean power at 70 km/h from
        the start (:func:`response`) [K].
    steady_K : tuple of float
        The same for ever (:func:`steady_state`) [K].
    tolerance_K : tuple of float
        How far the run may lie from ``reference_K`` (:meth:`bound`) [K].
    history_K : tuple of float
        Blocks' and wheel's temperature at the end with each chunk's heat at its mean power
        and speed (:func:`history_response`) [K].
    history_tolerance_K : tuple of float
        How far the run may lie from ``history_K`` (:func:`history_bound`) [K].
    simulator : Simulator
        The simulator at the end of the run.
    events : tuple of Event
        The events of the run.
    """

    model: str
    time_s: np.ndarray
    speed_m_s: np.ndarray
    work_J: np.ndarray
    distance_m: float
    energy_J: float
    expected_energy_J: float
    block_K: float
    wheel_K: float
    reference_K: tuple
    steady_K: tuple
    tolerance_K: tuple
    history_K: tuple
    history_tolerance_K: tuple
    simulator: Simulator
    events: tuple

    @property
    def mean_power_W(self) -> float:
        """Mean friction power per wheel [W]."""
        return self.energy_J / self.time_s[-1]

    @staticmethod
    def bound(arrays: ThermalArrays, time_s, work_J, speed_m_s) -> tuple:
        """How far the end temperatures may lie from those of constant power and speed [K].

        The temperatures are linear in the power history: a deviation dP(t) from the mean
        (zero on the whole) moves them by int K(t_end - t) dP(t) dt, at most
        (max K - min K) / 2 int |dP| dt, K the impulse response (:func:`impulse_response`,
        per chunk); a speed off 70 km/h changes the cooling, at most |dT/dv| max |v - 70|.
        """
        t = np.asarray(time_s, float)
        dt = np.diff(np.concatenate(([0.0], t)))
        power = np.asarray(work_J, float) / dt
        mean = np.sum(work_J) / t[-1]
        v_ref = SPEED_KMH / KMH_PER_MS
        kernel = impulse_response(arrays, 0, v_ref, t[-1] - (t - 0.5 * dt))
        spread = 0.5 * (kernel.max(axis=1) - kernel.min(axis=1))
        deviation = np.sum(np.abs(power - mean) * dt)
        dv = 0.01
        hi, lo = (np.array(response(arrays, 0, mean, v_ref + s * dv, t[-1])) for s in (1, -1))
        slope = np.abs(hi - lo) / (2.0 * dv)
        off = np.max(np.abs(np.asarray(speed_m_s, float) - v_ref))
        return tuple(spread * deviation + slope * off)


def drag_braking(params: BrakeParams | None = None, *, step_s: float = 0.5,
                 chunk_s: float = 2.0, distance_m: float = DISTANCE_M) -> DragBraking:
    """Run the TSI's reference case (see the module).

    Parameters
    ----------
    params : BrakeParams, optional
        Brake model and parameters (default: the paper's empirical model).
    step_s : float, optional
        Integration step [s] (one wagon at a held speed: 0.5 s is accurate with the empirical
        model; the brake-pipe model's service brake cycles, take 0.1 s).
    chunk_s : float, optional
        Control period of the speed loop [s].
    distance_m : float, optional
        Length of the descent, run for as many whole chunks as it takes at 70 km/h [m].

    Returns
    -------
    DragBraking
    """
    wagon = tsi_wagon()
    sim = Simulator(wagon, SPEED_KMH, params, track=Track(gradient_permille=(GRADIENT_PERMILLE,)),
                    step_s=step_s)
    wheels = float(sim.model.thermal.wheels[0])
    v_ref = SPEED_KMH / KMH_PER_MS
    integral, demand = 0.3, 0.3
    times, speeds, works, events = [], [], [], []
    done = 0.0
    chunks = math.ceil(distance_m / v_ref / chunk_s - 1e-9)
    for _ in range(chunks):
        snap = sim.advance(chunk_s, Commands(brake_demand=min(max(demand, 0.0), 1.0)))
        events += snap.events
        energy = float(sim.brake_energy_J[0]) / wheels
        times.append(snap.time_s)
        speeds.append(float(snap.speed_m_s[0]))
        works.append(energy - done)
        done = energy
        error = speeds[-1] - v_ref
        integral = min(max(integral + GAIN_I * error * chunk_s, 0.0), 1.0)
        demand = integral + GAIN_P * error
    block, wheel = sim.temperatures()
    mass = float(sim.mass_kg[0])
    distance = sim.distance_travelled_m
    resistance = resistance_N(mass, float(wagon.vehicles[0].axles), v_ref)[0]
    rho = wagon.vehicles[0].inertia_factor
    kinetic = 0.5 * rho * mass * (speeds[-1] ** 2 - v_ref ** 2)
    expected = (mass * G * -GRADIENT_PERMILLE / 1e3 * distance - resistance * distance
                - kinetic) / wheels
    arrays = sim.model.thermal
    t, w = np.array(times), np.array(works)
    mean = done / t[-1]
    return DragBraking(sim.params.model, t, np.array(speeds), w, distance, done, expected,
                       float(block[0]), float(wheel[0]), response(arrays, 0, mean, v_ref, t[-1]),
                       steady_state(arrays, 0, mean, v_ref),
                       DragBraking.bound(arrays, t, w, speeds),
                       history_response(arrays, 0, t, w, speeds),
                       history_bound(arrays, t, w, speeds), sim, tuple(events))


def _celsius(kelvin: float) -> str:
    return f"{kelvin - 273.15:.0f} C"


def report(runs: list[DragBraking], arrays: ThermalArrays) -> str:
    """Markdown: the model's constants at 70 km/h, then each run beside its reference."""
    v_ref = SPEED_KMH / KMH_PER_MS
    m, _s = _matrix(arrays, 0, v_ref)
    taus = sorted(-1.0 / np.linalg.eigvals(m).real)
    vf = v_ref ** 0.8
    gross = AXLE_LOAD_T / 2 * 1e3 * G * -GRADIENT_PERMILLE / 1e3
    nominal = response(arrays, 0, gross * v_ref, v_ref, DISTANCE_M / v_ref)
    lines = [
        f"heat model {VALIDATION}: no published drag-braking case with rim temperatures "
        "was found to check it against; no fade (no sourced friction law)",
        f"wheel share gamma {arrays.wheel_share[0]:.3f}; per wheel: blocks "
        f"{arrays.block_capacity_J_K[0] / 1e3:.1f} kJ/K, wheel "
        f"{arrays.wheel_capacity_J_K[0] / 1e3:.0f} kJ/K, contact {arrays.contact_W_K[0]:.1f} W/K, "
        f"to the air at 70 km/h blocks "
        f"{arrays.block_still_W_K[0] + arrays.block_speed_W_K[0] * vf:.1f} W/K, wheel "
        f"{arrays.wheel_still_W_K[0] + arrays.wheel_speed_W_K[0] * vf:.0f} W/K; time "
        f"constants {taus[0]:.0f} s and {taus[1] / 60:.1f} min",
        f"TSI nominal {gross * v_ref / 1e3:.1f} kW per wheel (no running resistance) for "
        f"{DISTANCE_M / v_ref / 60:.1f} min: {gross * DISTANCE_M / 1e6:.1f} MJ per wheel, blocks "
        f"{_celsius(nominal[0])}, wheel {_celsius(nominal[1])} (analytic)",
        "",
        "| brake model | energy per wheel (expected) | mean power per wheel | blocks / wheel at "
        "the end | analytic, mean power (bound) | analytic, chunk by chunk (bound) | steady "
        "state |",
        "|---|---|---|---|---|---|---|"]

    def pair(temps, digits=1):
        return " / ".join(f"{t - 273.15:.{digits}f}" for t in temps) + " C"
    for r in runs:
        lines.append(
            f"| {r.model} | {r.energy_J / 1e6:.2f} MJ ({r.expected_energy_J / 1e6:.2f}) | "
            f"{r.mean_power_W / 1e3:.1f} kW | {pair((r.block_K, r.wheel_K))} | "
            f"{pair(r.reference_K)} (±{r.tolerance_K[0]:.1f} / ±{r.tolerance_K[1]:.1f} K) | "
            f"{pair(r.history_K)} (±{r.history_tolerance_K[0]:.1f} / "
            f"±{r.history_tolerance_K[1]:.1f} K) | {pair(r.steady_K, 0)} |")
    return "\n".join(lines)


def main() -> None:
    """Print :func:`report` for the empirical and the brake-pipe model."""
    runs = [drag_braking(),
            drag_braking(load_brake_params("brake_params/uic_brake_pipe.yaml"), step_s=0.1)]
    sim = Simulator(tsi_wagon(), SPEED_KMH)
    print(report(runs, sim.model.thermal))


if __name__ == "__main__":
    main()

"""The UIC brake pipe and distributors, fluid-empirical: pipe air flow, valve characteristics.

The brake pipe is a 1-D isothermal compressible flow along the train (continuity and momentum,
the convective term neglected at the pipe's low Mach numbers), one finite volume per vehicle
(its length over buffers, the pipe bore and the branch volume of its distributor), one face per
hose coupling carrying the mass flow between two volumes with wall friction (laminar 64/Re,
turbulent Colebrook, in Haaland's explicit form, with the wall roughness of commercial steel)
and a concentrated loss per vehicle junction. Both ends are closed. Branch flows leave
or enter each volume: the driver's brake valve (feed valve from the main reservoir, relay vent,
emergency orifice) at the venting vehicle, and at every braked vehicle the charging of its
auxiliary reservoir, its quick-service chamber and its acceleration chamber (emergency
accelerator). Orifices follow the isentropic law, choked below the critical ratio 0.528.

Scheme. Each internal step (``pipe_step_s``) is backward Euler on a staggered grid with the
friction and the branch flows linearised about the last step; eliminating the face flows leaves
one tridiagonal system in the pressures (Thomas algorithm, O(n)). Backward Euler is unconditionally
stable, so the step is not limited by the CFL condition of the sound speed nor by the stiff
orifices (an emergency orifice on a 12 L volume has a time constant of milliseconds), and it is
monotone: no oscillation near a front can fire a distributor or an accelerator early. It costs
one tridiagonal solve per step (``benchmarks/bench_brake_pipe.py``: about the cost of the
mechanics for a short train, a tenth of it for 1000 wagons). At the default step (Courant number
c dt / dx ~ 0.1) halving the step moves the propagation speeds with acceleration chambers and the
stopping distances of Tables 1-2 by under 1 % and 0.1 % (the propagation without chambers,
a slow diffusive drop crossing a threshold, by about 10 %).

A release of kind ``OVERCHARGE`` raises the equalising reservoir ``overcharge_Pa`` above the
running pressure for ``overcharge_hold_s``, then lowers it back at
``overcharge_reduction_rate_Pa_s``, slower than the distributors' control reservoirs lag behind
their application threshold (insensitivity): the higher head pressure drives more air along the
pipe and the tail releases sooner, without a spurious application on the way back to 5 bar.

With ``distributed_power`` every other locomotive has a driver's brake valve of its own that
repeats the venting vehicle's commands ``radio_delay_s`` later (radio distributed power).

Distributors (UIC 540 behaviour, measured characteristics rather than valve geometry): a control
reservoir that follows the pipe through a choke while released (insensitivity to slow drops),
application when the pipe is more than ``application_threshold`` below it, a one-shot
quick-service chamber that draws air from the pipe at the start, the cylinder held at no more
than ``application_stroke`` until ``application_stroke_s`` after the application (the piston's
stroke; 0 s: no hold), the first stage (inshot: filling at ``inshot_rate`` up to
``inshot_pressure``), target cylinder pressure proportional to the
pipe drop, 3.8 bar at 1.5 bar, with a play hysteresis between application and release
(graduated application and release), P/G filling rates and release time constants, the
auxiliary reservoir emptying polytropically into the cylinder, and an accelerator that vents
the pipe into its acceleration chamber when the pipe falls faster than its reference chamber
can follow: a local drop of a few tenths of a bar that carries an emergency along the train;
the rest of the drop flows along the pipe to the emergency orifice of the driver's brake valve
(diffusive: its time grows as the square of the distance). Empty/loaded
changes the full block force through the braked weight (Eq. 4), not the cylinder pressure.
Block force = full block force x max(0, p - p0) / (p_max - p0), p the cylinder pressure and p0
``block_force_threshold`` (the return spring and slack adjuster: UIC 544-1's brake calculation
has F_dyn = ((p A - F_F) i - 8 F_R) eta, linear in p, zero at about 0.22 bar): no force below p0,
the full block force of the braked weight at p_max.

Time grid. The model advances on a fixed global grid t_k = k * pipe_step_s; a command issued at t
reaches the driver's brake valve at t + valve_delay, within a step from that instant on (the
equalising reservoir moves for the rest of the step, the emergency orifice opens linearly over
its opening time), so results vary continuously with command times and delays. The block
forces held between grid points are those of the last grid point reached. ``advance(t0, t1)``
steps from the stored grid point to the last one at or before t1, so any split of [t0, t1] gives
bit-identical results. A step uses the commands issued before its end, all known to the advance
that computes it (commands are issued between advances, at their ends).

``delay_s`` is the earliest a command can reach each vehicle's distributor: over the driver's
brake valves, the least valve delay plus distance over the isothermal sound speed. No
distributor applies before it; a release acts later than it, once the pipe has risen back
above the release characteristic (about 3.5 bar after a full application).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..equations import centre_offsets_m, jit_inner, jit_step_inner
from ..parameters import Fittable, parameter
from .base import (EMERGENCY, OVERCHARGE, BrakeArrays, BrakeState, CompileError,
                   released_state)

NAME = "uic_brake_pipe"
#: Registry id: selects this model's branch of the jitted dispatch.
ID = 2

P_ATM = 101325.0  # [Pa]
R_AIR = 287.05  # specific gas constant of air [J/(kg K)]
_CRITICAL = 0.528  # critical pressure ratio of air (kappa = 1.4)
_LAMINAR = 0.995  # above this pressure ratio the orifice law is linear (finite derivative)
_C_CHOKED = math.sqrt(1.4) * (2.0 / 2.4) ** (2.4 / 0.8)  # sqrt(k) (2/(k+1))^((k+1)/(2(k-1)))
_GRID_TOL = 1e-6  # grid points within this fraction of a step count as reached

# ---- columns of BrakeArrays.coef: per vehicle
C_CAP = 0  # capacitance of the vehicle's volume, V / (R T) [kg/Pa]
C_DX = 1  # distance to the next vehicle's centre (face i, i + 1) [m]
C_DISTRIBUTOR = 2  # 1: the vehicle has a distributor
C_FILL_RATE = 3  # filling rate of the cylinder after inshot (P or G) [Pa/s]
C_LAP_TAU = 4  # time constant of the approach to the target pressure [s]
C_RELEASE_TAU = 5  # time constant of the release [s]
# ---- scalars (the same in every row)
S_DT, S_AREA, S_DIAM, S_HOSE_K, S_MU, S_RT = 6, 7, 8, 9, 10, 11
S_P_RUN, S_P_MR, S_A_FEED, S_A_VENT, S_A_EMERG, S_BAND = 12, 13, 14, 15, 16, 17
S_FIRST_STEP, S_FULL_SERVICE, S_ER_DOWN, S_ER_UP, S_VENT = 18, 19, 20, 21, 22
S_THETA_APP, S_CR_TAU, S_P_CMAX, S_DP_FULL, S_HYST, S_THETA_REL = 23, 24, 25, 26, 27, 28
S_P_INSHOT, S_INSHOT_RATE, S_A_AUX, S_V_AUX, S_V_CYL, S_N_POLY = 29, 30, 31, 32, 33, 34
S_A_QS, S_V_QS, S_ACC_ON, S_ACC_THETA, S_ACC_TAU, S_A_ACC, S_V_ACC = (35, 36, 37, 38, 39,
                                                                           40, 41)
S_SUPPLY_BAND = 42
# ---- per vehicle (continued)
C_LAP_DECAY = 43  # exp(-pipe step / C_LAP_TAU)
C_RELEASE_DECAY = 44  # exp(-pipe step / C_RELEASE_TAU)
# ---- scalars (continued)
S_VALVE_DELAY = 45
S_EM_OPEN = 46
# ---- per vehicle (continued)
C_VALVE = 47  # delay from a command to this vehicle's driver's brake valve acting [s]; -1: none
# ---- scalars (continued)
S_OVER, S_OVER_HOLD, S_OVER_RATE = 48, 49, 50
# ---- per face (i, i + 1)
C_FACE_G = 51  # dt * A / dx: conductance of the face without friction [m s]
C_FACE_HOSE = 52  # hose loss per length, K / dx [1/m]
# ---- scalars (continued)
S_ROUGH = 53  # relative roughness of the pipe wall, epsilon / D [-]
S_P_STROKE = 54  # cylinder pressure held during the application stroke, gauge [Pa]
S_STROKE_S = 55  # duration of the application stroke from the distributor applying [s]
S_P_FORCE0 = 56  # cylinder pressure below which the blocks give no force, gauge [Pa]
N_COEF = 57

# ---- columns of BrakeState.extra
X_P = 0  # pipe pressure, absolute [Pa]
X_M = 1  # mass flow from vehicle i to i + 1 [kg/s]
X_CR = 2  # control reservoir, absolute [Pa]
X_AUX = 3  # auxiliary reservoir, absolute [Pa]
X_CYL = 4  # brake cylinder, gauge [Pa]
X_TARGET = 5  # target cylinder pressure of the distributor, gauge [Pa]
X_APPLIED = 6  # 1: the distributor is in application
X_REF = 7  # accelerator reference chamber, absolute [Pa]
X_ACC = 8  # accelerator: 0 armed, 1 venting into its chamber, 2 spent
X_QS = 9  # quick-service chamber, absolute [Pa]
X_QS_STATE = 10  # quick service: 0 armed, 1 drawing, 2 done
X_GRID = 11  # row 0: index of the grid point reached (-1: none yet)
X_ER = 12  # equalising reservoir of the vehicle's driver's brake valve, absolute [Pa]
X_T_ACT = 13  # when the current command reached the vehicle's driver's brake valve [s]
X_MODE = 14  # position of the vehicle's driver's brake valve in the current step
X_EM_OPEN = 15  # opening of its emergency orifice in the current step [-]
X_ACC_P = 16  # acceleration chamber, absolute [Pa]
X_T_APP = 17  # when the distributor last went into application (end of that step) [s]
N_EXTRA = 18

#: Rows of ``BrakeState.work`` the advance uses: the pipe step's tridiagonal system (sub-,
#: main and super-diagonal, right-hand side), the face conductances and the pressures before
#: the step.
N_WORK = 6

# driver's brake valve positions
_RELEASE, _SERVICE, _EMERGENCY = 0, 1, 2

BAR = 1e5


@dataclass(frozen=True)
class Params:
    """Parameters of the UIC brake pipe and distributors (file keys in bar where so named).

    Sources: UIC 540 (distributor performance: 5 bar running pressure, 3.8 bar maximum
    cylinder pressure at a 1.5 bar pipe drop, P and G filling 3-5 s and 18-30 s, release
    15-20 s and 45-60 s, sensitivity and insensitivity), UIC 541-03 (driver's brake valve,
    first step, full service), the brake-pipe models of Cantone et al. (2009), Proc. IMechE F
    223:305 and Wu et al. (2021), Veh. Syst. Dyn. 59:1445 (pipe bore, hose losses, isothermal
    flow), UIC 544-1's worked brake calculation of a four-axle wagon (block force threshold).
    Values marked "fitted" were chosen so that the model meets the UIC 540 windows and
    propagation speeds printed by ``ltd-brake validate --brake-pipe``.
    """

    # --- pipe
    pipe_diameter_m: float = parameter(0.032, "brake-pipe bore (1 1/4 in pipe, Cantone 2009) [m]",
                                       lo=0.01, hi=0.1)
    branch_volume_m3: float = parameter(0.003, "volume of each vehicle's distributor branch and "
                                        "dirt collector (fitted) [m3]", lo=0.0, hi=0.05)
    hose_loss_coefficient: float = parameter(3.92, "concentrated loss coefficient of a "
                                             "vehicle junction (hose coupling and cocks) "
                                             "referred to the pipe bore: TrainDy's two losses "
                                             "of 3 per junction at 35.6 mm bore, 6 (32/35.6)^4 "
                                             "= 3.92 at 32 mm [-]", lo=0.0, hi=50.0)
    pipe_roughness_m: float = parameter(4.6e-5, "wall roughness of the pipe for the "
                                        "Colebrook friction factor (commercial steel, 0.046 mm, "
                                        "as TrainDy) [m]", lo=0.0, hi=1e-3)
    air_temperature_K: float = parameter(288.0, "air temperature, isothermal pipe [K]",
                                         lo=200.0, hi=350.0)
    air_viscosity_Pa_s: float = parameter(1.8e-5, "dynamic viscosity of air [Pa s]",
                                          lo=1e-6, hi=1e-4)
    pipe_step_s: float = parameter(0.005, "internal step of the pipe on its fixed time grid "
                                   "(numerical) [s]", lo=1e-4, hi=0.05)
    # --- driver's brake valve
    valve_delay_s: float = parameter(1.12, "delay from a command to the driver's brake valve "
                                     "acting on the pipe (fitted to the LTDPoliTo distances of "
                                     "Tables 1-2) [s]", lo=0.0, hi=5.0)
    running_pressure_Pa: float = parameter(5.0 * BAR, "brake-pipe running pressure (UIC 540) "
                                           "[bar]", key="running_pressure_bar", scale=BAR,
                                           lo=3.0, hi=7.0)
    main_reservoir_pressure_Pa: float = parameter(9.0 * BAR, "main reservoir feeding the pipe "
                                                  "(8-10 bar typical) [bar]",
                                                  key="main_reservoir_pressure_bar", scale=BAR,
                                                  lo=5.0, hi=12.0)
    feed_area_m2: float = parameter(1.5e-4, "effective area of the feed/relay valve from the "
                                    "main reservoir (fitted) [m2]", lo=1e-6, hi=1e-2)
    service_vent_area_m2: float = parameter(1.5e-4, "effective area of the relay valve's vent "
                                            "(fitted) [m2]", lo=1e-6, hi=1e-2)
    emergency_opening_s: float = parameter(0.1, "time of the emergency orifice to open fully "
                                           "(fitted) [s]", lo=0.001, hi=2.0)
    emergency_area_m2: float = parameter(5e-4, "effective area of the emergency position's "
                                         "orifice (1 1/4 in bore, fitted) [m2]", lo=1e-6,
                                         hi=1e-2)
    relay_band_Pa: float = parameter(0.05 * BAR, "pressure error that opens the relay valve "
                                     "fully (fitted) [bar]", key="relay_band_bar", scale=BAR,
                                     lo=0.001, hi=1.0)
    first_step_Pa: float = parameter(0.45 * BAR, "pipe reduction of the first service step "
                                     "(UIC 541-03: 0.4-0.5 bar) [bar]", key="first_step_bar",
                                     scale=BAR, lo=0.1, hi=1.5)
    full_service_Pa: float = parameter(1.5 * BAR, "pipe reduction of a full service "
                                       "application (UIC 540) [bar]", key="full_service_bar",
                                       scale=BAR, lo=0.5, hi=3.0)
    equalising_rate_down_Pa_s: float = parameter(0.4 * BAR, "rate at which the equalising "
                                                 "reservoir falls in service (fitted) [bar/s]",
                                                 key="equalising_rate_down_bar_s", scale=BAR,
                                                 lo=0.01, lo_open=True, hi=10.0)
    equalising_rate_up_Pa_s: float = parameter(2.0 * BAR, "rate at which the equalising "
                                               "reservoir rises on release (fitted) [bar/s]",
                                               key="equalising_rate_up_bar_s", scale=BAR,
                                               lo=0.01, lo_open=True, hi=20.0)
    overcharge_Pa: float = parameter(0.4 * BAR, "overcharge of the pipe above the running "
                                     "pressure on a release with overcharge (5.4 bar, UIC "
                                     "541-03 driver's brake valve) [bar]", key="overcharge_bar",
                                     scale=BAR, lo=0.0, hi=1.0)
    overcharge_hold_s: float = parameter(30.0, "time the driver's brake valve holds the full "
                                         "overcharge (assumed) [s]", lo=0.0, hi=600.0)
    overcharge_reduction_rate_Pa_s: float = parameter(
        0.4 * BAR / 200.0, "rate at which the overcharge is then reduced, slower than the "
        "0.3 bar in 60 s a distributor must not sense (UIC 540 insensitivity; assumed) [bar/s]",
        key="overcharge_reduction_rate_bar_s", scale=BAR, lo=1e-4, lo_open=True, hi=0.01)
    distributed_power: bool = parameter(False, "locomotives other than the venting vehicle "
                                        "repeat its driver's brake valve by radio")
    radio_delay_s: float = parameter(0.5, "delay of the radio repeating the commands at the "
                                     "other locomotives (assumed) [s]", lo=0.0, hi=10.0)
    # --- distributor
    application_threshold_Pa: float = parameter(0.27 * BAR, "pipe drop below the control "
                                                "reservoir that starts an application (UIC "
                                                "540 sensitivity, fitted) [bar]",
                                                key="application_threshold_bar", scale=BAR,
                                                lo=0.01, hi=1.0)
    control_time_constant_s: float = parameter(40.0, "time constant of the control reservoir "
                                               "following the pipe (insensitivity: 0.3 bar in "
                                               "60 s does not brake, UIC 540; fitted) [s]",
                                               lo=0.5, hi=200.0)
    max_cylinder_pressure_Pa: float = parameter(3.8 * BAR, "maximum brake-cylinder pressure "
                                                "(UIC 540) [bar]",
                                                key="max_cylinder_pressure_bar", scale=BAR,
                                                lo=1.0, hi=6.0)
    full_application_drop_Pa: float = parameter(1.5 * BAR, "pipe drop giving the maximum "
                                                "cylinder pressure (UIC 540) [bar]",
                                                key="full_application_drop_bar", scale=BAR,
                                                lo=0.5, hi=3.0)
    hysteresis_Pa: float = parameter(0.1 * BAR, "pipe rise needed before a graduated release "
                                     "step (fitted) [bar]", key="hysteresis_bar", scale=BAR,
                                     lo=0.0, hi=1.0)
    release_threshold_Pa: float = parameter(0.15 * BAR, "pipe drop below which the distributor "
                                            "releases fully (fitted) [bar]",
                                            key="release_threshold_bar", scale=BAR,
                                            lo=0.0, hi=1.0)
    inshot_pressure_Pa: float = parameter(1.445 * BAR, "first stage: cylinder pressure "
                                          "reached at the inshot rate (fitted to the peak forces "
                                          "of Tables 1-2 as 1.3 bar without a force threshold; "
                                          "0.22 + 1.3 x 3.58 / 3.8 gives the same block force "
                                          "above the threshold) [bar]",
                                          key="inshot_pressure_bar", scale=BAR, lo=0.0, hi=2.0)
    inshot_rate_Pa_s: float = parameter(8.0 * BAR, "cylinder filling rate during inshot "
                                        "(fitted) [bar/s]", key="inshot_rate_bar_s", scale=BAR,
                                        lo=0.01, lo_open=True, hi=50.0)
    application_stroke_Pa: float = parameter(0.0, "cylinder pressure held while the piston "
                                             "travels its application stroke, before the first "
                                             "stage fills on (0 with application_stroke_s 0: "
                                             "not modelled) [bar]", key="application_stroke_bar",
                                             scale=BAR, lo=0.0, hi=1.0)
    application_stroke_s: float = parameter(0.0, "time from the distributor applying until its "
                                            "application stroke ends: the cylinder stays at or "
                                            "below application_stroke_bar until then (0: no "
                                            "hold) [s]", lo=0.0, hi=5.0)
    block_force_threshold_Pa: float = parameter(0.22 * BAR, "cylinder pressure below which "
                                                "the blocks give no force (return spring and "
                                                "slack adjuster: 0.22 bar from UIC 544-1's worked "
                                                "brake calculation); above it the force grows "
                                                "linearly to the full block force at "
                                                "max_cylinder_pressure_bar [bar]",
                                                key="block_force_threshold_bar", scale=BAR,
                                                lo=0.0, hi=1.0)
    fill_rate_P_Pa_s: float = parameter(0.65 * BAR, "cylinder filling rate after inshot in P "
                                        "(fitted to UIC 540 P filling 3-5 s) [bar/s]",
                                        key="fill_rate_P_bar_s", scale=BAR, lo=0.01,
                                        lo_open=True, hi=50.0)
    fill_rate_G_Pa_s: float = parameter(0.09 * BAR, "cylinder filling rate after inshot in G "
                                        "(fitted to UIC 540 G filling 18-30 s and the ETCS "
                                        "conversion model's G build-up time) [bar/s]",
                                        key="fill_rate_G_bar_s", scale=BAR, lo=0.001,
                                        lo_open=True, hi=50.0)
    lap_time_constant_P_s: float = parameter(0.4, "time constant of the final approach to the "
                                             "target pressure in P (fitted) [s]", lo=0.01,
                                             hi=30.0)
    lap_time_constant_G_s: float = parameter(2.0, "time constant of the final approach to the "
                                             "target pressure in G (fitted) [s]", lo=0.01,
                                             hi=60.0)
    release_time_constant_P_s: float = parameter(4.0, "time constant of the cylinder exhaust "
                                                 "in P (fitted to UIC 540 release 15-20 s) [s]",
                                                 lo=0.1, hi=100.0)
    release_time_constant_G_s: float = parameter(20.0, "time constant of the cylinder exhaust "
                                                 "in G (fitted to UIC 540 release 45-60 s) "
                                                 "[s]", lo=0.1, hi=300.0)
    aux_reservoir_volume_m3: float = parameter(0.1, "auxiliary reservoir volume (assumed "
                                               "100 L) [m3]", lo=0.005, hi=1.0)
    cylinder_volume_m3: float = parameter(0.02, "brake-cylinder volume at full stroke (assumed "
                                          "20 L) [m3]", lo=0.001, hi=0.5)
    aux_polytropic_index: float = parameter(1.2, "polytropic index of the auxiliary "
                                            "reservoir's expansion (1 isothermal, 1.4 "
                                            "adiabatic) [-]", lo=1.0, hi=1.4)
    aux_charge_area_m2: float = parameter(2e-6, "effective area of the auxiliary reservoir's "
                                          "charging choke (fitted) [m2]", lo=0.0, hi=1e-3)
    supply_band_Pa: float = parameter(0.1 * BAR, "auxiliary-reservoir surplus over the cylinder "
                                      "below which filling slows (fitted) [bar]",
                                      key="supply_band_bar", scale=BAR, lo=0.001, hi=1.0)
    quick_service_area_m2: float = parameter(1e-5, "effective area of the quick-service "
                                             "connection (fitted) [m2]", lo=0.0, hi=1e-3)
    quick_service_volume_m3: float = parameter(0.0005, "quick-service chamber (fitted) [m3]",
                                               lo=1e-5, hi=0.05)
    acceleration_chambers: bool = parameter(True, "distributors vent the pipe locally on an "
                                            "emergency drop (UIC 540 emergency accelerator)")
    accelerator_threshold_Pa: float = parameter(0.25 * BAR, "excess of the accelerator's "
                                                "reference chamber over the pipe that opens it "
                                                "(fitted) [bar]",
                                                key="accelerator_threshold_bar", scale=BAR,
                                                lo=0.01, hi=3.0)
    accelerator_time_constant_s: float = parameter(0.2, "time constant of the reference "
                                                   "chamber (drop rates above threshold / tau "
                                                   "open it; fitted) [s]", lo=0.001, hi=10.0)
    accelerator_area_m2: float = parameter(2e-4, "effective area of the accelerator's vent "
                                           "(fitted) [m2]", lo=0.0, hi=1e-2)
    accelerator_chamber_volume_m3: float = parameter(0.001, "acceleration chamber the "
                                                     "accelerator vents the pipe into, at "
                                                     "atmospheric pressure when charged "
                                                     "(fitted) [m3]", lo=1e-5, hi=0.05)


#: Parameters calibration may fit, by short name.
FITTABLE = {
    "valve_delay": Fittable("valve_delay_s", "s", 0.0, 3.0, 1.0,
                            "delay from a command to the driver's brake valve acting"),
    "fill_rate_P": Fittable("fill_rate_P_Pa_s", "Pa/s", 0.4 * BAR, 3.0 * BAR, 1.0 * BAR,
                            "cylinder filling rate after inshot in P (UIC 540: 3-5 s)"),
    "inshot": Fittable("inshot_pressure_Pa", "Pa", 0.0, 2.0 * BAR, 1.0 * BAR,
                       "cylinder pressure reached at the inshot rate"),
    "hose_loss": Fittable("hose_loss_coefficient", "-", 0.0, 30.0, 10.0,
                          "concentrated loss coefficient of a hose coupling"),
}


#: The model's validated range: the longest run of brake pipe from the nearest driver's brake
#: valve to a train end [m]. Its targets (UIC 540 windows and propagation at 500-1 500 m,
#: SUBSET-026's build-up time as a bound at 300-1 500 m, ``ltd-brake validate --brake-pipe``)
#: reach trains of up to 1 500 m vented from one end; longer trains run in reality with
#: distributed power (a driver's brake valve on every locomotive, repeated by radio).
MAX_VENTED_LENGTH_M = 1500.0


def validity(consist, p: Params) -> list[str]:
    """Where a run of this train leaves the model's validated range (empty: inside it).

    Parameters
    ----------
    consist : Consist
    p : Params

    Returns
    -------
    list of str
        One sentence per reason.
    """
    vs = consist.vehicles
    length = np.array([v.length_m for v in vs], float)
    front = np.concatenate(([0.0], np.cumsum(length)[:-1]))  # of each vehicle, from the head
    vent = int(getattr(consist, "venting_vehicle", 0))
    valves = [vent] + ([i for i, v in enumerate(vs) if v.traction is not None and i != vent]
                       if p.distributed_power else [])
    # the points furthest from every valve: the train's ends and midway between two valves
    centres = np.sort(front[valves] + length[valves] / 2)
    points = np.concatenate(([0.0, float(length.sum())], (centres[1:] + centres[:-1]) / 2))
    far = float(np.max(np.min(np.abs(points[:, None] - centres[None, :]), axis=1)))
    if far <= MAX_VENTED_LENGTH_M:
        return []
    how = ("with distributed power" if len(valves) > 1 else "vented from one end")
    return [f"brake-pipe model outside its validated range: {far:.0f} m of pipe from the "
            f"nearest driver's brake valve ({length.sum():.0f} m train, {how}), "
            f"beyond the {MAX_VENTED_LENGTH_M:.0f} m its UIC 540 and SUBSET-026 targets "
            "reach; pressures, delays and forces there are an extrapolation"]


def check_fields(p: Params) -> None:
    """Combinations of pressures and volumes no UIC brake has, each named with the other.

    Raises
    ------
    CompileError
    """
    def bar(x: float) -> str:
        return f"{x / BAR:g} bar"

    if p.main_reservoir_pressure_Pa <= p.running_pressure_Pa + p.overcharge_Pa:
        raise CompileError("main_reservoir_pressure_bar", f"{bar(p.main_reservoir_pressure_Pa)} "
                           f"cannot charge the pipe to running_pressure_bar + overcharge_bar "
                           f"({bar(p.running_pressure_Pa + p.overcharge_Pa)})")
    if p.full_service_Pa >= p.running_pressure_Pa:
        raise CompileError("full_service_bar", f"a reduction of {bar(p.full_service_Pa)} "
                           f"empties a pipe at running_pressure_bar {bar(p.running_pressure_Pa)}")
    if p.first_step_Pa >= p.full_service_Pa:
        raise CompileError("first_step_bar", f"{bar(p.first_step_Pa)} is not below "
                           f"full_service_bar ({bar(p.full_service_Pa)})")
    if p.release_threshold_Pa >= p.application_threshold_Pa:
        raise CompileError("release_threshold_bar", f"{bar(p.release_threshold_Pa)} is not "
                           f"below application_threshold_bar ({bar(p.application_threshold_Pa)}"
                           "): every application would release at once")
    if p.application_threshold_Pa >= p.full_application_drop_Pa:
        raise CompileError("application_threshold_bar", f"{bar(p.application_threshold_Pa)} is "
                           "not below full_application_drop_bar "
                           f"({bar(p.full_application_drop_Pa)})")
    if p.block_force_threshold_Pa >= p.max_cylinder_pressure_Pa:
        raise CompileError("block_force_threshold_bar", f"{bar(p.block_force_threshold_Pa)} is "
                           "not below max_cylinder_pressure_bar "
                           f"({bar(p.max_cylinder_pressure_Pa)}): the blocks would never "
                           "give their full force")
    if p.application_stroke_Pa > p.inshot_pressure_Pa:
        raise CompileError("application_stroke_bar", f"{bar(p.application_stroke_Pa)} is above "
                           f"inshot_pressure_bar ({bar(p.inshot_pressure_Pa)}): the stroke "
                           "comes before the first stage")
    if p.inshot_pressure_Pa > p.max_cylinder_pressure_Pa:
        raise CompileError("inshot_pressure_bar", f"{bar(p.inshot_pressure_Pa)} is above "
                           f"max_cylinder_pressure_bar ({bar(p.max_cylinder_pressure_Pa)})")
    # the auxiliary reservoir at running pressure, shared with an empty cylinder at full
    # stroke (isothermal: the most it can give) must reach the maximum cylinder pressure
    v_aux, v_cyl = p.aux_reservoir_volume_m3, p.cylinder_volume_m3
    p_eq = (v_aux * (P_ATM + p.running_pressure_Pa) + v_cyl * P_ATM) / (v_aux + v_cyl) - P_ATM
    if p_eq < p.max_cylinder_pressure_Pa:
        raise CompileError("cylinder_volume_m3", f"{v_cyl:g} m3 filled from "
                           f"aux_reservoir_volume_m3 {v_aux:g} m3 at running pressure reaches "
                           f"at most {p_eq / BAR:.3g} bar, below max_cylinder_pressure_bar "
                           f"({bar(p.max_cylinder_pressure_Pa)})")


def compile(consist, params: Params, force_max_N: np.ndarray) -> BrakeArrays:  # noqa: A001
    """Pipe volumes, hose faces, distributor constants and the scalars of a train.

    Parameters
    ----------
    consist : Consist
        The train, head first (lengths, brakes, brake positions, venting vehicle).
    params : Params
    force_max_N : ndarray
        Full block force of each vehicle [N] (zeros: brakes switched off).

    Returns
    -------
    BrakeArrays
        ``coef`` columns ``C_*`` per vehicle and ``S_*`` scalars.
    """
    p = params
    vs = consist.vehicles
    n = len(vs)
    length = np.array([v.length_m for v in vs], float)
    area = math.pi * p.pipe_diameter_m ** 2 / 4.0
    rt = R_AIR * p.air_temperature_K
    coef = np.zeros((n, N_COEF))
    coef[:, C_CAP] = (area * length + p.branch_volume_m3) / rt
    coef[:-1, C_DX] = 0.5 * (length[:-1] + length[1:])
    coef[:-1, C_FACE_G] = p.pipe_step_s * area / coef[:-1, C_DX]
    coef[:-1, C_FACE_HOSE] = p.hose_loss_coefficient / coef[:-1, C_DX]
    coef[:, C_DISTRIBUTOR] = [1.0 if v.brake is not None else 0.0 for v in vs]
    in_g = np.array([v.brake_position == "G" for v in vs])
    coef[:, C_FILL_RATE] = np.where(in_g, p.fill_rate_G_Pa_s, p.fill_rate_P_Pa_s)
    coef[:, C_LAP_TAU] = np.where(in_g, p.lap_time_constant_G_s, p.lap_time_constant_P_s)
    coef[:, C_RELEASE_TAU] = np.where(in_g, p.release_time_constant_G_s,
                                      p.release_time_constant_P_s)
    coef[:, C_LAP_DECAY] = np.exp(-p.pipe_step_s / coef[:, C_LAP_TAU])
    coef[:, C_RELEASE_DECAY] = np.exp(-p.pipe_step_s / coef[:, C_RELEASE_TAU])
    vent = int(getattr(consist, "venting_vehicle", 0))
    scalars = {
        S_DT: p.pipe_step_s, S_AREA: area, S_DIAM: p.pipe_diameter_m,
        S_HOSE_K: p.hose_loss_coefficient, S_MU: p.air_viscosity_Pa_s, S_RT: rt,
        S_ROUGH: p.pipe_roughness_m / p.pipe_diameter_m,
        S_P_RUN: P_ATM + p.running_pressure_Pa, S_P_MR: P_ATM + p.main_reservoir_pressure_Pa,
        S_A_FEED: p.feed_area_m2, S_A_VENT: p.service_vent_area_m2,
        S_A_EMERG: p.emergency_area_m2, S_BAND: p.relay_band_Pa,
        S_FIRST_STEP: p.first_step_Pa, S_FULL_SERVICE: p.full_service_Pa,
        S_ER_DOWN: p.equalising_rate_down_Pa_s, S_ER_UP: p.equalising_rate_up_Pa_s,
        S_VENT: float(vent), S_THETA_APP: p.application_threshold_Pa,
        S_CR_TAU: p.control_time_constant_s, S_P_CMAX: p.max_cylinder_pressure_Pa,
        S_DP_FULL: p.full_application_drop_Pa, S_HYST: p.hysteresis_Pa,
        S_THETA_REL: p.release_threshold_Pa, S_P_INSHOT: p.inshot_pressure_Pa,
        S_INSHOT_RATE: p.inshot_rate_Pa_s, S_A_AUX: p.aux_charge_area_m2,
        S_V_AUX: p.aux_reservoir_volume_m3, S_V_CYL: p.cylinder_volume_m3,
        S_N_POLY: p.aux_polytropic_index, S_A_QS: p.quick_service_area_m2,
        S_V_QS: p.quick_service_volume_m3, S_ACC_ON: 1.0 if p.acceleration_chambers else 0.0,
        S_ACC_THETA: p.accelerator_threshold_Pa, S_ACC_TAU: p.accelerator_time_constant_s,
        S_A_ACC: p.accelerator_area_m2, S_V_ACC: p.accelerator_chamber_volume_m3,
        S_SUPPLY_BAND: p.supply_band_Pa, S_VALVE_DELAY: p.valve_delay_s,
        S_EM_OPEN: p.emergency_opening_s, S_OVER: p.overcharge_Pa,
        S_OVER_HOLD: p.overcharge_hold_s, S_OVER_RATE: p.overcharge_reduction_rate_Pa_s,
        S_P_STROKE: p.application_stroke_Pa, S_STROKE_S: p.application_stroke_s,
        S_P_FORCE0: p.block_force_threshold_Pa,
    }
    for col, value in scalars.items():
        coef[:, col] = value
    coef[:, C_VALVE] = -1.0
    coef[vent, C_VALVE] = p.valve_delay_s
    if p.distributed_power:
        for i, v in enumerate(vs):
            if v.traction is not None and i != vent:
                coef[i, C_VALVE] = p.valve_delay_s + p.radio_delay_s
    centre = centre_offsets_m(length)
    valves = np.flatnonzero(coef[:, C_VALVE] >= 0.0)
    reach = np.abs(centre[:, None] - centre[valves][None, :]) / math.sqrt(rt)
    delay = np.min(coef[valves, C_VALVE][None, :] + reach, axis=1)
    return BrakeArrays(ID, delay, np.ascontiguousarray(force_max_N, float), coef)


def initial_state(arrays: BrakeArrays) -> BrakeState:
    """A charged train: pipe and reservoirs at the running pressure, brakes released."""
    coef = arrays.coef
    n = coef.shape[0]
    p_run = coef[0, S_P_RUN]
    state = released_state(n, N_EXTRA, N_WORK)
    extra = state.extra
    for col in (X_P, X_CR, X_AUX, X_REF, X_ER):
        extra[:, col] = p_run
    extra[:, X_QS] = P_ATM
    extra[:, X_ACC_P] = P_ATM
    extra[:, X_GRID] = -1.0
    extra[:, X_T_ACT] = -1e9  # long before any command
    extra[:, X_T_APP] = -1e9
    return state


# --------------------------------------------------------------------------- equations


@jit_inner
def orifice(p_up, p_down, area):
    """Mass flow through an orifice per unit c_choked / sqrt(R T), and its derivatives.

    Isentropic nozzle: choked below the critical ratio, the ellipse ISO 6358 form above it,
    linear over the last 0.5 % before equal pressures (keeps the derivative finite).

    Parameters
    ----------
    p_up, p_down : float
        Absolute pressures [Pa]; no flow when ``p_up <= p_down``.
    area : float
        Effective area [m2].

    Returns
    -------
    m : float
        area * p_up * phi(p_down / p_up) [m2 Pa]; times ``_C_CHOKED / sqrt(R T)`` gives kg/s.
    dm_dup, dm_ddown : float
        Derivatives [m2].
    """
    if p_up <= p_down or area <= 0.0:
        return 0.0, 0.0, 0.0
    r = p_down / p_up
    if r <= _CRITICAL:
        return area * p_up, area, 0.0
    zl = (_LAMINAR - _CRITICAL) / (1.0 - _CRITICAL)
    if r < _LAMINAR:
        z = (r - _CRITICAL) / (1.0 - _CRITICAL)
        phi = math.sqrt(1.0 - z * z)
        dphi = -z / ((1.0 - _CRITICAL) * phi)
    else:
        phil = math.sqrt(1.0 - zl * zl)
        phi = phil * (1.0 - r) / (1.0 - _LAMINAR)
        dphi = -phil / (1.0 - _LAMINAR)
    return area * p_up * phi, area * (phi - r * dphi), area * dphi


@jit_inner
def _clip01(x):
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@jit_inner
def _valve_branch(p, coef, mode, em_open, per):
    """Outflow through a driver's brake valve in position ``mode`` at pipe pressure ``p`` and
    equalising-reservoir pressure ``per`` [Pa abs], and its derivative, in orifice units (see
    :func:`orifice`); negative: feed."""
    if mode == _EMERGENCY:
        m, d, _ = orifice(p, P_ATM, em_open * coef[0, S_A_EMERG])
        return m, d
    band = coef[0, S_BAND]
    if p > per:
        s = _clip01((p - per) / band)
        m, d, _ = orifice(p, P_ATM, coef[0, S_A_VENT])
        ds = 1.0 / band if s < 1.0 else 0.0
        return s * m, s * d + ds * m
    if p < per:
        s = _clip01((per - p) / band)
        m, _, dd = orifice(coef[0, S_P_MR], p, coef[0, S_A_FEED])
        ds = -1.0 / band if s < 1.0 else 0.0
        return -s * m, -(s * dd + ds * m)
    return 0.0, 0.0


@jit_inner
def _distributor_branch(i, p, coef, extra):
    """Outflow from pipe volume i into its distributor's accelerator vent, quick-service
    chamber and auxiliary reservoir at pipe pressure ``p`` [Pa abs], and its derivative, in
    orifice units (see :func:`orifice`)."""
    q = 0.0
    dq = 0.0
    if extra[i, X_ACC] == 1.0:
        m, d, _ = orifice(p, extra[i, X_ACC_P], coef[0, S_A_ACC])
        q += m
        dq += d
    if extra[i, X_QS_STATE] == 1.0:
        m, d, _ = orifice(p, extra[i, X_QS], coef[0, S_A_QS])
        q += m
        dq += d
    if p > extra[i, X_AUX]:  # check valve: pipe -> auxiliary reservoir
        m, d, _ = orifice(p, extra[i, X_AUX], coef[0, S_A_AUX])
        q += m
        dq += d
    return q, dq


@jit_step_inner
def _pipe_step(coef, extra, dt, a, b, c, rhs, work):
    """One backward-Euler step of the pipe pressures and face flows (in ``extra``)."""
    n = coef.shape[0]
    area, diam, mu, rt = coef[0, S_AREA], coef[0, S_DIAM], coef[0, S_MU], coef[0, S_RT]
    kflow = _C_CHOKED / math.sqrt(rt)
    lam_floor = 64.0 * mu * area / diam  # laminar f |m| at vanishing flow [kg/s]
    inv_dt = 1.0 / dt
    for i in range(n):
        a[i] = 0.0
        c[i] = 0.0
        cap = coef[i, C_CAP] * inv_dt
        p = extra[i, X_P]
        b[i] = cap
        rhs[i] = cap * p
        if coef[i, C_DISTRIBUTOR] > 0.0:
            q, dq = _distributor_branch(i, p, coef, extra)
            b[i] += dq * kflow
            rhs[i] += (dq * p - q) * kflow
        if coef[i, C_VALVE] >= 0.0:
            q, dq = _valve_branch(p, coef, int(extra[i, X_MODE]), extra[i, X_EM_OPEN],
                                  extra[i, X_ER])
            b[i] += dq * kflow
            rhs[i] += (dq * p - q) * kflow
    # face flow under friction, linearised: m_new (1 + dt lam) = m + dt A / dx (p_f - p_f+1),
    # dt lam = dt R T / A (f_m / D + K |m| / dx) / (p_f + p_f+1), f_m = f |m| (64/Re laminar
    # floor; turbulent: Colebrook's friction factor in Haaland's explicit form, within 2 %,
    # 1/sqrt(f) = -1.8 log10((eps/D / 3.7)^1.11 + 6.9/Re))
    c_lam = dt * rt / area
    inv_diam = 1.0 / diam
    re_per_m = diam / (area * mu)  # Re per kg/s of face flow
    rough = (coef[0, S_ROUGH] / 3.7) ** 1.11
    for f in range(n - 1):
        m = extra[f, X_M]
        am = abs(m)
        fm = lam_floor
        if am * re_per_m > 2000.0:
            x = -1.8 * math.log10(rough + 6.9 / (am * re_per_m))
            fm = max(lam_floor, am / (x * x))
        psum = extra[f, X_P] + extra[f + 1, X_P]
        inv_den = psum / (psum + c_lam * (fm * inv_diam + coef[f, C_FACE_HOSE] * am))
        g = coef[f, C_FACE_G] * inv_den
        mt = m * inv_den
        work[f] = g
        # m_new = mt + g (p_f - p_f+1)
        b[f] += g
        b[f + 1] += g
        c[f] = -g
        a[f + 1] = -g
        rhs[f] -= mt
        rhs[f + 1] += mt
        extra[f, X_M] = mt  # provisional: completed below
    # Thomas algorithm (diagonally dominant: no pivoting); b keeps the pivots' reciprocals
    for i in range(1, n):
        inv = 1.0 / b[i - 1]
        b[i - 1] = inv
        w = a[i] * inv
        b[i] -= w * c[i - 1]
        rhs[i] -= w * rhs[i - 1]
    b[n - 1] = 1.0 / b[n - 1]
    rhs[n - 1] *= b[n - 1]
    for i in range(n - 2, -1, -1):
        rhs[i] = (rhs[i] - c[i] * rhs[i + 1]) * b[i]
    for f in range(n - 1):
        extra[f, X_M] += work[f] * (rhs[f] - rhs[f + 1])


@jit_inner
def _chamber_fill(p0, p, pc, area, volume, dt, rt, kflow):
    """A chamber at ``pc`` [Pa abs] filled from the pipe (``p0`` -> ``p`` over the step) through
    ``area`` [m2] into ``volume`` [m3]: its new pressure and whether it has equalised (within
    0.02 bar of the pipe)."""
    m, d, _ = orifice(p0, pc, area)
    q = (m + d * (p - p0)) * kflow
    pc = pc + dt * rt / volume * max(q, 0.0)
    if pc >= p - 0.02 * BAR:
        return min(pc, p), True
    return pc, False


@jit_step_inner
def _grid_step(arrays, state, events, k, a, b, c, rhs, work, pold):
    """Advance the pipe, the driver's valve and every distributor from grid point k to k + 1."""
    coef, extra = arrays.coef, state.extra
    n = coef.shape[0]
    dt = coef[0, S_DT]
    tk = k * dt
    lvl, lkind, nxt = state.level, state.level_kind, state.next_event
    p_run = coef[0, S_P_RUN]
    for v in range(n):
        delay = coef[v, C_VALVE]
        if delay < 0.0:
            continue
        # commands that act before the end of this step (issued a valve delay earlier) reach
        # this driver's brake valve; within the step they act from their own time on
        j = nxt[v]
        while j < events.count and events.time_s[j] + delay < tk + dt:
            extra[v, X_T_ACT] = events.time_s[j] + delay
            lvl[v] = events.level[j]
            lkind[v] = events.kind[j]
            j += 1
        nxt[v] = j
        level = lvl[v]
        if level > 0.0 and lkind[v] == EMERGENCY:
            mode = _EMERGENCY
            er_target = P_ATM
        elif level > 0.0:
            mode = _SERVICE
            red = max(coef[0, S_FIRST_STEP], level * coef[0, S_FULL_SERVICE])
            er_target = p_run - min(red, coef[0, S_FULL_SERVICE])
        else:
            mode = _RELEASE
            er_target = p_run
            if lkind[v] == OVERCHARGE:
                # overcharge held, then reduced slower than a distributor senses
                since = tk + dt - extra[v, X_T_ACT] - coef[0, S_OVER_HOLD]
                er_target += max(0.0, coef[0, S_OVER] - coef[0, S_OVER_RATE] * max(0.0, since))
        # the equalising reservoir moves for the part of the step the command acts
        acting = _clip01((tk + dt - extra[v, X_T_ACT]) / dt)
        er = extra[v, X_ER]
        if er > er_target:
            er = max(er_target, er - coef[0, S_ER_DOWN] * dt * acting)
        else:
            er = min(er_target, er + coef[0, S_ER_UP] * dt * acting)
        extra[v, X_ER] = er
        extra[v, X_MODE] = float(mode)
        # the emergency valve opens linearly over its opening time
        extra[v, X_EM_OPEN] = _clip01((tk + dt - extra[v, X_T_ACT]) / coef[0, S_EM_OPEN])
    # vehicles without a valve show the venting vehicle's command
    lead = int(coef[0, S_VENT])
    for i in range(n):
        if coef[i, C_VALVE] < 0.0:
            lvl[i] = lvl[lead]
            lkind[i] = lkind[lead]
            nxt[i] = nxt[lead]
    for i in range(n):
        pold[i] = extra[i, X_P]
    _pipe_step(coef, extra, dt, a, b, c, rhs, work)
    rt = coef[0, S_RT]
    kflow = _C_CHOKED / math.sqrt(rt)
    for i in range(n):
        p = rhs[i]
        if p < P_ATM:
            p = P_ATM
        extra[i, X_P] = p
    # branch reservoirs take what the linearised pipe step gave them (mass conserved)
    p_cmax = coef[0, S_P_CMAX]
    dp_full = coef[0, S_DP_FULL]
    hyst = coef[0, S_HYST]
    e_cr = 1.0 - math.exp(-dt / coef[0, S_CR_TAU])
    e_ref = 1.0 - math.exp(-dt / coef[0, S_ACC_TAU])
    acc_on = coef[0, S_ACC_ON] > 0.0
    v_aux = coef[0, S_V_AUX]
    draw = coef[0, S_N_POLY] * coef[0, S_V_CYL] / v_aux
    p_stroke, stroke_s = coef[0, S_P_STROKE], coef[0, S_STROKE_S]
    p_force0 = coef[0, S_P_FORCE0]
    for i in range(n):
        if coef[i, C_DISTRIBUTOR] <= 0.0:
            continue
        p = extra[i, X_P]
        p0 = pold[i]
        # auxiliary reservoir charging through its check valve
        m, d, _ = orifice(p0, extra[i, X_AUX], coef[0, S_A_AUX])
        qa = (m + d * (p - p0)) * kflow
        if qa > 0.0:
            extra[i, X_AUX] = min(extra[i, X_AUX] + dt * rt / v_aux * qa, max(p, extra[i, X_AUX]))
        # quick-service chamber
        if extra[i, X_QS_STATE] == 1.0:
            extra[i, X_QS], full = _chamber_fill(p0, p, extra[i, X_QS], coef[0, S_A_QS],
                                                 coef[0, S_V_QS], dt, rt, kflow)
            if full:
                extra[i, X_QS_STATE] = 2.0
        # accelerator: opens when the pipe falls faster than its reference chamber follows and
        # vents the pipe into its acceleration chamber until the two have equalised
        if extra[i, X_ACC] == 1.0:
            extra[i, X_ACC_P], full = _chamber_fill(p0, p, extra[i, X_ACC_P], coef[0, S_A_ACC],
                                                    coef[0, S_V_ACC], dt, rt, kflow)
            if full:
                extra[i, X_ACC] = 2.0
        ref = extra[i, X_REF]
        if extra[i, X_ACC] == 0.0 and acc_on and ref - p > coef[0, S_ACC_THETA]:
            extra[i, X_ACC] = 1.0
        extra[i, X_REF] = ref + (p - ref) * e_ref
        # control reservoir, application and release
        cr = extra[i, X_CR]
        drop = cr - p
        if extra[i, X_APPLIED] == 0.0:
            if drop > coef[0, S_THETA_APP]:
                extra[i, X_APPLIED] = 1.0
                extra[i, X_T_APP] = tk + dt
                if extra[i, X_QS_STATE] == 0.0:
                    extra[i, X_QS_STATE] = 1.0
            else:
                extra[i, X_CR] = cr + (p - cr) * e_cr
        target = extra[i, X_TARGET]
        if extra[i, X_APPLIED] == 1.0:
            if drop < coef[0, S_THETA_REL]:
                # fully released: the control reservoir follows the pipe again
                extra[i, X_APPLIED] = 0.0
                extra[i, X_QS_STATE] = 0.0
                extra[i, X_QS] = P_ATM
                extra[i, X_ACC] = 0.0
                extra[i, X_ACC_P] = P_ATM
                target = 0.0
            else:
                # play hysteresis between the application and release characteristics
                lo = p_cmax * _clip01(drop / dp_full)
                hi = p_cmax * _clip01((drop + hyst) / dp_full)
                target = min(max(target, lo), hi)
        extra[i, X_TARGET] = target
        # brake cylinder
        pc = extra[i, X_CYL]
        if target > pc:
            rate = coef[0, S_INSHOT_RATE] if pc < coef[0, S_P_INSHOT] else coef[i, C_FILL_RATE]
            surplus = extra[i, X_AUX] - P_ATM - pc
            rate *= _clip01(surplus / coef[0, S_SUPPLY_BAND])
            gap = target - pc
            tau = coef[i, C_LAP_TAU]
            new = pc
            if gap <= rate * tau:
                new = target - gap * coef[i, C_LAP_DECAY]
            elif rate > 0.0:
                linear_s = (gap - rate * tau) / rate  # time left at the full rate
                if linear_s >= dt:
                    new = pc + rate * dt
                else:
                    new = target - rate * tau * math.exp(-(dt - linear_s) / tau)
            new = min(new, target, p_cmax)
            if tk + dt - extra[i, X_T_APP] < stroke_s:
                # the piston travels its application stroke: the first stage waits
                new = min(new, p_stroke)
            if new > pc:
                extra[i, X_AUX] -= draw * (new - pc)
                pc = new
        elif target < pc:
            pc = target + (pc - target) * coef[i, C_RELEASE_DECAY]
        extra[i, X_CYL] = pc
        state.force_N[i] = arrays.force_max_N[i] * max(pc - p_force0, 0.0) / (p_cmax - p_force0)


@jit_step_inner
def advance(arrays, state, events, t0, t1):
    """Advance pipe and distributors on their time grid up to t1 [s] (state updated in place).

    Grid steps from the stored grid point to the last one at or before t1; the block forces
    are those of that grid point (see the module notes: independent of how [t0, t1] is split).
    """
    extra = state.extra
    dt = arrays.coef[0, S_DT]
    k = int(extra[0, X_GRID])
    if k < 0:
        k = int(math.floor(t0 / dt + _GRID_TOL))
    k1 = int(math.floor(t1 / dt + _GRID_TOL))
    if k1 <= k:
        extra[0, X_GRID] = float(k)
        return
    scratch = state.work
    a, b, c, rhs, work, pold = (scratch[0], scratch[1], scratch[2], scratch[3], scratch[4],
                                scratch[5])
    while k < k1:
        _grid_step(arrays, state, events, k, a, b, c, rhs, work, pold)
        k += 1
    extra[0, X_GRID] = float(k)


def snapshot_extras(arrays: BrakeArrays, state) -> dict:
    """Brake-pipe and brake-cylinder pressure of every vehicle, gauge [Pa]."""
    return {"brake_pipe_pressure_Pa": state.extra[:, X_P] - P_ATM,
            "brake_cylinder_pressure_Pa": state.extra[:, X_CYL].copy()}

"""Verdicts on a run: coupler strength and travel, endurable compressive force, adhesion,
wheel temperature.

One table, one row per criterion. Each criterion states what it assesses, over which part of
the run (its scope) and by what source; its status is PASS, its severity when a limit is
exceeded (FAIL, WARN or INFO), or ``not assessed``, and it names every coupler or vehicle
beyond its limit (by how much, when, at what speed):

======================  ==========  ======================================================
``draft_strength``      FAIL        each coupler's draft force against the breaking load of
                                    the draw gear (all speeds)
``buff_strength``       FAIL        each coupler's buff force against the compressive
                                    strength of the vehicle ends (all speeds)
``endurable_lcf``       FAIL        buff force against the endurable longitudinal compressive
                                    force of the two vehicles (EN 15839); not assessed unless
                                    a consist gives one
``coupler_travel``      FAIL        each coupler's deflection against the coupler model's
                                    travel (a buffer's solid end, a table's last point):
                                    beyond it the forces are not physical and the run is
                                    marked so
``adhesion``            FAIL        each vehicle's mean utilised adhesion over the braked
                                    part of a stop from 100 km/h or more (full application
                                    to 5 km/h) against its limit, 0.12 for a vehicle without
                                    wheel-slide protection
``adhesion_at_speed``   WARN        each vehicle's instantaneous adhesion demand above
                                    30 km/h against 0.15
``adhesion_low_speed``  INFO        the largest instantaneous demand below 30 km/h (never a
                                    failure: block friction peaks as the wheels slow down;
                                    noted where it exceeds a wet rail's adhesion)
``standstill_holding``  FAIL        after the stop, the force each vehicle must hold (coupler
                                    forces, grade) against what its brake holds at rest
``wheel_temperature``   WARN        each tread-braked vehicle's peak mean wheel temperature
                                    (:mod:`~.physics.brakes.thermal`) against 350 C, a
                                    conservative value (no limit verified)
======================  ==========  ======================================================

Adhesion demand is the air brake's retarding force over the vehicle's weight, m g; its mean
over a stop (EN 14531-1's mean-value calculation) subtracts what decelerates the rotating
masses, ((rho - 1) M a), and weights by distance: the brake's work at the rails over the
distance run while the brake is fully applied (:data:`~.physics.kernel.FULL_APPLICATION`) and
the vehicle runs at 5 km/h or faster. The kinetic brake force is never evaluated at rest: a
stopped, braked wheel holds, it demands no sliding adhesion.

Limits of coupler j (joining vehicles j - 1 and j, vehicles numbered from 0 at the head): the
smaller of the two vehicles' ``limits`` in the consist file, else the coupler model's
(``draft_strength_kN``/``buff_strength_kN`` of the coupler file), else the defaults below.
Every default names its source and whether its value was verified in the source's text.

The simulator (:class:`Watch`) raises an event when a limit is first exceeded; ``ltd-brake
simulate``, the run report (:func:`judge` on recorded samples), the campaign flags
(:func:`flags`) and the plant's diagnostics (:func:`diagnostic_values`) use this module alike.
"""
from __future__ import annotations

from .rules import (ADHESION_AT_SPEED_LIMIT, ADHESION_LIMIT, ADHESION_LIMIT_WSP,
                    ADHESION_SPEED_KMH, BUFF_STRENGTH_N, CRITERIA, DRAFT_STRENGTH_N,
                    MEAN_ADHESION_MIN_INITIAL_KMH, REST_ADHESION, WHEEL_TEMPERATURE_LIMIT_K,
                    Rule, TrainLimits,
                    default_coupler_limits, limits_from_metadata, limits_metadata, train_limits,
                    wet_rail_adhesion)
from .table import (FLAG_NAMES, Criterion, Exceedance, VehicleDemand, Verdicts,
                    diagnostic_values, flags, judge, merge)
from .watch import SampledDemand, Watch

__all__ = ["ADHESION_AT_SPEED_LIMIT", "ADHESION_LIMIT", "ADHESION_LIMIT_WSP",
           "ADHESION_SPEED_KMH", "BUFF_STRENGTH_N", "CRITERIA", "DRAFT_STRENGTH_N",
           "FLAG_NAMES", "MEAN_ADHESION_MIN_INITIAL_KMH", "REST_ADHESION", "Criterion",
           "Exceedance", "Rule",
           "SampledDemand", "TrainLimits", "VehicleDemand", "Verdicts",
           "WHEEL_TEMPERATURE_LIMIT_K", "Watch", "default_coupler_limits", "diagnostic_values",
           "flags", "judge", "limits_from_metadata", "merge", "limits_metadata", "train_limits",
           "wet_rail_adhesion"]

"""Verdicts on a run: coupler strength, the buffers' limit state and travel, endurable
compressive force, adhesion by design and against the rail, holding at rest, wheel temperature.

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
``buffer_limit_state``  FAIL        each coupling's buff force against twice its buffers'
                                    declared end force: beyond it the run is non-physical
``coupler_travel``      FAIL        each coupler's deflection against the coupler model's
                                    travel: beyond it the run is non-physical
``adhesion``            FAIL        each braked vehicle's mean utilised adhesion by design,
                                    its own stop from its maximum speed (the mean-value
                                    method), whatever the run, against 0.12 (0.15 with
                                    wheel-slide protection)
``adhesion_demand``     WARN        each braked vehicle's demand while moving against the
                                    declared rail's adhesion: wheel slide expected
``standstill_holding``  FAIL        the train settled at rest: the force it must hold against
                                    what its vehicles hold (a parking-brake calculation)
``runaway``             FAIL        a vehicle moving from a settled standstill without
                                    traction
``wheel_temperature``   WARN        each tread-braked vehicle's peak mean wheel temperature
                                    against 350 C, indicative (no limit verified)
======================  ==========  ======================================================

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

"""Calibration of model parameters: brake parameters against reference stopping distances,
coupler parameters against the paper's peak in-train forces.

The paper tuned ``t_app``, ``v_air`` and ``t_fill`` by trial and error until its simulated
emergency stops matched UIC 544-1. Here the chosen parameters are fitted by bounded nonlinear
least squares (:func:`scipy.optimize.least_squares`, trust-region reflective) on the relative
stopping-distance errors ``(S_sim - S_ref) / S_ref`` of a set of trains
(:func:`calibrate`), or on the peak draft and buff forces of Tables 1-2 with the coupler
positions and the distances as constraints (:func:`calibrate_couplers`).

A fit that generalises fits only what its targets determine: asked to, it holds the later of
two parameters whose estimates correlate beyond :data:`MAX_ABS_CORRELATION` at its start value
(a physical prior given by the start file) and fits again; it reports leave-one-train-out
errors (each train left out of the fit in turn and predicted by the others' values) next to
the fit's own; and the command line refuses to write a parameter file with a value on a bound.

Targets
-------
``uic``
    UIC 544-1 at 100 km/h: the UIC column of Table 1 for the paper's trains, and the UIC
    reference curve ``S = C / lambda + D`` (C = 50 752 m %, D = 53.45 m, the fit of that
    column) for any other train, with lambda from Eq. 11.
``paper``
    The LTDPoliTo column of Tables 1-2 (the paper's own model), at 100 or 50 km/h.

Every residual evaluation runs the trains' emergency stops on one process pool that lives for
the whole fit; the finite-difference columns of the Jacobian are evaluated as one batch spread
over the workers. The uncertainty reported is the usual linearised one,
``cov = (J^T J)^-1 s^2`` with ``s^2 = |r|^2 / (m - n)`` (m targets, n parameters not held by a
bound), J from second-order differences at the fitted values. The reference distances carry no
measurement noise, so the intervals measure how closely the model structure can follow the
references; the correlation matrix shows which parameters the chosen trains cannot tell apart.
A parameter that ends on a bound is reported as such, without an interval.
"""
from __future__ import annotations

from ...inputs import InputError
from .parameters import (BOUND_TOL, FIT_PARAMETERS, FitParameter, HOLD_CORRELATION,
                         MAX_ABS_CORRELATION, MAX_RELATIVE_CI, UIC_C_M_PERCENT, UIC_D_M,
                         UIC_SPEED_KMH, WRITE_DIGITS, coupler_fit_parameters, fit_parameters,
                         parse_fit, parse_values, with_bounds)
from .targets import (Target, braked_weight_percent, build_targets, companion_rows,
                      uic_curve_distance_m)
from .evaluation import BUFF, BUFF_AT, DISTANCE, DRAFT, DRAFT_AT, DistanceEvaluator, METRICS
from .fit import Calibration, FitOutcome, calibrate
from .forces import (BUFF_TOL, CouplerCalibration, DISTANCE_TOL, DRAFT_LIMIT_N, DRAFT_TOL,
                     FORCE_RESIDUALS, LIMIT_WEIGHT, MARGIN_WEIGHT, POSITION_TOL, POSITION_WEIGHT,
                     TARGET_MARGIN, calibrate_couplers, force_residuals, limit_residuals,
                     snatch_trains)
from .tables import (companion_table, correlation_table, force_summary_lines, force_table,
                     limit_lines, parameters_table, summary_lines, targets_table)
from .files import coupler_file_text, display_path, parameter_file_text, parameter_lines
from .validation import validation_targets

__all__ = ['BOUND_TOL', 'BUFF', 'BUFF_AT', 'BUFF_TOL', 'Calibration', 'CouplerCalibration',
           'DISTANCE', 'DISTANCE_TOL', 'DRAFT', 'DRAFT_AT', 'DRAFT_LIMIT_N', 'DRAFT_TOL',
           'DistanceEvaluator', 'FIT_PARAMETERS', 'FORCE_RESIDUALS', 'FitOutcome', 'FitParameter',
           'HOLD_CORRELATION', 'InputError', 'LIMIT_WEIGHT', 'MARGIN_WEIGHT',
           'MAX_ABS_CORRELATION', 'MAX_RELATIVE_CI', 'METRICS', 'POSITION_TOL', 'POSITION_WEIGHT',
           'TARGET_MARGIN', 'Target', 'UIC_C_M_PERCENT', 'UIC_D_M', 'UIC_SPEED_KMH',
           'WRITE_DIGITS', 'braked_weight_percent', 'build_targets', 'calibrate',
           'calibrate_couplers', 'companion_rows', 'companion_table', 'correlation_table',
           'coupler_file_text', 'coupler_fit_parameters', 'display_path', 'fit_parameters',
           'force_residuals', 'force_summary_lines', 'force_table', 'limit_lines',
           'limit_residuals', 'parameter_file_text', 'parameter_lines', 'parameters_table',
           'parse_fit', 'parse_values', 'snatch_trains', 'summary_lines', 'targets_table',
           'uic_curve_distance_m', 'validation_targets', 'with_bounds']

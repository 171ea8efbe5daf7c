"""A calibration as a parameter file, with how it was produced."""
from __future__ import annotations

import dataclasses
import math
import os
import textwrap
from pathlib import Path

import numpy as np

from ...inputs import BrakeParams
from ...outputs import one_line
from ...physics import brakes, couplers
from ...physics.couplers import lut_hysteresis
from ...physics.parameters import specs
from .parameters import WRITE_DIGITS, _field_comment
from .evaluation import BUFF, BUFF_AT, DRAFT, DRAFT_AT
from .fit import Calibration
from .forces import BUFF_TOL, CouplerCalibration, DRAFT_TOL
from .tables import _pct, limit_lines


def display_path(path: str) -> str:
    """``path`` relative to the working directory where it can be, as a user typed it.

    Parameters
    ----------
    path : str

    Returns
    -------
    str
    """
    try:
        return os.path.relpath(path)
    except ValueError:
        return path


def _held_and_warnings(cal) -> list[str]:
    """Comment lines of the parameters held at their start values and of the warnings."""
    head = []
    for w in cal.warnings:
        head += textwrap.wrap(f"warning: {w}", 98, initial_indent="# ",
                              subsequent_indent="#   ")
    return head


def _fitted_lines(cal) -> list[str]:
    """Comment lines of the fitted values with their 95 % confidence half-widths."""
    head = [f"# Fitted values, 95 % confidence half-widths (Student t, {max(cal.dof, 0)} dof, "
            "(J^T J)^-1 s^2):"]
    for j, p in enumerate(cal.fit):
        ci = cal.ci95[j]
        if p.name in cal.at_bound:
            head.append(f"#   {p.field} = {cal.value(p):.5g} {p.unit} (on its bound)")
        else:
            head.append(f"#   {p.field} = {cal.value(p):.5g} +/- "
                        f"{'NA' if not np.isfinite(ci) else f'{ci:.2g}'}"
                        f"{'' if p.unit == '-' else ' ' + p.unit}"
                        f"  (bounds {p.lower:.4g} to {p.upper:.4g})")
    return head


def _file_value(value, spec) -> str:
    """A field's value in its file unit, as YAML."""
    if isinstance(value, bool):
        return str(value).lower()
    if spec.sequence:
        return "[" + ", ".join(f"{v / spec.scale:.{WRITE_DIGITS}g}" for v in value) + "]"
    return f"{float(value) / spec.scale:.{WRITE_DIGITS}g}"


def coupler_file_text(cal: "CouplerCalibration", command: str) -> str:
    """Coupler YAML of the fitted values, headed by how they were produced.

    Parameters
    ----------
    cal : CouplerCalibration
    command : str
        The command line that produced it.

    Returns
    -------
    str
        A document that :func:`~ltd_brake_ros.inputs.load_coupler_lut` accepts.
    """
    head = ["# Coupler characteristic calibrated against the peak draft and buff forces of the",
            "# paper's Tables 1-2 (positions and LTDPoliTo distances as constraints), by least",
            "# squares on the force errors in fractions of their targets (draft "
            f"+/-{100 * DRAFT_TOL:g} %, buff +/-{100 * BUFF_TOL:g} %).",
            "# Produced by:", f"#   {command}",
            f"# Start values: {display_path(cal.start.source)}; brake parameters: "
            f"{display_path(cal.brake.source)}.",
            "# Peak forces at the values below, kN@coupler (paper, ours, error, left out: "
            "fitted without the train):"]
    ea, ec = cal.error_percent("after"), cal.error_percent("cv")
    for i, s in enumerate(cal.scenarios):
        p, a = s.paper, cal.after[i]
        head.append(f"#   run {s.number:>2} draft {p['draft_kN']:>3}@{p['draft_coupler']:<2} "
                    f"{a[DRAFT]:4.0f}@{a[DRAFT_AT]:<2.0f} {_pct(ea[i, 0]):>9} "
                    f"({_pct(ec[i, 0])})  buff {p['buff_kN']:>3}@{p['buff_coupler']:<2} "
                    f"{a[BUFF]:4.0f}@{a[BUFF_AT]:<2.0f} {_pct(ea[i, 1]):>9} ({_pct(ec[i, 1])})")
    if cal.limits:
        head.append("# Held below the draft limit (start -> fitted):")
        head += [f"#   {line}" for line in limit_lines(cal)]
    head += _fitted_lines(cal)
    model = couplers.model_of(cal.params)
    if model is lut_hysteresis:
        head.append(f"# Energy one buffer stores over its 105 mm stroke: "
                    f"{lut_hysteresis.buffer_energy_J(cal.params) / 1e3:.1f} kJ (UIC 526-1 / "
                    "EN 15551 categories: A 30, B 50, C 70 kJ).")
    head += _held_and_warnings(cal)
    body = [] if model.NAME == couplers.DEFAULT_MODEL else [f"model: {model.NAME}"]
    stem = Path(cal.start.source).stem if cal.start.source else model.NAME
    body.append(f"name: {stem} calibrated to the peak forces of Tables 1-2")
    defaults = {f.name: f.default for f in dataclasses.fields(cal.params)}
    for name, spec in specs(type(cal.params)).items():
        value = getattr(cal.params, name)
        if not spec.sequence and value == defaults[name] and not math.isfinite(value):
            continue  # an unknown strength stays unknown
        body.append(f"{spec.key or name}: {_file_value(value, spec)}  # {spec.doc}")
    return "\n".join([one_line(line) for line in head] + body) + "\n"


def parameter_file_text(cal: Calibration, command: str) -> str:
    """Brake-parameter YAML of the fitted values, headed by how they were produced.

    Parameters
    ----------
    cal : Calibration
    command : str
        The command line that produced it.

    Returns
    -------
    str
        A document that :func:`~ltd_brake_ros.inputs.load_brake_params` accepts.
    """
    ref = {t.reference for t in cal.targets}
    speeds = ", ".join(sorted({f"{t.speed_kmh:g}" for t in cal.targets}))
    head = [f"# Brake-model parameters calibrated against {' and '.join(sorted(ref))} stopping",
            f"# distances at {speeds} km/h, by least squares on the relative distance errors.",
            "# Produced by:",
            f"#   {command}",
            f"# Start values: {display_path(cal.start.source)}; the fields not fitted keep them.",
            "# Residuals (simulated - reference) / reference at the values below:"]
    names = [f"scenario {t.label}" if t.scenario is not None else t.label for t in cal.targets]
    wn = max(len(x) for x in names)
    wc = max(len(t.consist.name) for t in cal.targets)
    for i, (t, name) in enumerate(zip(cal.targets, names)):
        cv = cal.cv_error_percent[i]
        head.append(f"#   {name:<{wn}}  {t.consist.name:<{wc}}  lambda {t.lambda_percent:5.1f} %  "
                    f"ref {t.distance_m:6.1f} m  sim {cal.after_m[i]:6.1f} m  "
                    f"{cal.after_error_percent[i]:+.2f} %"
                    + (f"  (left out {cv:+.2f} %)" if np.isfinite(cv) else "")
                    + (f"  ({t.reference})" if len(ref) > 1 else ""))
    head += _fitted_lines(cal)
    head += _held_and_warnings(cal)
    return "\n".join([one_line(line) for line in head]
                     + parameter_lines(cal.params)) + "\n"


def parameter_lines(params: BrakeParams) -> list[str]:
    """Every field of a brake-parameter set as brake-parameter YAML lines, with their meaning.

    Keys and units are the file's (a field declared with ``key=``/``scale=`` is written as
    the file reads it), so the lines alone reproduce ``params``; brake-heat fields are written
    where they differ from their defaults.

    Parameters
    ----------
    params : BrakeParams

    Returns
    -------
    list of str
    """
    body = [] if params.model == brakes.DEFAULT_MODEL else [f"model: {params.model}"]
    fields = [(name, spec) for part in (params.pneumatic, params.friction)
              for name, spec in specs(type(part)).items()]
    # the brake-heat fields only where they differ from their defaults: a fit never moves
    # them, and a file that set them keeps them
    heat = type(params.thermal)()
    fields += [(name, spec) for name, spec in specs(type(params.thermal)).items()
               if getattr(params.thermal, name) != getattr(heat, name)]
    width = max(len(spec.key or name) for name, spec in fields) + 2
    for name, spec in fields:
        value = _file_value(getattr(params, name), spec)
        body.append(f"{(spec.key or name) + ':':<{width}} {value:<10} "
                    f"# {_field_comment(params, name)}")
    return body

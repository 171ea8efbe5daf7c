"""Calibration of the coupler characteristic against peak in-train forces.

Synthetic references made with a known buff scale are recovered; positions and distances cost
nothing inside their tolerances; each train left out is predicted by the others' fit.
"""
from dataclasses import replace

import numpy as np
import pytest

from ltd_brake_ros.inputs import load_brake_params, load_coupler_lut, load_scenarios
from ltd_brake_ros.studies import calibration as cal_mod

FIG4 = load_coupler_lut("couplers/buffer_hook_fig4.yaml")
TRUE_BUFF_SCALE = 2.0


@pytest.fixture(scope="module")
def synthetic():
    """Runs 1 and 2 (two trains at 100 km/h) whose 'paper' values a buff scale of 2 made."""
    catalogue = load_scenarios()
    runs = [catalogue[1], catalogue[2]]
    brake, step_s = load_brake_params(), 0.02
    truth = replace(FIG4, buff_scale=TRUE_BUFF_SCALE)
    with cal_mod.DistanceEvaluator([(s.consist(), s.speed_kmh) for s in runs], FIG4,
                                   step_s=step_s, workers=2) as ev:
        m = ev.metrics([(brake, truth)])[0]
        fake = [replace(s, paper=dict(s.paper, ltdpolito_m=m[i, cal_mod.DISTANCE],
                                      draft_kN=m[i, cal_mod.DRAFT],
                                      draft_coupler=int(m[i, cal_mod.DRAFT_AT]),
                                      buff_kN=m[i, cal_mod.BUFF],
                                      buff_coupler=int(m[i, cal_mod.BUFF_AT])))
                for i, s in enumerate(runs)]
        start = replace(FIG4, buff_scale=1.5, source="start")
        cal = cal_mod.calibrate_couplers(fake, ["buff_scale"], start, brake, step_s=step_s,
                                         evaluator=ev, cross_validate=True)
    return m, cal


def test_a_known_buff_scale_is_recovered(synthetic):
    _, cal = synthetic
    assert cal.converged, cal.message
    assert [p.name for p in cal.fit] == ["buff_scale"]
    assert cal.params.buff_scale == pytest.approx(TRUE_BUFF_SCALE, rel=0.01)
    assert np.abs(cal.error_percent("after")).max() < 1.0
    # the start (buff scale 1.5) was far off in buff, not in draft
    assert np.abs(cal.error_percent("before")[:, 1]).min() > 5.0


def test_each_train_left_out_is_predicted_by_the_other(synthetic):
    _, cal = synthetic
    cv = cal.error_percent("cv")
    assert np.all(np.isfinite(cv))
    # one true characteristic made both trains: the other train's fit predicts each
    assert np.abs(cv).max() < 2.0


def test_force_residuals_are_fractions_of_the_targets():
    sc = load_scenarios()[6]          # paper: 171 kN @1 draft, 205 kN @21 buff, 489.1 m
    p = sc.paper
    exact = np.array([[[p["ltdpolito_m"], p["draft_kN"], p["draft_coupler"], p["buff_kN"],
                        p["buff_coupler"]]]], float)
    assert np.all(cal_mod.force_residuals(exact, [sc]) == 0.0)
    off = exact.copy()
    off[0, 0, cal_mod.DRAFT] *= 1.05                    # half the draft tolerance
    off[0, 0, cal_mod.BUFF] *= 0.80                     # the whole buff tolerance
    off[0, 0, cal_mod.BUFF_AT] += cal_mod.POSITION_TOL  # inside: free
    off[0, 0, cal_mod.DRAFT_AT] += cal_mod.POSITION_TOL + 2
    off[0, 0, cal_mod.DISTANCE] *= 1.0005               # inside 0.1 %: free
    r = cal_mod.force_residuals(off, [sc])[0]
    margin = cal_mod.MARGIN_WEIGHT * (1.0 - cal_mod.TARGET_MARGIN)  # buff at its tolerance
    np.testing.assert_allclose(r, [0.5, -1.0, 2 * cal_mod.POSITION_WEIGHT, 0.0, 0.0, 0.0,
                                   margin], atol=1e-12)
    off[0, 0, cal_mod.DISTANCE] = exact[0, 0, cal_mod.DISTANCE] * 1.002  # twice the tolerance
    assert cal_mod.force_residuals(off, [sc])[0, 4] == pytest.approx(1.0)


def test_coupler_file_round_trips(synthetic, tmp_path):
    _, cal = synthetic
    out = tmp_path / "fitted.yaml"
    out.write_text(cal_mod.coupler_file_text(cal, "ltd-brake calibrate --target forces"))
    loaded = load_coupler_lut(out)
    assert replace(loaded, source="") == replace(cal.params, source="")
    text = out.read_text()
    assert "ltd-brake calibrate --target forces" in text and "kJ" in text


def test_coupler_names_resolve_against_the_coupler_model():
    assert [p.field for p in cal_mod.parse_fit("buff_scale,draft_hysteresis", "lut_hysteresis",
                                               part="coupler")] == ["buff_scale",
                                                                    "draft_hysteresis"]
    assert cal_mod.parse_fit("stiffness", "linear", part="coupler")[0].part == "coupler"
    with pytest.raises(cal_mod.InputError, match="unknown parameter 'k0'"):
        cal_mod.parse_fit("k0", "lut_hysteresis", part="coupler")


def test_limit_residuals_cost_only_above_the_limit():
    m = np.zeros((1, 3, len(cal_mod.METRICS)))
    m[0, :, cal_mod.DRAFT] = [400.0, 500.0, 750.0]  # kN
    np.testing.assert_allclose(cal_mod.limit_residuals(m, 500e3)[0],
                               [0.0, 0.0, 0.5 * cal_mod.LIMIT_WEIGHT])

"""The scales a coupler table declares fittable: what they do to the curves, their bounds.

A buff or draft scale s multiplies both curves of its side; a hysteresis scale h scales the gap
between them, F_U = s (F_L - h (F_L - F_U)) with the table's curves on the right. The buff
scale is bounded by the energy one side buffer stores over its 105 mm stroke (UIC 526-1 /
EN 15551 categories A 30 kJ to C 70 kJ).
"""
import dataclasses

import numpy as np
import pytest
import yaml

from ltd_brake_ros.inputs import InputError, load_coupler_lut
from ltd_brake_ros.physics import couplers
from ltd_brake_ros.physics.couplers import lut_hysteresis as lut_model
from ltd_brake_ros.physics.parameters import CompileError

#: The Fig. 4 reconstruction, unscaled.
FIG4 = load_coupler_lut("couplers/buffer_hook_fig4.yaml")


def table(params):
    return couplers.compile(params).table


def test_unit_scales_leave_the_table_exactly_as_written():
    t = table(FIG4)
    assert np.array_equal(t[lut_model.DEFLECTION], FIG4.deflection_m)
    assert np.array_equal(t[lut_model.LOADING], FIG4.loading_N)
    assert np.array_equal(t[lut_model.UNLOADING], FIG4.unloading_N)


@pytest.mark.parametrize("side", ["buff", "draft"])
def test_a_side_scale_multiplies_both_curves_of_that_side_only(side):
    scaled = table(dataclasses.replace(FIG4, **{f"{side}_scale": 2.5}))
    base = table(FIG4)
    d = base[lut_model.DEFLECTION]
    mine = d < 0 if side == "buff" else d > 0
    for row in (lut_model.LOADING, lut_model.UNLOADING):
        np.testing.assert_allclose(scaled[row, mine], 2.5 * base[row, mine], rtol=1e-15)
        np.testing.assert_array_equal(scaled[row, ~mine], base[row, ~mine])


@pytest.mark.parametrize("side,ratio", [("buff", 0.5), ("draft", 0.6)])
def test_hysteresis_scale_moves_the_unloading_curve(side, ratio):
    # the reconstruction unloads at 0.5 F_L in buff and 0.6 F_L in draft (data sheet section 4)
    d = np.array(FIG4.deflection_m)
    inner = (d < 0) & (d > -0.21) if side == "buff" else (d > 0) & (d < 0.15)
    fl = np.array(FIG4.loading_N)[inner]
    for h, expected in ((0.0, 1.0), (1.0, ratio), (1.5, 1.0 - 1.5 * (1.0 - ratio))):
        t = table(dataclasses.replace(FIG4, **{f"{side}_hysteresis": h}))
        np.testing.assert_allclose(t[lut_model.UNLOADING, inner], expected * fl, rtol=1e-12)
        np.testing.assert_array_equal(t[lut_model.LOADING], FIG4.loading_N)


def test_buffer_energy_of_the_reconstruction_and_the_bounds_of_the_buff_scale():
    # trapezoids of the loading curve from 0 to -210 mm (two 105 mm buffers in series), four
    # buffers per interface: (0.5 + 3.8 + 7.6 + 12.8 + 15.6 + 16.0 + 29.6) kJ / 4
    assert lut_model.buffer_energy_J(FIG4) == pytest.approx(85.9e3 / 4, rel=1e-3)
    assert lut_model.buffer_energy_J(FIG4) == pytest.approx(
        lut_model.RECONSTRUCTION_BUFFER_ENERGY_J, rel=1e-3)
    fit = lut_model.FITTABLE["buff_scale"]
    for scale, category in ((fit.lower, "A"), (fit.upper, "C")):
        energy = lut_model.buffer_energy_J(dataclasses.replace(FIG4, buff_scale=scale))
        assert energy == pytest.approx(lut_model.BUFFER_ENERGY_J[category], rel=1e-3)


def test_a_scale_that_turns_a_curve_over_is_refused_by_name():
    # h = 3 in draft: F_U = F_L - 3 * 0.4 F_L = -0.2 F_L pushes in draft
    with pytest.raises(CompileError) as err:
        couplers.compile(dataclasses.replace(FIG4, draft_hysteresis=3.0))
    assert err.value.field == "draft_hysteresis" and "wrong sign" in err.value.reason


def test_the_default_coupler_is_the_reconstruction_with_fitted_scales():
    shipped = load_coupler_lut()
    assert (shipped.deflection_m, shipped.loading_N, shipped.unloading_N) == \
        (FIG4.deflection_m, FIG4.loading_N, FIG4.unloading_N)
    for name, fit in lut_model.FITTABLE.items():
        assert fit.lower < getattr(shipped, fit.field) < fit.upper, name
    # a standard buffer: at least category A's 30 kJ over the stroke
    assert lut_model.buffer_energy_J(shipped) > lut_model.BUFFER_ENERGY_J["A"]


def test_a_bad_scale_in_a_file_is_one_line(tmp_path):
    doc = yaml.safe_load(open(FIG4.source))
    doc["buff_scale"] = -1.0
    p = tmp_path / "coupler.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError) as err:
        load_coupler_lut(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}: buff_scale: ") and "\n" not in msg

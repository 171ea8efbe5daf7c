"""The buffer-and-draw-gear coupling: category energy, solid ends, excursions reported."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ltd_brake_ros.inputs import (InputError, consist_from_mapping, load_brake_params,
                                  load_coupler_lut)
from ltd_brake_ros.physics import couplers
from ltd_brake_ros.physics.couplers import buffer_draw_gear as bdg
from ltd_brake_ros.simulator import Commands, Simulator

SHIPPED = "couplers/buffer_draw_gear.yaml"


def test_the_shipped_file_is_a_buffer_of_its_stated_category():
    p = load_coupler_lut(SHIPPED)
    assert isinstance(p, bdg.Params)
    # the table's piecewise-linear energy equals the characteristic's (16 points: within 1 %)
    assert bdg.buffer_energy_J(p) == pytest.approx(p.buffer_energy_J, rel=0.01)
    cat = bdg.category(p)
    lo = bdg.CATEGORY_ENERGY_J[cat]
    hi = {"A": 50e3, "B": 70e3, "C": np.inf}[cat]
    assert lo <= bdg.buffer_energy_J(p) < hi
    assert cat in p.source or cat in open(load_coupler_lut(SHIPPED).source).read()


@pytest.mark.parametrize("energy_kJ", [30.0, 55.0, 90.0])
def test_energy_over_the_stroke_is_the_declared_one(energy_kJ):
    p = bdg.Params(buffer_energy_J=energy_kJ * 1e3)
    d, fl, _ = bdg.curves(p)
    # one buffer's characteristic F0 + (Fe - F0)(x/s)^p integrates to E over the stroke
    s = p.buffer_stroke_m
    x = np.linspace(0.0, s, 20001)
    f = p.buffer_preload_N + (p.curve_end_force_N - p.buffer_preload_N) * (x / s) ** p.buffer_shape
    assert float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x))) == pytest.approx(energy_kJ * 1e3,
                                                                              rel=1e-6)
    assert bdg.buffer_energy_J(p) == pytest.approx(energy_kJ * 1e3, rel=0.01)
    # the interface pushes with both sides' buffers at the end of the stroke
    assert np.interp(-2 * s, d, fl) == pytest.approx(-p.solid_end_force_N, rel=1e-9)


def test_beyond_the_travel_the_force_rises_with_the_structures_stiffness():
    p = bdg.Params()
    arrays = couplers.compile(p)
    lo, hi = arrays.valid_lo_m, arrays.valid_hi_m
    assert lo == pytest.approx(-2 * p.buffer_stroke_m) and hi == pytest.approx(p.draw_travel_m)
    for end, sign in ((lo, -1.0), (hi, 1.0)):
        f0 = couplers.force_of(arrays, end, 0.0)[0]
        for extra in (0.01, 0.05):  # within the table, then extrapolated with the same slope
            f1 = couplers.force_of(arrays, end + sign * extra, 0.0)[0]
            assert (f1 - f0) / (sign * extra) == pytest.approx(p.solid_stiffness_N_m, rel=1e-6)


def test_a_run_beyond_the_buffers_travel_is_reported_and_marked_non_physical():
    c = consist_from_mapping({"vehicles": [{"type": "E402B"},
                                           {"type": "Shimmns", "count": 150, "mass_t": 80.0,
                                            "brake_position": "G"}]}, "long train")
    # the empirical model (outside its range here: the run says so) runs the train into its
    # buffers' solid ends
    sim = Simulator(c, 100.0, load_brake_params("brake_params/paper.yaml"),
                    lut=load_coupler_lut(SHIPPED))
    assert any("empirical brake model outside" in w for w in sim.model_warnings)
    sim.advance(1.0, Commands(emergency=True))
    while sim.stop_time_s is None:
        sim.advance(1.0)
    ex = sim.coupler_excursions()
    table = sim.verdicts()
    assert ex.count > 0  # braked from the head, 150 loaded wagons in G run in beyond 210 mm
    assert table.non_physical and table["coupler_travel"].status == "FAIL"
    assert "solid end" in table["coupler_travel"].origin
    beyond = {e.number for e in table["coupler_travel"].exceedances}
    assert beyond == set(np.flatnonzero(sim.lut_excursion_m > 0.0) + 1)


@pytest.mark.parametrize("field,value,reason", [
    ("buffer_energy_kJ", 20.0, "30"),
    ("buffer_preload_kN", 500.0, "200"),
    ("draw_dissipation", 1.2, "0.9"),
])
def test_a_coupler_file_out_of_its_physics_is_refused(tmp_path, field, value, reason):
    text = open(load_coupler_lut(SHIPPED).source).read()
    lines = [ln for ln in text.splitlines() if not ln.startswith(field + ":")]
    p = tmp_path / "c.yaml"
    p.write_text("\n".join(lines + [f"{field}: {value}"]) + "\n")
    with pytest.raises(InputError, match=field):
        load_coupler_lut(p)


def test_fittable_bounds_are_physical():
    for name, fit in bdg.FITTABLE.items():
        p = dataclasses.replace(bdg.Params(), **{fit.field: fit.lower})
        couplers.compile(p)  # every bound compiles
        p = dataclasses.replace(bdg.Params(), **{fit.field: fit.upper})
        couplers.compile(p)
    assert bdg.FITTABLE["buffer_energy"].lower == bdg.CATEGORY_ENERGY_J["A"]

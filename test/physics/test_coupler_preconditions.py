"""Every physical precondition of a coupler's parameters is checked when it is compiled.

A table whose unloading curve lies beyond its loading curve would give back more energy than the
coupling absorbed; absurd forces or slopes reached the compiled kernel and ended in a
ZeroDivisionError traceback. The model states its preconditions in ``compile``; the loader runs
them at load time (one line naming file and field), the simulator for parameters built in code,
and a step that still meets an arithmetic failure or a non-finite force raises SimulationError.
"""
import dataclasses
import math

import numpy as np
import pytest
import yaml

from ltd_brake_ros.inputs import InputError, consist_from_mapping, load_coupler_lut
from ltd_brake_ros.physics import couplers
from ltd_brake_ros.physics.couplers import linear, lut_hysteresis
from ltd_brake_ros.physics.parameters import CompileError
from ltd_brake_ros.simulator import Commands, SimulationError, Simulator

SHIPPED = load_coupler_lut()
TABLE = yaml.safe_load(open(SHIPPED.source))
#: Index of the table point at +50 mm (draft: 80 kN loading, 48 unloading) and at -210 mm
#: (buff: -2000 kN loading, -1000 unloading).
DRAFT, BUFF = TABLE["deflection_mm"].index(50), TABLE["deflection_mm"].index(-210)


def load(tmp_path, **change):
    doc = dict(TABLE, **change)
    p = tmp_path / "coupler.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError) as err:
        load_coupler_lut(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    return msg


def column(name, index, value):
    values = list(TABLE[name])
    values[index] = value
    return {name: values}


def test_shipped_table_meets_every_precondition():
    couplers.compile(SHIPPED)


@pytest.mark.parametrize("index,beyond", [(DRAFT, 85.0), (BUFF, -2200.0)])
def test_unloading_beyond_loading_is_refused(tmp_path, index, beyond):
    # draft: unloading above loading; buff: unloading more compressive than loading; both
    # curves still monotone, so only the energy balance catches it
    msg = load(tmp_path, **column("unloading_kN", index, beyond))
    assert f"unloading_kN[{index}]: " in msg and "exceeds the loading curve" in msg
    assert "more energy than it absorbed" in msg


def test_swapped_columns_are_refused(tmp_path):
    msg = load(tmp_path, loading_kN=TABLE["unloading_kN"], unloading_kN=TABLE["loading_kN"])
    assert "unloading_kN[" in msg and "columns swapped?" in msg


def test_force_of_the_wrong_sign_is_refused(tmp_path):
    # a draft point (+50 mm) pushing: monotone still, so only the sign convention catches it
    values = [f - 100.0 for f in TABLE["loading_kN"]]
    unloading = [min(u - 100.0, f) if d > 0 else max(u - 100.0, f)
                 for d, u, f in zip(TABLE["deflection_mm"], TABLE["unloading_kN"], values)]
    msg = load(tmp_path, loading_kN=values, unloading_kN=unloading)
    assert "loading_kN[" in msg and "wrong sign" in msg


def test_table_must_span_zero(tmp_path):
    msg = load(tmp_path, deflection_mm=[d + 400.0 for d in TABLE["deflection_mm"]])
    assert "deflection_mm: must run from buff (negative) to draft (positive)" in msg


@pytest.mark.parametrize("change,field,words", [
    # the table that reached the kernel and raised ZeroDivisionError
    (dict(deflection_mm=[-100, 0, 100], loading_kN=[-1e200, 0, 1e200],
          unloading_kN=[-1e199, 0, 1e199]), "loading_kN[0]", "outside -20000 to 20000 kN"),
    (column("loading_kN", -1, 25000.0), f"loading_kN[{len(TABLE['loading_kN']) - 1}]",
     "outside -20000 to 20000 kN"),
    (dict(deflection_mm=[-3000, 0, 100], loading_kN=[-100, 0, 100], unloading_kN=[-50, 0, 50]),
     "deflection_mm[0]", "outside -1000 to 1000 mm"),
    # 10 000 kN over 0.5 mm: 20 000 kN/mm
    (dict(deflection_mm=[-100, 0, 0.5], loading_kN=[-100, 0, 10000], unloading_kN=[-50, 0, 10000]),
     "loading_kN[2]", "stiffer than 10000 kN/mm"),
    ({"v_th_mm_s": 1e-6}, "v_th_mm_s", "must be >= 0.001"),
    ({"draft_strength_kN": 0.0}, "draft_strength_kN", "must be > 0"),
])
def test_implausible_magnitudes_are_refused_at_load(tmp_path, change, field, words):
    msg = load(tmp_path, **change)
    assert f": {field}: " in msg and words in msg


def test_bounds_themselves_are_accepted(tmp_path):
    doc = dict(deflection_mm=[-1000, 0, 1000], loading_kN=[-20000, 0, 10000],
               unloading_kN=[-20000, 0, 10000], v_th_mm_s=1e-3)
    p = tmp_path / "edge.yaml"
    p.write_text(yaml.safe_dump(doc))
    lut = load_coupler_lut(p)
    assert lut.loading_N[0] == -2e7 and lut.v_th_m_s == pytest.approx(1e-6)


@pytest.mark.parametrize("params,field", [
    (dataclasses.replace(SHIPPED, unloading_N=tuple(
        1.2 * f for f in SHIPPED.loading_N)), "unloading_kN["),
    (dataclasses.replace(SHIPPED, v_th_m_s=0.0), "v_th_mm_s"),
    (dataclasses.replace(SHIPPED, loading_N=(math.nan,) + SHIPPED.loading_N[1:]), "loading_kN[0]"),
    (linear.Params(stiffness_N_m=-1.0), "stiffness_kN_per_mm"),
    (linear.Params(stiffness_N_m=2e7, damping_N_s_m=math.inf), "damping_kN_s_per_m"),
    (linear.Params(stiffness_N_m=2e10), "stiffness_kN_per_mm"),
])
def test_compile_states_the_preconditions_of_every_model(params, field):
    with pytest.raises(CompileError) as err:
        couplers.compile(params)
    assert err.value.field.startswith(field)


def train(wagons=5):
    return consist_from_mapping({"name": "t", "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": wagons, "mass_t": 80.0}]}, "<test>")


def test_simulator_refuses_parameters_built_in_code():
    bad = dataclasses.replace(SHIPPED, source="my_table", v_th_m_s=-1.0)
    with pytest.raises(InputError, match=r"^my_table: v_th_mm_s: must be >= 0.001"):
        Simulator(train(), 100.0, lut=bad)


def inject(sim, table, v_th_m_s=1e-4):
    """Put a table into a built simulator, past every check (what the kernel alone sees)."""
    arrays = lut_hysteresis.compile(SHIPPED)._replace(table=lut_hysteresis.table_of(*table),
                                                      coef=np.array([v_th_m_s]))
    sim.model = sim.model._replace(couplers=arrays)


def test_arithmetic_failure_in_a_step_is_a_simulation_error():
    sim = Simulator(train(), 100.0)
    inject(sim, [[-0.1, 0.0, 0.1], [-1e203, 0.0, 1e203], [-1e202, 0.0, 1e202]])
    with pytest.raises(SimulationError) as err:
        sim.advance(5.0, Commands(emergency=True))
    msg = str(err.value)
    assert "ZeroDivisionError" in msg and "\n" not in msg and "t = 0" in msg
    with pytest.raises(SimulationError, match="call reset"):
        sim.advance(0.1)


def test_non_finite_coupler_force_is_a_simulation_error():
    sim = Simulator(train(), 100.0)
    inject(sim, [[-0.1, 0.0, 0.1], [-1e6, math.nan, 1e6], [-1e6, 0.0, 1e6]])
    with pytest.raises(SimulationError, match=r"not finite .* t = 0\.0000 s"):
        sim.advance(1.0, Commands(emergency=True))
    sim.reset()
    assert sim.time_s == 0.0

"""The reducer FMU with model = "dynamic": the dynamic model stepped inside each communication step."""

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from rvfmu.core.units import ARCSEC
from rvfmu.fmu.build import build_fmu
from test_fmu import Instance, free_instances  # noqa: F401 - frees every instance after a test

SLOW = 5 * 2 * np.pi / 60          # rad/s: 5 rpm input, where dynamics adds nothing
FAST = 1600 * 2 * np.pi / 60


@pytest.fixture(scope="module")
def fmu(tmp_path_factory, rv40, seed002):
    path = build_fmu(rv40, seed002, tmp_path_factory.mktemp("fmu_dyn") / "RVReducer.fmu",
                     points=4 * 40 * 39)
    return path, read_model_description(str(path))


def drive(inst, speed, load, steps, step, start=0):
    te = []
    for k in range(start, start + steps):
        inst.set(theta_in=speed * (k + 1) * step, tau_load=load)
        inst.step(k * step, step)
        te.append(inst.get("te")[0])
    return np.array(te)


def test_the_fmu_declares_the_dynamic_parameters_and_still_validates(fmu):
    path, md = fmu
    assert validate_fmu(str(path)) == []
    names = {v.name: v for v in md.modelVariables}
    assert names["dynamic_step"].unit == "s" and "dynamic" in names["model"].description


def test_at_slow_speed_the_dynamic_fmu_follows_the_quasi_static_fmu(fmu):
    path, md = fmu
    step, steps = 0.02, 500                          # 10 s at 5 rpm: 5.2 rad of input
    # started in equilibrium under the load: a load step at a 20 ms internal step would ring
    # in the kHz modes, which the average-acceleration rule does not damp
    dynamic = Instance(path, md, name="dyn", strings={"model": "dynamic"},
                       reals={"dynamic_step": step, "tau_load": -300.0})
    static = Instance(path, md, name="qs", reals={"tau_load": -300.0})
    te_dyn = drive(dynamic, SLOW, -300.0, steps, step)
    te_qs = drive(static, SLOW, -300.0, steps, step)
    pp = np.ptp(te_qs[50:])
    assert pp > 1.0 * ARCSEC
    assert np.ptp(te_dyn[50:]) == pytest.approx(pp, rel=0.05)
    assert np.max(np.abs(te_dyn[50:] - te_qs[50:])) < 0.05 * pp


def test_results_do_not_depend_on_the_communication_step(fmu):
    path, md = fmu
    options = dict(strings={"model": "dynamic"}, reals={"dynamic_step": 1e-4, "tau_load": -206.0})
    coarse = drive(Instance(path, md, name="c", **options), FAST, -206.0, 50, 1e-3)
    fine = drive(Instance(path, md, name="f", **options), FAST, -206.0, 100, 5e-4)[1::2]
    assert np.max(np.abs(coarse - fine)) < 0.01 * np.ptp(coarse)


def test_state_roll_back_re_steps_identically_and_bad_inputs_are_discarded(fmu, capfd):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"},
                    reals={"dynamic_step": 2e-4, "tau_load": -206.0})
    drive(inst, FAST, -206.0, 5, 1e-3)
    state = inst.fmu.getFMUstate()
    first = drive(inst, FAST, -206.0, 3, 1e-3, start=5)
    drive(inst, FAST, 100.0, 4, 1e-3, start=8)
    inst.fmu.setFMUstate(state)
    assert np.array_equal(drive(inst, FAST, -206.0, 3, 1e-3, start=5), first)
    inst.set(theta_in=float("nan"), tau_load=-206.0)
    with pytest.raises(Exception, match="status 2"):
        inst.step(8e-3, 1e-3)
    assert "input theta_in = nan: must be finite" in capfd.readouterr().out


def test_a_bad_dynamic_step_is_reported_at_initialisation(fmu, capfd):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"}, reals={"dynamic_step": 0.0})
    assert "dynamic_step = 0.0: must be a finite number > 0" in capfd.readouterr().out
    with pytest.raises(Exception, match="status 2"):
        inst.step(0.0, 1e-3)


def test_reset_returns_the_dynamic_model_to_its_start(fmu):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"},
                    reals={"dynamic_step": 2e-4, "tau_load": -206.0})
    start = inst.get("theta_out", "te", "tau_in")
    drive(inst, FAST, -206.0, 5, 1e-3)
    assert inst.get("te") != start[1:2]
    inst.fmu.reset()                    # every variable back to its start value (FMI 2.0):
    inst.fmu.setString([inst.vr["model"]], ["dynamic"])          # the host sets them again
    inst.set(theta_in=0.0, tau_load=-206.0, dynamic_step=2e-4)
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    assert inst.get("theta_out", "te", "tau_in") == start

"""The reducer FMU with model = "dynamic": the dynamic model stepped inside each communication step."""

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu
from test_fmu import (
    Instance,
    free_instances,  # noqa: F401 - frees every instance after a test
    native_env,
    signal,
)

from rvfmu.core.base.units import ARCSEC
from rvfmu.fmu.build import build_fmu

SLOW = 5 * 2 * np.pi / 60  # rad/s: 5 rpm input, where dynamics adds nothing
FAST = 1600 * 2 * np.pi / 60


@pytest.fixture(scope="module")
def fmu(tmp_path_factory, rv40, seed002):
    path = build_fmu(rv40, seed002, tmp_path_factory.mktemp("fmu_dyn") / "RVReducer.fmu", points=4 * 40 * 39)
    return path, read_model_description(str(path))


def drive(inst, speed, load, steps, step, start=0):
    te = []
    for k in range(start, start + steps):
        inst.set(theta_in=speed * (k + 1) * step, tau_load=load)
        inst.step(k * step, step)
        te.append(inst.get("te")[0])
    return np.array(te)


def drive_as_a_master(inst, theta_in, tau_load, step):
    """te_arcsec after each step, inputs [k] set at k * step and held to (k + 1) * step."""
    te = []
    for k, (theta, load) in enumerate(zip(theta_in, tau_load)):
        inst.set(theta_in=theta, tau_load=load)
        inst.step(k * step, step)
        te.append(inst.get("te_arcsec")[0])
    return np.array(te)


def test_the_fmu_declares_the_dynamic_parameters_and_still_validates(fmu):
    path, md = fmu
    assert validate_fmu(str(path)) == []
    names = {v.name: v for v in md.modelVariables}
    assert names["dynamic_step"].unit == "s" and "dynamic" in names["model"].description


def test_at_slow_speed_the_dynamic_fmu_follows_the_quasi_static_fmu(fmu):
    path, md = fmu
    step, steps = 0.02, 500  # 10 s at 5 rpm: 5.2 rad of input
    # started in equilibrium under the load: a load step at a 20 ms internal step would ring
    # in the kHz modes, which the average-acceleration rule does not damp
    dynamic = Instance(
        path, md, name="dyn", strings={"model": "dynamic"}, reals={"dynamic_step": step, "tau_load": -300.0}
    )
    static = Instance(path, md, name="qs", reals={"tau_load": -300.0})
    te_dyn = drive(dynamic, SLOW, -300.0, steps, step)
    te_qs = drive(static, SLOW, -300.0, steps, step)
    pp = np.ptp(te_qs[50:])
    assert pp > 1.0 * ARCSEC
    assert np.ptp(te_dyn[50:]) == pytest.approx(pp, rel=0.05)
    wound_back(te_dyn[50:], te_qs[50:])
    # both carry the losses: the same efficiency within a point (docs/model.md section 9)
    assert 0.8 < dynamic.get("efficiency")[0] < 0.97
    assert dynamic.get("efficiency")[0] == pytest.approx(static.get("efficiency")[0], abs=0.01)
    assert dynamic.get("P_loss")[0] > 0.0


def wound_back(te_dynamic, te_static):
    """The dynamic model's TE is the quasi-static map's (frictionless, docs/model.md section 5)
    wound back by the windup of the contacts' friction torque: a shift of the loaded side's
    sign, below 2 % of the windup, and the same curve within 5 % of its range."""
    shift = te_dynamic - te_static
    assert -0.02 * abs(np.mean(te_static)) < np.mean(shift) < 0.0
    assert np.max(np.abs(shift - np.mean(shift))) < 0.05 * np.ptp(te_static)


def test_results_do_not_depend_on_the_communication_step(fmu):
    path, md = fmu
    options = dict(strings={"model": "dynamic"}, reals={"dynamic_step": 1e-4, "tau_load": -206.0})
    coarse = drive(Instance(path, md, name="c", **options), FAST, -206.0, 50, 1e-3)
    fine = drive(Instance(path, md, name="f", **options), FAST, -206.0, 100, 5e-4)[1::2]
    assert np.max(np.abs(coarse - fine)) < 0.01 * np.ptp(coarse)


def test_state_roll_back_re_steps_identically_and_bad_inputs_are_discarded(fmu, capfd):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"}, reals={"dynamic_step": 2e-4, "tau_load": -206.0})
    drive(inst, FAST, -206.0, 5, 1e-3)
    state = inst.fmu.getFMUstate()
    first = drive(inst, FAST, -206.0, 3, 1e-3, start=5)
    drive(inst, FAST, 100.0, 4, 1e-3, start=8)
    inst.fmu.setFMUstate(state)
    assert np.array_equal(drive(inst, FAST, -206.0, 3, 1e-3, start=5), first)
    inst.set(theta_in=float("nan"), tau_load=-206.0)
    with pytest.raises(Exception, match="status 3"):  # fmi2Error: the run has ended
        inst.step(8e-3, 1e-3)
    assert "input theta_in = nan: must be finite" in capfd.readouterr().out


def test_a_bad_dynamic_step_is_reported_at_initialisation(fmu, capfd):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"}, reals={"dynamic_step": 0.0})
    assert "dynamic_step = 0.0: must be a finite number > 0" in capfd.readouterr().out
    with pytest.raises(Exception, match="status 3"):
        inst.step(0.0, 1e-3)


def test_reset_returns_the_dynamic_model_to_its_start(fmu):
    path, md = fmu
    inst = Instance(path, md, strings={"model": "dynamic"}, reals={"dynamic_step": 2e-4, "tau_load": -206.0})
    start = inst.get("theta_out", "te", "tau_in")
    drive(inst, FAST, -206.0, 5, 1e-3)
    assert inst.get("te") != start[1:2]
    inst.fmu.reset()  # every variable back to its start value (FMI 2.0):
    inst.fmu.setString([inst.vr["model"]], ["dynamic"])  # the host sets them again
    inst.set(theta_in=0.0, tau_load=-206.0, dynamic_step=2e-4)
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    assert inst.get("theta_out", "te", "tau_in") == start


def test_native_engine_libcosim_runs_the_dynamic_fmu_step_for_step_as_fmpy_does(fmu, tmp_path):
    path, md = fmu
    step, load = 1e-3, 206.0  # the script's communication step [s]; N*m
    out = tmp_path / "cosim.csv"
    site = ":".join(p for p in sys.path if p.endswith("site-packages"))
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "studies" / "native_host" / "run_libcosim.py"),
            str(path),
            str(out),
            "--model",
            "dynamic",
            "--speed",
            repr(FAST),
            "--load",
            repr(load),
            "--duration",
            "0.03",
        ],
        env=native_env(site),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    cosim = np.genfromtxt(out, delimiter=",", names=True)
    # libcosim sets theta_in(t) then steps to t + h: the same input samples, by hand through fmpy
    k = np.arange(cosim.size)
    np.testing.assert_allclose(cosim["time"], (k + 1) * step, rtol=1e-12)
    inst = Instance(path, md, strings={"model": "dynamic"}, reals={"tau_load": -load})
    fmpy_te = drive_as_a_master(inst, [FAST * (i * step) for i in k], [-load] * cosim.size, step)
    assert np.ptp(fmpy_te) > 1.0  # a TE curve, not a constant, is compared
    np.testing.assert_allclose(cosim["te_arcsec"], fmpy_te, rtol=0, atol=1e-9)


def test_fmpy_simulate_fmu_runs_the_dynamic_model_given_as_a_start_value(fmu):
    path, _ = fmu
    step, stop, load = 0.02, 10.0, -300.0  # 10 s at 5 rpm, as in the slow-speed test above
    times = np.arange(0.0, stop + step / 2, step)
    common = dict(
        start_time=0.0,
        stop_time=stop,
        output_interval=step,
        step_size=step,
        input=signal(times, SLOW * times, load + 0 * times),
        output=["te_arcsec"],
    )
    # the load is applied in initialisation too: the dynamic model starts in equilibrium under it
    te_dyn = simulate_fmu(str(path), start_values={"model": "dynamic", "dynamic_step": step}, **common)[
        "te_arcsec"
    ]
    te_qs = simulate_fmu(str(path), **common)["te_arcsec"]
    assert te_dyn.shape == te_qs.shape == times.shape and np.isfinite(te_dyn).all()
    pp = np.ptp(te_qs[50:])
    assert pp > 1.0
    assert np.max(np.abs(te_dyn - te_qs)) > 1e-6 * pp  # another model ran, not the TE map
    assert np.ptp(te_dyn[50:]) == pytest.approx(pp, rel=0.05)
    wound_back(te_dyn[50:], te_qs[50:])


def test_the_fmu_bundles_the_compiled_kernels_and_a_host_loads_them_without_compiling(
    fmu, tmp_path, rv40, seed002
):
    """A host with numba runs the FMU's dynamic model, from its initial equilibrium (the
    quasi-static Newton kernels) through its communication steps, on the kernels the FMU
    carries: nothing is compiled."""
    import zipfile
    from pathlib import Path

    import rvfmu
    from rvfmu.core.steppers.dynamic_reducer import compile_kernels

    package = Path(rvfmu.__file__).resolve().parent
    # each room's kernels in that room's cache folder, as the FMU's copy of the core has them
    expected = {path.resolve().relative_to(package).as_posix() for path in compile_kernels(rv40, seed002)}
    assert expected, "numba is a dependency: the kernels must compile"
    assert {name.split("/")[1] for name in expected if name.count("/") == 3} >= {
        "statics",
        "laws",
        "dynamics",
        "steppers",
    }
    with zipfile.ZipFile(fmu[0]) as archive:
        archive.extractall(tmp_path)
        bundled = {
            name.removeprefix("resources/rvfmu/")
            for name in archive.namelist()
            if name.startswith("resources/rvfmu/core/") and "/__pycache__/" in name
        }
    assert bundled == expected
    needed = {"element_forces", "newmark_steps", "build_geometry", "communication_step", "newton_pairs"}
    assert {name.rsplit("/", 1)[1].split(".")[1].split("-")[0] for name in expected} >= needed
    # the FMU's own copy of the core (not the installed rvfmu), with the design and errors it
    # carries, finds the kernels in its cache
    script = (
        "import sys; from pathlib import Path; sys.path.insert(0, sys.argv[1])\n"
        "import numpy as np, rvfmu\n"
        "assert rvfmu.__file__.startswith(sys.argv[1]), rvfmu.__file__\n"
        "from rvfmu.core.reducer.design import load_design\n"
        "from rvfmu.core.dynamics.dynamic import DynamicModel, ramp_motion\n"
        "from rvfmu.core.steppers.dynamic_reducer import DynamicReducer\n"
        "from rvfmu.core.reducer.errors import load_errors\n"
        "from rvfmu.core.dynamics.newmark import NewmarkStepper\n"
        "d = load_design(Path(sys.argv[1]) / 'design.toml')\n"
        "e = load_errors(Path(sys.argv[1]) / 'errors.toml', d)\n"
        "m = DynamicModel(d, e)\n"
        "m.prepare(ramp_motion(np.arange(3) * 1e-4, 10.0, 0.0))\n"
        "NewmarkStepper.starting_at(m, np.zeros(m.n)).advance(2)\n"
        "r = DynamicReducer(d, e); r.initialize(0.0, 0.0, -206.0)\n"
        "r.step(0.0, 1e-3, 0.1, -206.0)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "resources")],
        env={**os.environ, "NUMBA_DEBUG_CACHE": "1"},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    loaded = [line for line in proc.stdout.splitlines() if line.startswith("[cache] data loaded")]
    assert {line.split("__pycache__/")[1].split(".")[1].split("-")[0] for line in loaded} >= needed
    assert all(str(tmp_path) in line for line in loaded)
    assert "data saved" not in proc.stdout


def test_the_dynamic_input_torque_is_the_mean_over_the_communication_step(rv40, seed002):
    from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

    # 40 internal steps of 25 us in a 1 ms step are the 10 of each of its four 0.25 ms steps:
    # the same motion, so the 1 ms tau_in is the mean of the four
    speed, load = FAST, -206.0
    coarse, fine = DynamicReducer(rv40, seed002, 2.5e-5), DynamicReducer(rv40, seed002, 2.5e-5)
    coarse.initialize(0.0, 0.0, load)
    fine.initialize(0.0, 0.0, load)
    for k in range(5):
        big = coarse.step(k * 1e-3, 1e-3, speed * (k + 1) * 1e-3, load)
        small = [
            fine.step(k * 1e-3 + m * 2.5e-4, 2.5e-4, speed * (k * 1e-3 + (m + 1) * 2.5e-4), load)
            for m in range(4)
        ]
        assert big.tau_in == pytest.approx(np.mean([o.tau_in for o in small]), rel=1e-9, abs=1e-12)
        assert big.te == pytest.approx(small[-1].te, rel=1e-9, abs=1e-15)


def test_the_compiled_communication_step_is_the_python_one(rv40, seed002, monkeypatch):
    """With numba a communication step is one compiled call (`communication_step`); the same
    steps made of the Python calls (the route without it) reach the same state to the bit and
    the same outputs to round-off (only the sums of the means run in another order), through
    changes of speed and load, and with the crank bearings' roller law and the Hertz pins."""
    from rvfmu.core.reducer.design import preset
    from rvfmu.core.steppers import dynamic_reducer

    if not dynamic_reducer.COMPILED:
        pytest.fail("numba is a dependency: the communication step must compile")
    for design in (rv40, preset("RV-40E-121")):
        runs = []
        for compiled in (True, False):
            monkeypatch.setattr(dynamic_reducer, "COMPILED", compiled)
            reducer = dynamic_reducer.DynamicReducer(design, seed002)
            reducer.initialize(0.0, 0.0, -206.0)
            outputs, theta = [], 0.0
            for k in range(30):
                theta += FAST * (1.0 + 0.2 * np.sin(k / 5.0)) * 1e-3
                outputs.append(reducer.step(k * 1e-3, 1e-3, theta, -206.0 * (1.0 + 0.5 * np.cos(k / 7.0))))
            runs.append((outputs, reducer.state))
        (fast, end), (slow, reference) = runs
        for name in ("q", "v", "a"):
            assert np.array_equal(getattr(end, name), getattr(reference, name)), name
        for a, b in zip(fast, slow):
            for name in ("theta_out", "omega_out", "te", "tau_in", "p_loss", "efficiency"):
                assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-13, abs=1e-300), name
        assert np.ptp([o.tau_in for o in fast]) > 1.0  # the load and the speed did change

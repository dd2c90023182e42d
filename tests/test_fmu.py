"""The reducer FMU in real FMI importers: fmpy, a native engine (libcosim), a bare venv."""

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from rvfmu.core.base.units import ARCSEC
from rvfmu.core.statics.quasistatic import equilibria
from rvfmu.fmu.build import build_fmu

MAP_POINTS = 6240  # 4 per pin-passing period: te_pp within 0.5 % of the core
SPEED = 1600 * 2 * np.pi / 60  # rad/s at the input, as in seeds 000/001
STEP = 1e-3
LONG = 1e4  # [s] a step over which any jump of an angle is a slow turn


@pytest.fixture(scope="module")
def fmu_path(tmp_path_factory, rv40, seed002):
    return build_fmu(rv40, seed002, tmp_path_factory.mktemp("fmu") / "RVReducer.fmu", points=MAP_POINTS)


@pytest.fixture(scope="module")
def description(fmu_path):
    return read_model_description(str(fmu_path))


def signal(times, theta_in, tau_load):
    rows = np.zeros(len(times), dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
    rows["time"], rows["theta_in"], rows["tau_load"] = times, theta_in, tau_load
    return rows


def run(fmu_path, stop, step, theta_of_t, tau_of_t, outputs=("theta_out", "te_arcsec", "tau_in")):
    times = np.arange(0.0, stop + step / 2, step)
    return simulate_fmu(
        str(fmu_path),
        start_time=0.0,
        stop_time=stop,
        output_interval=step,
        step_size=step,
        input=signal(times, theta_of_t(times), tau_of_t(times)),
        output=list(outputs),
    )


class Instance:
    """One FMU instance driven by hand through fmpy's FMI 2.0 API, with its log.

    Every instance is freed after the test that made it (`free_instances`): an FMU
    left to the interpreter's exit would be torn down after Python itself.
    """

    opened = []

    def __init__(self, fmu_path, description, name="reducer", strings=None, reals=None, ints=None):
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.log = []
        unzipped = extract(str(fmu_path))
        self.fmu = FMU2Slave(
            guid=description.guid,
            unzipDirectory=unzipped,
            modelIdentifier=description.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(loggingOn=True, callbacks=None)
        Instance.opened.append(self.fmu)
        self.fmu.fmi2SetDebugLogging(self.fmu.component, True, 0, None)
        for key, value in (strings or {}).items():
            self.fmu.setString([self.vr[key]], [value])
        for key, value in (reals or {}).items():
            self.fmu.setReal([self.vr[key]], [value])
        for key, value in (ints or {}).items():
            self.fmu.setInteger([self.vr[key]], [value])
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set(self, **values):
        self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, *names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, time, size):
        return self.fmu.doStep(currentCommunicationPoint=time, communicationStepSize=size)


@pytest.fixture(autouse=True)
def free_instances():
    yield
    while Instance.opened:
        fmu = Instance.opened.pop()
        try:
            fmu.terminate()
        except Exception:  # noqa: BLE001 - an instance a test left in an error state
            pass
        fmu.freeInstance()


def test_validates_with_units_and_default_experiment(fmu_path, description):
    assert validate_fmu(str(fmu_path)) == []
    units = {v.name: v.unit for v in description.modelVariables}
    assert units["theta_in"] == "rad" and units["omega_out"] == "rad/s"
    assert units["tau_load"] == units["tau_in"] == "N.m"
    assert {u.name for u in description.unitDefinitions} >= {"rad", "rad/s", "N.m"}
    assert float(description.defaultExperiment.stepSize) == STEP
    assert description.coSimulation.canGetAndSetFMUstate
    with zipfile.ZipFile(fmu_path) as archive:
        names = set(archive.namelist())
    assert {
        "resources/rvfmu/core/statics/solver.py",
        "resources/te_map.npz",
        "resources/design.toml",
        "resources/errors.toml",
    } <= names


def test_constant_speed_and_load_reproduce_the_core_te_curve(fmu_path, rv40, seed002):
    """One output revolution at 1600 rpm under rated load: te_pp within 1 % of the core."""
    load = -rv40.rated_torque
    revolution = np.ceil(2 * np.pi * rv40.ratio / SPEED / STEP) * STEP
    result = run(fmu_path, revolution, STEP, lambda t: SPEED * t, lambda t: load + 0 * t)
    # Co-simulation holds an input over a step: the outputs at t + h belong to theta_in(t).
    theta_in = SPEED * np.maximum(result["time"] - STEP, 0.0)
    core = equilibria(rv40, seed002, theta_in, [load]).te[0, 0] / ARCSEC
    fmu = result["te_arcsec"]
    assert abs(np.ptp(fmu) / np.ptp(core) - 1) < 0.01
    assert np.max(np.abs(fmu - core)) < 0.05 * np.ptp(core)
    np.testing.assert_allclose(result["theta_out"], theta_in / rv40.ratio + fmu * ARCSEC, atol=1e-12)


def test_a_load_change_moves_the_output_by_the_core_windup(fmu_path, rv40, seed002):
    """Input held still, the load steps from a quarter to all of the rated torque."""
    theta = 123.4
    loads = (-0.25 * rv40.rated_torque, -rv40.rated_torque)
    result = run(
        fmu_path, 0.2, STEP, lambda t: theta + 0 * t, lambda t: np.where(t < 0.1, loads[0], loads[1])
    )
    before = result["theta_out"][(result["time"] > 0.05) & (result["time"] < 0.095)]
    after = result["theta_out"][result["time"] > 0.15]
    assert np.ptp(before) < 1e-15 and np.ptp(after) < 1e-15
    core = equilibria(rv40, seed002, [theta], list(loads)).te[0, :, 0]
    np.testing.assert_allclose(after[0] - before[0], core[1] - core[0], rtol=0.01)
    # and the input torque follows the load through the ratio
    np.testing.assert_allclose(result["tau_in"][-1] * rv40.ratio, loads[1], rtol=1e-3)


def test_results_do_not_depend_on_the_communication_step(fmu_path, rv40):
    def load(t):
        return -rv40.rated_torque * (0.5 + 0.5 * np.sin(20 * t))

    coarse = run(fmu_path, 0.1, 1e-3, lambda t: SPEED * t, load)
    fine = run(fmu_path, 0.1, 1e-4, lambda t: SPEED * t, load)
    at = np.searchsorted(fine["time"], coarse["time"] - 1e-9)
    fine_te = fine["te_arcsec"][at]
    np.testing.assert_allclose(coarse["te_arcsec"], fine_te, rtol=0.01, atol=0.01 * np.ptp(fine_te))


def test_bad_inputs_are_refused_with_a_logged_message_not_a_crash(fmu_path, description, capfd):
    """Each ends the simulation (fmi2Error, every later step refused) until a reset."""
    inst = Instance(fmu_path, description)
    for values, size, expected in (
        ({"theta_in": float("nan"), "tau_load": -100.0}, STEP, "theta_in"),
        ({"theta_in": 1.0, "tau_load": float("inf")}, STEP, "tau_load"),
        ({"theta_in": 1.0, "tau_load": -100.0}, -STEP, "step size"),
        ({"theta_in": 1.0, "tau_load": -100.0}, 0.0, "step size = 0.0"),
        ({"theta_in": 1.0, "tau_load": -100.0}, float("nan"), "step size = nan"),
    ):
        restart(inst)
        inst.set(theta_in=0.5, tau_load=-100.0)
        inst.step(0.0, STEP)
        good = inst.get("te_arcsec")
        inst.set(**values)
        with pytest.raises(Exception, match="status 3"):
            inst.step(STEP, size)
        assert expected in capfd.readouterr().out
        inst.set(theta_in=0.6, tau_load=-100.0)
        with pytest.raises(Exception, match="status 3"):  # ended: good inputs too
            inst.step(STEP, STEP)
        assert expected in capfd.readouterr().out
        assert inst.get("te_arcsec") == good  # the outputs of the last step
    restart(inst)
    inst.set(theta_in=0.5, tau_load=-100.0)
    inst.step(0.0, STEP)
    assert inst.get("te_arcsec") == good  # usable again after a reset


def restart(inst):
    """fmi2Reset and a new start of `inst`."""
    inst.fmu.reset()
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()


@pytest.mark.parametrize(
    "design_file, expected",
    [
        ("/no/such/design.toml", "neither a preset"),
        ("RV-99", "RV-99"),
        ("bad_z_c", "z_c"),
    ],
)
def test_a_bad_design_parameter_is_reported_at_initialisation(
    fmu_path, description, tmp_path, capfd, design_file, expected
):
    if design_file == "bad_z_c":
        path = tmp_path / "bad.toml"
        path.write_text('preset = "RV-40E-121"\nz_c = 41\n')
        design_file = str(path)
    inst = Instance(fmu_path, description, strings={"design_file": design_file})
    assert expected in capfd.readouterr().out
    with pytest.raises(Exception, match="status 2|status 3"):
        inst.step(0.0, STEP)
    assert expected in capfd.readouterr().out


def test_an_error_scale_that_carries_the_errors_past_the_models_limits_is_reported(
    fmu_path, description, capfd
):
    # the bundled errors are a few um; x 1e4 they are centimetres (docs/model.md section 4)
    inst = Instance(fmu_path, description, reals={"error_scale": 1e4})
    expected = "must be at most 130 um, 0.1 x the eccentricity e = 1.3 mm"
    assert expected in capfd.readouterr().out
    with pytest.raises(Exception, match="status 2|status 3"):
        inst.step(0.0, STEP)
    assert expected in capfd.readouterr().out


def test_info_names_the_bundled_design_and_errors(fmu_path, rv40):
    from rvfmu.fmu.api import fmu_info

    text = fmu_info(fmu_path)
    assert f"design   {rv40.name} (z_s 12, z_pl 36, z_p 40, rated torque 412.0 N*m)" in text
    assert "errors   8 nonzero: crank_cam_eccentricity, disc_crank_hole" in text
    assert "a preset name or a design TOML path" in text  # design_file, as the README says


def test_load_above_the_momentary_class_warns_once_and_above_emergency_stop_is_refused(
    fmu_path, description, rv40, capfd
):
    inst = Instance(fmu_path, description)
    capfd.readouterr()
    rated = rv40.rated_torque
    for k, load in enumerate((-2.0 * rated, -3.0 * rated, 4.0 * rated)):  # in range: no Discard
        inst.set(theta_in=1.0 + k, tau_load=load)
        inst.step(k * STEP, STEP)
    log = capfd.readouterr().out
    assert log.count("above the momentary maximum class") == 1  # warned once, not per step
    assert "tau_load = -1236 N*m" in log  # the first offending input
    inst.set(theta_in=3.5, tau_load=-5.5 * rated)
    with pytest.raises(Exception, match="status 3"):  # fmi2Error: ended
        inst.step(3 * STEP, STEP)
    assert "tau_load = -2266.0: must be within +-5 x the rated torque 412" in capfd.readouterr().out
    restart(inst)
    inst.set(theta_in=0.5, tau_load=-rated)
    inst.step(0.0, STEP)  # usable after a reset


def test_error_scale_zero_is_the_error_free_reducer(fmu_path, description, rv40, tmp_path):
    clean_fmu = build_fmu(rv40, None, tmp_path / "clean.fmu", points=624)
    clean = Instance(clean_fmu, read_model_description(str(clean_fmu)))
    zeroed = Instance(fmu_path, description, reals={"error_scale": 0.0}, ints={"map_points": 624})
    errors = Instance(fmu_path, description, reals={"error_scale": 1.0}, ints={"map_points": 624})
    t = 0.0
    for theta, load in ((0.3, -400.0), (17.0, -10.0), (2.2, 0.0), (50.0, 300.0), (80.1, -800.0)):
        for inst in (clean, zeroed, errors):
            inst.set(theta_in=theta, tau_load=load)
            inst.step(t, LONG)
        t += LONG
        assert zeroed.get("te")[0] == pytest.approx(clean.get("te")[0], abs=1e-12)
        assert zeroed.get("tau_in")[0] == pytest.approx(clean.get("tau_in")[0], abs=1e-12)
        assert abs(errors.get("te")[0] - clean.get("te")[0]) > 1e-7  # the errors do show


def test_state_roll_back_and_re_step_give_identical_results(fmu_path, description):
    inst = Instance(fmu_path, description, reals={"theta_in": 9.9})  # no jump to 10 in 1 ms
    inst.set(theta_in=10.0, tau_load=-200.0)
    inst.step(0.0, STEP)
    state = inst.fmu.getFMUstate()
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    first = inst.get("theta_out", "omega_out", "te", "tau_in")
    inst.set(theta_in=55.0, tau_load=100.0)
    inst.step(2 * STEP, 1.0)  # 45 rad in 1 s, not in 1 ms
    inst.fmu.setFMUstate(state)
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    assert inst.get("theta_out", "omega_out", "te", "tau_in") == first
    inst.fmu.freeFMUstate(state)


def test_reset_returns_to_the_start(fmu_path, description):
    inst = Instance(fmu_path, description)
    start = inst.get("theta_out", "te")
    inst.set(theta_in=20.0, tau_load=-400.0)
    inst.step(0.0, 1.0)  # 20 rad in 1 s, not in 1 ms
    inst.fmu.reset()
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    assert inst.get("theta_out", "te") == start


def test_instances_in_one_process_stay_independent(fmu_path, description, rv40):
    plain = Instance(fmu_path, description, name="plain", reals={"theta_in": 4.9})
    # a second instance with other physics: no errors, the map solved again at init
    clean = Instance(
        fmu_path,
        description,
        name="clean",
        reals={"error_scale": 0.0, "pin_stiffness_scale": 1.0, "theta_in": 4.9},
    )
    alone = Instance(fmu_path, description, name="alone", reals={"theta_in": 4.9})
    for inst, theta in ((plain, 5.0), (clean, 5.0), (alone, 5.0)):
        inst.set(theta_in=theta, tau_load=-rv40.rated_torque)
    plain.step(0.0, STEP)
    clean.step(0.0, STEP)
    alone.step(0.0, STEP)
    assert plain.get("te") == alone.get("te")
    assert plain.get("te") != clean.get("te")


def native_env(site_packages):
    import sysconfig

    libpython = Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("LDLIBRARY")
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.update(LD_PRELOAD=str(libpython), PYTHONHOME=sys.base_prefix, PYTHONPATH=site_packages)
    return env


def test_native_engine_libcosim_runs_the_fmu_with_the_readme_recipe(fmu_path, rv40, tmp_path):
    site = ":".join(p for p in sys.path if p.endswith("site-packages"))
    out = tmp_path / "cosim.csv"
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "studies" / "native_host" / "run_libcosim.py"),
            str(fmu_path),
            str(out),
            "--load",
            str(rv40.rated_torque),
            "--duration",
            "0.05",
        ],
        env=native_env(site),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = np.genfromtxt(out, delimiter=",", names=True)
    # libcosim sets theta_in(t) then steps to t + h: outputs belong to theta_in(t)
    theta_in = SPEED * (data["time"] - STEP)
    reference = equilibria(rv40, rv40_errors(), theta_in, [-rv40.rated_torque]).te[0, 0] / ARCSEC
    np.testing.assert_allclose(data["te_arcsec"], reference, atol=0.05 * np.ptp(reference) + 0.5)


def rv40_errors():
    from rvfmu.core.reducer.design import preset
    from rvfmu.core.reducer.errors import load_errors

    return load_errors(ROOT / "studies" / "seed002_errors.toml", preset("RV-40E-121"))


def test_runs_where_numpy_and_scipy_are_installed_but_not_rvte_nor_numba(fmu_path, tmp_path):
    """A fresh venv with numpy, scipy, fmpy and libcosimpy only: both importers run the FMU,
    quasi-static and dynamic (the dynamic model's kernels then run as plain numpy)."""
    venv = tmp_path / "venv"
    # a venv without pip of its own, filled by this one's (pip --python), without byte-compiling
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-compile"]
        + ["numpy", "scipy", "fmpy", "libcosimpy"],
        check=True,
        timeout=900,
        capture_output=True,
    )
    for module in ("rvfmu", "numba"):
        probe = subprocess.run(
            [str(python), "-c", f"import {module}"], capture_output=True, text=True, cwd=tmp_path
        )
        assert probe.returncode != 0 and f"No module named '{module}'" in probe.stderr
    script = tmp_path / "run.py"
    script.write_text(
        "import json, sys, numpy as np\n"
        "from fmpy import simulate_fmu\n"
        "def log(env, name, status, category, message):  # the FMU's errors, for the test's message\n"
        "    if status > 1: print(message.decode(), file=sys.stderr)\n"
        "t = np.arange(0, 0.0505, 0.001)\n"
        "sig = np.zeros(t.size, dtype=[('time', float), ('theta_in', float), ('tau_load', float)])\n"
        f"sig['time'] = t; sig['theta_in'] = {SPEED} * t; sig['tau_load'] = -412.0\n"
        "options = dict(output_interval=0.001, step_size=0.001, input=sig, output=['te_arcsec'],\n"
        "               debug_logging=True, logger=log)\n"
        "r = simulate_fmu(sys.argv[1], stop_time=0.05, **options)\n"
        "print(repr(float(r['te_arcsec'][-1])))\n"
        "r = simulate_fmu(sys.argv[1], stop_time=0.01, start_values={'model': 'dynamic'}, **options)\n"
        "print(json.dumps(r['te_arcsec'].tolist()))\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    proc = subprocess.run(
        [str(python), str(script), str(fmu_path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    static_last, dynamic = proc.stdout.strip().splitlines()[-2:]
    inside = run(fmu_path, 0.05, STEP, lambda t: SPEED * t, lambda t: -412.0 + 0 * t)
    assert float(static_last) == pytest.approx(inside["te_arcsec"][-1], abs=1e-9)
    # the same dynamic run in this process, where the kernels may be numba-compiled: equal to rounding
    times = np.arange(0, 0.0505, STEP)
    inside = simulate_fmu(
        str(fmu_path),
        stop_time=0.01,
        output_interval=STEP,
        step_size=STEP,
        input=signal(times, SPEED * times, -412.0 + 0 * times),
        output=["te_arcsec"],
        start_values={"model": "dynamic"},
    )["te_arcsec"]
    dynamic = np.array(json.loads(dynamic))
    assert dynamic.shape == inside.shape, proc.stderr[-2000:]
    assert np.isfinite(dynamic).all()
    np.testing.assert_allclose(dynamic, inside, rtol=0, atol=1e-6)
    site = str(next((venv / "lib").glob("python3*/site-packages")))
    cosim = {}
    for model, duration in (("quasistatic", "0.02"), ("dynamic", "0.01")):
        out = tmp_path / f"cosim_{model}.csv"
        proc = subprocess.run(
            [
                str(python),
                str(ROOT / "studies" / "native_host" / "run_libcosim.py"),
                str(fmu_path),
                str(out),
                "--load",
                "412",
                "--duration",
                duration,
                "--model",
                model,
            ],
            env=native_env(site),
            capture_output=True,
            text=True,
            timeout=600,
            cwd=tmp_path,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        cosim[model] = np.genfromtxt(out, delimiter=",", names=True)["te_arcsec"]
        assert np.isfinite(cosim[model]).all()
    # libcosim's row k is at (k + 1) h, fmpy's at k h; the same inputs, the same plain-numpy kernels
    np.testing.assert_allclose(cosim["dynamic"][:-1], dynamic[1:], rtol=0, atol=1e-9)

"""The native reducer FMU (rvfmu.fmu.native): compiled C from the TE map, no Python at run time."""

import contextlib
import io
import shutil
import struct
import subprocess
import zipfile
from ctypes import byref
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CoSimulation, fmi2False, fmi2Terminated, fmi2True
from fmpy.validation import validate_fmu
from test_fmu import (
    Instance,
    free_instances,  # noqa: F401 - frees every instance after a test
)

from rvfmu.core.base.units import ARCSEC
from rvfmu.core.steppers.reducer_model import friction_step
from rvfmu.fmu.api import fmu_build, fmu_info
from rvfmu.fmu.build import build_fmu
from rvfmu.fmu.native import (
    PARAMETERS,
    TABLE_HEADER,
    TABLE_NAME,
    VARIABLES,
    WIN64_COMPILER,
    native_platforms,
    read_table,
)

MAP_POINTS = 4 * 40 * 39  # as tests/test_fmu_dynamic.py
STEP = 1e-3
LONG = 1e4  # [s] a step over which any jump of an angle is a slow turn
OUTPUTS = ("theta_out", "omega_out", "te", "te_arcsec", "tau_in", "P_loss", "efficiency")
FMI2_COSIMULATION_FUNCTIONS = (
    "GetTypesPlatform GetVersion SetDebugLogging Instantiate FreeInstance SetupExperiment "
    "EnterInitializationMode ExitInitializationMode Terminate Reset GetReal GetInteger GetBoolean "
    "GetString SetReal SetInteger SetBoolean SetString GetFMUstate SetFMUstate FreeFMUstate "
    "SerializedFMUstateSize SerializeFMUstate DeSerializeFMUstate GetDirectionalDerivative "
    "SetRealInputDerivatives GetRealOutputDerivatives DoStep CancelStep GetStatus GetRealStatus "
    "GetIntegerStatus GetBooleanStatus GetStringStatus"
).split()


@pytest.fixture(scope="module")
def native(tmp_path_factory, rv40, seed002):
    path = fmu_build(
        rv40, seed002, tmp_path_factory.mktemp("native") / "RVReducer.fmu", points=MAP_POINTS, native=True
    )
    return path, read_model_description(str(path))


@pytest.fixture(scope="module")
def python_fmu(tmp_path_factory, rv40, seed002):
    path = build_fmu(rv40, seed002, tmp_path_factory.mktemp("python") / "RVReducer.fmu", points=MAP_POINTS)
    return path, read_model_description(str(path))


@pytest.fixture(scope="module")
def unzipped(native, tmp_path_factory):
    return extract(str(native[0]), unzipdir=tmp_path_factory.mktemp("unzipped"))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The error-free reducer, built by `rvte fmu build --native` on a machine without cmake
    nor mingw-w64: the C compiler directly, no win64.  (path, description, printed lines)"""
    from rvfmu import cli

    path = tmp_path_factory.mktemp("clean") / "clean.fmu"
    which = shutil.which

    def hidden(name):
        return None if name in ("cmake", WIN64_COMPILER) else which(name)

    printed = io.StringIO()
    with mock.patch("shutil.which", hidden), contextlib.redirect_stdout(printed):
        assert cli.main(["fmu", "build", "RV-40E-121", "--native", "--points", "624", "-o", str(path)]) in (
            0,
            None,
        )
    return path, read_model_description(str(path)), printed.getvalue()


def drive(inst, theta_in, tau_load):
    """Every output after each 1 ms step; inputs [k] set at k * STEP, held to (k + 1) * STEP."""
    rows = []
    for k, (theta, load) in enumerate(zip(theta_in, tau_load)):
        inst.set(theta_in=theta, tau_load=load)
        inst.step(k * STEP, STEP)
        rows.append(inst.get(*OUTPUTS))
    return np.array(rows)


def varying_run(rated_torque, steps=6000):
    """Input speed swinging 200..1800 rpm, backwards for the first 0.1 s (from the start
    angle 0: negative angles too, and no jump the speed limit would refuse), held still for a
    while, a load swinging +-2.7 x rated (both branches, past the momentary class where the
    map is extrapolated)."""
    t = np.arange(steps) * STEP
    speed = (1000 + 800 * np.sin(2 * np.pi * 1.5 * t)) * 2 * np.pi / 60
    speed[(t > 1.0) & (t < 1.3)] = 0.0
    speed[t < 0.1] *= -1.0
    theta_in = np.cumsum(speed) * STEP  # negative angles too
    tau_load = 2.7 * rated_torque * np.sin(2 * np.pi * 2.2 * t + 0.3)
    tau_load[::97] = 0.0  # exactly no load, both signs
    tau_load[::89] = -0.0
    return theta_in, tau_load


def test_outputs_equal_the_python_fmu_over_a_long_varying_run(native, python_fmu, rv40):
    theta_in, tau_load = varying_run(rv40.rated_torque)
    assert (tau_load > 0).any() and (tau_load < 0).any()
    ours = drive(Instance(*native, name="native"), theta_in, tau_load)
    theirs = drive(Instance(*python_fmu, name="python"), theta_in, tau_load)
    te, theirs_te = ours[:, 2], theirs[:, 2]
    np.testing.assert_allclose(te, theirs_te, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours[:, 0], theirs[:, 0], rtol=0, atol=1e-9)  # theta_out
    np.testing.assert_allclose(ours[:, 3], theirs[:, 3], rtol=0, atol=1e-12 / ARCSEC)
    np.testing.assert_allclose(ours[:, 4], theirs[:, 4], rtol=1e-12, atol=1e-12)  # tau_in
    np.testing.assert_allclose(ours[:, 1], theirs[:, 1], rtol=0, atol=1e-9)  # omega_out
    np.testing.assert_allclose(ours[:, 5:], theirs[:, 5:], rtol=1e-9, atol=1e-12)  # P_loss, eff.
    assert np.ptp(te) > 1e-5 and np.ptp(ours[:, 1]) > 1.0


def test_friction_from_rest_through_reversal_and_backdriving(native, python_fmu, rv40):
    """Both FMUs carry the same friction (to 1e-9) over a run that starts from rest, turns
    forward against the load, is backdriven by it, reverses and stops; the input torque's
    friction opposes the input's turning, the loss is the mean of the power in less the
    power out, and at standstill nothing chatters."""
    steps = 4000
    t = np.arange(steps) * STEP
    speed = 150.0 * np.sin(2 * np.pi * 0.5 * t) * np.minimum(t / 0.2, 1.0)  # rad/s at the input
    speed[t > 3.5] = 0.0
    theta_in = np.cumsum(speed) * STEP
    tau_load = np.where(t < 1.0, -0.6, 0.6) * rv40.rated_torque  # resisting, then driving
    ours = drive(Instance(*native, name="native"), theta_in, tau_load)
    theirs = drive(Instance(*python_fmu, name="python"), theta_in, tau_load)
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-12)
    tau_in, p_loss, efficiency = ours[:, 4], ours[:, 5], ours[:, 6]
    omega_in = np.diff(theta_in, prepend=theta_in[0]) / STEP
    ideal = tau_load / rv40.ratio
    moving = np.abs(omega_in) > 1.0
    # friction takes from the input's turning: the input torque less the ideal one opposes it
    assert np.all((tau_in - ideal)[moving] * omega_in[moving] < 0.0)
    assert np.all(p_loss >= 0.0) and np.all(p_loss[moving] > 0.0)
    np.testing.assert_allclose(p_loss, (ideal - tau_in) * omega_in, rtol=2e-3, atol=1e-6)
    # forward (the motor drives against the load) and backdriving: efficiency within (0, 1)
    forward = moving & (tau_load * omega_in < 0)
    backward = moving & (tau_load * omega_in > 0)
    assert forward.any() and backward.any()
    assert np.all((efficiency[forward] > 0.5) & (efficiency[forward] < 1.0))
    assert np.all(efficiency[backward] < efficiency[forward].max())
    # the mean power balance over the forward stretch: in - out = loss
    run = forward & (t > 0.3) & (t < 0.9)
    p_in = -tau_in * omega_in
    p_out = -tau_load * ours[:, 1]
    assert np.mean(p_in[run] - p_out[run]) == pytest.approx(np.mean(p_loss[run]), rel=0.02)
    # at standstill: no loss, the input torque steady
    still = t > 3.6
    assert np.all(p_loss[still] == 0.0) and np.ptp(tau_in[still]) < 1e-9


def test_interpolation_is_te_map_evaluate_one_to_the_bit(native, unzipped, rv40):
    """Random angles (negative, many revolutions), loads on the levels and beyond the grid."""
    path, md = native
    te_map, rated = read_table(f"{unzipped}/resources/{TABLE_NAME}")
    assert rated == rv40.rated_torque
    rng = np.random.default_rng(9)
    theta = np.concatenate(
        [
            rng.uniform(-3000, 3000, 600),
            te_map.theta_in[:50],
            [0.0, -0.0, te_map.period, -te_map.period, 1e-300, -1e-300],
        ]
    )
    load = np.concatenate(
        [
            rng.uniform(-5, 5, 300) * rated,
            np.repeat(np.concatenate([te_map.torque_magnitude, -te_map.torque_magnitude]), 10),
        ]
    )
    load = np.resize(load, theta.size)
    inst = Instance(path, md)
    # steps of LONG: the angles jump by up to 6000 rad, at a speed the limit lets through
    for k, (a, b) in enumerate(zip(theta, load)):
        inst.set(theta_in=a, tau_load=b)
        inst.step(k * LONG, LONG)
        te = inst.get("te")[0]
        assert te == te_map.evaluate_one(float(a), float(b))[0], (a, b)
    # the friction table and the load-free friction, to the bit: tau_in and P_loss at input
    # speeds across the friction law's scale and the drag table (up to 11 rad/s at the output,
    # within the speed limit), both senses of power flow
    for k, (a, b) in enumerate(zip(theta[:300], load[:300])):
        omega_in = (k % 23 - 11) * 10.0 ** (k % 7 - 6) * te_map.ratio
        inst.set(theta_in=a, tau_load=b)
        inst.step(0.0, LONG)  # the angle of the step's start
        inst.set(theta_in=a + omega_in * STEP, tau_load=b)
        inst.step(STEP, STEP)
        tau_in, p_loss, efficiency = inst.get("tau_in", "P_loss", "efficiency")
        _, tau_map, coulomb = te_map.evaluate_one(float(a + omega_in * STEP), float(b))
        omega = (float(a + omega_in * STEP) - float(a)) / STEP
        expected = friction_step(
            tau_map,
            coulomb + te_map.load_free_one(omega / te_map.ratio),
            te_map.ratio,
            omega,
            coulomb + te_map.seal,
            te_map.static_friction_factor,
        )
        assert (tau_in, p_loss, efficiency) == expected, (a, b, omega_in)


def test_validates_declares_its_sources_and_carries_its_binaries(native, python_fmu, rv40):
    path, md = native
    assert validate_fmu(str(path)) == []
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert md.buildConfigurations[0].sourceFileSets[0].sourceFiles == [
        "model.c",
        "instance.c",
        "fmi2Functions.c",
    ]
    assert float(md.defaultExperiment.stepSize) == STEP
    # the pythonfmu FMU's inputs and outputs, to the unit and the description; of its
    # parameters temperature_C only
    theirs = {v.name: v for v in python_fmu[1].modelVariables}
    assert [v.name for v in md.modelVariables] == list(VARIABLES) + list(PARAMETERS)
    for v in md.modelVariables:
        t = theirs[v.name]
        assert (v.valueReference, v.causality, v.unit, v.description) == (
            t.valueReference,
            t.causality,
            t.unit,
            t.description,
        )
    assert {u.name for u in md.unitDefinitions} == {u.name for u in python_fmu[1].unitDefinitions}
    with zipfile.ZipFile(path) as archive:
        names = set(archive.namelist())
    assert {
        "binaries/linux64/RVReducer.so",
        "sources/model.c",
        "sources/model.h",
        "sources/instance.c",
        "sources/instance.h",
        "sources/fmi2Functions.c",
        f"resources/{TABLE_NAME}",
        "resources/design.toml",
        "resources/errors.toml",
    } <= names
    assert not any("python" in n.lower() or n.endswith(".py") for n in names)
    text = fmu_info(path)  # reads the XML and resources only
    assert f"design   {rv40.name} (z_s 12, z_pl 36, z_p 40, rated torque 412.0 N*m)" in text
    assert "errors   8 nonzero" in text and "design_file" not in text


C_HOST = r"""
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list args;
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name)

int main(int argc, char **argv) {   /* library, resources URI, GUID */
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference inputs[2] = {0, 1}, te = 4;
    fmi2Real start[2] = {-20.0, 0.0};
    fmi2Component c;
    int k;
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    LOAD(fmi2Instantiate); LOAD(fmi2SetupExperiment); LOAD(fmi2EnterInitializationMode);
    LOAD(fmi2ExitInitializationMode); LOAD(fmi2SetReal); LOAD(fmi2GetReal); LOAD(fmi2DoStep);
    LOAD(fmi2Terminate); LOAD(fmi2FreeInstance);
    c = fmi2Instantiate("host", fmi2CoSimulation, argv[3], argv[2], &callbacks, fmi2False, fmi2False);
    if (!c) return 2;
    fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    fmi2EnterInitializationMode(c);
    fmi2SetReal(c, inputs, 2, start);   /* the first step's angle: no jump to refuse */
    fmi2ExitInitializationMode(c);
    for (k = 0; k < 500; k++) {
        fmi2Real values[2] = {0.37 * k - 20.0, 300.0 * (k % 7 - 3)}, out;
        fmi2SetReal(c, inputs, 2, values);
        if (fmi2DoStep(c, k * 1e-3, 1e-3, fmi2True) != fmi2OK) return 3;
        fmi2GetReal(c, &te, 1, &out);
        printf("%a\n", out);
    }
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    dlclose(lib);
    return 0;
}
"""


def test_a_c_host_without_python_nor_libm_runs_the_fmu(native, unzipped, tmp_path):
    """The library loads and steps in a plain C program (not linked with libm)."""
    import fmpy

    (tmp_path / "host.c").write_text(C_HOST)
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(
        ["cc", "-std=c99", f"-I{headers}", str(tmp_path / "host.c"), "-o", str(tmp_path / "host"), "-ldl"],
        check=True,
        capture_output=True,
    )
    done = subprocess.run(
        [
            str(tmp_path / "host"),
            f"{unzipped}/binaries/linux64/RVReducer.so",
            Path(unzipped, "resources").as_uri(),
            native[1].guid,
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert done.returncode == 0, done.stderr
    te_map, _ = read_table(f"{unzipped}/resources/{TABLE_NAME}")
    expected = [te_map.evaluate_one(0.37 * k - 20.0, 300.0 * (k % 7 - 3))[0] for k in range(500)]
    assert [float.fromhex(line) for line in done.stdout.split()] == expected


def test_the_shared_library_exports_only_the_fmi_functions(unzipped):
    exported = subprocess.run(
        ["nm", "-D", "--defined-only", f"{unzipped}/binaries/linux64/RVReducer.so"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    functions = {name for name in exported if name.startswith("fmi2")}
    assert functions == {f"fmi2{f}" for f in FMI2_COSIMULATION_FUNCTIONS}
    assert not {"te_map_read", "reducer_step", "format_number"} & set(exported)


def test_win64_is_a_pe_dll_exporting_the_fmi2_cosimulation_api(native, unzipped):
    if "win64" not in native_platforms(native[0]):
        pytest.skip("built without x86_64-w64-mingw32-gcc (Debian package mingw-w64)")
    dump = subprocess.run(
        ["x86_64-w64-mingw32-objdump", "-p", f"{unzipped}/binaries/win64/RVReducer.dll"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "pei-x86-64" in dump and "DLL" in dump
    exports = dump[dump.index("[Ordinal/Name Pointer] Table") :]
    for function in FMI2_COSIMULATION_FUNCTIONS:
        assert f"] fmi2{function}\n" in exports, function
    imported = {line.split()[-1].lower() for line in dump.splitlines() if "DLL Name:" in line}
    assert imported <= {"kernel32.dll", "msvcrt.dll"}  # no libgcc DLL to ship


# -- a bad table -------------------------------------------------------------------------


def corrupt(data: bytearray, how: str) -> bytes:
    points, levels = struct.unpack_from("<2I", data, 12)
    te = TABLE_HEADER.size + 8 * levels
    if how == "nan":
        data[te + 8 * 5 : te + 8 * 6] = struct.pack("<d", float("nan"))
    elif how == "magic":
        data[:8] = b"RVTEMAQ\0"
    elif how == "version":
        data[8:12] = struct.pack("<I", 2)  # a table from before the speed limit
    elif how == "truncated":
        del data[-8:]
    elif how == "levels":
        data[TABLE_HEADER.size + 8 : TABLE_HEADER.size + 16] = struct.pack("<d", -1.0)
    elif how == "empty":
        del data[:]
    return bytes(data)


@pytest.mark.parametrize(
    "how, reason",
    [
        ("nan", "non-finite values in the torque levels, te, tau_in or the friction"),
        ("magic", "not a TE map table (no RVTEMAP magic)"),
        ("version", "format version 2, this FMU reads version 4"),
        ("truncated", "6240 angle points x 16 torque levels, 259 speeds and 49 temperatures do not fit its"),
        ("levels", "the torque levels must be strictly ascending"),
        ("empty", "not a TE map table"),
        ("missing", "cannot be opened"),
    ],
)
def test_a_bad_table_fails_instantiation_with_the_reason_logged(
    native, unzipped, tmp_path, capfd, how, reason
):
    copy = tmp_path / "fmu"
    shutil.copytree(unzipped, copy)
    table = copy / "resources" / TABLE_NAME
    if how == "missing":
        table.unlink()
    else:
        table.write_bytes(corrupt(bytearray(table.read_bytes()), how))
    md = native[1]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(copy), modelIdentifier="RVReducer", instanceName="bad")
    capfd.readouterr()
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(loggingOn=False)
    log = capfd.readouterr().out
    assert f"[ERROR] TE map table {table}: {reason}" in log
    fmu.freeLibrary()


@pytest.mark.parametrize("form", ["file://{}", "file:{}", "file://localhost{}", "{}", "http://x{}"])
def test_the_resource_location_is_read_in_its_file_uri_forms(native, unzipped, tmp_path, capfd, form):
    """Percent-encoding (a space and a % in the path), file:///, file:/, file://localhost/."""
    from urllib.parse import quote

    copy = tmp_path / "a dir with 100% of the map"
    shutil.copytree(unzipped, copy)
    md = native[1]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(copy), modelIdentifier="RVReducer", instanceName="uri")
    fmu.callbacks = defaultCallbacks
    uri = form.format(quote(str(copy / "resources")))
    fmu.component = fmu.fmi2Instantiate(
        b"uri", fmi2CoSimulation, md.guid.encode(), uri.encode(), byref(fmu.callbacks), fmi2False, fmi2True
    )
    if not form.startswith("file:"):
        assert fmu.component is None
        assert f"fmuResourceLocation = {uri}: must be a file URI" in capfd.readouterr().out
        fmu.freeLibrary()
        return
    assert fmu.component is not None
    assert (
        f"TE map {copy}/resources/{TABLE_NAME}: 6240 angle points x 16 torque levels"
        in capfd.readouterr().out
    )  # logged with loggingOn
    fmu.freeInstance()


# -- bad inputs and load limits ------------------------------------------------------------

BAD_STEPS = [
    ({"theta_in": float("nan"), "tau_load": -100.0}, STEP, "input theta_in = nan: must be finite"),
    ({"theta_in": 1.0, "tau_load": float("inf")}, STEP, "input tau_load = inf: must be finite"),
    ({"theta_in": float("-inf"), "tau_load": 0.0}, STEP, "input theta_in = -inf: must be finite"),
    ({"theta_in": 1.0, "tau_load": -100.0}, -STEP, "communication step size = -0.001: must be a number > 0"),
    ({"theta_in": 1.0, "tau_load": -100.0}, 0.0, "communication step size = 0.0: must be"),
    ({"theta_in": 1.0, "tau_load": -100.0}, float("nan"), "communication step size = nan"),
    (
        {"theta_in": 1.0, "tau_load": -5.5 * 412.0},
        STEP,
        "input tau_load = -2266.0: must be within +-5 x the rated torque 412 N*m "
        "(emergency-stop class, 2060 N*m): the small-displacement model does not hold beyond",
    ),
    ({"theta_in": 1.0, "tau_load": 1e6}, STEP, "input tau_load = 1000000.0: must be within"),
]


def restart(inst, **inputs):
    """fmi2Reset and a new start of `inst`, with these initial inputs."""
    inst.fmu.reset()
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    if inputs:
        inst.set(**inputs)
    inst.fmu.exitInitializationMode()


def test_bad_inputs_are_refused_with_the_python_fmus_message(native, python_fmu, capfd):
    """Both end the simulation (fmi2Error, fmi2Terminated, every later step refused:
    docs/model.md section 8; the pythonfmu FMU through its guard, rvfmu/fmu/build.py), with the
    same message, the outputs unchanged."""
    for fmu in (native, python_fmu):
        status = r"status 3 \(error\)"
        inst = Instance(*fmu)
        for values, size, expected in BAD_STEPS:
            restart(inst)
            inst.set(theta_in=0.5, tau_load=-100.0)
            inst.step(0.0, STEP)
            good = inst.get(*OUTPUTS)
            inst.set(**values)
            capfd.readouterr()
            with pytest.raises(Exception, match=status):
                inst.step(STEP, size)
            assert f"[ERROR] {expected}" in capfd.readouterr().out, (fmu[0], expected)
            assert inst.get(*OUTPUTS) == good  # the step changed nothing
            assert inst.fmu.getBooleanStatus(fmi2Terminated)
            inst.set(theta_in=0.6, tau_load=-100.0)  # good inputs: still refused
            with pytest.raises(Exception, match=status):
                inst.step(STEP, STEP)
            assert f"[ERROR] {expected}" in capfd.readouterr().out
        restart(inst)  # usable again after a reset
        inst.set(theta_in=0.5, tau_load=-100.0)
        inst.step(0.0, STEP)
        assert inst.get("te") == good[2:3]


def test_a_load_above_the_momentary_class_warns_once(native, rv40, capfd):
    inst = Instance(*native)
    capfd.readouterr()
    rated = rv40.rated_torque
    for k, load in enumerate((-2.0 * rated, -3.0 * rated, 4.0 * rated, -4.9 * rated)):
        inst.set(theta_in=1.0 + k, tau_load=load)
        inst.step(k * STEP, STEP)  # computed: no exception
    log = capfd.readouterr().out
    assert log.count("above the momentary maximum class") == 1
    assert (
        "[WARNING] input tau_load = -1236 N*m is 3 x the rated torque 412 N*m, above the "
        "momentary maximum class (2.5 x): the small-displacement model is stretched; treat "
        "the results with care"
    ) in log


def test_bad_initial_inputs_fail_initialisation_and_every_step_until_reset(native, capfd):
    path, md = native
    inst = Instance(path, md)
    inst.fmu.reset()
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.set(theta_in=float("nan"))
    capfd.readouterr()
    with pytest.raises(Exception, match=r"status 3"):
        inst.fmu.exitInitializationMode()
    assert "[ERROR] initialisation failed: input theta_in = nan: must be finite" in capfd.readouterr().out
    inst.set(theta_in=1.0, tau_load=0.0)
    with pytest.raises(Exception, match=r"status 3"):
        inst.step(0.0, STEP)
    assert "initialisation failed: input theta_in = nan" in capfd.readouterr().out
    assert inst.fmu.getBooleanStatus(fmi2Terminated)
    restart(inst, theta_in=1.0)
    assert not inst.fmu.getBooleanStatus(fmi2Terminated)
    inst.step(0.0, STEP)


def test_initial_outputs_in_initialisation_mode_and_log_categories(native, unzipped, rv40, capfd):
    md = native[1]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="RVReducer", instanceName="init")
    fmu.instantiate(loggingOn=False)
    Instance.opened.append(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [vr[name] for name in OUTPUTS]
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([vr["theta_in"], vr["tau_load"]], [3.0, -50.0])
    initial = fmu.getReal(outputs)  # initial unknowns, from these inputs
    fmu.exitInitializationMode()
    assert fmu.getReal(outputs) == initial and initial[0] != 0.0
    capfd.readouterr()
    fmu.setDebugLogging(False, ["logStatusWarning"])  # the host silences the load warning
    fmu.setReal([vr["tau_load"]], [-3 * rv40.rated_torque])
    fmu.doStep(0.0, STEP)
    assert capfd.readouterr().out == ""
    with pytest.raises(Exception, match="status 3"):
        fmu.setDebugLogging(True, ["logNothing"])
    assert (
        "log category logNothing: must be logEvents, logStatusWarning or logStatusError"
        in capfd.readouterr().out
    )


# -- states, reset, instances ---------------------------------------------------------------


def test_state_roll_back_and_serialisation_re_step_identically(native):
    inst = Instance(*native, reals={"theta_in": 9.9})  # no jump to 10: a slow turn
    inst.set(theta_in=10.0, tau_load=-200.0)
    inst.step(0.0, STEP)
    state = inst.fmu.getFMUstate()
    serialized = inst.fmu.serializeFMUstate(state)
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    first = inst.get(*OUTPUTS)
    assert first[1] != 0.0  # omega_out from the last step
    inst.set(theta_in=55.0, tau_load=100.0)
    inst.step(2 * STEP, 1.0)  # 45 rad in 1 s, not in 1 ms
    inst.fmu.setFMUstate(state)
    assert inst.get("theta_in", "tau_load") == [10.0, -200.0]  # the inputs come back too
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    assert inst.get(*OUTPUTS) == first
    inst.fmu.freeFMUstate(state)
    # a serialised state, read back, in another instance
    other = Instance(*native, name="other")
    restored = other.fmu.deSerializeFMUstate(serialized)
    other.fmu.setFMUstate(restored)
    other.set(theta_in=10.1, tau_load=-300.0)
    other.step(STEP, STEP)
    assert other.get(*OUTPUTS) == first
    other.fmu.freeFMUstate(restored)
    with pytest.raises(Exception, match="status 3"):
        other.fmu.deSerializeFMUstate(serialized[:-1])
    with pytest.raises(Exception, match="status 3"):
        other.fmu.deSerializeFMUstate(b"X" + serialized[1:])


def test_reset_returns_to_the_start(native):
    inst = Instance(*native, reals={"theta_in": 3.0, "tau_load": -50.0})
    start = inst.get(*OUTPUTS)
    assert start[1] == 0.0 and start[0] != 0.0  # outputs from the initial inputs
    inst.set(theta_in=20.0, tau_load=-400.0)
    inst.step(0.0, 1.0)  # 17 rad in 1 s, not in 1 ms
    inst.fmu.reset()
    assert inst.get("theta_in", *OUTPUTS) == [0.0] * (1 + len(OUTPUTS))
    inst.set(theta_in=3.0, tau_load=-50.0)
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    assert inst.get(*OUTPUTS) == start


def test_without_cmake_nor_mingw_the_c_compiler_builds_this_platform_alone(clean):
    path, md, printed = clean
    assert native_platforms(path) == ["linux64"]
    assert "binaries: linux64; no win64: x86_64-w64-mingw32-gcc was not found" in printed
    assert validate_fmu(str(path)) == []
    inst = Instance(path, md)
    inst.set(theta_in=1.0, tau_load=-412.0)
    inst.step(0.0, STEP)
    assert inst.get("te")[0] < 0  # a resisting load winds the output back


def test_instances_of_two_native_fmus_in_one_process_stay_independent(native, clean, rv40):
    clean_path, clean_md, _ = clean
    theta_in, tau_load = varying_run(rv40.rated_torque, steps=300)
    alone = drive(Instance(*native, name="alone"), theta_in, tau_load)
    clean_alone = drive(Instance(clean_path, clean_md, name="clean alone"), theta_in, tau_load)
    insts = [
        Instance(*native, name="a"),
        Instance(clean_path, clean_md, name="b"),
        Instance(*native, name="c"),
    ]
    rows = [[], [], []]
    for k, (theta, load) in enumerate(zip(theta_in, tau_load)):
        for j, inst in enumerate(insts):  # interleaved, c half a step on
            inst.set(theta_in=theta + (0.5 if j == 2 else 0.0), tau_load=load)
            inst.step(k * STEP, STEP)
            rows[j].append(inst.get(*OUTPUTS))
    np.testing.assert_array_equal(rows[0], alone)
    np.testing.assert_array_equal(rows[1], clean_alone)
    assert not np.array_equal(rows[0], rows[1]) and not np.array_equal(rows[0], rows[2])

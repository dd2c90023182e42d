"""The FMI 3.0 native reducer FMU (`rvte fmu build --native --fmi-version 3`): the FMI 2.0 one's
model.c and instance.c under fmi3Functions.c, held against the FMI 2.0 native FMU.

Both FMUs are built from the same design and errors; every check that the two standards
share is made on both and compared: outputs over a long run, refusals and their log lines,
states.  The FMI 3.0 FMU is also run where nothing of ours is importable, under valgrind
and the sanitizers (tests/native3_host_cycles.c), compiled from its sources/ alone as a
tool would from buildDescription.xml, and checked by fmu-manipulation-toolbox.
"""

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import zipfile
from ctypes import byref
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave, fmi3Boolean, fmi3Error, fmi3Float64, fmi3OK
from fmpy.validation import validate_fmu
from test_fmu import (
    Instance,
    free_instances,  # noqa: F401 - frees every instance after a test
)
from test_fmu_native import (
    BAD_STEPS,
    MAP_POINTS,
    OUTPUTS,
    STEP,
    corrupt,
    drive,
    native,  # noqa: F401 - the FMI 2.0 native FMU fixture
    varying_run,
)
from test_fmu_native_hosts import (
    CYCLES,
    SANITIZE,
    STEPS,
    VALGRIND,
    assert_fmutool_compliant,
    assert_sanitizers_clean,
    assert_valgrind_clean,
    compile_host,
    fmutool,  # noqa: F401 - fmu-manipulation-toolbox's command
    fmutool_check,
    last_step_te,
    nan_table_resources,
    sanitized_library,
    tool,
    without_line,
)

from rvfmu import cli
from rvfmu.core.base.checks import InputError
from rvfmu.fmu.api import check_fmi_version, fmu_build, fmu_info
from rvfmu.fmu.fmi3 import FMI3_SOURCE_FILES
from rvfmu.fmu.native import PARAMETERS, TABLE_NAME, VARIABLES, WIN64_COMPILER, native_platforms

HOST_SOURCE = Path(__file__).with_name("native3_host_cycles.c")
LIBRARY = "binaries/x86_64-linux/RVReducer.so"
DLL = "binaries/x86_64-windows/RVReducer.dll"
# FMI 3.0's common functions and those of co-simulation (not model exchange's nor
# scheduled execution's own)
FMI3_COSIMULATION_FUNCTIONS = (
    "GetVersion SetDebugLogging InstantiateModelExchange InstantiateCoSimulation "
    "InstantiateScheduledExecution FreeInstance EnterInitializationMode ExitInitializationMode "
    "EnterEventMode Terminate Reset GetFloat32 GetFloat64 GetInt8 GetUInt8 GetInt16 GetUInt16 "
    "GetInt32 GetUInt32 GetInt64 GetUInt64 GetBoolean GetString GetBinary GetClock SetFloat32 "
    "SetFloat64 SetInt8 SetUInt8 SetInt16 SetUInt16 SetInt32 SetUInt32 SetInt64 SetUInt64 "
    "SetBoolean SetString SetBinary SetClock GetNumberOfVariableDependencies "
    "GetVariableDependencies GetFMUState SetFMUState FreeFMUState SerializedFMUStateSize "
    "SerializeFMUState DeserializeFMUState GetDirectionalDerivative GetAdjointDerivative "
    "EnterConfigurationMode ExitConfigurationMode GetIntervalDecimal GetIntervalFraction "
    "GetShiftDecimal GetShiftFraction SetIntervalDecimal SetIntervalFraction SetShiftDecimal "
    "SetShiftFraction EvaluateDiscreteStates UpdateDiscreteStates EnterStepMode "
    "GetOutputDerivatives DoStep"
).split()
# the rest of the API, exported too (importers look every function up), refusing every call
FMI3_OTHER_FUNCTIONS = (
    "EnterContinuousTimeMode CompletedIntegratorStep SetTime SetContinuousStates "
    "GetContinuousStateDerivatives GetEventIndicators GetContinuousStates "
    "GetNominalsOfContinuousStates GetNumberOfEventIndicators GetNumberOfContinuousStates "
    "ActivateModelPartition"
).split()


@pytest.fixture(scope="module")
def native3(tmp_path_factory, rv40, seed002):
    path = fmu_build(
        rv40,
        seed002,
        tmp_path_factory.mktemp("native3") / "RVReducer3.fmu",
        points=MAP_POINTS,
        native=True,
        fmi_version=3,
    )
    return path, read_model_description(str(path))


@pytest.fixture(scope="module")
def unzipped3(native3, tmp_path_factory):
    return Path(extract(str(native3[0]), unzipdir=tmp_path_factory.mktemp("unzipped3")))


@pytest.fixture(scope="module")
def bad_resources(unzipped3, tmp_path_factory):
    """resources/ with a NaN in the table: instantiation must return NULL."""
    return nan_table_resources(unzipped3, tmp_path_factory)


class Instance3(Instance):
    """One FMI 3.0 instance driven by hand through fmpy, with the FMI 2.0 `Instance`'s methods
    (so that `drive` runs both); freed after the test as those are."""

    def __init__(self, fmu_path, description, name="reducer", reals=None, unzipped=None):
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        unzipped = unzipped or extract(str(fmu_path))
        self.fmu = FMU3Slave(
            guid=description.guid,
            unzipDirectory=unzipped,
            modelIdentifier=description.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.fmu.instantiate(loggingOn=True)
        Instance.opened.append(self.fmu)
        self.start(reals)

    def start(self, reals=None):
        for key, value in (reals or {}).items():
            self.fmu.setFloat64([self.vr[key]], [value])
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def set(self, **values):
        self.fmu.setFloat64([self.vr[k] for k in values], list(values.values()))

    def get(self, *names):
        return self.fmu.getFloat64([self.vr[n] for n in names])

    def step(self, time, size):
        return self.fmu.doStep(currentCommunicationPoint=time, communicationStepSize=size)


# -- the same outputs, refusals and log lines as the FMI 2.0 native FMU ---------------------


def test_outputs_equal_the_fmi2_fmus_over_a_long_varying_run(native, native3, rv40):
    """Speed swinging 200..1800 rpm, held still, a load reversing through +-2.7 x rated."""
    theta_in, tau_load = varying_run(rv40.rated_torque)
    three = drive(Instance3(*native3, name="fmi3"), theta_in, tau_load)
    two = drive(Instance(*native, name="fmi2"), theta_in, tau_load)
    np.testing.assert_allclose(three, two, rtol=1e-12, atol=0)
    # the run exercises what it compares: TE, speed, both power flows, the friction outputs
    te, omega_out, p_loss, efficiency = three[:, 2], three[:, 1], three[:, 5], three[:, 6]
    assert np.ptp(te) > 1e-5 and np.ptp(omega_out) > 1.0
    assert (omega_out == 0).any() and (p_loss > 0).mean() > 0.5
    assert ((efficiency > 0) & (efficiency < 1)).any()


def test_bad_inputs_end_the_simulation_with_the_fmi2_fmus_log_lines(native, native3, capfd):
    """Each input no retry can make valid: status 3 (error), the outputs unchanged, the next step
    refused with the same line, usable again after a reset; the log lines of both standards."""
    logs = {}
    for fmu, make in ((native, Instance), (native3, Instance3)):
        inst = make(*fmu)
        capfd.readouterr()
        for values, size, _expected in BAD_STEPS:
            inst.fmu.reset()
            if make is Instance:
                inst.fmu.setupExperiment(startTime=0.0)
                inst.fmu.enterInitializationMode()
                inst.fmu.exitInitializationMode()
            else:
                inst.start()
            inst.set(theta_in=0.5, tau_load=-100.0)
            inst.step(0.0, STEP)
            good = inst.get(*OUTPUTS)
            inst.set(**values)
            with pytest.raises(Exception, match=r"status 3 \(error\)"):
                inst.step(STEP, size)
            assert inst.get(*OUTPUTS) == good  # the step changed nothing
            inst.set(theta_in=0.6, tau_load=-100.0)
            with pytest.raises(Exception, match=r"status 3 \(error\)"):
                inst.step(STEP, STEP)  # ended: good inputs refused too
        logs[make] = [
            line for line in capfd.readouterr().out.splitlines() if not line.startswith("[OK]")
        ]  # the resets, with logging on
    assert len(logs[Instance3]) == 2 * len(BAD_STEPS)
    for k, (_, _, expected) in enumerate(BAD_STEPS):
        assert logs[Instance3][2 * k].startswith(f"[ERROR] {expected}"), logs[Instance3][2 * k]
        assert logs[Instance3][2 * k + 1] == logs[Instance3][2 * k]
    assert logs[Instance3] == logs[Instance]


def test_a_load_above_the_momentary_class_warns_once_as_in_fmi2(native, native3, rv40, capfd):
    logs = {}
    rated = rv40.rated_torque
    for fmu, make in ((native, Instance), (native3, Instance3)):
        inst = make(*fmu)
        capfd.readouterr()
        for k, load in enumerate((-2.0 * rated, -3.0 * rated, 4.0 * rated, -4.9 * rated)):
            inst.set(theta_in=0.5 + 0.5 * k, tau_load=load)  # 39 rpm out: no speed warning
            inst.step(k * STEP, STEP)  # computed: no exception
        logs[make] = capfd.readouterr().out.splitlines()
    assert (
        logs[Instance3]
        == logs[Instance]
        == [
            "[WARNING] input tau_load = -1236 N*m is 3 x the rated torque 412 N*m, above the "
            "momentary maximum class (2.5 x): the small-displacement model is stretched; treat "
            "the results with care"
        ]
    )


def test_step_results_say_a_refused_input_ends_the_simulation(native3, capfd):
    inst = Instance3(*native3)
    do_step = inst.fmu.dll.fmi3DoStep  # the C function: its status and flags
    flags = [fmi3Boolean(True) for _ in range(3)]  # eventHandlingNeeded, terminate, early
    reached = fmi3Float64()
    inst.set(theta_in=0.5)
    status = do_step(inst.fmu.component, 0.5, STEP, True, *map(byref, flags), byref(reached))
    assert status == fmi3OK and [f.value for f in flags] == [False, False, False]
    assert reached.value == 0.5 + STEP
    inst.set(theta_in=float("nan"))
    status = do_step(inst.fmu.component, 0.5 + STEP, STEP, True, *map(byref, flags), byref(reached))
    assert status == fmi3Error and [f.value for f in flags] == [False, True, False]
    assert reached.value == 0.5 + STEP  # it did not get past the start
    inst.set(theta_in=0.6)  # good inputs: the simulation has ended
    status = do_step(inst.fmu.component, 0.5 + STEP, STEP, True, *map(byref, flags), byref(reached))
    assert status == fmi3Error and flags[1].value
    # bad initial inputs: fmi3ExitInitializationMode refuses, and every step after it
    inst.fmu.reset()
    capfd.readouterr()
    inst.fmu.setFloat64([inst.vr["theta_in"]], [float("nan")])
    inst.fmu.enterInitializationMode(startTime=0.0)
    with pytest.raises(Exception, match=r"status 3"):
        inst.fmu.exitInitializationMode()
    assert "[ERROR] initialisation failed: input theta_in = nan: must be finite" in capfd.readouterr().out
    inst.set(theta_in=1.0, tau_load=0.0)
    status = do_step(inst.fmu.component, 0.0, STEP, True, *map(byref, flags), byref(reached))
    assert status == fmi3Error and flags[1].value  # terminateSimulation
    inst.fmu.reset()
    inst.start()
    inst.step(0.0, STEP)


@pytest.mark.parametrize(
    "how, reason",
    [
        ("nan", "non-finite values in the torque levels, te, tau_in or the friction"),
        ("magic", "not a TE map table (no RVTEMAP magic)"),
        ("truncated", "6240 angle points x 16 torque levels, 259 speeds and 49 temperatures do not fit its"),
        ("missing", "cannot be opened"),
    ],
)
def test_a_corrupt_table_fails_instantiation_with_the_reason_logged(
    native3, unzipped3, tmp_path, capfd, how, reason
):
    copy = tmp_path / "fmu"
    shutil.copytree(unzipped3, copy)
    table = copy / "resources" / TABLE_NAME
    if how == "missing":
        table.unlink()
    else:
        table.write_bytes(corrupt(bytearray(table.read_bytes()), how))
    fmu = FMU3Slave(
        guid=native3[1].guid, unzipDirectory=str(copy), modelIdentifier="RVReducer", instanceName="bad"
    )
    capfd.readouterr()
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(loggingOn=False)
    assert f"[ERROR] TE map table {table}: {reason}" in capfd.readouterr().out
    fmu.freeLibrary()


# -- the FMU: description, sources, binaries, the CLI ---------------------------------------


def test_validates_with_the_fmi2_fmus_variables_units_and_value_references(native, native3):
    path, md = native3
    assert validate_fmu(str(path)) == []
    assert md.fmiVersion == "3.0" and md.guid.startswith("{")  # the instantiationToken
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.canHandleVariableCommunicationStepSize and not cs.hasEventMode
    assert float(md.defaultExperiment.stepSize) == STEP
    time, *variables = md.modelVariables
    assert (time.name, time.causality, time.unit, time.valueReference) == (
        "time",
        "independent",
        "s",
        len(VARIABLES),
    )
    two = native[1]
    assert (
        [v.name for v in variables]
        == [v.name for v in two.modelVariables]
        == list(VARIABLES) + list(PARAMETERS)
    )
    for v, t in zip(variables, two.modelVariables):
        assert v.type == "Float64"
        assert (v.valueReference, v.causality, v.variability, v.initial, v.unit, v.description) == (
            t.valueReference,
            t.causality,
            t.variability,
            t.initial,
            t.unit,
            t.description,
        )
    assert {(u.name, str(u.baseUnit)) for u in md.unitDefinitions} == {
        (u.name, str(u.baseUnit)) for u in two.unitDefinitions
    }
    outputs = [v for v in variables if v.causality == "output"]
    assert [u.variable for u in md.outputs] == outputs
    assert [u.variable for u in md.initialUnknowns] == outputs
    # the sources a tool compiles, from buildDescription.xml
    source_set = md.buildConfigurations[0].sourceFileSets[0]
    assert source_set.sourceFiles == list(FMI3_SOURCE_FILES) and source_set.language == "C99"
    with zipfile.ZipFile(path) as archive:
        names = set(archive.namelist())
    assert {
        LIBRARY,
        DLL,
        "sources/buildDescription.xml",
        "sources/fmi3Functions.c",
        "sources/model.c",
        "sources/model.h",
        "sources/instance.c",
        "sources/instance.h",
        f"resources/{TABLE_NAME}",
        "resources/design.toml",
        "resources/errors.toml",
    } <= names
    assert not any("fmi2" in n or "python" in n.lower() or n.endswith(".py") for n in names)
    assert native_platforms(path) == ["x86_64-linux", "x86_64-windows"]


def test_model_c_is_the_fmi2_fmus_to_the_byte(unzipped3, native):
    with zipfile.ZipFile(native[0]) as archive:
        for name in ("model.c", "model.h", "instance.c", "instance.h"):
            assert archive.read(f"sources/{name}") == (unzipped3 / "sources" / name).read_bytes()


def test_fmu_info_says_the_fmi_version(native, native3):
    for fmu, version in ((native3, "3.0"), (native, "2.0")):
        assert (
            fmu_info(fmu[0]).splitlines()[0] == f"RVReducer  FMI {version} co-simulation  (rvte (native FMU))"
        )


def test_the_cli_builds_it_and_refuses_other_versions_and_fmi3_without_native(tmp_path, capsys):
    """`rvte fmu build --native --fmi-version 3` on a machine without cmake nor mingw-w64: the C
    compiler alone builds x86_64-linux; --fmi-version takes 2 or 3, 3 only with --native."""
    path = tmp_path / "clean3.fmu"
    which = shutil.which

    def hidden(name):
        return None if name in ("cmake", WIN64_COMPILER) else which(name)

    printed = io.StringIO()
    with mock.patch("shutil.which", hidden), contextlib.redirect_stdout(printed):
        assert cli.main(
            [
                "fmu",
                "build",
                "RV-40E-121",
                "--native",
                "--fmi-version",
                "3",
                "--points",
                "624",
                "-o",
                str(path),
            ]
        ) in (0, None)
    assert "binaries: x86_64-linux; no win64: x86_64-w64-mingw32-gcc was not found" in printed.getvalue()
    assert native_platforms(path) == ["x86_64-linux"] and validate_fmu(str(path)) == []
    inst = Instance3(path, read_model_description(str(path)))
    inst.set(theta_in=1.0, tau_load=-412.0)
    inst.step(0.0, STEP)
    assert inst.get("te")[0] < 0  # a resisting load winds the output back
    assert cli.main(["fmu", "info", str(path)]) in (0, None)
    assert "FMI 3.0 co-simulation" in capsys.readouterr().out
    for argv, message in (
        (["--native", "--fmi-version", "4"], "fmi_version = '4': must be 2 or 3 (FMI 2.0 or FMI 3.0)"),
        (["--native", "--fmi-version", "3.1"], "fmi_version = '3.1': must be 2 or 3"),
        (
            ["--fmi-version", "3"],
            "fmi_version = '3': FMI 3.0 needs the native FMU (--native): the pythonfmu FMU is FMI 2.0 only",
        ),
    ):
        assert cli.main(["fmu", "build", "RV-40E-121", *argv, "-o", str(tmp_path / "x.fmu")]) == 2
        assert f"rvte fmu: error: {message}" in capsys.readouterr().err
    assert not (tmp_path / "x.fmu").exists()


def test_the_fmi_version_is_2_or_3_and_3_is_native_only():
    for given, native_fmu, version in (
        (2, False, 2),
        ("2", True, 2),
        ("3", True, 3),
        (3.0, True, 3),
        ("3.0", True, 3),
    ):
        assert check_fmi_version(given, native_fmu) == version
    for given in (1, 4, "2.5", "three", True, None, ""):
        with pytest.raises(InputError, match="fmi_version = .*: must be 2 or 3"):
            check_fmi_version(given, True)
    with pytest.raises(InputError, match="FMI 3.0 needs the native FMU"):
        check_fmi_version(3, False)


def test_a_tool_compiles_the_sources_from_build_description_alone(native3, unzipped3, rv40, tmp_path):
    """What `fmpy compile` does: binaries/ removed, the library rebuilt from sources/ as
    buildDescription.xml lists them (no flag of ours), and it steps as the shipped one."""
    from fmpy.build import build_platform_binary

    tool("cmake", "cmake")
    copy = tmp_path / "source_only"
    shutil.copytree(unzipped3, copy)
    shutil.rmtree(copy / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(copy, tmp_path / "build")
    assert (copy / LIBRARY).is_file()
    theta_in, tau_load = varying_run(rv40.rated_torque, steps=400)
    rebuilt = drive(Instance3(*native3, unzipped=str(copy), name="rebuilt"), theta_in, tau_load)
    shipped = drive(Instance3(*native3, unzipped=str(unzipped3), name="shipped"), theta_in, tau_load)
    np.testing.assert_allclose(rebuilt, shipped, rtol=1e-12, atol=1e-15)


def test_the_shared_library_exports_only_the_fmi3_functions(unzipped3):
    exported = subprocess.run(
        ["nm", "-D", "--defined-only", str(unzipped3 / LIBRARY)], capture_output=True, text=True, check=True
    ).stdout.split()
    assert {name for name in exported if name.startswith("fmi")} == {
        f"fmi3{f}" for f in FMI3_COSIMULATION_FUNCTIONS + FMI3_OTHER_FUNCTIONS
    }
    assert not {"te_map_read", "reducer_step", "core_step"} & set(exported)


def test_win64_is_a_pe_dll_exporting_every_fmi3_cosimulation_function(native3, unzipped3):
    tool(WIN64_COMPILER, "mingw-w64")
    dump = subprocess.run(
        ["x86_64-w64-mingw32-objdump", "-p", str(unzipped3 / DLL)], capture_output=True, text=True, check=True
    ).stdout
    assert "pei-x86-64" in dump and "DLL" in dump
    exports = dump[dump.index("[Ordinal/Name Pointer] Table") :]
    exported = {line.split()[-1] for line in exports.splitlines() if "] fmi" in line}
    assert exported == {f"fmi3{f}" for f in FMI3_COSIMULATION_FUNCTIONS + FMI3_OTHER_FUNCTIONS}
    imported = {line.split()[-1].lower() for line in dump.splitlines() if "DLL Name:" in line}
    assert imported <= {"kernel32.dll", "msvcrt.dll"}  # no libgcc DLL to ship


# -- states, reset, instances ---------------------------------------------------------------


def test_state_roll_back_serialisation_and_reset(native3):
    inst = Instance3(*native3, reals={"theta_in": 9.9, "tau_load": -50.0})
    start = inst.get(*OUTPUTS)
    assert start[1] == 0.0 and start[0] != 0.0  # from the initial inputs
    inst.set(theta_in=10.0, tau_load=-200.0)
    inst.step(0.0, STEP)
    state = inst.fmu.getFMUState()
    serialized = inst.fmu.serializeFMUState(state)
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    first = inst.get(*OUTPUTS)
    assert first[1] != 0.0
    inst.set(theta_in=55.0, tau_load=100.0)
    inst.step(2 * STEP, 1.0)  # 45 rad in 1 s, not in 1 ms
    inst.fmu.setFMUState(state)
    assert inst.get("theta_in", "tau_load", "time") == [10.0, -200.0, STEP]
    inst.set(theta_in=10.1, tau_load=-300.0)
    inst.step(STEP, STEP)
    assert inst.get(*OUTPUTS) == first
    inst.fmu.freeFMUState(state)
    other = Instance3(*native3, name="other")  # read back in another instance
    restored = other.fmu.deserializeFMUState(serialized)
    other.fmu.setFMUState(restored)
    other.set(theta_in=10.1, tau_load=-300.0)
    other.step(STEP, STEP)
    assert other.get(*OUTPUTS) == first
    other.fmu.freeFMUState(restored)
    for bad in (serialized[:-1], b"X" + serialized[1:]):
        with pytest.raises(Exception, match="status 3"):
            other.fmu.deserializeFMUState(bad)
    # reset: back to the start values, and a second start repeats the first
    inst.fmu.reset()
    assert inst.get("theta_in", *OUTPUTS) == [0.0] * (1 + len(OUTPUTS))
    inst.start({"theta_in": 9.9, "tau_load": -50.0})
    assert inst.get(*OUTPUTS) == start


def test_several_instances_of_both_standards_in_one_process_stay_independent(native, native3, rv40):
    theta_in, tau_load = varying_run(rv40.rated_torque, steps=300)
    alone = drive(Instance3(*native3, name="alone"), theta_in, tau_load)
    insts = [Instance3(*native3, name="a"), Instance(*native, name="b"), Instance3(*native3, name="c")]
    rows = [[], [], []]
    for k, (theta, load) in enumerate(zip(theta_in, tau_load)):
        for j, inst in enumerate(insts):  # interleaved, c half a rad on
            inst.set(theta_in=theta + (0.5 if j == 2 else 0.0), tau_load=load)
            inst.step(k * STEP, STEP)
            rows[j].append(inst.get(*OUTPUTS))
    np.testing.assert_array_equal(rows[0], alone)
    np.testing.assert_allclose(rows[1], alone, rtol=1e-12, atol=0)
    assert not np.array_equal(rows[0], rows[2])


# -- real hosts, nothing of ours importable --------------------------------------------------

CLEAN_HOST = r'''
"""fmpy's simulate_fmu on the FMI 3.0 and FMI 2.0 native FMUs in a process started with
`python -I -S`: site-packages put on sys.path by hand, so that no .pth file runs (the one that
makes the editable rvte importable among them)."""
import json, os, sys

site, fmu3, fmu2, out, rated = sys.argv[1:]
sys.path.extend(site.split(os.pathsep))
report = {"environment": sorted(k for k in os.environ
                                if k.startswith("PYTHON") or k == "LD_PRELOAD")}
for name in ("rvfmu", "tolerance"):
    try:
        __import__(name)
        report[name] = "imported"
    except ImportError as exc:
        report[name] = str(exc)

import numpy as np
from fmpy import simulate_fmu

t = np.arange(2001) * 1e-3
speed = (1000 + 800 * np.sin(2 * np.pi * 1.5 * t)) * 2 * np.pi / 60
signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
signal["time"], signal["theta_in"] = t, np.cumsum(speed) * 1e-3
signal["tau_load"] = 2.7 * float(rated) * np.sin(2 * np.pi * 2.2 * t + 0.3)    # reverses
outputs = ["theta_out", "omega_out", "te", "te_arcsec", "tau_in", "P_loss", "efficiency"]
for label, fmu in (("fmi3", fmu3), ("fmi2", fmu2)):
    result = simulate_fmu(fmu, stop_time=2.0, output_interval=1e-3, step_size=1e-3, input=signal,
                          output=outputs)
    np.save(f"{out}/{label}.npy", result)
report["loaded"] = sorted(m for m in sys.modules
                          if m.split(".")[0] in ("rvfmu", "tolerance", "pythonfmu"))
with open(f"{out}/report.json", "w") as handle:
    json.dump(report, handle)
'''


def test_fmpy_simulates_it_as_the_fmi2_fmu_in_a_process_without_rvte_nor_python_variables(
    native, native3, unzipped3, rv40, tmp_path
):
    needed = subprocess.run(
        ["readelf", "-d", str(unzipped3 / LIBRARY)], capture_output=True, text=True, check=True
    ).stdout
    assert "NEEDED" in needed and "python" not in needed.lower()
    script = tmp_path / "clean_host.py"
    script.write_text(CLEAN_HOST)
    site = os.pathsep.join(
        dict.fromkeys(p for p in sys.path if Path(p).name in ("site-packages", "dist-packages"))
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "LD_PRELOAD"}
    work = tmp_path / "cwd"
    work.mkdir()
    done = subprocess.run(
        [
            sys.executable,
            "-I",
            "-S",
            str(script),
            site,
            str(native3[0]),
            str(native[0]),
            str(work),
            repr(rv40.rated_torque),
        ],
        env=env,
        cwd=work,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    report = json.loads((work / "report.json").read_text())
    assert report["environment"] == [] and report["loaded"] == []
    assert report["rvfmu"] == "No module named 'rvfmu'"
    assert report["tolerance"] == "No module named 'tolerance'"
    three, two = np.load(work / "fmi3.npy"), np.load(work / "fmi2.npy")
    assert three.size == two.size == 2001
    for name in three.dtype.names:
        np.testing.assert_allclose(three[name], two[name], rtol=1e-12, atol=0, err_msg=name)
    assert np.ptp(three["te_arcsec"]) > 10.0 and (three["P_loss"] > 0).any()


def test_the_fmu_manipulation_toolbox_checker_finds_it_fmi3_compliant(native3, unzipped3, fmutool, tmp_path):
    assert_fmutool_compliant(fmutool, native3[0], "3.0")
    # and it does catch what it checks: an output left out of <ModelStructure> (tau_in's)
    broken = without_line(unzipped3, tmp_path, '<Output valueReference="6" />')
    code, log = fmutool_check(fmutool, broken)
    assert code != 0, log


ECOS_HOST = r'''
"""The ecos co-simulation engine (ecospy) stepping the FMI 3.0 FMU: the inputs of `varying_run`
set before each 1 ms step, every output read after it.  ecospy's library needs oneTBB's
libtbb.so.12: pip's `tbb` puts it in its environment's lib folder (this venv's, or the base
Python's where a venv sees the system's packages), outside the loader's path, so it is loaded
first (where it is missing, the system's is found as usual)."""
import ctypes, json, sys
from pathlib import Path

found = [p for base in dict.fromkeys((sys.prefix, sys.base_prefix))
         for p in sorted(Path(base, "lib").glob("libtbb.so.12*"))]
for tbb in found[:1]:
    ctypes.CDLL(str(tbb), mode=ctypes.RTLD_GLOBAL)
from ecospy import EcosSimulation, EcosSimulationStructure

fmu, inputs, out, *outputs = sys.argv[1:]
inputs = json.loads(Path(inputs).read_text())
structure = EcosSimulationStructure()
structure.add_model("reducer", fmu)
rows = []
with EcosSimulation(structure=structure, step_size=1e-3) as simulation:
    simulation.init()
    for theta, load in zip(inputs["theta_in"], inputs["tau_load"]):
        simulation.set_real("reducer::theta_in", theta)
        simulation.set_real("reducer::tau_load", load)
        simulation.step()
        rows.append([simulation.get_real(f"reducer::{name}") for name in outputs])
    simulation.terminate()
Path(out).write_text(json.dumps(rows))
'''


def test_the_ecos_engine_steps_it_as_fmpy_does(native3, rv40, tmp_path):
    from importlib.util import find_spec

    # ecospy's import loads its library, which needs libtbb: only the host script can import it
    assert find_spec("ecospy"), "ecospy not installed (pyproject's [test] extra, with tbb)"

    theta_in, tau_load = varying_run(rv40.rated_torque, steps=1500)
    (tmp_path / "inputs.json").write_text(
        json.dumps({"theta_in": theta_in.tolist(), "tau_load": tau_load.tolist()})
    )
    (tmp_path / "ecos_host.py").write_text(ECOS_HOST)
    done = subprocess.run(
        [
            sys.executable,
            str(tmp_path / "ecos_host.py"),
            str(native3[0]),
            str(tmp_path / "inputs.json"),
            str(tmp_path / "out.json"),
            *OUTPUTS,
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, (done.stdout + done.stderr)[-4000:]
    by_ecos = np.array(json.loads((tmp_path / "out.json").read_text()))
    by_fmpy = drive(Instance3(*native3, name="fmpy"), theta_in, tau_load)
    assert by_ecos.shape == by_fmpy.shape == (1500, len(OUTPUTS))
    # ecos keeps time as a sum of steps, fmpy's as k h here: omega_out and the friction that goes
    # with it divide by step sizes that differ by a rounding error
    np.testing.assert_array_equal(by_ecos[:, [0, 2, 3]], by_fmpy[:, [0, 2, 3]])  # angles, TE
    np.testing.assert_allclose(by_ecos, by_fmpy, rtol=1e-12, atol=1e-12)
    assert np.ptp(by_ecos[:, 2]) > 1e-5


# -- memory checkers ---------------------------------------------------------------------


def run_cycles(host, library, unzipped, bad_resources, token, prefix=(), env=None):
    return subprocess.run(
        [
            *prefix,
            str(host),
            str(library),
            f"{unzipped / 'resources'}/",
            f"{bad_resources}/",
            token,
            str(CYCLES),
            str(STEPS),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )


def assert_summary(done, unzipped):
    """The host's closing line: its counts, and the TE of its last step from the Python map."""
    assert done.returncode == 0, done.stderr[-4000:]
    last_te = last_step_te(unzipped)
    # 11 steps refused per cycle (as the FMI 2.0 host); a load above the momentary class and
    # a speed above the allowable one warn; 21 errors logged per cycle and 4 for the instances
    # that are never made
    head = (
        f"cycles {CYCLES} steps {STEPS} refused {11 * CYCLES} warnings {2 * CYCLES} "
        f"errors {21 * CYCLES + 4} sum "
    )
    line = done.stdout.strip()
    assert line.startswith(head) and line.endswith(f" last te {last_te.hex()}"), (line, head)
    assert "[logStatusError] TE map table" in done.stderr
    assert "non-finite values in the torque levels, te, tau_in or the friction" in done.stderr


def test_valgrind_finds_no_error_nor_leak_over_100_instantiate_free_cycles(
    native3, unzipped3, bad_resources, tmp_path
):
    valgrind = tool("valgrind", "valgrind")
    host = compile_host(tmp_path / "host", source=HOST_SOURCE)
    done = run_cycles(
        host, unzipped3 / LIBRARY, unzipped3, bad_resources, native3[1].guid, prefix=[valgrind, *VALGRIND]
    )
    assert_summary(done, unzipped3)
    assert_valgrind_clean(done.stderr)


def test_address_and_undefined_behaviour_sanitizers_find_nothing_over_the_same_cycles(
    native3, unzipped3, bad_resources, tmp_path
):
    """The FMU's own sources/ rebuilt with the sanitizers (and its C_FLAGS: the same numbers)."""
    library, env = sanitized_library(
        unzipped3 / "sources", FMI3_SOURCE_FILES, tmp_path / "RVReducer_sanitized.so"
    )
    host = compile_host(tmp_path / "host_sanitized", *SANITIZE, source=HOST_SOURCE)
    done = run_cycles(host, library, unzipped3, bad_resources, native3[1].guid, env=env)
    assert_summary(done, unzipped3)
    assert_sanitizers_clean(done)

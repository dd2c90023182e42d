"""No host hangs on the reducer FMUs, and none is left without the reason a simulation ended.

docs/model.md section 8: an input no retry can make valid (NaN, inf, a load or a speed beyond
the design's limits) ends the simulation.  The native FMU says so with fmi2Error / fmi3Error
(and fmi2Terminated / terminateSimulation), which every host here stops on: fmpy's
simulate_fmu (its FMI 2.0 loop retries a discarded step for ever unless fmi2Terminated is
true), libcosim, and the plain C hosts of the other tests.  Each host runs in a subprocess
under a time limit, so a host that loops fails the test instead of hanging it.  The
pythonfmu FMU does the same through the library its Linux binary is wrapped in
(rvfmu/fmu/native/pythonfmu_guard.c: pythonfmu 0.7.0 has no fmi2Error for a Python slave
and logs nothing unless the host's logging is on).  The reason is logged with status error
at the host's default logging.  A jump of the input angle is a speed: beyond SPEED_FACTOR x
the design's allowable output speed it is refused, above it a warning is logged.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from fmpy import extract, read_model_description
from test_fmu_native_hosts import HEADERS, compile_host, nan_table_resources, tool

from rvfmu import cli
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import RPM
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.limits import SPEED_FACTOR, check_load, check_speed
from rvfmu.fmu.api import fmu_build
from rvfmu.fmu.build import GUARD_SOURCE, PYTHONFMU_LIBRARY
from rvfmu.fmu.native import FMI_VERSIONS, TABLE_NAME, table_limits

DESIGN = "RV-40E-121"  # allowable output speed 70 rpm, ratio 121, rated torque 412 N*m
POINTS = 624  # a coarse map: these tests are about statuses, not TE values
STEP = 1e-3
HOST_LIMIT = 60  # [s] a host that has not finished by then is taken to hang
CYCLES_SOURCE = {
    2: Path(__file__).with_name("native_host_cycles.c"),
    3: Path(__file__).with_name("native3_host_cycles.c"),
}
LIBRARY = {2: "binaries/linux64/RVReducer.so", 3: "binaries/x86_64-linux/RVReducer.so"}


@pytest.fixture(scope="module")
def design():
    return preset(DESIGN)


@pytest.fixture(scope="module")
def native(tmp_path_factory, design):
    """{FMI version: the native FMU's path}, one build each."""
    folder = tmp_path_factory.mktemp("native")
    return {
        version: fmu_build(
            design, None, folder / f"RVReducer{version}.fmu", points=POINTS, native=True, fmi_version=version
        )
        for version in FMI_VERSIONS
    }


@pytest.fixture(scope="module")
def python_fmu(tmp_path_factory, design):
    return fmu_build(design, None, tmp_path_factory.mktemp("python") / "RVReducer.fmu", points=POINTS)


def speed_message(design, theta_before, theta_in, step=STEP):
    """What rvfmu.core.reducer.limits says of the step from theta_before to theta_in [rad] in `step`
    [s]: the refusal's text (as the FMUs log it, after "input "), or the warning's, or None."""
    theta_before, theta_in = float(theta_before), float(theta_in)
    speed = (theta_in - theta_before) / step / design.ratio
    try:
        warning = check_speed("theta_in", theta_in, speed, design)
    except InputError as exc:
        return f"input {exc}"
    return warning and f"input {warning}"


def refusals(design):
    """(input, value from 50 ms on, the message) of every input no retry can make valid; the
    signal before 50 ms is theta_in = 100 t [rad] (7.9 rpm out), tau_load = -100 N*m."""
    with pytest.raises(InputError) as beyond:
        check_load("tau_load", -1e9, design.rated_torque)
    return [
        ("theta_in", "nan", "input theta_in = nan: must be finite"),
        ("tau_load", "nan", "input tau_load = nan: must be finite"),
        ("tau_load", "-inf", "input tau_load = -inf: must be finite"),
        ("tau_load", "-1e9", f"input {beyond.value}"),
        ("theta_in", "1e6", speed_message(design, 4.9, 1e6)),
    ]


# -- fmpy -----------------------------------------------------------------------------------

FMPY_HOST = r'''
"""fmpy's simulate_fmu over 0.1 s, the input `name` set to `value` from 50 ms on, once per case;
prints, per case, what simulate_fmu raised (or its rows) and what the FMU logged."""
import json, sys, time
import numpy as np
from fmpy import simulate_fmu

fmu, cases, start_values = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
results = []
for name, value in cases:
    t = np.arange(0, 0.1005, 0.001)
    signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
    signal["time"], signal["theta_in"], signal["tau_load"] = t, 100.0 * t, -100.0
    signal[name][50:] = float(value)
    log = []
    def logger(*args):       # FMI 2.0: (env, name, status, category, message); 3.0: no name
        status, category, message = args[-3:]
        log.append([int(status), category.decode(), message.decode()])
    start = time.monotonic()
    try:
        rows = len(simulate_fmu(fmu, stop_time=0.1, output_interval=0.001, step_size=0.001,
                                input=signal, logger=logger, start_values=start_values))
        raised = None
    except Exception as exc:
        rows, raised = None, str(exc)
    results.append({"raised": raised, "rows": rows, "log": log,
                    "seconds": time.monotonic() - start})
print(json.dumps(results))
'''


@pytest.mark.parametrize(
    "fmu, version, model",
    [("native", 2, None), ("native", 3, None), ("python", 2, "quasistatic"), ("python", 2, "dynamic")],
)
def test_fmpy_stops_with_an_error_on_every_input_no_retry_can_make_valid(
    native, python_fmu, design, fmu, version, model, tmp_path
):
    """A NaN angle; a NaN, -inf, -1e9 N*m load; 1e6 rad in 1 ms.  fmpy 0.3.32 retried the
    native FMU's discarded step for ever (FMI 2.0); the pythonfmu FMU's run ended early with
    no exception and nothing logged, and 1e6 rad in 1 ms was taken (omega_out 8.3e6 rad/s).
    Now simulate_fmu raises at once, the reason logged once with status error, at fmpy's
    default logging."""
    cases = refusals(design)
    script = tmp_path / "fmpy_host.py"
    script.write_text(FMPY_HOST)
    path = native[version] if fmu == "native" else python_fmu
    start_values = {"model": model} if model else {}
    done = subprocess.run(
        [
            sys.executable,
            str(script),
            str(path),
            json.dumps([[name, value] for name, value, _ in cases]),
            json.dumps(start_values),
        ],
        capture_output=True,
        text=True,
        timeout=HOST_LIMIT,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(done.stdout)
    assert len(results) == len(cases)
    for (name, value, message), result in zip(cases, results):
        assert result["raised"] == f"fmi{version}DoStep failed with status 3 (error).", (name, value)
        assert result["log"] == [[3, "logStatusError", message]], (name, value)  # once: no retry
        assert result["seconds"] < HOST_LIMIT / 2


def valgrind_errors(report):
    """valgrind's error records in `report` (its stderr), each as one text."""
    records, lines = [], []
    for line in report.splitlines():
        match = re.match(r"==\d+== ?(.*)$", line)
        if not match:
            continue
        text = match.group(1)
        if text.strip():
            lines.append(text)
        elif lines:
            records.append("\n".join(lines))
            lines = []
    return [r for r in records if r.startswith(("Invalid", "Mismatched", "Source and destination"))]


def test_a_python_host_that_exits_with_the_pythonfmu_fmu_loaded_touches_no_freed_memory(
    python_fmu, design, tmp_path
):
    """fmpy leaves the FMU loaded and its instance alive after a simulation that raised.  At the
    host's exit, pythonfmu 0.7.0 then released its interpreter state twice: exit() ran its
    static's destructor, which freed the state, and the library's unload function
    (finalizePythonInterpreter) decremented the freed block again.  valgrind shows it as an
    invalid read of a block freed in exit(); glibc aborted about one host in 60 (`corrupted
    double-linked list`, CI and 5 of ~310 runs of the test above), whenever the freed block had
    gone to a bin whose link the decrement broke.  The guard (native/pythonfmu_guard.c) now
    releases the state once, before either.  Under valgrind, no error may point into the FMU's
    binaries, and the host must still see the refusal."""
    valgrind = tool("valgrind", "valgrind")
    script = tmp_path / "fmpy_host.py"
    script.write_text(FMPY_HOST)
    extracted = tmp_path / "extracted"  # where fmpy unpacks the FMU (and leaves it)
    extracted.mkdir()
    message = refusals(design)[0][2]
    done = subprocess.run(
        [
            valgrind,
            "--undef-value-errors=no",  # CPython's own uninitialised reads are not the question
            sys.executable,
            str(script),
            str(python_fmu),
            json.dumps([["theta_in", "nan"]]),
            json.dumps({"model": "quasistatic"}),
        ],
        capture_output=True,
        text=True,
        timeout=900,
        env=os.environ | {"TMPDIR": str(extracted), "PYTHONMALLOC": "malloc"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    [result] = json.loads(done.stdout)
    assert result["raised"] == "fmi2DoStep failed with status 3 (error).", result
    assert result["log"] == [[3, "logStatusError", message]]
    ours = [record for record in valgrind_errors(done.stderr) if str(extracted) in record]
    assert not ours, "\n\n".join(ours)[:4000]


RELOAD_HOST = r'''
"""fmpy's simulate_fmu over 10 ms, twice from the FMU file (fmpy unpacks it to a new folder,
frees its library and deletes the folder each time), then twice from one folder unpacked
once; prints each run's last te_arcsec."""
import json, sys
import numpy as np
from fmpy import extract, simulate_fmu

fmu = sys.argv[1]
t = np.arange(0, 0.0105, 0.001)
signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
signal["time"], signal["theta_in"], signal["tau_load"] = t, 10.0 * t, -412.0
folder = extract(fmu)
last = [float(simulate_fmu(where, stop_time=0.01, output_interval=0.001, step_size=0.001,
                           input=signal, output=["te_arcsec"])["te_arcsec"][-1])
        for where in (fmu, fmu, folder, folder)]
print(json.dumps(last))
'''


def test_a_python_host_that_unloads_the_pythonfmu_fmu_and_runs_it_again_touches_no_freed_memory(
    python_fmu, tmp_path
):
    """The host of the bare-venv test (tests/test_fmu.py) aborted at exit in every full run of
    the suite for a day (`corrupted double-linked list`), never alone: fmpy frees the FMU's
    library after each simulate_fmu, but pythonfmu's library stays loaded (its C++ objects of
    unique binding make it undeletable) and released its interpreter state twice at exit, while
    the guard's exit handler had gone with the guard at the dlclose.  Whether glibc noticed
    hung on the heap's layout, which the temporary folders' names shift.  The guard now stays
    loaded with its handler (native/pythonfmu_guard.c).  Under valgrind: no error points into
    the FMU's binaries, and the four runs give the same TE."""
    valgrind = tool("valgrind", "valgrind")
    script = tmp_path / "reload_host.py"
    script.write_text(RELOAD_HOST)
    extracted = tmp_path / "extracted"  # where fmpy unpacks the FMU
    extracted.mkdir()
    done = subprocess.run(
        [valgrind, "--undef-value-errors=no", sys.executable, str(script), str(python_fmu)],
        capture_output=True,
        text=True,
        timeout=900,
        env=os.environ | {"TMPDIR": str(extracted), "PYTHONMALLOC": "malloc"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    last = json.loads(done.stdout)
    assert len(last) == 4 and np.isfinite(last).all() and len(set(last)) == 1, last
    ours = [record for record in valgrind_errors(done.stderr) if str(extracted) in record]
    assert not ours, "\n\n".join(ours)[:4000]


SPEED_HOST = r'''
"""fmpy's simulate_fmu over 0.1 s at a constant input speed [rad/s], at fmpy's default logging,
once per set of start values; prints, per run, the rows' times, theta_in and omega_out and
what the FMU logged."""
import json, sys
import numpy as np
from fmpy import simulate_fmu

fmu, speed, runs = sys.argv[1], float(sys.argv[2]), json.loads(sys.argv[3])
t = np.arange(0, 0.1005, 0.001)
signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
signal["time"], signal["theta_in"], signal["tau_load"] = t, speed * t, 0.0
out = []
for start_values in runs:
    log = []
    try:
        result = simulate_fmu(fmu, stop_time=0.1, output_interval=0.001, step_size=0.001,
                              input=signal, start_values=start_values,
                              output=["theta_in", "omega_out"],
                              logger=lambda *args: log.append((int(args[-3]),
                                                               args[-1].decode())))
    except Exception:
        print(json.dumps([start_values, log]), file=sys.stderr)
        raise
    out.append({name: result[name].tolist() for name in ("time", "theta_in", "omega_out")}
               | {"log": log})
print(json.dumps(out))
'''


def test_a_speed_above_the_allowable_one_is_computed_with_one_warning(native, python_fmu, design, tmp_path):
    """1.5 x the allowable output speed for 0.1 s: every row computed, status OK, one warning
    naming theta_in, the speed and the limit, in the three FMUs (and both pythonfmu models).
    In a host process of its own: fmpy keeps the logger of the last simulate_fmu in one global
    of its logging library, which every later default-logging instance of the process calls."""
    output_speed = 1.5 * design.allowable_output_speed
    script = tmp_path / "speed_host.py"
    script.write_text(SPEED_HOST)
    runs = [(native[2], [{}]), (native[3], [{}]), (python_fmu, [{}, {"model": "dynamic"}])]
    for fmu, start_values in runs:
        done = subprocess.run(
            [
                sys.executable,
                str(script),
                str(fmu),
                repr(output_speed * design.ratio),
                json.dumps(start_values),
            ],
            capture_output=True,
            text=True,
            timeout=HOST_LIMIT,
        )
        assert done.returncode == 0, done.stderr[-3000:]
        for values, result in zip(start_values, json.loads(done.stdout)):
            assert result["time"][-1] == pytest.approx(0.1)
            # row k holds the input applied at (k - 1) ms: the first move is from row 1 to row 2
            warning = speed_message(design, result["theta_in"][1], result["theta_in"][2])
            assert warning.startswith("input theta_in = 1.33046") and warning.endswith(
                " is an output speed of 105 rpm, 1.5 x the allowable output speed 70 rpm of "
                "RV-40E-121: no rating covers it; treat the results with care"
            ), warning
            warnings = [message for status, message in result["log"] if status == 1]
            assert warnings == [warning], (fmu, values)
            assert not [message for status, message in result["log"] if status > 1]
            omega = np.array(result["omega_out"])
            moving = omega[52:] if values else omega[2:]
            np.testing.assert_allclose(moving.mean(), output_speed, rtol=0.01)
            if not values:  # quasi-static: every step
                np.testing.assert_allclose(moving, output_speed, rtol=0.01)


TWICE_HOST = r"""
import json, os, sys
import numpy as np
from fmpy import simulate_fmu
t = np.arange(0, 0.0205, 0.001)
signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
signal["time"], signal["theta_in"] = t, 100.0 * t
out = []
for start_values in json.loads(sys.argv[2]):
    result = simulate_fmu(sys.argv[1], stop_time=0.02, output_interval=0.001, step_size=0.001,
                          input=signal, start_values=start_values, output=["omega_out"])
    out.append(float(np.mean(result["omega_out"][5:])))
kernels = sys.modules["rvfmu.core.dynamics.kernels"]
print("RESULT", json.dumps({"omega": out, "kernels": kernels.__file__,
                            "folders": sorted(os.listdir(os.environ["TMPDIR"]))}))
"""


def test_a_host_that_runs_the_python_fmu_again_after_deleting_its_folder_compiles_nothing(
    python_fmu, design, tmp_path
):
    """fmpy's simulate_fmu unpacks the FMU, runs it and deletes the folder; a second run in the
    same process (the dynamic model after the quasi-static one) used to find the rvfmu modules
    of the first, their files and cached kernels gone, and compiled every kernel again (84 s on
    a 2-core AMD EPYC).  The FMU's package is imported from its copy in the user's cache folder
    instead (`rvfmu.fmu.slave.stable_bundle`): both runs load every kernel they take from there,
    none is compiled, and a second process reuses the copy."""
    script = tmp_path / "twice_host.py"
    script.write_text(TWICE_HOST)
    cache, temp = tmp_path / "cache", tmp_path / "temp"
    temp.mkdir()
    env = {**os.environ, "XDG_CACHE_HOME": str(cache), "TMPDIR": str(temp), "NUMBA_DEBUG_CACHE": "1"}
    runs = json.dumps([{}, {"model": "dynamic"}])
    for process in range(2):
        done = subprocess.run(
            [sys.executable, str(script), str(python_fmu), runs],
            capture_output=True,
            text=True,
            timeout=HOST_LIMIT,
            env=env,
        )
        assert done.returncode == 0, done.stderr[-3000:]
        result = json.loads(done.stdout.split("RESULT ", 1)[1])
        copies = sorted(cache.joinpath("rvte").iterdir())
        assert len(copies) == 1 and copies[0].name.startswith("fmu-"), copies  # no staging left
        assert result["kernels"].startswith(str(copies[0])), result["kernels"]
        assert result["folders"] == []  # fmpy deleted both folders it unpacked
        saved = [line for line in done.stdout.splitlines() if line.startswith("[cache] data saved")]
        loaded = [line for line in done.stdout.splitlines() if line.startswith("[cache] data loaded")]
        assert not saved, saved[:3]
        assert loaded and all(str(copies[0]) in line for line in loaded), loaded[:3]
        assert any("communication_step" in line for line in loaded)  # the dynamic step
        # both models turn the output at the input's speed over the ratio
        np.testing.assert_allclose(result["omega"], 100.0 / design.ratio, rtol=0.02)
        if process == 0:
            made = copies[0].stat().st_mtime_ns
    assert copies[0].stat().st_mtime_ns == made  # the second process copied nothing


def test_the_bundle_is_copied_once_per_digest_or_imported_in_place(tmp_path):
    """`stable_bundle`: no rvfmu beside the module (not in an FMU) -> None; a bundle -> its copy
    under the cache root, made once and named by the digest of its sources; a changed source
    -> another copy; a cache root that cannot be written, or no home folder -> None (imported
    in place)."""
    from rvfmu.fmu.slave import stable_bundle

    here = tmp_path / "resources"
    (here / "rvfmu" / "core").mkdir(parents=True)
    (here / "rvfmu" / "__init__.py").write_text("")
    (here / "rvfmu" / "core" / "kernel.py").write_text("X = 1\n")
    assert stable_bundle(tmp_path / "elsewhere", tmp_path / "cache") is None
    first = stable_bundle(here, tmp_path / "cache")
    assert first.parent == tmp_path / "cache" and first.name.startswith("fmu-")
    assert (first / "rvfmu" / "core" / "kernel.py").read_text() == "X = 1\n"
    assert stable_bundle(here, tmp_path / "cache") == first
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == [first.name]
    (here / "rvfmu" / "core" / "kernel.py").write_text("X = 2\n")
    second = stable_bundle(here, tmp_path / "cache")
    assert second != first and (second / "rvfmu" / "core" / "kernel.py").read_text() == "X = 2\n"
    blocked = tmp_path / "file"
    blocked.write_text("")  # a file where the cache folder should be
    assert stable_bundle(here, blocked / "rvte") is None
    # no XDG_CACHE_HOME and no home folder: in place, nothing raised into the host
    with mock.patch.dict(os.environ, {"XDG_CACHE_HOME": ""}):
        with mock.patch("pathlib.Path.home", side_effect=RuntimeError("no home directory")):
            assert stable_bundle(here) is None


# -- libcosim ---------------------------------------------------------------------------------

COSIM_HOST = r'''
"""libcosim steps the FMU 100 times by 1 ms, the input `name` set to `value` from step 50 on,
once per case; prints, per case, the step that failed (None: none did)."""
import json, sys
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimSlave import CosimLocalSlave

fmu, cases = sys.argv[1], json.loads(sys.argv[2])
failed = []
for name, value in cases:
    execution = CosimExecution.from_step_size(step_size=1000000)
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=fmu, instance_name="reducer"))
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    manipulator = CosimManipulator.create_override()
    execution.add_manipulator(manipulator)
    at = None
    for k in range(100):
        inputs = {"theta_in": 0.1 * k, "tau_load": -100.0}
        if k >= 50:
            inputs[name] = float(value)
        manipulator.slave_real_values(index, [refs["theta_in"], refs["tau_load"]],
                                      [inputs["theta_in"], inputs["tau_load"]])
        if not execution.step():
            at = k
            break
    failed.append(at)
print("failed steps: " + json.dumps(failed), flush=True)   # libcosim logs to stdout too
'''


@pytest.mark.parametrize("fmu", ["native", "python"])
def test_libcosim_fails_the_step_and_logs_why(native, python_fmu, design, fmu, tmp_path):
    """libcosim (FMI 1.0 and 2.0 only): the FMI 2.0 native FMU with nothing preloaded, the
    pythonfmu FMU with libpython preloaded (the README's recipe)."""
    from test_fmu import native_env

    cases = [
        ("theta_in", "nan", "input theta_in = nan: must be finite"),
        ("tau_load", "-1e9", refusals(design)[3][2]),
        ("theta_in", "1e6", speed_message(design, 4.9, 1e6)),
    ]
    script = tmp_path / "cosim_host.py"
    script.write_text(COSIM_HOST)
    if fmu == "native":
        path = native[2]
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "LD_PRELOAD"}
    else:
        path = python_fmu
        env = native_env(":".join(p for p in sys.path if p.endswith("site-packages")))
    done = subprocess.run(
        [sys.executable, str(script), str(path), json.dumps([[name, value] for name, value, _ in cases])],
        capture_output=True,
        text=True,
        timeout=HOST_LIMIT,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    reports = [line for line in done.stdout.splitlines() if line.startswith("failed steps: ")]
    assert reports == ["failed steps: [50, 50, 50]"]
    for _, _, message in cases:
        assert f"[FMI status=error, category=logStatusError] {message}" in done.stdout + done.stderr


# -- the plain C hosts --------------------------------------------------------------------------


@pytest.mark.parametrize("version", FMI_VERSIONS)
def test_the_c_hosts_see_every_refusal_end_the_simulation(
    native, design, version, tmp_path, tmp_path_factory
):
    """tests/native_host_cycles.c and native3_host_cycles.c, built with -Wall -Wextra -Werror:
    each refusal ends the simulation with fmi2Error / fmi3Error (and the terminate flag), the
    next step is refused too, a reset starts again; the host finishes within the time limit."""
    unzipped = Path(extract(str(native[version]), unzipdir=tmp_path / "fmu"))
    bad = nan_table_resources(unzipped, tmp_path_factory)
    host = compile_host(tmp_path / "host", source=CYCLES_SOURCE[version])
    md = read_model_description(str(native[version]))
    if version == 2:
        where = [(unzipped / "resources").as_uri(), bad.as_uri(), md.guid]
    else:
        where = [f"{unzipped / 'resources'}/", f"{bad}/", md.instantiationToken]
    done = subprocess.run(
        [str(host), str(unzipped / LIBRARY[version]), *where, "2", "300"],
        capture_output=True,
        text=True,
        timeout=HOST_LIMIT,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    never_made = 3 if version == 2 else 4
    assert done.stdout.startswith(
        f"cycles 2 steps 300 refused 22 warnings 4 errors {21 * 2 + never_made} sum "
    )
    # the first cycle's log: each refusal twice (the step, and the next one), the warnings once
    lines = done.stderr.splitlines()
    prefix = "[logStatusError] cycle: " if version == 2 else "[logStatusError] "
    for message in (
        "input theta_in = nan: must be finite",
        "input tau_load = inf: must be finite",
        "communication step size = 0.0: must be a number > 0",
        "input tau_load = -1000000.0: must be within +-5 x the rated torque 412 N*m",
        "input theta_in = 999980.37: is an output speed of 7.892e+07 rpm: must be "
        "within 2 x the allowable output speed 70 rpm of RV-40E-121 (140 rpm out, "
        "16940 rpm in)",
        "initialisation failed: input theta_in = nan: must be finite",
    ):
        assert sum(line.startswith(prefix + message) for line in lines) == 2, message
    speed = speed_message(design, 0.37 * 150 - 20.0, 0.37 * 151 - 20.0 + 1.2)
    assert speed.startswith("input theta_in = 37.07 is an output speed of 123.9 rpm, 1.8 x")
    assert sum(speed in line for line in lines) == 1


def test_the_fmu_sources_compile_without_warnings(native, python_fmu, tmp_path):
    """The native FMUs' sources/, and the guard the pythonfmu FMU's Linux binary is (which
    opens pythonfmu's library, carried beside it, by its path)."""
    with zipfile.ZipFile(python_fmu) as archive:
        names = set(archive.namelist())
    assert {
        "binaries/linux64/RVReducer.so",
        f"binaries/linux64/{PYTHONFMU_LIBRARY}",
        "binaries/win64/RVReducer.dll",
    } <= names
    done = subprocess.run(
        [
            "gcc",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-O2",
            "-fPIC",
            f"-I{HEADERS}",
            "-c",
            str(GUARD_SOURCE),
            "-o",
            str(tmp_path / "g.o"),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0 and done.stderr == "", done.stderr
    for version in FMI_VERSIONS:
        sources = Path(extract(str(native[version]), unzipdir=tmp_path / str(version))) / "sources"
        glue = "fmi2Functions.c" if version == 2 else "fmi3Functions.c"
        for name in ("model.c", "instance.c", glue):
            done = subprocess.run(
                [
                    "gcc",
                    "-std=c99",
                    "-Wall",
                    "-Wextra",
                    "-Werror",
                    "-O2",
                    "-ffp-contract=off",
                    f"-I{HEADERS}",
                    f"-I{sources}",
                    "-c",
                    str(sources / name),
                    "-o",
                    str(tmp_path / f"{version}{name}.o"),
                ],
                capture_output=True,
                text=True,
            )
            assert done.returncode == 0 and done.stderr == "", (version, name, done.stderr)


TWO_FMUS_HOST = r'''
"""Two pythonfmu FMUs, one after the other, in one process: fmpy deletes the first one's
folder after its run; the second must run on its own copy of pythonfmu's library."""
import sys
import numpy as np
from fmpy import simulate_fmu

t = np.arange(0, 0.0205, 0.001)
signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
signal["time"], signal["theta_in"], signal["tau_load"] = t, 100.0 * t, -100.0
for fmu in sys.argv[1:]:
    print(len(simulate_fmu(fmu, stop_time=0.02, output_interval=0.001, step_size=0.001,
                           input=signal)))
signal["tau_load"][10:] = np.nan
try:
    simulate_fmu(sys.argv[-1], stop_time=0.02, output_interval=0.001, step_size=0.001,
                 input=signal)
except Exception as exc:
    print(exc)
'''


def test_two_pythonfmu_fmus_in_one_process_each_run_their_own_library(python_fmu, design, tmp_path):
    """A second FMU's guard once took the first one's pythonfmu library (the dynamic loader
    matched it by its soname), whose folder fmpy had deleted: the host crashed on the second
    FMU's first log message."""
    other = fmu_build(design, None, tmp_path / "Other.fmu", points=POINTS)
    script = tmp_path / "two_fmus.py"
    script.write_text(TWO_FMUS_HOST)
    done = subprocess.run(
        [sys.executable, str(script), str(python_fmu), str(other)],
        capture_output=True,
        text=True,
        timeout=HOST_LIMIT,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines() == [
        "21",
        "21",
        "[ERROR] input tau_load = nan: must be finite",
        "fmi2DoStep failed with status 3 (error).",
    ]


# -- the table carries the speed limit ----------------------------------------------------------


def test_the_table_carries_the_designs_speed_limit(native, design, tmp_path):
    with zipfile.ZipFile(native[2]) as archive:
        (tmp_path / TABLE_NAME).write_bytes(archive.read(f"resources/{TABLE_NAME}"))
    assert table_limits(tmp_path / TABLE_NAME) == {
        "allowable_output_speed": design.allowable_output_speed,
        "speed_factor": SPEED_FACTOR,
        "design": "RV-40E-121",
    }
    assert design.allowable_output_speed == pytest.approx(70 * RPM)


# -- rvte fmu build -o ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["x.zip", "x", "x.fmu.zip", "RVReducer."])
def test_an_output_not_ending_in_fmu_is_refused_before_any_build(name, tmp_path, capsys):
    """`-o x.zip` wrote x.fmu; now one line naming the option, the value and the rule, before
    the TE map is solved (nothing written)."""
    output = tmp_path / name
    with (
        mock.patch("rvfmu.fmu.build.prepare", side_effect=AssertionError("built")),
        mock.patch("rvfmu.fmu.native.prepare", side_effect=AssertionError("built")),
        mock.patch("rvfmu.core.steppers.te_map.build_te_map", side_effect=AssertionError("solved")),
    ):
        for native in ([], ["--native"]):
            assert cli.main(["fmu", "build", DESIGN, "-o", str(output), *native]) == 2
            err = capsys.readouterr().err.strip()
            assert err.splitlines() == [err]
            assert f"output = {str(output)!r}: must end in .fmu" in err
    assert list(tmp_path.iterdir()) == []


def test_an_existing_fmu_is_replaced_as_the_help_says(native, tmp_path, capsys):
    output = tmp_path / "RVReducer.fmu"
    shutil.copy(native[2], output)
    before = read_model_description(str(output)).guid
    assert cli.main(["fmu", "build", DESIGN, "--native", "--points", str(POINTS), "-o", str(output)]) in (
        0,
        None,
    )
    assert f"wrote {output}" in capsys.readouterr().out
    assert read_model_description(str(output)).guid != before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["RVReducer.fmu"]
    with pytest.raises(SystemExit):
        cli.main(["fmu", "build", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "FMU file to write, ending in .fmu (an existing file is replaced)" in help_text

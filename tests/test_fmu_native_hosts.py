"""The native reducer FMU in real hosts with nothing preloaded, under memory checkers, and
through a third-party FMI checker.

The native FMU's promise is that a host needs the file and nothing else: no Python, no
LD_PRELOAD, no rvte.  So fmpy and libcosim run it in a process that cannot import rvfmu
and has none of the environment the pythonfmu FMU needs (tests/test_fmu.py), and agree
row for row (the same C code: to the bit).  A plain C host (tests/native_host_cycles.c)
drives it through 100 instantiate/free cycles, every FMI function and every refusal path,
under valgrind and, with the FMU's sources rebuilt with -fsanitize=address,undefined,
under the sanitizers.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from conftest import ROOT
from fmpy import extract
from test_fmu_native import corrupt, native  # noqa: F401 - the native FMU fixture

from rvfmu.fmu.native import C_FLAGS, SOURCE_FILES, TABLE_NAME, read_table

SPEED = 1600 * 2 * np.pi / 60  # rad/s at the input, as in seeds 000/001
HEADERS = Path(fmpy.__file__).parent / "c-code"  # the FMI 2.0 and 3.0 headers fmpy ships
HOST_SOURCE = Path(__file__).with_name("native_host_cycles.c")
CYCLES, STEPS = 100, 300
SANITIZE = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"]


@pytest.fixture(scope="module")
def unzipped(native, tmp_path_factory):
    return Path(extract(str(native[0]), unzipdir=tmp_path_factory.mktemp("unzipped")))


def nan_table_resources(unzipped, tmp_path_factory):
    """A copy of an unzipped FMU's resources/ whose table has a NaN in it."""
    resources = tmp_path_factory.mktemp("bad") / "resources"
    shutil.copytree(unzipped / "resources", resources)
    table = resources / TABLE_NAME
    table.write_bytes(corrupt(bytearray(table.read_bytes()), "nan"))
    return resources


@pytest.fixture(scope="module")
def bad_resources(unzipped, tmp_path_factory):
    """resources/ with a NaN in the table: fmi2Instantiate must return NULL."""
    return nan_table_resources(unzipped, tmp_path_factory)


def tool(name, package):
    path = shutil.which(name)
    assert path, f"{name} not found: apt-get install {package} (the README's test command does)"
    return path


def compile_host(target, *flags, source=HOST_SOURCE):
    """A plain C host of the cycles (`source`: this file's FMI 2.0 one by default)."""
    subprocess.run(
        [
            tool("gcc", "gcc"),
            "-std=c99",
            "-g",
            "-O1",
            "-Wall",
            "-Wextra",
            "-Werror",
            *flags,
            f"-I{HEADERS}",
            str(source),
            "-o",
            str(target),
            "-ldl",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    return target


VALGRIND = [
    "--leak-check=full",
    "--show-leak-kinds=all",
    "--errors-for-leak-kinds=definite,indirect",
    "--error-exitcode=99",
    "--track-origins=yes",
]


def assert_valgrind_clean(report):
    """valgrind's report (stderr) says no error and no leak."""
    assert "ERROR SUMMARY: 0 errors from 0 contexts" in report, report[-4000:]
    if "LEAK SUMMARY" in report:
        assert "definitely lost: 0 bytes in 0 blocks" in report, report[-4000:]
        assert "indirectly lost: 0 bytes in 0 blocks" in report, report[-4000:]
    else:
        assert "All heap blocks were freed -- no leaks are possible" in report, report[-4000:]


def sanitized_library(sources, files, library):
    """The FMU's own sources/ (`files` of it) rebuilt with the sanitizers into `library`, and
    with its C_FLAGS (the same numbers); the environment the sanitized run takes."""
    subprocess.run(
        [
            tool("gcc", "gcc"),
            "-std=c99",
            "-shared",
            "-fPIC",
            "-g",
            "-O1",
            *C_FLAGS.split(),
            *SANITIZE,
            f"-I{HEADERS}",
            f"-I{sources}",
            *(str(sources / f) for f in files),
            "-o",
            str(library),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    env = dict(
        os.environ,
        ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:exitcode=98",
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
    )
    env.pop("LD_PRELOAD", None)
    return library, env


def assert_sanitizers_clean(done):
    assert "Sanitizer" not in done.stderr, done.stderr[-4000:]
    assert "runtime error" not in done.stderr, done.stderr[-4000:]


def last_step_te(unzipped):
    """The TE of the cycles host's last step (its inputs at step STEPS - 1), from the Python map."""
    te_map, _ = read_table(unzipped / "resources" / TABLE_NAME)
    k = STEPS - 1
    return te_map.evaluate_one(0.37 * k - 20.0, 300.0 * (k % 7 - 3))[0]


def run_cycles(host, library, unzipped, bad_resources, guid, prefix=(), env=None):
    return subprocess.run(
        [
            *prefix,
            str(host),
            str(library),
            (unzipped / "resources").as_uri(),
            bad_resources.as_uri(),
            guid,
            str(CYCLES),
            str(STEPS),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )


def expected_summary(unzipped):
    """The host's closing line: its counts, and the TE of its last step from the Python map."""
    last_te = last_step_te(unzipped)
    # 11 steps refused per cycle (5 inputs no retry can make valid, each refused twice, and
    # the step after bad initial inputs); a load above the momentary class and a speed above
    # the allowable one warn; 21 errors logged per cycle and 3 for the instances never made
    return (
        f"cycles {CYCLES} steps {STEPS} refused {11 * CYCLES} warnings {2 * CYCLES} "
        f"errors {21 * CYCLES + 3} sum ",
        f" last te {last_te.hex()}",
    )


def assert_summary(done, unzipped):
    assert done.returncode == 0, done.stderr[-4000:]
    head, tail = expected_summary(unzipped)
    line = done.stdout.strip()
    assert line.startswith(head) and line.endswith(tail), (line, head, tail)
    assert "[logStatusError] corrupted: TE map table" in done.stderr
    assert "non-finite values in the torque levels, te, tau_in or the friction" in done.stderr


# -- real hosts, nothing preloaded -------------------------------------------------------

CLEAN_HOST = r'''
"""libcosim (studies/native_host/run_libcosim.py), then fmpy, on the native FMU in a process
started with `python -I -S`: site-packages is put on sys.path by hand, so that none of its
.pth files runs, the one that makes the editable rvte importable among them."""
import importlib.util, json, os, sys

site, fmu, script, out, speed, duration, *loads = sys.argv[1:]
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

spec = importlib.util.spec_from_file_location("run_libcosim", script)
run_libcosim = importlib.util.module_from_spec(spec)
spec.loader.exec_module(run_libcosim)
for load in loads:
    assert run_libcosim.main([fmu, f"{out}/cosim_{load}.csv", f"--load={load}", f"--speed={speed}",
                              f"--duration={duration}"]) == 0
    # fmpy: the inputs libcosim is given, sampled at the communication points k h
    t = np.arange(round(float(duration) / 1e-3) + 1) * 1e-3
    signal = np.zeros(t.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
    signal["time"], signal["theta_in"], signal["tau_load"] = t, float(speed) * t, -float(load)
    result = simulate_fmu(fmu, stop_time=float(duration), output_interval=1e-3, step_size=1e-3,
                          input=signal, output=["theta_out", "te_arcsec", "omega_out", "tau_in",
                                                "P_loss", "efficiency"])
    np.save(f"{out}/fmpy_{load}.npy", result)
report["loaded"] = sorted(m for m in sys.modules
                          if m.split(".")[0] in ("rvfmu", "tolerance", "pythonfmu"))
with open(f"{out}/report.json", "w") as handle:
    json.dump(report, handle)
'''


def test_fmpy_and_libcosim_agree_in_a_process_without_rvte_libpython_preload_or_pythonpath(
    native, unzipped, rv40, tmp_path
):
    """A resisting load at rated torque and a driving one at half of it, 1 s at 1600 rpm."""
    library = unzipped / "binaries" / "linux64" / "RVReducer.so"
    needed = subprocess.run(
        ["readelf", "-d", str(library)], capture_output=True, text=True, check=True
    ).stdout
    assert "NEEDED" in needed and "python" not in needed.lower()
    script = tmp_path / "clean_host.py"
    script.write_text(CLEAN_HOST)
    # every site-packages folder this interpreter reads (a venv's own, and the system's where
    # the venv includes them), without the .pth files that run when site.py adds them
    site = os.pathsep.join(
        dict.fromkeys(p for p in sys.path if Path(p).name in ("site-packages", "dist-packages"))
    )
    loads = [rv40.rated_torque, -0.5 * rv40.rated_torque]
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
            str(native[0]),
            str(ROOT / "studies" / "native_host" / "run_libcosim.py"),
            str(work),
            repr(SPEED),
            "1.0",
            *map(repr, loads),
        ],
        env=env,
        cwd=work,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    report = json.loads((work / "report.json").read_text())
    assert report["environment"] == []
    assert report["rvfmu"] == "No module named 'rvfmu'"
    assert report["tolerance"] == "No module named 'tolerance'"
    assert report["loaded"] == []  # nor pythonfmu: nothing embeds Python
    for load in map(repr, loads):
        cosim = np.genfromtxt(work / f"cosim_{load}.csv", delimiter=",", names=True)
        by_fmpy = np.load(work / f"fmpy_{load}.npy")
        assert cosim.size == 1001 and by_fmpy.size == 1001
        # libcosim sets the inputs at t and steps to t + h: its row k is fmpy's row k + 1
        np.testing.assert_allclose(cosim["time"][:-1], by_fmpy["time"][1:], rtol=0, atol=1e-12)
        for name in ("te_arcsec", "theta_out"):  # the same C code, the same inputs
            np.testing.assert_array_equal(cosim[name][:-1], by_fmpy[name][1:], err_msg=f"{name}, {load}")
        # omega_out divides by the step size: libcosim's is a whole number of nanoseconds,
        # fmpy's (k + 1) h - k h; they differ by a rounding error, and so does the friction in
        # tau_in, P_loss and efficiency, which goes with the input speed over the step
        for name in ("omega_out", "tau_in", "P_loss", "efficiency"):
            np.testing.assert_allclose(
                cosim[name][:-1], by_fmpy[name][1:], rtol=1e-12, atol=1e-12, err_msg=f"{name}, {load}"
            )
        assert np.ptp(cosim["te_arcsec"]) > 10.0  # the TE does move over the run
    # a resisting load winds the output back, a driving one forward
    resisting, driving = (
        np.genfromtxt(work / f"cosim_{load!r}.csv", delimiter=",", names=True) for load in loads
    )
    assert resisting["te_arcsec"].mean() < driving["te_arcsec"].mean()


# -- memory checkers ---------------------------------------------------------------------


def test_valgrind_finds_no_error_nor_leak_over_100_instantiate_free_cycles(
    native, unzipped, bad_resources, tmp_path
):
    valgrind = tool("valgrind", "valgrind")
    host = compile_host(tmp_path / "host")
    done = run_cycles(
        host,
        unzipped / "binaries" / "linux64" / "RVReducer.so",
        unzipped,
        bad_resources,
        native[1].guid,
        prefix=[valgrind, *VALGRIND],
    )
    assert_summary(done, unzipped)
    assert_valgrind_clean(done.stderr)


def test_address_and_undefined_behaviour_sanitizers_find_nothing_over_the_same_cycles(
    native, unzipped, bad_resources, tmp_path
):
    """The FMU's own sources/ rebuilt with the sanitizers (and its C_FLAGS: the same numbers)."""
    library, env = sanitized_library(unzipped / "sources", SOURCE_FILES, tmp_path / "RVReducer_sanitized.so")
    host = compile_host(tmp_path / "host_sanitized", *SANITIZE)
    done = run_cycles(host, library, unzipped, bad_resources, native[1].guid, env=env)
    assert_summary(done, unzipped)
    assert_sanitizers_clean(done)


# -- a third-party FMI checker -----------------------------------------------------------


@pytest.fixture(scope="module")
def fmutool():
    """The command of fmu-manipulation-toolbox's `fmutool` (a test dependency, pyproject's
    [test] extra; it checks modelDescription.xml against the FMI 2.0 XSD schema and the
    rules the schema cannot express)."""
    import fmu_manipulation_toolbox  # noqa: F401 - fails here, not in a subprocess, if missing

    command = [sys.executable, "-c", "from fmu_manipulation_toolbox.cli.fmutool import fmutool; fmutool()"]
    return command, dict(os.environ)


def fmutool_check(fmutool, fmu):
    """fmutool's -check of the FMU file `fmu`: (its exit code, what it printed)."""
    command, env = fmutool
    done = subprocess.run(
        [*command, "-input", str(fmu), "-check"], capture_output=True, text=True, env=env, timeout=300
    )
    return done.returncode, done.stdout + done.stderr


def without_line(unzipped, tmp_path, line):
    """An FMU file made from the unzipped FMU with `line` taken out of its modelDescription.xml."""
    broken = tmp_path / "broken"
    shutil.copytree(unzipped, broken)
    description = broken / "modelDescription.xml"
    text = description.read_text()
    assert line in text
    description.write_text(text.replace(line, "", 1))
    return shutil.move(shutil.make_archive(str(broken), "zip", broken), tmp_path / "broken.fmu")


def assert_fmutool_compliant(fmutool, fmu, version):
    """The toolbox's checker passes `fmu` as compliant with FMI `version` ("2.0", "3.0"), with
    no semantic error and nothing logged as an error."""
    code, log = fmutool_check(fmutool, fmu)
    assert code == 0, log
    assert f"This FMU seems to be compliant with FMI-{version}." in log
    assert f"No semantic error against the FMI-{version[0]} standard." in log
    assert "ERROR" not in log


def test_the_fmu_manipulation_toolbox_checker_finds_it_compliant(native, unzipped, fmutool, tmp_path):
    assert_fmutool_compliant(fmutool, native[0], "2.0")
    # and it does catch what it checks: an output left out of <ModelStructure><Outputs>
    code, log = fmutool_check(fmutool, without_line(unzipped, tmp_path, '<Unknown index="7" />'))
    assert code != 0
    assert "Output 'tau_in' is not listed in <Outputs>" in log

"""Real-time factor of the reducer FMUs, pythonfmu and native, under fmpy.

What it measures: one output revolution of the RV-40E-121 with the seed 002
errors at 1600 rpm input (4.54 s simulated) with a 1 ms communication step
and a load varying between 20 % and 100 % of rated torque, run
- by fmpy's `simulate_fmu` (what a user does),
- by a bare FMI 2.0 loop through fmpy's `FMU2Slave` (set inputs, step, get outputs),
- beside the same reducer model stepped in Python without FMI, and a pass-through
  pythonfmu FMU under the same bare loop (the cost of FMI and pythonfmu alone),
for the pythonfmu FMU and the native one (`rvte fmu build --native`, the same
TE map stepped in C), plus the native FMU under the same FMI calls made from a
small C host (what a Modelica tool or Simulink sees: the FMU's own cost,
without Python's), and the time to instantiate and initialise each FMU.
Targets: the pythonfmu FMU >= 20x faster than real time (aim 100x),
instantiation under 2 s; the native FMU >= 1000x in a bare loop.  A loop
driven from Python is bounded by fmpy's per-call cost (a few microseconds a
call, three calls a step), whatever the FMU: the C host row shows the FMU.
Ratios are to the pythonfmu FMU's bare loop, run in the same process.

Run:  python studies/benchmarks/bench_fmu.py [--points N]
"""

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2True, fmi2ValueReference

from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import load_errors
from rvfmu.core.steppers.reducer_model import QuasiStaticReducer
from rvfmu.core.steppers.te_map import TEMap
from rvfmu.fmu.build import build_fmu
from rvfmu.fmu.native import build_native_fmu

ROOT = Path(__file__).resolve().parents[2]
SPEED = 1600 * 2 * np.pi / 60
STEP = 1e-3

PASS_THROUGH = """
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassThrough(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.theta_in = 0.0
        self.tau_load = 0.0
        self.theta_out = 0.0
        self.register_variable(Real("theta_in", causality=Fmi2Causality.input))
        self.register_variable(Real("tau_load", causality=Fmi2Causality.input))
        self.register_variable(Real("theta_out", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.theta_out = self.theta_in / 121.0
        return True
"""


# The bare loop of `bare_loop` in C: instantiate, then `repeats` runs over the inputs (theta_in,
# tau_load per step, float64 pairs in a file), each started by fmi2Reset; prints the seconds
# of one run (the stepping only) and the last te_arcsec.
C_LOOP = r"""
#define _POSIX_C_SOURCE 199309L   /* clock_gettime under -std=c99 */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c,
                   fmi2String m, ...) { (void)e, (void)n, (void)s, (void)c; fprintf(stderr, "%s\n", m); }

#define LOAD(f) f##TYPE *f = (f##TYPE *)dlsym(lib, #f)

int main(int argc, char **argv) {   /* library, resources URI, GUID, inputs file, steps, repeats */
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    const fmi2ValueReference in[2] = {0, 1}, out[3] = {2, 5, 6};
    int steps = atoi(argv[5]), repeats = atoi(argv[6]), k, r;
    double *u = malloc(2 * sizeof(double) * steps), h = 1e-3, y[3] = {0};
    FILE *file = fopen(argv[4], "rb");
    struct timespec t0, t1;
    fmi2Component c;
    if (argc != 7 || !lib || !u || !file || fread(u, 2 * sizeof(double), steps, file) != (size_t)steps) return 1;
    fclose(file);
    LOAD(fmi2Instantiate); LOAD(fmi2SetupExperiment); LOAD(fmi2EnterInitializationMode);
    LOAD(fmi2ExitInitializationMode); LOAD(fmi2SetReal); LOAD(fmi2GetReal); LOAD(fmi2DoStep);
    LOAD(fmi2Reset); LOAD(fmi2FreeInstance);
    if (!(c = fmi2Instantiate("bench", fmi2CoSimulation, argv[3], argv[2], &callbacks, 0, 0))) return 2;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (r = 0; r < repeats; r++) {
        fmi2Reset(c);
        fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
        fmi2EnterInitializationMode(c);
        fmi2ExitInitializationMode(c);
        for (k = 0; k < steps; k++) {
            fmi2SetReal(c, in, 2, u + 2 * k);
            if (fmi2DoStep(c, k * h, h, fmi2True) != fmi2OK) return 3;
            fmi2GetReal(c, out, 3, y);
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    printf("%.9g %a\n", ((t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec)) / repeats, y[1]);
    fmi2FreeInstance(c);
    free(u);
    return 0;
}
"""
C_RUNS = 200  # runs of the C loop: one takes a fraction of a millisecond


def load_profile(design, t):
    return -design.rated_torque * (0.6 + 0.4 * np.sin(2 * np.pi * 2.0 * t))


def bare_loop(path, times, theta, tau, outputs, arrays_once=False):
    """(instantiate + initialise [s], the steps [s], the last outputs) of set inputs, doStep,
    get outputs through fmpy's FMU2Slave; arrays_once: through its ctypes functions with the
    argument arrays made once, the least a Python loop can do per step."""
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    start = time.perf_counter()
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(path)),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bench",
    )
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    ready = time.perf_counter()
    inputs, out = [vr["theta_in"], vr["tau_load"]], [vr[n] for n in outputs]
    if arrays_once:
        refs_in, refs_out = (fmi2ValueReference * 2)(*inputs), (fmi2ValueReference * len(out))(*out)
        u, y = (fmi2Real * 2)(), (fmi2Real * len(out))()
        for t, theta_k, tau_k in zip(times.tolist(), theta.tolist(), tau.tolist()):
            u[0], u[1] = theta_k, tau_k
            fmu.fmi2SetReal(fmu.component, refs_in, 2, u)
            fmu.fmi2DoStep(fmu.component, t, STEP, fmi2True)
            fmu.fmi2GetReal(fmu.component, refs_out, len(out), y)
    else:
        for k, t in enumerate(times):
            fmu.setReal(inputs, [theta[k], tau[k]])
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=STEP)
            fmu.getReal(out)
    done = time.perf_counter()
    last = fmu.getReal(out)
    fmu.terminate()
    fmu.freeInstance()
    return ready - start, done - ready, last


def c_host_loop(path, times, theta, tau, work):
    """(seconds of one run over `times` from a C host, its last te_arcsec): `bare_loop`'s FMI
    calls and inputs from C.  None without a C compiler."""
    import fmpy

    compiler = shutil.which("cc") or shutil.which("gcc")
    if not compiler:
        return None
    md = read_model_description(str(path))
    unzipped = Path(extract(str(path)))
    (work / "loop.c").write_text(C_LOOP)
    np.column_stack([theta, tau]).astype("<f8").tofile(work / "inputs.bin")
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(
        [compiler, "-O2", "-std=c99", f"-I{headers}", str(work / "loop.c"), "-o", str(work / "loop"), "-ldl"],
        check=True,
    )
    library = unzipped / "binaries" / fmpy.platform / f"{md.coSimulation.modelIdentifier}.so"
    done = subprocess.run(
        [
            str(work / "loop"),
            str(library),
            (unzipped / "resources").as_uri(),
            md.guid,
            str(work / "inputs.bin"),
            str(times.size),
            str(C_RUNS),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    seconds, last = done.stdout.split()
    return float(seconds), float.fromhex(last)


def simulate_rows(label, path, revolution, sig, outputs):
    """fmpy's simulate_fmu from the file, then with the instance ready: two table rows."""
    rows = []
    t0 = time.perf_counter()
    simulate_fmu(str(path), stop_time=revolution, output_interval=STEP, input=sig, output=outputs)
    rows.append((f"{label}, fmpy simulate_fmu (with unzip, instantiation)", time.perf_counter() - t0))
    md = read_model_description(str(path))
    unzipped = extract(str(path))
    instance = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipped,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="sim",
    )
    instance.instantiate()
    t0 = time.perf_counter()
    simulate_fmu(
        unzipped,
        stop_time=revolution,
        output_interval=STEP,
        input=sig,
        output=outputs,
        model_description=md,
        fmu_instance=instance,
        terminate=False,
        fmi_call_logger=None,
    )
    rows.append((f"{label}, fmpy simulate_fmu (instance ready)", time.perf_counter() - t0))
    instance.freeInstance()
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=None, help="TE map points per revolution")
    args = parser.parse_args()
    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        path = build_fmu(design, errors, tmp / "RVReducer.fmu", points=args.points)
        build_time = time.perf_counter() - t0
        t0 = time.perf_counter()
        native = build_native_fmu(design, errors, tmp / "native" / "RVReducer.fmu", points=args.points)
        native_build_time = time.perf_counter() - t0
        script = tmp / "src" / "passthrough.py"
        script.parent.mkdir()
        script.write_text(PASS_THROUGH)
        from pythonfmu import FmuBuilder

        passthrough = FmuBuilder.build_FMU(script, dest=tmp / "PassThrough.fmu")

        revolution = np.ceil(2 * np.pi * design.ratio / SPEED / STEP) * STEP
        times = np.arange(0.0, revolution, STEP)
        theta, tau = SPEED * times, load_profile(design, times)
        rows = []

        sig = np.zeros(times.size, dtype=[("time", float), ("theta_in", float), ("tau_load", float)])
        sig["time"], sig["theta_in"], sig["tau_load"] = times, theta, tau
        outputs = ["theta_out", "te_arcsec", "tau_in"]
        rows += simulate_rows("reducer FMU", path, revolution, sig, outputs)
        init, run, _ = bare_loop(path, times, theta, tau, outputs)
        rows.append(("reducer FMU, bare FMI loop", run))
        rows += simulate_rows("native reducer FMU", native, revolution, sig, outputs)
        native_init, native_run, native_last = bare_loop(native, times, theta, tau, outputs)
        rows.append(("native reducer FMU, bare FMI loop", native_run))
        _, lean_run, lean_last = bare_loop(native, times, theta, tau, outputs, arrays_once=True)
        rows.append(("native reducer FMU, bare loop, fmpy's ctypes calls, arrays made once", lean_run))
        in_c = c_host_loop(native, times, theta, tau, tmp)
        if in_c:
            rows.append(("native reducer FMU, the same FMI calls from a C host", in_c[0]))
        _, pass_run, _ = bare_loop(passthrough, times, theta, tau, ["theta_out"])
        rows.append(("pass-through pythonfmu FMU, bare FMI loop", pass_run))
        with np.load(Path(extract(str(path))) / "resources" / "te_map.npz") as arrays:
            model = QuasiStaticReducer(TEMap.from_arrays(arrays))
        t0 = time.perf_counter()
        model.initialize(0.0, 0.0, tau[0])
        for k, t in enumerate(times):
            model.step(t, STEP, theta[k], tau[k])
        rows.append(("reducer model in Python, no FMI", time.perf_counter() - t0))

    baseline = rows[2][1]
    print(
        f"RV-40E-121 + seed 002 errors, one output revolution at 1600 rpm: {revolution:.3f} s "
        f"simulated, {times.size} steps of {STEP * 1e3:g} ms, load 20-100 % rated"
    )
    print(f"FMU build: {build_time:.1f} s;  instantiate + initialise: {init:.3f} s (target < 2 s)")
    print(
        f"native FMU build: {native_build_time:.1f} s;  instantiate + initialise: {native_init * 1e3:.1f} ms"
    )
    assert lean_last == native_last, (lean_last, native_last)
    if in_c:
        same = "the same" if in_c[1] == native_last[1] else f"NOT the same ({in_c[1]!r})"
        print(f"C host: {times.size} steps x {C_RUNS} runs, last te_arcsec {same} as the fmpy loop's")
    else:
        print("C host: no C compiler (cc or gcc) on PATH, its row is left out")
    width = max(len(what) for what, _ in rows)
    print(
        f"{'what':<{width}} {'steps':>6} {'time [s]':>9} {'real-time factor':>17} {'steps/s':>9} "
        f"{'ratio to bare FMU loop':>23}"
    )
    for what, seconds in rows:
        print(
            f"{what:<{width}} {times.size:>6} {seconds:>9.4g} {revolution / seconds:>16.1f}x "
            f"{times.size / seconds:>9.0f} {seconds / baseline:>23.3g}"
        )
    print("ratio: time / that of the first bare FMI loop (the pythonfmu reducer FMU's)")


if __name__ == "__main__":
    main()

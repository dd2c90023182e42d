"""Real-time factor of the reducer FMU under fmpy.

What it measures: one output revolution of the RV-40E-121 with the seed 002
errors at 1600 rpm input (4.54 s simulated) with a 1 ms communication step
and a load varying between 20 % and 100 % of rated torque, run
- by fmpy's `simulate_fmu` (what a user does),
- by a bare FMI 2.0 loop through fmpy's `FMU2Slave` (set inputs, step, get outputs),
- beside the same reducer model stepped in Python without FMI, and a pass-through
  pythonfmu FMU under the same bare loop (the cost of FMI and pythonfmu alone),
plus the time to instantiate and initialise the FMU.  Targets: >= 20x faster
than real time (aim 100x), instantiation under 2 s.

Run:  python studies/benchmarks/bench_fmu.py [--points N]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

from rvfmu.core.design import preset
from rvfmu.core.errors import load_errors
from rvfmu.core.reducer_model import QuasiStaticReducer
from rvfmu.core.te_map import TEMap
from rvfmu.fmu.build import build_fmu

ROOT = Path(__file__).resolve().parents[2]
SPEED = 1600 * 2 * np.pi / 60
STEP = 1e-3

PASS_THROUGH = '''
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
'''


def load_profile(design, t):
    return -design.rated_torque * (0.6 + 0.4 * np.sin(2 * np.pi * 2.0 * t))


def bare_loop(path, times, theta, tau, outputs):
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    start = time.perf_counter()
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    ready = time.perf_counter()
    inputs, out = [vr["theta_in"], vr["tau_load"]], [vr[n] for n in outputs]
    for k, t in enumerate(times):
        fmu.setReal(inputs, [theta[k], tau[k]])
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=STEP)
        fmu.getReal(out)
    done = time.perf_counter()
    fmu.terminate()
    fmu.freeInstance()
    return ready - start, done - ready


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
        t0 = time.perf_counter()
        simulate_fmu(str(path), stop_time=revolution, output_interval=STEP, input=sig, output=outputs)
        rows.append(("reducer FMU, fmpy simulate_fmu (with unzip, instantiation)",
                     time.perf_counter() - t0))
        md = read_model_description(str(path))
        unzipped = extract(str(path))
        instance = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName="sim")
        instance.instantiate()
        t0 = time.perf_counter()
        simulate_fmu(unzipped, stop_time=revolution, output_interval=STEP, input=sig, output=outputs,
                     model_description=md, fmu_instance=instance, terminate=False,
                     fmi_call_logger=None)
        rows.append(("reducer FMU, fmpy simulate_fmu (instance ready)", time.perf_counter() - t0))
        instance.freeInstance()
        init, run = bare_loop(path, times, theta, tau, ["theta_out", "te_arcsec", "tau_in"])
        rows.append(("reducer FMU, bare FMI loop", run))
        _, pass_run = bare_loop(passthrough, times, theta, tau, ["theta_out"])
        rows.append(("pass-through pythonfmu FMU, bare FMI loop", pass_run))
        with np.load(Path(extract(str(path))) / "resources" / "te_map.npz") as arrays:
            model = QuasiStaticReducer(TEMap.from_arrays(arrays))
        t0 = time.perf_counter()
        model.initialize(0.0, 0.0, tau[0])
        for k, t in enumerate(times):
            model.step(t, STEP, theta[k], tau[k])
        rows.append(("reducer model in Python, no FMI", time.perf_counter() - t0))

    baseline = rows[2][1]
    print(f"RV-40E-121 + seed 002 errors, one output revolution at 1600 rpm: {revolution:.3f} s "
          f"simulated, {times.size} steps of {STEP * 1e3:g} ms, load 20-100 % rated")
    print(f"FMU build: {build_time:.1f} s;  instantiate + initialise: {init:.3f} s (target < 2 s)")
    print(f"{'what':<56} {'steps':>6} {'time [s]':>9} {'real-time factor':>17} {'steps/s':>9} "
          f"{'ratio to bare FMU loop':>23}")
    for what, seconds in rows:
        print(f"{what:<56} {times.size:>6} {seconds:>9.3f} {revolution / seconds:>16.1f}x "
              f"{times.size / seconds:>9.0f} {seconds / baseline:>23.2f}")


if __name__ == "__main__":
    main()

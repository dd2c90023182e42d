"""Speed of the dynamic model: real-time factor of the Newmark integrator beside solve_ivp.

What it measures, on one core (BLAS threads set to 1 before numpy loads):
- the RV-40E-121 with the seed 002 errors at 1600 rpm input and half its rated
  load, Newmark at the default step, for `--revolutions` output revolutions
  after the start ramp (one revolution is 4.54 s simulated), with its contacts'
  friction and without (docs/model.md section 9: what friction costs);
- scipy's solve_ivp (BDF, the adaptive reference) on the first `--reference`
  seconds of the same run, and Newmark on that same interval, so the ratio
  column compares the two integrators on equal work;
- the FMU's dynamic model at a 1 ms communication step (internal steps of at most
  0.1 ms): each step one compiled call (`dynamic_reducer.communication_step`), the same
  steps as the Python calls they are made of, and through a bare fmpy FMI loop
  (`--fmu-seconds`);
- the output revolution and the FMU's model again with the element geometry built in
  numpy (`DynamicModel._chunk_numpy`, the reference the compiled one is held to);
- the same short run with the kernels as plain numpy (RVTE_NUMBA=0, in a child
  process), what a host without numba gets;
- where the Newmark time goes (cProfile, the five largest own times).
Real-time factor = simulated time / wall time.  Target: >= 1 (aim 10).  The
kernels are compiled (or loaded from numba's cache) by a warm-up run first.

Run:  python studies/benchmarks/bench_dynamic.py [--revolutions 1] [--reference 0.004]
"""

import argparse
import cProfile
import os
import pstats
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("RVTE_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[2]


def fmu_loop(design, errors, speed, load, steps, comm) -> float:
    """Seconds of a bare FMI loop (set inputs, doStep, get outputs) over the dynamic FMU."""
    import tempfile

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from rvfmu.fmu.build import build_fmu

    with tempfile.TemporaryDirectory() as tmp:
        path = build_fmu(design, errors, Path(tmp) / "R.fmu", points=624)
        md = read_model_description(str(path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=extract(str(path)),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName="bench",
        )
        fmu.instantiate()
        fmu.setString([vr["model"]], ["dynamic"])
        fmu.setReal([vr["tau_load"]], [-load])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.setReal([vr["theta_in"], vr["tau_load"]], [speed * comm, -load])
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=comm)  # loads the kernels
        start = time.perf_counter()
        for k in range(1, steps + 1):
            fmu.setReal([vr["theta_in"], vr["tau_load"]], [speed * (k + 1) * comm, -load])
            fmu.doStep(currentCommunicationPoint=k * comm, communicationStepSize=comm)
            fmu.getReal([vr["te"], vr["tau_in"]])
        seconds = time.perf_counter() - start
        fmu.terminate()
        fmu.freeInstance()
    return seconds


def plain_numpy(load, seconds):
    """(label, steps, simulated, wall) of a Newmark run with the kernels as plain numpy."""
    import json
    import subprocess
    import sys

    script = (
        "import json, sys, time\n"
        "from rvfmu.core.dynamics import kernels\n"
        "from rvfmu.core.reducer.design import preset\n"
        "from rvfmu.core.reducer.errors import load_errors\n"
        "from rvfmu.core.dynamics.simulation import simulate\n"
        "assert not kernels.COMPILED\n"
        "d = preset('RV-40E-121'); e = load_errors(sys.argv[1], d)\n"
        "t = time.perf_counter()\n"
        "s = simulate(d, e, speed_rpm=1600.0, load=float(sys.argv[2]), duration=float(sys.argv[3]),"
        " ramp=float(sys.argv[3]))\n"
        "print(json.dumps([s.time.size - 1, float(s.time[-1]), time.perf_counter() - t]))\n"
    )
    env = dict(os.environ, RVTE_NUMBA="0")
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            script,
            str(ROOT / "studies" / "seed002_errors.toml"),
            str(load),
            str(seconds),
        ],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    steps, simulated, wall = json.loads(out.strip().splitlines()[-1])
    return ("Newmark, plain numpy (no numba)", steps, simulated, wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--revolutions", type=float, default=1.0)
    parser.add_argument(
        "--reference", type=float, default=0.004, help="seconds at speed for the solve_ivp comparison"
    )
    parser.add_argument("--fmu-seconds", type=float, default=0.2, help="simulated seconds of the FMU rows")
    parser.add_argument(
        "--plain", type=float, default=0.02, help="seconds at speed (and of ramp) of the plain-numpy row"
    )
    args = parser.parse_args()

    from rvfmu.core.dynamics.dynamic import DynamicModel
    from rvfmu.core.dynamics.simulation import simulate
    from rvfmu.core.reducer.design import preset
    from rvfmu.core.reducer.errors import load_errors

    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    load = design.rated_torque / 2
    rows = []

    def run(label, **options):
        start = time.perf_counter()
        sim = simulate(design, errors, speed_rpm=1600.0, load=load, **options)
        seconds = time.perf_counter() - start
        rows.append((label, sim.time.size - 1, sim.time[-1], seconds))
        return sim

    short = dict(duration=args.reference, ramp=args.reference)
    simulate(design, errors, speed_rpm=1600.0, load=load, **short)  # warm-up: compile
    run("Newmark, short run", **short)
    run("solve_ivp BDF, short run", method="BDF", **short)
    full = run(f"Newmark, {args.revolutions:g} output rev", revolutions=args.revolutions)
    run("  the same without friction", revolutions=args.revolutions, friction=False)
    DynamicModel.compiled_geometry = False
    run("  the same, geometry in numpy", revolutions=args.revolutions)
    DynamicModel.compiled_geometry = True

    # the FMU's model: 1 ms communication steps, internal steps of at most 0.1 ms; each step one
    # compiled call, then the same steps as the Python calls they are made of, then those with
    # the geometry in numpy
    from rvfmu.core.base.compiled import COMPILED
    from rvfmu.core.steppers import dynamic_reducer
    from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

    speed = 1600 * 2 * 3.141592653589793 / 60
    comm, steps = 1e-3, int(args.fmu_seconds / 1e-3)
    for label, one_call, compiled in (
        ("FMU model, 1 ms comm (one call)", True, True),
        ("  the same, the step in Python", False, True),
        ("  the same, geometry in numpy", False, False),
    ):
        DynamicModel.compiled_geometry = compiled
        dynamic_reducer.COMPILED = COMPILED and one_call and compiled
        reducer = DynamicReducer(design, errors)
        reducer.initialize(0.0, 0.0, -load)
        reducer.step(0.0, comm, speed * comm, -load)  # warm-up: loads this route's kernels
        start = time.perf_counter()
        for k in range(1, steps + 1):
            reducer.step(k * comm, comm, speed * (k + 1) * comm, -load)
        rows.append((label, steps * 10, steps * comm, time.perf_counter() - start))
    DynamicModel.compiled_geometry = True
    dynamic_reducer.COMPILED = COMPILED
    rows.append(
        (
            "FMU, bare fmpy loop, 1 ms comm",
            steps * 10,
            steps * comm,
            fmu_loop(design, errors, speed, load, steps, comm),
        )
    )
    rows.append(plain_numpy(load, args.plain))
    # where the time goes: the output revolution again, under the profiler (its overhead kept
    # out of the rows above)
    profiler = cProfile.Profile()
    profiler.enable()
    simulate(design, errors, speed_rpm=1600.0, load=load, revolutions=args.revolutions)
    profiler.disable()

    print(
        f"RV-40E-121, seed 002 errors, 1600 rpm, load {load:g} N*m, step "
        f"{full.step * 1e6:.1f} us, {full.failed_steps} unconverged steps"
    )
    base = rows[1][3] / rows[1][2]
    print(
        f"{'what':<32} {'steps':>7} {'simulated [s]':>14} {'wall [s]':>9} {'steps/s':>9} "
        f"{'real-time x':>12} {'ratio':>7}"
    )
    for label, steps, simulated, seconds in rows:
        per = seconds / simulated
        print(
            f"{label:<32} {steps:>7} {simulated:>14.4f} {seconds:>9.2f} {steps / seconds:>9.0f} "
            f"{simulated / seconds:>12.3f} {base / per:>7.1f}"
        )
    print("\nwhere the Newmark time goes (own time, largest five):")
    stats = pstats.Stats(profiler)
    total = sum(v[2] for v in stats.stats.values())
    top = sorted(stats.stats.items(), key=lambda item: -item[1][2])[:5]
    for (filename, line, name), values in top:
        print(f"  {100 * values[2] / total:5.1f} %  {name} ({Path(filename).name}:{line})")


if __name__ == "__main__":
    main()

"""Benchmark: the dynamic FMU's model at longer internal steps, its speed against its accuracy.

The dynamic model (`rvfmu.core.steppers.dynamic_reducer.DynamicReducer`, the
FMU's `model = "dynamic"`) integrates each 1 ms communication step in
internal Newmark steps of at most `internal_step` (default
DEFAULT_INTERNAL_STEP, 0.1 ms).  Would a longer one give the real-time factor
a host wants, and at what error?  This script runs the RV-40E-121 with the
seed 002 errors, ramped to --rpm over 50 ms and held there, at no load and at
half its rated torque, for --seconds simulated, at internal steps from 0.05 to
1 ms, and compares each TE and input torque (means over each communication
step, as the FMU gives them) with a run at 0.01 ms (the reference) after the
first 0.1 s.  Speed: simulated over wall time, the model stepped in Python as
the FMU steps it (no FMI calls), BLAS on one thread.

    python studies/benchmarks/bench_internal_step.py [--rpm 1600] [--seconds 0.3]

Prints one table: load, internal step, internal steps per communication step,
the largest and the RMS difference of TE from the reference [arcsec], the
largest difference of the input torque [N m], the real-time factor, and the
speed as a ratio to the default step's, run in the same process.
"""

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from rvfmu.core.base.units import rad_to_arcsec  # noqa: E402
from rvfmu.core.reducer.design import preset  # noqa: E402
from rvfmu.core.reducer.errors import load_errors  # noqa: E402
from rvfmu.core.steppers.dynamic_reducer import DEFAULT_INTERNAL_STEP, DynamicReducer  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
COMM = 1e-3  # [s] the communication step
RAMP = 0.05  # [s] to full speed at constant acceleration
SETTLE = 0.1  # [s] compared after this
REFERENCE = 1e-5  # [s] the reference's internal step
STEPS = (5e-5, 1e-4, 2e-4, 2.5e-4, 5e-4, 1e-3)


def run(design, errors, h: float, load: float, speed: float, seconds: float):
    """(TE [arcsec], tau_in [N m], wall [s]) at each communication step of a run at internal
    step h under a resisting load [N m]."""
    reducer = DynamicReducer(design, errors, internal_step=h)
    reducer.initialize(0.0, 0.0, -load)
    steps = int(round(seconds / COMM))
    te, tau = np.empty(steps), np.empty(steps)
    clock = time.perf_counter()
    for k in range(steps):
        t = (k + 1) * COMM
        theta = speed * t * t / (2 * RAMP) if t < RAMP else speed * (t - RAMP / 2)
        out = reducer.step(k * COMM, COMM, theta, -load)
        te[k], tau[k] = out.te, out.tau_in
    return rad_to_arcsec(te), tau, time.perf_counter() - clock


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rpm", type=float, default=1600.0)
    parser.add_argument("--seconds", type=float, default=0.3)
    args = parser.parse_args(argv)
    if not args.seconds > SETTLE + 0.05:
        raise SystemExit(
            f"--seconds {args.seconds}: must be above {SETTLE + 0.05} (compared after {SETTLE} s)"
        )
    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    speed = args.rpm * 2 * np.pi / 60
    run(design, errors, 1e-3, 0.0, speed, 0.01)  # loads the compiled kernels
    print(f"# bench_internal_step: RV-40E-121, seed 002 errors, {args.rpm:g} rpm, {args.seconds:g} s")
    print(
        "| load [N m] | internal step [ms] | steps per 1 ms | max dTE [arcsec] | RMS dTE [arcsec] | "
        "max d tau_in [N m] | x real time | speed / default's |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for load in (0.0, design.rated_torque / 2):
        ref_te, ref_tau, _ = run(design, errors, REFERENCE, load, speed, args.seconds)
        window = slice(int(round(SETTLE / COMM)), None)
        rows, default_rate = [], None
        for h in STEPS:
            te, tau, wall = run(design, errors, h, load, speed, args.seconds)
            rate = args.seconds / wall
            if h == DEFAULT_INTERNAL_STEP:
                default_rate = rate
            d = te[window] - ref_te[window]
            rows.append(
                (h, np.max(np.abs(d)), np.sqrt(np.mean(d**2)), np.max(np.abs(tau - ref_tau)[window]), rate)
            )
        for h, dmax, drms, dtau, rate in rows:
            mark = " (default)" if h == DEFAULT_INTERNAL_STEP else ""
            print(
                f"| {load:.0f} | {h * 1e3:g}{mark} | {COMM / h:g} | {dmax:.4f} | {drms:.4f} | {dtau:.4f} | "
                f"{rate:.2f} | {rate / default_rate:.2f} |"
            )
        print(
            f"| {load:.0f} | reference {REFERENCE * 1e3:g} | {COMM / REFERENCE:g} | TE peak to peak "
            f"{np.ptp(ref_te[window]):.3f} | | tau_in mean {ref_tau[window].mean():.3f} | | |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

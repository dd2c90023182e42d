"""What the windup test costs a study: the whole catalogue test against the torques its metrics read.

Lost motion reads the windup at +-3 % of rated torque, the torsional rigidity at +-50 % and
+-100 %; the catalogue test (`quasistatic.catalogue_torques`) solves twelve torques, and each
is a separate equilibrium.  The studies (`tolerance.evaluate`) and the calibration solve the
six they read (`quasistatic.metric_torques`).  Both ways run here, in this process on every
core, on the same batches of `--reducers` reducers at 8 positions:

- studies/quick_mc.toml's reducers (the calibrated RV-40E-121 with seed 002's tolerances,
  crank bearings on the roller law, no bearing clearance);
- studies/rv40e_121_full.toml's (every bearing clearance drawn as well).

Each time is the best of `--repeats` runs after one that compiles; the ratio is the whole
test's time over the six torques'.  The last column is the largest difference of lost
motion and rigidity between the two, relative to the value: the benchmark stops with an
error if it is not zero to round-off.

Run:  python studies/benchmarks/bench_windup.py [--reducers 64] [--repeats 3]
"""

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def best_of(job, repeats):
    result = job()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        job()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.statics.quasistatic import catalogue_torques, metric_torques, windup
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    print(f"machine: {machine()}")
    print(
        f"{'study':<22} {'torques':<26} {'size':>14} {'time [s]':>9} {'reducers/s':>11} "
        f"{'ratio':>6} {'largest rel. difference':>24}"
    )
    for name in ("quick_mc.toml", "rv40e_121_full.toml"):
        study = load_study(ROOT / "studies" / name)
        design = study.design
        errors = errors_from_unit(study, sample(study, args.reducers))
        size = f"{args.reducers} x {study.windup_positions} pos."
        rows = []
        for label, torques in (
            ("catalogue test (12)", catalogue_torques(design)),
            ("the metrics' torques (6)", metric_torques(design)),
        ):
            seconds, w = best_of(
                lambda t=torques: windup(design, errors, t, positions=study.windup_positions), args.repeats
            )
            rows.append((label, seconds, w.lost_motion_arcmin(), w.torsional_rigidity_Nm_per_arcmin()))
        base = rows[0][1]
        for label, seconds, lost, rigid in rows:
            diff = max(
                float(np.max(np.abs(lost - rows[0][2]) / np.abs(rows[0][2]))),
                float(np.max(np.abs(rigid - rows[0][3]) / np.abs(rows[0][3]))),
            )
            if diff > 1e-12:
                raise SystemExit(f"{name}: {label} differs from the catalogue test by {diff:.3g}")
            print(
                f"{name:<22} {label:<26} {size:>14} {seconds:>9.3f} {args.reducers / seconds:>11.1f} "
                f"{base / seconds:>6.2f} {diff:>24.2g}"
            )


if __name__ == "__main__":
    main()

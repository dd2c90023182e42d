"""What the Python around the compiled Newton iteration costs a study's batch, before and after.

A batch of a study solves every (reducer, angle) pair in the compiled iteration, which
splits them over the cores, and around it, in numpy under Python's lock, builds each
pair's element offsets, finds the kinematic no-load pose and, after the solve, computes the
pins' and meshes' forces.  Three of those parts changed, and their old routes are kept:

- the pins' offsets (`EquivalentModel.offsets`) by the compiled `pin_offsets`, pair by pair,
  instead of a (B, 4, 2, z_p) gather and its numpy arithmetic (`compiled_pins`; the same
  values to the bit);
- the kinematic no-load pose's first pin by the compiled `first_pin` instead of numpy
  (`ReducedSystem.compiled_first_pin`; the same pose to round-off);
- the studies ask for the TE alone (`te_curve(..., forces=False)`, and the windup test never
  reads its forces): no pin and mesh forces after each solve (the same TE to the bit).

Both ways run here, in this process on every core, on the same `--reducers` reducers of each
study (a quarter of them for the complete study, at 720 points instead of its 3200), with the
study's outputs (the TE curve, and the windup test at its positions where it asks for lost
motion): "numpy parts, with forces" is the route of before, "compiled parts, TE alone" the one
`tolerance.evaluate` takes now.  Each time is the best of `--repeats` runs, the two routes
taking turns, after one run of each that compiles; wall and CPU time (this process, every
thread).  The ratio is the old route's wall time over the new one's.  The last column is the
largest difference of the TE between the two [arcsec]: the benchmark stops with an error
above 1e-9.

Run:  python studies/benchmarks/bench_batch_parts.py [--reducers 64] [--repeats 5]
"""

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
# (study, points (None: the study's), share of --reducers): the complete study at 720 points and
# a quarter of the reducers, for its continuation over the bearings' clearances costs ~10x
STUDIES = (("quick_mc.toml", None, 1), ("rv40e_121_sobol.toml", None, 1), ("rv40e_121_full.toml", 720, 4))


def best_of_both(jobs, repeats):
    """For each job, (best (wall, CPU) [s] of `repeats` runs, its result), the jobs taking turns
    run by run so that a machine's drift falls on both alike; one run of each first (compiles)."""
    results = [job() for job in jobs]
    best = [(np.inf, np.inf)] * len(jobs)
    for _ in range(repeats):
        for k, job in enumerate(jobs):
            wall, cpu = time.perf_counter(), time.process_time()
            job()
            best[k] = min(best[k], (time.perf_counter() - wall, time.process_time() - cpu))
    return list(zip(best, results))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.quasistatic import (
        equilibrium_te,
        metric_torques,
        te_curve,
        windup,
        windup_positions,
    )
    from rvfmu.core.statics.solver import ReducedSystem
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    def numpy_parts(flag: bool) -> None:
        EquivalentModel.compiled_pins = not flag
        ReducedSystem.compiled_first_pin = not flag

    print(f"machine: {machine()}")
    print(
        f"{'study':<22} {'route':<30} {'size':>16} {'wall [s]':>9} {'CPU [s]':>8} "
        f"{'reducers/s':>11} {'ratio':>6} {'largest TE diff. [arcsec]':>26}"
    )
    for name, points, share in STUDIES:
        study = load_study(ROOT / "studies" / name)
        points = points or study.points
        design, load = study.design, -study.load_Nm
        reducers = max(1, args.reducers // share)
        errors = errors_from_unit(study, sample(study, reducers))
        windup_too = "lost_motion" in study.metrics
        size = f"{reducers} x {points} pts"

        positions = windup_positions(design, study.windup_positions)

        def before():
            numpy_parts(True)
            try:
                curve = te_curve(design, errors, load, points, forces=True)
                if windup_too:
                    equilibrium_te(design, errors, positions, metric_torques(design), forces=True)
                return curve.te_arcsec
            finally:
                numpy_parts(False)

        def after():  # what `tolerance.evaluate.outputs` solves
            curve = te_curve(design, errors, load, points, forces=False)
            if windup_too:
                windup(design, errors, metric_torques(design), positions=study.windup_positions)
            return curve.te_arcsec

        labels = ("numpy parts, with forces", "compiled parts, TE alone")
        timed = best_of_both((before, after), args.repeats)
        rows = [(label, wall, cpu, te) for label, ((wall, cpu), te) in zip(labels, timed)]
        reference, base = rows[0][3], rows[0][1]
        differences = [float(np.max(np.abs(row[3] - reference))) for row in rows]
        if max(differences) > 1e-9:
            raise SystemExit(f"{name}: the routes' TE differ by {max(differences):.3g} arcsec")
        for (label, wall, cpu, _), diff in zip(rows, differences):
            print(
                f"{name:<22} {label:<30} {size:>16} {wall:>9.3f} {cpu:>8.3f} "
                f"{reducers / wall:>11.1f} {base / wall:>6.2f} {diff:>26.2g}"
            )


if __name__ == "__main__":
    main()

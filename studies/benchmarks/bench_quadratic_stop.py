"""The compiled Newton iteration's quadratic stop, against ending every pair on a step that no
longer moves: Newton steps, time and TE of a study's batch.

The compiled iteration (`newton_kernel.newton_pairs`) ended a pair when its Newton step
moved less than `newton.STEP_TOLERANCE` (1e-14 m): in Newton's quadratic phase that is one
evaluation after a step of some 1e-10 m, whose only news is that nothing moves any more.
With `newton.QUADRATIC_CAP` it ends the pair on a step below the cap after a full one where
the two steps' quadratic convergence puts the next below a tenth of the tolerance, without
that evaluation.  `QUADRATIC_CAP = None` is the route of before, kept as the reference.

Both routes run here, in this process on every core, on the same `--reducers` reducers of
each study (a quarter of them for the complete study, at 720 points instead of its 3200),
with what `tolerance.evaluate` solves: the TE curve at the study's load without forces, and
the windup test at its positions where the study asks for lost motion.  Each time is the
best of `--repeats` runs, the two routes taking turns, after one run of each that compiles;
wall and CPU time (this process, every thread).  "steps/pair" is the mean number of Newton
steps over every pair the iteration solved (TE curve and windup test).  The ratio is the old
route's wall time over the new one's.  The last columns: the largest difference of the TE
and of te_pp between the routes [arcsec]; the benchmark stops with an error above 1e-6
(the TE) or 1e-8 (te_pp).

Run:  python studies/benchmarks/bench_quadratic_stop.py [--reducers 64] [--repeats 5]
"""

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
# (study, points (None: the study's), share of --reducers): the complete study at 720 points and
# a quarter of the reducers, for its continuation over the bearings' clearances costs ~10x
STUDIES = (("quick_mc.toml", None, 1), ("rv40e_121_sobol.toml", None, 1), ("rv40e_121_full.toml", 720, 4))


class StepCount:
    """Counts the Newton steps of every pair the compiled iteration solves while installed."""

    def __init__(self, kernel_module):
        self.module, self.pairs, self.steps = kernel_module, 0, 0

    def __enter__(self):
        inner = self.original = self.module.newton_pairs

        def counted(*args):
            inner(*args)
            iterations = args[-1]
            self.pairs += iterations.size
            self.steps += int(iterations.sum())

        self.module.newton_pairs = counted
        return self

    def __exit__(self, *exc):
        self.module.newton_pairs = self.original


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    from bench_batch_parts import best_of_both
    from bench_jobs import machine

    from rvfmu.core.statics import newton, newton_kernel
    from rvfmu.core.statics.metrics import te_pp
    from rvfmu.core.statics.quasistatic import metric_torques, te_curve, windup
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    cap = newton.QUADRATIC_CAP
    print(f"machine: {machine()}")
    print(
        f"{'study':<22} {'route':<34} {'size':>16} {'wall [s]':>9} {'CPU [s]':>8} {'steps/pair':>10} "
        f"{'reducers/s':>11} {'ratio':>6} {'TE diff. [″]':>13} {'te_pp diff. [″]':>16}"
    )
    for name, points, share in STUDIES:
        study = load_study(ROOT / "studies" / name)
        points = points or study.points
        design, load = study.design, -study.load_Nm
        reducers = max(1, args.reducers // share)
        errors = errors_from_unit(study, sample(study, reducers))
        windup_too = "lost_motion" in study.metrics
        size = f"{reducers} x {points} pts"

        def solve(stop):
            def job():
                newton.QUADRATIC_CAP = stop
                try:
                    curve = te_curve(design, errors, load, points, forces=False)
                    if windup_too:
                        windup(design, errors, metric_torques(design), positions=study.windup_positions)
                    return curve.te_arcsec
                finally:
                    newton.QUADRATIC_CAP = cap

            return job

        labels = ("step below the tolerance (before)", f"quadratic stop, cap {cap:g} m")
        routes = (solve(None), solve(cap))
        steps = []
        for route in routes:
            with StepCount(newton_kernel) as count:
                route()
            steps.append(count.steps / count.pairs)
        timed = best_of_both(routes, args.repeats)
        rows = [(label, wall, cpu, te) for label, ((wall, cpu), te) in zip(labels, timed)]
        reference, base = rows[0][3], rows[0][1]
        te_diff = [float(np.max(np.abs(row[3] - reference))) for row in rows]
        pp_diff = [float(np.max(np.abs(te_pp(row[3]) - te_pp(reference)))) for row in rows]
        if max(te_diff) > 1e-4 or max(pp_diff) > 1e-6:
            raise SystemExit(
                f"{name}: the routes differ by {max(te_diff):.3g} (TE), {max(pp_diff):.3g} (te_pp)"
            )
        for (label, wall, cpu, _), mean_steps, d_te, d_pp in zip(rows, steps, te_diff, pp_diff):
            print(
                f"{name:<22} {label:<34} {size:>16} {wall:>9.3f} {cpu:>8.3f} {mean_steps:>10.2f} "
                f"{reducers / wall:>11.1f} {base / wall:>6.2f} {d_te:>13.2g} {d_pp:>16.2g}"
            )


if __name__ == "__main__":
    main()

"""Where the roller law's no-load solve starts: the kinematic pose against the elastic solve.

Without bearing clearance, the no-load TE with the crank bearings on their roller law is one
Newton solve under 1e-3 x the probe torque, started from the no-load limit with the stated
stiffnesses (docs/model.md section 6).  That limit is the kinematic pose: the linear parts
take the shape the errors force on them, the carrier turns until the first pin touches.
Where errors preload the discs, that pose leaves pins in interference, and the reference
route (`solve_pairs(law_start="elastic")`) first removes it by an elastic solve with the
stated stiffnesses, taken back to zero load.  The energy is convex, so the law's solve reaches
the same minimiser from the kinematic pose itself (`law_start="kinematic"`, the default).

The same `--reducers` reducers of studies/quick_mc.toml (the calibrated RV-40E-121, seed 002's
tolerances, no load) at 720 points per output revolution, solved by both routes in this
process; each time is the best of `--repeats` runs after one that compiles.  Printed: the
time, the throughput, the Newton steps of all solves, the ratio to the reference and the
largest difference of TE between the two routes.

    python studies/benchmarks/bench_no_load_start.py [--reducers 64] [--repeats 3]
"""

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
POINTS = 720


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from bench_jobs import machine
    from rvfmu.core import newton_kernel, solver
    from rvfmu.core.equivalent import EquivalentModel
    from rvfmu.core.quasistatic import NO_LOAD_PROBE, input_angles
    from rvfmu.core.units import ARCSEC
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    design = study.design
    errors = errors_from_unit(study, sample(study, args.reducers))
    model = EquivalentModel(design, input_angles(design, POINTS), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(errors.samples), np.arange(POINTS),
                                           indexing="ij"))
    zero = np.zeros(s.size)
    probe = NO_LOAD_PROBE * design.rated_torque

    steps = []
    solve_pairs_kernel = newton_kernel.newton_pairs

    def counted(*arguments):
        solve_pairs_kernel(*arguments)
        steps.append(int(arguments[-1].sum()))      # the kernel's iterations (B,), filled in

    def run(start):
        steps.clear()
        began = time.perf_counter()
        eq = solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, law_start=start)
        return time.perf_counter() - began, eq, sum(steps)

    newton_kernel.newton_pairs = counted
    try:
        results = {}
        for start in ("elastic", "kinematic"):          # the reference first
            run(start)
            best = min((run(start) for _ in range(args.repeats)), key=lambda r: r[0])
            results[start] = best
    finally:
        newton_kernel.newton_pairs = solve_pairs_kernel

    te = {k: model.output_angle(eq.q, zero) / ARCSEC for k, (_, eq, _) in results.items()}
    reference = results["elastic"][0]
    print(f"machine: {machine()}")
    print(f"{'what':<44} {'size':>16} {'time [s]':>9} {'throughput':>16} {'Newton steps':>13} "
          f"{'ratio':>6}")
    for start, label in (("elastic", "law from the elastic solve (reference)"),
                         ("kinematic", "law from the kinematic pose")):
        seconds, eq, count = results[start]
        assert eq.converged.all(), f"{start}: not every pair converged"
        print(f"{label:<44} {f'{args.reducers} x {POINTS} pts':>16} {seconds:>9.3f} "
              f"{args.reducers / seconds:>9.1f} red./s {count:>13d} {seconds / reference:>6.2f}")
    print(f"largest |TE difference|: {np.max(np.abs(te['kinematic'] - te['elastic'])):.2e} arcsec "
          f"(TE spread {np.ptp(te['elastic']):.2f} arcsec)")


if __name__ == "__main__":
    main()

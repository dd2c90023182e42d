"""The roller law's no-load solve: where it starts, and how its weak springs let go.

Without bearing clearance, the no-load TE with the crank bearings on their roller law is one
Newton solve under 1e-3 x the probe torque, started from the no-load limit with the stated
stiffnesses (docs/model.md section 6).  That limit is the kinematic pose: the linear parts
take the shape the errors force on them, the carrier turns until the first pin touches.
Where errors preload the discs, that pose leaves pins in interference, and the reference
route (`solve_pairs(law_start="elastic")`) first removes it by an elastic solve with the
stated stiffnesses, taken back to zero load.  The energy is convex, so the law's solve reaches
the same minimiser from the kinematic pose itself (`law_start="kinematic"`, the default).
Then the weak springs that keep the parts determinate let go: by a solve with them centred on
the solution (`law_release="solve"`, the reference), or by the one Newton step that solve's
first step is, taken in the compiled iteration with the Hessian it has factored at the
solution (`law_release="step"`, the default; `newton.release_step`).

The same `--reducers` reducers of studies/quick_mc.toml (the calibrated RV-40E-121, seed 002's
tolerances, no load) at 720 points per output revolution, solved by both routes in this
process by three routes; each time is the best of `--repeats` runs after one that compiles.
Printed: the time, the throughput, the Newton steps of all solves, the ratio to the reference
(the elastic start, the release solved), and the largest difference of each route's TE and
te_pp from the reference's.

    python studies/benchmarks/bench_no_load_start.py [--reducers 64] [--repeats 3]
"""

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
POINTS = 720


def no_load_pairs(study_file: str, reducers: int, points: int):
    """(model, errors, sample, angle, zero, probe): every (reducer, angle) pair of the first
    `reducers` Monte Carlo reducers of studies/<study_file> at `points` per revolution, at no
    load, with the probe torque the solver takes there."""
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.quasistatic import NO_LOAD_PROBE, input_angles
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / study_file)
    design = study.design
    errors = errors_from_unit(study, sample(study, reducers))
    model = EquivalentModel(design, input_angles(design, points), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(errors.samples), np.arange(points), indexing="ij"))
    return model, errors, s, a, np.zeros(s.size), NO_LOAD_PROBE * design.rated_torque


@contextlib.contextmanager
def counted_steps():
    """A list that receives the Newton steps of every call of the compiled iteration
    (`newton_kernel.newton_pairs`) while the block runs."""
    from rvfmu.core.statics import newton_kernel

    steps = []
    kernel = newton_kernel.newton_pairs
    at = newton_kernel.newton_pairs_argument("iterations")

    def counted(*arguments):
        kernel(*arguments)
        steps.append(int(arguments[at].sum()))  # the kernel's iterations (B,), filled in

    newton_kernel.newton_pairs = counted
    try:
        yield steps
    finally:
        newton_kernel.newton_pairs = kernel


def route_columns(width: int) -> str:
    """The header of a route's leading columns (`route_cells`), its label `width` wide."""
    return (
        f"{'route':<{width}} {'size':>16} {'time [s]':>9} {'throughput':>16} {'Newton steps':>13} "
        f"{'ratio':>6}"
    )


def route_cells(label, width, size, seconds, reducers, steps, reference_seconds, eq) -> str:
    """A route's leading columns: label, size, time, reducers per second, Newton steps, and the
    ratio to the reference's time; every pair of the route must have converged."""
    assert eq.converged.all(), f"{label}: not every pair converged"
    return (
        f"{label:<{width}} {size:>16} {seconds:>9.3f} {reducers / seconds:>9.2f} red./s {steps:>13d} "
        f"{seconds / reference_seconds:>6.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.base.units import ARCSEC
    from rvfmu.core.statics import solver

    model, errors, s, a, zero, probe = no_load_pairs("quick_mc.toml", args.reducers, POINTS)

    def run(route):
        steps.clear()
        began = time.perf_counter()
        eq = solver.solve_pairs(
            model, errors, s, a, zero, no_load_probe=probe, law_start=route[0], law_release=route[1]
        )
        return time.perf_counter() - began, eq, sum(steps)

    routes = (
        (("elastic", "solve"), "elastic start, release solved (reference)"),
        (("kinematic", "solve"), "kinematic start, release solved"),
        (("kinematic", "step"), "kinematic start, release by one step"),
    )
    with counted_steps() as steps:
        results = {}
        for route, _ in routes:  # the reference first
            run(route)
            results[route] = min((run(route) for _ in range(args.repeats)), key=lambda r: r[0])

    te = {
        k: (model.output_angle(eq.q, zero) / ARCSEC).reshape(args.reducers, POINTS)
        for k, (_, eq, _) in results.items()
    }
    reference = routes[0][0]
    print(f"machine: {machine()}")
    print(f"{route_columns(44)} {'max |dTE| [arcsec]':>19} {'max |d te_pp|':>14}")
    for route, label in routes:
        seconds, eq, count = results[route]
        d_te = np.max(np.abs(te[route] - te[reference]))
        d_pp = np.max(np.abs(np.ptp(te[route], axis=1) - np.ptp(te[reference], axis=1)))
        cells = route_cells(
            label,
            44,
            f"{args.reducers} x {POINTS} pts",
            seconds,
            args.reducers,
            count,
            results[reference][0],
            eq,
        )
        print(f"{cells} {d_te:>19.2e} {d_pp:>14.2e}")
    print(f"(the reference's TE spans {np.ptp(te[reference]):.2f} arcsec)")


if __name__ == "__main__":
    main()

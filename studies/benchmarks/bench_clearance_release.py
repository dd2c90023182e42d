"""The no-load limit with bearing clearances: where its weak springs let go.

With bearing clearances the no-load TE is reached by continuation: a solve at 10 probe
torques, one at the probe, and the step back to zero load along the tangent (or the chord
through the two; docs/model.md section 5).  Weak springs hold the parts that float in their
clearances; solves with the springs re-centred on the last solution let them go.  The
reference route (`solve_pairs(clearance_release="every")`) takes three such solves at each of
the two probe loads: eight solves a point.  The default (`clearance_release="probe"`) lets go
at the probe alone, by the same three solves (five a point): the solve at 10 probes only
starts the probe's and anchors the chord.

A third route leaves the solve at 10 probes out (`ReducedSystem._probe_steps` made the probe
alone).  The probe's solve has one minimiser, the weak springs being centred at zero (printed:
the largest difference of the probe's released equilibrium from the default's, each route
solved again on one thread so that the chunks come in order); but without a second probe load
there is no chord back to zero load, and the tangent alone is followed everywhere.

The routes run here, in this process on every core, on the same `--reducers` reducers of
studies/rv40e_121_full.toml (the calibrated RV-40E-121, its 15 tolerances with the three
bearing clearances, no load, 3200 points), and so does a yardstick that neither route is: the
reference's continuation with RELEASE_ROUNDS = `--converged` solves at each load, where the
springs have let go further than either route takes them.  Each time is the best of
`--repeats` runs after one that compiles.  Printed: the time, the throughput, the Newton steps
of all solves, the ratio to the reference, and each route's largest, 99.9th-percentile and
median difference of the TE and the largest of te_pp from the reference and from the
yardstick.

    python studies/benchmarks/bench_clearance_release.py [--reducers 32] [--repeats 2] [--converged 12]
"""

import argparse
import os
import time
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=32)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--converged", type=int, default=12, help="release solves of the yardstick")
    args = parser.parse_args()
    if args.reducers < 1 or args.repeats < 1 or args.converged < 4:
        parser.error("--reducers and --repeats must be >= 1, --converged >= 4")

    from bench_jobs import machine
    from bench_no_load_start import counted_steps, no_load_pairs, route_cells, route_columns

    from rvfmu.core.base.units import ARCSEC
    from rvfmu.core.statics import solver
    from tolerance.study import load_study

    points = load_study(ROOT / "studies" / "rv40e_121_full.toml").points
    model, errors, s, a, zero, probe = no_load_pairs("rv40e_121_full.toml", args.reducers, points)

    continued = solver.ReducedSystem._probe_steps

    def run(release, rounds, continuation=True):
        kept = solver.RELEASE_ROUNDS
        solver.RELEASE_ROUNDS = rounds
        if not continuation:
            solver.ReducedSystem._probe_steps = lambda self: (1.0,)
        steps.clear()
        try:
            began = time.perf_counter()
            eq = solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, clearance_release=release)
            return time.perf_counter() - began, eq, sum(steps)
        finally:
            solver.RELEASE_ROUNDS = kept
            solver.ReducedSystem._probe_steps = continued

    def at_probe(route):
        """The released equilibria at the probe (pairs, nN) of `route`, in the pairs' order."""
        found = []
        back = solver.ReducedSystem._back_to_zero

        def recorded(self, group, angle, f0, pin_b, brg_off, c_half, path, depth=0):
            found.append(path[-1][1])
            return back(self, group, angle, f0, pin_b, brg_off, c_half, path, depth)

        with (
            mock.patch.dict(os.environ, {"RVTE_THREADS": "1"}),
            mock.patch.object(solver.ReducedSystem, "_back_to_zero", recorded),
        ):
            run(*route)
        return np.concatenate(found)

    rounds = solver.RELEASE_ROUNDS
    routes = (
        (("every", rounds), f"{rounds} release solves at 10 probes and at the probe (reference)"),
        (("probe", rounds), f"{rounds} release solves at the probe alone"),
        (("probe", rounds, False), "the same without the solve at 10 probes: tangent alone"),
        (("every", args.converged), f"yardstick: {args.converged} release solves at each load"),
    )
    with counted_steps() as steps:
        results = {}
        for route, _ in routes:
            run(*route)  # compiles
            results[route] = min((run(*route) for _ in range(args.repeats)), key=lambda r: r[0])

    te = {
        k: (model.output_angle(eq.q, zero) / ARCSEC).reshape(args.reducers, points)
        for k, (_, eq, _) in results.items()
    }
    reference, yardstick = routes[0][0], routes[3][0]
    same = np.abs(at_probe(routes[1][0]) - at_probe(routes[2][0])).max()

    def differences(route, against):
        d = np.abs(te[route] - te[against])
        d_pp = np.abs(np.ptp(te[route], axis=1) - np.ptp(te[against], axis=1))
        return f"{d.max():>9.2e} {np.quantile(d, 0.999):>9.2e} {np.median(d):>9.1e} {d_pp.max():>9.2e}"

    print(f"machine: {machine()}")
    print(
        f"differences [arcsec]: TE max, 99.9 %, median, te_pp max; the reference's TE spans "
        f"{np.ptp(te[reference]):.2f} arcsec, its te_pp {np.ptp(te[reference], axis=1).min():.1f} to "
        f"{np.ptp(te[reference], axis=1).max():.1f}"
    )
    print(
        "the probe's released equilibrium without the solve at 10 probes against with it: largest "
        f"difference {same:.2e} m"
    )
    print(f"{route_columns(58)}  {'from the reference':>39}  {'from the yardstick':>39}")
    for route, label in routes:
        seconds, eq, count = results[route]
        cells = route_cells(
            label,
            58,
            f"{args.reducers} x {points} pts",
            seconds,
            args.reducers,
            count,
            results[reference][0],
            eq,
        )
        print(f"{cells}  {differences(route, reference)}  {differences(route, yardstick)}")


if __name__ == "__main__":
    main()

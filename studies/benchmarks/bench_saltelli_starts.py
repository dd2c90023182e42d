"""Saltelli's design solved with each row A_B^(i) started from its base sample's row A, against
every row started from its own kinematic pose (the reference).

`rvte sobol` solves N (G + 2) reducers: per base sample the rows A and B and G rows A_B^(i),
each A with the columns of group i taken from B.  A_B^(i) shares every error but group i's
with A, so its equilibria lie near A's: `tolerance.evaluate` finds that row in the batch
(`related_rows`) and the roller law's no-load solves of A_B^(i) start from A's solutions at
the same angles (`quasistatic.te_curve`, start_from) instead of the kinematic pose.  The energy
is convex: the same minimiser, in fewer Newton steps.

Both run in this process, taking turns on the same batches of the study's own design (the
first `--base` base samples, in the study's batches), on every core as `rvte sobol` runs
them; the reference evaluates each batch with the relation switched off
(`evaluate.RELATED_SHARE` above 1).  Printed: the time, reducers per second, the compiled
iteration's Newton steps, the ratio, and the largest difference of each metric between the
two.  It stops with an error if a metric differs by more than 1e-6 (arcsec).

    python studies/benchmarks/bench_saltelli_starts.py [--study studies/rv40e_121_sobol.toml] [--base 32] [--repeats 2]
"""

import argparse
import importlib
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", default=str(ROOT / "studies" / "rv40e_121_sobol.toml"))
    parser.add_argument("--base", type=int, default=32, help="base samples (default 32)")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()

    from bench_jobs import machine
    from bench_no_load_start import counted_steps

    evaluate_module = importlib.import_module(
        "tolerance.evaluate"
    )  # the package's `evaluate` is the function
    from tolerance import sobol
    from tolerance.study import load_study

    study = load_study(args.study)
    problem = study.problem()
    per = sobol.rows_per_base_sample(problem, False)
    X = sobol.sample(problem, max(args.base, 1), False, seed=study.seed)[: args.base * per]
    batches = [X[k : k + study.batch_size] for k in range(0, X.shape[0], study.batch_size)]
    share = evaluate_module.RELATED_SHARE
    routes = (("kinematic starts (reference)", 2.0), ("A_B^(i) from A", share))

    def run(related):
        evaluate_module.RELATED_SHARE = related
        steps.clear()
        began = time.perf_counter()
        Y = np.vstack([evaluate_module.evaluate(study, batch)[0] for batch in batches])
        return time.perf_counter() - began, sum(steps), Y

    try:
        with counted_steps() as steps:
            run(share)  # compiled, the model's matrices made
            best = {}
            for _ in range(args.repeats):
                for label, related in routes:
                    result = run(related)
                    if label not in best or result[0] < best[label][0]:
                        best[label] = result
    finally:
        evaluate_module.RELATED_SHARE = share

    reference = best[routes[0][0]]
    print(f"machine: {machine()}")
    print(
        f"{study.name}: {args.base} base samples of Saltelli's design, {X.shape[0]} reducers in {len(batches)} batches"
    )
    columns = study.metric_columns
    print(
        f"{'route':<30} {'time [s]':>9} {'reducers/s':>11} {'Newton steps':>13} {'ratio':>6}  "
        + "  ".join(f"{'max d ' + c:>22}" for c in columns)
    )
    worst = 0.0
    for label, _ in routes:
        seconds, count, Y = best[label]
        difference = np.nanmax(np.abs(Y - reference[2]), axis=0)
        worst = max(worst, float(difference.max()))
        print(
            f"{label:<30} {seconds:>9.2f} {X.shape[0] / seconds:>11.1f} {count:>13d} "
            f"{reference[0] / seconds:>6.2f}  " + "  ".join(f"{d:>22.1e}" for d in difference)
        )
    print("ratio: the reference's time over each row's")
    if worst > 1e-6:
        raise SystemExit(f"the metrics moved by {worst:.3g}: more than 1e-6")


if __name__ == "__main__":
    main()

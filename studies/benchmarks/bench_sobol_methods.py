"""Saltelli's design solved against the linearized method, on one study, in one run.

Runs `rvte sobol` twice on the same study, each in a fresh output folder: with
method "saltelli" (every reducer of Saltelli's design solved: the reference) and
with method "linearized" (the TE curve linearized in the errors by 2A + 1 solves,
Saltelli's design evaluated on it and corrected by the first `solved_n` base samples
solved, tolerance/linearized.py).  It prints what each solved, how long it took and
the ratio to the reference, then for every metric the linearized method's check, its
order groups beside the reference's, and each factor's ST against the reference's
interval.

Default: the complete study at rated load (studies/rv40e_121_full_rated.toml, 15
factors) at N = 256; `--n 1024` is the published run.

Run:  python studies/benchmarks/bench_sobol_methods.py [--study FILE] [--n 256]
      [--processes 2]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", default=str(ROOT / "studies" / "rv40e_121_full_rated.toml"))
    parser.add_argument("--n", type=int, default=256)
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()

    from bench_jobs import machine

    from tolerance.sobol_runs import run_sobol

    runs = {}
    with tempfile.TemporaryDirectory() as folder:
        for method in ("saltelli", "linearized"):
            start = time.perf_counter()
            result = run_sobol(
                args.study,
                args.n,
                output=Path(folder) / method,
                method=method,
                processes=args.processes,
                plots=False,
            )
            runs[method] = (result, time.perf_counter() - start)
    reference, base = runs["saltelli"]
    print(f"machine: {machine()}")
    print(
        f"study: {Path(args.study).name}, N = {args.n}, {len(reference.study.groups)} factors, "
        f"{args.processes} worker processes"
    )
    print(f"{'method':<12} {'reducers solved':>16} {'time [s]':>9} {'throughput':>18} {'ratio':>6}")
    for method, (result, seconds) in runs.items():
        solved = result.computed.computed_rows
        print(
            f"{method:<12} {solved:>16} {seconds:>9.1f} {solved / seconds:>11.1f} red./s "
            f"{seconds / base:>6.3f}"
        )
    linear = runs["linearized"][0]
    for line in linear.check.lines():
        print(line)
    for column, analysis in linear.analyses.items():
        a, b = analysis.indices, reference.analyses[column].indices
        print(
            f"\n{column} ({analysis.method}): order groups {a.order_groups()}, reference {b.order_groups()}"
        )
        print(f"  {'factor':<26} {'ST':>15} {'ST reference':>15} {'|diff|':>7} in reference CI")
        for g in b.ranking():
            diff = abs(a.ST[g] - b.ST[g])
            print(
                f"  {a.names[g]:<26} {a.ST[g]:>7.4f} ± {a.ST_conf[g]:.4f} "
                f"{b.ST[g]:>7.4f} ± {b.ST_conf[g]:.4f} {diff:>7.4f} "
                f"{'yes' if diff <= b.ST_conf[g] else 'no'}"
            )
        print(f"  largest |ST - ST reference| {np.max(np.abs(a.ST - b.ST)):.4f}")


if __name__ == "__main__":
    main()

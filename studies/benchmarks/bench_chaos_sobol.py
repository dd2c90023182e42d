"""Benchmark: model evaluations for group total indices within +-0.02, chaos against Saltelli.

Two functions with analytic indices (the ones tests/test_chaos_sobol.py checks):
Ishigami (a = 7, b = 0.1, three single inputs) and Sobol's G-function of six
inputs in three groups of two (a = 0, 1, 4.5, 9, 99, 99).  Both arms run in this
process, on the same machine:

1. Saltelli: `tolerance.sobol.sample` + `tolerance.sobol.indices` (SALib's
   scrambled Sobol' cross-sampling and estimators, as `rvte sobol` runs them),
   N = 32, 64, ... base samples, N (G + 2) evaluations.
2. Chaos: `tolerance.chaos_sobol.chaos_indices` on n independent uniform rows
   (a Monte Carlo study's rows), n from --rows, at each total degree given.

"Needs" is the fewest evaluations at which the largest |ST - analytic ST| over
the groups is within --tolerance (0.02) for every one of --seeds seeds, and,
for the chaos, its own check passes on every seed (Q2 >= Q2_MIN: an estimate
the estimator refuses to rank on does not count).  Saltelli's N are powers of
2 (the balance of the Sobol' sequence), so its figure is within a factor 2.  The
search runs without intervals; the time column is one estimate at that size
with its intervals (--resamples bootstrap refits for the chaos, 200 resamples
for SALib, as `rvte sobol` does) and excludes the model (these functions cost
nothing; a reducer costs ~15-100 ms, so on the study the evaluations decide).
The ratio is Saltelli's evaluations over the row's.

    python studies/benchmarks/bench_chaos_sobol.py [--seeds 3] [--tolerance 0.02] [--resamples 100]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from test_chaos_sobol import ISHIGAMI, g_function, g_group_indices, ishigami, ishigami_indices  # noqa: E402

from tolerance import sobol  # noqa: E402
from tolerance.chaos_sobol import Q2_MIN, chaos_indices  # noqa: E402

G_A = np.array([0.0, 1.0, 4.5, 9.0, 99.0, 99.0])
G_PROBLEM = {
    "num_vars": 6,
    "names": [f"x{i}" for i in range(6)],
    "bounds": [[0.0, 1.0]] * 6,
    "groups": ["g1", "g1", "g2", "g2", "g3", "g3"],
}
CASES = {  # name: (problem, model of unit rows, analytic ST, chaos degrees)
    "Ishigami": (ISHIGAMI, ishigami, ishigami_indices()[1], (6, 8, 10)),
    "G-function": (
        G_PROBLEM,
        lambda U: g_function(U, G_A),
        g_group_indices(G_A, [[0, 1], [2, 3], [4, 5]])[1],
        (3, 4, 5),
    ),
}
BASE_SAMPLES = tuple(2**k for k in range(5, 15))
ROWS = (40, 60, 80, 100, 130, 160, 200, 250, 300, 400, 500, 700, 1000)


def saltelli_error(problem, model, ST, N, seed):
    X = sobol.sample(problem, N, seed=seed)
    return float(np.max(np.abs(sobol.indices(problem, model(X), resamples=10, seed=seed).ST - ST)))


def chaos_error(problem, model, ST, n, degree, seed):
    U = np.random.default_rng(seed).random((n, problem["num_vars"]))
    (result,) = chaos_indices(U, model(U), problem, degree=degree, resamples=0)
    return float(np.max(np.abs(result.ST - ST))), result.q2


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--tolerance", type=float, default=0.02)
    parser.add_argument("--resamples", type=int, default=100)
    args = parser.parse_args(argv)
    seeds = range(args.seeds)
    print(
        f"{'what':34s} {'evaluations':>11s} {'time s':>8s} {'max |ST err|':>13s} {'Q2 min':>7s} {'ratio':>6s}"
    )
    for name, (problem, model, ST, degrees) in CASES.items():
        G = len(sobol.group_names(problem))
        saltelli = None
        for N in BASE_SAMPLES:
            worst = max(saltelli_error(problem, model, ST, N, s) for s in seeds)
            if worst <= args.tolerance:
                X = sobol.sample(problem, N, seed=0)
                y = model(X)
                start = time.perf_counter()
                sobol.indices(problem, y, resamples=200, seed=0)
                saltelli = N * (G + 2)
                print(
                    f"{name + ' Saltelli N=' + str(N):34s} {saltelli:11d} "
                    f"{time.perf_counter() - start:8.2f} {worst:13.4f} {'':>7s} {1.0:6.1f}"
                )
                break
        else:
            print(f"{name + ' Saltelli':34s} {'> ' + str(BASE_SAMPLES[-1] * (G + 2)):>11s}")
        for degree in degrees:
            for n in ROWS:
                runs = [chaos_error(problem, model, ST, n, degree, s) for s in seeds]
                worst = max(error for error, _ in runs)
                if worst <= args.tolerance and min(q2 for _, q2 in runs) >= Q2_MIN:
                    U = np.random.default_rng(0).random((n, problem["num_vars"]))
                    y = model(U)
                    start = time.perf_counter()
                    chaos_indices(U, y, problem, degree=degree, resamples=args.resamples)
                    ratio = f"{saltelli / n:6.1f}" if saltelli else "     -"
                    print(
                        f"{name + ' chaos degree ' + str(degree):34s} {n:11d} "
                        f"{time.perf_counter() - start:8.2f} {worst:13.4f} "
                        f"{min(q2 for _, q2 in runs):7.4f} {ratio}"
                    )
                    break
            else:
                print(f"{name + ' chaos degree ' + str(degree):34s} {'> ' + str(ROWS[-1]):>11s}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()

"""Benchmark: the compiled quasi-static Newton iteration against the numpy one, same reducers.

The quasi-static solver's Newton iteration runs compiled, pair by pair
(rvfmu/core/statics/newton_kernel.py), where numba is installed; the numpy iteration of
whole chunks (`newton.newton_batched`) is the baseline, timed in the same
process on the same reducers.  Cases:
- reducers of the complete RV-40E-121 study (studies/rv40e_121_full.toml: 15
  error sources, the three bearing clearances included) at no load, 3200
  points per revolution: the study's own setting, the slowest route (each pose
  by continuation through the clearances);
- the same reducers under the rated torque, 720 points (the rated study);
- the seed 002 errors without clearances (studies/seed002_errors.toml), at no
  load and at rated load, 720 points.
Each case also prints the largest TE difference between the two iterations.
BLAS runs on one thread, so reducers/s is per core; the compiled kernel is
warmed up (compiled or loaded from numba's cache) before it is timed.

    python studies/benchmarks/bench_newton.py [--quick]

--quick: 4 study reducers instead of 16, 8 seed 002 copies instead of 32.
"""

import os
import sys

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from unittest import mock  # noqa: E402

import numpy as np  # noqa: E402

from rvfmu.core.reducer.design import preset  # noqa: E402
from rvfmu.core.reducer.errors import load_errors, stack  # noqa: E402
from rvfmu.core.statics import newton_kernel  # noqa: E402
from rvfmu.core.statics.quasistatic import te_curve  # noqa: E402
from tolerance.sampling import errors_from_unit  # noqa: E402
from tolerance.study import load_study  # noqa: E402

STUDIES = Path(__file__).resolve().parents[1]


def timed(run):
    start = time.perf_counter()
    result = run()
    return time.perf_counter() - start, result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller batches")
    args = parser.parse_args(argv)
    if not newton_kernel.COMPILED:
        sys.exit("numba is not installed (or RVTE_NUMBA=0): there is no compiled iteration to time")
    n_study, n_copies = (4, 8) if args.quick else (16, 32)

    study = load_study(STUDIES / "rv40e_121_full.toml")
    X = np.random.default_rng(2024).random((n_study, len(study.columns)))
    full = errors_from_unit(study, X)
    rv40 = preset("RV-40E-121")
    seed002 = stack([load_errors(STUDIES / "seed002_errors.toml", rv40)] * n_copies)
    cases = [
        ("complete study reducers, no load", study.design, full, 0.0, study.points),
        ("complete study reducers, rated load", study.design, full, -412.0, 720),
        ("seed 002 errors, no clearance, no load", rv40, seed002, 0.0, 720),
        ("seed 002 errors, no clearance, rated load", rv40, seed002, -rv40.rated_torque, 720),
    ]

    start = time.perf_counter()
    for _, design, errors, tau, _ in cases:  # compile or load the kernels of every case
        te_curve(design, errors.take([0]), tau_load=tau, points=16)
    warm = time.perf_counter() - start

    rows, worst = [], []
    for what, design, errors, tau, points in cases:
        run = lambda: te_curve(design, errors, tau_load=tau, points=points)  # noqa: E731
        with mock.patch.object(newton_kernel, "COMPILED", False):
            t_plain, plain = timed(run)
        t_fast, fast = timed(run)
        n = errors.samples
        rows.append((f"{what}, numpy iteration (baseline)", n, points, t_plain, n / t_plain, 1.0))
        rows.append((f"{what}, compiled iteration", n, points, t_fast, n / t_fast, t_plain / t_fast))
        worst.append(
            (
                what,
                np.max(np.abs(fast.te_arcsec - plain.te_arcsec)),
                bool(fast.converged.all() and plain.converged.all()),
            )
        )

    print(f"\nRV-40E-121, 1 BLAS thread; kernel warm-up (compile or cache load) {warm:.1f} s, not counted")
    print("| what | reducers | points | time [s] | throughput [reducers/s] | speed-up |")
    print("|---|---|---|---|---|---|")
    for what, n, points, t, rate, ratio in rows:
        print(f"| {what} | {n} | {points} | {t:.2f} | {rate:.2f} | {ratio:.1f} |")
    print("\nagreement, compiled against numpy:")
    for what, diff, converged in worst:
        print(f"  {what}: max |TE difference| = {diff:.1e} arcsec; all converged: {converged}")


if __name__ == "__main__":
    main()

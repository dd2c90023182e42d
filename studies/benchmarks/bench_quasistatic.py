"""Benchmark: quasi-static TE curves per second per core, beside a plain scipy solve.

Measures `rvfmu.core.statics.quasistatic.te_curve` for the RV-40E-121 with the seed 002
errors (studies/seed002_errors.toml), 720 points per output revolution, at no
load (tau_load = 0) and at rated load (tau_load = -rated_torque), for batches of
1, 64 and 1024 copies of that reducer.  The baseline is `rvfmu.core.statics.reference.
te_reference`, one L-BFGS-B solve of all unknowns per angle (two at no load),
timed on 36 of the 720 angles and scaled to curves/s; the table says so.  The
script also checks that both give the same TE on those angles, reports the
tracemalloc peak of the batch-1024 runs and a cProfile of one batch-64 loaded
run.  BLAS runs on one thread, so curves/s is per core.  Where the two disagree by
more than AGREEMENT_ARCSEC on any angle the script says so and exits with status 1:
the reference models every element the solver has, so a disagreement is a bug.

Targets: >= 100 loaded curves/s/core; peak memory < 4 GB at batch 1024.

    python studies/benchmarks/bench_quasistatic.py [--quick] [--batches 1,64,1024]

--quick: batches 1 and 64, one timed repeat after the warm-up (about a minute).
"""

import os
import sys

# One BLAS thread: throughput per core.  Only effective if numpy is not imported yet.
BLAS_PRESET = "numpy" not in sys.modules
for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from rvfmu.core.base.units import rad_to_arcsec  # noqa: E402
from rvfmu.core.reducer.design import preset  # noqa: E402
from rvfmu.core.reducer.errors import load_errors, stack  # noqa: E402
from rvfmu.core.statics.quasistatic import input_angles, te_curve  # noqa: E402
from rvfmu.core.statics.reference import te_reference  # noqa: E402

ERRORS_FILE = Path(__file__).resolve().parents[1] / "seed002_errors.toml"
POINTS = 720  # per output revolution, as asked of the benchmark
BASELINE_STRIDE = 20  # scipy on every 20th angle: 36 angles, ~5 ms to 50 ms each
TARGET_LOADED_PER_S = 100.0
TARGET_PEAK_BYTES = 4e9
BIG_BATCH = 1024  # from this size on: best of 1, and the memory is traced
AGREEMENT_ARCSEC = 0.01  # solver against reference: the tests' tolerance


def best_of(run, repeats, trace=False):
    """(best wall time [s], last result, tracemalloc peak of the warm-up [bytes] or None)."""
    if trace:
        tracemalloc.start()
    result = run()  # warm-up
    peak = tracemalloc.get_traced_memory()[1] if trace else None
    if trace:
        tracemalloc.stop()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), result, peak


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="batches 1,64; one repeat")
    parser.add_argument("--batches", default=None, help="comma-separated batch sizes (1,64,1024)")
    args = parser.parse_args(argv)
    batches = [int(b) for b in (args.batches or ("1,64" if args.quick else "1,64,1024")).split(",")]
    repeats = 1 if args.quick else 3
    if not BLAS_PRESET:
        print("note: numpy was imported before this module; BLAS may use several threads")

    design = preset("RV-40E-121")
    errors = load_errors(ERRORS_FILE, design)
    loads = {"no load": 0.0, "rated load": -design.rated_torque}
    subset = np.arange(0, POINTS, BASELINE_STRIDE)
    theta_sub = input_angles(design, POINTS)[subset]
    fraction = subset.size / POINTS

    rows, baseline, reference, fast, peaks = [], {}, {}, {}, {}
    for label, tau in loads.items():
        t, reference[label], _ = best_of(lambda: te_reference(design, errors, theta_sub, tau), repeats)
        baseline[label] = fraction / t
        rows.append(
            (
                f"scipy per angle, {label} ({subset.size} of {POINTS} angles, scaled)",
                1,
                f"{subset.size}/{POINTS}",
                t,
                baseline[label],
                1.0,
            )
        )
    for n in batches:
        batch = stack([errors] * n)
        for label, tau in loads.items():
            t, curve, peak = best_of(
                lambda: te_curve(design, batch, tau_load=tau, points=POINTS),
                1 if n >= BIG_BATCH else repeats,
                trace=n >= BIG_BATCH,
            )
            if not curve.converged.all():
                print(f"warning: {label}, batch {n}: {np.sum(~curve.converged)} curves not converged")
            if n == 1:
                fast[label] = curve.te[0, subset]
            if peak is not None:
                peaks[(label, n)] = peak
            rows.append((f"te_curve, {label}", n, str(POINTS), t, n / t, n / t / baseline[label]))

    print(
        f"\nRV-40E-121, seed 002 errors, {POINTS} points/rev, 1 BLAS thread; best of "
        f"{repeats} after a warm-up (best of 1 at batch >= {BIG_BATCH})"
    )
    header = ("what", "batch size", "points", "time [s]", "throughput [curves/s]", "ratio to scipy")
    widths = (max(len(r[0]) for r in rows), 10, 8, 9, 21, 14)
    print("  ".join(h.ljust(w) if i == 0 else h.rjust(w) for i, (h, w) in enumerate(zip(header, widths))))
    for what, n, pts, t, rate, ratio in rows:
        print(f"{what:<{widths[0]}}  {n:>10}  {pts:>8}  {t:>9.3f}  {rate:>21.2f}  {ratio:>14.1f}")

    print("\nagreement with scipy on the subset (batch-1 te_curve):")
    disagree = []
    for label in loads:
        if label in fast:
            diff = np.max(np.abs(rad_to_arcsec(fast[label] - reference[label])))
            print(f"  {label}: max |TE difference| = {diff:.2e} arcsec over {subset.size} angles")
            if not diff <= AGREEMENT_ARCSEC:
                disagree.append(f"{label}: {diff:.3g} arcsec")

    loaded = max((r[4], r[1]) for r in rows if r[0] == "te_curve, rated load")
    verdict = "meets" if loaded[0] >= TARGET_LOADED_PER_S else "misses"
    print(
        f"\ntarget >= {TARGET_LOADED_PER_S:.0f} loaded curves/s/core: best {loaded[0]:.1f} "
        f"(batch {loaded[1]}), {verdict} it"
    )
    for (label, n), peak in peaks.items():
        verdict = "meets" if peak < TARGET_PEAK_BYTES else "misses"
        print(
            f"peak memory, {label}, batch {n} (tracemalloc peak of the warm-up run, numpy and "
            f"Python allocations): {peak / 1e6:.0f} MB; target < 4 GB: {verdict} it"
        )

    print("\nwhere the time goes: cProfile of one batch-64 rated-load run, top 8 by tottime")
    profile = cProfile.Profile()
    batch = stack([errors] * 64)
    profile.runcall(te_curve, design, batch, tau_load=loads["rated load"], points=POINTS)
    stats = pstats.Stats(profile).sort_stats("tottime")
    print(f"  {'tottime [s]':>11}  {'share':>6}  {'calls':>7}  function")
    for func in stats.fcn_list[:8]:
        _, calls, tottime, _, _ = stats.stats[func]
        where = f"{Path(func[0]).name}:{func[1]}({func[2]})" if func[1] else func[2]
        print(f"  {tottime:>11.3f}  {tottime / stats.total_tt:>6.1%}  {calls:>7}  {where}")
    if disagree:
        print(
            f"\nFAILED: the solver and the reference disagree by more than {AGREEMENT_ARCSEC} "
            f"arcsec ({'; '.join(disagree)})",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: the same te_pp from fewer angles?  Measured on the reducers of rv40e_121_full.

A tolerance study's no-load te_pp is the max - min of the TE at P = 3200
input angles (studies/rv40e_121_full.toml), each an equilibrium of the costly
route with bearing clearances.  This script draws reducers as that study does
(its Monte Carlo rows), solves their full curves and measures, for coarse
subsets of every k-th grid point (k = 2, 4, 8, 16):

- how far (in grid points, around the revolution) the grid's argmax and argmin
  lie from the coarse ones, and how much te_pp the coarse subset loses;
- the largest excess of a coarse interval's interior beyond its two ends (how
  much a curve can hide between coarse points) and the largest change between
  neighbouring grid points (a local Lipschitz bound), beside its median;
- the solves an oracle scheme needs that refines every coarse interval whose
  ends plus the reducer's true largest excess could beat the coarse extremes.

Then it runs the rule of rvfmu/core/statics/adaptive_angles.py on the stored full
curves for several settings (solves and misses, no solving), and the solver
itself with the default settings beside the full curves, in the same run:
solves, time, max |delta te_pp| and the ratio.  BLAS and the kernels run on one
thread, so times are per core.

    python studies/benchmarks/bench_angles.py [--reducers 12] [--first 0] [--points 3200]

--first: the first Monte Carlo row (rows 0-11 chose the default settings; other
rows check them).
"""

import os
import sys

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from rvfmu.core.statics.adaptive_angles import PILOT, SAFETY, STRIDE, refine_extremes, te_pp_adaptive  # noqa: E402
from rvfmu.core.statics.quasistatic import te_curve  # noqa: E402
from tolerance import montecarlo  # noqa: E402
from tolerance.sampling import errors_from_unit  # noqa: E402
from tolerance.study import load_study  # noqa: E402

STUDY = Path(__file__).resolve().parents[1] / "rv40e_121_full.toml"
STRIDES = (2, 4, 8, 16)
RULES = [(k, c, p) for k in (2, 4, 8) for c in (1.5, 2.0, 3.0) for p in (0, PILOT)]
EXACT_ARCSEC = 1e-6  # adaptive te_pp against the full curve's


def periodic_distance(i, j, points):
    d = np.abs(np.asarray(i) - np.asarray(j))
    return np.minimum(d, points - d)


def measure(te, k):
    """Coarse-subset figures of curves te (S, P) [arcsec] at stride k, each (S,)."""
    S, P = te.shape
    n = P // k
    blocks = te[:, : n * k].reshape(S, n, k)
    left = blocks[:, :, 0]
    right = np.roll(left, -1, axis=1)
    if n * k < P:  # a last, shorter interval: its right end is index 0
        right[:, -1] = te[:, 0]
    hi, lo = np.maximum(left, right), np.minimum(left, right)
    excess = np.maximum(blocks.max(axis=2) - hi, lo - blocks.min(axis=2)).max(axis=1)
    coarse = te[:, ::k]
    top, bottom = coarse.max(axis=1), coarse.min(axis=1)
    oracle = (hi + excess[:, None] > top[:, None]) | (lo - excess[:, None] < bottom[:, None])
    return {
        "dmax": periodic_distance(k * coarse.argmax(axis=1), te.argmax(axis=1), P),
        "dmin": periodic_distance(k * coarse.argmin(axis=1), te.argmin(axis=1), P),
        "pp_lost": (te.max(axis=1) - te.min(axis=1)) - (top - bottom),
        "excess": excess,
        "oracle_solves": coarse.shape[1] + oracle.sum(axis=1) * (k - 1),
    }


def table_solver(te):
    return lambda s, a: (te[s, a], np.ones(s.size, dtype=bool))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=12)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--points", type=int, default=3200)
    args = parser.parse_args(argv)
    study = load_study(STUDY)
    design, P = study.design, args.points
    errors = errors_from_unit(study, montecarlo.rows(study, args.first, args.first + args.reducers))
    S = errors.samples
    te_curve(design, errors.take([0]), 0.0, points=64)  # warm-up: kernels loaded
    te_pp_adaptive(design, errors.take([0]), 0.0, points=64, stride=4, pilot=2)

    t = time.perf_counter()
    full = te_curve(design, errors, tau_load=0.0, points=P)
    t_full = time.perf_counter() - t
    te = full.te_arcsec
    pp = full.te_pp_arcsec
    step = np.abs(np.diff(te, axis=1, append=te[:, :1]))
    print(
        f"{S} reducers of {STUDY.name} (rows {args.first}-{args.first + S - 1}), no load, "
        f"P = {P}; full curves: {t_full:.2f} s, {1e6 * t_full / (S * P):.0f} us per solve, "
        f"converged {full.converged.all()}"
    )
    print(f"te_pp [arcsec]: {np.array2string(pp, precision=1)}")
    print(
        f"largest change between neighbouring grid points [arcsec]: "
        f"{np.array2string(step.max(axis=1), precision=1)}"
    )
    print(
        f"median change between neighbouring grid points [arcsec]:  "
        f"{np.array2string(np.median(step, axis=1), precision=2)}"
    )
    print()
    print(
        "stride | dist argmax (median / max) | dist argmin (median / max) | te_pp lost max | "
        "excess (median / max) | oracle solves (mean / max) of P"
    )
    for k in STRIDES:
        m = measure(te, k)
        print(
            f"{k:6d} | {np.median(m['dmax']):6.0f} / {m['dmax'].max():5d}        "
            f"| {np.median(m['dmin']):6.0f} / {m['dmin'].max():5d}        "
            f"| {m['pp_lost'].max():10.2f}     | {np.median(m['excess']):6.2f} / "
            f"{m['excess'].max():6.2f}       | {m['oracle_solves'].mean():6.0f} / "
            f"{m['oracle_solves'].max():5d} ({100 * m['oracle_solves'].mean() / P:.0f} %)"
        )
    print()
    print(
        "rule on the stored curves: stride | safety | pilot | solves mean / max (share) | "
        "rounds | missed (|delta te_pp| > 1e-6 arcsec)"
    )
    for k, c, p in RULES:
        r = refine_extremes(table_solver(te), S, P, stride=k, safety=c, pilot=p)
        delta = np.abs(r.te_pp_arcsec - pp)
        missed = int(np.sum(delta > EXACT_ARCSEC))
        print(
            f"  {k:4d} | {c:4.1f} | {p:3d} | {r.solves.mean():6.0f} / {r.solves.max():5d} "
            f"({100 * r.solves.mean() / P:3.0f} %) | {r.rounds} | {missed} of {S}"
            + (f", te_pp short by up to {delta.max():.2f} arcsec" if missed else "")
        )
    print()
    t = time.perf_counter()
    adaptive = te_pp_adaptive(design, errors, tau_load=0.0, points=P)
    t_adaptive = time.perf_counter() - t
    delta = np.abs(adaptive.te_pp_arcsec - pp)
    print(f"solver, same run (stride {STRIDE}, safety {SAFETY}, pilot {PILOT}):")
    print("route    | solves | time [s] | max |delta te_pp| [arcsec] | argmax/argmin equal")
    print(f"full     | {S * P:6d} | {t_full:8.2f} | {0.0:26.1e} | -")
    same = bool(np.all(adaptive.argmax == te.argmax(axis=1)) and np.all(adaptive.argmin == te.argmin(axis=1)))
    print(f"adaptive | {adaptive.solves.sum():6d} | {t_adaptive:8.2f} | {delta.max():26.1e} | {same}")
    print(f"ratio    | {adaptive.solves.sum() / (S * P):6.2f} | {t_adaptive / t_full:8.2f} |")
    print(
        f"per reducer solves: {adaptive.solves.tolist()}; final excess bound E [arcsec]: "
        f"{np.array2string(adaptive.excess_bound_arcsec, precision=1)}; rounds {adaptive.rounds}"
    )
    return 0 if delta.max() <= EXACT_ARCSEC and adaptive.converged.all() else 1


if __name__ == "__main__":
    sys.exit(main())

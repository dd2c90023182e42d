"""What the even chunks and the reduced system's angle blocks save a study, before and after.

Two changes to the quasi-static solve, both with the same numbers to the bit, and both
measured here against the route they replaced, which this script rebuilds in the same
process:

- **Even chunks** (`solver._chunks`).  A call's pairs are cut into chunks that the threads
  take up in turn.  Before, every chunk held CHUNK = 4096 pairs and the last the rest: a
  batch of quick_mc (64 reducers x 720 angles = 46 080 pairs) made 11 chunks of 4096 and
  one of 1024, so one thread finished a chunk and a quarter before the other.  Now the
  chunks are as even as whole warm-start chains allow and, where they run on threads, a
  multiple of the threads in number: 12 of 3840.
- **Angle blocks** (`solver.ReducedSystem`, ANGLE_BLOCK).  The reduced system's arrays
  (condensed stiffness, load rows, mechanism mode, candidate pins ... per angle) were made
  in one pass of numpy over all the angles, on one thread; made in blocks of 512 angles on
  the threads (numpy's stacked solves and products release Python's lock) they cost about
  half at the 12 480 angles of a full-resolution curve.  This is paid once per model: by
  the aliasing check of `rvte mc` (16 reducers at 12 480 points) and by `rvte te`.

Printed, on the calibrated RV-40E-121 of studies/quick_mc.toml:
1. the reduced systems of the no-load route (the kinematic one and the roller law's) at 720,
   3200 and 12 480 angles: one pass (before), blocks alone (RVTE_THREADS=1) and blocks on
   the threads (now); their arrays are compared to the bit;
2. quick_mc's outputs for `--batches` batches of 64 reducers (720 points, the windup test),
   and the aliasing check's 16 reducers at 12 480 points from a fresh model, before and
   after, taking turns, best of `--repeats`; the outputs are compared to the bit;
3. with `--mc`, `rvte mc studies/quick_mc.toml` itself (`tolerance.mc_runs.run_mc`, 2000
   reducers, the figures and files, a fresh folder each time), before and after in turn.

Run:  python studies/benchmarks/bench_chunks.py [--batches 8] [--repeats 3] [--mc]
"""

import argparse
import contextlib
import importlib
import os
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "quick_mc.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--mc", action="store_true", help="also time rvte mc studies/quick_mc.toml")
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.statics import quasistatic, solver
    from rvfmu.core.statics.equivalent import EquivalentModel
    from tolerance import aliasing, montecarlo
    from tolerance.study import load_study

    evaluate = importlib.import_module("tolerance.evaluate")  # the package's `evaluate` is the function
    study = load_study(STUDY)
    design = study.design
    new_chunks, new_block = solver._chunks, solver.ANGLE_BLOCK

    def old_chunks(size, begin=0):
        return [
            slice(s, min(s + solver.CHUNK, begin + size)) for s in range(begin, begin + size, solver.CHUNK)
        ]

    @contextlib.contextmanager
    def route(old: bool):
        solver._chunks = old_chunks if old else new_chunks
        solver.ANGLE_BLOCK = 10**9 if old else new_block
        quasistatic._equivalent_model.cache_clear()  # a fresh model: its reduced systems made again
        try:
            yield
        finally:
            solver._chunks, solver.ANGLE_BLOCK = new_chunks, new_block

    @contextlib.contextmanager
    def threads(count: str | None):
        before = os.environ.get("RVTE_THREADS")
        if count is None:
            os.environ.pop("RVTE_THREADS", None)
        else:
            os.environ["RVTE_THREADS"] = count
        try:
            yield
        finally:
            if before is None:
                os.environ.pop("RVTE_THREADS", None)
            else:
                os.environ["RVTE_THREADS"] = before

    print(f"machine: {machine()}")
    print("\n1. the no-load route's reduced systems (kinematic + roller law), best of", args.repeats)
    print(
        f"{'angles':>7} {'one pass [s]':>13} {'blocks, 1 thread [s]':>21} {'blocks, threads [s]':>20} {'ratio':>6}"
    )
    for points in (720, 3200, 12480):
        model = EquivalentModel(design, quasistatic.input_angles(design, points), flank=1)
        kinds = ((np.zeros(model.bearing_k.size, dtype=bool), False), (model.bearing_law_a > 0.0, True))

        def build(block, count):
            solver.ANGLE_BLOCK = block
            with threads(count):
                began = time.perf_counter()
                systems = [solver.ReducedSystem(model, nonlinear, rollers) for nonlinear, rollers in kinds]
                took = time.perf_counter() - began
            solver.ANGLE_BLOCK = new_block
            return took, systems

        times = {key: [] for key in ("one", "alone", "threads")}
        for _ in range(args.repeats):
            for key, block, count in (
                ("one", 10**9, None),
                ("alone", new_block, "1"),
                ("threads", new_block, None),
            ):
                took, systems = build(block, count)
                times[key].append(took)
                if key == "one":
                    reference = systems
                else:
                    for a, b in zip(reference, systems):
                        for name, value in vars(a).items():
                            if isinstance(value, np.ndarray) and not np.array_equal(value, vars(b)[name]):
                                raise SystemExit(f"{name} differs at {points} angles")
        best = {key: min(v) for key, v in times.items()}
        print(
            f"{points:>7} {best['one']:>13.3f} {best['alone']:>21.3f} {best['threads']:>20.3f}"
            f" {best['one'] / best['threads']:>6.2f}"
        )

    X = montecarlo.rows(study, 0, 64 * args.batches)
    batches = [X[k : k + 64] for k in range(0, X.shape[0], 64)]
    check = montecarlo.rows(study, 0, aliasing.CHECK_ROWS)
    fine = replace(study, points=quasistatic.default_points(design), metrics=("te_pp", "rms"), spec=())
    jobs = (
        (
            f"quick_mc, {args.batches} batches of 64",
            lambda: np.vstack([evaluate.evaluate(study, b)[0] for b in batches]),
        ),
        (
            f"aliasing check, {aliasing.CHECK_ROWS} reducers at {fine.points} points",
            lambda: evaluate.evaluate(fine, check)[0],
        ),
    )
    for _, job in jobs:  # compile or load the kernels
        job()
    print(f"\n2. before (chunks of {solver.CHUNK}, one pass) and after, taking turns, best of {args.repeats}")
    print(f"{'what':<46} {'before [s]':>10} {'after [s]':>10} {'ratio':>6}  same to the bit")
    for label, job in jobs:
        times, outputs = {True: [], False: []}, {}
        for _ in range(args.repeats):
            for old in (True, False):
                with route(old):
                    began = time.perf_counter()
                    outputs[old] = job()
                    times[old].append(time.perf_counter() - began)
        same = np.array_equal(outputs[True], outputs[False])
        before, after = min(times[True]), min(times[False])
        print(f"{label:<46} {before:>10.2f} {after:>10.2f} {before / after:>6.2f}  {same}")
        if not same:
            raise SystemExit(f"{label}: the outputs differ")

    if args.mc:
        from tolerance.mc_runs import run_mc

        print(f"\n3. rvte mc {STUDY.relative_to(ROOT)} (a fresh folder each run, figures and files), in turn")
        times = {True: [], False: []}
        for _ in range(args.repeats):
            for old in (True, False):
                folder = Path(tempfile.mkdtemp())
                with route(old):
                    began = time.perf_counter()
                    run_mc(STUDY, output=folder, progress=False, log=lambda line: None)
                    times[old].append(time.perf_counter() - began)
                shutil.rmtree(folder, ignore_errors=True)
        print(f"{'what':<46} {'before [s]':>10} {'after [s]':>10} {'ratio':>6}")
        before, after = min(times[True]), min(times[False])
        print(
            f"{'rvte mc studies/quick_mc.toml, best':<46} {before:>10.2f} {after:>10.2f} {before / after:>6.2f}"
        )
        print(
            f"  every run: before {', '.join(f'{t:.2f}' for t in times[True])}; after {', '.join(f'{t:.2f}' for t in times[False])}"
        )


if __name__ == "__main__":
    main()

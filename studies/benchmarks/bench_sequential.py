"""Benchmark: an allocation whose verifications look at their yield as they go, against one
Monte Carlo of n reducers each.

`rvte allocate` judges every allocation it tries by a Monte Carlo of the true
model, at least 10 000 reducers at a target >= 0.99.  The sequential
verification (tolerance/least_cost.py, step 6) looks at the yield after n/16,
n/8, n/4, n/2 and n reducers and stops once its interval (99 % a look, so that
the 95 % holds over the five) is clear of the target.  This script runs
`tolerance.allocate` on one study both ways in this process, each on a fresh
output folder: `looks=1` (the reference: every verification n reducers) and
the default looks.  Then it runs each answer's allocated study file again with
another seed (--check reducers, draws neither search saw) to show its yield on
fresh reducers.

    python studies/benchmarks/bench_sequential.py [--study studies/quick_mc.toml]
        [--yield 0.99] [--points 90] [-n N] [--check 4000] [--processes P] [--only-sequential]

--points: per output revolution (default the study's own); -n: reducers of a
verification at most (default as `rvte allocate`).  Prints one table: what,
size, wall time, model evaluations, evaluations per second, total cost, the
answer's yield (interval, reducers), the yield on fresh draws, and the wall
time as a share of the reference's.
"""

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import re  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import tolerance  # noqa: E402
from tolerance.least_cost import LOOKS  # noqa: E402

STUDY = Path(__file__).resolve().parents[1] / "quick_mc.toml"
CHECK_SEED = 9001  # the fresh draws of the check: a seed no search derives


def edited(text: str, **values) -> str:
    """The study text with `key = value` lines replaced (each key there once)."""
    for key, value in values.items():
        text, count = re.subn(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text)
        if count != 1:
            raise SystemExit(f"{key}: expected once in the study file, found {count} times")
    return text


def study_copy(study: Path, folder: Path, name: str, points: int | None) -> Path:
    """The study file under another name, its output in folder/name, at `points` if given."""
    values = {"name": f'"{name}"', "output": f'"{folder / name}"'}
    if points is not None:
        values["points"] = points
    text = study.read_text()
    if not re.search(r"(?m)^output\s*=", text):  # the default output: give it one
        text = re.sub(r"(?m)^\[study\]\s*$", '[study]\noutput = "output"', text, count=1)
    path = folder / f"{name}.toml"
    path.write_text(edited(text, **values))
    return path


def fresh_yield(result, folder: Path, n: int, processes) -> str:
    """The allocated study file's yield on n reducers of another seed."""
    if n <= 0:
        return "-"
    allocated = Path(result.allocated_study_file)
    check = folder / f"{allocated.stem}_check.toml"
    check.write_text(edited(allocated.read_text(), seed=CHECK_SEED, output=f'"{folder / check.stem}"'))
    mc = tolerance.run_mc(check, n, processes=processes, plots=False)
    line = mc.analysis.yields[-1]  # all spec lines at once
    return f"{line.fraction:.4f} ({line.low:.4f}-{line.high:.4f}) of {line.n}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, default=STUDY)
    parser.add_argument("--yield", dest="target", type=float, default=0.99)
    parser.add_argument("--points", type=int, default=None)
    parser.add_argument("-n", type=int, default=None)
    parser.add_argument("--check", type=int, default=4000)
    parser.add_argument("--processes", type=int, default=None)
    parser.add_argument("--only-sequential", action="store_true", help="skip the reference (looks=1)")
    args = parser.parse_args(argv)
    if not args.study.is_file():
        raise SystemExit(f"--study {args.study}: no such file")
    folder = Path(tempfile.mkdtemp(prefix="bench_sequential_"))
    points = args.points or tolerance.load_study(args.study).points
    print(
        f"# bench_sequential: {args.study.name}, {points} points, yield >= {args.target}, "
        f"load average {os.getloadavg()[0]:.2f}; work in {folder}",
        flush=True,
    )
    arms = (
        [("sequential", LOOKS)]
        if args.only_sequential
        else [("one look (reference)", 1), ("sequential", LOOKS)]
    )
    lines = [
        "| what | looks | wall [s] | model evaluations | evaluations/s | total cost | "
        "yield of the answer (95 % interval) | on fresh draws | wall / reference's |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    reference = None
    for what, looks in arms:
        path = study_copy(args.study, folder, f"looks{looks}", args.points)
        clock = time.perf_counter()
        result = tolerance.allocate(
            path,
            args.target,
            n=args.n,
            processes=args.processes,
            looks=looks,
            progress=None,
            log=lambda text: print(text, flush=True),
        )
        seconds = time.perf_counter() - clock
        reference = reference or seconds
        print(result.table(), flush=True)
        y = result.yield_allocated
        lines.append(
            f"| {what} | {looks} | {seconds:.0f} | {result.model_evaluations} | "
            f"{result.model_evaluations / seconds:.1f} | {result.total_cost_current:.3f} -> "
            f"{result.total_cost_allocated:.3f} | {y.estimate:.5f} ({y.low:.5f}-{y.high:.5f}) of {y.n}"
            f"{'' if result.feasible else ', NOT met'} | "
            f"{fresh_yield(result, folder, args.check, args.processes)} | {seconds / reference:.2f} |"
        )
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

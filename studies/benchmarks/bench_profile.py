"""Where the time goes: a profile of the quasi-static study routes and of the dynamic step.

What it measures, on one core (BLAS on one thread), each route under cProfile:
- the no-load route with the bearing clearances: a batch of `--reducers` reducers of the
  complete RV-40E-121 study (studies/rv40e_121_full.toml: 15 tolerances, 3200 points per
  output revolution), drawn by its Monte Carlo sampler and evaluated as `rvte mc` does
  (`tolerance.evaluate`: the TE curve, then the windup test);
- the rated route: the same count of reducers of studies/rv40e_121_full_rated.toml (412 N*m,
  720 points);
- the dynamic step: Newmark over `--seconds` of the RV-40E-121 with the seed 002 errors at
  1600 rpm and half its rated load, with its friction (`rvfmu.core.dynamics.simulation.simulate`).
Each route is run once untimed first (numba compiles or loads its kernels), then timed
without and with the profiler: the wall time and throughput are those without it.  Then
the two quasi-static routes again with the compiled iteration on every core of this
machine (RVTE_THREADS, `rvfmu.core.statics.newton.kernel_threads`) against one, in the same
process: the ratio is what one process gains from its threads.  The
profile's own time is grouped by where it is spent:
- "compiled Newton": the active-set Newton iteration (core/statics/newton_kernel.py, compiled);
- "continuation, release": the no-load continuation, release rounds and contact routes
  around it (core/statics/solver.py, core/statics/newton.py), Python between compiled calls;
- "geometry, offsets": element rows and error offsets per angle (core/statics/equivalent.py, and
  the dynamic model's compiled geometry of its steps, core/dynamics/dynamic_geometry.py);
- "Newmark kernel": the dynamic model's compiled step (core/dynamics/kernels.py);
- "numpy": numpy and scipy routines called from Python;
- "other Python": everything else (sampling, metrics, windup bookkeeping, the dynamic
  model's chunks outside those, ...).

    python studies/benchmarks/bench_profile.py [--reducers 16] [--seconds 0.2] [--top 6]
"""

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
GROUPS = (
    "compiled Newton",
    "continuation, release",
    "geometry, offsets",
    "Newmark kernel",
    "numpy",
    "other Python",
)


def group_of(filename: str, name: str) -> str:
    """The group a function's own time belongs to (module docstring)."""
    path = filename.replace("\\", "/")
    if path.endswith("core/statics/newton_kernel.py"):
        return "compiled Newton"
    if path.endswith(("core/statics/solver.py", "core/statics/newton.py")):
        return "continuation, release"
    if path.endswith(("core/statics/equivalent.py", "core/dynamics/dynamic_geometry.py")):
        return "geometry, offsets"
    if path.endswith("core/dynamics/kernels.py"):
        return "Newmark kernel"
    if "numpy" in path or "scipy" in path or filename == "~":
        return "numpy"
    return "other Python"


def profiled(work):
    """(wall time without the profiler [s], {group: share of the profiled own time}, top
    functions [(share, label)]) of work()."""
    work()  # untimed: compile or load the kernels
    start = time.perf_counter()
    work()
    wall = time.perf_counter() - start
    profiler = cProfile.Profile()
    profiler.enable()
    work()
    profiler.disable()
    stats = pstats.Stats(profiler).stats
    total = sum(v[2] for v in stats.values()) or 1.0
    shares = dict.fromkeys(GROUPS, 0.0)
    for (filename, _line, name), values in stats.items():
        shares[group_of(filename, name)] += values[2] / total
    top = sorted(stats.items(), key=lambda item: -item[1][2])
    labels = [
        (values[2] / total, f"{name} ({Path(filename).name}:{line})")
        for (filename, line, name), values in top
    ]
    return wall, shares, labels


def study_route(path: Path, reducers: int):
    from tolerance import montecarlo
    from tolerance.evaluate import evaluate
    from tolerance.study import load_study

    study = load_study(path)
    X = montecarlo.rows(study, 0, reducers)
    return study, (lambda: evaluate(study, X))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=16)
    parser.add_argument(
        "--seconds",
        type=float,
        default=0.2,
        help="simulated seconds of the dynamic route (after a 0.05 s ramp)",
    )
    parser.add_argument("--top", type=int, default=6, help="functions listed per route")
    args = parser.parse_args()

    from rvfmu.core.dynamics.simulation import simulate
    from rvfmu.core.reducer.design import preset
    from rvfmu.core.reducer.errors import load_errors

    rows = []
    for label, file in (
        ("no load, clearances", "rv40e_121_full.toml"),
        ("rated", "rv40e_121_full_rated.toml"),
    ):
        study, work = study_route(ROOT / "studies" / file, args.reducers)
        wall, shares, top = profiled(work)
        rows.append(
            (
                f"{label} ({study.points} points)",
                f"{args.reducers} reducers",
                wall,
                f"{args.reducers / wall:.2f} reducers/s",
                shares,
                top,
            )
        )
    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    holder = {}

    def dynamic():
        holder["sim"] = simulate(
            design, errors, speed_rpm=1600.0, load=design.rated_torque / 2, duration=args.seconds, ramp=0.05
        )

    wall, shares, top = profiled(dynamic)
    sim = holder["sim"]
    rows.append(
        (
            "dynamic step (Newmark, friction)",
            f"{sim.time.size - 1} steps",
            wall,
            f"{sim.time[-1] / wall:.2f} x real time",
            shares,
            top,
        )
    )

    print("one core; wall time without the profiler; shares of the profiled own time [%]")
    head = f"{'route':<36} {'size':>14} {'wall [s]':>9} {'throughput':>22}"
    print(head + "".join(f" {g:>22}" for g in GROUPS))
    for label, size, wall, throughput, shares, _ in rows:
        print(
            f"{label:<36} {size:>14} {wall:>9.2f} {throughput:>22}"
            + "".join(f" {100 * shares[g]:>22.1f}" for g in GROUPS)
        )
    for label, _, _, _, _, top in rows:
        print(f"\n{label}: largest own times")
        for share, name in top[: args.top]:
            print(f"  {100 * share:5.1f} %  {name}")

    cores = os.cpu_count() or 1
    print(f"\nthreads of the compiled iteration (one process): 1 against {cores}")
    print(f"{'route':<36} {'1 thread [s]':>13} {f'{cores} threads [s]':>14} {'ratio':>7}")
    for label, file in (
        ("no load, clearances", "rv40e_121_full.toml"),
        ("rated", "rv40e_121_full_rated.toml"),
    ):
        study, work = study_route(ROOT / "studies" / file, args.reducers)
        walls = []
        for threads in (1, cores):
            os.environ["RVTE_THREADS"] = str(threads)
            start = time.perf_counter()
            work()
            walls.append(time.perf_counter() - start)
        os.environ["RVTE_THREADS"] = "1"
        print(
            f"{label + f' ({study.points} points)':<36} {walls[0]:>13.2f} {walls[1]:>14.2f} "
            f"{walls[0] / walls[1]:>7.2f}"
        )


if __name__ == "__main__":
    main()

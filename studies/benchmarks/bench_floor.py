"""What the model's definitions allow: each route's solves counted, and its speed if every
solve took the fewest Newton steps it can.

The speed targets of the quasi-static and the dynamic routes are measured here against
the work the model's definitions prescribe, on one core (BLAS and the compiled iteration on
one thread):

- the quasi-static routes of the complete RV-40E-121 study (`--reducers` reducers drawn by
  its Monte Carlo sampler and evaluated as `rvte mc` does: the TE curve, then the windup
  test): at no load with the bearing clearances (studies/rv40e_121_full.toml, 3200 points)
  and at rated load (studies/rv40e_121_full_rated.toml, 720 points).  Every call of the
  compiled Newton iteration (`newton_kernel.newton_pairs`) is timed and its Newton steps
  counted, by the stage of docs/model.md section 5 it belongs to: the solves at 10 probes
  and at the probe, the release rounds that let the weak springs go, the solves under load,
  and those of the error-free reducer that give the first guess.  A solve whose start is
  not already its solution takes at least two Newton steps: one that reaches the solution
  and one that finds the update below the step tolerance (`newton.STEP_TOLERANCE`, 1e-14
  m).  "At fewest" is the iteration's floor: each solve at two steps, or at one where it
  took one, at what a step of its stage costs now (the stage's mean).
- the dynamic step (Newmark with friction, seed 002 errors, 1600 rpm, half the rated load,
  `--seconds` after the ramp): its element forces and Newton iterations per step are
  counted on a short run with the kernels as plain numpy (RVTE_NUMBA=0, in a child
  process: the same algorithm); one evaluation of the element forces with the Newmark
  residual (`kernels._newmark_residual`) and one elimination of the 18 x 18 tangent
  (`kernels.factor_step` and `kernels.solve_factors`) are timed compiled on a state of the run; the element geometry of
  the steps is timed as built (`DynamicModel._chunk`).  A step takes at least its
  geometry, one evaluation and one elimination: the floor.  The FMU's dynamic model
  steps the same Newmark at internal steps of 0.1 ms (`dynamic_reducer.DEFAULT_INTERNAL_STEP`),
  ten to a 1 ms communication step: its floor is that step over the same floor, before
  anything the communication step adds (`bench_dynamic.py` measures the FMU itself).

The targets (issue "Speed"): no load 20 reducers/s/core, rated 300 reducers/s/core, Newmark
30 x real time, the dynamic FMU 10 x.

    python studies/benchmarks/bench_floor.py [--reducers 16] [--seconds 0.2]
"""

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
FEWEST_STEPS = 2  # a solve: one Newton step to the solution, one that finds it there
TARGETS = {"no load": 20.0, "rated": 300.0, "Newmark": 30.0, "FMU": 10.0}
SPEED_RPM = 1600.0


class StageCounter:
    """Times and counts the compiled Newton iteration's calls by solver stage, while installed
    (`installed`): it wraps `newton_kernel.newton_pairs` and `solver.ReducedSystem`'s
    `solve`, `_solve_group` and `solver._nominal_guess`, which name the stage."""

    def __init__(self):
        # stage: [solves, Newton steps, seconds, steps had each solve taken at most FEWEST_STEPS]
        self.stats = defaultdict(lambda: [0, 0, 0.0, 0])
        self.local = threading.local()

    def stage(self, loads, probe, release):
        """The stage a group of solves belongs to (docs/model.md section 5)."""
        what = "release round" if release else "solve"
        multiple = abs(loads[0] / probe) if len(loads) and probe else float("inf")
        where = f"no load, {what} at {multiple:g} x probe" if multiple <= 10.5 else f"under load, {what}"
        return where + (" (error-free guess)" if getattr(self.local, "nominal", False) else "")

    def installed(self):
        """A context manager: the wrappers in place, then the originals back."""
        from contextlib import contextmanager

        import numpy as np

        from rvfmu.core.statics import newton_kernel, solver

        counter = self
        kernel, solve, group, nominal = (
            newton_kernel.newton_pairs,
            solver.ReducedSystem.solve,
            solver.ReducedSystem._solve_group,
            solver._nominal_guess,
        )

        def timed_kernel(*args):
            start = time.perf_counter()
            result = kernel(*args)
            seconds = time.perf_counter() - start
            iterations = args[newton_kernel.newton_pairs_argument("iterations")]
            row = counter.stats[getattr(counter.local, "stage", "other")]
            row[0] += iterations.size
            row[1] += int(iterations.sum())
            row[2] += seconds
            row[3] += int(np.minimum(iterations, FEWEST_STEPS).sum())
            return result

        def labelled_solve(system, errors, sample, angle, tau_load, half, probe, *args, **kwargs):
            counter.local.probe = probe
            return solve(system, errors, sample, angle, tau_load, half, probe, *args, **kwargs)

        def labelled_group(
            system, group_, angle, f0, pin_b, brg_off, c_half, loads, *args, centre=None, **kwargs
        ):
            counter.local.stage = counter.stage(loads, counter.local.probe, centre is not None)
            return group(
                system, group_, angle, f0, pin_b, brg_off, c_half, loads, *args, centre=centre, **kwargs
            )

        def labelled_nominal(*args, **kwargs):
            counter.local.nominal = True
            try:
                return nominal(*args, **kwargs)
            finally:
                counter.local.nominal = False

        @contextmanager
        def wrapped():
            newton_kernel.newton_pairs = timed_kernel
            solver.ReducedSystem.solve = labelled_solve
            solver.ReducedSystem._solve_group = labelled_group
            solver._nominal_guess = labelled_nominal
            try:
                yield self
            finally:
                newton_kernel.newton_pairs = kernel
                solver.ReducedSystem.solve = solve
                solver.ReducedSystem._solve_group = group
                solver._nominal_guess = nominal

        return wrapped()


def quasi_static(file: str, reducers: int):
    """(study, wall [s], {stage: `StageCounter.stats` row}) of one timed evaluation of
    `reducers` of the study's reducers, after an untimed one (numba loads its kernels)."""
    from tolerance import montecarlo
    from tolerance.evaluate import evaluate
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / file)
    X = montecarlo.rows(study, 0, reducers)
    evaluate(study, X)
    counter = StageCounter()
    with counter.installed():
        start = time.perf_counter()
        evaluate(study, X)
        wall = time.perf_counter() - start
    return study, wall, dict(counter.stats)


def print_stages(label, study, reducers, wall, stats):
    """The stage table of one quasi-static route; returns its summary row."""
    pairs = reducers * study.points
    newton = sum(row[2] for row in stats.values())
    floor = 0.0  # [s]: every solve at its fewest steps, at its stage's cost per step
    print(
        f"\n{label} ({study.points} points, {reducers} reducers, {wall:.2f} s, "
        f"{reducers / wall:.2f} reducers/s; the compiled iteration {100 * newton / wall:.0f} %)"
    )
    print(
        f"{'stage':<56} {'solves/point':>12} {'steps/solve':>11} {'fewest':>7} "
        f"{'us/step':>8} {'us/point':>9} {'at fewest':>10}"
    )
    for stage, (solved, steps, seconds, fewest) in sorted(stats.items(), key=lambda item: -item[1][2]):
        per_step = seconds / max(steps, 1)
        floor += fewest * per_step
        print(
            f"{stage:<56} {solved / pairs:>12.3f} {steps / max(solved, 1):>11.2f} "
            f"{fewest / max(solved, 1):>7.2f} {1e6 * per_step:>8.2f} "
            f"{1e6 * seconds / pairs:>9.1f} {1e6 * fewest * per_step / pairs:>10.1f}"
        )
    print(
        f"{'all':<56} {'':>12} {'':>11} {'':>7} {'':>8} {1e6 * newton / pairs:>9.1f} "
        f"{1e6 * floor / pairs:>10.1f}"
    )
    rest = wall - newton
    return (label, reducers / wall, reducers / (floor + rest), reducers / floor)


def dynamic_counts(seconds: float) -> dict:
    """Element-force evaluations and eliminations per Newmark step, counted on a run with
    the kernels as plain numpy in a child process."""
    script = (
        "import json, os\n"
        "os.environ['RVTE_NUMBA'] = '0'\n"
        "from rvfmu.core.dynamics import kernels\n"
        "from rvfmu.core.reducer.design import preset\n"
        "from rvfmu.core.reducer.errors import load_errors\n"
        "from rvfmu.core.dynamics.simulation import simulate\n"
        "count = {'evaluations': 0, 'eliminations': 0}\n"
        "residual, factor = kernels._residual, kernels.factor_step\n"
        "def counted_residual(*a):\n"
        "    count['evaluations'] += 1\n"
        "    return residual(*a)\n"
        "def counted_factor(*a):\n"
        "    count['eliminations'] += 1\n"
        "    return factor(*a)\n"
        "kernels._residual, kernels.factor_step = counted_residual, counted_factor\n"
        "d = preset('RV-40E-121')\n"
        f"e = load_errors({str(ROOT / 'studies' / 'seed002_errors.toml')!r}, d)\n"
        f"sim = simulate(d, e, speed_rpm={SPEED_RPM}, load=d.rated_torque / 2, "
        f"duration={seconds}, ramp=0.01)\n"
        "count['steps'] = sim.time.size - 1\n"
        "print(json.dumps(count))\n"
    )
    env = dict(os.environ, RVTE_NUMBA="0")
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=ROOT, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def dynamic(seconds: float):
    """{what: value} of the compiled Newmark route: wall, steps, time in the compiled steps and
    in the element geometry, and one evaluation and one elimination timed alone."""
    import numba
    import numpy as np

    from rvfmu.core.dynamics import dynamic as dynamic_module
    from rvfmu.core.dynamics import kernels, newmark
    from rvfmu.core.dynamics.simulation import simulate
    from rvfmu.core.reducer.design import preset
    from rvfmu.core.reducer.errors import load_errors

    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)

    def run():
        return simulate(
            design, errors, speed_rpm=SPEED_RPM, load=design.rated_torque / 2, duration=seconds, ramp=0.05
        )

    run()  # numba loads its kernels
    spent = {"steps": 0.0, "geometry": 0.0}
    kept = {}
    steps_kernel, chunk = newmark.newmark_steps, dynamic_module.DynamicModel._chunk

    def timed_steps(el, g, first, last, mass, q, v, a, *rest):
        start = time.perf_counter()
        result = steps_kernel(el, g, first, last, mass, q, v, a, *rest)
        spent["steps"] += time.perf_counter() - start
        kept["state"] = (el, g, last - 1, mass, q.copy(), v.copy(), a.copy())
        return result

    def timed_chunk(self, start_step, stop):
        start = time.perf_counter()
        result = chunk(self, start_step, stop)
        spent["geometry"] += time.perf_counter() - start
        return result

    newmark.newmark_steps, dynamic_module.DynamicModel._chunk = timed_steps, timed_chunk
    try:
        start = time.perf_counter()
        sim = run()
        wall = time.perf_counter() - start
    finally:
        newmark.newmark_steps, dynamic_module.DynamicModel._chunk = steps_kernel, chunk

    el, g, k, mass, q, v, a = kept["state"]
    h = float(g.h[k])

    @numba.njit
    def evaluations(repeat, el, g, k, q, v, a, mass, h):
        n = q.size
        f, residual = np.empty(n), np.empty(n)
        K, C = np.empty((n, n)), np.empty((n, n))
        q_old, v_old, a_old, a_new = q - h * v, v.copy(), a.copy(), a.copy()
        work = kernels.scratch(el, g)
        total = 0.0
        for _ in range(repeat):
            power = kernels._newmark_residual(
                el,
                g,
                k,
                q,
                v,
                a_new,
                q_old,
                v_old,
                a_old,
                h,
                newmark.BETA,
                newmark.GAMMA,
                mass,
                f,
                K,
                C,
                residual,
                work,
            )
            total += power[0]
        return total, K, C

    @numba.njit
    def eliminations(repeat, J):
        n = J.shape[0]
        A, x, pivots = np.empty((n, n)), np.empty(n), np.empty(n, dtype=np.int64)
        for _ in range(repeat):
            A[:, :] = J
            for i in range(n):
                x[i] = 1.0
            kernels.factor_step(A, pivots)
            kernels.solve_factors(A, pivots, x)
        return x

    repeat = 20000
    _, K, C = evaluations(1, el, g, k, q, v, a, mass, h)
    J = K + C * (newmark.GAMMA / (newmark.BETA * h)) + np.diag(mass / (newmark.BETA * h * h))
    eliminations(1, J)
    start = time.perf_counter()
    evaluations(repeat, el, g, k, q, v, a, mass, h)
    evaluation = (time.perf_counter() - start) / repeat
    start = time.perf_counter()
    eliminations(repeat, J)
    elimination = (time.perf_counter() - start) / repeat
    steps = sim.time.size - 1
    return {
        "wall": wall,
        "simulated": float(sim.time[-1] - sim.time[0]),
        "steps": steps,
        "step": h,
        "in steps": spent["steps"],
        "geometry": spent["geometry"],
        "evaluation": evaluation,
        "elimination": elimination,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--reducers", type=int, default=16, help="reducers of each quasi-static route (default 16)"
    )
    parser.add_argument(
        "--seconds",
        type=float,
        default=0.2,
        help="simulated seconds of the dynamic route after its ramp (default 0.2)",
    )
    parser.add_argument(
        "--count-seconds",
        type=float,
        default=0.03,
        help="simulated seconds of the counted plain-numpy run (default 0.03)",
    )
    args = parser.parse_args()
    if args.reducers < 1 or args.seconds <= 0.0 or args.count_seconds <= 0.0:
        parser.error("--reducers must be >= 1, --seconds and --count-seconds > 0")

    print(
        "one core; a stage's time is that of its compiled Newton calls; 'fewest': Newton "
        "steps per solve had each taken at most two; 'at fewest': its time then [us]"
    )
    summary = []
    for label, file in (("no load", "rv40e_121_full.toml"), ("rated", "rv40e_121_full_rated.toml")):
        study, wall, stats = quasi_static(file, args.reducers)
        summary.append(print_stages(label, study, args.reducers, wall, stats))

    d = dynamic(args.seconds)
    counts = dynamic_counts(args.count_seconds)
    per_step = d["wall"] / d["steps"]
    geometry = d["geometry"] / d["steps"]
    evaluations = counts["evaluations"] / counts["steps"]
    eliminations = counts["eliminations"] / counts["steps"]
    floor = geometry + d["evaluation"] + d["elimination"]
    real = d["simulated"] / d["wall"]
    print(
        f"\ndynamic step (Newmark with friction, {d['steps']} steps of {1e6 * d['step']:.1f} us, "
        f"{d['wall']:.2f} s, {real:.2f} x real time)"
    )
    print(f"{'what':<58} {'per step':>10} {'us':>8}")
    print(f"{'the whole run (setup, record and metrics included)':<58} {'':>10} {1e6 * per_step:>8.2f}")
    print(f"{'the compiled steps':<58} {'':>10} {1e6 * d['in steps'] / d['steps']:>8.2f}")
    print(f"{'element geometry of the steps':<58} {'':>10} {1e6 * geometry:>8.2f}")
    print(
        f"{'element forces and Newmark residual (counted, plain numpy)':<58} "
        f"{evaluations:>10.2f} {1e6 * d['evaluation']:>8.2f}"
    )
    print(
        f"{'eliminations of the tangent (counted, plain numpy)':<58} "
        f"{eliminations:>10.2f} {1e6 * d['elimination']:>8.2f}"
    )
    print(f"{'floor: geometry, one evaluation, one elimination':<58} {'':>10} {1e6 * floor:>8.2f}")

    print("\nroute: throughput now, with every solve at its fewest steps, and the target")
    print(f"{'route':<10} {'now':>14} {'floor, rest as now':>20} {'floor, Newton alone':>20} {'target':>10}")
    for label, now, floor_rest, floor_alone in summary:
        print(
            f"{label:<10} {now:>14.2f} {floor_rest:>20.2f} {floor_alone:>20.2f} "
            f"{TARGETS[label]:>10.0f}   reducers/s, one core"
        )
    from rvfmu.core.steppers.dynamic_reducer import DEFAULT_INTERNAL_STEP

    bare = d["evaluation"] + d["elimination"]
    for label, step, now in (
        ("Newmark", d["step"], f"{real:.2f}"),
        ("FMU", DEFAULT_INTERNAL_STEP, "bench_dynamic"),
    ):
        print(
            f"{label:<10} {now:>14} {step / floor:>20.2f} {step / bare:>20.2f} "
            f"{TARGETS[label]:>10.0f}   x real time"
        )
    print("(the dynamic floor alone: one evaluation and one elimination a step, no geometry)")


if __name__ == "__main__":
    main()

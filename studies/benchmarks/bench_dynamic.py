"""Speed of the dynamic model: real-time factor of the Newmark integrator beside solve_ivp.

What it measures, on one core (BLAS threads set to 1 before numpy loads):
- the RV-40E-121 with the seed 002 errors at 1600 rpm input and half its rated
  load, Newmark at the default step, for `--revolutions` output revolutions
  after the start ramp (one revolution is 4.54 s simulated);
- scipy's solve_ivp (BDF, the adaptive reference) on the first `--reference`
  seconds of the same run, and Newmark on that same interval, so the ratio
  column compares the two integrators on equal work;
- where the Newmark time goes (cProfile, the five largest own times).
Real-time factor = simulated time / wall time.  Target: >= 1 (aim 10).

Run:  python studies/benchmarks/bench_dynamic.py [--revolutions 1] [--reference 0.004]
"""

import argparse
import cProfile
import os
import pstats
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--revolutions", type=float, default=1.0)
    parser.add_argument("--reference", type=float, default=0.004,
                        help="seconds at speed for the solve_ivp comparison")
    args = parser.parse_args()

    from rvfmu.core.design import preset
    from rvfmu.core.errors import load_errors
    from rvfmu.core.simulation import simulate

    design = preset("RV-40E-121")
    errors = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    load = design.rated_torque / 2
    rows = []

    def run(label, **options):
        start = time.perf_counter()
        sim = simulate(design, errors, speed_rpm=1600.0, load=load, **options)
        seconds = time.perf_counter() - start
        rows.append((label, sim.time.size - 1, sim.time[-1], seconds))
        return sim

    short = dict(duration=args.reference, ramp=args.reference)
    run("Newmark, short run", **short)
    run("solve_ivp BDF, short run", method="BDF", **short)
    profiler = cProfile.Profile()
    profiler.enable()
    full = run(f"Newmark, {args.revolutions:g} output rev", revolutions=args.revolutions)
    profiler.disable()

    print(f"RV-40E-121, seed 002 errors, 1600 rpm, load {load:g} N*m, step "
          f"{full.step * 1e6:.1f} us, {full.failed_steps} unconverged steps")
    base = rows[1][3] / rows[1][2]
    print(f"{'what':<32} {'steps':>7} {'simulated [s]':>14} {'wall [s]':>9} {'steps/s':>9} "
          f"{'real-time x':>12} {'ratio':>7}")
    for label, steps, simulated, seconds in rows:
        per = seconds / simulated
        print(f"{label:<32} {steps:>7} {simulated:>14.4f} {seconds:>9.2f} {steps / seconds:>9.0f} "
              f"{simulated / seconds:>12.3f} {base / per:>7.1f}")
    print("\nwhere the Newmark time goes (own time, largest five):")
    stats = pstats.Stats(profiler)
    total = sum(v[2] for v in stats.stats.values())
    top = sorted(stats.stats.items(), key=lambda item: -item[1][2])[:5]
    for (filename, line, name), values in top:
        print(f"  {100 * values[2] / total:5.1f} %  {name} ({Path(filename).name}:{line})")


if __name__ == "__main__":
    main()

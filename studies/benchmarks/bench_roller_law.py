"""What the roller law of the crank bearings, and the pins' Hertz law, cost the quasi-static model.

The same 16 reducers of studies/quick_mc.toml (the calibrated RV-40E-121 with
seed 002's tolerances), 720 points per output revolution, solved twice in this
process: with the crank bearings as linear springs of their stated stiffness
(the baseline), with the rollers of the preset's [sources] given, so that
they follow the roller law, and with the pins' groove of its [sources] given
too, so that the pins follow the Hertz law (docs/model.md section 6).  Three jobs: the no-load
TE curve, the TE curve at rated torque, and the windup test (lost motion and
rigidity, 8 positions).  Each time is the best of `--repeats` runs, after one
run that compiles.  The ratio column is each one's time over the baseline's.

Run:  python studies/benchmarks/bench_roller_law.py [--repeats 3]
"""

import argparse
import math
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REDUCERS = 16
POINTS = 720


def best_of(job, repeats):
    job()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        job()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.reducer.design import preset_file
    from rvfmu.core.statics.quasistatic import equilibria, input_angles, windup
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    errors = errors_from_unit(study, sample(study, REDUCERS))
    linear = study.design.with_fields(needle_rollers=0, tapered_rollers=0, pin_groove_clearance=0.0)
    given = preset_file("RV-40E-121")
    given = given if given["needle_rollers"] else given["sources"]
    law = linear.with_fields(
        needle_rollers=given["needle_rollers"],
        needle_roller_length=given["needle_roller_length_mm"] * 1e-3,
        tapered_rollers=given["tapered_rollers"],
        tapered_roller_length=given["tapered_roller_length_mm"] * 1e-3,
        tapered_contact_angle=math.radians(given["tapered_contact_angle_deg"]),
    )
    hertz = law.with_fields(pin_groove_clearance=preset_file("RV-40E-121")["pin_groove_clearance_mm"] * 1e-3)
    theta_in = input_angles(linear, POINTS)
    rated = -linear.rated_torque
    jobs = (
        (
            "no-load TE curve",
            f"{REDUCERS} x {POINTS} points",
            lambda d: equilibria(d, errors, theta_in, [0.0]),
        ),
        (
            "TE curve at rated torque",
            f"{REDUCERS} x {POINTS} points",
            lambda d: equilibria(d, errors, theta_in, [rated]),
        ),
        ("windup test (8 positions)", f"{REDUCERS} reducers", lambda d: windup(d, errors)),
    )
    print(f"machine: {machine()}")
    print(f"{'what':<28} {'laws':<22} {'size':>18} {'time [s]':>9} {'throughput':>16} {'ratio':>6}")
    for what, size, job in jobs:
        base = best_of(lambda: job(linear), args.repeats)
        for name, design in (("linear", linear), ("roller law", law), ("roller law, Hertz pins", hertz)):
            seconds = base if design is linear else best_of(lambda: job(design), args.repeats)
            print(
                f"{what:<28} {name:<22} {size:>18} {seconds:>9.3f} "
                f"{REDUCERS / seconds:>9.1f} red./s {seconds / base:>6.2f}"
            )


if __name__ == "__main__":
    main()

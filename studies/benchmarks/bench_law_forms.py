"""What inverting the two contact laws without an inner iteration gains: the Newton-inverted
reference forms and the direct forms side by side (docs/model.md section 6).

The pins' Hertz law (`pin_law`: Newton on v - ln v = c from a cubic table, against a
quintic table with no step) and the crank bearings' roller law (`roller_law`: Newton on
u + C F(u) = s from u = s until it settles, against a tabulated start and one correction).
numba freezes a kernel's callees when it compiles it, so each form runs in its own process,
chosen by RVTE_LAWS (`rvfmu/core/base/compiled.py`; the reference's kernels are compiled afresh,
uncached, which is why its first run is slow).  Each process measures:

- the law calls alone on the RV-40E-121's laws (its pins' (k, b, F*), its needle and its
  tapered bearings' (a, C)): CALLS pin deflections spread over 0-20 um and as many bearing
  deflections 0-20 um beyond half-clearances of 0-15 um (a tenth of them within 1e-9 m of
  the play), in a compiled loop over `contact` / `roller_law` and over arrays (`contacts`,
  `radial_law`, as the numpy code calls them: where numba is, the direct forms run the
  compiled law over the array, the references numpy), as calls per second;
- the three quasi-static jobs of bench_roller_law.py on the same 16 reducers (the calibrated
  RV-40E-121 with seed 002's tolerances, studies/quick_mc.toml), its crank bearings on the
  roller law and its pins on the Hertz law, 720 points per output revolution: the no-load
  TE curve, the TE curve at rated torque, the windup test (8 positions).

Each time is the best of `--repeats` runs after one that compiles, and of `--rounds` pairs of
processes run one after the other (the machine is shared: a time is the least it took); the
ratio column is the reference's time over the direct form's.  The last lines give the
largest difference between the two forms' results (law values, TE, windup): round-off, so
the two processes did run different code, and to the same results.

Run:  python studies/benchmarks/bench_law_forms.py [--repeats 3] [--rounds 2]
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
REDUCERS = 16
POINTS = 720
CALLS = 200_000
FORMS = ("newton", "direct")


def law_arguments(design):
    """(pin deflections (CALLS,), pin law (3,), bearing (s, c, a, C) each (2 CALLS,)): the
    arguments of the law calls, drawn once (seeded) from `design`'s laws."""
    rng = np.random.default_rng(2026)
    pin = rng.uniform(0.0, 20e-6, CALLS)
    laws = design.roller_laws
    a = np.repeat([laws["crank_disc"][0], laws["crank_carrier"][0]], CALLS)
    compliance = np.repeat([laws["crank_disc"][1], laws["crank_carrier"][1]], CALLS)
    c = rng.uniform(0.0, 15e-6, 2 * CALLS)
    beyond = rng.uniform(0.0, 20e-6, 2 * CALLS)
    near = rng.random(2 * CALLS) < 0.1
    beyond[near] = rng.uniform(0.0, 1e-9, near.sum())
    return pin, np.array(design.pin_law, dtype=float), (c + beyond, c, a, compliance)


def measure(forms, repeats, results_file):
    """Run in a process of RVTE_LAWS = `forms`: the timings as a dict, the results saved."""
    import numba
    from bench_jobs import machine
    from bench_roller_law import best_of

    from rvfmu.core.base import compiled
    from rvfmu.core.base.units import ARCSEC
    from rvfmu.core.laws import pin_law, roller_law
    from rvfmu.core.statics.quasistatic import equilibria, input_angles, windup
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    assert compiled.NEWTON_LAWS == (forms == "newton")
    contact, law_of_roller = pin_law.contact, roller_law.roller_law

    @numba.njit(nogil=True)
    def pin_loop(delta, law, out):
        for i in range(delta.size):
            out[0, i], out[1, i], out[2, i] = contact(delta[i], law)

    @numba.njit(nogil=True)
    def roller_loop(table_e, table_de, s, c, a, compliance, out):
        for i in range(s.size):
            out[0, i], out[1, i], out[2, i] = law_of_roller(
                table_e, table_de, s[i], c[i], a[i], compliance[i]
            )

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    errors = errors_from_unit(study, sample(study, REDUCERS))
    from rvfmu.core.reducer.design import preset_file

    given = preset_file("RV-40E-121")
    given = given if given["needle_rollers"] else given["sources"]
    design = study.design.with_fields(
        needle_rollers=given["needle_rollers"],
        needle_roller_length=given["needle_roller_length_mm"] * 1e-3,
        tapered_rollers=given["tapered_rollers"],
        tapered_roller_length=given["tapered_roller_length_mm"] * 1e-3,
        tapered_contact_angle=math.radians(given["tapered_contact_angle_deg"]),
        pin_groove_clearance=preset_file("RV-40E-121")["pin_groove_clearance_mm"] * 1e-3,
    )
    pin, law, bearing = law_arguments(design)
    pin_out, roller_out = np.empty((3, pin.size)), np.empty((3, bearing[0].size))
    table = (roller_law.TABLE_E, roller_law.TABLE_DE)
    times, results = {}, {}
    times["pins' law, compiled"] = (best_of(lambda: pin_loop(pin, law, pin_out), repeats), pin.size)
    times["pins' law, numpy"] = (best_of(lambda: pin_law.contacts(pin, law), repeats), pin.size)
    times["roller law, compiled"] = (
        best_of(lambda: roller_loop(*table, *bearing, roller_out), repeats),
        bearing[0].size,
    )
    times["roller law, numpy"] = (best_of(lambda: roller_law.radial_law(*bearing), repeats), bearing[0].size)
    results["pins' law"] = pin_out
    results["roller law"] = roller_out
    results["pins' law, numpy"] = np.array(pin_law.contacts(pin, law))
    results["roller law, numpy"] = np.array(roller_law.radial_law(*bearing))

    theta_in = input_angles(design, POINTS)
    rated = -design.rated_torque
    jobs = (
        ("no-load TE curve", lambda: equilibria(design, errors, theta_in, [0.0])),
        ("TE curve at rated torque", lambda: equilibria(design, errors, theta_in, [rated])),
        ("windup test (8 positions)", lambda: windup(design, errors)),
    )
    for what, job in jobs:
        times[what] = (best_of(job, repeats), REDUCERS)
        out = job()
        results[what] = (out.te if hasattr(out, "te") else out.windup) / ARCSEC
    np.savez(results_file, **results)
    return {"machine": machine(), "times": times}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--forms", choices=FORMS, help=argparse.SUPPRESS)  # a child's
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.forms:
        timings = measure(args.forms, args.repeats, args.out)
        print(json.dumps(timings))
        return

    runs = {}
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(args.rounds):
            for forms in FORMS:
                out = Path(folder) / f"{forms}.npz"
                child = subprocess.run(
                    [
                        sys.executable,
                        __file__,
                        "--forms",
                        forms,
                        "--out",
                        str(out),
                        "--repeats",
                        str(args.repeats),
                    ],
                    env={**os.environ, "RVTE_LAWS": forms},
                    capture_output=True,
                    text=True,
                    check=True,
                    cwd=Path(__file__).parent,
                )
                timing = json.loads(child.stdout.strip().splitlines()[-1])
                if forms in runs:  # the least time of the rounds
                    for what, (seconds, _size) in runs[forms][0]["times"].items():
                        timing["times"][what][0] = min(timing["times"][what][0], seconds)
                with np.load(out) as saved:
                    runs[forms] = (timing, {k: saved[k] for k in saved.files})

    print(f"machine: {runs['direct'][0]['machine']}")
    print(f"{'what':<28} {'forms':<8} {'size':>16} {'time [s]':>9} {'throughput':>20} {'ratio':>6}")
    for what, (direct_s, size) in runs["direct"][0]["times"].items():
        newton_s = runs["newton"][0]["times"][what][0]
        job = what in ("no-load TE curve", "TE curve at rated torque", "windup test (8 positions)")
        count = f"{REDUCERS} reducers" if job else f"{size} calls"
        for name, seconds in (("Newton", newton_s), ("direct", direct_s)):
            rate = f"{size / seconds:>9.1f} red./s" if job else f"{size / seconds / 1e6:>8.2f} Mcalls/s"
            print(f"{what:<28} {name:<8} {count:>16} {seconds:>9.4f} {rate:>20} {newton_s / seconds:>6.2f}")
    print("largest difference, direct against Newton:")
    for what, new in runs["direct"][1].items():
        old = runs["newton"][1][what]
        if what in ("pins' law", "roller law", "pins' law, numpy", "roller law, numpy"):
            scale = np.maximum(np.abs(old), 1e-300)
            rel = np.abs(new - old) / scale
            big = np.abs(old) > 1e-12 * np.abs(old).max(axis=1, keepdims=True)
            print(
                f"  {what:<26} energy, force, stiffness relative (values above 1e-12 of the "
                f"largest): {', '.join(f'{r[b].max():.1e}' for r, b in zip(rel, big))}"
            )
        else:
            print(f"  {what:<26} {np.max(np.abs(new - old)):.2e} arcsec")


if __name__ == "__main__":
    main()

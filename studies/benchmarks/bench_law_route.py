"""Where the roller law's no-load solve spends its time: Newton steps per pair, and what one
step costs, part by part.

The no-load TE of the studies without bearing clearance (studies/quick_mc.toml,
studies/rv40e_121_sobol.toml) is one Newton solve per (reducer, angle) pair on 15 unknowns
(the discs, and the cranks that the roller law's bearings hold), started from the kinematic
pose with the stated stiffnesses (docs/model.md section 6; `bench_no_load_start.py`).  It is
nearly all of `rvte mc` and `rvte sobol` on those studies.  This script, on one core
(RVTE_THREADS=1), on `--reducers` of a study's own Monte Carlo rows at 720 points:

1. solves them as the studies do, counting each pair's Newton steps in the compiled iteration
   (`newton_kernel.newton_pairs`), and groups the pairs by the largest pin interference the
   kinematic start leaves: how many pairs, their mean steps, their share of all steps;
2. times the compiled parts of one step alone, each over every pair of the roller law's solve
   at its start (a diagnostic, not the solve): the energy, gradient and Hessian in one pass
   (`_evaluate`), the energy alone (`_energy`), its pins and its bearings' law
   (`roller_law.roller_law`) apart, the Cholesky factorisation and solve (`_solve_spd`), and,
   as a bound, the bearings with the law's three powers s^(n - 1) replaced by a square root
   and its start table by a constant (wrong values, the cost of the rest of the law);
3. the whole compiled solve of those pairs: microseconds per pair and per step.

Each time is the best of `--repeats`.  The numbers describe the formulation, not a change: a
step cannot cost less than one evaluation and one factorisation, and a pair from a start a
micrometre off takes four steps at fewest (three to converge, one that finds the last below
the tolerance).

    python studies/benchmarks/bench_law_route.py [--study studies/quick_mc.toml] [--reducers 16] [--repeats 5]
"""

import argparse
import math
import os
import time
from pathlib import Path

os.environ.setdefault("RVTE_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
POINTS = 720
CLASSES = (  # the largest pin interference a pair's start leaves [m], and its label
    (-np.inf, 1e-12, "none (a gap or contact)"),
    (1e-12, 1e-6, "up to 1 um"),
    (1e-6, 5e-6, "1 - 5 um"),
    (5e-6, 20e-6, "5 - 20 um"),
    (20e-6, np.inf, "above 20 um"),
)


def captured_solve(study, reducers):
    """(kernel arguments of the roller law's solve, its start q, each pair's steps, the largest
    pin interference of each pair's start [m]) for `reducers` Monte Carlo rows at no load."""
    from rvfmu.core.statics import newton_kernel, solver
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.newton import pin_delta
    from rvfmu.core.statics.quasistatic import NO_LOAD_PROBE, input_angles
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit

    design = study.design
    errors = errors_from_unit(study, sample(study, reducers))
    model = EquivalentModel(design, input_angles(design, POINTS), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(reducers), np.arange(POINTS), indexing="ij"))
    kernel, elastic, solve = (
        newton_kernel.newton_pairs,
        solver.ReducedSystem._elastic,
        solver.ReducedSystem.solve,
    )
    calls, starts, law = [], [], []

    def kept(*arguments):
        q_start = arguments[17].copy()  # q: the starts, overwritten by the solutions
        kernel(*arguments)
        calls.append((arguments, q_start))

    def law_seen(self, *arguments, start=None, **options):
        law.append(start is not None)  # the roller law's solve, from the kinematic pose
        try:
            return solve(self, *arguments, start=start, **options)
        finally:
            law.pop()

    def start_seen(self, angle, f, pin_b, brg_off, c_half, direction, count, q0=None, **options):
        seen = q0 is not None and law and law[-1]
        if seen:
            delta = pin_delta(self.model.pin_rows[angle], q0[:, self.pin_local], pin_b)
            starts.append(delta.max(axis=(1, 2)))
            calls.clear()
        result = elastic(self, angle, f, pin_b, brg_off, c_half, direction, count, q0, **options)
        if seen:
            starts.append(calls[-1])
        return result

    newton_kernel.newton_pairs, solver.ReducedSystem._elastic = kept, start_seen
    solver.ReducedSystem.solve = law_seen
    try:
        solver.solve_pairs(
            model, errors, s, a, np.zeros(s.size), NO_LOAD_PROBE * design.rated_torque, forces=False
        )
    finally:
        newton_kernel.newton_pairs, solver.ReducedSystem._elastic = kernel, elastic
        solver.ReducedSystem.solve = solve
    if not starts:
        raise SystemExit(
            f"{study.name}: its no-load pairs take the continuation of bearing clearances, not the "
            "roller law's solve from the kinematic pose (bench_floor.py measures that route)"
        )
    interference = np.concatenate(starts[0::2])
    chunks = starts[1::2]
    at = newton_kernel.newton_pairs_argument("iterations")
    steps = np.concatenate([arguments[at] for arguments, _ in chunks])
    return chunks, steps, interference


def part_loops():
    """The compiled loops that time each part over the pairs of one chunk."""
    import numba

    from rvfmu.core.laws.pin_law import contact
    from rvfmu.core.laws.roller_law import N, _hermite, roller_law
    from rvfmu.core.statics.newton_kernel import (
        _bearing_deflections,
        _deflections,
        _energy,
        _evaluate,
        _solve_spd,
    )

    @numba.njit
    def evaluate(angle, K, Kh, brg_rows, shared, gap, Q):
        brg_cols, f, rows, pin_b, pin_local, pin_law, brg_off, c_half, law, table = shared
        n = Q.shape[1]
        grad, hess, Kt = np.empty(n), np.empty((n, n)), np.empty((n, n))
        used = np.empty((2, rows.shape[2]), dtype=np.bool_)
        delta, d = np.empty((2, rows.shape[2])), np.empty((brg_rows.shape[1], 2))
        e = 0.0
        for s in range(Q.shape[0]):
            for i in range(n):
                for j in range(n):
                    Kt[i, j] = K[angle[s], i, j] + Kh[angle[s], i, j]
            e += _evaluate(
                K[angle[s]],
                Kt,
                f[s],
                rows[s],
                pin_b[s],
                pin_local,
                pin_law,
                brg_rows[angle[s]],
                brg_cols,
                brg_off[s],
                c_half[s],
                law,
                table,
                gap,
                Q[s],
                grad,
                hess,
                used,
                delta,
                d,
            )
        return e

    @numba.njit
    def energy(angle, K, brg_rows, shared, Q):
        brg_cols, f, rows, pin_b, pin_local, pin_law, brg_off, c_half, law, table = shared
        delta, d = np.empty((2, rows.shape[2])), np.empty((brg_rows.shape[1], 2))
        e = 0.0
        for s in range(Q.shape[0]):
            e += _energy(
                K[angle[s]],
                f[s],
                rows[s],
                pin_b[s],
                pin_local,
                pin_law,
                brg_rows[angle[s]],
                brg_cols,
                brg_off[s],
                c_half[s],
                law,
                table,
                Q[s],
                delta,
                d,
            )
        return e

    @numba.njit
    def pins(rows, pin_b, pin_local, pin_law, Q):
        delta = np.empty((2, rows.shape[2]))
        e, touching = 0.0, 0
        for s in range(Q.shape[0]):
            _deflections(rows[s], pin_b[s], pin_local, Q[s], delta)
            for j in range(2):
                for k in range(delta.shape[1]):
                    e += contact(delta[j, k], pin_law)[0]
                    touching += delta[j, k] > 0.0
        return e, touching

    @numba.njit
    def cheap_rollers(table_e, table_de, s, c, a):
        rho = c / s
        e, d1, d2 = _hermite(table_e, table_de, rho)
        sn1 = math.sqrt(s)  # in place of s ** (N - 1): a cheap operation, not the law
        force = a * sn1 * s * (e - rho * d1 / (N + 1.0))
        stiffness = a * sn1 * (N * e - 2.0 * N * rho * d1 / (N + 1.0) + rho * rho * d2 / (N + 1.0))
        return a * sn1 * s * s * e / (N + 1.0), force, stiffness

    @numba.njit
    def bearings(angle, brg_rows, brg_cols, brg_off, c_half, law, table, Q, which):
        d = np.empty((brg_rows.shape[1], 2))
        e = 0.0
        for s in range(Q.shape[0]):
            _bearing_deflections(brg_rows[angle[s]], brg_cols, brg_off[s], Q[s], d)
            for b in range(d.shape[0]):
                r = np.sqrt(d[b, 0] ** 2 + d[b, 1] ** 2)
                if which == 0:
                    e += roller_law(table[0], table[1], r, c_half[s, b], law[b, 1], law[b, 2])[0]
                elif which == 1 and r > c_half[s, b]:
                    u = 0.7 * r  # in place of the start table
                    _, force, stiffness = cheap_rollers(table[0], table[1], u, c_half[s, b], law[b, 1])
                    u -= (u + law[b, 2] * force - r) / (1.0 + law[b, 2] * stiffness)
                    e += cheap_rollers(table[0], table[1], u, c_half[s, b], law[b, 1])[0]
                else:
                    e += r
        return e

    @numba.njit
    def cholesky(angle, K, Kh, Q):
        n = Q.shape[1]
        A, L, x, b = np.empty((n, n)), np.empty((n, n)), np.empty(n), np.ones(n)
        done = 0
        for s in range(Q.shape[0]):
            for i in range(n):
                for j in range(n):
                    A[i, j] = K[angle[s], i, j] + Kh[angle[s], i, j]
            done += _solve_spd(A, b, L, x)
        return done

    @numba.njit
    def copies(angle, K, Kh, Q):
        n = Q.shape[1]
        A = np.empty((n, n))
        t = 0.0
        for s in range(Q.shape[0]):
            for i in range(n):
                for j in range(n):
                    A[i, j] = K[angle[s], i, j] + Kh[angle[s], i, j]
            t += A[0, 0]
        return t

    return evaluate, energy, pins, bearings, cholesky, copies


def best_of(repeats, function, *arguments):
    """The least time [s] of `repeats` calls, after one that compiles."""
    function(*arguments)
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        function(*arguments)
        times.append(time.perf_counter() - began)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", default=str(ROOT / "studies" / "quick_mc.toml"))
    parser.add_argument("--reducers", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    from bench_jobs import machine

    from rvfmu.core.statics import newton_kernel
    from tolerance.study import load_study

    study = load_study(args.study)
    chunks, steps, interference = captured_solve(study, args.reducers)
    print(f"machine: {machine()}; one core; {study.name}, {args.reducers} reducers x {POINTS} points")
    print(
        f"\nNewton steps of the roller law's solve ({steps.size} pairs, {steps.mean():.2f} steps a pair on average)"
    )
    print(
        f"{'largest pin interference at the start':<40} {'share of pairs':>15} {'mean steps':>11} {'share of steps':>15}"
    )
    for low, high, label in CLASSES:
        inside = (interference > low) & (interference <= high)
        if not inside.any():
            continue
        print(
            f"{label:<40} {inside.mean():>15.3f} {steps[inside].mean():>11.2f} "
            f"{steps[inside].sum() / steps.sum():>15.3f}"
        )
    print(f"fewest steps of a pair: {steps.min()}")

    arguments, q_start = chunks[0]
    angle, K, Kh, brg_rows, brg_cols, f, rows, pin_b, pin_local, pin_law, brg_off, c_half, law, table = (
        arguments[:14]
    )
    position = newton_kernel.newton_pairs_argument
    gap, iterations = arguments[position("gap_tolerance")], arguments[position("iterations")]
    B = angle.size
    evaluate, energy, pins, bearings, cholesky, copies = part_loops()
    shared = (brg_cols, f, rows, pin_b, pin_local, pin_law, brg_off, c_half, law, table)
    touching = pins(rows, pin_b, pin_local, pin_law, q_start)[1] / B
    parts = [
        (
            "energy, gradient and Hessian (`_evaluate`)",
            evaluate,
            (angle, K, Kh, brg_rows, shared, gap, q_start),
        ),
        ("energy alone (`_energy`)", energy, (angle, K, brg_rows, shared, q_start)),
        (
            f"  its pins ({2 * rows.shape[2]}, {touching:.1f} touching)",
            pins,
            (rows, pin_b, pin_local, pin_law, q_start),
        ),
        (
            f"  its bearings' law ({law.shape[0]} bearings)",
            bearings,
            (angle, brg_rows, brg_cols, brg_off, c_half, law, table, q_start, 0),
        ),
        (
            "  the same without powers and start table (bound)",
            bearings,
            (angle, brg_rows, brg_cols, brg_off, c_half, law, table, q_start, 1),
        ),
        (
            "  the bearings' deflections alone",
            bearings,
            (angle, brg_rows, brg_cols, brg_off, c_half, law, table, q_start, 2),
        ),
        ("Cholesky factorisation and solve", cholesky, (angle, K, Kh, q_start)),
        ("  of which the Hessian's constant part copied", copies, (angle, K, Kh, q_start)),
    ]
    print(f"\nparts of one Newton step, timed alone over the {B} pairs of one chunk at their starts")
    print(f"{'part':<52} {'us a pair':>10}")
    for label, function, part_arguments in parts:
        seconds = best_of(args.repeats, function, *part_arguments)
        print(f"{label:<52} {seconds / B * 1e6:>10.3f}")

    def whole():
        again = list(arguments)
        again[position("q")] = q_start.copy()  # the starts, which the kernel overwrites
        again[position("converged")] = arguments[position("converged")].copy()
        newton_kernel.newton_pairs(*again)

    seconds = best_of(args.repeats, whole)
    print(
        f"\nthe whole compiled solve of those pairs: {seconds / B * 1e6:.2f} us a pair, "
        f"{iterations.mean():.2f} steps, {seconds / iterations.sum() * 1e6:.2f} us a step"
    )


if __name__ == "__main__":
    main()

"""The dynamic step made cheaper without changing what it computes.

- the elimination kept as factors (`kernels.factor_in_place`, `solve_factored`) solves as
  the elimination in place it replaced (`solve_in_place`, kept here) does, to the bit, and LAPACK's stand-in without numba to round-off;
- the forces evaluated without their tangent (`kernels.forces_only`) are the forces, to the bit;
- a Newton update from the factors of the one before (`kernels.REUSE_BELOW`) moves a run by
  far less than the integrator's tolerance against Newton's own updates throughout, and
  saves a third of the eliminations;
- the pins' disc lobes kept from step to step (`dynamic_geometry._same_lobe`) are atan2's:
  the geometry is the numpy reference's over runs of the FMU's small steps;
- the communication step that takes its constants as plain tuples
  (`DynamicReducer._compiled_parts`) is the Python route's, through a change of flank.
No timing here: studies/benchmarks/bench_dynamic.py measures the speed.
"""

import numba
import numpy as np
import pytest

from rvfmu.core.dynamics import kernels
from rvfmu.core.dynamics.dynamic import DynamicModel, Motion
from rvfmu.core.dynamics.dynamic_geometry import LOBE_MARGIN, _same_lobe
from rvfmu.core.dynamics.newmark import BETA, CYCLE_TOLERANCE, GAMMA, MAX_ITERATIONS, TOLERANCE
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import zero_errors
from rvfmu.core.steppers import dynamic_reducer
from rvfmu.core.steppers.dynamic_reducer import DynamicReducer

FAST = 1600 * 2 * np.pi / 60  # rad/s at the input


def test_numba_is_in_use():
    assert kernels.COMPILED, "numba is a dependency: the kernels must compile"


@numba.njit
def solve_in_place(A, x):
    """x <- A^-1 x by Gaussian elimination with partial pivoting, A overwritten; False where
    a pivot is zero: the elimination the step solved with before it kept its factors (the
    reference `kernels.factor_in_place` and `solve_factored` are held to)."""
    n = x.size
    for c in range(n):
        pivot, big = c, abs(A[c, c])
        for r in range(c + 1, n):
            if abs(A[r, c]) > big:
                pivot, big = r, abs(A[r, c])
        if big == 0.0:
            return False
        if pivot != c:
            for j in range(c, n):
                A[c, j], A[pivot, j] = A[pivot, j], A[c, j]
            x[c], x[pivot] = x[pivot], x[c]
        for r in range(c + 1, n):
            m = A[r, c] / A[c, c]
            if m != 0.0:
                for j in range(c + 1, n):
                    A[r, j] -= m * A[c, j]
                x[r] -= m * x[c]
    for r in range(n - 1, -1, -1):
        value = x[r]
        for j in range(r + 1, n):
            value -= A[r, j] * x[j]
        x[r] = value / A[r, r]
    return True


def tangents(n=18, count=20, seed=3):
    """Random tangents that need row swaps (small diagonal), and right-hand sides."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        A = rng.standard_normal((n, n)) * 10.0 ** rng.uniform(-3, 3, (n, 1))
        A[np.diag_indices(n)] *= 1e-3
        yield A, rng.standard_normal(n)


def test_the_factors_solve_as_the_elimination_to_the_bit():
    for A, x in tangents():
        A1, x1 = A.copy(), x.copy()
        assert solve_in_place(A1, x1)
        A2, x2, pivots = A.copy(), x.copy(), np.empty(A.shape[0], dtype=np.int64)
        assert kernels.factor_in_place(A2, pivots)
        assert np.any(pivots != np.arange(A.shape[0]))  # rows were swapped
        kernels.solve_factored(A2, pivots, x2)
        assert np.array_equal(x1, x2)
        # a backward-stable solve: each equation holds to round-off of its own terms (the
        # rows' scales span six decades, so a residual against max |x| would measure the
        # matrix product's round-off, which the BLAS build decides, not the solve's)
        assert np.all(np.abs(A @ x2 - x) <= 1e-13 * (np.abs(A) @ np.abs(x2) + np.abs(x)))
        # a second right-hand side from the same factors
        y = np.arange(1.0, A.shape[0] + 1.0)
        z = y.copy()
        kernels.solve_factored(A2, pivots, z)
        np.testing.assert_allclose(z, np.linalg.solve(A, y), rtol=1e-8)
        # LAPACK's getrf/getrs, the plain-numpy route's, on the same tangent
        A3, x3 = A.copy(), x.copy()
        assert kernels._factor_numpy(A3, pivots)
        kernels._solve_factored_numpy(A3, pivots, x3)
        np.testing.assert_allclose(x3, x1, rtol=1e-9, atol=1e-12 * np.abs(x1).max())


def test_a_singular_tangent_is_told_by_every_route():
    A = np.arange(1.0, 17.0).reshape(4, 4)  # rank 2
    A[:, 3] = 0.0
    pivots = np.empty(4, dtype=np.int64)
    assert not solve_in_place(A.copy(), np.ones(4))
    assert not kernels.factor_in_place(A.copy(), pivots)
    assert not kernels._factor_numpy(A.copy(), pivots)


def reducer_after(design, errors, steps=20, load=-206.0):
    """A DynamicReducer run at 1600 rpm for `steps` 1 ms communication steps."""
    reducer = DynamicReducer(design, errors)
    reducer.initialize(0.0, 0.0, load)
    for k in range(steps):
        reducer.step(k * 1e-3, 1e-3, FAST * (k + 1) * 1e-3, load)
    return reducer


def geometry_of(reducer, count=10):
    """The model's geometry over the next communication step of `reducer` (A = count + 1)."""
    model = reducer.model
    t = reducer.time + 1e-3 * np.arange(count + 1) / count
    model.prepare(
        Motion(
            t, reducer.theta_in + FAST * (t - t[0]), np.full(t.size, FAST), np.zeros(t.size), reducer.tau_load
        )
    )
    return model, model.geometry(1)[0]


@pytest.mark.parametrize("name", ["RV-40E-121", "RV-110E"])
def test_the_forces_without_their_tangent_are_the_forces_to_the_bit(name, seed002):
    design = preset(name)
    errors = seed002 if name == "RV-40E-121" else zero_errors(design)
    reducer = reducer_after(design, errors, steps=5, load=-0.5 * design.rated_torque)
    model, g = geometry_of(reducer)
    el, n = model.elements, model.n
    rng = np.random.default_rng(1)
    work = kernels.scratch(el, g)
    for a in range(1, g.h.size):
        q = reducer.state.q + 1e-7 * rng.standard_normal(n)
        v = reducer.state.v + 1e-3 * rng.standard_normal(n)
        f1, K1, C1 = np.empty(n), np.empty((n, n)), np.empty((n, n))
        p1 = kernels.forces_into(el, g, a, q, v, f1, K1, C1, work)
        f2, K2, C2 = np.empty(n), np.full((n, n), np.nan), np.full((n, n), np.nan)
        p2 = kernels.forces_only(el, g, a, q, v, f2, K2, C2, work, False)
        assert np.array_equal(f1, f2) and p1 == p2
        assert np.all(np.isnan(K2)) and np.all(np.isnan(C2))  # left as they were
        assert p1[0] > 0.0 and np.count_nonzero(K1) > n  # friction, contacts


class Counted:
    """A kernel called from Python that counts its calls."""

    def __init__(self, function):
        self.function, self.calls = function, 0

    def __call__(self, *args):
        self.calls += 1
        return self.function(*args)


def newton_run(model, g, state, reuse_below, monkeypatch):
    """The Newmark steps of g from `state` by `newmark_steps` as Python (its py_func, the
    kernels it calls compiled) with REUSE_BELOW = reuse_below: (q (A, n), eliminations)."""
    monkeypatch.setattr(kernels, "REUSE_BELOW", reuse_below)
    counted = Counted(kernels.factor_step)
    monkeypatch.setattr(kernels, "factor_step", counted)
    A, n = g.h.size, model.n
    q, v, a = (x.copy() for x in (state.q, state.v, state.a))
    out_q, out_v, power = np.empty((A, n)), np.empty((A, n)), np.empty((A, 2))
    most, failed = kernels.newmark_steps.py_func(
        model.elements,
        g,
        1,
        A,
        model.mass,
        q,
        v,
        a,
        BETA,
        GAMMA,
        TOLERANCE,
        CYCLE_TOLERANCE,
        MAX_ITERATIONS,
        out_q,
        out_v,
        power,
    )
    monkeypatch.undo()
    assert failed == 0
    return out_q[1:], counted.calls


def test_the_reused_factors_move_the_run_by_far_less_than_the_tolerance(seed002, monkeypatch):
    """Over 40 communication steps of the RV-40E-121 with its friction at 1600 rpm, the steps
    that reuse the factors for their last update reach Newton's own states within 2e-3 of
    the integrator's tolerance (TOLERANCE, 1e-13 m: 1.12e-3 with the output seal's 0.50 N*m
    from its law on the carrier, 3.9e-4 without it), with a third fewer eliminations; the
    compiled loop is the Python one's to round-off."""
    design = preset("RV-40E-121")
    reducer = reducer_after(design, seed002, steps=3)
    worst, counts = 0.0, {True: 0, False: 0}
    steps = 0
    for _ in range(40):
        model, g = geometry_of(reducer)
        state = reducer.state
        reused, calls = newton_run(model, g, state, kernels.REUSE_BELOW, monkeypatch)
        newton, newton_calls = newton_run(model, g, state, 0.0, monkeypatch)
        counts[True] += calls
        counts[False] += newton_calls
        steps += g.h.size - 1
        worst = max(worst, float(np.abs(reused - newton).max()))
        q, v, a = (x.copy() for x in (state.q, state.v, state.a))
        A, n = g.h.size, model.n
        out_q, out_v, power = np.empty((A, n)), np.empty((A, n)), np.empty((A, 2))
        kernels.newmark_steps(
            model.elements,
            g,
            1,
            A,
            model.mass,
            q,
            v,
            a,
            BETA,
            GAMMA,
            TOLERANCE,
            CYCLE_TOLERANCE,
            MAX_ITERATIONS,
            out_q,
            out_v,
            power,
        )
        np.testing.assert_allclose(out_q[1:], reused, rtol=0, atol=1e-20)
        reducer.step(reducer.time, 1e-3, reducer.theta_in + FAST * 1e-3, reducer.tau_load)
    assert 0.0 < worst < 2e-3 * TOLERANCE
    assert counts[False] >= 3 * steps  # Newton: three eliminations a step
    assert counts[True] <= counts[False] - 0.75 * steps  # reused: one fewer in most steps


def test_a_lobe_is_kept_only_well_inside_it():
    z_c = 39
    angles = 2 * np.pi * np.r_[np.arange(z_c), 0] / z_c
    edges = np.ascontiguousarray(np.stack([np.cos(angles), np.sin(angles)], axis=-1))
    width = 2 * np.pi / z_c
    r = 0.08
    for lobe in (0, 5, z_c - 1):
        for guess in (lobe, (lobe + 1) % z_c, (lobe - 1) % z_c):
            for inside in (0.5, 1e-6, 1 - 1e-6):
                angle = (lobe + inside) * width + 7 * 2 * np.pi
                assert _same_lobe(r * np.cos(angle), r * np.sin(angle), edges, guess, z_c) == lobe
        # within the margin of an edge, or two lobes off, or no lobe before: atan2 decides
        for angle in (lobe * width + 0.2 * LOBE_MARGIN, (lobe + 1) * width - 0.2 * LOBE_MARGIN):
            assert _same_lobe(r * np.cos(angle), r * np.sin(angle), edges, lobe, z_c) == -1
        angle = (lobe + 0.5) * width
        assert _same_lobe(r * np.cos(angle), r * np.sin(angle), edges, (lobe + 2) % z_c, z_c) == -1
        assert _same_lobe(r * np.cos(angle), r * np.sin(angle), edges, -1, z_c) == -1


@pytest.mark.parametrize("name", ["RV-40E-121", "RV-20E"])
def test_the_lobes_kept_over_small_steps_give_the_numpy_geometry(name):
    """Runs of the FMU's 0.1 ms steps (at 1600 rpm, and at 5 rpm where every lobe is kept
    for thousands of steps) and of steps of a third of a lobe: the compiled geometry, whose
    pins keep their lobe from step to step, is the numpy reference's to round-off."""
    from test_dynamic_inputs import random_errors

    design = preset(name)
    model = DynamicModel(design, random_errors(design, 5))
    for speed, step, count in (
        (FAST, 1e-4, 2000),
        (5 * 2 * np.pi / 60, 1e-4, 600),
        (2 * np.pi / design.z_c / 3 * design.ratio / 1e-4, 1e-4, 300),
    ):
        t = step * np.arange(count + 1)
        model.prepare(
            Motion(t, 1.234 + speed * t, np.full(t.size, speed), np.zeros(t.size), -0.3 * design.rated_torque)
        )
        compiled, reference = model._chunk(0, t.size), model._chunk_numpy(0, t.size)
        for field, x, y in zip(reference._fields, compiled, reference):
            np.testing.assert_allclose(
                x,
                y,
                rtol=0,
                atol=1e-13 * max(np.abs(y).max(), 1e-300),
                err_msg=f"{name} {field} at {speed} rad/s",
            )


def test_the_one_call_step_is_the_python_route_through_a_change_of_flank(seed002, monkeypatch):
    """The load changes sign (a new model on the other flank: new constants for the one
    compiled call); the compiled communication step reaches the Python route's states to the
    bit and its outputs to round-off."""
    design = preset("RV-40E-121")
    loads = [-206.0] * 6 + [150.0] * 6 + [-100.0] * 4
    runs = []
    for compiled in (True, False):
        monkeypatch.setattr(dynamic_reducer, "COMPILED", compiled)
        reducer = DynamicReducer(design, seed002)
        reducer.initialize(0.0, 0.0, loads[0])
        outputs, flanks = [], set()
        for k, load in enumerate(loads):
            outputs.append(reducer.step(k * 1e-3, 1e-3, FAST * (k + 1) * 1e-3, load))
            flanks.add(reducer.model.flank)
        runs.append((outputs, reducer.state, flanks))
    (fast, end, flanks), (slow, reference, _) = runs
    assert flanks == {1, -1}
    for name in ("q", "v", "a"):
        assert np.array_equal(getattr(end, name), getattr(reference, name)), name
    for a, b in zip(fast, slow):
        for name in ("te", "tau_in", "p_loss"):
            assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-13, abs=1e-300), name

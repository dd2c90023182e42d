"""The compiled quasi-static Newton iteration against the numpy one it replaces.

Both iterate the same active-set Newton method on the same reduced energy
(rvfmu/core/statics/newton_kernel.py, rvfmu/core/statics/newton.py); the numpy one iterates a
whole chunk at once and is the reference.  Their equilibria must agree to
1e-9 arcsec on every route the solver takes: loaded and no-load, with and
without bearing clearances (the continuation), resisting and driving, the
pairs re-solved on all pins, and the compiled iteration's warm starts from the
neighbouring angle (which the numpy one does not take).
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

from rvfmu.core.reducer.errors import stack
from rvfmu.core.statics import newton_kernel
from rvfmu.core.statics.equivalent import touched_columns
from rvfmu.core.statics.newton_kernel import (
    _bearing_deflections,
    _energy,
    _evaluate,
    _gradient_hessian,
    _solve_spd,
)
from rvfmu.core.statics.quasistatic import te_curve, windup
from tolerance.sampling import errors_from_unit
from tolerance.study import load_study

ROOT = Path(__file__).resolve().parents[1]


AGREE_ARCSEC = 1e-9


def assert_agree(compiled, plain, switch_share=0.0):
    """TE curves equal to AGREE_ARCSEC, but for a share `switch_share` of the pairs that may
    differ by up to 1e-5 arcsec: at no load with bearing clearances, where a bearing ends
    within round-off of its clearance circle at the probe solution (|d| - c ~ 1e-17 m), the
    step back to zero load takes the tangent from one side of its switch or the other."""
    diff = np.abs(compiled - plain)
    assert np.mean(diff > AGREE_ARCSEC) <= switch_share, np.sort(diff.ravel())[-5:]
    assert diff.max() <= (1e-5 if switch_share else AGREE_ARCSEC), diff.max()


def both(run):
    """run() with the compiled iteration, then with the numpy one."""
    assert newton_kernel.COMPILED, "numba is a dependency: the compiled iteration must be the one in use"
    compiled = run()
    with mock.patch.object(newton_kernel, "COMPILED", False):
        plain = run()
    return compiled, plain


@pytest.fixture(scope="module")
def full_study_reducers():
    """Four reducers of the complete RV-40E-121 study: every error source, the three bearing
    clearances included (rows of the study's own sampling)."""
    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    X = np.random.default_rng(11).random((4, len(study.columns)))
    return study.design, errors_from_unit(study, X)


@pytest.mark.parametrize("tau", [0.0, -412.0, 150.0], ids=["no load", "resisting", "driving"])
def test_with_bearing_clearances_the_compiled_and_numpy_equilibria_agree(full_study_reducers, tau):
    design, errors = full_study_reducers
    compiled, plain = both(lambda: te_curve(design, errors, tau_load=tau, points=400))
    assert compiled.converged.all() and plain.converged.all()
    assert_agree(compiled.te_arcsec, plain.te_arcsec, switch_share=0.005 if tau == 0.0 else 0.0)
    # at no load the pin forces are those of the probe torque's continuation, micronewtons
    np.testing.assert_allclose(compiled.pin_force_max, plain.pin_force_max, rtol=1e-6, atol=1e-5)
    # the curves are not trivial: clearances and errors make tens of arcsec
    assert np.all(compiled.te_pp_arcsec > 5.0)


@pytest.mark.parametrize("tau", [0.0, -412.0], ids=["no load", "rated"])
def test_without_clearances_the_compiled_and_numpy_equilibria_agree(rv40, seed002, tau):
    errors = stack([seed002] * 2)
    compiled, plain = both(lambda: te_curve(rv40, errors, tau_load=tau, points=720))
    assert_agree(compiled.te_arcsec, plain.te_arcsec)
    np.testing.assert_array_equal(compiled.converged, plain.converged)


def test_the_windup_test_agrees(full_study_reducers):
    design, errors = full_study_reducers
    compiled, plain = both(lambda: windup(design, errors, positions=4))
    np.testing.assert_allclose(compiled.lost_motion_arcmin(), plain.lost_motion_arcmin(), rtol=1e-9)
    np.testing.assert_allclose(
        compiled.torsional_rigidity_Nm_per_arcmin(), plain.torsional_rigidity_Nm_per_arcmin(), rtol=1e-9
    )


@pytest.mark.parametrize("tau", [0.0, -412.0], ids=["no load", "rated"])
def test_warm_starts_from_the_neighbouring_angle_reach_the_same_equilibria(full_study_reducers, tau):
    """The compiled iteration starts each angle from its neighbour's solution (solver.chain_links,
    newton.CHAIN_LENGTH): the energy and its minimiser are the same, so is the curve."""
    from rvfmu.core.statics import solver

    design, errors = full_study_reducers
    chained = te_curve(design, errors, tau_load=tau, points=400)
    with mock.patch.object(solver, "chain_links", lambda s, a, t: np.zeros(len(s), dtype=bool)):
        cold = te_curve(design, errors, tau_load=tau, points=400)
    assert chained.converged.all() and cold.converged.all()
    assert_agree(chained.te_arcsec, cold.te_arcsec, switch_share=0.005 if tau == 0.0 else 0.0)


def test_chains_link_neighbouring_angles_of_one_reducer_and_load_only():
    from rvfmu.core.statics.newton import CHAIN_LENGTH, chain_links

    sample = np.repeat([0, 1], 2 * CHAIN_LENGTH)
    angle = np.tile(np.arange(2 * CHAIN_LENGTH), 2)
    load = np.zeros(sample.size)
    load[CHAIN_LENGTH // 2] = 1.0  # another load breaks the chain, twice
    angle[CHAIN_LENGTH + 3] = 99  # an angle that is not the next one, twice
    link = chain_links(sample, angle, load)
    expected = np.ones(sample.size, dtype=bool)
    expected[::CHAIN_LENGTH] = False  # cut every CHAIN_LENGTH pairs
    expected[[CHAIN_LENGTH // 2, CHAIN_LENGTH // 2 + 1, CHAIN_LENGTH + 3, CHAIN_LENGTH + 4]] = False
    expected[2 * CHAIN_LENGTH] = False  # a new reducer
    assert np.array_equal(link, expected)


def test_the_bearing_loops_visit_the_unknowns_a_bearing_touches_and_sum_as_over_all():
    """Each bearing's rows are summed over the unknowns they touch at any angle
    (`equivalent.touched_columns`); the other terms are exact zeros, so the deflections are those
    of the rows over every unknown."""
    rng = np.random.default_rng(5)
    B, p, n = 3, 3, 7
    rows = np.zeros((B, p, 2, n))
    rows[0, 0, 0, 4], rows[2, 0, 1, 1], rows[1, 0, :, 2] = 0.7, -1.3, (0.2, 0.9)  # 1, 2, 4
    rows[:, 2, :, :] = rng.standard_normal((B, 2, n))  # all seven
    cols = touched_columns(rows)
    np.testing.assert_array_equal(cols, [[1, 2, 4, -1, -1, -1, -1], [-1] * n, list(range(n))])
    assert touched_columns(rows[:, :0]).shape == (0, 1)
    offset, q = rng.standard_normal((B, p, 2)), rng.standard_normal((B, n))
    out = np.empty((p, 2))
    for s in range(B):
        _bearing_deflections(rows[s], cols, offset[s], q[s], out)
        np.testing.assert_allclose(
            out, np.einsum("pxn,n->px", rows[s], q[s]) + offset[s], rtol=1e-15, atol=1e-15
        )
        assert np.all(out[1] == offset[s, 1])  # touching nothing: the offset alone


def test_the_weak_springs_pull_as_their_matrix_does_and_leave_the_mechanism_free(rv40):
    """`ReducedSystem.reg_pull`, reg (c - m (m . c)) with m the unit mechanism mode, is the
    release rounds' reg_matrix[angle] @ centre without the matrices: the same to round-off,
    and nothing along the mode."""
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.solver import ReducedSystem

    model = EquivalentModel(rv40, np.linspace(0.0, 0.3, 12), -1)
    system = ReducedSystem(model, np.ones(model.bearing_k.size, dtype=bool))
    angle = np.arange(30) % 12
    centre = np.random.default_rng(7).standard_normal((30, system.N.size)) * 1e-6
    matrix = np.einsum("bij,bj->bi", system.reg_matrix[angle], centre)
    np.testing.assert_allclose(
        system.reg_pull(angle, centre), matrix, rtol=0, atol=1e-14 * np.abs(matrix).max()
    )
    along = system.mode_unit[angle] * 3e-6
    assert np.abs(system.reg_pull(angle, along)).max() <= 1e-15 * system.reg * 3e-6


@pytest.mark.parametrize("laws", ["linear", "hertz and rollers"])
def test_one_pass_gives_the_energy_gradient_and_hessian_of_the_two_to_the_bit(rv40_hertz, laws):
    """`_evaluate`, which every Newton step after the first calls where the step before landed,
    is `_energy` and `_gradient_hessian` (nothing guessed or engaged) in one pass: the same
    numbers to the bit, with pins open, touching and pressed, and bearings inside their play
    and out of it, linear and by the roller law."""
    from rvfmu.core.laws.roller_law import TABLE_DE, TABLE_E
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.solver import ReducedSystem

    model = EquivalentModel(rv40_hertz, np.linspace(0.0, 0.3, 6), -1)
    system = ReducedSystem(model, np.ones(model.bearing_k.size, dtype=bool))
    rng = np.random.default_rng(17)
    n, K, p = system.N.size, 40, system.brg_k.size
    hertz = laws != "linear"
    pin_law = np.array(model.pin_law, dtype=float) if hertz else np.array([2.2e8, 0.0, 0.0])
    brg_law = np.stack(
        [system.brg_k, system.brg_law_a if hertz else 0.0 * system.brg_k, system.brg_law_compliance], axis=-1
    )
    assert (brg_law[:, 1] > 0).any() == hertz and (pin_law[1] > 0) == hertz
    table = np.stack([TABLE_E, TABLE_DE])
    c_half = np.full(p, 5e-6)
    for a in range(6):
        Ks = np.ascontiguousarray(system.K_red[a])
        Kh = np.ascontiguousarray(system.mode_stiffness[a])
        Bs = np.ascontiguousarray(system.brg_rows[a])
        q = rng.standard_normal(n) * 2e-6
        f = rng.standard_normal(n) * 10.0
        rows = rng.standard_normal((2, K, 3)) * 0.3
        pin_b = rng.standard_normal((2, K)) * 1e-6
        pin_b[0, :3] = -np.einsum("kx,x->k", rows[0, :3], q[system.pin_local[0]])  # at contact
        # the bearings' deflections: every other one inside its play, the others 1-20 um out of it
        radius = np.where(np.arange(p) % 2 == 0, 0.5 * c_half, c_half + rng.uniform(1e-6, 2e-5, p))
        turn = rng.uniform(0.0, 2 * np.pi, p)
        brg_off = np.stack([np.cos(turn), np.sin(turn)], axis=-1) * radius[:, None] - np.einsum(
            "bxn,n->bx", Bs, q
        )
        delta, d = np.empty((2, K)), np.empty((p, 2))
        energy = _energy(
            Ks,
            f,
            rows,
            pin_b,
            system.pin_local,
            pin_law,
            Bs,
            system.brg_cols,
            brg_off,
            c_half,
            brg_law,
            table,
            q,
            delta,
            d,
        )
        grad, hess, true_grad = np.empty(n), np.empty((n, n)), np.empty(n)
        used = np.empty((2, K), dtype=bool)
        _gradient_hessian(
            Ks,
            Kh,
            f,
            rows,
            pin_b,
            system.pin_local,
            pin_law,
            Bs,
            system.brg_cols,
            brg_off,
            c_half,
            brg_law,
            table,
            np.zeros((p, 2)),
            False,
            1e-12,
            q,
            np.zeros((2, K), dtype=bool),
            False,
            False,
            grad,
            hess,
            true_grad,
            used,
            delta,
            d,
        )
        inside = np.hypot(d[:, 0], d[:, 1]) <= c_half
        assert inside.any() and not inside.all() and (delta > 0).any() and (delta < 0).any()
        grad1, hess1, used1 = np.empty(n), np.empty((n, n)), np.empty((2, K), dtype=bool)
        energy1 = _evaluate(
            Ks,
            Ks + Kh,
            f,
            rows,
            pin_b,
            system.pin_local,
            pin_law,
            Bs,
            system.brg_cols,
            brg_off,
            c_half,
            brg_law,
            table,
            1e-12,
            q,
            grad1,
            hess1,
            used1,
            np.empty((2, K)),
            np.empty((p, 2)),
        )
        assert energy1 == energy
        assert np.array_equal(grad1, grad) and np.array_equal(grad, true_grad)
        assert np.array_equal(hess1, hess) and np.array_equal(used1, used)


def test_the_cholesky_solve_matches_lapack_and_refuses_an_indefinite_matrix():
    rng = np.random.default_rng(3)
    for n in (3, 9, 15):
        R = rng.standard_normal((n, n))
        # condition as the Hessians': a weak direction six orders below the rest
        A = R @ R.T + n * np.eye(n)
        w, V = np.linalg.eigh(A)
        A = (V * np.r_[w[0] * 1e-6, w[1:]]) @ V.T
        b = rng.standard_normal(n)
        x = np.empty(n)
        assert _solve_spd(A, b, np.empty((n, n)), x)
        np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-8 * np.abs(b).max())
        np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-6)
    indefinite = np.diag([1.0, -1.0, 2.0])
    assert not _solve_spd(indefinite, np.ones(3), np.empty((3, 3)), np.empty(3))


def test_on_every_pin_the_compiled_and_numpy_equilibria_agree(full_study_reducers):
    """The iteration on all z_p pins of each disc (where a pin outside the candidates
    touches, the solver re-solves on all of them): no candidates preselected at all."""
    from rvfmu.core.statics import solver

    design, errors = full_study_reducers
    with mock.patch.object(solver, "CANDIDATE_MARGIN", design.z_p):
        compiled, plain = both(lambda: te_curve(design, errors, tau_load=0.0, points=200))
    assert_agree(compiled.te_arcsec, plain.te_arcsec, switch_share=0.005)
    # and the candidates change nothing: the same equilibria as the preselected iteration
    candidates = te_curve(design, errors, tau_load=0.0, points=200)
    np.testing.assert_allclose(compiled.te_arcsec, candidates.te_arcsec, rtol=0, atol=1e-6)


@pytest.mark.parametrize("clearances", [False, True], ids=["tight", "clearances"])
def test_with_the_roller_law_the_compiled_and_numpy_equilibria_agree(
    rv40_rollers, full_study_reducers, clearances
):
    """The crank bearings follow the roller law under load (rvfmu/core/laws/roller_law.py): both
    iterations evaluate it, the compiled one through the same compiled law."""
    from rvfmu.core.reducer.errors import load_errors

    design = rv40_rollers
    if clearances:
        errors = full_study_reducers[1]
    else:
        errors = stack([load_errors(ROOT / "studies" / "seed002_errors.toml", design)] * 2)
    for tau in (-412.0, -12.0, 150.0, 0.0):
        compiled, plain = both(lambda: te_curve(design, errors, tau_load=tau, points=240))
        assert compiled.converged.all() and plain.converged.all()
        assert_agree(
            compiled.te_arcsec, plain.te_arcsec, switch_share=0.005 if clearances and tau == 0.0 else 0.0
        )


def test_a_changed_callee_in_another_file_is_recompiled_not_loaded_stale(tmp_path):
    """numba's disk cache keys a kernel by its own file: one that calls pin_law's `contact`
    would keep the old contact after pin_law.py changed.  The core's cache is dropped whole
    when any of its sources changes, in any of its rooms (`compiled.SOURCES_STAMP`)."""
    package = tmp_path / "rvfmu"
    shutil.copytree(ROOT / "rvfmu", package, ignore=shutil.ignore_patterns("__pycache__"))
    (package / "core" / "statics" / "probe.py").write_text(  # another room than pin_law's
        "from ..base.compiled import kernel\nfrom ..laws.pin_law import contact\n\n\n"
        "@kernel\ndef force(delta, law):\n    return contact(delta, law)[1]\n"
    )
    script = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "import numpy as np\nfrom rvfmu.core.statics.probe import force\n"
        "print(repr(force(1e-6, np.array([2e8, 5.5e-10, 3.05e6]))))\n"
    )

    def run():
        proc = subprocess.run(
            [sys.executable, "-c", script, str(tmp_path)],
            capture_output=True,
            text=True,
            timeout=600,
            env={**os.environ, "NUMBA_DEBUG_CACHE": "1"},
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        lines = proc.stdout.splitlines()
        return float(lines[-1]), any(line.startswith("[cache] data loaded") for line in lines)

    first, loaded = run()
    assert not loaded and first > 0.0
    again, loaded = run()
    assert loaded and again == first  # unchanged sources: the cache serves
    law = package / "core" / "laws" / "pin_law.py"
    text = law.read_text()
    assert text.count("force = delta / (b * v)") == 1
    law.write_text(text.replace("force = delta / (b * v)", "force = 2.0 * delta / (b * v)"))
    changed, loaded = run()
    assert not loaded and changed == pytest.approx(2.0 * first, rel=1e-15)

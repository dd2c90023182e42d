"""The two contact laws without an inner iteration (rvfmu/core/laws/pin_law.py, roller_law.py)
against their Newton-inverted reference forms, which they replace in the solvers.

The pins' law reads v(c) off a quintic table; the roller law starts from a tabulated
share of the travel and takes one Newton correction.  Both must give the reference's
energy, force and tangent stiffness within 1e-9 relative over the whole range the
reducers use (pins: every positive deflection of a double; bearings: half-clearances
0-30 um, the load and compliance constants of every preset, deflections up to 100 um
beyond the play), compiled and in numpy alike, and a reducer solved on them the same TE.
Where a bearing's deflection lies within some 1e-11 m of its play, u - c is only known to
an ulp of s, the reference's values are at round-off themselves, and the two agree within
the spread the reference shows over a few ulps of its own u.
"""

import math
import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from conftest import ROOT

from rvfmu.core.base import compiled
from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCSEC
from rvfmu.core.laws import pin_law, roller_law
from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import load_errors, stack
from rvfmu.core.statics import newton, newton_kernel, solver
from rvfmu.core.statics.quasistatic import equilibria, input_angles

PRESETS = ("RV-40E-121", "RV-40E-81", "RV-20E", "RV-110E")
RTOL = 1e-9


def laws_of_presets():
    """(pin laws (P, 3), bearing laws (B, 2) of (a, C)) of every preset."""
    pins, bearings = [], []
    for name in PRESETS:
        design = preset(name)
        pins.append(design.pin_law)
        bearings += list(design.roller_laws.values())
    return np.array(pins, dtype=float), np.array(bearings, dtype=float)


# --- the pins' law ---------------------------------------------------------------------------


def test_the_pins_table_is_newtons_root_to_round_off_over_its_whole_range():
    """100 points per interval of both parts of the table, against Newton's roots run until
    they no longer move: within 2e-15 of v, 4e-15 of v - 1 (the tangent's)."""
    fine = np.linspace(pin_law.C_LIMIT, pin_law.ROOT_TABLE_END, 100 * pin_law.FINE_INTERVALS + 1)
    tail = np.linspace(pin_law.ROOT_TABLE_END, pin_law.TAIL_END, 100 * pin_law.TAIL_INTERVALS + 1)
    c = np.concatenate([fine, tail])
    exact = pin_law._newton_roots(c)
    for table in (pin_law._inverse_numpy(c), pin_law._inverse_array(c)):  # numpy, compiled
        assert np.max(np.abs(table - exact) / exact) < 2e-15
        assert np.max(np.abs(table - exact) / (exact - 1.0)) < 4e-15
    some = c[::4999]
    np.testing.assert_array_equal([pin_law._inverse(x) for x in some], pin_law._inverse_array(some))
    np.testing.assert_allclose(pin_law._inverse_numpy(some), pin_law._inverse_array(some), rtol=1e-15, atol=0)
    # the table ends past the largest c of a positive double's y
    assert pin_law.TAIL_END > -math.log(pin_law.Y_SMALLEST)


def _pin_sweep(rng, count):
    """(deflections (count,), laws (count, 3)): the presets' laws, b and F* scaled by up to 3
    either way, deflections log-uniform from 1e-300 of b F* to past the law's limit."""
    pins, _ = laws_of_presets()
    laws = pins[rng.integers(0, len(pins), count)].copy()
    laws[:, 1:] *= np.exp(rng.uniform(-math.log(3.0), math.log(3.0), (count, 2)))
    y = 10.0 ** rng.uniform(-300.0, math.log10(2.0 * pin_law.Y_LIMIT), count)
    return y * laws[:, 1] * laws[:, 2], laws


@numba.njit
def _pin_loop(delta, laws, out_direct, out_newton):
    for i in range(delta.size):
        out_direct[0, i], out_direct[1, i], out_direct[2, i] = pin_law.contact_direct(delta[i], laws[i])
        out_newton[0, i], out_newton[1, i], out_newton[2, i] = pin_law.contact_newton(delta[i], laws[i])


def test_the_pins_direct_form_is_the_newton_form_compiled_and_in_numpy():
    assert newton_kernel.COMPILED
    rng = np.random.default_rng(11)
    delta, laws = _pin_sweep(rng, 200_000)
    direct, reference = np.empty((3, delta.size)), np.empty((3, delta.size))
    _pin_loop(delta, laws, direct, reference)
    assert np.all(np.isfinite(direct)) and np.all(direct[1] > 0.0)
    # energies from y ~ 1e-150 down underflow towards the subnormals, where relative
    # precision ends: compared above 1e-280 J
    np.testing.assert_allclose(direct, reference, rtol=2e-14, atol=1e-280)
    for law in laws[:3]:  # numpy, one law per call as the solvers call it
        d = delta * (law[1] * law[2]) / (laws[:, 1] * laws[:, 2])
        numpy_direct = np.array(pin_law.contacts_direct(d, law))
        numpy_newton = np.array(pin_law.contacts_newton(d, law))
        np.testing.assert_allclose(numpy_direct, numpy_newton, rtol=2e-14, atol=1e-280)
        compiled_direct = np.array([pin_law.contact_direct(x, law) for x in d[:2000]]).T
        np.testing.assert_allclose(compiled_direct, numpy_direct[:, :2000], rtol=2e-15, atol=1e-280)


def test_the_pins_direct_form_covers_every_positive_deflection():
    """A deflection whose y underflows (the smallest double over b F* > 1 m) is read at the
    table's end: a force of at most delta / (b 744), finite, where Newton's start is not."""
    law = np.array([2e8, 5e-10, 4e9])  # b F* = 2 m
    energy, force, tangent = pin_law.contact_direct(5e-324, law)
    assert 0.0 <= force <= 5e-324 / (law[1] * 744.0) and energy == 0.0
    assert 0.0 < tangent < 1.0 / (law[1] * 743.0)
    assert np.all(np.isfinite(pin_law.contacts_direct(np.array([5e-324, 1e-320, 1e-6]), law)))
    assert math.isnan(pin_law.contact_newton(5e-324, law)[1])


# --- the roller law --------------------------------------------------------------------------


def _roller_sweep(rng, count):
    """(s, c, a, C) each (count,): half-clearances 0-30 um (a fifth of them 0), the presets'
    (a, C) and values between them, C = 0 a tenth of them, s - c uniform to 100 um for half
    of them and log-uniform from 1e-13 m for the others."""
    _, bearings = laws_of_presets()
    pick = rng.integers(0, len(bearings), count)
    a = np.where(
        rng.random(count) < 0.5,
        bearings[pick, 0],
        rng.uniform(bearings[:, 0].min(), bearings[:, 0].max(), count),
    )
    compliance = np.where(
        rng.random(count) < 0.5, bearings[pick, 1], rng.uniform(0.0, bearings[:, 1].max(), count)
    )
    compliance[rng.random(count) < 0.1] = 0.0
    c = np.where(rng.random(count) < 0.2, 0.0, rng.uniform(0.0, 30e-6, count))
    beyond = np.where(
        rng.random(count) < 0.5, rng.uniform(0.0, 100e-6, count), 10.0 ** rng.uniform(-13.0, -4.0, count)
    )
    return c + beyond, c, a, compliance


def _reference_spread(s, c, a, compliance):
    """(3, count): how far the reference's energy, force and stiffness move over 8 ulps of
    its own u either way, the round-off they are known to."""
    u = roller_law._series_deflection(s, c, a, compliance)
    here = np.array(roller_law._series_law(u, c, a, compliance))
    ulp = np.spacing(s)
    return np.max(
        [
            np.abs(np.array(roller_law._series_law(u + k * ulp, c, a, compliance)) - here)
            for k in (-8, -4, -2, -1, 1, 2, 4, 8)
        ],
        axis=0,
    )


def _assert_agree(new, reference, spread, s, c):
    """new equals the reference within RTOL, or within its spread; within RTOL alone where
    s - c > 1e-10 m."""
    scale = np.abs(reference)
    off = np.abs(new - reference)
    assert np.all(off <= RTOL * scale + spread), np.max(off / (RTOL * scale + spread))
    clear = s - c > 1e-10
    assert np.all(off[:, clear] <= RTOL * scale[:, clear])


def test_the_roller_laws_direct_form_is_the_newton_form_in_numpy():
    rng = np.random.default_rng(12)
    args = _roller_sweep(rng, 300_000)
    new = np.array(roller_law._radial_numpy(*args))
    reference = np.array(roller_law.radial_law_newton(*args))
    _assert_agree(new, reference, _reference_spread(*args), args[0], args[1])
    # the presets' own bearings over the catalogue's range are far from round-off
    clear = args[0] - args[1] > 1e-8
    worst = np.max(np.abs(new - reference)[:, clear] / np.abs(reference[:, clear]), axis=1)
    assert np.all(worst < 1e-10), worst


@numba.njit
def _roller_loop(table_e, table_de, s, c, a, compliance, out_direct, out_newton):
    for i in range(s.size):
        out_direct[0, i], out_direct[1, i], out_direct[2, i] = roller_law.roller_law_direct(
            table_e, table_de, s[i], c[i], a[i], compliance[i]
        )
        out_newton[0, i], out_newton[1, i], out_newton[2, i] = roller_law.roller_law_newton(
            table_e, table_de, s[i], c[i], a[i], compliance[i]
        )


def test_the_roller_laws_direct_form_is_the_newton_form_compiled_and_agrees_with_numpy():
    assert newton_kernel.COMPILED
    rng = np.random.default_rng(13)
    args = _roller_sweep(rng, 300_000)
    direct, reference = np.empty((3, args[0].size)), np.empty((3, args[0].size))
    _roller_loop(roller_law.TABLE_E, roller_law.TABLE_DE, *args, direct, reference)
    spread = _reference_spread(*args)
    _assert_agree(direct, reference, spread, args[0], args[1])
    _assert_agree(direct, np.array(roller_law._radial_numpy(*args)), spread, args[0], args[1])
    # over arrays (broadcast), where numba is: the compiled law at each bearing
    shaped = [np.broadcast_to(v[:600].reshape(20, 30), (2, 20, 30)) for v in args]
    np.testing.assert_array_equal(
        np.array(roller_law.radial_law_direct(*shaped))[:, 0], direct[:, :600].reshape(3, 20, 30)
    )
    # nothing inside the play, the bearing alone without a spring
    inside = roller_law.roller_law_direct(roller_law.TABLE_E, roller_law.TABLE_DE, 2e-6, 2e-6, 1e9, 1e-9)
    assert inside == (0.0, 0.0, 0.0)
    alone = roller_law.roller_law_direct(roller_law.TABLE_E, roller_law.TABLE_DE, 9e-6, 2e-6, 1e9, 0.0)
    assert alone == roller_law._rollers(roller_law.TABLE_E, roller_law.TABLE_DE, 9e-6, 2e-6, 1e9)


@pytest.mark.parametrize("c", [0.0, 5e-6])
def test_the_roller_laws_direct_force_is_its_energys_derivative(c):
    """The energy's increase over [s1, s2] is the integral of the force, the force's that of
    the stiffness, by 40-point Gauss-Legendre: within 1e-11.  With c = 0 the law is smooth
    (rho = 0); with c > 0, [s1, s2] is where the bearing's rho = c / u spans most of interval
    300 of the E table, over which the interpolated E is one polynomial."""
    nodes, weights = np.polynomial.legendre.leggauss(40)
    _, bearings = laws_of_presets()
    for a, compliance in bearings:
        if c == 0.0:
            s1, s2 = 2e-6, 20e-6
        else:
            u = c * roller_law.INTERVALS / np.array([300.95, 300.05])
            s1, s2 = u + compliance * roller_law._rollers_array(u, c, a)[1]
        s = s1 + 0.5 * (s2 - s1) * (nodes + 1.0)
        w = 0.5 * (s2 - s1) * weights
        law = [
            roller_law.roller_law_direct(roller_law.TABLE_E, roller_law.TABLE_DE, x, c, a, compliance)
            for x in (s1, s2, *s)
        ]
        energy, force, stiffness = np.array(law).T
        assert energy[1] - energy[0] == pytest.approx(np.sum(w * force[2:]), rel=1e-11)
        assert force[1] - force[0] == pytest.approx(np.sum(w * stiffness[2:]), rel=1e-11)


def test_the_roller_laws_direct_form_is_as_consistent_as_the_reference():
    """Central differences of energy and force (h = 1e-4 (s - c)) against force and stiffness
    differ between the two forms by at most 1e-9 of the force and the stiffness where
    s - c > 0.1 um: the one correction adds no inconsistency the solvers could see.  Such a
    difference is round-off of the energy and the force over the step, whose last bits the
    math library sets (below 5e-10 on an Intel Xeon, 5.3e-10 on an AMD EPYC)."""
    rng = np.random.default_rng(14)
    s, c, a, compliance = _roller_sweep(rng, 50_000)
    keep = (compliance > 0.0) & (s - c > 1e-7)
    s, c, a, compliance = s[keep], c[keep], a[keep], compliance[keep]
    h = 1e-4 * (s - c)
    slips = []
    for law in (roller_law._radial_numpy, roller_law.radial_law_newton):
        up, down, here = (np.array(law(x, c, a, compliance)) for x in (s + h, s - h, s))
        slips.append(((up[0] - down[0]) / (2 * h) - here[1], (up[1] - down[1]) / (2 * h) - here[2]))
    assert np.max(np.abs(slips[0][0] - slips[1][0]) / here[1]) < 1e-9
    assert np.max(np.abs(slips[0][1] - slips[1][1]) / here[2]) < 1e-9


# --- the reducer on them, and the switch -----------------------------------------------------


def rv40_errors():
    """(design, errors): the calibrated RV-40E-121 (its crank bearings on the roller law, its
    pins on the Hertz law), with seed 002's errors, those with crank and main bearing
    clearances of 6, 4, 10 um, and two reducers of studies/quick_mc.toml.  Not a larger
    clearance: a disc floating in 20 um of needle clearance at no load is held by the solver's
    step tolerance alone, to some 4e-5 arcsec, where the compiled and the numpy iterations
    on the same law differ by as much."""
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    design = preset("RV-40E-121")
    assert design.pin_law[1] > 0.0 and set(design.roller_laws) == {"crank_disc", "crank_carrier"}
    base = load_errors(ROOT / "studies" / "seed002_errors.toml", design)
    study = load_study(ROOT / "studies" / "quick_mc.toml")
    assert study.design.name == design.name
    cases = [base] + [
        base.replace(
            crank_disc_clearance=np.array([d * 1e-6]),
            crank_carrier_clearance=np.array([k * 1e-6]),
            main_bearing_clearance=np.array([m * 1e-6]),
        )
        for d, k, m in ((6.0, 4.0, 10.0),)
    ]
    return design, stack(cases + [errors_from_unit(study, sample(study, 2))])


@pytest.fixture(scope="module")
def rv40_cases():
    return rv40_errors()


TE_LOADS = (0.0, -0.03, -1.0)  # x rated torque
TE_POINTS = 48


def _te(design, errors):
    theta = input_angles(design, TE_POINTS) + 0.1
    eq = equilibria(design, errors, theta, [f * design.rated_torque for f in TE_LOADS])
    assert eq.converged.all()
    return eq.te / ARCSEC


def test_a_reducer_on_the_direct_forms_has_the_te_of_the_newton_forms_in_numpy(rv40_cases):
    """The numpy path (as without numba: the numpy iteration, the laws in numpy) solved twice
    in this process, the second time on the reference forms: the same TE to 1e-9 arcsec."""
    design, errors = rv40_cases
    with pytest.MonkeyPatch.context() as patch:
        for module in (newton_kernel, pin_law, roller_law):
            patch.setattr(module, "COMPILED", False)
        direct = _te(design, errors)
        patch.setattr(newton, "contacts", pin_law.contacts_newton)
        patch.setattr(newton, "radial_law", roller_law.radial_law_newton)
        patch.setattr(solver, "contacts", pin_law.contacts_newton)
        reference = _te(design, errors)
    assert np.max(np.abs(direct)) > 1.0
    np.testing.assert_allclose(direct, reference, rtol=0, atol=1e-9)


REFERENCE_RUN = """
import numpy as np, sys
sys.path.insert(0, {tests!r})
from rvfmu.core.laws import pin_law, roller_law
from rvfmu.core.base import compiled
assert compiled.NEWTON_LAWS and pin_law.contact is pin_law.contact_newton
assert roller_law.roller_law is roller_law.roller_law_newton
from test_law_forms import _te, rv40_errors
design, errors = rv40_errors()
np.save({out!r}, _te(design, errors))
"""


def test_a_reducer_compiled_on_the_direct_forms_has_the_te_of_the_newton_forms(rv40_cases, tmp_path):
    """RVTE_LAWS=newton compiles the kernels afresh on the reference forms in a process of
    their own (numba freezes a kernel's callees): the same TE to 1e-9 arcsec, and not
    bit for bit, so that process did run other code."""
    assert newton_kernel.COMPILED and not compiled.NEWTON_LAWS
    design, errors = rv40_cases
    direct = _te(design, errors)
    out = tmp_path / "te.npy"
    script = REFERENCE_RUN.format(tests=str(ROOT / "tests"), out=str(out))
    run = subprocess.run(
        [sys.executable, "-c", script],
        env={**os.environ, "RVTE_LAWS": "newton"},
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    reference = np.load(out)
    np.testing.assert_allclose(direct, reference, rtol=0, atol=1e-9)
    assert not np.array_equal(direct, reference)


def test_a_bad_law_forms_setting_is_refused_naming_it(monkeypatch):
    run = subprocess.run(
        [sys.executable, "-c", "import rvfmu.cli"],
        capture_output=True,
        text=True,
        env={**os.environ, "RVTE_LAWS": "exact"},
        timeout=300,
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "rvte: error: environment: RVTE_LAWS = 'exact': must be 'direct' (the default) or 'newton'"
    ]
    monkeypatch.setenv("RVTE_LAWS", "exact")
    with pytest.raises(
        InputError,
        match=r"environment: RVTE_LAWS = 'exact': must be 'direct' "
        r"\(the default\) or 'newton'",
    ):
        compiled._law_forms()
    monkeypatch.setenv("RVTE_LAWS", "newton")
    assert compiled._law_forms() is True
    monkeypatch.delenv("RVTE_LAWS")
    assert compiled._law_forms() is False
    assert pin_law.contact is pin_law.contact_direct and pin_law.contacts is pin_law.contacts_direct
    assert roller_law.roller_law is roller_law.roller_law_direct
    assert roller_law.radial_law is roller_law.radial_law_direct


def test_the_laws_no_load_solve_from_the_kinematic_pose_is_the_one_from_the_elastic_solve():
    """Without bearing clearance the roller law's no-load solve starts from the kinematic pose
    with the stated stiffnesses, pins in interference and all; the reference route first
    removes the interference by an elastic solve.  The energy is convex: the same TE to
    1e-9 arcsec, on reducers where the kinematic pose does leave interference."""
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.quasistatic import NO_LOAD_PROBE
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    design = study.design
    errors = stack(
        [
            load_errors(ROOT / "studies" / "seed002_errors.toml", design),
            errors_from_unit(study, sample(study, 3)),
        ]
    )
    model = EquivalentModel(design, input_angles(design, 60) + 0.05, flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(errors.samples), np.arange(60), indexing="ij"))
    probe = NO_LOAD_PROBE * design.rated_torque
    zero = np.zeros(s.size)
    te = {}
    for start in solver.LAW_STARTS:
        eq = solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, law_start=start)
        assert eq.converged.all()
        te[start] = model.output_angle(eq.q, zero) / ARCSEC
    assert np.ptp(te["elastic"]) > 1.0
    np.testing.assert_allclose(te["kinematic"], te["elastic"], rtol=0, atol=1e-9)
    # the two routes do start differently: the kinematic pose leaves pins in interference
    stated = solver.ReducedSystem(model, np.zeros(model.bearing_k.size, dtype=bool), rollers=False)
    half = model.clearance_halves(errors)
    poses = [stated.solve(errors, s, a, zero, half, -probe, start_only=only).q for only in (True, False)]
    assert np.max(np.abs(poses[0] - poses[1])) > 1e-9
    with pytest.raises(ValueError, match="law_start"):
        solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, law_start="newton")


def test_the_laws_no_load_release_by_one_step_is_the_release_solved():
    """The weak springs let go of the roller law's no-load solution by one Newton step at the
    end of the solve (`newton.release_step`) instead of a solve with the springs re-centred
    (the reference): the TE within 1e-4 arcsec, te_pp within 1e-6 arcsec; the compiled step,
    from the Hessian it factored, and the numpy one, from the Hessian at the solution, agree."""
    from rvfmu.core.statics.equivalent import EquivalentModel
    from rvfmu.core.statics.quasistatic import NO_LOAD_PROBE
    from tolerance.montecarlo import sample
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "quick_mc.toml")
    design = study.design
    errors = stack(
        [
            load_errors(ROOT / "studies" / "seed002_errors.toml", design),
            errors_from_unit(study, sample(study, 3)),
        ]
    )
    points = 90
    model = EquivalentModel(design, input_angles(design, points), flank=1)
    s, a = (g.ravel() for g in np.meshgrid(np.arange(errors.samples), np.arange(points), indexing="ij"))
    probe = NO_LOAD_PROBE * design.rated_torque
    zero = np.zeros(s.size)

    def te(release):
        eq = solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, law_release=release)
        assert eq.converged.all()
        return (model.output_angle(eq.q, zero) / ARCSEC).reshape(errors.samples, points)

    solved, stepped = te("solve"), te("step")
    assert 0.0 < np.max(np.abs(stepped - solved)) < 1e-4  # the step is not the solve ...
    np.testing.assert_allclose(np.ptp(stepped, axis=1), np.ptp(solved, axis=1), rtol=0, atol=1e-6)
    with pytest.MonkeyPatch.context() as patch:
        for module in (newton_kernel, pin_law, roller_law):
            patch.setattr(module, "COMPILED", False)
        in_numpy = te("step")
    np.testing.assert_allclose(in_numpy, stepped, rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="law_release"):
        solver.solve_pairs(model, errors, s, a, zero, no_load_probe=probe, law_release="twice")


def test_the_corrected_deflections_power_by_its_series_is_the_power_to_round_off():
    """roller_law_direct takes u^(n-1) at the corrected u from the start's by the binomial
    series of (1 - x)^(n-1) to x^3 where |x| < SERIES_POWER_BELOW: against the power itself
    over that range (x^4's term is below 3e-18 there), and the law against the law with every
    power taken (`_rollers`), to round-off."""
    from rvfmu.core.laws import roller_law as law

    x = np.linspace(-law.SERIES_POWER_BELOW, law.SERIES_POWER_BELOW, 2001)
    series = 1.0 - x * (law.POWER_1 - x * (law.POWER_2 - x * law.POWER_3))
    exact = (1.0 - x) ** (law.N - 1.0)
    assert np.max(np.abs(series - exact)) <= 4e-16
    rng = np.random.default_rng(5)
    for _ in range(200):
        c = rng.choice([0.0, rng.uniform(0.0, 5e-6)])
        s = c + 10.0 ** rng.uniform(-9.0, -5.0)
        a, compliance = 10.0 ** rng.uniform(8.5, 9.5), 10.0 ** rng.uniform(-11.0, -9.0)
        direct = law.roller_law_direct(law.TABLE_E, law.TABLE_DE, s, c, a, compliance)
        u = law._start(s, c, a, compliance)
        _, force, stiffness = law._rollers(law.TABLE_E, law.TABLE_DE, u, c, a)
        u -= (u + compliance * force - s) / (1.0 + compliance * stiffness)
        energy, force, stiffness = law._rollers(law.TABLE_E, law.TABLE_DE, u, c, a)
        powers = (
            energy + 0.5 * compliance * force * force,
            force,
            stiffness / (1.0 + compliance * stiffness),
        )
        np.testing.assert_allclose(direct, powers, rtol=1e-14, atol=0.0)


def test_a_bearing_without_play_takes_the_general_laws_numbers_to_the_bit():
    """roller_law_direct writes the law out for c = 0 (`_tight`): the general path's start
    table and Hermite interpolant at rho = 0, taken by their pieces here, give the same
    energy, force and stiffness to the last bit."""
    from rvfmu.core.laws import roller_law as law

    rng = np.random.default_rng(11)
    for _ in range(2000):
        s = 10.0 ** rng.uniform(-10.0, -4.0)
        a, compliance = 10.0 ** rng.uniform(8.0, 10.0), 10.0 ** rng.uniform(-12.0, -8.0)
        u = law._start(s, 0.0, a, compliance)
        un1 = u ** (law.N - 1.0)
        _, force, stiffness = law._rollers_at(law.TABLE_E, law.TABLE_DE, u, 0.0, a, un1)
        u, un1 = law._corrected(u, un1, (u + compliance * force - s) / (1.0 + compliance * stiffness))
        energy, force, stiffness = law._rollers_at(law.TABLE_E, law.TABLE_DE, u, 0.0, a, un1)
        general = (
            energy + 0.5 * compliance * force * force,
            force,
            stiffness / (1.0 + compliance * stiffness),
        )
        assert law.roller_law_direct(law.TABLE_E, law.TABLE_DE, s, 0.0, a, compliance) == general

"""The pins' Hertz law (rvfmu/core/laws/pin_law.py): its closed form, its inverse, and the model on it.

A pin pressed between its disc and its housing groove is two Hertz line contacts in
series; Radzimovsky's approach of each (`stiffness.hertz_line_contact_approach`) is
delta = b_i F ln(F_i*/F), so the pair is one law b F ln(F*/F).  The solvers invert it at a
deflection; the tests check the law against Radzimovsky's form written out, the inverse
against scipy's Lambert W, the energy, force and tangent against each other, and the
quasi-static, dynamic and budget computations on it.
"""

import math
from unittest import mock

import numpy as np
import pytest
from conftest import ROOT
from scipy.special import lambertw

from rvfmu.core.base.checks import InputError
from rvfmu.core.base.units import ARCSEC
from rvfmu.core.laws.pin_law import U_LIMIT, approach, contact, contact_forces, contacts, law_constants
from rvfmu.core.laws.stiffness import (
    disc_curvature_radius_at_largest_lever,
    hertz_line_contact_approach,
    pin_contact_loads,
    pin_stiffness_estimate,
)
from rvfmu.core.reducer.design import preset, preset_file
from rvfmu.core.reducer.errors import load_errors, stack
from rvfmu.core.statics import newton_kernel
from rvfmu.core.statics.quasistatic import equilibrium_te, input_angles, te_curve, windup

E, NU = 206e9, 0.3
PIN, DISC, GROOVE, WIDTH = 5e-3, 0.034, -5.005e-3, 0.015  # m: a pin, a convex disc, its groove


def test_the_law_is_radzimovskys_two_line_contacts_in_series():
    b, f_star = law_constants(PIN, DISC, GROOVE, WIDTH, E, NU)
    for force in (1e-3, 1.0, 40.0, 400.0, 1e4):
        written_out = hertz_line_contact_approach(
            force, WIDTH, PIN, DISC, E, NU
        ) + hertz_line_contact_approach(force, WIDTH, PIN, GROOVE, E, NU)
        assert float(approach(force, b, f_star)) == pytest.approx(written_out, rel=1e-12)
    # b is twice one contact's 2 (1 - nu^2) / (pi E l)
    assert b == pytest.approx(4.0 * (1.0 - NU**2) / (math.pi * E * WIDTH), rel=1e-14)


def test_the_inverse_is_lambert_w_to_round_off_over_the_whole_range():
    b, f_star = law_constants(PIN, DISC, GROOVE, WIDTH, E, NU)
    law = np.array([2e8, b, f_star])
    y = np.logspace(-250, math.log10(-U_LIMIT * math.exp(U_LIMIT)), 400)
    exact = f_star * np.exp(lambertw(-y, -1).real)
    compiled = np.array([contact(v * b * f_star, law)[1] for v in y])
    np.testing.assert_allclose(compiled, exact, rtol=1e-12)
    np.testing.assert_allclose(contacts(y * b * f_star, law)[1], compiled, rtol=1e-14)
    # the compiled loop over an array (the equilibria's pin forces): the same forces, its shape
    grid = (y * b * f_star).reshape(2, 4, 50)
    np.testing.assert_array_equal(contact_forces(grid, law), compiled.reshape(2, 4, 50))
    # and approach(force(delta)) is delta
    np.testing.assert_allclose(approach(compiled, b, f_star), y * b * f_star, rtol=1e-12)


def test_newton_starts_from_the_table_within_one_step_of_the_root():
    """v(c) tabulated and interpolated is within 1e-9 of Lambert W's root over the table, so
    the first Newton step is below the stop (STEP_TOLERANCE v) and ends the iteration there;
    beyond the table de Bruijn's start takes over, still to round-off."""
    from rvfmu.core.laws import pin_law

    c = np.linspace(pin_law.C_LIMIT, pin_law.ROOT_TABLE_END, 100_003)[:-1]
    exact = -lambertw(-np.exp(-c), -1).real  # v - ln v = c, v >= 1
    start = pin_law._table_start(c)
    np.testing.assert_allclose(start, exact, rtol=2e-9, atol=0)
    first_step = (start - np.log(start) - c) * start / (start - 1.0)
    assert np.all(np.abs(first_step) < pin_law.STEP_TOLERANCE * start)
    for value in c[::997]:
        assert pin_law._start(value) == pytest.approx(pin_law._table_start(np.array([value]))[0], rel=1e-15)
    beyond = np.array([pin_law.ROOT_TABLE_END, 60.0, 300.0])
    root = np.array([pin_law._root(x) for x in beyond])
    np.testing.assert_allclose(root, -lambertw(-np.exp(-beyond), -1).real, rtol=1e-14)


@pytest.mark.parametrize("delta", [1e-10, 1e-7, 2e-6, 1e-4, 0.05], ids=str)
def test_force_is_the_energys_derivative_and_the_tangent_the_forces(delta):
    """Also beyond the law's range (0.05 m: past F* e^-2), where its tangent continues."""
    law = np.array([2e8, *law_constants(PIN, DISC, GROOVE, WIDTH, E, NU)])
    h = delta * 1e-5
    up, down, here = contact(delta + h, law), contact(delta - h, law), contact(delta, law)
    assert (up[0] - down[0]) / (2 * h) == pytest.approx(here[1], rel=1e-8)
    assert (up[1] - down[1]) / (2 * h) == pytest.approx(here[2], rel=1e-6)
    assert contacts(np.array([delta]), law)[0][0] == pytest.approx(here[0], rel=1e-12)


def test_nothing_in_clearance_and_the_linear_law_without_b():
    law = np.array([2e8, *law_constants(PIN, DISC, GROOVE, WIDTH, E, NU)])
    assert contact(-1e-6, law) == (0.0, 0.0, 0.0) and contact(0.0, law) == (0.0, 0.0, 0.0)
    linear = np.array([2e8, 0.0, 0.0])
    assert contact(3e-6, linear) == pytest.approx((0.5 * 2e8 * 9e-12, 600.0, 2e8))
    e, f, k = contacts(np.array([-1e-6, 3e-6]), linear)
    assert list(f) == [0.0, 600.0] and list(k) == [0.0, 2e8]
    assert list(contact_forces(np.array([-1e-6, 0.0, 3e-6]), linear)) == [0.0, 0.0, 600.0]
    assert list(contact_forces(np.array([-1e-6, 0.0]), law)) == [0.0, 0.0]


@pytest.mark.parametrize("name", ["RV-40E-121", "RV-20E", "RV-110E"])
def test_the_law_winds_up_as_the_stated_stiffness_over_the_rated_range_and_softer_near_zero(name):
    """Its secant over 50-100 % of the rated pin force is the stated stiffness; with the
    estimate's own stiffness the law is Radzimovsky's unscaled; at the lost motion's 3 % it
    is softer, by the logarithm."""
    design = preset(name + "-estimate")
    assert design.pin_groove_clearance > 0.0  # the presets give the groove
    k, b, f_star = design.pin_law
    low, high = pin_contact_loads(design.rated_torque, design.R_p, design.e, design.z_p)
    secant = (high - low) / (approach(high, b, f_star) - approach(low, b, f_star))
    assert secant == pytest.approx(k, rel=1e-12)
    own = pin_stiffness_estimate(
        design.rated_torque,
        design.R_p,
        design.r_rp,
        design.e,
        design.z_p,
        design.disc_width,
        preset_file(name)["pin_groove_clearance_mm"] * 1e-3,
        design.youngs_modulus,
        design.poisson_ratio,
    )
    assert k == pytest.approx(own, rel=1e-3)  # the file holds it to four digits
    radius = disc_curvature_radius_at_largest_lever(design.R_p, design.r_rp, design.e, design.z_p)
    b0, _ = law_constants(
        design.r_rp,
        radius,
        -(design.r_rp + design.pin_groove_clearance),
        design.disc_width,
        design.youngs_modulus,
        design.poisson_ratio,
    )
    assert b == pytest.approx(b0 * own / k, rel=1e-9)
    small = 0.03 * high
    assert small / approach(small, b, f_star) < 0.8 * k


def test_a_groove_wider_than_its_pin_and_hertz_without_a_groove_are_refused(rv40, rv40_hertz):
    from rvfmu.core.dynamics.dynamic import DynamicModel
    from rvfmu.core.reducer.errors import zero_errors

    with pytest.raises(InputError, match="pin_groove_clearance_mm"):
        rv40.with_fields(pin_groove_clearance=1.01 * rv40.r_rp)
    with pytest.raises(InputError, match="pin_groove_clearance_mm"):
        rv40.with_fields(pin_groove_clearance=-1e-6)
    with pytest.raises(InputError, match="contact"):
        DynamicModel(rv40, zero_errors(rv40), contact="hertz")
    assert DynamicModel(rv40_hertz, zero_errors(rv40_hertz)).contact == "hertz"
    assert DynamicModel(rv40, zero_errors(rv40)).contact == "linear"


@pytest.fixture(scope="module")
def seed002_hertz(rv40_hertz):
    return load_errors(ROOT / "studies" / "seed002_errors.toml", rv40_hertz)


def test_no_load_te_is_the_rigid_limit_and_loaded_te_carries_the_law(rv40_rollers, rv40_hertz, seed002_hertz):
    """No preload (seed 002's errors on the estimate): the no-load TE is kinematic and does not
    see the law; under load the law winds up more at small loads, alike at rated."""
    theta = input_angles(rv40_hertz, 48) + 0.1
    none_h, _, ok = equilibrium_te(rv40_hertz, seed002_hertz, theta, [0.0])
    none_l, _, _ = equilibrium_te(rv40_rollers, seed002_hertz, theta, [0.0])
    assert ok.all()
    np.testing.assert_allclose(none_h[0, 0] / ARCSEC, none_l[0, 0] / ARCSEC, atol=1e-4)
    small = -0.03 * rv40_hertz.rated_torque
    loaded_h, _, _ = equilibrium_te(rv40_hertz, seed002_hertz, theta, [small])
    loaded_l, _, _ = equilibrium_te(rv40_rollers, seed002_hertz, theta, [small])
    # the law is softer than its secant there: the output turns further back
    assert np.mean(loaded_l[0, 0] - loaded_h[0, 0]) / ARCSEC > 0.1
    hertz, linear = windup(rv40_hertz, seed002_hertz), windup(rv40_rollers, seed002_hertz)
    assert hertz.lost_motion_arcmin()[0] > linear.lost_motion_arcmin()[0]
    assert hertz.torsional_rigidity_Nm_per_arcmin()[0] == pytest.approx(
        linear.torsional_rigidity_Nm_per_arcmin()[0], rel=0.01
    )


@pytest.mark.parametrize("tau", [0.0, -412.0, -12.0], ids=["no load", "rated", "3 %"])
def test_the_compiled_and_numpy_iterations_agree_on_the_law(rv40_hertz, seed002_hertz, tau):
    errors = stack([seed002_hertz] * 2)

    def run():
        return te_curve(rv40_hertz, errors, tau_load=tau, points=240)

    assert newton_kernel.COMPILED
    compiled = run()
    with mock.patch.object(newton_kernel, "COMPILED", False):
        plain = run()
    assert compiled.converged.all() and plain.converged.all()
    np.testing.assert_allclose(compiled.te_arcsec, plain.te_arcsec, rtol=0, atol=1e-8)
    # the pin forces: the compiled law's, the numpy law's
    np.testing.assert_allclose(compiled.pin_force_max, plain.pin_force_max, rtol=1e-9, atol=1e-9)


def test_the_dynamic_tangent_is_the_derivative_of_the_law(rv40_hertz, seed002_hertz):
    from rvfmu.core.dynamics.dynamic import DynamicModel, ramp_motion
    from rvfmu.core.dynamics.simulation import _quasi_static_start

    model = DynamicModel(rv40_hertz, seed002_hertz, mesh="varying")
    model.prepare(ramp_motion(np.array([0.0, 1e-4]), 100.0, 0.0))
    q = _quasi_static_start(model, rv40_hertz, seed002_hertz, -300.0, 1)
    v = np.zeros(model.n)
    _, K, _ = model.forces(1, q, v)
    for k in model.pin_dofs.ravel():
        dq = np.zeros(model.n)
        dq[k] = 1e-11
        df = (model.forces(1, q + dq, v)[0] - model.forces(1, q - dq, v)[0]) / 2e-11
        np.testing.assert_allclose(df, K[:, k], rtol=1e-4, atol=1e-6 * np.abs(K).max())


def test_the_budget_adds_up_with_the_law(rv40_hertz, seed002_hertz):
    from rvfmu.core.statics.budget import compliance_budget

    budget = compliance_budget(rv40_hertz, seed002_hertz)
    assert budget.converged
    assert abs(budget.share_sum - 1.0) < 1e-6
    assert budget.torsional_rigidity_Nm_per_arcmin == pytest.approx(
        windup(rv40_hertz, seed002_hertz).torsional_rigidity_Nm_per_arcmin()[0], rel=1e-9
    )
    pins = {e.name: e for e in budget.elements}["pin-disc contacts"]
    assert pins.stiffness == rv40_hertz.pin_disc_stiffness and pins.share > 0.01

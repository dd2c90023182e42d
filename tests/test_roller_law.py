"""A roller bearing's radial law as the solvers use it (rvfmu/core/laws/roller_law.py): against
closed forms, the load-distribution integral of rvfmu/core/laws/compliance.py and its own
derivatives."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from rvfmu.core.laws import roller_law as rl
from rvfmu.core.laws.compliance import (
    LINE_EXPONENT,
    bearing_deflection,
    bearing_radial_force,
    roller_load_constant,
)

N = LINE_EXPONENT
ROLLERS, LENGTH = 12, 8e-3  # the RV-40E-121's needle bearing ([sources])
A = rl.load_constant(ROLLERS, roller_load_constant(LENGTH))


def law(s, c=0.0, compliance=0.0, a=A):
    return rl.roller_law(rl.TABLE_E, rl.TABLE_DE, s, c, a, compliance)


def test_zero_clearance_is_the_power_law_with_wallis_integral():
    """With no clearance every roller within +-90 deg carries K_n (s cos psi)^n:
    F = a s^n * 2 * integral_0^(pi/2) cos^(n+1) = a s^n sqrt(pi) G((n+2)/2) / G((n+3)/2)."""
    wallis = math.sqrt(math.pi) * math.gamma((N + 2) / 2) / math.gamma((N + 3) / 2)
    for s in (1e-7, 2e-6, 3e-5):
        energy, force, stiffness = law(s)
        assert force == pytest.approx(A * s**N * wallis, rel=1e-9)
        assert stiffness == pytest.approx(N * force / s, rel=1e-9)
        assert energy == pytest.approx(force * s / (N + 1), rel=1e-9)


@pytest.mark.parametrize(
    "c, s", [(0.0, 1.2e-6), (0.0, 2e-5), (1e-6, 1.2e-6), (1e-6, 5e-6), (4e-6, 5e-6), (4e-6, 2e-5)]
)
def test_force_and_stiffness_agree_with_the_load_distribution_integral(c, s):
    """compliance.bearing_radial_force integrates the force over the loaded arc directly;
    the law builds it from the tabulated energy: within 1e-6 (force), 1e-4 (stiffness)."""
    force, stiffness = bearing_radial_force(s, ROLLERS, LENGTH, c)
    _, f, k = law(s, c)
    assert f == pytest.approx(force, rel=1e-6)
    assert k == pytest.approx(stiffness, rel=1e-4)


@pytest.mark.parametrize("compliance", [0.0, 1.0 / 5e8])
@pytest.mark.parametrize("c", [0.0, 3e-6])
def test_force_is_the_derivative_of_the_energy_and_stiffness_that_of_the_force(c, compliance):
    for s in (c + 0.4e-6, c + 3e-6, c + 25e-6):
        h = 1e-5 * s
        e_plus, f_plus, _ = law(s + h, c, compliance)
        e_minus, f_minus, _ = law(s - h, c, compliance)
        _, f, k = law(s, c, compliance)
        assert (e_plus - e_minus) / (2 * h) == pytest.approx(f, rel=1e-7)
        assert (f_plus - f_minus) / (2 * h) == pytest.approx(k, rel=2e-4)


def test_nothing_inside_the_clearance():
    assert law(2e-6, 2e-6) == (0.0, 0.0, 0.0)
    assert law(1e-6, 2e-6, 1e-9) == (0.0, 0.0, 0.0)
    assert law(0.0) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("c", [0.0, 2e-6])
def test_series_spring_deflections_add_and_energy_is_the_work_done(c):
    """The bearing and a spring of compliance C in series: s = u(F) + C F with u the
    bearing's own deflection under F (compliance.bearing_deflection, a separate Newton
    iteration on the integral), and the energy the integral of the force over s."""
    C = 1.0 / 4.56e8  # the RV-40E-121's crank bent at its cams
    for s in (c + 2e-6, c + 1.5e-5):
        energy, force, stiffness = law(s, c, C)
        u = bearing_deflection(force, ROLLERS, LENGTH, c)
        assert u + C * force == pytest.approx(s, rel=1e-7)
        work, _ = quad(lambda x: law(x, c, C)[1], c, s, epsabs=0.0, epsrel=1e-10, limit=200)
        assert energy == pytest.approx(work, rel=1e-7)
        _, _, k_bearing = law(u, c)
        assert 1.0 / stiffness == pytest.approx(1.0 / k_bearing + C, rel=1e-9)


def test_tapered_pair_matches_the_estimate_of_its_stiffness():
    """Two tapered roller bearings at 10 deg to the radial plane, each half the radial
    load: the radial deflection of the pair as stiffness.crank_carrier_stiffness_estimate
    takes it (one bearing's deflection under F / (2 cos alpha), over cos alpha)."""
    rollers, length, alpha = 14, 6e-3, math.radians(10.0)
    a = rl.load_constant(rollers, roller_load_constant(length), alpha, bearings=2)
    for force in (500.0, 5722.0):
        d = bearing_deflection(0.5 * force / math.cos(alpha), rollers, length) / math.cos(alpha)
        assert law(d, a=a)[1] == pytest.approx(force, rel=1e-7)


def test_array_form_agrees_with_the_compiled_one():
    s = np.array([[0.5e-6, 3e-6, 2e-5], [1e-6, 7e-6, 4e-5]])
    c = np.array([[0.0, 1e-6, 2e-6], [2e-6, 0.0, 5e-6]])
    C = np.array([[0.0, 2e-9, 0.0], [0.0, 1e-9, 3e-9]])
    energy, force, stiffness = rl.radial_law(s, c, A, C)
    for i in np.ndindex(s.shape):
        assert (energy[i], force[i], stiffness[i]) == pytest.approx(law(s[i], c[i], C[i]), rel=1e-12)

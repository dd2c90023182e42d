"""Element laws from geometry (rvfmu/core/laws/compliance.py), each against a closed form."""

import math

import pytest

from rvfmu.core.laws import compliance as c
from rvfmu.core.laws.stiffness import hertz_line_contact_approach, simply_supported_beam_stiffness

E, NU = 211e9, 0.29


@pytest.mark.parametrize("load", [200.0, 1000.0, 4000.0])
def test_palmgren_agrees_with_the_hertz_line_contact(load):
    """A 3 mm needle on an 18 mm cam, 8 mm long: Palmgren's power law against Radzimovsky's
    closed form of the Hertz line contact, one contact, within 5 %."""
    palmgren = c.palmgren_roller_approach(load, 8e-3, contacts=1)
    hertz = hertz_line_contact_approach(load, 8e-3, 1.5e-3, 9e-3, E, NU)
    assert palmgren == pytest.approx(hertz, rel=0.05)


def test_palmgren_worked_example():
    """Harris & Kotzalas's form by hand: 1000 N on a 10 mm roller, one contact,
    3.84e-5 * 1000^0.9 / 10^0.8 mm = 3.84e-5 * 501.19 / 6.3096 = 3.050 um; two contacts twice."""
    assert c.palmgren_roller_approach(1000.0, 10e-3, contacts=1) == pytest.approx(3.050e-6, rel=1e-3)
    assert c.palmgren_roller_approach(1000.0, 10e-3) == pytest.approx(6.100e-6, rel=1e-3)
    # the load constant inverts it
    k = c.roller_load_constant(10e-3)
    assert k * c.palmgren_roller_approach(1000.0, 10e-3) ** c.LINE_EXPONENT == pytest.approx(1000.0)


def test_stribeck_constant_of_a_line_contact_bearing_without_clearance():
    """Zero clearance: the most loaded roller carries 4.08 F / Z (Stribeck, line contact;
    Harris & Kotzalas's J_r(0.5) = 0.2453 for a finite roller count)."""
    for rollers, force in ((12, 1000.0), (20, 5000.0)):
        q_max = c.most_loaded_roller(force, rollers, 8e-3)
        assert q_max * rollers / force == pytest.approx(4.08, abs=0.01)


def test_loaded_arc_integral_of_a_linear_law_has_its_closed_form():
    """With exponent 1: the integral of (d cos psi - c) cos psi over |psi| < psi_l is
    d (psi_l + sin psi_l cos psi_l) - 2 c sin psi_l."""
    for d, half in ((1.0, 0.0), (2.0, 0.7), (5.0, 4.9)):
        limit = math.acos(half / d)
        exact = d * (limit + math.sin(limit) * math.cos(limit)) - 2.0 * half * math.sin(limit)
        force, _ = c._loaded_arc_integrals(d, half, n=1.0)
        assert force == pytest.approx(exact, rel=1e-10)


def test_bearing_force_tangent_and_inverse():
    for half in (0.0, 3e-6):
        d = c.bearing_deflection(2500.0, 14, 6e-3, half)
        force, tangent = c.bearing_radial_force(d, 14, 6e-3, half)
        assert force == pytest.approx(2500.0, rel=1e-10)
        h = 1e-4 * d
        numeric = (
            c.bearing_radial_force(d + h, 14, 6e-3, half)[0]
            - c.bearing_radial_force(d - h, 14, 6e-3, half)[0]
        ) / (2 * h)
        assert tangent == pytest.approx(numeric, rel=1e-4)
    # free within the clearance, and the clearance is the free play of the centre
    assert c.bearing_radial_force(2.9e-6, 14, 6e-3, 3e-6) == (0.0, 0.0)
    with_play = c.bearing_deflection(2500.0, 14, 6e-3, 3e-6)
    without = c.bearing_deflection(2500.0, 14, 6e-3)
    assert with_play > without + 3e-6 * 0.5  # fewer rollers carry it: more than the play alone


def test_bearing_stiffens_under_load():
    """delta ~ F^0.9 without clearance: the secant stiffness grows as F^0.1."""
    law = lambda f: c.bearing_deflection(f, 12, 8e-3)  # noqa: E731
    low, high = c.secant_stiffness(law, 100.0, 200.0), c.secant_stiffness(law, 1000.0, 2000.0)
    assert high / low == pytest.approx(10.0**0.1, rel=1e-6)


def test_beam_influence_reciprocity_and_the_central_load():
    inertia = math.pi * 0.016**4 / 64
    assert c.beam_influence(0.04, 0.01, 0.03, E, inertia) == pytest.approx(
        c.beam_influence(0.04, 0.03, 0.01, E, inertia), rel=1e-12
    )  # Maxwell
    assert c.beam_shear_influence(0.04, 0.01, 0.03, 8e10, 2e-4, 0.9) == pytest.approx(
        c.beam_shear_influence(0.04, 0.03, 0.01, 8e10, 2e-4, 0.9), rel=1e-12
    )
    # a central load: Euler-Bernoulli L^3 / (48 E I) plus Timoshenko's shear L / (4 k G A)
    d, span = 0.016, 0.04
    g, area = E / (2 * (1 + NU)), math.pi * d**2 / 4
    kappa = 6 * (1 + NU) / (7 + 6 * NU)
    assert c.round_shear_coefficient(NU) == pytest.approx(0.88558, rel=1e-4)
    central = 1 / c.crank_influence(E, NU, d, span, [0.02])[0, 0]
    bending = simply_supported_beam_stiffness(E, d, span)
    assert 1 / central == pytest.approx(1 / bending + span / (4 * kappa * g * area), rel=1e-12)
    # the crank is short: shear adds a third to its bending here (2.18 (d/L)^2 = 0.35)
    assert bending / central - 1 == pytest.approx(0.75 * 2 * (1 + NU) / kappa * (d / span) ** 2, rel=1e-12)
    # a slender shaft is Euler-Bernoulli's
    assert 1 / c.crank_influence(E, NU, 0.002, 0.4, [0.2])[0, 0] == pytest.approx(
        simply_supported_beam_stiffness(E, 0.002, 0.4), rel=1e-4
    )
    # two cams loaded alike at b from each support (Roark table 8.1, case 1e twice):
    # at a cam b^2 (3L - 4b) / (6 E I) bent, plus b / (k G A) sheared
    b = 0.015
    two = c.crank_influence(E, NU, d, span, [b, span - b]).sum(axis=1)
    assert two == pytest.approx(
        b * b * (3 * span - 4 * b) / (6 * E * inertia) + b / (kappa * g * area), rel=1e-12
    )
    # two cams loaded alike bend the crank more than one
    assert two[0] > c.crank_influence(E, NU, d, span, [b])[0, 0]


def test_the_crank_splits_into_like_and_opposite_cam_loads_as_the_half_beam_gives():
    """Two cams at b from each support of a crank of span L, s = L - 2b apart.

    Like loads P at both: at a cam b^2 (3L - 4b) / (6 E I) + b / (k G A) (Roark 8.1, 1e
    twice), each bearing carrying P.  Opposite loads +-P: the midspan is an inflection
    point that does not move, so each half is a simply supported beam of span L/2 with P
    at b: P b^2 (s/2)^2 / (3 E I L/2) bent and P b (s/2) / ((L/2) k G A) sheared (Roark 8.1,
    1e at its load).  The bearings, each k_1, react +-P s / L: the crank turns by
    2 P s / (L^2 k_1) and a cam, s/2 from the middle, moves P s^2 / (L^2 k_1).  The model
    gives like loads each + 2 common, opposite loads each."""
    d, span, b = 0.016, 0.04, 0.015
    s, half = span - 2 * b, span / 2
    inertia, area = math.pi * d**4 / 64, math.pi * d**2 / 4
    kga = c.round_shear_coefficient(NU) * c.shear_modulus(E, NU) * area
    like = b * b * (3 * span - 4 * b) / (6 * E * inertia) + b / kga
    opposite = b**2 * (s / 2) ** 2 / (3 * E * inertia * half) + b * (s / 2) / (half * kga)
    influence = c.crank_influence(E, NU, d, span, (b, span - b))
    assert influence.shape == (2, 2) and influence[0, 1] == pytest.approx(influence[1, 0], rel=1e-12)
    rigid_each, rigid_common = c.crank_split(influence, span, (b, span - b), math.inf)
    assert rigid_each == pytest.approx(opposite, rel=1e-12)
    assert rigid_each + 2 * rigid_common == pytest.approx(like, rel=1e-12)
    # the cams sit close: opposite loads bend the crank under a tenth as much as like loads
    assert rigid_each < 0.1 * like
    pair = 6e8  # both bearings, each 3e8
    each, common = c.crank_split(influence, span, (b, span - b), pair)
    assert each - rigid_each == pytest.approx(s**2 / (span**2 * 0.5 * pair), rel=1e-12)
    assert each + 2 * common == pytest.approx(like, rel=1e-12)  # like loads do not tilt it
    # the seat's element is the pair in series with the common part, and gives the pair back
    seat = 1 / (1 / pair + common)
    assert c.crank_pair(influence, span, (b, span - b), seat) == pytest.approx(pair, rel=1e-12)
    assert c.crank_pair(influence, span, (b, span - b), 1.01 / common) < 0  # no room for a pair
    with pytest.raises(ValueError, match="two cams"):
        c.crank_split(influence[:1, :1], span, (b,), pair)


def test_guided_beam_and_torsion_closed_forms():
    inertia, area = 1e-9, 1e-4
    slender = c.guided_beam_stiffness(E, NU, inertia, area, 0.3, 0.85)
    assert slender == pytest.approx(12 * E * inertia / 0.3**3, rel=0.01)  # shear negligible
    stubby = c.guided_beam_stiffness(E, NU, 1e-7, area, 0.005, 0.85)
    g = E / (2 * (1 + NU))
    assert 1 / stubby == pytest.approx(0.005**3 / (12 * E * 1e-7) + 0.005 / (0.85 * g * area))
    assert c.shaft_torsion_stiffness(g, 0.02, 0.1) == pytest.approx(g * math.pi * 0.02**4 / 32 / 0.1)


def test_carrier_compliance_by_energy():
    """Symmetric cams: half the torque through the far flange; four pillars of k at r
    twist it by (T/2) / (4 k r^2), and the output sees a quarter of that per unit torque."""
    share = c.end_plate_share([0.01, 0.03], 0.04)
    assert share == 0.5
    k, r = 2e8, 0.04
    assert c.carrier_torsional_compliance(4, k, r, share) == pytest.approx(0.25 / (4 * k * r * r))

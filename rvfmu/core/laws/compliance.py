"""Element laws from geometry: rolling bearings, line contacts and beams of an RV reducer.

The engineering question: how stiff is each load path of a reducer whose
catalogue figure nobody has measured yet?  The published analytic and FE
models of RV-reducer torsional stiffness build it from a handful of classical
laws, each with a closed form; this module holds them, in SI units (N, m, Pa,
N*m/rad) unless a name says otherwise.  Nothing here knows the reducer's
kinematics: `equivalent.py` places the elements, these laws say how hard each
one pushes back.

- A roller between two raceways (needle and tapered roller bearings) follows
  Palmgren's line-contact law, delta = 3.84e-5 Q^0.9 / l^0.8 per contact
  (mm, N; Harris & Kotzalas, Rolling Bearing Analysis, 5th ed., vol. 1, ch. 6).
  It is the Hertz line contact with its logarithm folded into a power law: it
  agrees with Radzimovsky's closed form to a few per cent over the loads of a
  reducer (tests/test_compliance.py).
- A bearing's rollers share its radial load by their deflections,
  Q(psi) = K_n (delta_r cos psi - c/2)^n for |psi| below the loaded arc
  (Stribeck; Harris & Kotzalas ch. 7, the Sjovall integral J_r): the bearing is
  stiffer under load and free within its clearance, where a linear spring is
  neither.  Zero clearance gives Stribeck's Q_max = 4.08 F_r / Z.
- A pin pressed between a disc and its housing groove is two Hertz line contacts
  in series (`stiffness.hertz_line_contact_approach`, Radzimovsky's form).
- Shafts and pillars are beams: the crankshaft simply supported by its two
  tapered roller bearings and loaded at its cams, alike by the torque and
  oppositely by the two discs' pin forces (`crank_split`), twisted between its
  planet and its cams; the carrier's pillars clamped in both flanges, bent and sheared
  (Timoshenko) when the flanges turn against each other (Roark's Formulas for
  Stress and Strain, 8th ed., table 8.1).
"""

from __future__ import annotations

import math

import numpy as np

PALMGREN_COEFFICIENT = 3.84e-5  # mm / (N^0.9 mm^-0.8): one roller-raceway line contact, steel
LINE_EXPONENT = 10.0 / 9.0  # Q = K delta^(10/9): the inverse of Palmgren's delta ~ Q^0.9
MM = 1e-3
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(24)  # the roller integral over the loaded arc


def palmgren_roller_approach(load, roller_length, contacts: int = 2):
    """Approach [m] of the raceways across one roller under `load` [N] (Palmgren's law).

    roller_length [m]: effective contact length; contacts: 2 for a roller between
    an inner and an outer raceway, 1 for one contact.
    """
    load = np.asarray(load, dtype=float)
    per_contact = PALMGREN_COEFFICIENT * np.maximum(load, 0.0) ** 0.9 / (roller_length / MM) ** 0.8
    return contacts * per_contact * MM


def roller_load_constant(roller_length, contacts: int = 2) -> float:
    """K_n [N/m^(10/9)] of Q = K_n delta^(10/9), the inverse of `palmgren_roller_approach`."""
    # delta_mm = a Q^0.9  ->  Q = (delta_mm / a)^(10/9), with delta_mm = delta / MM
    a = contacts * PALMGREN_COEFFICIENT / (roller_length / MM) ** 0.8
    return (1.0 / (a * MM)) ** LINE_EXPONENT


def _loaded_arc_integrals(deflection, half_clearance, n=LINE_EXPONENT):
    """(I_F, I_K): the integrals over the loaded arc |psi| < psi_l of
    (d cos psi - c)^n cos psi and n (d cos psi - c)^(n-1) cos^2 psi, d > c >= 0."""
    d, c = float(deflection), float(half_clearance)
    limit = math.acos(c / d)
    psi = 0.5 * limit * (_NODES + 1.0)  # Gauss-Legendre nodes on [0, psi_l]
    w = 0.5 * limit * _WEIGHTS
    approach = d * np.cos(psi) - c
    force = 2.0 * np.sum(w * approach**n * np.cos(psi))
    tangent = 2.0 * np.sum(w * n * approach ** (n - 1.0) * np.cos(psi) ** 2)
    return force, tangent


def bearing_radial_force(deflection, rollers: int, roller_length, half_clearance=0.0, contacts: int = 2):
    """(force [N], tangent stiffness [N/m]) of a roller bearing at radial deflection [m].

    The rollers, `rollers` of them evenly round the bearing and taken as spread
    over its circumference (the mean over cage positions), each carry
    Q = K_n (deflection cos psi - half_clearance)^(10/9) where that is positive;
    half_clearance [m] is the free play of the centre (half the radial clearance,
    as `EquivalentModel.clearance_halves`).  F = Z/(2 pi) * integral of Q cos psi.
    """
    if deflection <= half_clearance:
        return 0.0, 0.0
    k_n = roller_load_constant(roller_length, contacts)
    i_force, i_tangent = _loaded_arc_integrals(deflection, half_clearance)
    scale = rollers * k_n / (2.0 * math.pi)
    return scale * i_force, scale * i_tangent


def most_loaded_roller(force, rollers: int, roller_length, half_clearance=0.0, contacts: int = 2) -> float:
    """Load [N] of the most loaded roller of a bearing carrying radial `force` [N]."""
    deflection = bearing_deflection(force, rollers, roller_length, half_clearance, contacts)
    k_n = roller_load_constant(roller_length, contacts)
    return k_n * (deflection - half_clearance) ** LINE_EXPONENT


def bearing_deflection(force, rollers: int, roller_length, half_clearance=0.0, contacts: int = 2) -> float:
    """Radial deflection [m] of a roller bearing under radial `force` [N] (Newton's method
    on `bearing_radial_force`, from the zero-clearance closed form)."""
    if force <= 0.0:
        return 0.0
    k_n = roller_load_constant(roller_length, contacts)
    j0, _ = _loaded_arc_integrals(1.0, 0.0)
    d = half_clearance + (force * 2.0 * math.pi / (rollers * k_n * j0)) ** (1.0 / LINE_EXPONENT)
    for _ in range(60):
        f, k = bearing_radial_force(d, rollers, roller_length, half_clearance, contacts)
        step = (f - force) / k
        d = max(d - step, half_clearance + 0.5 * (d - half_clearance))
        if abs(step) <= 1e-13 * d:
            break
    return d


def secant_stiffness(law, low: float, high: float) -> float:
    """(high - low) / (x(high) - x(low)) [N/m] of a load-deflection law x(load): the
    stiffness a linear element must have to wind up as the law does between two loads."""
    return (high - low) / (law(high) - law(low))


def beam_influence(span, at, load_at, youngs_modulus, second_moment):
    """Deflection [m/N] at `at` of a simply supported beam of `span` under a unit load at
    `load_at` (positions from one support, m): Roark table 8.1 case 1e,
    y = P b x (L^2 - b^2 - x^2) / (6 E I L) for x <= a, b = L - a."""
    x, a = (at, load_at) if at <= load_at else (span - at, span - load_at)
    b = span - a
    return b * x * (span**2 - b**2 - x**2) / (6.0 * youngs_modulus * second_moment * span)


def beam_shear_influence(span, at, load_at, shear_modulus, area, shear_coefficient):
    """Shear deflection [m/N] at `at` of a simply supported beam of `span` under a unit load
    at `load_at` (Timoshenko; unit-load method, the shear force (L - z)/L left of the load
    and -z/L right of it): x (L - z) / (L k G A) for x <= z, k the shear coefficient."""
    x, z = min(at, load_at), max(at, load_at)
    return x * (span - z) / (span * shear_coefficient * shear_modulus * area)


def shear_modulus(youngs_modulus, poisson_ratio) -> float:
    """G = E / (2 (1 + nu)) of an isotropic material [Pa]."""
    return youngs_modulus / (2.0 * (1.0 + poisson_ratio))


def round_shear_coefficient(poisson_ratio) -> float:
    """Cowper's shear coefficient of a solid circular section, 6 (1 + nu) / (7 + 6 nu)."""
    return 6.0 * (1.0 + poisson_ratio) / (7.0 + 6.0 * poisson_ratio)


def crank_influence(youngs_modulus, poisson_ratio, diameter, span, cam_positions) -> np.ndarray:
    """(n, n) deflection [m/N] at cam i under a unit load at cam k of the crankshaft simply
    supported by its bearings at 0 and `span`, bent and sheared (Timoshenko: the crank is
    short, span/diameter 2.5-2.6 on the presets, and shear adds about 30 % to its bending
    there)."""
    inertia, area = math.pi * diameter**4 / 64.0, math.pi * diameter**2 / 4.0
    g, kappa = shear_modulus(youngs_modulus, poisson_ratio), round_shear_coefficient(poisson_ratio)
    return np.array(
        [
            [
                beam_influence(span, x, z, youngs_modulus, inertia)
                + beam_shear_influence(span, x, z, g, area, kappa)
                for z in cam_positions
            ]
            for x in cam_positions
        ]
    )


def crank_split(influence, span, cam_positions, bearing_pair) -> tuple[float, float]:
    """(each cam, common) compliances [m/N] of a crankshaft with two cams between its two
    bearings, as the model's elements carry it: a spring at each cam in series with one
    spring at the crank's seat that carries both cams' loads.

    The two discs, half a turn apart, load the cams with t + r and t - r: t the torque's
    part, alike at both; r the cam's part of its disc's pin-force resultant, opposite on the
    two discs (it is as large as t: |r|/|t| = 0.7-1.0 on the presets).  Like loads bend the
    crank by b11 + b12 at a cam and load each bearing with t; opposite loads bend it by
    b11 - b12 only and tilt it in its bearings, whose reactions are +-r s / L (s the cams'
    spacing, L the span), so a cam moves by r s^2 / (L^2 k_1), k_1 = `bearing_pair` / 2.
    The elements give like loads each + 2 common and opposite loads each, so
    each = b11 - b12 + 2 s^2 / (L^2 k_pair) and common = b12 - s^2 / (L^2 k_pair)
    (the pair's own compliance 1 / k_pair is the seat's bearing element)."""
    if len(cam_positions) != 2:
        raise ValueError("crank_split: a crankshaft of the model has two cams")
    influence = np.asarray(influence, dtype=float)
    own, cross = 0.5 * float(influence[0, 0] + influence[1, 1]), float(influence[0, 1])
    tilt = _tilt_ratio(span, cam_positions) / bearing_pair
    return own - cross + 2.0 * tilt, cross - tilt


def crank_pair(influence, span, cam_positions, seat_stiffness) -> float:
    """The bearing pair [N/m] inside a crank's seat element of `seat_stiffness` (the pair in
    series with `crank_split`'s common part): 1 / k_seat = (1 - s^2 / L^2) / k_pair + b12.
    Not positive where the seat is stiffer than the crank's common part alone."""
    left = 1.0 / seat_stiffness - float(np.asarray(influence)[0, 1])
    return (1.0 - _tilt_ratio(span, cam_positions)) / left if left > 0.0 else -np.inf


def _tilt_ratio(span, cam_positions) -> float:
    """s^2 / L^2: a cam's deflection per unit opposite load, times one bearing's stiffness
    over 2, when the crank tilts in its bearings (`crank_split`)."""
    return (cam_positions[1] - cam_positions[0]) ** 2 / span**2


def shaft_torsion_stiffness(shear_modulus, diameter, length) -> float:
    """Torsional stiffness G J / L [N*m/rad] of a round shaft, J = pi d^4 / 32."""
    return shear_modulus * math.pi * diameter**4 / 32.0 / length


def guided_beam_stiffness(
    youngs_modulus, poisson_ratio, second_moment, area, length, shear_coefficient
) -> float:
    """Transverse stiffness [N/m] of a beam clamped at both ends, one end sliding
    square to the axis: bending 12 E I / L^3 in series with shear k G A / L (Timoshenko)."""
    bending = 12.0 * youngs_modulus * second_moment / length**3
    shear = shear_coefficient * shear_modulus(youngs_modulus, poisson_ratio) * area / length
    return 1.0 / (1.0 / bending + 1.0 / shear)


def end_plate_share(cam_positions, span) -> float:
    """Share of the crank loads that reaches the carrier's far flange (at `span`) through its
    bearing there, equal loads at the cams: mean of z / span (statics of the crank)."""
    return float(np.mean(np.asarray(cam_positions) / span))


def carrier_torsional_compliance(pillars: int, pillar_stiffness, pillar_radius, share) -> float:
    """Windup [rad] per output torque [N*m] of the carrier's flanges turning against each other:
    the far flange carries `share` of the torque to the output flange through `pillars`
    pillars of transverse `pillar_stiffness` at `pillar_radius`, so by energy
    share^2 / (pillars k r^2)."""
    return share**2 / (pillars * pillar_stiffness * pillar_radius**2)

"""Engineering estimates of the stiffnesses that the seeds do not give.

A preset that lacks a measured stiffness takes it from these formulas, and a
test recomputes every preset value from the inputs listed in the preset's
`[sources]` table, so a number in a preset file is never a bare guess.
All functions take and return SI units (N, m, Pa) unless the name says so.

Why these formulas:
- pin-disc contact is a line contact of two cylinders; its approach is nearly
  linear in the load but for a logarithm, so we take the secant stiffness at the
  largest pin force under rated torque (Radzimovsky's closed form of the Hertz
  line-contact approach);
- the sun-planet mesh is ISO 6336-1 method B (single stiffness c' and mesh
  stiffness c_gamma_alpha per unit face width);
- rolling bearings follow Palmgren's line contact with the rollers' load
  distribution (`compliance.py`); seed 003's formulas (its R_pd, R_b) are kept
  in `roller_bearing_stiffness`, no longer used;
- a crankshaft is short and thick, yet its bending and shear between its
  support bearings are as soft as the bearings themselves: the needle bearing
  and the tapered roller pair are each in series with their part of it
  (`compliance.crank_split`).
"""

import math

import numpy as np


def series(*stiffnesses):
    """Stiffness of springs in series [same unit as the inputs]."""
    return 1.0 / sum(1.0 / k for k in stiffnesses)


def hertz_line_contact_approach(force, length, radius_1, radius_2, youngs_modulus, poisson_ratio):
    """Approach of two steel cylinders in line contact [m] (Radzimovsky's form of Hertz).

    delta = 2 w (1 - nu^2) / (pi E) * (2/3 + ln(2 rho_1 / b) + ln(2 |rho_2| / b)),
    with w = force/length and the Hertz half width b = sqrt(4 w R* / (pi E*)),
    1/R* = 1/rho_1 + 1/rho_2 (a concave surface has a negative radius),
    E* = E / (2 (1 - nu^2)) for two bodies of the same steel.
    """
    w = force / length
    e_star = youngs_modulus / (2.0 * (1.0 - poisson_ratio**2))
    r_star = 1.0 / (1.0 / radius_1 + 1.0 / radius_2)
    if r_star <= 0:
        raise ValueError("the concave radius must be larger than the convex one")
    b = math.sqrt(4.0 * w * r_star / (math.pi * e_star))
    log_terms = 2.0 / 3.0 + math.log(2.0 * abs(radius_1) / b) + math.log(2.0 * abs(radius_2) / b)
    return 2.0 * w * (1.0 - poisson_ratio**2) / (math.pi * youngs_modulus) * log_terms


def hertz_line_contact_stiffness(force, length, radius_1, radius_2, youngs_modulus, poisson_ratio):
    """Secant stiffness force / approach of a line contact at `force` [N/m]."""
    return force / hertz_line_contact_approach(
        force, length, radius_1, radius_2, youngs_modulus, poisson_ratio
    )


def largest_pin_force(torque_per_disc, R_p, e, z_p):
    """Largest pin force on one disc carrying `torque_per_disc` [N].

    Classic cycloid-drive estimate with about half of the pins loaded:
    F_max = 4 T / (K1 z_c R_p), K1 = e z_p / R_p.
    """
    k1 = e * z_p / R_p
    return 4.0 * torque_per_disc / (k1 * (z_p - 1) * R_p)


def disc_curvature_radius_at_largest_lever(R_p, r_rp, e, z_p):
    """Radius of curvature of the disc profile where the pin lever arm is largest [m].

    The profile is the pin-centre trochoid offset inward by r_rp, so its radius is
    the trochoid radius minus r_rp (convex parts) or plus r_rp (concave parts,
    returned negative).  The lever arm about the disc centre of the normal through
    the pitch point is largest where the normal is square to the eccentric line.
    """
    t = np.linspace(1e-4, math.pi / (z_p - 1), 20001)  # valley to tip of one lobe
    u = np.cos((z_p - 1) * t)
    speed = np.sqrt(R_p**2 + (e * z_p) ** 2 - 2.0 * R_p * e * z_p * u)
    cross = R_p**2 + e**2 * z_p**3 - R_p * e * z_p * (z_p + 1) * u
    # Tangent of the pin path; the normal through the pitch point is square to it.
    tx = -R_p * np.sin(t) + e * z_p * np.sin(z_p * t)
    ty = R_p * np.cos(t) - e * z_p * np.cos(z_p * t)
    x = R_p * np.cos(t) - e * np.cos(z_p * t)
    y = R_p * np.sin(t) - e * np.sin(z_p * t)
    lever = np.abs(x * tx + y * ty) / speed  # distance from disc centre to the normal line
    i = int(np.argmax(lever))
    rho_path = speed[i] ** 3 / cross[i]
    return rho_path - r_rp  # inward offset: convex radii shrink, concave (negative) ones grow


def iso6336_mesh_stiffness(z_1, z_2, module, pressure_angle, face_width):
    """Mesh stiffness of a spur pair along the line of action, ISO 6336-1 method B [N/m].

    c'_th = 1/q', q' = C1 + C2/z_1 + C3/z_2 (unshifted, external spur gears),
    c' = c'_th C_M C_R C_B with C_M = 0.8 (solid gears), C_R = 1 (solid blanks),
    C_B = (1 + 0.5 (1.2 - h_fP/m)) (1 - 0.02 (20 - alpha_deg)) with h_fP = 1.25 m;
    c_gamma_alpha = c' (0.75 eps_alpha + 0.25) in N/(mm um), times the face width in mm.
    """
    c1, c2, c3 = 0.04723, 0.15551, 0.25791  # ISO 6336-1 table (mm um / N)
    q = c1 + c2 / z_1 + c3 / z_2
    alpha_deg = math.degrees(pressure_angle)
    c_b = (1.0 + 0.5 * (1.2 - 1.25)) * (1.0 - 0.02 * (20.0 - alpha_deg))
    c_single = (1.0 / q) * 0.8 * 1.0 * c_b
    eps = transverse_contact_ratio(z_1, z_2, module, pressure_angle)
    c_gamma = c_single * (0.75 * eps + 0.25)  # N / (mm um)
    return c_gamma * (face_width / 1e-3) * 1e6  # N/um per mm * mm -> N/m


def transverse_contact_ratio(z_1, z_2, module, pressure_angle):
    """Contact ratio eps_alpha of an unshifted external spur pair with addendum = module."""
    r1, r2 = module * z_1 / 2.0, module * z_2 / 2.0
    rb1, rb2 = r1 * math.cos(pressure_angle), r2 * math.cos(pressure_angle)
    ra1, ra2 = r1 + module, r2 + module
    path = math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2) - (r1 + r2) * math.sin(pressure_angle)
    return path / (math.pi * module * math.cos(pressure_angle))


def roller_bearing_stiffness(roller_length, rollers, youngs_modulus, poisson_ratio, contact_angle=None):
    """Radial stiffness of a roller bearing by seed 003's formulas [N/m].

    Cylindrical or needle (R_pd): pi l E n / (8 (1 - mu^2)).
    Tapered (R_b): the same divided by sin(contact_angle); seed 003 uses 80 deg.
    """
    k = math.pi * roller_length * youngs_modulus * rollers / (8.0 * (1.0 - poisson_ratio**2))
    if contact_angle is not None:
        k /= math.sin(contact_angle)
    return k


def simply_supported_beam_stiffness(youngs_modulus, diameter, span):
    """Stiffness of a round shaft under a central load between two supports, 48 E I / L^3 [N/m]."""
    inertia = math.pi * diameter**4 / 64.0
    return 48.0 * youngs_modulus * inertia / span**3


def cantilever_stiffness(youngs_modulus, diameter, length):
    """Stiffness of a round shaft loaded at its free end, 3 E I / L^3 [N/m]."""
    inertia = math.pi * diameter**4 / 64.0
    return 3.0 * youngs_modulus * inertia / length**3


# -- the estimate of every element from the reducer's geometry -----------------------------
#
# The laws of `compliance.py` are nonlinear (Palmgren's delta ~ Q^0.9, the roller load
# distribution, the Hertz logarithm); the element set of the quasi-static and dynamic
# models holds one stiffness per element.  Each is therefore the secant of its law between
# the element's loads at 50 % and 100 % of rated torque: the stiffness the catalogue's
# rigidity test sees (docs/model.md section 5).  The loads come from statics with rigid
# parts: the output torque T reaches the carrier through the n_c crank seats on the crank
# circle a (T / (n_c a) each), each disc carrying half of it through its n_c cams
# (T / (2 n_c a) each); the largest pin force is `largest_pin_force`.  The crankshaft
# between its bearings is split over the two elements that carry it
# (`compliance.crank_split`): its compliance under opposite cam loads stays in each cam's
# needle element, the rest in its seat's element, with the tapered roller pair.
#
# Geometry the [sources] of a preset do not give follows one rule for every frame
# (docs/model.md section 6): the two discs side by side in the middle of the crank span
# (cams at span/2 -+ disc_width/2); n_c pillars of diameter a/2 on the crank
# circle, as long as the two discs plus 2 mm, clamped in both flanges; pins lying in housing
# grooves along their whole length (no pin bending), the groove radius larger than the pin's
# by the design's `pin_groove_clearance_mm`.

RATED_RANGE = (0.5, 1.0)  # the catalogue's rigidity range, x rated torque
PILLAR_DIAMETER_PER_CRANK_RADIUS = 0.5
PILLAR_EXTRA_LENGTH = 2e-3  # m beyond the two discs' widths


def cam_positions(span, disc_width):
    """Axial positions [m] of the two cams from the output-side crank bearing."""
    return (0.5 * span - 0.5 * disc_width, 0.5 * span + 0.5 * disc_width)


def _secant_over_rated(approach, load_at_rated):
    """Secant stiffness [N/m] of a load-deflection law between 50 % and 100 % of its
    load at rated torque."""
    from .compliance import secant_stiffness

    low, high = (f * load_at_rated for f in RATED_RANGE)
    return secant_stiffness(approach, low, high)


def pin_contact_loads(rated_torque, R_p, e, z_p):
    """(low, high) [N]: the largest pin force at 50 % and 100 % of rated torque (half the
    torque per disc), the range over which a pin's stated stiffness is its law's secant."""
    force = largest_pin_force(rated_torque / 2.0, R_p, e, z_p)
    return tuple(f * force for f in RATED_RANGE)


def pin_law_constants(R_p, r_rp, e, z_p, disc_width, groove_clearance, youngs_modulus, poisson_ratio):
    """(b0 [m/N], F* [N]) of one pin between its disc and its housing groove
    (`pin_law.law_constants`): the disc's radius of curvature where the lever is largest,
    the groove's radius the pin's plus `groove_clearance`."""
    from .pin_law import law_constants

    disc_radius = disc_curvature_radius_at_largest_lever(R_p, r_rp, e, z_p)
    return law_constants(
        r_rp, disc_radius, -(r_rp + groove_clearance), disc_width, youngs_modulus, poisson_ratio
    )


def pin_stiffness_estimate(
    rated_torque, R_p, r_rp, e, z_p, disc_width, groove_clearance, youngs_modulus, poisson_ratio
):
    """One pin between a disc and its housing groove, along the contact normal [N/m]:
    the pin-disc and the pin-groove Hertz line contacts in series (each Radzimovsky's
    approach, `pin_law`), secant over the rated range at the largest pin force (half the
    torque per disc)."""
    from .pin_law import approach

    b0, f_star = pin_law_constants(
        R_p, r_rp, e, z_p, disc_width, groove_clearance, youngs_modulus, poisson_ratio
    )
    low, high = pin_contact_loads(rated_torque, R_p, e, z_p)
    return (high - low) / float(approach(high, b0, f_star) - approach(low, b0, f_star))


def pin_law(design) -> tuple:
    """(k [N/m], b [m/N], F* [N]) of the pins of `design` (`pin_law.contact`): where it gives
    the pins' groove, the Hertz law whose secant over 50-100 % of the rated pin force is the
    stated pin stiffness; else b = F* = 0, the linear spring.

    F* is some four orders of magnitude above the rated pin force for any steel pin (the law
    holds up to F* e^-2, `pin_law.U_LIMIT`)."""
    from .pin_law import scaled_law

    k = design.pin_disc_stiffness
    if design.pin_groove_clearance == 0.0:
        return (k, 0.0, 0.0)
    _, f_star = pin_law_constants(
        design.R_p,
        design.r_rp,
        design.e,
        design.z_p,
        design.disc_width,
        design.pin_groove_clearance,
        design.youngs_modulus,
        design.poisson_ratio,
    )
    low, high = pin_contact_loads(design.rated_torque, design.R_p, design.e, design.z_p)
    return (k, scaled_law(k, f_star, low, high), f_star)


def crank_split_estimate(
    crank_diameter, span, disc_width, bearing_pair, youngs_modulus, poisson_ratio
) -> tuple[float, float]:
    """(each cam, common) compliances [m/N] of the crankshaft between its bearings
    (`compliance.crank_split`), the cams by the rule above."""
    from .compliance import crank_influence, crank_split

    cams = cam_positions(span, disc_width)
    return crank_split(
        crank_influence(youngs_modulus, poisson_ratio, crank_diameter, span, cams), span, cams, bearing_pair
    )


def crank_disc_stiffness_estimate(rated_torque, n_c, crank_radius, rollers, roller_length, crank_compliance):
    """A cam's needle bearing in series with the crankshaft's compliance at that cam [N/m]
    (`crank_split_estimate`'s first value).

    Needle bearing: Palmgren's law with the roller load distribution, no clearance (the
    clearance is an error, docs/model.md section 4), at T / (2 n_c a).
    """
    from .compliance import bearing_deflection

    needle = _secant_over_rated(
        lambda f: bearing_deflection(f, rollers, roller_length), rated_torque / (2.0 * n_c * crank_radius)
    )
    return series(needle, 1.0 / crank_compliance)


def crank_carrier_stiffness_estimate(
    rated_torque, n_c, crank_radius, rollers, roller_length, seed003_contact_angle
):
    """The two tapered roller bearings of one crankshaft, radial, at its cams [N/m].

    Each carries half the crank's load T / (n_c a) (cams symmetric in the span); a roller's
    normal approach is the radial deflection times cos(alpha) and its load's radial part
    Q cos(alpha), alpha the contact angle to the radial plane (seed 003 writes 80 deg from
    the axis: alpha = 90 - 80 = 10 deg).
    """
    from .compliance import bearing_deflection

    alpha = math.pi / 2.0 - seed003_contact_angle
    c = math.cos(alpha)

    def approach(f):  # both bearings alike, each with half the load
        return bearing_deflection(0.5 * f / c, rollers, roller_length) / c

    return _secant_over_rated(approach, rated_torque / (n_c * crank_radius))


def carrier_compliance_estimate(n_c, crank_radius, disc_width, span, youngs_modulus, poisson_ratio):
    """Windup [rad] per output torque [N*m] of the carrier's far flange turning on its
    pillars (`compliance.carrier_torsional_compliance`), pillars by the rule above."""
    from .compliance import (
        carrier_torsional_compliance,
        end_plate_share,
        guided_beam_stiffness,
        round_shear_coefficient,
    )

    diameter = PILLAR_DIAMETER_PER_CRANK_RADIUS * crank_radius
    length = 2.0 * disc_width + PILLAR_EXTRA_LENGTH
    pillar = guided_beam_stiffness(
        youngs_modulus,
        poisson_ratio,
        math.pi * diameter**4 / 64.0,
        math.pi * diameter**2 / 4.0,
        length,
        round_shear_coefficient(poisson_ratio),
    )
    share = end_plate_share(cam_positions(span, disc_width), span)
    return carrier_torsional_compliance(n_c, pillar, crank_radius, share)


def estimate_from_sources(values: dict) -> dict:
    """Every stiffness of a preset file estimated from its geometry and [sources]:
    {file key: value in file units}.  `values`: the preset file as read (file keys)."""
    src = values["sources"]
    mm, E, nu = 1e-3, values["youngs_modulus_GPa"] * 1e9, values["poisson_ratio"]
    T, n_c = values["rated_torque_Nm"], values["n_c"]
    R_p, r_rp, e = values["R_p_mm"] * mm, values["r_rp_mm"] * mm, values["e_mm"] * mm
    module, alpha = values["m_mm"] * mm, math.radians(values["pressure_angle_deg"])
    a = module * (values["z_s"] + values["z_pl"]) / 2.0
    width, gear = values["disc_width_mm"] * mm, values["gear_width_mm"] * mm
    crank, span = src["crank_diameter_mm"] * mm, src["crank_span_mm"] * mm
    pair = crank_carrier_stiffness_estimate(
        T,
        n_c,
        a,
        values["tapered_rollers"],
        values["tapered_roller_length_mm"] * mm,
        math.radians(values["tapered_contact_angle_deg"]),
    )
    at_cam, common = crank_split_estimate(crank, span, width, pair, E, nu)
    return {
        "pin_disc_stiffness_N_per_m": pin_stiffness_estimate(
            T, R_p, r_rp, e, values["z_p"], width, values["pin_groove_clearance_mm"] * mm, E, nu
        ),
        "mesh_stiffness_N_per_m": iso6336_mesh_stiffness(values["z_s"], values["z_pl"], module, alpha, gear),
        "crank_disc_bearing_stiffness_N_per_m": crank_disc_stiffness_estimate(
            T, n_c, a, values["needle_rollers"], values["needle_roller_length_mm"] * mm, at_cam
        ),
        "crank_carrier_bearing_stiffness_N_per_m": series(pair, 1.0 / common),
        "main_bearing_stiffness_N_per_m": (
            src["main_bearing_reference_N_per_m"] * values["R_p_mm"] / src["main_bearing_reference_R_p_mm"]
        ),
        "sun_support_stiffness_N_per_m": cantilever_stiffness(
            E, src["input_shaft_diameter_mm"] * mm, src["input_shaft_length_mm"] * mm
        ),
        "carrier_compliance_arcsec_per_Nm": carrier_compliance_estimate(n_c, a, width, span, E, nu)
        / (math.pi / 180.0 / 3600.0),
    }


# -- the roller law of a design's crank bearings ---------------------------------------------
#
# A design states one stiffness per bearing: its secant over the rated range, the stiffness
# every linear part of the model uses (docs/model.md section 6).  Where it also gives the
# rollers, the bearing follows their law (`roller_law`) and the rest of the stated
# compliance is a linear spring in series (for the needle bearing: the crank bent and sheared
# at its cams): 1 / k_stated = 1 / (the rollers' own secant) + C.  So the law and the stated
# stiffness wind up alike between 50 % and 100 % of the rated torque.

SERIES_ROUNDING = 1e-3  # a stated stiffness this much above the rollers' own secant: no series spring


def roller_secant(a, load_at_rated):
    """Secant stiffness [N/m] of the zero-clearance roller law F = a E(0) s^n over
    50-100 % of its load at rated torque (closed form: s = (F / (a E(0)))^(1/n))."""
    from .roller_law import TABLE_E, N

    return _secant_over_rated(lambda f: (f / (a * TABLE_E[0])) ** (1.0 / N), load_at_rated)


def roller_laws(design) -> dict:
    """{kind: (a [N/m^n], series compliance [m/N])} of the bearings of `design` that follow
    the roller law: "crank_disc" (needle_rollers > 0), "crank_carrier" (tapered_rollers > 0).

    Raises InputError where a stated stiffness is stiffer than its rollers alone."""
    from ..base.checks import InputError
    from .compliance import roller_load_constant
    from .roller_law import load_constant

    crank_load = design.rated_torque / (design.n_c * design.crank_circle_radius)
    laws = {}
    for kind, rollers, length, angle, load, stated, key in (
        (
            "crank_disc",
            design.needle_rollers,
            design.needle_roller_length,
            0.0,
            crank_load / 2.0,
            design.crank_disc_bearing_stiffness,
            "crank_disc_bearing_stiffness_N_per_m",
        ),
        (
            "crank_carrier",
            design.tapered_rollers,
            design.tapered_roller_length,
            math.pi / 2.0 - design.tapered_contact_angle,
            crank_load,
            design.crank_carrier_bearing_stiffness,
            "crank_carrier_bearing_stiffness_N_per_m",
        ),
    ):
        if rollers == 0:
            continue
        a = load_constant(
            rollers, roller_load_constant(length), angle, bearings=1 if kind == "crank_disc" else 2
        )
        own = roller_secant(a, load)
        compliance = 1.0 / stated - 1.0 / own
        if compliance < -SERIES_ROUNDING / stated:
            raise InputError(
                key,
                stated,
                f"must not exceed the secant stiffness of its rollers "
                f"alone, {own:.4g} N/m (50-100 % of the rated load): the rollers "
                "given are softer than the bearing stated",
                design.name,
            )
        laws[kind] = (a, max(compliance, 0.0))
    return laws

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
- rolling bearings use seed 003's formulas (cylindrical/needle: R_pd, tapered:
  R_b);
- a crankshaft is slender: its bending between its support bearings is as soft
  as the bearings themselves, so the crank-disc path is the needle bearing in
  series with the crank bent as a simply supported beam.
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
    e_star = youngs_modulus / (2.0 * (1.0 - poisson_ratio ** 2))
    r_star = 1.0 / (1.0 / radius_1 + 1.0 / radius_2)
    if r_star <= 0:
        raise ValueError("the concave radius must be larger than the convex one")
    b = math.sqrt(4.0 * w * r_star / (math.pi * e_star))
    log_terms = 2.0 / 3.0 + math.log(2.0 * abs(radius_1) / b) + math.log(2.0 * abs(radius_2) / b)
    return 2.0 * w * (1.0 - poisson_ratio ** 2) / (math.pi * youngs_modulus) * log_terms


def hertz_line_contact_stiffness(force, length, radius_1, radius_2, youngs_modulus, poisson_ratio):
    """Secant stiffness force / approach of a line contact at `force` [N/m]."""
    return force / hertz_line_contact_approach(
        force, length, radius_1, radius_2, youngs_modulus, poisson_ratio)


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
    speed = np.sqrt(R_p ** 2 + (e * z_p) ** 2 - 2.0 * R_p * e * z_p * u)
    cross = R_p ** 2 + e ** 2 * z_p ** 3 - R_p * e * z_p * (z_p + 1) * u
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
    c_gamma = c_single * (0.75 * eps + 0.25)          # N / (mm um)
    return c_gamma * (face_width / 1e-3) * 1e6         # N/um per mm * mm -> N/m


def transverse_contact_ratio(z_1, z_2, module, pressure_angle):
    """Contact ratio eps_alpha of an unshifted external spur pair with addendum = module."""
    r1, r2 = module * z_1 / 2.0, module * z_2 / 2.0
    rb1, rb2 = r1 * math.cos(pressure_angle), r2 * math.cos(pressure_angle)
    ra1, ra2 = r1 + module, r2 + module
    path = (math.sqrt(ra1 ** 2 - rb1 ** 2) + math.sqrt(ra2 ** 2 - rb2 ** 2)
            - (r1 + r2) * math.sin(pressure_angle))
    return path / (math.pi * module * math.cos(pressure_angle))


def roller_bearing_stiffness(roller_length, rollers, youngs_modulus, poisson_ratio,
                             contact_angle=None):
    """Radial stiffness of a roller bearing by seed 003's formulas [N/m].

    Cylindrical or needle (R_pd): pi l E n / (8 (1 - mu^2)).
    Tapered (R_b): the same divided by sin(contact_angle); seed 003 uses 80 deg.
    """
    k = math.pi * roller_length * youngs_modulus * rollers / (8.0 * (1.0 - poisson_ratio ** 2))
    if contact_angle is not None:
        k /= math.sin(contact_angle)
    return k


def simply_supported_beam_stiffness(youngs_modulus, diameter, span):
    """Stiffness of a round shaft under a central load between two supports, 48 E I / L^3 [N/m]."""
    inertia = math.pi * diameter ** 4 / 64.0
    return 48.0 * youngs_modulus * inertia / span ** 3


def cantilever_stiffness(youngs_modulus, diameter, length):
    """Stiffness of a round shaft loaded at its free end, 3 E I / L^3 [N/m]."""
    inertia = math.pi * diameter ** 4 / 64.0
    return 3.0 * youngs_modulus * inertia / length ** 3

"""Churning: the power the lubricant takes from the parts that turn in it.

The engineering question: how much does the reducer lose, at no load, to stirring its own
lubricant, and how much more when the joint starts cold?  Palmgren's drag (`friction.py`)
is the lubricant's resistance inside each rolling bearing; this module adds what the large
parts lose pushing the lubricant around the housing: the two cycloid discs, the planet
(spur) gears on their cranks and the sun on the input shaft.  It grows with the viscosity
and steeply with speed, so it is small against the contacts' losses at rated torque and
slow speed, and dominates a lightly loaded, fast or cold reducer.

The law: ISO/TR 14179-2:2001 (Gears -- Thermal capacity -- Part 2: Thermal load-carrying
capacity), its no-load (churning and windage) power loss of a dip-lubricated gear, the
spur-gear form [kW]:

    P = f_g nu n^3 (1.474 D^5.7 + 7.37 D^4.7 b R_f) / (A_g 1e26),   R_f = 7.93 - 4.648 / m

nu the kinematic viscosity at the running temperature [mm^2/s], n the speed [rpm], D the
outside diameter [mm], b the face width [mm], m the module [mm] (R_f: the teeth's roughness
factor), A_g = 0.2 the arrangement constant of a gear in a housing, f_g the dip factor, 0
for a part clear of the lubricant to 1 for one submerged.  The first term is the two side
faces, the second the toothed periphery.  It is the law of a gear dipping in the oil sump
of an enclosed gear unit; no range of speed or viscosity is stated with it here, so a cold
start (nu in the thousands of mm^2/s) is an extrapolation.  It is linear in nu, and its
torque (P / n) grows as n^2.

Where the RV's parts lie against it, and the assumptions (every frame):
- the lubricant's fill `lubricant_fill` is the dip factor of every part: the share of the
  housing's free volume the lubricant fills, each part turning in it as deep; 0 = dry, no
  churning.  RV reducers are grease-filled; the law is the base oil's, at its viscosity
  (`lubricant.viscosity_cSt`), which overstates a grease that has been channelled away from
  the parts after running in;
- the discs: gears of their lobes' outside diameter 2 (R_p + e - r_rp), face width
  `disc_width` and module 2 e (the disc's pitch circle z_c e rolls on the pins' z_p e),
  turning at their own rotation relative to the housing, the output's |n_out| (a disc turns
  with the carrier that holds its cranks).  Their orbit, the translation of their centres
  on circles of radius e at the cranks' speed z_c |n_out|, is not a spinning gear's motion,
  and the law has no form for it: a surface point moves at e times the orbit's speed, 2 e / D
  of a spinning disc's rim at that speed (0.02 on the RV-40E), so the law taken at the
  orbit speed, tried first, put 289 W into the RV-40E's two discs at 60 rpm output (0.38 N*m
  at the input at 40 C, 20 N*m at -10 C), a loss no catalogue's running torque allows.  The
  orbit's share is left out: an open gap of the model, said in docs/model.md section 9;
- the planets with their cranks: n_c spur gears of outside diameter m (z_pl + 2) and face
  width `gear_width`, at the cranks' speed relative to the housing z_c |n_out|;
- the sun: a spur gear of outside diameter m (z_s + 2) and face width `gear_width` at the
  input speed i |n_out|.
At the catalogue's rated 15 rpm the planets' peripheral speed is about 1.7 m/s (RV-40E), the
sun's about 2 m/s: the low end of a dip-lubricated gear unit's range.  The parts' own
bearings are not churning: their drag is Palmgren's, in `friction.py`, counted once.
"""

from __future__ import annotations

import numpy as np

from ..base.units import MM, RPM
from ..laws.lubricant import REFERENCE_TEMPERATURE_C, viscosity_cSt
from ..reducer.design import RVDesign

# ISO/TR 14179-2, the no-load loss of a dip-lubricated spur gear (module docstring).
FACE_COEFFICIENT = 1.474  # the two side faces, x D^5.7
PERIPHERY_COEFFICIENT = 7.37  # the toothed periphery, x D^4.7 b R_f
ARRANGEMENT_CONSTANT = 0.2  # A_g: a gear turning in a housing
LAW_SCALE = 1e26  # the law's units: kW from mm^2/s, rpm, mm
ROUGHNESS_INTERCEPT = 7.93  # R_f = 7.93 - 4.648 / m, m in mm
ROUGHNESS_SLOPE = 4.648
KW = 1e3  # W

CHURNING_NAMES = ("discs churning", "gears churning")
DISCS = 2  # cycloid discs of every RV reducer (docs/model.md section 2)


def roughness_factor(module_mm: float) -> float:
    """ISO/TR 14179-2's roughness factor of a gear's teeth, R_f = 7.93 - 4.648 / m (m [mm]);
    0 below m = 0.586 mm, where the line would make the teeth lose less than a smooth rim."""
    return max(ROUGHNESS_INTERCEPT - ROUGHNESS_SLOPE / module_mm, 0.0)


def gear_churning_power(
    dip: float, viscosity: float, speed_rpm, outer_diameter_mm: float, face_width_mm: float, module_mm: float
) -> np.ndarray:
    """ISO/TR 14179-2's no-load churning loss [W] of one spur gear, shaped like `speed_rpm`:
    dip factor `dip` (0-1), kinematic viscosity `viscosity` [mm^2/s], speeds [rpm] (either
    sign), outside diameter, face width and module [mm] (module docstring)."""
    n = np.abs(np.asarray(speed_rpm, dtype=float))
    return (
        dip
        * viscosity
        * n**3
        * _geometry_term(outer_diameter_mm, face_width_mm, module_mm)
        * KW
        / (ARRANGEMENT_CONSTANT * LAW_SCALE)
    )


def _geometry_term(d: float, b: float, m: float) -> float:
    """1.474 D^5.7 + 7.37 D^4.7 b R_f of ISO/TR 14179-2's gear law (mm)."""
    return FACE_COEFFICIENT * d**5.7 + PERIPHERY_COEFFICIENT * d**4.7 * b * roughness_factor(m)


def churning_parts(design: RVDesign) -> dict:
    """{CHURNING_NAMES: ((count, outside diameter [mm], face width [mm], module [mm], speed per
    output speed), ...)}: the parts that turn in the lubricant, as gears of ISO/TR 14179-2
    (module docstring: the discs, then the planets and the sun)."""
    d = design
    disc = (DISCS, 2.0 * (d.R_p + d.e - d.r_rp) / MM, d.disc_width / MM, 2.0 * d.e / MM, 1.0)
    planet = (d.n_c, d.m * (d.z_pl + 2) / MM, d.gear_width / MM, d.m / MM, d.z_c)
    sun = (1, d.m * (d.z_s + 2) / MM, d.gear_width / MM, d.m / MM, d.ratio)
    return {"discs churning": (disc,), "gears churning": (planet, sun)}


def churning_torques(
    design: RVDesign, output_speed_rpm, temperature_C: float = REFERENCE_TEMPERATURE_C
) -> dict:
    """{CHURNING_NAMES: (V,) [N*m]} the churning of the discs and of the gears as torques at
    the output, their power over the output speed, at output speeds (V,) [rpm] (either
    sign), the lubricant at `temperature_C` [C] and the design's `lubricant_fill`.  The
    power grows as n^3, so the torque as n^2: 0 at standstill.  All zero without a fill."""
    n_out = np.abs(np.atleast_1d(np.asarray(output_speed_rpm, dtype=float)))
    if design.lubricant_fill == 0.0:  # dry: not even the viscosity is needed
        return {name: np.zeros(n_out.shape) for name in CHURNING_NAMES}
    nu = viscosity_cSt(design, temperature_C)
    scale = design.lubricant_fill * nu * KW / (ARRANGEMENT_CONSTANT * LAW_SCALE * RPM)
    out = {}
    for name, parts in churning_parts(design).items():
        # P / w_out = scale' k^3 n_out^3 / (n_out RPM): written on n_out^2, finite at rest
        per_speed = sum(
            count * ratio**3 * _geometry_term(dia, width, module)
            for count, dia, width, module, ratio in parts
        )
        out[name] = scale * per_speed * n_out**2
    return out

"""Lip seals: the friction torque of the reducer's output and input seals, and breakaway.

The engineering question: what torque do the seals take from the motor, and how much more
must it give to start the reducer from rest?  An RV reducer keeps its grease in with a lip
seal on the output flange (between the housing and the carrier, beside the main bearings)
and one on the input shaft.  A lip presses on its counterface with its own preload, not
with the reducer's load, so its friction torque does not depend on the load: at a small
load it is a large share of what is lost, and the input seal, turning i times faster than
the output, costs i times its torque at the output.

The law is SKF's frictional moment of a contact seal (SKF, Rolling bearings catalogue,
PUB BU/P1 17000 EN (2018), chapter "Friction", section "Frictional moment of seals"):

    M_seal = K_S1 * d_s^beta + K_S2    [N*mm],  d_s the seal's counterface diameter [mm],

with beta, K_S1 and K_S2 from its table "Seal frictional moment: exponent and constants", one
row per seal kind and bearing series (SKF_SEAL_ROWS below).  The designs take the row of
the LS seals of cylindrical roller bearings (bearing outside diameter 42 < D <= 360 mm):
beta = 2, K_S1 = 0.032, K_S2 = 50.  Why that row: it is the table's contact lip of a
reinforced NBR seal running on a ground steel counterface with one row for every size of
the presets' output seals (94 to 154 mm); the RS1 rows of deep groove ball bearings change
their constants in steps with the bearing's size.  What is not sure, so the law is an
estimate for these seals, not a calibration:
- the table is for the seals built into rolling bearings; a spring-loaded radial shaft seal
  (DIN 3760) presses harder and turns stiffer, by a factor no source at hand gives;
- the input seals (12 to 20 mm) are below the LS row's bearing sizes: its K_S2 (50 N*mm)
  carries them, an extrapolation;
- SKF's text gives the moment of a sealed bearing, which may be sealed on both sides: if
  the constants are for two seals, one seal takes half; the model takes the whole for one.
SKF's law does not depend on the speed or the oil's viscosity (the lip runs in a thin film
whose shear it leaves in its constants), so the seals take the same torque warm and cold;
the temperature acts through the bearings' drag (`friction.py`, `lubricant.py`).

A design states its seals by their counterface diameters (`output_seal_diameter_mm`,
`input_seal_diameter_mm`; 0 = no such seal) and the row's constants
(`seal_friction_exponent`, `seal_friction_K_S1`, `seal_friction_K_S2_Nmm`).  A stated
`seal_torque_Nm` > 0 is the output seal's torque instead of its law (a measured figure,
or a fitted one: `rvte calibrate --fit seal_torque`).  The presets give the diameters by
one rule for every frame (`seal_diameters_from_sources`): an estimate, no drawing gives them.

Breakaway.  From rest a lubricated contact must first break its boundary film: it starts at
a friction above its running one.  SKF's friction model takes the sliding friction
coefficient of its boundary film as 0.12 running and 0.15 at standstill (Rolling bearings
catalogue, "Sliding frictional moment": mu_bl), a ratio of 1.25; the designs take that
ratio (`static_friction_factor`) for every Coulomb contact (pins, meshes, the bearings'
load-proportional moment) and for the seals, whose own breakaway no source at hand gives
(after a long standstill a lip breaks away higher: 1.25 is the least of it, an estimate).
Palmgren's load-free drag is viscous: it has no breakaway (`friction.py`).
"""

from __future__ import annotations

import numpy as np

from ..base.checks import InputError
from ..base.units import MM

# SKF, Rolling bearings catalogue (2018), "Seal frictional moment: exponent and constants":
# {seal kind and bearing series, its bearing outside diameters D [mm]: (beta, K_S1, K_S2 [N*mm])};
# d_s is the counterface the table names (d1, d2 or E of the bearing's dimension table).
SKF_SEAL_ROWS = {
    "RSL, deep groove ball, D <= 25": (0.0, 0.0, 0.0),
    "RSL, deep groove ball, 25 < D <= 52": (2.25, 0.0018, 0.0),
    "RSH, deep groove ball, D <= 52": (2.25, 0.028, 2.0),
    "RS1, deep groove ball, D <= 62": (2.25, 0.023, 2.0),
    "RS1, deep groove ball, 62 < D <= 80": (2.25, 0.018, 20.0),
    "RS1, deep groove ball, 80 < D <= 100": (2.25, 0.018, 15.0),
    "RS1, deep groove ball, 100 < D": (2.25, 0.018, 0.0),
    "RS1, angular contact ball, 30 < D <= 120": (2.0, 0.014, 10.0),
    "RS1, self-aligning ball, 30 < D <= 125": (2.0, 0.014, 10.0),
    "LS, cylindrical roller, 42 < D <= 360": (2.0, 0.032, 50.0),
    "CS, CS2, CS5, spherical roller, 62 < D <= 300": (2.0, 0.057, 50.0),
    "CS5, CARB toroidal roller, 42 < D <= 340": (2.0, 0.057, 50.0),
}
DEFAULT_SEAL_ROW = "LS, cylindrical roller, 42 < D <= 360"
SEAL_NAMES = ("output seal", "input seal")  # the seals' names among the losses (`seal_torques`)
# SKF's exponents are 0, 2 and 2.25; a counterface's moment cannot grow faster than its
# contact length times the lip's lever times a load growing with the size, d^3.
EXPONENT_RANGE = (0.0, 3.0)
# A seal sits inside the housing, whose outline is about 1.5 x the pin circle's diameter
# (RV-40E: 190 mm about a pin circle of 128 mm); a counterface beyond is no seal of the frame.
SEAL_DIAMETER_FACTOR = 1.5
# Breakaway over running friction: SKF's mu_bl, 0.15 at standstill over 0.12 running.
STATIC_FRICTION_FACTOR = 0.15 / 0.12
# A contact that breaks away at more than 3 x its running friction has lost its film at
# rest, a state the running coefficients do not describe.
STATIC_FACTOR_RANGE = (1.0, 3.0)
# The presets' rule: the output seal runs on the carrier flange just inside the main
# bearings, their pitch diameter less this margin (the inner ring's half-section and the
# seal's seat); the input seal on the input shaft, at its diameter.
OUTPUT_SEAL_MARGIN_MM = 10.0


def lip_seal_torque(diameter, exponent: float, k_s1: float, k_s2: float):
    """SKF's seal frictional moment [N*m], shaped like `diameter` [m] (the counterface):
    (K_S1 (d_s / mm)^beta + K_S2) N*mm; 0 where the diameter is 0 (no seal)."""
    d_mm = np.asarray(diameter, dtype=float) / MM
    torque = (k_s1 * d_mm**exponent + k_s2) * 1e-3
    return np.where(d_mm > 0.0, torque, 0.0)


def seal_torques(design) -> dict:
    """{"output seal": [N*m] at the output, "input seal": [N*m] at the input} the running
    friction torque of each seal of `design`: its stated `seal_torque` > 0 for the output
    seal, else SKF's law on the seal's counterface diameter (0 without a seal)."""
    d = design
    law = {
        name: float(
            lip_seal_torque(diameter, d.seal_friction_exponent, d.seal_friction_K_S1, d.seal_friction_K_S2)
        )
        for name, diameter in zip(SEAL_NAMES, (d.output_seal_diameter, d.input_seal_diameter))
    }
    if d.seal_torque > 0.0:
        law["output seal"] = float(d.seal_torque)
    return law


def seal_diameters_from_sources(values: dict) -> dict:
    """The seals' counterface diameters of a preset file {file key: mm}, by one rule for
    every frame: the output seal on the carrier flange, the main bearings' pitch diameter
    less OUTPUT_SEAL_MARGIN_MM; the input seal on the input shaft ([sources])."""
    return {
        "output_seal_diameter_mm": values["main_bearing_pitch_diameter_mm"] - OUTPUT_SEAL_MARGIN_MM,
        "input_seal_diameter_mm": values["sources"]["input_shaft_diameter_mm"],
    }


def check_seals(design, where: str = "") -> None:
    """Refuse (InputError) a seal diameter beyond SEAL_DIAMETER_FACTOR x the pin circle's, an
    exponent outside EXPONENT_RANGE or a static friction factor outside STATIC_FACTOR_RANGE
    (each field's own sign is checked where the design is built)."""
    d = design
    largest = SEAL_DIAMETER_FACTOR * 2.0 * d.R_p
    for key, value in (
        ("output_seal_diameter_mm", d.output_seal_diameter),
        ("input_seal_diameter_mm", d.input_seal_diameter),
    ):
        if value > largest:
            raise InputError(
                key,
                value / MM,
                f"must be from 0 (no seal) to {largest / MM:.4g} mm, "
                f"{SEAL_DIAMETER_FACTOR:g} x the pin circle's diameter: a seal sits "
                "inside the housing",
                where,
            )
    low, high = EXPONENT_RANGE
    if not low <= d.seal_friction_exponent <= high:
        raise InputError(
            "seal_friction_exponent",
            d.seal_friction_exponent,
            f"must be from {low:g} to {high:g} (SKF's seal exponents are 0, 2 and 2.25)",
            where,
        )
    low, high = STATIC_FACTOR_RANGE
    if not low <= d.static_friction_factor <= high:
        raise InputError(
            "static_friction_factor",
            d.static_friction_factor,
            f"must be from {low:g} to {high:g}: a contact breaks away at no less "
            "than its running friction, and a lubricated one at no more than "
            f"{high:g} x it",
            where,
        )

"""The RV reducer design: geometry, stiffnesses, inertias and ratings.

A design is plain, frozen data in SI units, checked once when it is built.
Files speak the units of docs/model.md section 1 and carry the unit in the key
(`R_p_mm`, `mesh_stiffness_N_per_m`); `DESIGN_FIELDS` is the one table that
maps a file key to a field and its scale.  A design file is either complete
or names a shipped preset (`preset = "RV-40E-121"`) and overrides any field by
its file key.  A preset by its name is calibrated against its frame's catalogue
(the `[calibration]` table of its file); `<name>-estimate` is the same preset
before calibration.  The masses, inertias and damping ratio are checked and kept for
the dynamic model (rvfmu/core/dynamics/dynamic.py); the quasi-static model does not use them.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..base.checks import InputError, finite_number, integer, non_negative, positive
from ..base.units import ARCMIN, ARCSEC, DEG, GPA, MM, RPM
from ..laws.lubricant import check_lubricant
from ..laws.seals import check_seals


@dataclass(frozen=True)
class FieldSpec:
    """How one design field is written in files and what values it takes."""

    field: str
    file_key: str
    scale: float  # file value * scale = SI value
    kind: str  # "int" (>= 1), "count" (>= 0), "positive", "signed", "non_negative", "fraction"
    doc: str
    default: float | None = None  # the value when a file leaves it out; None: required


DESIGN_FIELDS = (
    FieldSpec("z_s", "z_s", 1, "int", "sun teeth"),
    FieldSpec("z_pl", "z_pl", 1, "int", "planet teeth"),
    FieldSpec("m", "m_mm", MM, "positive", "stage-1 module"),
    FieldSpec("pressure_angle", "pressure_angle_deg", DEG, "positive", "stage-1 pressure angle"),
    FieldSpec("gear_width", "gear_width_mm", MM, "positive", "sun/planet face width"),
    FieldSpec("z_p", "z_p", 1, "int", "pins"),
    FieldSpec("z_c", "z_c", 1, "int", "disc lobes (z_p - 1)"),
    FieldSpec("R_p", "R_p_mm", MM, "positive", "pin circle radius"),
    FieldSpec("r_rp", "r_rp_mm", MM, "positive", "pin radius"),
    FieldSpec("e", "e_mm", MM, "positive", "eccentricity"),
    FieldSpec("d_rp", "d_rp_mm", MM, "signed", "shift (move-distance) modification"),
    FieldSpec("d_rrp", "d_rrp_mm", MM, "signed", "equidistant modification"),
    FieldSpec("disc_width", "disc_width_mm", MM, "positive", "face width of one disc"),
    FieldSpec("n_c", "n_c", 1, "int", "crankshafts"),
    FieldSpec(
        "pin_disc_stiffness",
        "pin_disc_stiffness_N_per_m",
        1.0,
        "positive",
        "one pin against one disc, along the contact normal",
    ),
    FieldSpec(
        "mesh_stiffness",
        "mesh_stiffness_N_per_m",
        1.0,
        "positive",
        "sun-planet mesh, along the line of action",
    ),
    FieldSpec(
        "crank_disc_bearing_stiffness",
        "crank_disc_bearing_stiffness_N_per_m",
        1.0,
        "positive",
        "needle bearing between one cam and its disc hole, radial",
    ),
    FieldSpec(
        "crank_carrier_bearing_stiffness",
        "crank_carrier_bearing_stiffness_N_per_m",
        1.0,
        "positive",
        "support bearings of one crankshaft in the carrier, radial",
    ),
    FieldSpec(
        "main_bearing_stiffness",
        "main_bearing_stiffness_N_per_m",
        1.0,
        "positive",
        "carrier main bearings, radial",
    ),
    FieldSpec(
        "sun_support_stiffness",
        "sun_support_stiffness_N_per_m",
        1.0,
        "positive",
        "input shaft radial support of the sun",
    ),
    FieldSpec(
        "damping_ratio", "damping_ratio", 1.0, "fraction", "damping ratio of every mode of the dynamic model"
    ),
    FieldSpec("sun_mass", "sun_mass_kg", 1.0, "positive", "sun gear with input shaft"),
    FieldSpec("sun_inertia", "sun_inertia_kg_m2", 1.0, "positive", "sun gear with input shaft"),
    FieldSpec("crank_mass", "crank_mass_kg", 1.0, "positive", "one planet with its crankshaft"),
    FieldSpec("crank_inertia", "crank_inertia_kg_m2", 1.0, "positive", "one planet with its crankshaft"),
    FieldSpec("disc_mass", "disc_mass_kg", 1.0, "positive", "one cycloid disc"),
    FieldSpec("disc_inertia", "disc_inertia_kg_m2", 1.0, "positive", "one cycloid disc"),
    FieldSpec("carrier_mass", "carrier_mass_kg", 1.0, "positive", "carrier (output flange)"),
    FieldSpec("carrier_inertia", "carrier_inertia_kg_m2", 1.0, "positive", "carrier (output flange)"),
    FieldSpec("rated_torque", "rated_torque_Nm", 1.0, "positive", "catalogue rated output torque"),
    FieldSpec(
        "allowable_output_speed",
        "allowable_output_speed_rpm",
        RPM,
        "positive",
        "catalogue allowable output speed (rvfmu/core/reducer/limits.py refuses beyond "
        "SPEED_FACTOR x it); left out, the fastest frame of the E series' (RV-6E)",
        100.0,
    ),
    FieldSpec("youngs_modulus", "youngs_modulus_GPa", GPA, "positive", "steel of the parts"),
    FieldSpec("poisson_ratio", "poisson_ratio", 1.0, "fraction", "steel of the parts"),
    FieldSpec(
        "needle_rollers",
        "needle_rollers",
        1,
        "count",
        "needles of one crank-disc bearing: with them the bearing follows the roller law "
        "(docs/model.md section 6); 0 = the linear spring crank_disc_bearing_stiffness",
        0,
    ),
    FieldSpec(
        "needle_roller_length",
        "needle_roller_length_mm",
        MM,
        "non_negative",
        "effective contact length of a needle",
        0.0,
    ),
    FieldSpec(
        "tapered_rollers",
        "tapered_rollers",
        1,
        "count",
        "rollers of one of the two tapered roller bearings of a crankshaft in the carrier: "
        "with them the pair follows the roller law; 0 = the linear spring "
        "crank_carrier_bearing_stiffness",
        0,
    ),
    FieldSpec(
        "tapered_roller_length",
        "tapered_roller_length_mm",
        MM,
        "non_negative",
        "effective contact length of a tapered roller",
        0.0,
    ),
    FieldSpec(
        "tapered_contact_angle",
        "tapered_contact_angle_deg",
        DEG,
        "non_negative",
        "contact angle of the tapered rollers, from the axis (seed 003: 80 deg)",
        0.0,
    ),
    FieldSpec(
        "pin_groove_clearance",
        "pin_groove_clearance_mm",
        MM,
        "non_negative",
        "radius of the pins' housing grooves less the pin radius: with it the pins follow "
        "the Hertz law of two line contacts in series (docs/model.md section 6); 0 = the "
        "linear spring pin_disc_stiffness",
        0.0,
    ),
    FieldSpec(
        "carrier_compliance",
        "carrier_compliance_arcsec_per_Nm",
        ARCSEC,
        "non_negative",
        "torsional compliance of the carrier in series with the output: its far flange "
        "turning on its pillars, windup per output torque (estimated from geometry); "
        "0 = rigid",
        0.0,
    ),
    FieldSpec(
        "output_compliance",
        "output_compliance_arcsec_per_Nm",
        ARCSEC,
        "non_negative",
        "further torsional compliance in series with the output (what no element "
        "models: output flange, housing and its fixing), windup per output torque, "
        "fitted by calibration; 0 = rigid",
        0.0,
    ),
    # Friction (docs/model.md section 9, `friction.py`): the defaults are the literature's
    # values named there; a coefficient of 0 leaves its contact without friction, a bearing
    # without a pitch diameter has none.
    FieldSpec(
        "pin_disc_friction",
        "pin_disc_friction_coefficient",
        1.0,
        "non_negative",
        "Coulomb coefficient of a pin on a disc lobe",
        0.05,
    ),
    FieldSpec(
        "pin_groove_friction",
        "pin_groove_friction_coefficient",
        1.0,
        "non_negative",
        "Coulomb coefficient of a pin in its housing groove",
        0.05,
    ),
    FieldSpec(
        "mesh_friction",
        "mesh_friction_coefficient",
        1.0,
        "non_negative",
        "mean Coulomb coefficient of the sun-planet meshes (ISO/TR 14179-2)",
        0.05,
    ),
    FieldSpec(
        "needle_friction",
        "needle_bearing_friction_coefficient",
        1.0,
        "non_negative",
        "load-proportional friction of a crank-disc needle bearing, M = mu P d_m / 2",
        0.002,
    ),
    FieldSpec(
        "tapered_friction",
        "tapered_bearing_friction_coefficient",
        1.0,
        "non_negative",
        "load-proportional friction of a crank's tapered roller bearings",
        0.0018,
    ),
    FieldSpec(
        "main_bearing_friction",
        "main_bearing_friction_coefficient",
        1.0,
        "non_negative",
        "load-proportional friction of the main bearings",
        0.002,
    ),
    FieldSpec(
        "bearing_drag_factor",
        "bearing_drag_factor",
        1.0,
        "non_negative",
        "Palmgren's f0 of the load-free drag of every rolling bearing",
        2.0,
    ),
    FieldSpec(
        "lubricant_viscosity",
        "lubricant_viscosity_cSt",
        1.0,
        "non_negative",
        "kinematic viscosity of the lubricant [mm^2/s], when stated the same at every "
        "temperature; 0 = not stated: that of lubricant_iso_vg and "
        "lubricant_viscosity_index at the temperature (rvfmu/core/laws/lubricant.py)",
        0.0,
    ),
    FieldSpec(
        "lubricant_iso_vg",
        "lubricant_iso_vg",
        1,
        "int",
        "ISO 3448 viscosity grade of the lubricant: its viscosity at 40 C [mm^2/s]",
        100,
    ),
    FieldSpec(
        "lubricant_viscosity_index",
        "lubricant_viscosity_index",
        1.0,
        "signed",
        "viscosity index of the lubricant (ASTM D2270), 0 to 400; 95: a typical mineral gear oil",
        95.0,
    ),
    FieldSpec(
        "lubricant_fill",
        "lubricant_fill",
        1.0,
        "non_negative",
        "share of the housing's free volume the lubricant fills, 0 to 1: the dip factor "
        "of the churning of the discs and gears (rvfmu/core/losses/churning.py); 0 = dry, none",
        0.0,
    ),
    FieldSpec(
        "needle_pitch_diameter",
        "needle_pitch_diameter_mm",
        MM,
        "non_negative",
        "pitch diameter of a crank-disc needle bearing; 0 = its friction left out",
        0.0,
    ),
    FieldSpec(
        "tapered_pitch_diameter",
        "tapered_pitch_diameter_mm",
        MM,
        "non_negative",
        "pitch diameter of a crank's tapered roller bearings; 0 = their friction left out",
        0.0,
    ),
    FieldSpec(
        "main_bearing_pitch_diameter",
        "main_bearing_pitch_diameter_mm",
        MM,
        "non_negative",
        "pitch diameter of the main bearings; 0 = their friction left out",
        0.0,
    ),
    FieldSpec(
        "seal_torque",
        "seal_torque_Nm",
        1.0,
        "non_negative",
        "friction torque of the output's lip seal when stated (> 0), instead of its law; "
        "0 = its law (rvfmu/core/laws/seals.py)",
        0.0,
    ),
    # The seals (`seals.py`): SKF's M = K_S1 d_s^beta + K_S2 on each seal's counterface, the
    # constants of its LS row by default; breakaway = static factor x running friction.
    FieldSpec(
        "output_seal_diameter",
        "output_seal_diameter_mm",
        MM,
        "non_negative",
        "counterface diameter of the output's lip seal; 0 = no seal law",
        0.0,
    ),
    FieldSpec(
        "input_seal_diameter",
        "input_seal_diameter_mm",
        MM,
        "non_negative",
        "counterface diameter of the input shaft's lip seal; 0 = no input seal",
        0.0,
    ),
    FieldSpec(
        "seal_friction_exponent",
        "seal_friction_exponent",
        1.0,
        "non_negative",
        "SKF's seal exponent beta, 0 to 3",
        2.0,
    ),
    FieldSpec(
        "seal_friction_K_S1",
        "seal_friction_K_S1",
        1.0,
        "non_negative",
        "SKF's seal constant K_S1 [N*mm / mm^beta]",
        0.032,
    ),
    FieldSpec(
        "seal_friction_K_S2",
        "seal_friction_K_S2_Nmm",
        1.0,
        "non_negative",
        "SKF's seal constant K_S2 [N*mm]",
        50.0,
    ),
    FieldSpec(
        "static_friction_factor",
        "static_friction_factor",
        1.0,
        "positive",
        "breakaway over running friction of the Coulomb contacts and the seals, 1 to 3 "
        "(SKF's mu_bl 0.15 / 0.12)",
        1.25,
    ),
)

_BY_KEY = {spec.file_key: spec for spec in DESIGN_FIELDS}

# What stiffness an element of a reducer can have [N/m].  Every element is a steel contact,
# bearing or mesh; their stiffness grows with size and barely with load.  Stiffest: the main
# bearings (seed 003 identified 8e10 N/m on the RV-20E; the presets scale it to 1.3e11 on the
# RV-110E); a line contact gives about E' x its length / 2, 1e10 N/m for 100 mm of steel, so
# 1e12 is eight times the stiffest element of the presets.  Softest: the input shaft's radial
# support (the presets 5e6-1.4e7 N/m; a 10 mm shaft overhanging 100 mm gives 3e5), and a
# mesh gives about 2e7 N/m per mm of face width (ISO 6336-1).  Beyond the range the model
# is no reducer: pins of 1e15 N/m once printed a rigidity of 289 N*m/arcmin for a frame of 108.
STIFFNESS_RANGE = (1e5, 1e12)
STIFFNESS_FIELDS = (
    "pin_disc_stiffness",
    "mesh_stiffness",
    "crank_disc_bearing_stiffness",
    "crank_carrier_bearing_stiffness",
    "main_bearing_stiffness",
    "sun_support_stiffness",
)
# The elements that hold the solver's reduced unknowns (all but the sun support, which only
# holds the sun, condensed out exactly) must lie within this factor of each other.  The
# solver's weak springs are REGULARISATION = 1e-6 x the softest of them (or 30 x the sun
# support, `solver.weak_stiffness`), so the stiffest over them, the conditioning of the Newton
# steps, stays below 1e11 (3e11 with the softest sun support), where it converges; at 1e13
# (pins of 1e5 N/m beside meshes of 1e12) it no longer did.  The presets span 600.
STIFFNESS_SPREAD = 1e5
# A series compliance (carrier pillars, the output's) that alone winds the output up by more
# than this at rated torque is no reducer: catalogue frames wind up 3-4 arcmin there in all.
SERIES_WINDUP_MAX = 60.0 * ARCMIN
INTEGER_MINIMUM = {"int": 1, "count": 0}  # the whole-number kinds and their least value
PRESET_NAMES = ("RV-40E-121", "RV-40E-81", "RV-20E", "RV-110E")
# A preset by its name is calibrated against its frame's catalogue figures (the [calibration]
# table of its file); the same name with this suffix is the estimate from the seeds and the
# formulas alone, before calibration.
ESTIMATE_SUFFIX = "-estimate"
ESTIMATE_NAMES = tuple(name + ESTIMATE_SUFFIX for name in PRESET_NAMES)


@dataclass(frozen=True)
class RVDesign:
    """An RV reducer (docs/model.md sections 2, 3 and 6), SI units throughout.

    Build it with `RVDesign(**fields)`, `load_design(...)` or `preset(...)`;
    the constructor checks every field and every relation between fields.
    """

    name: str
    z_s: int
    z_pl: int
    m: float
    pressure_angle: float
    gear_width: float
    z_p: int
    z_c: int
    R_p: float
    r_rp: float
    e: float
    d_rp: float
    d_rrp: float
    disc_width: float
    n_c: int
    pin_disc_stiffness: float
    mesh_stiffness: float
    crank_disc_bearing_stiffness: float
    crank_carrier_bearing_stiffness: float
    main_bearing_stiffness: float
    sun_support_stiffness: float
    damping_ratio: float
    sun_mass: float
    sun_inertia: float
    crank_mass: float
    crank_inertia: float
    disc_mass: float
    disc_inertia: float
    carrier_mass: float
    carrier_inertia: float
    rated_torque: float
    youngs_modulus: float
    poisson_ratio: float
    needle_rollers: int = 0
    needle_roller_length: float = 0.0
    tapered_rollers: int = 0
    tapered_roller_length: float = 0.0
    tapered_contact_angle: float = 0.0
    pin_groove_clearance: float = 0.0
    carrier_compliance: float = 0.0
    output_compliance: float = 0.0
    pin_disc_friction: float = 0.05
    pin_groove_friction: float = 0.05
    mesh_friction: float = 0.05
    needle_friction: float = 0.002
    tapered_friction: float = 0.0018
    main_bearing_friction: float = 0.002
    bearing_drag_factor: float = 2.0
    lubricant_viscosity: float = 0.0
    lubricant_iso_vg: int = 100
    lubricant_viscosity_index: float = 95.0
    lubricant_fill: float = 0.0
    needle_pitch_diameter: float = 0.0
    tapered_pitch_diameter: float = 0.0
    main_bearing_pitch_diameter: float = 0.0
    seal_torque: float = 0.0
    output_seal_diameter: float = 0.0
    input_seal_diameter: float = 0.0
    seal_friction_exponent: float = 2.0
    seal_friction_K_S1: float = 0.032
    seal_friction_K_S2: float = 50.0
    static_friction_factor: float = 1.25
    allowable_output_speed: float = 100.0 * RPM

    def __post_init__(self):
        for spec in DESIGN_FIELDS:
            object.__setattr__(self, spec.field, _checked(spec, getattr(self, spec.field), self.name))
        _check_relations(self)
        self.roller_laws  # noqa: B018 (a stated stiffness its rollers cannot reach is refused now)

    # -- derived quantities (docs/model.md section 2) --------------------------------
    @property
    def ratio(self) -> float:
        """Reduction ratio with fixed housing and carrier output, i = 1 + z_pl/z_s * z_p."""
        return 1.0 + self.z_pl / self.z_s * self.z_p

    @property
    def crank_circle_radius(self) -> float:
        """Stage-1 centre distance m*(z_s + z_pl)/2 [m]: where the crank axes sit."""
        return self.m * (self.z_s + self.z_pl) / 2.0

    @property
    def sun_base_radius(self) -> float:
        return self.m * self.z_s / 2.0 * math.cos(self.pressure_angle)

    @property
    def planet_base_radius(self) -> float:
        return self.m * self.z_pl / 2.0 * math.cos(self.pressure_angle)

    @property
    def series_compliance(self) -> float:
        """Everything in series with the output [rad per N*m]: the carrier's pillars and the
        calibrated output compliance; the output flange turns by tau_load times it beyond
        the carrier's crank seats."""
        return self.carrier_compliance + self.output_compliance

    @functools.cached_property
    def roller_laws(self) -> dict:
        """{"crank_disc" | "crank_carrier": (a, series compliance)} of the crank bearings that
        follow the roller law (`stiffness.roller_laws`); empty without roller geometry."""
        from ..laws.stiffness import roller_laws

        return roller_laws(self)

    @functools.cached_property
    def pin_law(self) -> tuple:
        """(k [N/m], b [m/N], F* [N]) of the pins' contact law (`pin_law.contact`): b = 0 the
        linear spring k, without the pins' groove (`stiffness.pin_law`)."""
        from ..laws.stiffness import pin_law

        return pin_law(self)

    @property
    def tip_root_clearance(self) -> float:
        """Radial pin clearance at every lobe tip and root, d_rrp - d_rp [m] (docs/model.md section 3)."""
        return self.d_rrp - self.d_rp

    def with_fields(self, **changes) -> "RVDesign":
        """A copy with some SI fields changed (checked again)."""
        return dataclasses.replace(self, **changes)

    def file_values(self) -> dict:
        """The design as a design file would write it (file keys and units)."""
        values = {"name": self.name}
        for spec in DESIGN_FIELDS:
            value = getattr(self, spec.field)
            values[spec.file_key] = value if spec.kind in INTEGER_MINIMUM else value / spec.scale
        return values


def in_file_units(fields: dict) -> dict:
    """{file key: value in file units} of some SI design fields {field: value}."""
    specs = {spec.field: spec for spec in DESIGN_FIELDS}
    return {
        specs[k].file_key: v if specs[k].kind in INTEGER_MINIMUM else v / specs[k].scale
        for k, v in fields.items()
    }


def _checked(spec: FieldSpec, value, where: str):
    if spec.kind in INTEGER_MINIMUM:
        return integer(spec.file_key, value, INTEGER_MINIMUM[spec.kind], where=where)
    # Checks are made on the file value so that the message shows what the user wrote.
    shown = value / spec.scale if isinstance(value, (int, float)) and not isinstance(value, bool) else value
    if spec.kind == "positive":
        positive(spec.file_key, shown, where)
    elif spec.kind == "non_negative":
        non_negative(spec.file_key, shown, where)
    elif spec.kind == "fraction":
        shown = finite_number(spec.file_key, shown, where)
        if not 0.0 <= shown < 1.0:
            raise InputError(spec.file_key, shown, "must be from 0 to below 1", where)
    else:
        finite_number(spec.file_key, shown, where)
    return float(value)


def _check_relations(d: RVDesign) -> None:
    where = d.name
    if d.z_c != d.z_p - 1:
        raise InputError("z_c", d.z_c, f"must be z_p - 1 = {d.z_p - 1}", where)
    if d.z_p % 2:
        raise InputError(
            "z_p",
            d.z_p,
            "must be even: disc 1 is disc 0 turned by 180 deg, "
            "which is conjugate only for even z_p (docs/model.md section 4)",
            where,
        )
    if d.z_p < 6:
        raise InputError("z_p", d.z_p, "must be >= 6", where)
    if d.n_c not in (2, 3):
        raise InputError("n_c", d.n_c, "must be 2 or 3 crankshafts", where)
    if d.z_s < 6 or d.z_pl < 6:
        field, value = ("z_s", d.z_s) if d.z_s < 6 else ("z_pl", d.z_pl)
        raise InputError(field, value, "must be >= 6 teeth", where)
    if d.z_s % d.n_c:
        raise InputError(
            "z_s",
            d.z_s,
            f"must be divisible by n_c = {d.n_c} so that all planets, "
            "fixed to cranks turning together, mesh in phase",
            where,
        )
    e_max = d.R_p / d.z_p
    if d.e >= e_max:
        raise InputError(
            "e_mm",
            d.e / MM,
            f"must be < R_p/z_p = {e_max / MM:.4g} mm "
            "(otherwise the trochoid loops and the disc cannot be made)",
            where,
        )
    pin_gap = 2.0 * d.R_p * math.sin(math.pi / d.z_p)
    if 2.0 * d.r_rp >= pin_gap:
        raise InputError(
            "r_rp_mm", d.r_rp / MM, f"must be < {pin_gap / 2 / MM:.4g} mm: neighbouring pins overlap", where
        )
    rho_min = min_trochoid_curvature_radius(d.R_p, d.e, d.z_p)
    if d.r_rp + d.d_rrp >= rho_min:
        raise InputError(
            "r_rp_mm",
            d.r_rp / MM,
            f"with d_rrp must stay below the smallest convex radius of curvature "
            f"of the pin path, {rho_min / MM:.4g} mm (else the profile undercuts)",
            where,
        )
    if abs(d.d_rp) > 0.01 * d.R_p or abs(d.d_rrp) > 0.5 * d.r_rp:
        field, value = ("d_rp_mm", d.d_rp) if abs(d.d_rp) > 0.01 * d.R_p else ("d_rrp_mm", d.d_rrp)
        raise InputError(
            field,
            value / MM,
            "is too large for a profile modification (|d_rp| <= 1 % of R_p, |d_rrp| <= half the pin radius)",
            where,
        )
    a = d.crank_circle_radius
    planet_tip = d.m * (d.z_pl + 2) / 2.0
    if d.n_c > 1 and 2.0 * a * math.sin(math.pi / d.n_c) <= 2.0 * planet_tip:
        raise InputError(
            "z_pl",
            d.z_pl,
            f"planets of tip radius {planet_tip / MM:.4g} mm collide "
            f"on a crank circle of {a / MM:.4g} mm with {d.n_c} cranks",
            where,
        )
    for rollers, length, name in (
        (d.needle_rollers, d.needle_roller_length, "needle"),
        (d.tapered_rollers, d.tapered_roller_length, "tapered"),
    ):
        if rollers and not length > 0.0:
            raise InputError(
                f"{name}_roller_length_mm", length / MM, f"must be > 0 with {name}_rollers = {rollers}", where
            )
    if d.pin_groove_clearance > d.r_rp:
        raise InputError(
            "pin_groove_clearance_mm",
            d.pin_groove_clearance / MM,
            f"must not exceed the pin radius {d.r_rp / MM:.4g} mm: a groove that wide does not hold its pin",
            where,
        )
    if d.tapered_rollers and not 0.0 < d.tapered_contact_angle < math.pi / 2.0:
        raise InputError(
            "tapered_contact_angle_deg",
            math.degrees(d.tapered_contact_angle),
            "must be between 0 and 90 deg (from the axis) with tapered rollers",
            where,
        )
    if not 0.0 < d.pressure_angle < math.radians(45):
        raise InputError(
            "pressure_angle_deg", math.degrees(d.pressure_angle), "must be between 0 and 45 deg", where
        )
    check_lubricant(d.lubricant_iso_vg, d.lubricant_viscosity_index, where)
    check_seals(d, where)
    if d.lubricant_fill > 1.0:
        raise InputError(
            "lubricant_fill",
            d.lubricant_fill,
            "must be from 0 to 1: the share of the housing's free volume the lubricant fills (1 = full)",
            where,
        )
    _check_stiffnesses(d)


def _check_stiffnesses(d: RVDesign) -> None:
    """Every stiffness within STIFFNESS_RANGE, those the solver's reduced unknowns feel within
    STIFFNESS_SPREAD of each other, each series compliance within SERIES_WINDUP_MAX at rated
    torque."""
    where = d.name
    low, high = STIFFNESS_RANGE
    for field in STIFFNESS_FIELDS:
        value = getattr(d, field)
        if not low <= value <= high:
            raise InputError(
                f"{field}_N_per_m",
                value,
                f"must be from {low:.0e} to {high:.0e} N/m, "
                "the range of steel contacts, bearings and meshes in reducers",
                where,
            )
    held = {field: getattr(d, field) for field in STIFFNESS_FIELDS if field != "sun_support_stiffness"}
    softest, stiffest = min(held, key=held.get), max(held, key=held.get)
    if held[stiffest] > STIFFNESS_SPREAD * held[softest]:
        raise InputError(
            f"{softest}_N_per_m",
            held[softest],
            f"must be from {held[stiffest] / STIFFNESS_SPREAD:.4g} to {high:.0e} N/m: "
            f"within {STIFFNESS_SPREAD:.0e} x of the stiffest of the pins, meshes and "
            f"bearings ({stiffest}_N_per_m = {held[stiffest]:.4g}), or the "
            "equilibrium is too ill-conditioned to solve",
            where,
        )
    for field in ("carrier_compliance", "output_compliance"):
        value, limit = getattr(d, field), SERIES_WINDUP_MAX / d.rated_torque
        if value > limit:
            raise InputError(
                f"{field}_arcsec_per_Nm",
                value / ARCSEC,
                f"must be from 0 to {limit / ARCSEC:.4g} arcsec/(N*m): more winds the "
                f"output up by over {SERIES_WINDUP_MAX / ARCMIN:g} arcmin at the rated "
                f"torque {d.rated_torque:g} N*m by itself",
                where,
            )


def min_trochoid_curvature_radius(R_p: float, e: float, z_p: int) -> float:
    """Smallest radius of curvature of the convex part of the pin-centre path [m].

    The path in the disc frame is C(t) = (R cos t - e cos z t, R sin t - e sin z t) with
    z = z_p.  With u = cos((z - 1) t):  |C'|^2 = R^2 + e^2 z^2 - 2 R e z u  and
    C' x C'' = R^2 + e^2 z^3 - R e z (z + 1) u, so the radius |C'|^3 / (C' x C'') depends
    on u alone; the inward offset by the pin radius undercuts where that radius, on the
    convex part (C' x C'' > 0), is smaller than the pin radius.
    """
    u = np.linspace(-1.0, 1.0, 4001)
    speed = np.sqrt(R_p * R_p + e * e * z_p * z_p - 2.0 * R_p * e * z_p * u)
    cross = R_p * R_p + e * e * z_p**3 - R_p * e * z_p * (z_p + 1) * u
    convex = cross > 0
    return float(np.min(speed[convex] ** 3 / cross[convex]))


def design_from_file_values(values: dict, where: str = "design") -> RVDesign:
    """Build a design from file keys; `preset` (optional) supplies the missing ones."""
    values = dict(values)
    values.pop("sources", None)  # inputs of engineering estimates, for the reader and the tests
    values.pop("calibration", None)  # how a calibrated design was made (rvte calibrate)
    base = {}
    preset_name = values.pop("preset", None)
    if preset_name is not None:
        base = _preset_values(preset_name, where)
    unknown = [key for key in values if key not in _BY_KEY and key != "name"]
    if unknown:
        known = ", ".join(["preset", "name"] + [spec.file_key for spec in DESIGN_FIELDS])
        raise InputError(unknown[0], values[unknown[0]], f"is not a design key; known keys: {known}", where)
    merged = {**base, **values}
    name = merged.get("name", preset_name or where)
    if "name" not in values and preset_name is not None and len(values) > 0:
        name = f"{preset_name} (modified)"
    missing = [
        spec.file_key for spec in DESIGN_FIELDS if spec.file_key not in merged and spec.default is None
    ]
    if missing:
        raise InputError(missing[0], None, "is missing (give it, or name a preset to take it from)", where)
    fields = {}
    for spec in DESIGN_FIELDS:
        raw = merged.get(spec.file_key, spec.default)
        if spec.kind in INTEGER_MINIMUM:
            fields[spec.field] = integer(spec.file_key, raw, INTEGER_MINIMUM[spec.kind], where=where)
        else:
            fields[spec.field] = finite_number(spec.file_key, raw, where) * spec.scale
    return RVDesign(name=str(name), **fields)


def preset_file(name: str) -> dict:
    """The whole file of preset `name` (one of PRESET_NAMES), tables included."""
    text = resources.files("rvfmu.core.reducer.presets").joinpath(f"{name}.toml").read_text()
    return tomllib.loads(text)


def _preset_values(name, where):
    if name not in PRESET_NAMES + ESTIMATE_NAMES:
        raise InputError(
            "preset",
            name,
            f"must be one of {', '.join(PRESET_NAMES)} (calibrated "
            f"against the catalogue) or the same with {ESTIMATE_SUFFIX} (before "
            "calibration)",
            where,
        )
    estimate = name.endswith(ESTIMATE_SUFFIX)
    values = preset_file(name.removesuffix(ESTIMATE_SUFFIX))
    values.pop("sources", None)
    calibration = values.pop("calibration", None)
    if not estimate and calibration is not None:
        values.update(calibration["fields"])
    values["name"] = name
    return values


def preset(name: str) -> RVDesign:
    """The shipped preset `name`: one of PRESET_NAMES (calibrated), or ESTIMATE_NAMES."""
    return design_from_file_values({"preset": name}, where=f"preset {name}")


def load_design(spec: str | Path) -> RVDesign:
    """A preset name or the path of a design TOML file."""
    text = str(spec)
    if text in PRESET_NAMES + ESTIMATE_NAMES:
        return preset(text)
    path = Path(spec)
    if not path.is_file():
        raise InputError(
            "design",
            text,
            f"is neither a preset ({', '.join(PRESET_NAMES)}, or "
            f"one of them with {ESTIMATE_SUFFIX}) nor a readable TOML file",
        )
    try:
        values = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError("design", text, f"is not valid TOML ({exc})") from None
    return design_from_file_values(values, where=path.name)

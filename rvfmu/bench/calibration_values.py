"""The values a calibration fits, and their search windows.

Each value is a `Parameter`: its reported name, the design field(s) it sets, its
starting value and bounds.  Any stiffness field of the design may be fitted
(`STIFFNESS_FIELDS`), seed 003's bearing names (`SEED003_NAMES`), the friction
fields (`FRICTION_FIELDS`, fitted to a catalogue's efficiencies and running
torques: `rvfmu.bench.calibration_problem`) and the two values below.  All are
fitted on their logarithms (`rvfmu.bench.calibration_fit`); without bounds from the
user, a value's bounds are a search window around its start (DEFAULT_BOUND_FACTOR,
OUTPUT_STIFFNESS_BOUND_FACTOR, MODIFICATION_SCALE_BOUNDS).

- Besides the stiffnesses, two values that the catalogue figures identify:
  `output_stiffness` [N*m/arcmin], the torsional stiffness of what is in series
  with the output (flange, carrier body, housing; it sets the design's
  output_compliance = 1 / it), which moves the torsional rigidity and barely the
  lost motion; and `modification_scale`, a factor on the disc's modification
  pair (d_rp, d_rrp) that keeps their ratio, which sets the tip and root
  clearance and with it the lost motion.  Both are fitted on their logarithms
  like the stiffnesses.
- Seed 003's names (its equations of the carrier, planets and discs):
  R_ca, the angular contact bearings of the carrier, is `main_bearing_stiffness`;
  R_b, the tapered roller bearings of the crankshafts in the carrier, is the
  pair inside `crank_carrier_bearing_stiffness`; R_pd, the cylindrical roller
  (needle) bearing between a cam and its disc, is the bearing inside
  `crank_disc_bearing_stiffness`.  The presets take each in series with its part
  of the crankshaft bent and sheared between its supports (docs/model.md
  section 6, `rvfmu.core.laws.compliance.crank_split`).  Fitting R_pd therefore sets
  crank_disc_bearing_stiffness = series(R_pd, the crank at a cam), and R_b
  crank_carrier_bearing_stiffness = series(R_b, the crank's common part), with
  the crank's diameter and span from the design's [sources] table (or its
  preset's): the bearings are what seed 003 identifies, the crank is geometry.
  The crank's tilt in its bearings takes the pair at the start of the fit.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.base.checks import InputError, finite_number, positive
from ..core.base.units import ARCMIN, ARCSEC, MM
from ..core.laws import compliance
from ..core.laws.stiffness import cam_positions, series
from ..core.reducer.design import DESIGN_FIELDS, RVDesign

# The stiffness fields of a design: every one may be fitted.
STIFFNESS_FIELDS = tuple(spec for spec in DESIGN_FIELDS if spec.file_key.endswith("_N_per_m"))
_BY_NAME = {**{s.field: s for s in STIFFNESS_FIELDS}, **{s.file_key: s for s in STIFFNESS_FIELDS}}
# The friction fields that may be fitted (to efficiencies and running torques), with their
# units; with the bearings' pitch diameters they leave the contact loads as they are.
FRICTION_UNITS = {
    "pin_disc_friction": "1",
    "pin_groove_friction": "1",
    "mesh_friction": "1",
    "needle_friction": "1",
    "tapered_friction": "1",
    "main_bearing_friction": "1",
    "bearing_drag_factor": "1",
    "lubricant_viscosity": "cSt",
    "seal_torque": "N*m",
}
FRICTION_FIELDS = tuple(spec for spec in DESIGN_FIELDS if spec.field in FRICTION_UNITS)
_FRICTION_BY_NAME = {**{s.field: s for s in FRICTION_FIELDS}, **{s.file_key: s for s in FRICTION_FIELDS}}
LOAD_FREE_FIELDS = tuple(FRICTION_UNITS) + (
    "needle_pitch_diameter",
    "tapered_pitch_diameter",
    "main_bearing_pitch_diameter",
)

# Seed 003's support stiffnesses and the design field each one sets (module docstring).
SEED003_NAMES = {
    "R_ca": "main_bearing_stiffness",
    "R_b": "crank_carrier_bearing_stiffness",
    "R_pd": "crank_disc_bearing_stiffness",
}
SEED003_DOC = {
    "R_ca": "carrier angular contact bearings (seed 003)",
    "R_b": "crank tapered roller bearings in the carrier (seed 003), in series with the crank's common part",
    "R_pd": "crank-disc needle bearing (seed 003), in series with the crank at a cam",
}

# Default bounds: the starting value divided and multiplied by this.  Wide enough for an
# estimate from a formula (the presets' bearing stiffnesses are within x3 of seed 003's
# identified ones), narrow enough for a small global search.
DEFAULT_BOUND_FACTOR = 4.0

# Values that are not a stiffness field (module docstring): name -> (design fields, unit, doc).
OUTPUT_STIFFNESS = "output_stiffness"
MODIFICATION_SCALE = "modification_scale"
OTHER_NAMES = {
    OUTPUT_STIFFNESS: (
        "output_compliance",
        "N*m/arcmin",
        "torsional stiffness in series with the output (sets output_compliance)",
    ),
    MODIFICATION_SCALE: ("d_rp,d_rrp", "x", "factor on the modification pair d_rp, d_rrp (their ratio kept)"),
}
# Without a series compliance in the design, output_stiffness starts at the rated torque per
# arcmin (a catalogue frame's rigidity is about 0.3 of that, the model's without it about 1)
# and is bounded by this factor either way: a wide search, since the start is a guess.
OUTPUT_STIFFNESS_BOUND_FACTOR = 30.0
MODIFICATION_SCALE_BOUNDS = (0.05, 4.0)


@dataclass(frozen=True)
class Parameter:
    """One fitted value.

    name: as reported (R_ca, R_b, R_pd, a design field, output_stiffness or
    modification_scale); field: the design field(s) it sets; value: the starting value
    (of the bearing itself for R_pd and R_b); lower, upper: bounds; series_with: for R_pd
    and R_b, the crankshaft's stiffness [N/m] in series (`crank_parts`); unit: of value and
    bounds; base: for modification_scale, the design's (d_rp, d_rrp) [m] that it scales;
    bounds_given: the bounds are the user's (else the default search window, which a fit
    must not end on: `out_of_reach`).
    """

    name: str
    field: str
    value: float
    lower: float
    upper: float
    series_with: float | None = None
    unit: str = "N/m"
    base: tuple[float, float] | None = None
    bounds_given: bool = False

    def field_values(self, value: float) -> dict:
        """The design fields (SI) that the fitted `value` sets."""
        if self.name == OUTPUT_STIFFNESS:
            return {"output_compliance": ARCMIN / value}
        if self.name == MODIFICATION_SCALE:
            return {"d_rp": self.base[0] * value, "d_rrp": self.base[1] * value}
        return {self.field: value if self.series_with is None else series(value, self.series_with)}


def resolve_name(name: str) -> tuple[str, str]:
    """(reported name, design field) of a --fit name: R_ca, R_b, R_pd, a stiffness field or
    its file key, output_stiffness or modification_scale; an InputError naming what is
    allowed otherwise."""
    text = str(name).strip()
    if text in SEED003_NAMES:
        return text, SEED003_NAMES[text]
    if text in OTHER_NAMES:
        return text, OTHER_NAMES[text][0]
    if text in _BY_NAME:
        return _BY_NAME[text].field, _BY_NAME[text].field
    if text in _FRICTION_BY_NAME:
        return _FRICTION_BY_NAME[text].field, _FRICTION_BY_NAME[text].field
    allowed = ", ".join(
        list(SEED003_NAMES) + [s.field for s in STIFFNESS_FIELDS] + list(OTHER_NAMES) + list(FRICTION_UNITS)
    )
    raise InputError(
        "fit",
        text,
        f"is not a value the calibration fits; fit one or more of {allowed} "
        "(or their file keys, e.g. pin_disc_stiffness_N_per_m)",
    )


def crank_parts(design: RVDesign, sources: dict | None, name: str) -> tuple[float, float]:
    """(at each cam, common to both cams) stiffnesses [N/m] of the crankshaft between its
    bearings (`rvfmu.core.laws.compliance.crank_split`, cams by `stiffness.cam_positions`): the
    springs in series with R_pd and with R_b.  From [sources] crank_diameter_mm and
    crank_span_mm and the design's disc width and Young's modulus; the tilt in the bearings
    takes the tapered roller pair that the design's crank_carrier_bearing_stiffness holds
    (its common part removed).  An InputError if the sources are missing or the stated
    crank-carrier stiffness leaves no bearing behind the crank."""
    needed = ("crank_diameter_mm", "crank_span_mm")
    if not sources or any(k not in sources for k in needed):
        raise InputError(
            "fit",
            name,
            "needs the crankshaft's compliance in series with the "
            "bearing: the design file (or its preset) must have a [sources] "
            "table with crank_diameter_mm and crank_span_mm; or fit "
            f"{SEED003_NAMES[name]} itself",
        )
    diameter = positive("sources.crank_diameter_mm", sources["crank_diameter_mm"]) * MM
    span = positive("sources.crank_span_mm", sources["crank_span_mm"]) * MM
    cams = cam_positions(span, design.disc_width)
    influence = compliance.crank_influence(design.youngs_modulus, design.poisson_ratio, diameter, span, cams)
    pair = compliance.crank_pair(influence, span, cams, design.crank_carrier_bearing_stiffness)
    if pair <= 0.0:
        raise InputError(
            "crank_carrier_bearing_stiffness_N_per_m",
            design.crank_carrier_bearing_stiffness,
            f"must be below the crankshaft's common stiffness {1.0 / influence[0, 1]:.4g} "
            "N/m to hold a tapered roller pair in series with it",
        )
    at_cam, common = compliance.crank_split(influence, span, cams, pair)
    return 1.0 / at_cam, 1.0 / common


def parameters(
    design: RVDesign,
    names,
    bounds: dict | None = None,
    sources: dict | None = None,
    factor: float = DEFAULT_BOUND_FACTOR,
) -> tuple[Parameter, ...]:
    """The values to fit: names (--fit), bounds {name: (lower, upper)} (in each value's unit)
    for some of them (default: start / factor to start x factor; OUTPUT_STIFFNESS_BOUND_FACTOR
    and MODIFICATION_SCALE_BOUNDS for the two that are not stiffnesses), sources: the
    design's [sources] (for R_pd)."""
    names = [n for n in (str(x).strip() for x in names) if n]
    if not names:
        raise InputError("fit", "", "name at least one stiffness to fit, e.g. --fit R_ca,R_b,R_pd")
    resolved = [resolve_name(n) for n in names]
    fields = [f for _, f in resolved]
    for k, f in enumerate(fields):
        if f in fields[:k]:
            raise InputError("fit", names[k], f"sets {f}, which another --fit name sets already")
    given = {}
    for key, pair in (bounds or {}).items():
        name = resolve_name(key)[0]
        if name not in [n for n, _ in resolved]:
            raise InputError(
                "bounds", key, "is not among the fitted names: " + ", ".join(n for n, _ in resolved)
            )
        given[name] = _bound_pair(name, pair)
    out = []
    for name, field in resolved:
        if name in OTHER_NAMES:
            out.append(_other_parameter(design, name, given.get(name)))
            continue
        if name in FRICTION_UNITS:
            current = getattr(design, field)
            if field == "lubricant_viscosity" and current == 0.0:
                # not stated: start from its grade's at 40 C; the fit states it (every temperature)
                from ..core.laws.lubricant import viscosity_cSt

                current = viscosity_cSt(design)
            if not current > 0.0:
                raise InputError(
                    "fit",
                    name,
                    f"is fitted on its logarithm, and the design's "
                    f"{_FRICTION_BY_NAME[name].file_key} is {current:g}: give it a "
                    "starting value > 0",
                )
            lower, upper = given.get(name, (current / factor, current * factor))
            out.append(
                Parameter(
                    name, field, current, lower, upper, unit=FRICTION_UNITS[name], bounds_given=name in given
                )
            )
            continue
        law = {
            "crank_disc_bearing_stiffness": ("crank_disc", "needle_rollers"),
            "crank_carrier_bearing_stiffness": ("crank_carrier", "tapered_rollers"),
        }.get(field)
        if law is not None and law[0] in design.roller_laws:
            raise InputError(
                "fit",
                name,
                f"sets {field}, but that bearing follows the roller law "
                f"({law[1]} = {getattr(design, law[1])}): its stiffness comes from "
                f"its rollers; fit another value, or set {law[1]} = 0 to fit it as "
                "a linear spring",
            )
        current = getattr(design, field)
        crank = None
        if name in ("R_pd", "R_b"):
            crank = crank_parts(design, sources, name)[0 if name == "R_pd" else 1]
            if current >= crank:
                raise InputError(
                    f"{field}_N_per_m",
                    current,
                    f"must be below the crankshaft's "
                    f"stiffness {crank:.4g} N/m in series with it to hold a "
                    f"bearing ({name})",
                )
            current = 1.0 / (1.0 / current - 1.0 / crank)
        lower, upper = given.get(name, (current / factor, current * factor))
        out.append(Parameter(name, field, current, lower, upper, crank, bounds_given=name in given))
    return tuple(out)


def _other_parameter(design: RVDesign, name: str, bounds) -> Parameter:
    """output_stiffness or modification_scale of `design` (module docstring)."""
    field, unit, _ = OTHER_NAMES[name]
    if name == OUTPUT_STIFFNESS:
        if design.output_compliance > 0.0:
            start, factor = ARCMIN / design.output_compliance, DEFAULT_BOUND_FACTOR
        else:
            start, factor = design.rated_torque, OUTPUT_STIFFNESS_BOUND_FACTOR
        lower, upper = bounds or (start / factor, start * factor)
        return Parameter(name, field, start, lower, upper, unit=unit, bounds_given=bounds is not None)
    base = (design.d_rp, design.d_rrp)
    if design.tip_root_clearance <= 0.0:
        raise InputError(
            "fit",
            name,
            f"scales the modification pair, which leaves no tip and root "
            f"clearance here (d_rrp - d_rp = {design.tip_root_clearance / MM:.4g} mm): "
            "give the design a clearance to scale first",
        )
    lower, upper = bounds or MODIFICATION_SCALE_BOUNDS
    return Parameter(name, field, 1.0, lower, upper, unit=unit, base=base, bounds_given=bounds is not None)


def _bound_pair(name, pair):
    field = f"bounds.{name}"
    unit = OTHER_NAMES[name][1] if name in OTHER_NAMES else FRICTION_UNITS.get(name, "N/m")
    try:
        lower, upper = pair
    except (TypeError, ValueError):
        raise InputError(field, pair, f"give two numbers LOWER:UPPER in {unit}") from None
    lower, upper = finite_number(field, lower), finite_number(field, upper)
    for value in (lower, upper):
        if value <= 0.0:
            raise InputError(field, value, f"must be > 0 {unit}: fitted on its logarithm")
    if upper <= lower:
        raise InputError(field, [lower, upper], "the upper bound must be above the lower one")
    return lower, upper


# -- what a fitted value is and sets, for reports -------------------------------------------


def setting(parameter: Parameter, value: float) -> str:
    """What the fitted `value` sets in the design, in file units, for reports."""
    p = parameter
    if p.series_with is not None:
        return (
            f"{p.field} = series({p.name}, crankshaft {p.series_with:.4g} N/m) = "
            f"{p.field_values(value)[p.field]:.6g}"
        )
    if p.name == OUTPUT_STIFFNESS:
        return f"output_compliance_arcsec_per_Nm = {p.field_values(value)['output_compliance'] / ARCSEC:.6g}"
    if p.name == MODIFICATION_SCALE:
        pair = p.field_values(value)
        return f"d_rp_mm = {pair['d_rp'] / MM:.6g}, d_rrp_mm = {pair['d_rrp'] / MM:.6g}"
    return p.field


def describe(parameter: Parameter) -> str:
    """What a fitted name is, for reports."""
    if parameter.name in SEED003_DOC:
        return f"{SEED003_DOC[parameter.name]} -> {parameter.field}"
    if parameter.name in OTHER_NAMES:
        return f"{OTHER_NAMES[parameter.name][2]} -> {parameter.field}"
    return parameter.field


__all__ = [
    "SEED003_NAMES",
    "STIFFNESS_FIELDS",
    "FRICTION_FIELDS",
    "OUTPUT_STIFFNESS",
    "MODIFICATION_SCALE",
    "Parameter",
    "resolve_name",
    "crank_parts",
    "parameters",
    "setting",
    "describe",
]

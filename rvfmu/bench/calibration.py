"""Calibrating a design's stiffnesses against measurements.

The question: which values of a few stiffnesses make the model of this design
reproduce what was measured: the TE peak of each data set (seed 003), whole TE
curves of bench records, or the catalogue's torsional rigidity and lost motion?
How it is answered, and why so:

- Least squares between measured and modelled quantities, seed 003's objective
  1/2 sum (u*_i - u_i)^2, over the logarithms of the fitted values: stiffnesses
  act by ratio and span decades, and a log scale keeps them positive.
  Residuals: peaks and curves in arcsec; catalogue figures relative to the
  catalogue's value, so that rigidity and lost motion weigh alike.
- Global, then local: scipy.optimize.differential_evolution within the bounds
  (the misfit of a contact model need not be convex: pins come in and out of
  contact), from a seeded population so that the same data give the same answer
  next month, then scipy.optimize.least_squares from its best member.  No
  hand-written genetic algorithm (seed 003 uses one).
- Uncertainty: the Jacobian J of the residuals with respect to ln(value) at the
  optimum (central differences), covariance (J^T J)^-1 s^2 with the residual
  variance s^2 = sum r^2 / (n - p); the 1-sigma of a value is value x the sigma of
  its logarithm (linearised).  A direction in which the residuals do not change
  (a singular value of J below SINGULAR_RELATIVE x the largest, or below what the
  solver resolves) is not identifiable from these data: a value that moves along
  it gets sigma = inf; a value whose sigma exceeds itself is reported as not
  determined by the data.
  With as many residuals as values (n = p) there is no variance left: sigma = nan.
- Friction (docs/model.md section 9): a catalogue file may also hold efficiency points
  (output speed, resisting torque, efficiency) and no-load running torques at the
  input (output speed, torque), each with its conditions; the friction fields
  (`FRICTION_FIELDS`: the contacts' coefficients, the bearings' drag factor, the
  lubricant's viscosity, the seal's torque) are fitted to them on their logarithms
  like the stiffnesses.  An efficiency's residual is that of its loss share 1 - eta,
  relative, which is what the coefficients set (an efficiency near 1 would hide it).
  The contact loads do not depend on friction (the first-order power balance), so a
  data set's loads are solved once per stiffness state and every friction value
  costs only the losses.
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
  section 6, `rvfmu.core.compliance.crank_split`).  Fitting R_pd therefore sets
  crank_disc_bearing_stiffness = series(R_pd, the crank at a cam), and R_b
  crank_carrier_bearing_stiffness = series(R_b, the crank's common part), with
  the crank's diameter and span from the design's [sources] table (or its
  preset's): the bearings are what seed 003 identifies, the crank is geometry.
  The crank's tilt in its bearings takes the pair at the start of the fit.
- Figures out of reach.  A fit that ends on a default bound is no calibration
  (`out_of_reach`): the default
  bounds (start / and x DEFAULT_BOUND_FACTOR, OUTPUT_STIFFNESS_BOUND_FACTOR,
  MODIFICATION_SCALE_BOUNDS) are a search window around an estimate, not a property of
  the reducer, so a value pressed against one (the misfit still falls beyond it) means a
  figure the design cannot reach: a catalogue rigidity of 1e9 N*m/arcmin or a lost motion
  of 1e-9 arcmin ended at the bounds and was written as a calibrated design.  Its error
  names the figure that presses hardest, its value, the value at its bound and the model's
  figure there (the nearest the window reaches); `rvfmu.api.calibrate` raises it instead of
  writing the design, and a report without a file to write carries it as a warning (a
  study may fit only to read the start values, as studies/seed003_calibration does).
  Bounds the user gives (--bounds) are a statement about the reducer: a value may end on
  them, reported "at bound" (seed 003's own bounds, studies/seed003_calibration, end so).
  A figure far beyond the window may also leave the misfit flat (a rigidity of 1e9 moves
  the relative residual by 1e-7 over the whole window, a TE peak of 1000 arcsec at no
  error hardly moves with the pins' stiffness) and the fit anywhere inside it: so every
  figure (a catalogue figure, a peak, a curve's te_pp) is first held against what the
  design gives at the corners of the default bounds (`beyond_reach`, before the fit):
  each figure rises or falls with each value, the rigidity with every stiffness, the lost
  motion with the clearance, a peak with the compliances, so its extremes over the bounds
  are at corners; REACH_MARGIN covers the values' interplay.  Not with bounds given: seed
  003's peaks on the coarse grid of a quick run lie 10 % above what its bounds reach.
- Speeds of catalogue friction points are checked against the design's allowable output
  speed as every speed is (`rvfmu.core.limits.check_speed`): refused beyond SPEED_FACTOR x
  it, a warning of the problem above it.
- Cheap evaluations: a data set's model costs its grid, `points` per output
  revolution, not its rows (`rvfmu.bench.compare`); data sets at the same load are
  solved as one batch.  The default for peaks and curves, POINTS_PER_CRANK_TURN
  = 32 points per crank revolution (32 z_p: 1280 on the 40-pin presets, 1/10 of
  the 8 z_p z_c = 12 480 that resolve the pin-passing ripple), resolves the
  errors' low orders and the crank order and their harmonics; the pin-passing
  ripple (order z_p z_c) is sampled, not resolved.  te_pp at 1280 against 12 480
  points, seed 002's errors (x1 to x3.3) at rated torque: RV-20E 1.0 % and 0.4 %
  low, RV-40E-121 0.15 % high and 0.5 % low; at no load, where interference
  makes the peaks sharper, up to 4 % low.  At 640 points (16 z_p) the same
  peaks are 2 to 6 % low, for half the cost.  A fit compares the model with
  itself at one resolution, so the part of such a bias that does not change
  with the fitted values cancels.

Arrays and plain records in, a record out: the files are read and written by
`rvfmu.api.calibrate`, except the small TOML inputs parsed here.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .compare import as_bench_sees, model_grid, periodic
from ..core.checks import InputError, finite_number, integer, non_negative, positive
from ..core.limits import check_speed
from ..core.design import DESIGN_FIELDS, ESTIMATE_SUFFIX, PRESET_NAMES, RVDesign, preset_file
from ..core.errors import ErrorSet, load_errors, stack, toml_text, zero_errors
from ..core.quasistatic import windup
from ..core import compliance
from ..core.stiffness import cam_positions, series
from ..core.units import ARCMIN, ARCSEC, MM, RPM
from .measured import MeasuredTE

TARGETS = ("peaks", "curve", "catalogue")

# The stiffness fields of a design: every one may be fitted.
STIFFNESS_FIELDS = tuple(spec for spec in DESIGN_FIELDS if spec.file_key.endswith("_N_per_m"))
_BY_NAME = {**{s.field: s for s in STIFFNESS_FIELDS}, **{s.file_key: s for s in STIFFNESS_FIELDS}}
# The friction fields that may be fitted (to efficiencies and running torques), with their
# units; with the bearings' pitch diameters they leave the contact loads as they are.
FRICTION_UNITS = {"pin_disc_friction": "1", "pin_groove_friction": "1", "mesh_friction": "1",
                  "needle_friction": "1", "tapered_friction": "1", "main_bearing_friction": "1",
                  "bearing_drag_factor": "1", "lubricant_viscosity": "cSt", "seal_torque": "N*m"}
FRICTION_FIELDS = tuple(spec for spec in DESIGN_FIELDS if spec.field in FRICTION_UNITS)
_FRICTION_BY_NAME = {**{s.field: s for s in FRICTION_FIELDS},
                     **{s.file_key: s for s in FRICTION_FIELDS}}
LOAD_FREE_FIELDS = tuple(FRICTION_UNITS) + ("needle_pitch_diameter", "tapered_pitch_diameter",
                                            "main_bearing_pitch_diameter")

# Seed 003's support stiffnesses and the design field each one sets (module docstring).
SEED003_NAMES = {"R_ca": "main_bearing_stiffness", "R_b": "crank_carrier_bearing_stiffness",
                 "R_pd": "crank_disc_bearing_stiffness"}
SEED003_DOC = {"R_ca": "carrier angular contact bearings (seed 003)",
               "R_b": "crank tapered roller bearings in the carrier (seed 003), in series with "
                      "the crank's common part",
               "R_pd": "crank-disc needle bearing (seed 003), in series with the crank at a cam"}

# Default bounds: the starting value divided and multiplied by this.  Wide enough for an
# estimate from a formula (the presets' bearing stiffnesses are within x3 of seed 003's
# identified ones), narrow enough for a small global search.
DEFAULT_BOUND_FACTOR = 4.0

POINTS_PER_CRANK_TURN = 32          # default grid: 32 z_p points per output revolution

# differential_evolution budget: popsize x (number of values) members, maxiter generations.
# Seeded (seed 003's number): the same data give the same fit.
DE_POPSIZE = 10
DE_MAXITER = 30
DE_TOL = 1e-3
DE_SEED = 3
LS_MAX_EVALUATIONS = 200

# Step of ln(value) for the Jacobians: 0.1 % of a stiffness moves a TE by ~1e-4 of itself,
# far above the solver's convergence (~1e-8 arcsec) and small enough to stay linear.
JACOBIAN_STEP = 1e-3
# A singular value of J below this share of the largest, or below SENSITIVITY_FLOOR: that
# direction is not identifiable.  The floor: a residual change under 1e-6 (arcsec, or
# relative) for a factor e in the values is below what the solver resolves (its
# regularisation moves a TE by ~1e-6 of itself, rvfmu/core/metrics.py).
SINGULAR_RELATIVE = 1e-6
SENSITIVITY_FLOOR = 1e-6
# A misfit that is not a number (a pose that did not solve) counts as this, in arcsec.
FAILED_RESIDUAL = 1e6
# A figure more than this share beyond the range the design gives at the corners
# of the fitted values' bounds is out of reach (`beyond_reach`); the share covers the
# values' interplay, which may put a figure's extreme a little inside the bounds.
REACH_MARGIN = 0.1
# Corners evaluated for it at most: 2^p models of p values (8: 256, against the 10 p x 31
# of the fit's differential evolution, 2480).
REACH_MAX_VALUES = 8


# Values that are not a stiffness field (module docstring): name -> (design fields, unit, doc).
OUTPUT_STIFFNESS = "output_stiffness"
MODIFICATION_SCALE = "modification_scale"
OTHER_NAMES = {
    OUTPUT_STIFFNESS: ("output_compliance", "N*m/arcmin",
                       "torsional stiffness in series with the output (sets output_compliance)"),
    MODIFICATION_SCALE: ("d_rp,d_rrp", "x",
                         "factor on the modification pair d_rp, d_rrp (their ratio kept)"),
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


@dataclass(frozen=True)
class Catalogue:
    """Catalogue figures of a reducer; rated_torque_Nm: the torque the stiffness figures refer
    to (lost motion at +-3 % of it, rigidity between 50 and 100 %), None: the design's;
    efficiency: ((output speed [rpm], resisting torque [N*m], efficiency), ...), forward;
    running_torque: ((output speed [rpm], no-load running torque at the input [N*m]), ...)."""

    torsional_rigidity_Nm_per_arcmin: float | None = None
    lost_motion_arcmin: float | None = None
    rated_torque_Nm: float | None = None
    efficiency: tuple = ()
    running_torque: tuple = ()

    def figures(self) -> dict:
        """The stiffness figures given: {name: value}."""
        return {k: v for k, v in (("torsional_rigidity_Nm_per_arcmin",
                                   self.torsional_rigidity_Nm_per_arcmin),
                                  ("lost_motion_arcmin", self.lost_motion_arcmin)) if v is not None}

    def labels(self) -> list[str]:
        """A name for each of `values`."""
        return (list(self.figures())
                + [f"1 - efficiency, {v:g} rpm {t:g} N*m" for v, t, _ in self.efficiency]
                + [f"running torque N*m, {v:g} rpm" for v, _ in self.running_torque])

    def values(self) -> np.ndarray:
        """Every figure as calibration compares it: the stiffness figures, the loss share
        1 - efficiency of each efficiency point, the running torques."""
        return np.array(list(self.figures().values()) + [1.0 - e for _, _, e in self.efficiency]
                        + [t for _, t in self.running_torque], dtype=float)


@dataclass(frozen=True)
class DataSet:
    """What was measured on one reducer under one condition.

    load_Nm: resisting output torque; errors: that reducer's errors (one sample), None for
    none.  One of: te_pp_arcsec (a TE peak-to-peak, as seed 003 gives them), measured (a
    bench record: its curve, or its te_pp without the runout), catalogue (figures).
    """

    name: str
    load_Nm: float = 0.0
    errors: ErrorSet | None = None
    te_pp_arcsec: float | None = None
    measured: MeasuredTE | None = None
    catalogue: Catalogue | None = None

    def target_value(self, target: str) -> np.ndarray:
        """The measured quantity this data set brings to `target`, as an array."""
        if target == "catalogue":
            return self.catalogue.values()
        if target == "curve":
            return self.measured.te_reducer_arcsec
        if self.te_pp_arcsec is not None:
            return np.array([self.te_pp_arcsec])
        return np.array([float(self.measured.te_pp_arcsec[1])])


@dataclass(frozen=True)
class Problem:
    """A calibration problem as plain data: the design, the values to fit, the data sets,
    the target (peaks, curve or catalogue) and the model's points per output revolution;
    warnings: texts for the report (catalogue speeds above the allowable output speed)."""

    design: RVDesign
    parameters: tuple[Parameter, ...]
    datasets: tuple[DataSet, ...]
    target: str
    points: int
    warnings: tuple[str, ...] = ()

    @property
    def start(self) -> np.ndarray:
        return np.array([p.value for p in self.parameters])

    @property
    def log_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of x = ln(value / start)."""
        return (np.log([p.lower / p.value for p in self.parameters]),
                np.log([p.upper / p.value for p in self.parameters]))

    def fields_at(self, values) -> dict:
        """The design fields (SI) that the fitted `values` (p,), each in its unit, set."""
        fields = {}
        for p, v in zip(self.parameters, values):
            fields.update(p.field_values(float(v)))
        return fields

    def design_at(self, values) -> RVDesign:
        """The design with the fitted fields set from `values` (p,), each in its unit."""
        return self.design.with_fields(**self.fields_at(values))

    def measured(self) -> list[np.ndarray]:
        return [d.target_value(self.target) for d in self.datasets]


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
    allowed = ", ".join(list(SEED003_NAMES) + [s.field for s in STIFFNESS_FIELDS] + list(OTHER_NAMES)
                        + list(FRICTION_UNITS))
    raise InputError("fit", text, f"is not a value the calibration fits; fit one or more of {allowed} "
                     "(or their file keys, e.g. pin_disc_stiffness_N_per_m)")


def crank_parts(design: RVDesign, sources: dict | None, name: str) -> tuple[float, float]:
    """(at each cam, common to both cams) stiffnesses [N/m] of the crankshaft between its
    bearings (`rvfmu.core.compliance.crank_split`, cams by `stiffness.cam_positions`): the
    springs in series with R_pd and with R_b.  From [sources] crank_diameter_mm and
    crank_span_mm and the design's disc width and Young's modulus; the tilt in the bearings
    takes the tapered roller pair that the design's crank_carrier_bearing_stiffness holds
    (its common part removed).  An InputError if the sources are missing or the stated
    crank-carrier stiffness leaves no bearing behind the crank."""
    needed = ("crank_diameter_mm", "crank_span_mm")
    if not sources or any(k not in sources for k in needed):
        raise InputError("fit", name, "needs the crankshaft's compliance in series with the "
                         "bearing: the design file (or its preset) must have a [sources] "
                         "table with crank_diameter_mm and crank_span_mm; or fit "
                         f"{SEED003_NAMES[name]} itself")
    diameter = positive("sources.crank_diameter_mm", sources["crank_diameter_mm"]) * MM
    span = positive("sources.crank_span_mm", sources["crank_span_mm"]) * MM
    cams = cam_positions(span, design.disc_width)
    influence = compliance.crank_influence(design.youngs_modulus, design.poisson_ratio,
                                           diameter, span, cams)
    pair = compliance.crank_pair(influence, span, cams, design.crank_carrier_bearing_stiffness)
    if pair <= 0.0:
        raise InputError("crank_carrier_bearing_stiffness_N_per_m", design.crank_carrier_bearing_stiffness,
                         f"must be below the crankshaft's common stiffness {1.0 / influence[0, 1]:.4g} "
                         "N/m to hold a tapered roller pair in series with it")
    at_cam, common = compliance.crank_split(influence, span, cams, pair)
    return 1.0 / at_cam, 1.0 / common


def parameters(design: RVDesign, names, bounds: dict | None = None, sources: dict | None = None,
               factor: float = DEFAULT_BOUND_FACTOR) -> tuple[Parameter, ...]:
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
            raise InputError("bounds", key, "is not among the fitted names: "
                             + ", ".join(n for n, _ in resolved))
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
                from ..core.lubricant import viscosity_cSt
                current = viscosity_cSt(design)
            if not current > 0.0:
                raise InputError("fit", name, f"is fitted on its logarithm, and the design's "
                                 f"{_FRICTION_BY_NAME[name].file_key} is {current:g}: give it a "
                                 "starting value > 0")
            lower, upper = given.get(name, (current / factor, current * factor))
            out.append(Parameter(name, field, current, lower, upper, unit=FRICTION_UNITS[name],
                                 bounds_given=name in given))
            continue
        law = {"crank_disc_bearing_stiffness": ("crank_disc", "needle_rollers"),
               "crank_carrier_bearing_stiffness": ("crank_carrier", "tapered_rollers")}.get(field)
        if law is not None and law[0] in design.roller_laws:
            raise InputError("fit", name, f"sets {field}, but that bearing follows the roller law "
                             f"({law[1]} = {getattr(design, law[1])}): its stiffness comes from "
                             f"its rollers; fit another value, or set {law[1]} = 0 to fit it as "
                             "a linear spring")
        current = getattr(design, field)
        crank = None
        if name in ("R_pd", "R_b"):
            crank = crank_parts(design, sources, name)[0 if name == "R_pd" else 1]
            if current >= crank:
                raise InputError(f"{field}_N_per_m", current, f"must be below the crankshaft's "
                                 f"stiffness {crank:.4g} N/m in series with it to hold a "
                                 f"bearing ({name})")
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
        return Parameter(name, field, start, lower, upper, unit=unit,
                         bounds_given=bounds is not None)
    base = (design.d_rp, design.d_rrp)
    if design.tip_root_clearance <= 0.0:
        raise InputError("fit", name, f"scales the modification pair, which leaves no tip and root "
                         f"clearance here (d_rrp - d_rp = {design.tip_root_clearance / MM:.4g} mm): "
                         "give the design a clearance to scale first")
    lower, upper = bounds or MODIFICATION_SCALE_BOUNDS
    return Parameter(name, field, 1.0, lower, upper, unit=unit, base=base,
                     bounds_given=bounds is not None)


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


# -- the data files ------------------------------------------------------------------------

CATALOGUE_KEYS = ("torsional_rigidity_Nm_per_arcmin", "lost_motion_arcmin", "rated_torque_Nm")
# Friction figures of a catalogue file: arrays of tables, each with its conditions.
FRICTION_CATALOGUE_KEYS = {
    "efficiency": ("output_speed_rpm", "load_Nm", "efficiency", "lubricant_temperature_C", "note"),
    "running_torque": ("output_speed_rpm", "input_torque_Nm", "lubricant_temperature_C", "note"),
}
CATALOGUE_NOTES = ("source", "note")
DATASETS_KEYS = ("load_Nm", "errors", "error_scale", "source", "dataset")
DATASET_KEYS = ("name", "te_pp_arcsec", "data", "load_Nm", "errors", "error_scale", "note")


def read_toml(field: str, path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise InputError(field, str(path), "must be an existing file")
    try:
        return tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(field, str(path), f"is not valid TOML ({exc})") from None


def is_catalogue(values: dict) -> bool:
    return any(k in values for k in CATALOGUE_KEYS + tuple(FRICTION_CATALOGUE_KEYS)) and \
        "dataset" not in values


def catalogue_dataset(path, values: dict, load: float = 0.0, errors=None) -> DataSet:
    """A catalogue TOML as a data set: torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin,
    optional rated_torque_Nm; [[efficiency]] tables (output_speed_rpm, load_Nm: the resisting
    torque, efficiency: forward, 0 < eta < 1) and [[running_torque]] tables (output_speed_rpm,
    input_torque_Nm: the no-load running torque at the input), each optionally with
    lubricant_temperature_C and a note; source and note: free text."""
    where = Path(path).name
    known = CATALOGUE_KEYS + tuple(FRICTION_CATALOGUE_KEYS) + CATALOGUE_NOTES
    unknown = [k for k in values if k not in known]
    if unknown:
        raise InputError(unknown[0], values[unknown[0]], "is not a catalogue key; known: "
                         + ", ".join(known), where)
    figures = {k: positive(k, values[k], where) for k in CATALOGUE_KEYS if k in values}
    points = {}
    for key, allowed in FRICTION_CATALOGUE_KEYS.items():
        entries = values.get(key, [])
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise InputError(key, entries, f"must be [[{key}]] tables", where)
        rows = []
        for k, entry in enumerate(entries):
            at = f"{where} {key} {k + 1}"
            unknown = [x for x in entry if x not in allowed]
            if unknown:
                raise InputError(unknown[0], entry[unknown[0]], f"is not a [[{key}]] key; known: "
                                 + ", ".join(allowed), at)
            needed = allowed[:3] if key == "efficiency" else allowed[:2]
            missing = [x for x in needed if x not in entry]
            if missing:
                raise InputError(missing[0], None, f"every [[{key}]] needs " + ", ".join(needed), at)
            numbers = [positive(x, entry[x], at) for x in needed]
            if key == "efficiency" and not numbers[2] < 1.0:
                raise InputError("efficiency", numbers[2], "must be below 1 (a fraction: 0.85, "
                                 "not 85 %)", at)
            rows.append(tuple(numbers))
        points[key] = tuple(rows)
    if not set(figures) - {"rated_torque_Nm"} and not any(points.values()):
        raise InputError("data", str(path), "a catalogue file needs torsional_rigidity_Nm_per_arcmin, "
                         "lost_motion_arcmin, [[efficiency]] or [[running_torque]]")
    return DataSet(where, load, errors, catalogue=Catalogue(**figures, **points))


def peaks_datasets(path, values: dict, design: RVDesign, load: float = 0.0,
                   errors: str | Path | ErrorSet | None = None, read_record=None) -> list[DataSet]:
    """The [[dataset]] tables of a data-set TOML, each with te_pp_arcsec (a measured TE
    peak-to-peak) or data (a bench CSV, read by read_record(path) -> MeasuredTE), and
    load_Nm, errors (an error file, relative to this file) and error_scale (x the errors),
    each defaulting to the file's top-level value, then to `load` and `errors`."""
    path = Path(path)
    where = path.name
    unknown = [k for k in values if k not in DATASETS_KEYS]
    if unknown:
        raise InputError(unknown[0], values[unknown[0]], "is not a data-set file key; known: "
                         + ", ".join(DATASETS_KEYS), where)
    entries = values.get("dataset")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise InputError("data", str(path), "is neither a catalogue TOML (it has none of "
                         "torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin, [[efficiency]], "
                         "[[running_torque]]) nor a data-set TOML (one or more [[dataset]] "
                         "tables)", where)
    top = {"load_Nm": load, "errors": errors, "error_scale": 1.0}
    for key in ("load_Nm", "error_scale"):
        if key in values:
            top[key] = finite_number(key, values[key], where)
    if "errors" in values:
        top["errors"] = path.parent / str(values["errors"])
    cache = {}
    out = []
    for k, entry in enumerate(entries):
        at = f"{where} dataset {k + 1}"
        unknown = [key for key in entry if key not in DATASET_KEYS]
        if unknown:
            raise InputError(unknown[0], entry[unknown[0]], "is not a [[dataset]] key; known: "
                             + ", ".join(DATASET_KEYS), at)
        name = str(entry.get("name", k + 1))
        load_k = non_negative("load_Nm", entry.get("load_Nm", top["load_Nm"]), at)
        scale = non_negative("error_scale", entry.get("error_scale", top["error_scale"]), at)
        source = path.parent / str(entry["errors"]) if "errors" in entry else top["errors"]
        err = None
        if isinstance(source, ErrorSet):
            err = source.check(design).scaled(scale)
        elif source is not None:
            if str(source) not in cache:
                cache[str(source)] = load_errors(source, design)
            err = cache[str(source)].scaled(scale)
        if ("te_pp_arcsec" in entry) == ("data" in entry):
            raise InputError("te_pp_arcsec", None, "give either te_pp_arcsec (a measured peak) or "
                             "data (a bench CSV), not both or neither", at)
        if "data" in entry:
            if read_record is None:
                raise InputError("data", entry["data"], "bench records are read by rvfmu.api", at)
            record = read_record(path.parent / str(entry["data"]))
            out.append(DataSet(name, load_k, err, measured=record))
        else:
            out.append(DataSet(name, load_k, err,
                               te_pp_arcsec=positive("te_pp_arcsec", entry["te_pp_arcsec"], at)))
    return out


def design_sources(spec) -> dict | None:
    """The [sources] table of a design: a preset name's, a design file's own, or (a file
    that names a preset and has none) its preset's; None when there is none."""
    text = str(spec).removesuffix(ESTIMATE_SUFFIX)
    if text in PRESET_NAMES:
        return preset_file(text).get("sources")
    path = Path(spec)
    if not path.is_file():
        return None
    try:
        values = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return None
    if isinstance(values.get("sources"), dict):
        return values["sources"]
    name = str(values.get("preset", "")).removesuffix(ESTIMATE_SUFFIX)
    return preset_file(name).get("sources") if name in PRESET_NAMES else None


def check_target(datasets, target: str | None) -> str:
    """The target: as given (checked against what the data sets bring), or the one they all
    bring (catalogue figures, peaks, bench curves) when None."""
    kinds = {"catalogue" if d.catalogue else "peaks" if d.te_pp_arcsec is not None else "curve"
             for d in datasets}
    if target is None:
        if len(kinds) > 1:
            raise InputError("target", None, f"the data bring {' and '.join(sorted(kinds))}: "
                             "choose one with --target peaks, curve or catalogue")
        return kinds.pop()
    if target not in TARGETS:
        raise InputError("target", target, "must be one of " + ", ".join(TARGETS))
    for d in datasets:
        ok = (d.catalogue is not None if target == "catalogue" else
              d.measured is not None if target == "curve" else
              d.catalogue is None)
        if not ok:
            what = ("catalogue figures (a TOML with torsional_rigidity_Nm_per_arcmin, "
                    "lost_motion_arcmin, [[efficiency]], [[running_torque]])"
                    if target == "catalogue" else
                    "a bench record (CSV)" if target == "curve" else
                    "a TE peak (te_pp_arcsec) or a bench record")
            raise InputError("target", target, f"needs {what} in every data set; {d.name} has none")
    return target


def default_points(design: RVDesign) -> int:
    """Model points per output revolution of a calibration: POINTS_PER_CRANK_TURN per crank
    revolution (module docstring)."""
    return POINTS_PER_CRANK_TURN * design.z_p


def problem(design: RVDesign, datasets, fit, target: str | None = None, bounds=None,
            sources=None, points: int | None = None) -> Problem:
    """A checked calibration problem (see `Problem`)."""
    datasets = tuple(datasets)
    if not datasets:
        raise InputError("data", [], "give one or more data files")
    target = check_target(datasets, target)
    points = default_points(design) if points is None else integer("points", points, 8)
    return Problem(design, parameters(design, fit, bounds, sources), datasets, target, points,
                   _speed_warnings(design, datasets))


def _speed_warnings(design: RVDesign, datasets) -> tuple[str, ...]:
    """The warnings of the catalogue friction points' output speeds [rpm]; an InputError
    naming the file and table for one beyond SPEED_FACTOR x the allowable output speed."""
    notes = []
    for d in datasets:
        c = d.catalogue
        if c is None:
            continue
        for key, rows in (("efficiency", c.efficiency), ("running_torque", c.running_torque)):
            for k, row in enumerate(rows):
                note = check_speed("output_speed_rpm", row[0], row[0] * RPM, design,
                                   f"{d.name} {key} {k + 1}")
                if note:
                    notes.append(f"{d.name} {key} {k + 1}: {note}")
    return tuple(notes)


# -- the model and the residuals -------------------------------------------------------------

def evaluate(problem: Problem, design: RVDesign) -> tuple[list[np.ndarray], bool]:
    """(the model's quantity of each data set for `design`, as `DataSet.target_value` gives
    the measured one; every pose converged).  Data sets at one load (and sense) are one batch."""
    out = [None] * len(problem.datasets)
    converged = True
    if problem.target == "catalogue":
        for k, d in enumerate(problem.datasets):
            c = d.catalogue
            parts = []
            if c.figures():
                model = design if c.rated_torque_Nm is None else design.with_fields(
                    rated_torque=c.rated_torque_Nm)
                w = windup(model, _errors(design, d))
                figures = {"torsional_rigidity_Nm_per_arcmin": w.torsional_rigidity_Nm_per_arcmin()[0],
                           "lost_motion_arcmin": w.lost_motion_arcmin()[0]}
                parts.append(np.array([figures[key] for key in c.figures()]))
                converged &= bool(w.converged[0])
            if c.efficiency or c.running_torque:
                values, ok = _friction_figures(design, d)
                parts.append(values)
                converged &= ok
            out[k] = np.concatenate(parts)
        return out, converged
    groups = {}
    for k, d in enumerate(problem.datasets):
        sense = d.measured.sense if d.measured is not None else 1
        batch = periodic(design) or d.measured is None
        groups.setdefault((d.load_Nm, sense, k if not batch else -1), []).append(k)
    for (load, sense, _), members in groups.items():
        sets = [problem.datasets[k] for k in members]
        span = None
        if sets[0].measured is not None:
            span = (float(sets[0].measured.theta_in.min()), float(sets[0].measured.theta_in.max()))
        grid = model_grid(design, stack([_errors(design, d) for d in sets]), load, problem.points,
                          sense, span)
        converged &= bool(np.all(grid.converged))
        for row, (k, d) in enumerate(zip(members, sets)):
            if d.measured is None:
                out[k] = np.array([np.ptp(grid.te_arcsec[row])])
                continue
            curve = as_bench_sees(d.measured, grid.at(d.measured.theta_in)[row])[0]
            out[k] = curve if problem.target == "curve" else np.array([np.ptp(curve)])
    return out, converged


def _errors(design, dataset):
    return zero_errors(design) if dataset.errors is None else dataset.errors


_LOADS: dict = {}


def _friction_figures(design: RVDesign, dataset: DataSet) -> tuple[np.ndarray, bool]:
    """(the model's 1 - efficiency at each efficiency point and running torque at each
    speed of the data set's catalogue, every equilibrium converged), from the power
    balance (`friction.efficiency_from_loads`) on the data set's contact loads, solved
    once for each state of the fields that set them (module docstring)."""
    from ..core.friction import contact_loads, crank_turn_angles, efficiency_from_loads

    c = dataset.catalogue
    speeds = sorted({row[0] for row in c.efficiency + c.running_torque})
    loads = sorted({row[1] for row in c.efficiency})
    key = (id(dataset), design.with_fields(**{f: 0.0 for f in LOAD_FREE_FIELDS}), tuple(loads))
    hit = _LOADS.get(key)
    if hit is None or hit[0] is not dataset:
        if len(_LOADS) > 32:
            _LOADS.clear()
        forward = contact_loads(design, _errors(design, dataset),
                                np.concatenate([[0.0], -np.asarray(loads, dtype=float)]),
                                crank_turn_angles(design))
        hit = _LOADS[key] = (dataset, forward)
    emap = efficiency_from_loads(design, hit[1], speeds, loads)
    efficiency = [emap.efficiency[speeds.index(v), loads.index(t)] for v, t, _ in c.efficiency]
    running = [emap.no_load_running_torque_Nm[speeds.index(v)] for v, _ in c.running_torque]
    return np.array([1.0 - e for e in efficiency] + running), emap.converged


def residuals_of(problem: Problem, model: list[np.ndarray]) -> np.ndarray:
    """(n,) model - measured, every data set's in turn: arcsec for peaks and curves, relative
    to the catalogue's figure for catalogue figures."""
    parts = []
    for measured, modelled in zip(problem.measured(), model):
        r = modelled - measured
        parts.append(r / measured if problem.target == "catalogue" else r)
    r = np.concatenate(parts)
    return np.where(np.isfinite(r), r, FAILED_RESIDUAL)


def values_at(problem: Problem, x) -> np.ndarray:
    """(p,) values (each in its unit) at x = ln(value / start)."""
    return problem.start * np.exp(np.asarray(x, dtype=float))


def residuals(problem: Problem, x) -> np.ndarray:
    """(n,) residuals at x = ln(value / start), (p,)."""
    return residuals_of(problem, evaluate(problem, problem.design_at(values_at(problem, x)))[0])


# -- the fit ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Calibration:
    """The fitted values with their uncertainty and the misfit before and after.

    values, sigma: (p,) [N/m] (sigma inf: not identifiable from these data, nan: no
    residual variance left); at_bound: (p,) bool; before, after: the model's quantity of
    each data set at the start and at the fit (as `evaluate`); jacobian: (n, p)
    d residual / d ln(value) at the fit; dof: n - p; evaluations: model evaluations;
    design: the calibrated design; messages: the optimisers' ends; reach_error: the
    InputError of a figure out of the bounds' reach (`beyond_reach`) or of a fit pressed
    against a default bound (`out_of_reach`), None if neither: such a fit is no
    calibration, and `rvfmu.api.calibrate` writes nothing for it.
    """

    problem: Problem
    values: np.ndarray
    sigma: np.ndarray
    at_bound: np.ndarray
    before: list
    after: list
    jacobian: np.ndarray
    dof: int
    evaluations: int
    design: RVDesign
    converged: bool
    messages: tuple[str, ...]
    reach_error: InputError | None = None

    @property
    def residuals_before(self) -> np.ndarray:
        return residuals_of(self.problem, self.before)

    @property
    def residuals_after(self) -> np.ndarray:
        return residuals_of(self.problem, self.after)

    @property
    def v_index(self) -> tuple[float, float]:
        """Mean squared residual before and after: seed 003's V for peaks."""
        return (float(np.mean(self.residuals_before ** 2)),
                float(np.mean(self.residuals_after ** 2)))

    def misfit(self) -> list[dict]:
        """One row per data set: measured, before, after (the quantity: one peak, a curve's
        RMS misfit, catalogue figures) and the misfit before and after with the improvement
        in % ((|before| - |after|) / |before|), as seed 003's table."""
        rows = []
        for d, measured, before, after in zip(self.problem.datasets, self.problem.measured(),
                                              self.before, self.after):
            if self.problem.target == "peaks":
                b, a = float(before[0] - measured[0]), float(after[0] - measured[0])
                row = {"name": d.name, "measured": float(measured[0]), "before": float(before[0]),
                       "after": float(after[0]), "misfit_before": b, "misfit_after": a}
            elif self.problem.target == "curve":
                b = float(np.sqrt(np.mean((before - measured) ** 2)))
                a = float(np.sqrt(np.mean((after - measured) ** 2)))
                row = {"name": d.name, "measured": float(np.ptp(measured)),
                       "before": float(np.ptp(before)), "after": float(np.ptp(after)),
                       "misfit_before": b, "misfit_after": a}
            else:
                b = float(np.sqrt(np.mean(((before - measured) / measured) ** 2)))
                a = float(np.sqrt(np.mean(((after - measured) / measured) ** 2)))
                row = {"name": d.name, "figures": d.catalogue.labels(),
                       "measured": measured.tolist(), "before": before.tolist(),
                       "after": after.tolist(), "misfit_before": b, "misfit_after": a}
            row["improvement_percent"] = (100.0 * (abs(b) - abs(a)) / abs(b)) if b else float("nan")
            rows.append(row)
        return rows

    def sensitivity(self) -> np.ndarray:
        """(p,) RMS change of the residuals [arcsec, or relative] per +1 % of each value."""
        return np.sqrt(np.mean((0.01 * self.jacobian) ** 2, axis=0))


def calibrate(problem: Problem, maxiter: int = DE_MAXITER, popsize: int = DE_POPSIZE,
              seed: int = DE_SEED, progress=None, refuse: bool = False) -> Calibration:
    """Fit the problem's values: differential evolution on ln(value) within the bounds, then
    least squares from its best member; the uncertainty from the Jacobian at the optimum.

    progress(evaluations done): optional, called after each model evaluation.  refuse: raise
    the InputError of a figure out of reach (`beyond_reach`, before the fit) or of a fit
    pressed against a default bound (`out_of_reach`), as a job that writes the design
    does; else the calibration carries it as `reach_error`.
    """
    from scipy.optimize import differential_evolution, least_squares

    maxiter = integer("maxiter", maxiter, 0)
    popsize = integer("popsize", popsize, 2)
    seed = integer("seed", seed, 0)
    count = [0]

    def r(x):
        count[0] += 1
        if progress is not None:
            progress(count[0])
        return residuals(problem, x)

    lower, upper = problem.log_bounds
    unreachable = beyond_reach(problem)
    if refuse and unreachable is not None:
        raise unreachable
    before, ok_before = evaluate(problem, problem.design)
    messages = []
    start = np.clip(np.zeros(lower.size), lower, upper)
    best = start
    if maxiter > 0:
        de = differential_evolution(lambda x: _half_ss(r(x)),
                                    list(zip(lower, upper)), maxiter=maxiter, popsize=popsize,
                                    tol=DE_TOL, seed=seed, polish=False, init="latinhypercube",
                                    updating="immediate")
        best = de.x
        messages.append(f"differential_evolution: {de.message} ({de.nit} generations)")
        # The design as given may fit better than every member (a flat misfit): start there.
        if np.array_equal(start, np.zeros(lower.size)) and \
                _half_ss(residuals_of(problem, before)) < de.fun:
            best = start
    ls = least_squares(r, best, bounds=(lower, upper), jac="2-point", diff_step=JACOBIAN_STEP,
                       x_scale=1.0, max_nfev=LS_MAX_EVALUATIONS)
    messages.append(f"least_squares: {ls.message}")
    x = ls.x
    jac = _jacobian(r, x)
    values = values_at(problem, x)
    design = problem.design_at(values)
    after, ok_after = evaluate(problem, design)
    res = residuals_of(problem, after)
    dof = res.size - x.size
    sigma = values * _sigma_log(jac, res, dof)
    span = upper - lower
    at_lower = x - lower < 1e-6 * np.maximum(span, 1)
    at_upper = upper - x < 1e-6 * np.maximum(span, 1)
    error = unreachable or out_of_reach(problem, at_lower, at_upper, jac, res, after)
    if refuse and error is not None:
        raise error
    return Calibration(problem, values, sigma, at_lower | at_upper, before, after, jac, dof,
                       count[0], design, ok_before and ok_after, tuple(messages), error)


def _figures(problem: Problem, model: list[np.ndarray]) -> list[tuple[str, float, float, slice]]:
    """(name, measured, modelled, its rows of the residuals) of every figure the fit matches:
    each catalogue figure, each data set's peak, each bench curve (its te_pp)."""
    out, row = [], 0
    for d, measured, modelled in zip(problem.datasets, problem.measured(), model):
        if problem.target == "catalogue":
            for name, m, v in zip(d.catalogue.labels(), measured, modelled):
                out.append((name, float(m), float(v), slice(row, row + 1)))
                row += 1
            continue
        if problem.target == "curve":
            out.append((f"te_pp_arcsec of the curve {d.name}", float(np.ptp(measured)),
                        float(np.ptp(modelled)), slice(row, row + measured.size)))
        else:
            out.append((f"te_pp_arcsec of {d.name}", float(measured[0]), float(modelled[0]),
                        slice(row, row + 1)))
        row += measured.size
    return out


def beyond_reach(problem: Problem) -> InputError | None:
    """The InputError of a figure (`_figures`) that the design cannot reach within the
    default bounds (module docstring), else None: it names the figure, its value, the range
    the design gives over the bounds' corners (2^p models) and the values with their
    bounds.  Only when no bounds were given (a window the user states may be ended on) and
    for p <= REACH_MAX_VALUES."""
    params = problem.parameters
    if any(p.bounds_given for p in params) or len(params) > REACH_MAX_VALUES:
        return None
    corners = np.array(np.meshgrid(*[(p.lower, p.upper) for p in params],
                                   indexing="ij")).reshape(len(params), -1).T    # (2^p, p)
    reached = [[f[2] for f in _figures(problem, evaluate(problem, problem.design_at(c))[0])]
               for c in corners]
    reached = np.array(reached, dtype=float)                                     # (2^p, F)
    for f, (name, measured, _, _) in enumerate(_figures(problem, problem.measured())):
        column = reached[:, f][np.isfinite(reached[:, f])]
        if column.size == 0:
            continue
        low, high = float(column.min()), float(column.max())
        if not low * (1.0 - REACH_MARGIN) <= measured <= high * (1.0 + REACH_MARGIN):
            window = ", ".join(f"{p.name} {p.lower:.4g} to {p.upper:.4g} {p.unit}"
                               for p in params)
            return InputError(name, measured, f"out of the fit's reach: within the default "
                              f"bounds ({window}) the design gives {low:.4g} to {high:.4g}; nothing "
                              "written; check the figure, or give --bounds NAME=LOWER:UPPER "
                              "if the value truly lies beyond")
    return None


def out_of_reach(problem: Problem, at_lower, at_upper, jac, res, after) -> InputError | None:
    """The InputError of a fit that ends on a default bound which the misfit presses against
    (module docstring), else None.  at_lower, at_upper (p,) bool: the fitted values on a bound; jac
    (n, p): d residual / d ln(value) at the fit; res (n,): the residuals there; after: the
    model's quantities there (as `evaluate`).  It names the figure that presses hardest on
    a bound, its value, each value on its bound with the bound, and the model's figure
    there: the nearest the search window reaches."""
    figures = _figures(problem, after)
    pressed = []
    for k, p in enumerate(problem.parameters):
        if p.bounds_given or not (at_lower[k] or at_upper[k]):
            continue
        outward = 1.0 if at_upper[k] else -1.0
        best = None
        for f, (_, measured, modelled, rows) in enumerate(figures):
            # minus the figure's share of the misfit's slope along ln(value), outward: > 0
            # where its misfit still falls beyond the bound
            if -outward * float(jac[rows, k] @ res[rows]) <= 0.0:
                continue
            # of the figures that press, the one the value moves most, relative to itself (a
            # relative residual's slope is d(model)/d ln(value) / measured)
            slope = np.linalg.norm(jac[rows, k]) * (abs(measured) if problem.target == "catalogue"
                                                    else 1.0)
            moves = slope / max(abs(modelled), 1e-300)
            if best is None or moves > best[0]:
                best = (moves, k, f)
        if best is not None:
            pressed.append(best)
    if not pressed:
        return None
    pressed.sort(key=lambda item: -item[0])
    name, measured, _, _ = figures[pressed[0][2]]
    parts = []
    for _, k, f in pressed:
        p = problem.parameters[k]
        side, bound = ("upper", p.upper) if at_upper[k] else ("lower", p.lower)
        figure = figures[f]
        parts.append(f"{p.name} ends at its {side} bound {bound:.4g} {p.unit} (the default "
                     f"search range {p.lower:.4g} to {p.upper:.4g}), where the model gives "
                     f"{figure[0]} = {figure[2]:.4g}" + ("" if f == pressed[0][2] else
                                                          f" against {figure[1]:.4g}"))
    return InputError(name, measured, "out of the fit's reach: " + "; ".join(parts)
                      + ": nothing written; check the figure, or give --bounds NAME=LOWER:UPPER "
                      "if the value truly lies beyond")


def _half_ss(r):
    return 0.5 * float(r @ r)


def _jacobian(r, x):
    """(n, p) central differences of r at x, step JACOBIAN_STEP in each ln(value)."""
    columns = []
    for k in range(x.size):
        step = np.zeros(x.size)
        step[k] = JACOBIAN_STEP
        columns.append((r(x + step) - r(x - step)) / (2.0 * JACOBIAN_STEP))
    return np.stack(columns, axis=1)


def _sigma_log(jac, res, dof):
    """(p,) 1-sigma of ln(value): sqrt(diag((J^T J)^-1) s^2), inf along directions that J does
    not see, nan without residual variance (dof <= 0)."""
    p = jac.shape[1]
    s2 = float(res @ res) / dof if dof > 0 else float("nan")
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    largest = singular.max() if singular.size else 0.0
    seen = singular > max(SINGULAR_RELATIVE * largest, SENSITIVITY_FLOOR)
    cov = (vt[seen].T / singular[seen] ** 2) @ vt[seen] * s2
    sigma = np.sqrt(np.abs(np.diag(cov)))
    blind = np.sum(vt[~seen] ** 2, axis=0) > 1e-6 if np.any(~seen) else np.zeros(p, dtype=bool)
    return np.where(blind, np.inf, sigma)


# -- the calibrated design file --------------------------------------------------------------

def design_text(calibration: Calibration, data_names, sources: dict | None = None,
                from_design: str = "") -> str:
    """A complete design TOML of the calibrated design, loadable by `rvte te`: a header saying
    what was fitted to what, every design key, and the [sources] table (for R_pd)."""
    cal = calibration
    lines = [f"Calibrated by rvte calibrate ({cal.problem.target}) from {from_design or cal.problem.design.name}",
             "against " + ", ".join(str(n) for n in data_names) + ".",
             "Fitted (1-sigma from the Jacobian at the optimum; inf: not identifiable from the data):"]
    for p, v, s in zip(cal.problem.parameters, cal.values, cal.sigma):
        lines.append(f"  {p.name} = {v:.6g} +- {s:.3g} {p.unit} ({setting(p, v)})")
    lines.append("Every other value as in the design calibrated.")
    values = cal.design.file_values()
    values["name"] = f"{cal.problem.design.name} calibrated"
    text = toml_text(values, header="\n".join(lines))
    if sources:
        text += "\n[sources]\n" + toml_text({k: v for k, v in sources.items()})
    return text


def setting(parameter: Parameter, value: float) -> str:
    """What the fitted `value` sets in the design, in file units, for reports."""
    p = parameter
    if p.series_with is not None:
        return (f"{p.field} = series({p.name}, crankshaft {p.series_with:.4g} N/m) = "
                f"{p.field_values(value)[p.field]:.6g}")
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


__all__ = ["TARGETS", "SEED003_NAMES", "Parameter", "Catalogue", "DataSet", "Problem", "Calibration",
           "problem", "parameters", "evaluate", "residuals", "calibrate", "design_text",
           "design_sources", "peaks_datasets", "catalogue_dataset", "is_catalogue", "read_toml"]

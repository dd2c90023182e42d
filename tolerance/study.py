"""A tolerance study: the study file (TOML) -> a frozen, checked `Study` and its problem definition.

The question a study answers: for this design at this operating point, with
these tolerances on the manufacturing errors of docs/model.md section 4, what TE do
the reducers we build have, how many meet the spec (Monte Carlo), and which
tolerances decide it (Sobol)?  The file speaks the units of docs/model.md section 1 (um, deg, N*m,
arcsec) and names every tolerance by its error name:

    [study]
    design = "RV-40E-121"          # preset, or a design file relative to this file
    errors = "seed002_errors.toml" # optional: fixed errors added to every sampled reducer
    seed = 2002                    # the same seed gives the same reducers, on every backend
    metrics = ["te_pp", "rms"]     # te_pp, rms, lost_motion, torsional_rigidity, order_<k>,
                                   # efficiency, no_load_running_torque
    batch_size = 64                # reducers per batch: unit of work, of storage and of resume
    output = "my_study/output"     # default: <study file stem>/output beside the file

    [operating]
    load_Nm = 0.0                  # resisting output torque T (tau_load = -T); 0: no-load TE
    points = 720                   # per output revolution
    windup_positions = 8           # input positions of the windup test (lost motion, rigidity)
    output_speed_rpm = 15.0        # of the friction metrics (efficiency, no_load_running_torque)
    temperature_C = 40.0           # of the friction metrics: the lubricant's temperature [C]

    [spec]                         # a metric column = its limit (maximum; rigidity: minimum)
    te_pp_arcsec = 60.0

    [montecarlo]                   # n: reducers; confidence: of the yield interval
    [sobol]                        # n: base samples (power of 2); second_order; resamples; confidence;
                                   # method: "saltelli" (default) or "linearized" (loaded studies),
                                   # solved_n: its solved base samples (default 64); rounds:
                                   # double from 64 until the order groups settle (n the budget)

    [tolerances.crank_cam_eccentricity]
    position_um = 9.0              # diameter of the true-position zone
    distribution = "uniform"       # or "normal" (tolerance = +-3 sigma); default uniform
    group = "crankshaft"           # optional: Sobol group shared with other factors

    [tolerances.crank_cam_eccentricity.cost]   # optional, for `rvte allocate` (tolerance/cost.py)
    a = 0.0                        # cost = a + b / t^k, t the allocated tolerance [um]
    b = 64.0
    k = 2.0
    tightest_um = 4.0              # the tightest and loosest tolerance the process can hold
    loosest_um = 20.0

The statistical model of each kind of tolerance is in tolerance/sampling.py.
A load_Nm beyond 5x the rated torque is refused; beyond 2.5x the runs warn
(`Study.load_warning`, rvfmu.core.reducer.limits).  The study hash
(`Study.inputs_hash`) covers everything that changes a computed number; the
spec, the sample counts, the analysis settings and the cost tables are left
out, so changing them reuses the stored batches.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass, field
from functools import cache, cached_property
from importlib import metadata
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import InputError, finite_number, integer
from rvfmu.core.base.units import RPM, UM
from rvfmu.core.laws.lubricant import REFERENCE_TEMPERATURE_C, check_temperature
from rvfmu.core.reducer.design import (
    ESTIMATE_NAMES,
    PRESET_NAMES,
    RVDesign,
    design_from_file_values,
    load_design,
)
from rvfmu.core.reducer.errors import (
    ERROR_FRACTION,
    ERROR_NAMES,
    ErrorSet,
    error_file_values,
    error_limits,
    errors_from_file_values,
    load_errors,
)
from rvfmu.core.reducer.limits import check_load, check_speed
from rvfmu.core.statics.equivalent import check_angles
from rvfmu.core.statics.quasistatic import default_points

from . import sampling
from .cost import CostModel, check_bounds, cost_model
from .evaluate import LOWER_LIMITED, metric_column, metric_kind, metric_order

SECTIONS = {
    "study": ("name", "design", "errors", "seed", "metrics", "batch_size", "output"),
    "operating": ("load_Nm", "points", "windup_positions", "output_speed_rpm", "temperature_C"),
    "spec": None,  # keys: metric columns
    "montecarlo": ("n", "confidence"),
    "sobol": ("n", "second_order", "resamples", "confidence", "method", "solved_n", "rounds"),
    "tolerances": None,  # keys: error names
}
FACTOR_KEYS = ("distribution", "group", "cost")
MAX_BATCH = 4096  # reducers per batch: bigger batches only cost memory (S x points x pins)
METRIC_NAMES_TEXT = (
    "must be te_pp, rms, lost_motion, torsional_rigidity, order_<k> "
    "(k cycles per output revolution), efficiency or no_load_running_torque"
)
OUTPUT_SPEED_RPM = 15.0  # default output speed of the friction metrics: the catalogue's rated speed
MIN_SOBOL_N = 8  # the convergence check analyses N/4 base samples: at least 2


@dataclass(frozen=True)
class Factor:
    """The tolerance of one error source and its statistical model (tolerance/sampling.py).

    Values in um: position_um (zone diameter), cumulative_um and single_um (F_p,
    f_pt), band_um (width of the band), min_um and max_um (clearance range).
    cost: the [tolerances.NAME.cost] table (tolerance/cost.py), or None for the
    defaults of the kind; it changes no computed number, so it is not in
    `file_values` and not in the study's inputs hash.
    """

    name: str
    kind: str
    distribution: str = "uniform"
    group: str = ""
    position_um: float = 0.0
    cumulative_um: float = 0.0
    single_um: float | None = None
    band_um: float = 0.0
    min_um: float = 0.0
    max_um: float = 0.0
    cost: CostModel | None = None

    @property
    def largest_um(self) -> tuple[str, float, float]:
        """(key, its value, the largest error size [um] the tolerance draws): half the zone's
        diameter, the cumulative pitch span, half the band, the largest clearance."""
        key, factor = {
            "zone": ("position_um", 0.5),
            "pitch": ("cumulative_um", 1.0),
            "band": ("band_um", 0.5),
            "clearance": ("max_um", 1.0),
        }[self.kind]
        value = getattr(self, key)
        return key, value, factor * value

    def __post_init__(self):
        here = f"tolerances.{self.name}"
        if self.name not in ERROR_NAMES:
            raise InputError(
                here,
                self.name,
                f"names no error of docs/model.md section 4; known names: {', '.join(ERROR_NAMES)}",
            )
        if self.kind != sampling.KIND_OF[self.name]:
            raise InputError(f"{here}.kind", self.kind, f"must be {sampling.KIND_OF[self.name]}")
        if self.distribution not in sampling.DISTRIBUTIONS:
            raise InputError(
                f"{here}.distribution",
                self.distribution,
                f"must be one of {', '.join(sampling.DISTRIBUTIONS)}",
            )
        if not isinstance(self.group, str):
            raise InputError(f"{here}.group", self.group, "must be a name")
        object.__setattr__(self, "group", self.group.strip() or self.name)
        for key in ("position_um", "cumulative_um", "band_um", "min_um", "max_um"):
            value = finite_number(f"{here}.{key}", getattr(self, key))
            if value < 0:
                raise InputError(f"{here}.{key}", value, "a tolerance must be >= 0 um")
        if self.single_um is not None:
            value = finite_number(f"{here}.single_um", self.single_um)
            if value <= 0:
                raise InputError(
                    f"{here}.single_um",
                    value,
                    "a single pitch tolerance must be "
                    "> 0 um (leave it out for no limit beyond cumulative_um)",
                )
        if self.max_um < self.min_um:
            raise InputError(f"{here}.max_um", self.max_um, f"must be >= min_um = {self.min_um}")
        if self.cost is not None:
            if not isinstance(self.cost, CostModel):
                raise InputError(f"{here}.cost", self.cost, "must be a tolerance.cost.CostModel")
            check_bounds(self, f"{here}.cost")

    def file_values(self) -> dict:
        """The factor as the study file writes it (its kind's keys only)."""
        values = {"distribution": self.distribution, "group": self.group}
        for key in sampling.KEYS[self.kind]:
            if getattr(self, key) is not None:
                values[key] = getattr(self, key)
        return values


@dataclass(frozen=True)
class SpecLimit:
    """metric column <= limit (sense 'max') or >= limit (sense 'min')."""

    metric: str
    column: str
    limit: float
    sense: str

    def passes(self, values):
        """(n,) bool: which of `values` (n,), in the column's unit, meet this limit."""
        return values <= self.limit if self.sense == "max" else values >= self.limit

    def __str__(self):
        return f"{self.column} {'<=' if self.sense == 'max' else '>='} {self.limit:g}"


@dataclass(frozen=True)
class Study:
    """A checked tolerance study; SI inside (the design, the fixed errors), file units elsewhere."""

    name: str
    design: RVDesign
    factors: tuple[Factor, ...]
    design_source: str = ""
    base_errors: ErrorSet | None = None
    errors_source: str = ""
    seed: int = 0
    metrics: tuple[str, ...] = ("te_pp",)
    batch_size: int = 64
    output: Path = Path("output")
    load_Nm: float = 0.0
    points: int | None = None
    windup_positions: int = 8
    output_speed_rpm: float = OUTPUT_SPEED_RPM
    temperature_C: float = REFERENCE_TEMPERATURE_C
    spec: tuple[SpecLimit, ...] = ()
    mc_n: int = 1000
    mc_confidence: float = 0.95
    sobol_n: int = 1024
    second_order: bool = False
    resamples: int = 200
    sobol_confidence: float = 0.95
    sobol_method: str = "saltelli"
    sobol_solved_n: int = 64
    sobol_rounds: bool = False
    path: Path | None = field(default=None, compare=False)
    text: str = field(default="", compare=False, repr=False)

    def __post_init__(self):
        where = self.path.name if self.path else self.name
        if self.points is None:
            object.__setattr__(self, "points", default_points(self.design))
        integer("points", self.points, 8, where=where)
        check_angles(self.design, self.points, "points", where)
        integer("windup_positions", self.windup_positions, 1, where=where)
        integer("batch_size", self.batch_size, 1, MAX_BATCH, where=where)
        integer("seed", self.seed, 0, 2**63 - 1, where=where)
        check_load("operating.load_Nm", self.load_Nm, self.design.rated_torque, where)
        if not self.factors:
            raise InputError(
                "tolerances",
                None,
                "a study needs at least one [tolerances.NAME] "
                f"table; NAME is one of {', '.join(ERROR_NAMES)}",
                where,
            )
        if not self.metrics:
            raise InputError("metrics", [], "name at least one metric", where)
        for name in self.metrics:
            if metric_kind(name) is None:
                raise InputError("metrics", name, METRIC_NAMES_TEXT, where)
            if metric_kind(name) == "order" and not 1 <= metric_order(name) < self.points // 2:
                raise InputError(
                    "metrics",
                    name,
                    f"the order must be from 1 to {self.points // 2 - 1}"
                    f" (Nyquist order of points = {self.points})",
                    where,
                )
        if not finite_number("operating.output_speed_rpm", self.output_speed_rpm, where) > 0.0:
            raise InputError(
                "operating.output_speed_rpm",
                self.output_speed_rpm,
                "must be a positive output speed [rpm]",
                where,
            )
        check_speed(
            "operating.output_speed_rpm",
            self.output_speed_rpm,
            self.output_speed_rpm * RPM,
            self.design,
            where,
        )
        check_temperature(self.temperature_C, "operating.temperature_C", where)
        if "efficiency" in self.metrics and not self.load_Nm > 0.0:
            raise InputError(
                "operating.load_Nm",
                self.load_Nm,
                "must be a resisting torque > 0 "
                "for the metric efficiency (the output's power over the input's)",
                where,
            )
        if len(set(self.metrics)) != len(self.metrics):
            raise InputError("metrics", list(self.metrics), "must not repeat a metric", where)
        for limit in self.spec:
            if limit.metric not in self.metrics:
                raise InputError(
                    "spec",
                    limit.column,
                    f"needs the metric {limit.metric!r} in [study] metrics (now {list(self.metrics)})",
                    where,
                )
        integer("montecarlo.n", self.mc_n, 1, where=where)
        sobol_base_samples("sobol.n", self.sobol_n, where)
        integer("sobol.resamples", self.resamples, 10, where=where)
        check_sobol_method("sobol.method", self.sobol_method, where)
        sobol_base_samples("sobol.solved_n", self.sobol_solved_n, where)
        for key, value in (
            ("montecarlo.confidence", self.mc_confidence),
            ("sobol.confidence", self.sobol_confidence),
        ):
            if not 0.0 < finite_number(key, value, where) < 1.0:
                raise InputError(key, value, "must be between 0 and 1 (e.g. 0.95)", where)
        if self.base_errors is not None:
            self.base_errors.check(self.design)
        limits = error_limits(self.design)
        for factor in self.factors:
            key, value, largest = factor.largest_um
            if largest * UM > limits[factor.name] * (1.0 + 1e-9):
                raise InputError(
                    f"tolerances.{factor.name}.{key}",
                    value,
                    f"allows errors of up to {largest:g} um, where the model takes "
                    f"at most {limits[factor.name] / UM:.4g} um for "
                    f"{factor.name} on {self.design.name} (ERROR_FRACTION = "
                    f"{ERROR_FRACTION:g} x the length it displaces, docs/model.md "
                    "section 4)",
                    where,
                )

    @property
    def load_warning(self) -> str | None:
        """A warning when the load is above the momentary maximum class (rvfmu.core.reducer.limits)."""
        where = self.path.name if self.path else self.name
        return check_load("operating.load_Nm", self.load_Nm, self.design.rated_torque, where)

    @property
    def operating_warnings(self) -> list[str]:
        """The warnings of the [operating] table: the load above the momentary maximum class,
        the output speed above the design's allowable speed (rvfmu.core.reducer.limits)."""
        where = self.path.name if self.path else self.name
        speed = check_speed(
            "operating.output_speed_rpm",
            self.output_speed_rpm,
            self.output_speed_rpm * RPM,
            self.design,
            where,
        )
        return [w for w in (self.load_warning, speed) if w]

    # -- the problem definition ----------------------------------------------------------
    @cached_property
    def layout(self) -> tuple[tuple[Factor, int, int], ...]:
        """(factor, first column, end column) of every factor, in file order."""
        out, start = [], 0
        for factor in self.factors:
            stop = start + len(sampling.draw_names(factor, self.design))
            out.append((factor, start, stop))
            start = stop
        return tuple(out)

    @cached_property
    def columns(self) -> tuple[str, ...]:
        """Names of the D unit columns of a sample row."""
        return tuple(n for f in self.factors for n in sampling.draw_names(f, self.design))

    @cached_property
    def groups(self) -> tuple[str, ...]:
        """The Sobol groups in order of first appearance (one per factor unless merged by `group`)."""
        return tuple(dict.fromkeys(f.group for f in self.factors))

    def problem(self) -> dict:
        """SALib problem: every column uniform on [0, 1), grouped by factor group."""
        groups = [f.group for f, start, stop in self.layout for _ in range(stop - start)]
        return {
            "num_vars": len(self.columns),
            "names": list(self.columns),
            "bounds": [[0.0, 1.0]] * len(self.columns),
            "groups": groups,
        }

    @property
    def metric_columns(self) -> tuple[str, ...]:
        return tuple(metric_column(m) for m in self.metrics)

    # -- identity ---------------------------------------------------------------------------
    def inputs(self) -> dict:
        """Every input that changes a computed number, normalised (file units, sorted keys)."""
        return {
            "design": self.design.file_values(),
            "errors": error_file_values(self.base_errors) if self.base_errors is not None else {},
            "operating": {
                "load_Nm": self.load_Nm,
                "points": self.points,
                "windup_positions": self.windup_positions,
                # only where it changes a number: the friction metrics
                **(
                    {"output_speed_rpm": self.output_speed_rpm, "temperature_C": self.temperature_C}
                    if set(self.metrics) & {"efficiency", "no_load_running_torque"}
                    else {}
                ),
            },
            "metrics": list(self.metrics),
            "tolerances": {f.name: f.file_values() for f in self.factors},
            "factor_order": [f.name for f in self.factors],
            "seed": self.seed,
            "batch_size": self.batch_size,
            "sampling_version": sampling.SAMPLING_VERSION,
        }

    @cached_property
    def inputs_hash(self) -> str:
        """sha256 of `inputs()` (canonical JSON)."""
        text = json.dumps(self.inputs(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


SOBOL_METHODS = ("saltelli", "linearized")


def check_sobol_method(field_name: str, method, where: str = "") -> str:
    """A Sobol method's name, checked: "saltelli" (the reference: every reducer of Saltelli's
    design solved) or "linearized" (the TE curve linearized in the errors,
    `tolerance.linearized`)."""
    if method not in SOBOL_METHODS:
        raise InputError(
            field_name, method, "must be one of " + ", ".join(f'"{m}"' for m in SOBOL_METHODS), where
        )
    return method


def sobol_base_samples(field_name: str, n, where: str = "") -> int:
    """N of a Sobol study: a power of 2 (balance of the Sobol' sequence), at least MIN_SOBOL_N."""
    n = integer(field_name, n, MIN_SOBOL_N, where=where)
    if n & (n - 1):
        raise InputError(
            field_name,
            n,
            f"must be a power of 2 (e.g. {1 << n.bit_length()}) so that "
            "the Sobol' sequence and its N/4 and N/2 heads are balanced",
            where,
        )
    return n


@cache
def model_fingerprint() -> str:
    """sha256 of the rvte version and the source of the model and of the sampling.

    Part of the identity of an output folder: batches computed by another
    version of the physics or of the sampling are never mixed with new ones.
    """
    import rvfmu.core

    digest = hashlib.sha256()
    try:
        digest.update(metadata.version("rvte").encode())
    except metadata.PackageNotFoundError:
        digest.update(b"rvte (not installed)")
    core = Path(rvfmu.core.__file__).parent
    here = Path(__file__).parent  # the sampling and the evaluation change numbers too
    files = sorted(core.rglob("*.py")) + [here / f"{m}.py" for m in ("sampling", "sequences", "evaluate")]
    for path in files:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


# -- reading a study file ----------------------------------------------------------------------


def load_study(path: str | Path, output: str | Path | None = None) -> Study:
    """Read and check a study file; `output` overrides its output folder."""
    path = Path(path)
    if not path.is_file():
        raise InputError("study", str(path), "must be a readable study TOML file")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError("study", str(path), f"is not a readable UTF-8 TOML study file ({exc})") from None
    try:
        values = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError("study", str(path), f"is not valid TOML ({exc})") from None
    return study_from_values(values, path, text, output)


def study_from_values(values: dict, path: Path, text: str = "", output=None) -> Study:
    """A Study from the parsed TOML of `path` (relative file names are resolved beside it)."""
    where = path.name
    _known(values, SECTIONS, "the study file", where)
    sections = {name: values.get(name, {}) for name in SECTIONS}
    for name, table in sections.items():
        if not isinstance(table, dict):
            raise InputError(name, table, f"must be a [{name}] table", where)
        if SECTIONS[name] is not None:
            _known(table, SECTIONS[name], f"[{name}]", where)
    head, op = sections["study"], sections["operating"]
    if "design" not in head:
        raise InputError(
            "study.design", None, f"is missing: a preset ({', '.join(PRESET_NAMES)}) or a design file", where
        )
    design_source = _text("study.design", head["design"], where)
    if design_source not in PRESET_NAMES + ESTIMATE_NAMES:
        design_source = str(_beside(path, design_source))  # so that reports can name the file
    design = load_design(design_source)
    errors_source = head.get("errors")
    base_errors = None
    if errors_source is not None:
        errors_source = _text("study.errors", errors_source, where)
        base_errors = load_errors(_beside(path, errors_source), design)
    metrics = head.get("metrics", ["te_pp"])
    if isinstance(metrics, str):
        metrics = [metrics]
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        raise InputError("study.metrics", metrics, "must be a list of metric names", where)
    for name in metrics:
        if metric_kind(name) is None:
            raise InputError("study.metrics", name, METRIC_NAMES_TEXT, where)
    study_dir = path.resolve().parent
    if output is not None:
        out = Path(output)
    elif "output" in head:
        out = Path(_text("study.output", head["output"], where))
    else:
        out = Path(path.stem) / "output"
    return Study(
        name=_text("study.name", head.get("name", path.stem), where),
        design=design,
        design_source=design_source,
        base_errors=base_errors,
        errors_source=errors_source or "",
        factors=_factors(sections["tolerances"], where),
        seed=integer("study.seed", head.get("seed", 0), 0, 2**63 - 1, where),
        metrics=tuple(metrics),
        batch_size=integer("study.batch_size", head.get("batch_size", 64), 1, MAX_BATCH, where),
        output=out if out.is_absolute() or output is not None else study_dir / out,
        load_Nm=finite_number("operating.load_Nm", op.get("load_Nm", 0.0), where),
        points=integer("operating.points", op["points"], 8, where=where) if "points" in op else None,
        windup_positions=integer("operating.windup_positions", op.get("windup_positions", 8), 1, where=where),
        output_speed_rpm=finite_number(
            "operating.output_speed_rpm", op.get("output_speed_rpm", OUTPUT_SPEED_RPM), where
        ),
        temperature_C=finite_number(
            "operating.temperature_C", op.get("temperature_C", REFERENCE_TEMPERATURE_C), where
        ),
        spec=_spec(sections["spec"], metrics, where),
        mc_n=integer("montecarlo.n", sections["montecarlo"].get("n", 1000), 1, where=where),
        mc_confidence=sections["montecarlo"].get("confidence", 0.95),
        sobol_n=sobol_base_samples("sobol.n", sections["sobol"].get("n", 1024), where),
        second_order=_bool("sobol.second_order", sections["sobol"].get("second_order", False), where),
        resamples=integer("sobol.resamples", sections["sobol"].get("resamples", 200), 10, where=where),
        sobol_confidence=sections["sobol"].get("confidence", 0.95),
        sobol_method=sections["sobol"].get("method", "saltelli"),
        sobol_solved_n=sections["sobol"].get("solved_n", 64),
        sobol_rounds=_bool("sobol.rounds", sections["sobol"].get("rounds", False), where),
        path=path,
        text=text,
    )


def study_from_store(folder: Path, name: str, inputs: dict, study_text: str = "") -> Study:
    """The study that computed an output folder's store.

    Its identity (design, fixed errors, operating point, metrics, tolerances,
    seed, batch size) comes from `inputs` (the folder's inputs.json, which
    hashes to the manifest's inputs hash), its name from the manifest, the
    rest (spec, sample counts, confidence levels) from `study_text`, the
    folder's copy of the study file (study.toml, as last run; "" if there is
    none: no spec).  Relative file names in that copy point beside the study
    file, which the folder does not record: reading the values from
    inputs.json needs no file but the folder's.  InputError if inputs.json or
    study.toml is not what rvte writes.
    """
    folder = Path(folder)
    try:
        values = tomllib.loads(study_text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError("study.toml", str(folder / "study.toml"), f"is not valid TOML ({exc})") from None
    for section in ("study", "spec", "montecarlo", "sobol"):
        if not isinstance(values.get(section, {}), dict):
            raise InputError(
                "study.toml",
                str(folder / "study.toml"),
                f"has {section} = "
                f"{values[section]!r} where a [{section}] table belongs: it is not "
                "the study file rvte copies there; restore it or run the study again",
            )
    head, sections = values.get("study", {}), {k: values.get(k, {}) for k in ("montecarlo", "sobol")}
    try:
        design = design_from_file_values(inputs["design"], where="inputs.json")
        errors = (
            errors_from_file_values(design, inputs["errors"], "inputs.json") if inputs["errors"] else None
        )
        factors = tuple(
            Factor(name=factor, kind=sampling.KIND_OF.get(factor), **inputs["tolerances"][factor])
            for factor in inputs["factor_order"]
        )
        metrics = tuple(inputs["metrics"])
        operating = inputs["operating"]
        return Study(
            name=name,
            design=design,
            factors=factors,
            design_source=str(head.get("design", design.name)),
            base_errors=errors,
            errors_source=str(head.get("errors", "")),
            seed=inputs["seed"],
            metrics=metrics,
            batch_size=inputs["batch_size"],
            output=folder,
            load_Nm=operating["load_Nm"],
            points=operating["points"],
            windup_positions=operating["windup_positions"],
            output_speed_rpm=operating.get("output_speed_rpm", OUTPUT_SPEED_RPM),
            temperature_C=operating.get("temperature_C", REFERENCE_TEMPERATURE_C),
            spec=_spec(values.get("spec", {}), metrics, "study.toml"),
            mc_n=sections["montecarlo"].get("n", 1000),
            mc_confidence=sections["montecarlo"].get("confidence", 0.95),
            sobol_n=sections["sobol"].get("n", 1024),
            second_order=sections["sobol"].get("second_order", False),
            resamples=sections["sobol"].get("resamples", 200),
            sobol_confidence=sections["sobol"].get("confidence", 0.95),
            sobol_method=sections["sobol"].get("method", "saltelli"),
            sobol_solved_n=sections["sobol"].get("solved_n", 64),
            sobol_rounds=sections["sobol"].get("rounds", False),
            path=folder / "study.toml",
            text=study_text,
        )
    except (KeyError, TypeError) as exc:
        raise InputError(
            "inputs.json",
            str(folder / "inputs.json"),
            f"lacks {exc} or holds a value of the wrong type: it is not the inputs.json rvte writes",
        ) from None


def _factors(table: dict, where: str) -> tuple[Factor, ...]:
    """The [tolerances.NAME] tables: keys and presence here, values checked by `Factor`."""
    factors = []
    for name, values in table.items():
        kind = sampling.KIND_OF.get(name)
        if kind is not None and not isinstance(values, dict):
            raise InputError(
                f"tolerances.{name}",
                values,
                f"must be a table with its tolerance ({', '.join(sampling.KEYS[kind])})",
                where,
            )
        values = values if isinstance(values, dict) else {}
        if kind is None:  # an unknown error name: say so, whatever keys its table holds
            raise InputError(
                f"tolerances.{name}",
                name,
                f"names no error of docs/model.md section 4; the errors are {', '.join(ERROR_NAMES)}",
                where,
            )
        if kind is not None:
            keys = sampling.KEYS[kind]
            _known(values, keys + FACTOR_KEYS, f"[tolerances.{name}]", where)
            required = keys[: sampling.REQUIRED[kind]]
            missing = [k for k in required if k not in values]
            if missing:
                raise InputError(
                    f"tolerances.{name}.{missing[0]}",
                    None,
                    f"is missing: a {kind} tolerance needs {', '.join(required)} (um)",
                    where,
                )
        if "cost" in values:
            values = {**values, "cost": cost_model(values["cost"], f"tolerances.{name}.cost", where)}
        try:
            factors.append(Factor(name=name, kind=kind, **values))
        except InputError as exc:  # the same message, located in the study file
            raise InputError(exc.field, exc.value, exc.allowed, where) from None
    return tuple(factors)


def _spec(table: dict, metrics, where: str) -> tuple[SpecLimit, ...]:
    by_column = {metric_column(m): m for m in metrics if metric_kind(m) is not None}
    limits = []
    for column, value in table.items():
        if column not in by_column:
            raise InputError(
                f"spec.{column}",
                value,
                f"must be the column of a metric in [study] metrics: {', '.join(by_column) or '(none)'}",
                where,
            )
        metric = by_column[column]
        sense = "min" if metric_kind(metric) in LOWER_LIMITED else "max"
        limits.append(SpecLimit(metric, column, finite_number(f"spec.{column}", value, where), sense))
    return tuple(limits)


def _known(values: dict, allowed, what: str, where: str) -> None:
    for key in values:
        if key not in allowed:
            raise InputError(
                key, values[key], f"is not a key of {what}; known keys: {', '.join(allowed)}", where
            )


def _text(name, value, where) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(name, value, "must be a non-empty text", where)
    return value


def _bool(name, value, where) -> bool:
    if not isinstance(value, bool):
        raise InputError(name, value, "must be true or false", where)
    return value


def flag(name: str, value, none: bool = False) -> bool | None:
    """A boolean keyword of the Python API: True or False (numpy's too), with `none` also None.

    Anything else is refused: a text such as "no" is truthy and would silently mean yes."""
    if value is None and none:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise InputError(name, value, "must be True or False" + (" (or None)" if none else ""))


def _beside(study_path: Path, name: str) -> Path:
    given = Path(name)
    return given if given.is_absolute() else study_path.resolve().parent / given


__all__ = [
    "Factor",
    "SpecLimit",
    "Study",
    "load_study",
    "study_from_values",
    "study_from_store",
    "model_fingerprint",
    "sobol_base_samples",
    "check_sobol_method",
    "flag",
]
